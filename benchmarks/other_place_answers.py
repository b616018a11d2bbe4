"""Why a view answers another place's name (issue 28, classes b and c of ``benchmarks/speech_errors.py``;
branch classc18): a diagnosis of the development configurations of ``benchmarks/natural_speech.py``.

For each seed the fits of ``speech_errors.py`` (same trial seeds, sweeps, ``--set``, ``--cache``; with
``--leave-one-out`` as there) are scored as the robot answers (``evaluate_answers``). For every wrong answer
of class b or c (the answer is a name of another place) one row per view gives:

- the answer, the place(s) it names, its probability, and the best accepted name's probability and rank;
- the concept the view is drawn to (``l*``, the most probable of the answer's concept posterior,
  :func:`spco.model.confidence.answer_concepts`) and what it holds: its taught samples in the other homes
  by place (the share of the scored place and of the answer's place), its top answerable name (the
  answer's θ^w, names said at its places) and its names channel's own top name (``place_names=False``);
- the concept that names the place (``l_r``): of the concepts whose top answerable name is an accepted
  name of the place, the one holding most of the other homes' taught samples of the place (``None``: no
  concept's top name is one of the place's);
- the room the pose is in (the most probable room of the room account, :func:`spco.model.rooms`): its
  training samples' places (the share of the scored place) and concepts;
- the terms of l* against l_r in the room account (nats, positive: l* wins): the concept prior
  log G_0, the room's pooled views at w against φ^v (the most probable room's), and the view at w;
- the home's own training samples of the place: how many the sampler put in l* and in l_r;
- how often people say the answer, and the place's accepted names, in the place's sentences (the
  development homes' people, ``speech_errors.place_speech``).

Each view gets one cause (:func:`cause`), in this order:

- **i merge**: l*'s samples elsewhere hold both places, the scored one and the answer's (each at least
  :data:`HOLDS` of them): one concept for two rooms;
- **iv name share**: l*'s samples elsewhere are mostly of the scored place (at least 0.5): the right kind
  of concept, and the answer its names' mix (or the posterior's mix over concepts) chose;
- **ii region**: l* is another room's concept, and the room the pose is in holds mostly samples of
  another place (less than 0.5 of the scored place): the home's region spans two rooms, or the pose is
  placed in the next room;
- **iii view**: l* is another room's concept though the room at the pose is the scored place's: the
  room's pooled views, the view and the prior put it there (which of them leads: the largest of the
  three terms).

and a flag **v said**: people say the answer at this place at least as often as its best accepted name
(the scoring: what people call the place against the accepted names).

Development seeds only (0–99); seeds 0–4 were looked at. Run::

    nice -n 5 python benchmarks/other_place_answers.py --seeds 0 1 2 3 4 --sweeps 60 --leave-one-out \\
        --set place_channel=home --cache /tmp/fits --json /tmp/other_place.json
"""

from __future__ import annotations

import argparse
import json
import sys
from collections import Counter
from pathlib import Path

import numpy as np
from scipy.special import logsumexp

sys.path.insert(0, str(Path(__file__).resolve().parent))
from natural_speech import diagnosed, fit_arguments
from speech_errors import (
    CALLED_BUT_NOT_ACCEPTED,
    classify_answer,
    names_of,
    share_said,
)

from spco.data import Corpus
from spco.data.language import normalize_name
from spco.evaluation import evaluate_answers
from spco.model.confidence import answer_concepts, model_answer_parameters
from spco.model.prediction import _safe_log, _visual_log_likelihood, gaussian_log_density, validate_poses
from spco.model.rooms import _room_log_posterior

#: A concept holds a place (for the merge cause) when at least this share of its taught samples in the
#: other homes are of it.
HOLDS = 0.25

#: The causes, in the order :func:`cause` tries them.
CAUSES = ("i merge", "iv name share", "ii region", "iii view")


def cause(true_share: float, answer_share: float, room_true_share: float) -> str:
    """The cause of one wrong answer (the module's docstring): ``true_share`` and ``answer_share`` the
    shares of the answering concept's taught samples elsewhere that are of the scored place and of the
    answer's place, ``room_true_share`` the share of the scored place among the training samples of the
    room the pose is in."""
    if true_share >= HOLDS and answer_share >= HOLDS:
        return "i merge"
    if true_share >= 0.5:
        return "iv name share"
    if room_true_share < 0.5:
        return "ii region"
    return "iii view"


def concept_holdings(model, corpus: Corpus, e: int) -> list[Counter]:
    """Per concept, the places of the other homes' taught samples it holds (a Counter; samples with a
    label and a sentence)."""
    out = [Counter() for _ in range(model.parameters_.n_concepts)]
    for h, env in enumerate(corpus):
        if h == e:
            continue
        labels = [lab for lab, test in zip(env.ground_truth.labels, env.is_test, strict=True) if not test]
        for c, label, sentence in zip(model.concepts_[h], labels, env.training_data().sentences, strict=True):
            if label is not None and sentence is not None:
                out[int(c)][normalize_name(label)] += 1
    return out


