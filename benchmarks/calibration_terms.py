"""Which term of the room account makes `what` sure? Development views only.

Reads the home models that ``benchmarks/calibration.py`` kept in ``--models`` (its ``--out``) for one
configuration (``--set`` ``development`` or ``development-new``, ``--features``, ``--size``; the
held-out set is refused: ``benchmarks/calibration/SPLIT.md``) and answers every scored view as
``calibration.py`` does — the room account P(l | x, v) ∝ Σ_k p(k | x) p(l | room k) p(v | l)
(:mod:`spco.model.rooms`), a ``development-new`` view left out of its room — and with one term changed
at a time, on the same models:

- ``account``: the room account as the robot answers (reproduces ``calibration.py``'s "after");
- ``no_view``: p(v | l) dropped (the pose and its rooms alone);
- ``no_room_evidence``: p(l | room k) replaced by G_0 (the view alone against φ^v);
- ``room_half`` / ``view_half``: the room's pooled views / the view at w/2 instead of w;
- ``view_moves_room``: the view decides which room (p(k | x, v) ∝ p(k | x) Σ_l p(l | room k) p(v | l)),
  the room's views alone its concept;
- ``view_joins_room``: the view pooled with its room's views into one count vector worth w (one piece
  of evidence per room), the room chosen as in ``view_moves_room``.

Printed: ECE (10 bins), accuracy, mean confidence, wrong answers at p ≥ 0.99, log loss of the right
name, per variant; the wrong answers of the account grouped by (home, place, answered name) with the
terms of the median answer — p(k | x) of the pose's likeliest room, that room's size and the places
of its samples, p(l* | room), the room's and the view's margins (nats, w-weighted log-likelihood of
the answered concept l* over the concept most sure of the right name), θ^w(answer | l*) — and each
place's mean confidence / accuracy per variant. Nothing is sampled: same models, same figures.

    python benchmarks/calibration.py --data D/sigverse --images D/sigverse_images --out OUT \\
        --sets development-new --features colour-hog --sizes 4 --first-seeds 3
    python benchmarks/calibration_terms.py --data D/sigverse --images D/sigverse_images --models OUT \\
        --set development-new --features colour-hog --size 4
"""

from __future__ import annotations

import argparse
import sys
import warnings
from collections import Counter, defaultdict
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np
import scipy.sparse as sp
from scipy.special import logsumexp

sys.path.insert(0, str(Path(__file__).resolve().parent))
from calibration import SETS, SURE, _load, ece, scored_views

VARIANTS = ("account", "no_view", "no_room_evidence", "room_half", "view_half", "view_moves_room",
            "view_joins_room")


def _normalise_rows(log_p: np.ndarray) -> np.ndarray:
    return log_p - logsumexp(log_p, axis=1, keepdims=True)


def view_terms(params: Any, rooms: Any, pose: np.ndarray, view: sp.csr_array, w: float | None
               ) -> dict[str, Any]:
    """The room account's terms at one observation (``pose`` (1, 4), ``view`` (1, D)) of home 0 and
    P(l | x, v) under each of :data:`VARIANTS` (module docstring), all in log space."""
    from spco.model.prediction import _visual_log_likelihood, gaussian_log_density
    from spco.model.rooms import _room_evidence

    room_log, counts, region_of = _room_evidence(params, rooms, w, 0)
    share, _ = rooms.membership(int(np.shape(params.region_means)[1]))
    onehot = share.copy()
    onehot.data[:] = 1.0
    pooled = sp.csr_array(onehot @ rooms.visual)  # (R, D) each room's views pooled
    phi = np.asarray(params.shared_visual_probabilities, dtype=np.float64)
    g0 = np.log(np.maximum(np.asarray(params.global_concept_weights, dtype=np.float64), 1e-300))
    density = gaussian_log_density(pose, params.region_means[0], params.region_covariances[0])[0]
    log_k = np.where(counts > 0, density[region_of] + np.log(np.maximum(counts, 1e-300)), -np.inf)
    log_k = log_k - logsumexp(log_k)  # log p(k | x)
    view_log = _visual_log_likelihood(phi, view, w)[0]  # (L,) log p(v | l) at w
    room_visual = _visual_log_likelihood(phi, pooled, w)  # (R, L) the pooled views at w
    other = room_log - g0[None, :] - room_visual  # the names taught in the room (0 if none)
    room_norm = _normalise_rows(room_log)  # log p(l | room k)

    def mix(room_term: np.ndarray, view_term: np.ndarray) -> np.ndarray:
        joint = logsumexp(log_k[:, None] + room_term + view_term[None, :], axis=0)
        return joint - logsumexp(joint)

    half_room = _normalise_rows(g0[None, :] + other + room_visual / 2)
    log_pk_v = log_k + logsumexp(room_norm + view_log[None, :], axis=1)  # log p(k | x, v)
    log_pk_v = log_pk_v - logsumexp(log_pk_v)
    joined = _normalise_rows(g0[None, :] + other
                             + _visual_log_likelihood(phi, sp.csr_array(pooled + view.toarray()), w))
    posteriors = {
        "account": mix(room_norm, view_log),
        "no_view": mix(room_norm, np.zeros_like(view_log)),
        "no_room_evidence": mix(np.broadcast_to(g0 - logsumexp(g0), room_norm.shape), view_log),
        "room_half": mix(half_room, view_log),
        "view_half": mix(room_norm, view_log / 2),
        "view_moves_room": logsumexp(log_pk_v[:, None] + room_norm, axis=0),
        "view_joins_room": logsumexp(log_pk_v[:, None] + joined, axis=0),
    }
    return {"log_k": log_k, "counts": counts, "room_norm": room_norm, "view_log": view_log,
            "share": share, "g0": g0, "posteriors": {k: np.exp(v) for k, v in posteriors.items()}}


