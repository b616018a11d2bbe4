"""Why is `what` wrong *and* sure? The cause of every wrong answer at p ≥ 0.99, development views only.

Reads the models and answers of a ``benchmarks/calibration.py --sets development-new`` (or
``development``) run (``--models OUT``: its ``--out``) and puts each wrong answer given at p ≥ 0.99
into the first of these classes that fits (``benchmarks/calibration/SPLIT.md``: development views
only; a held-out run's rows are refused):

- ``mask``: the right name is not among the names the home answers (``HomeModel.name_mask``);
- ``merged``: the view's room — the home's training samples with the view's label — is, by the
  majority of its samples' concepts after ``adapt``, in a concept that also holds the majority of
  another room of the home: two rooms, one concept, and the concept is named for the other room;
- ``misnamed``: the room has a concept of its own, but that concept's name (p(name | concept), the
  answer's parameters) is not the room's;
- ``view``: the room's concept names it right, and the position alone answers right; the view
  overrides it (the view's weight);
- ``position``: the room's concept names it right, the view alone answers right, the position
  overrides it (the position term);
- ``other``: neither alone answers right.

Printed per configuration (features × experienced homes): the number of answers, of wrong answers,
of wrong answers at p ≥ 0.99, and their classes; then each merged room (home, room, the concept's
name, the rooms sharing it, seeds). Same seed, same result (nothing is sampled).

``--rooms`` prints instead, for every room of the answer (:meth:`spco.model.rooms.HomeRooms.membership`)
that holds at least ``--min-views`` samples of one label and whose own evidence names it wrong, what
the room alone says: its top name and p(name | room) (:func:`spco.model.rooms.room_concepts`, names
from the answer's θ^w), and the cross-entropy per draw −Σ_d v̂_d log φ^v_{l,d} of its pooled
proportions v̂ to the best concept, the second, the best concept named for the room's label, the
G_0-weighted mean of the used concepts' φ^v (G_0 ≥ 0.01) and the uniform (log D); then, per
configuration, the same cross-entropies' medians over the rooms named right (how far a room is from
its concept when it is answered right).

    python benchmarks/calibration_diagnose.py --data D/sigverse --images D/sigverse_images --models /tmp/cal
    python benchmarks/calibration_diagnose.py … --models /tmp/cal --rooms
"""

from __future__ import annotations

import argparse
import json
import sys
import warnings
from collections import Counter, defaultdict
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
import calibration as cal

CLASSES = ("mask", "merged", "misnamed", "view", "position", "other")


def _names(params: Any, mask: np.ndarray, words: list[str]) -> list[str]:
    """The name each concept answers (argmax of p(name | concept) over the home's names)."""
    theta = np.asarray(params.word_probabilities[0], dtype=np.float64) * mask[None, :]
    return [words[int(np.argmax(row))] if row.sum() > 0 else "-" for row in theta]


def diagnose_home(home: Any, model: Any) -> list[dict[str, Any]]:
    """Every scored view of ``home`` with the answer, its probability and its class (module docstring;
    ``cls`` is ``None`` for answers that are right or below p 0.99)."""
    from spco.knowledge.queries import answer_parameters, name_prediction

    positions, visual, labels, ids = cal.scored_views(home)
    params = answer_parameters(model)
    mask = np.asarray(model.name_mask, dtype=bool)
    words = list(model.vocabulary.words)
    concept_name = _names(params, mask, words)
    # each room's (label's) majority concept among the adapted home's training samples
    label_of = dict(zip(home.ids.tolist(), home.labels(), strict=True))
    room_concepts: dict[str, Counter] = defaultdict(Counter)
    for sample, concept in zip(model.ids.tolist(), np.asarray(model.state.concepts).tolist(), strict=True):
        if label_of.get(sample) is not None:
            room_concepts[label_of[sample]][int(concept)] += 1
    majority = {room: c.most_common(1)[0][0] for room, c in room_concepts.items()}
    full = name_prediction(model, positions, visual, top_k=1)
    alone_position = name_prediction(model, positions, None, top_k=1)
    from spco.model.prediction import predict_names

    alone_view = predict_names(params, 0, model.vocabulary, positions, visual, top_k=1,
                               weighting=model.weighting,  # type: ignore[arg-type]
                               use_position=False, view_counts=model.hyperparameters.view_weight())
    rows = []
    for i, label in enumerate(labels):
        answer, p = full.best[i], float(full.confidence[i])
        cls = None
        concept = majority.get(label)
        sharing = sorted(r for r, c in majority.items() if c == concept and r != label)
        if answer != label and p >= cal.SURE:
            if label not in words or not mask[words.index(label)]:
                cls = "mask"
            elif concept is not None and concept_name[concept] != label and sharing:
                cls = "merged"
            elif concept is not None and concept_name[concept] != label:
                cls = "misnamed"
            elif alone_position.best[i] == label:
                cls = "view"
            elif alone_view.best[i] == label:
                cls = "position"
            else:
                cls = "other"
        rows.append({"home": home.name, "view": int(ids[i]), "label": label, "answer": answer, "p": p,
                     "cls": cls, "room_concept": concept,
                     "room_concept_name": None if concept is None else concept_name[concept],
                     "sharing": sharing, "position_alone": alone_position.best[i],
                     "view_alone": alone_view.best[i]})
    return rows