def _room_terms(answer, rooms, e: int, positions: np.ndarray, visual, view_counts) -> tuple:
    """The room account's pieces at the poses: (n, R) log p(k | x) normalised, (R,) region of each room,
    (R, L) each room's pooled-views term (log G_0 removed), (n, L) the view's term, (L,) log G_0."""
    room_log, counts, region_of = _room_log_posterior(answer, rooms, view_counts, e)
    x = validate_poses(positions)
    log_n = gaussian_log_density(x, answer.region_means[e], answer.region_covariances[e])
    log_k = np.where(counts[None, :] > 0, log_n[:, region_of] + _safe_log(counts)[None, :], -np.inf)
    log_k = log_k - logsumexp(log_k, axis=1, keepdims=True)
    prior = _safe_log(np.asarray(answer.global_concept_weights, dtype=np.float64))
    phi_v = np.asarray(answer.shared_visual_probabilities, dtype=np.float64)
    view = _visual_log_likelihood(phi_v, visual, view_counts)
    return log_k, region_of, room_log - prior[None, :], view, prior


def _tops(theta: object, mask: np.ndarray) -> np.ndarray:
    """(L,) each concept's most probable answerable name (``theta`` (L, V), ``mask`` (V,) answerable)."""
    return np.argmax(np.where(mask[None, :], np.asarray(theta, dtype=np.float64), -1.0), axis=1)


def diagnose(model, corpus: Corpus, e: int, env, scored, seed: int, accepted: dict, said: dict,
             home: str) -> list[dict]:
    """One row per wrong class-b or class-c answer (a view) of home ``e`` (the module's docstring)."""
    scores = evaluate_answers(model, e, scored, rng=seed)
    answer, rooms, _ = model.answer_inputs(e)
    vocabulary = corpus.vocabulary
    view_counts = model.settings_.view_counts
    rows = np.flatnonzero(scored.is_test)
    positions, visual = env.positions[rows], env.visual[rows]
    posterior = answer_concepts(answer, e, positions, visual, view_counts=view_counts, rooms=rooms,
                                settings=model.hyperparameters_.answer_settings())
    theta = np.asarray(answer.word_probabilities, dtype=np.float64)[e]
    mask = np.asarray(answer.word_mask, dtype=bool)
    probs = np.where(mask[None, :], posterior @ theta, -1.0)
    tops = _tops(theta, mask)
    own_tops = _tops(model_answer_parameters(model, e, place_names=False).word_probabilities[e], mask)
    held = concept_holdings(model, corpus, e)
    log_k, region_of, room_views, view_term, prior = _room_terms(answer, rooms, e, positions, visual,
                                                                 view_counts)
    share, _ = rooms.membership(int(np.shape(answer.region_means)[1]))
    share = share.toarray()  # (R, n_train) each training sample's share in each room
    labels = [lab for lab, test in zip(env.ground_truth.labels, env.is_test, strict=True) if not test]
    train_places = np.array([normalize_name(lab) if lab else "" for lab in labels], dtype=object)
    train_concepts = np.asarray(rooms.concepts)
    places = {*accepted, *CALLED_BUT_NOT_ACCEPTED}
    out = []
    for i, (place, name) in enumerate(zip(scores.labels, scores.predicted_names, strict=True)):
        if place is None or name in env.ground_truth.accepted(place):
            continue
        place = normalize_name(place)
        cls = classify_answer(place, name, accepted, said)
        if cls not in ("b", "c"):
            continue
        owners = sorted(p for p in places if p != place and name in names_of(p, accepted))
        concept = int(np.argmax(posterior[i]))
        holds = held[concept]
        n_held = max(sum(holds.values()), 1)
        true_share = holds[place] / n_held
        answer_share = max(holds[p] for p in owners) / n_held
        names = [k for k in (vocabulary.index(n) for n in env.ground_truth.accepted(place))
                 if k is not None and mask[k]]
        right = [m for m in range(theta.shape[0]) if tops[m] in names]
        named = max(right, key=lambda m: held[m][place]) if right else None
        order = np.argsort(-probs[i], kind="stable")
        best = max(names, key=lambda k: probs[i, k]) if names else None
        room = int(np.argmax(log_k[i]))
        members = share[room] > 0
        room_places = Counter(train_places[members].tolist())
        n_room = max(sum(room_places.values()), 1)
        same = train_places == place
        terms = {"prior": 0.0, "room views": 0.0, "view": 0.0}
        if named is not None:
            terms = {"prior": float(prior[concept] - prior[named]),
                     "room views": float(room_views[room, concept] - room_views[room, named]),
                     "view": float(view_term[i, concept] - view_term[i, named])}
        accepted_said = max((share_said(said, place, n) for n in env.ground_truth.accepted(place)),
                            default=0.0)
        out.append({
            "seed": seed, "home": home, "place": place, "class": cls, "word": name, "owners": owners,
            "p_word": float(probs[i, vocabulary.index(name)]),
            "accepted": None if best is None else vocabulary.words[best],
            "p_accepted": 0.0 if best is None else float(probs[i, best]),
            "accepted_rank": None if best is None else int(np.flatnonzero(order == best)[0]) + 1,
            "concept": concept, "p_concept": float(posterior[i, concept]),
            "concept_top": vocabulary.words[int(tops[concept])],
            "concept_own_top": vocabulary.words[int(own_tops[concept])],
            "concept_places": ", ".join(f"{p} {n}" for p, n in holds.most_common(3)),
            "true_share": true_share, "answer_share": answer_share,
            "named": named, "p_named": 0.0 if named is None else float(posterior[i, named]),
            "room": room, "p_room": float(np.exp(log_k[i, room])), "room_region": int(region_of[room]),
            "room_places": ", ".join(f"{p or '-'} {n}" for p, n in room_places.most_common(3)),
            "room_true_share": room_places[place] / n_room,
            "place_samples": int(same.sum()),
            "place_in_concept": int((train_concepts[same] == concept).sum()),
            "place_in_named": 0 if named is None else int((train_concepts[same] == named).sum()),
            "terms": terms, "said_word": share_said(said, place, name), "said_accepted": accepted_said,
            "cause": cause(true_share, answer_share, room_places[place] / n_room),
            "said": share_said(said, place, name) >= accepted_said,
        })
    return out