def _name_matrix(params: Any) -> tuple[np.ndarray, np.ndarray]:
    from spco.model.prediction import _word_matrix

    mask = np.asarray(params.word_mask, dtype=bool)
    theta = _word_matrix(params, 0) * mask[None, :]
    return theta / np.maximum(theta.sum(axis=1, keepdims=True), 1e-300), mask


def score_home(home: Any, model: Any, seed: int) -> list[dict[str, Any]]:
    """One row per scored view of ``home``: each variant's answer, its probability and the right
    name's, and the account's terms (for the wrong answers' table)."""
    from spco.knowledge.queries import answer_parameters, home_rooms

    params, all_rooms = answer_parameters(model), home_rooms(model)
    w = model.hyperparameters.view_weight()
    vocabulary = list(model.vocabulary.words)
    theta, mask = _name_matrix(params)
    ids = np.asarray(model.ids)
    positions, visual, labels, scored = scored_views(home)
    new_home = bool(home.is_test.any())
    place_of = dict(zip(np.asarray(home.ids).tolist(), home.labels(), strict=True))
    rows = []
    for i, label in enumerate(labels):
        keep = np.ones(ids.size, dtype=bool) if new_home else ids != int(scored[i])
        rooms = all_rooms if new_home else all_rooms.subset(keep)
        terms = view_terms(params, rooms, positions[[i]], sp.csr_array(visual[[i]]), w)
        right = vocabulary.index(label) if label in vocabulary else None
        row: dict[str, Any] = {"seed": seed, "home": home.name, "view": int(scored[i]), "label": label}
        for key, posterior in terms["posteriors"].items():
            names = posterior @ theta
            names = names / names.sum()
            best = int(np.argmax(np.where(mask, names, -1.0)))
            p_right = float(names[right]) if right is not None else 0.0
            row[key] = (vocabulary[best], float(names[best]), p_right)
        answer = row["account"][0]
        if answer != label:
            k = int(np.argmax(terms["log_k"]))
            concept = int(np.argmax(terms["posteriors"]["account"]))
            truth = int(np.argmax(theta[:, right])) if right is not None else concept
            members = np.flatnonzero(terms["share"].toarray()[k] > 0)
            row.update({
                "p_room": float(np.exp(terms["log_k"][k])), "room_n": float(terms["counts"][k]),
                "room_places": Counter(place_of.get(int(j)) for j in ids[keep][members]),
                "p_concept_room": float(np.exp(terms["room_norm"][k, concept])),
                "room_margin": float(terms["room_norm"][k, concept] - terms["room_norm"][k, truth]),
                "view_margin": float(terms["view_log"][concept] - terms["view_log"][truth]),
                "name_share": float(theta[concept, vocabulary.index(answer)]),
            })
        rows.append(row)
    return rows