def room_distances(home: Any, model: Any, min_views: int) -> list[dict[str, Any]]:
    """Each room of ``model`` (the answer's rooms) with at least ``min_views`` samples of one label of
    ``home``: the label, the room's own answer and its probability, and the cross-entropies per draw of
    its pooled views (module docstring, ``--rooms``)."""
    from spco.knowledge.queries import answer_inputs
    from spco.model.rooms import room_concepts

    params, rooms = answer_inputs(model)
    w = model.hyperparameters.view_weight()
    words = list(model.vocabulary.words)
    mask = np.asarray(params.word_mask, dtype=bool)
    theta = np.asarray(params.word_probabilities[0], dtype=np.float64) * mask[None, :]
    theta /= np.maximum(theta.sum(axis=1, keepdims=True), 1e-300)
    names = _names(params, mask, words)
    phi = np.asarray(params.shared_visual_probabilities, dtype=np.float64)
    g0 = np.asarray(params.global_concept_weights, dtype=np.float64)
    used = np.flatnonzero(g0 >= 0.01)
    mean_phi = (g0[used, None] * phi[used]).sum(axis=0) / g0[used].sum()
    _, posterior = room_concepts(params, 0, rooms, w)
    share, _ = rooms.membership(int(np.shape(params.region_means)[1]))
    label_of = dict(zip(home.ids.tolist(), home.labels(), strict=True))
    labels = [label_of.get(i) for i in model.ids.tolist()]
    onehot = share.copy()
    onehot.data[:] = 1.0
    pooled = np.asarray((onehot @ rooms.visual).toarray(), dtype=np.float64)
    rows = []
    for k in range(pooled.shape[0]):
        members = share.indices[share.indptr[k]:share.indptr[k + 1]]
        label, n = Counter(labels[j] for j in members).most_common(1)[0] if members.size else (None, 0)
        if label is None or n < min_views or pooled[k].sum() <= 0:
            continue
        v = pooled[k] / pooled[k].sum()
        cross = -(np.log(np.maximum(phi[used], 1e-300)) @ v)
        order = np.argsort(cross)
        own = [i for i in range(used.size) if names[used[i]] == label]
        p_names = posterior[k] @ theta
        rows.append({"home": home.name, "label": label, "views": int(n),
                     "answer": words[int(np.argmax(p_names))], "p": float(p_names.max()),
                     "best": names[used[order[0]]], "ce_best": float(cross[order[0]]),
                     "ce_second": float(cross[order[1]]) if used.size > 1 else float("nan"),
                     "ce_own": float(cross[own].min()) if own else float("nan"),
                     "ce_mean": float(-(np.log(np.maximum(mean_phi, 1e-300)) @ v)),
                     "ce_uniform": float(np.log(phi.shape[1]))})
    return rows