def summary(rows: list[dict]) -> dict:
    """Views per class and cause, the flag v per class, and the leading term of cause iii."""
    table: dict = {cls: {c: 0 for c in CAUSES} for cls in ("b", "c")}
    for r in rows:
        table[r["class"]][r["cause"]] += 1
    flag = {cls: sum(r["said"] for r in rows if r["class"] == cls) for cls in ("b", "c")}
    lead = Counter(max(r["terms"], key=r["terms"].get) for r in rows
                   if r["cause"] == "iii view" and r["named"] is not None)
    return {"causes": table, "v said": flag, "iii leading term": dict(lead),
            "no naming concept": sum(r["named"] is None for r in rows)}


def _print(rows: list[dict]) -> None:
    """One line per (seed, home, place, answer, concept) with its number of views, then the summary."""
    groups: dict[tuple, list[dict]] = {}
    for r in rows:
        key = (r["seed"], r["home"], r["place"], r["word"], r["concept"], r["cause"])
        groups.setdefault(key, []).append(r)
    print("| seed | home | place | cls | views | answer (p) | accepted (p, rank) | "
          "concept (p) [top; own top] | its samples elsewhere | naming concept (p) | "
          "room at pose (p): its samples | "
          "place's samples in concept / naming | prior / room views / view (nats) | "
          "said answer / accepted | cause |")
    print("|---|---|---|---|---:|---|---|---|---|---|---|---|---|---|---|")
    for (seed, home, place, word, concept, why), group in groups.items():
        r = group[0]
        t = {k: np.mean([g["terms"][k] for g in group]) for k in r["terms"]}
        print(f"| {seed} | {home} | {place} | {r['class']} | {len(group)} | "
              f"{word} ({np.mean([g['p_word'] for g in group]):.2f}) | "
              f"{r['accepted']} ({r['p_accepted']:.2f}, {r['accepted_rank']}) | "
              f"{concept} ({np.mean([g['p_concept'] for g in group]):.2f}) [{r['concept_top']}; "
              f"{r['concept_own_top']}] | "
              f"{r['concept_places']} | {r['named']} ({max(g['p_named'] for g in group):.2f}) | "
              f"{r['room']} ({np.mean([g['p_room'] for g in group]):.2f}): {r['room_places']} | "
              f"{r['place_in_concept']}/{r['place_samples']} / {r['place_in_named']} | "
              f"{t['prior']:+.1f} / {t['room views']:+.1f} / {t['view']:+.1f} | "
              f"{r['said_word']:.2f} / {r['said_accepted']:.2f} | {why}{' v' if r['said'] else ''} |")
    print(f"\nviews: {len(rows)}; {json.dumps(summary(rows))}")


def main() -> None:
    """Read (or fit) the fits, diagnose each class-b and class-c answer; print the table, write ``--json``."""
    parser = fit_arguments(argparse.ArgumentParser(description=__doc__.splitlines()[0]))
    args, rows = diagnosed(parser, diagnose, "class-b/c")
    _print(rows)
    if args.json:
        args.json.write_text(json.dumps({"rows": rows, "summary": summary(rows)}, indent=0), encoding="utf-8")


if __name__ == "__main__":
    main()