def report(rows: list[dict[str, Any]]) -> str:
    """The tables of the module docstring, as text."""
    out = ["| variant | ECE | accuracy | mean confidence | wrong at p ≥ 0.99 | log loss |",
           "|---|---|---|---|---|---|"]
    for key in VARIANTS:
        p = np.array([r[key][1] for r in rows])
        ok = np.array([r[key][0] == r["label"] for r in rows])
        loss = -np.log(np.maximum([r[key][2] for r in rows], 1e-12))
        out.append(f"| {key} | {ece(p, ok):.3f} | {ok.mean():.3f} | {p.mean():.3f} | "
                   f"{int((p[~ok] >= SURE).sum())} of {int((~ok).sum())} | {loss.mean():.3f} |")
    groups: dict[tuple[str, str, str], list[dict[str, Any]]] = defaultdict(list)
    for r in rows:
        if r["account"][0] != r["label"]:
            groups[(r["home"], r["label"], r["account"][0])].append(r)
    out += ["", "| home: place → answered | n | median p | p ≥ 0.99 | p(k | x) | room n | "
            "room's places (all answers) | p(l* | room) | room margin | view margin | θ^w(answer | l*) |",
            "|---" * 11 + "|"]
    for (home, label, answer), rs in sorted(groups.items(), key=lambda t: -len(t[1])):
        def med(key: str, rs: list[dict[str, Any]] = rs) -> float:
            return float(np.median([r[key] for r in rs]))
        places: Counter[str] = Counter()
        for r in rs:
            places.update(r["room_places"])
        p = [r["account"][1] for r in rs]
        out.append(f"| {home}: {label} → {answer} | {len(rs)} | {float(np.median(p)):.3f} | "
                   f"{sum(q >= SURE for q in p)} | {med('p_room'):.2f} | {med('room_n'):.0f} | "
                   f"{dict(places)} | {med('p_concept_room'):.2f} | {med('room_margin'):.1f} | "
                   f"{med('view_margin'):.1f} | {med('name_share'):.3f} |")
    places_rows: dict[tuple[str, str], list[dict[str, Any]]] = defaultdict(list)
    for r in rows:
        places_rows[(r["home"], r["label"])].append(r)
    out += ["", "| home: place (answers) | " + " | ".join(VARIANTS) + " |",
            "|---" * (len(VARIANTS) + 1) + "|"]
    for (home, label), rs in sorted(places_rows.items()):
        cells = [f"{np.mean([r[k][1] for r in rs]):.2f} / {np.mean([r[k][0] == label for r in rs]):.2f}"
                 for k in VARIANTS]
        out.append(f"| {home}: {label} ({len(rs)}) | " + " | ".join(cells) + " |")
    return "\n".join(out)


def main(argv: Sequence[str] | None = None) -> None:
    """Parse the arguments, score the configuration's kept models, print the tables."""
    import spco.knowledge as kn

    parser = argparse.ArgumentParser(description=__doc__.split("\n", 1)[0])
    parser.add_argument("--data", type=Path, required=True)
    parser.add_argument("--images", type=Path, default=None)
    parser.add_argument("--models", type=Path, required=True, help="calibration.py's --out")
    parser.add_argument("--set", dest="set_name", default="development-new",
                        choices=("development", "development-new"))
    parser.add_argument("--features", default="colour-hog")
    parser.add_argument("--size", type=int, required=True)
    parser.add_argument("--first-seeds", type=int, default=3)
    args = parser.parse_args(argv)
    warnings.filterwarnings("ignore")
    rows: list[dict[str, Any]] = []
    for seed in SETS[args.set_name]["seeds"][: args.first_seeds]:
        for name in SETS[args.set_name]["homes"]:
            path = args.models / "models" / f"home_{args.features}_{args.size}_{seed}_{name}.spco"
            if not path.exists():
                raise SystemExit(f"error: --models: {path} is missing (run benchmarks/calibration.py first)")
            home = _load(args.data, args.images, [name], args.features, 0)[0]
            rows += score_home(home, kn.load_home_model(path), seed)
    print(f"{args.set_name}, {args.features}, {args.size} experienced homes, seeds "
          f"{list(SETS[args.set_name]['seeds'][: args.first_seeds])}: {len(rows)} answers\n")
    print(report(rows))


if __name__ == "__main__":
    main()