def _print_rooms(tasks: dict[tuple[str, int], list[tuple[int, str, Path]]], args: argparse.Namespace) -> None:
    """``--rooms``: the rooms named wrong by their own evidence, and the medians of the rooms named right."""
    import spco.knowledge as kn

    keys = ("ce_best", "ce_second", "ce_own", "ce_mean")
    for (features, size), items in sorted(tasks.items()):
        right: list[dict[str, Any]] = []
        print(f"{features}, {size} homes (cross-entropy per draw of a room's pooled views; uniform "
              f"= log D): room, its own answer, best / second / own label's / mean concept", flush=True)
        for seed, name, path in sorted(items):
            home = cal._load(args.data, args.images, [name], features, 0)[0]
            for r in room_distances(home, kn.load_home_model(path), args.min_views):
                if r["answer"] == r["label"]:
                    right.append(r)
                    continue
                print(f"    seed {seed} {name} {r['label']} ({r['views']} views): {r['answer']!r} at "
                      f"{r['p']:.3f}; " + " / ".join(f"{r[k]:.3f}" for k in keys)
                      + f" (uniform {r['ce_uniform']:.2f})")
        if right:
            print(f"    rooms named right ({len(right)}), medians: "
                  + " / ".join(f"{float(np.nanmedian([r[k] for r in right])):.3f}" for k in keys)
                  + "; best minus own label's is 0 for them")


def main(argv: Sequence[str] | None = None) -> None:
    """Print the table (module docstring)."""
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--data", type=Path, required=True)
    parser.add_argument("--images", type=Path, default=None)
    parser.add_argument("--models", type=Path, required=True, help="a calibration.py --out (development)")
    parser.add_argument("--json", type=Path, default=None, help="write every classified answer here")
    parser.add_argument("--rooms", action="store_true",
                        help="what each room's own evidence says, and how far its views are from the "
                             "concepts (module docstring)")
    parser.add_argument("--min-views", type=int, default=8,
                        help="--rooms: rooms with at least this many samples of one label")
    args = parser.parse_args(argv)
    warnings.filterwarnings("ignore")
    import spco.knowledge as kn

    found = sorted((args.models / "models").glob("home_*.spco"))
    tasks: dict[tuple[str, int], list[tuple[int, str, Path]]] = defaultdict(list)
    for path in found:
        # home names hold "_" (2LDK_3): the stem is home_<features>_<size>_<seed>_<home>
        parts = path.stem[len("home_"):].split("_")
        features, size, seed, home = parts[0], int(parts[1]), int(parts[2]), "_".join(parts[3:])
        if home in cal.SETS["held-out"]["homes"]:
            raise SystemExit(f"error: {path} is a held-out home; this diagnosis reads development views only")
        tasks[(features, size)].append((seed, home, path))
    if args.rooms:
        _print_rooms(tasks, args)
        return
    everything = []
    for (features, size), items in sorted(tasks.items()):
        counts: Counter = Counter()
        answers = wrong = 0
        merges: dict[tuple[str, str, str, tuple[str, ...]], list[int]] = defaultdict(list)
        for seed, name, path in sorted(items):
            home = cal._load(args.data, args.images, [name], features, 0)[0]
            rows = diagnose_home(home, kn.load_home_model(path))
            for r in rows:
                r.update({"features": features, "size": size, "seed": seed})
            everything += rows
            answers += len(rows)
            wrong += sum(r["answer"] != r["label"] for r in rows)
            for r in rows:
                if r["cls"] is not None:
                    counts[r["cls"]] += 1
                    if r["cls"] == "merged":
                        key = (name, r["label"], r["room_concept_name"], tuple(r["sharing"]))
                        if seed not in merges[key]:
                            merges[key].append(seed)
        sure = sum(counts.values())
        print(f"{features}, {size} homes: {answers} answers, {wrong} wrong, {sure} wrong at p >= 0.99: "
              + ", ".join(f"{c} {counts[c]}" for c in CLASSES), flush=True)
        for (name, room, said, sharing), seeds in sorted(merges.items()):
            print(f"    merged: {name} {room} answered {said!r} (its concept holds {', '.join(sharing)}), "
                  f"seeds {seeds}")
    if args.json is not None:
        args.json.write_text("\n".join(json.dumps(r) for r in everything) + "\n")


if __name__ == "__main__":
    main()
