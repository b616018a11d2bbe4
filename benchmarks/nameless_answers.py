"""Why a view answers a word that is no place's name (issue 28, class a of ``benchmarks/speech_errors.py``;
branch nameless16): a diagnosis of the development configurations of ``benchmarks/natural_speech.py``.

For each seed the fits of ``speech_errors.py`` (same trial seeds, sweeps, ``--set``, ``--cache``; with
``--leave-one-out`` as there) are scored as the robot answers (``evaluate_answers``). For every wrong answer
of class a (a1: the concept's taught samples in the other homes say the place's name; a2: they do not) one
row per (seed, home, place, word, concept) gives:

- the views, the answer's probability and the second answer (with its probability), and the best accepted
  name's probability and rank;
- the concept the view is drawn to (the answer's concept posterior,
  :func:`spco.model.confidence.answer_concepts`) and its probability;
- the concept's expected name tokens: in this home (its own, ``concept_name_tokens``), its own samples' in
  the other homes, and the names said at its places over the other homes (``place_names``, the answer's
  P_l) — the answered word's and the accepted names' share of it, and the number of other homes that say
  the word there (at least 0.5 expected tokens);
- whether the right name is held by another concept of the same room: the concepts whose top answerable
  name is an accepted name of the place ("right" concepts), their posterior at the view, and how many of
  this home's training samples of the place (and of the regions they fill) are in a right concept rather
  than in the answering one.

Development seeds only (0–99); seeds 0–4 were looked at on nameless16. Run::

    nice -n 5 python benchmarks/nameless_answers.py --seeds 0 1 2 3 4 --sweeps 60 --leave-one-out \\
        --cache /tmp/fits --json /tmp/nameless.json
"""

from __future__ import annotations

import argparse
import json
import sys
from collections import Counter
from pathlib import Path

import numpy as np
import scipy.sparse as sp

sys.path.insert(0, str(Path(__file__).resolve().parent))
from natural_speech import diagnosed, fit_arguments
from speech_errors import (
    NAMED,
    classify_answer,
    named_share,
    names_of,
)

from spco.data import Corpus
from spco.data.language import normalize_name
from spco.evaluation import evaluate_answers
from spco.model.confidence import answer_concepts
from spco.model.unheard import stand_in_columns
from spco.model.word_channels import concept_name_tokens, place_names

#: A home says a word at a concept's places when it holds at least this many of its expected tokens there.
SAYS = 0.5


def _home_tokens(model, e: int, stand_ins: np.ndarray, n_concepts: int) -> tuple[np.ndarray, np.ndarray,
                                                                                   np.ndarray]:
    """(own here, own elsewhere, per other home's places) expected name tokens: (L, V), (L, V), (H, L, V)."""
    data, state = model.data_, model.state_
    homes = np.asarray(data.homes)
    here = slice(int(data.offsets[e]), int(data.offsets[e + 1]))
    others = np.flatnonzero(homes != e)
    own = concept_name_tokens(sp.csr_array(data.words[here]), homes[here], state.concepts[here],
                              state.log_theta_w, state.channels, n_concepts)
    elsewhere = concept_name_tokens(sp.csr_array(data.words[others]), homes[others], state.concepts[others],
                                    state.log_theta_w, state.channels, n_concepts)
    per_home = np.stack([place_names(data.words, homes, state.concepts, state.regions, state.log_theta_w,
                                     state.channels, n_concepts, rows=np.flatnonzero(homes == h),
                                     stand_ins=stand_ins) for h in range(e)])
    return own, elsewhere, per_home


def concept_places(model, corpus: Corpus, e: int, concept: int, accepted: dict) -> tuple[str, float]:
    """The places of the other homes' taught samples in ``concept`` (the three most frequent, with
    their counts) and the share of those samples whose sentence says a name of its own place."""
    places: Counter = Counter()
    named = total = 0
    for h, env in enumerate(corpus):
        if h == e:
            continue
        labels = [lab for lab, test in zip(env.ground_truth.labels, env.is_test, strict=True) if not test]
        sentences = env.training_data().sentences
        for c, label, sentence in zip(model.concepts_[h], labels, sentences, strict=True):
            if c != concept or sentence is None or label is None:
                continue
            place = normalize_name(label)
            places[place] += 1
            total += 1
            named += bool(names_of(place, accepted) & set(corpus.vocabulary.tokenize(sentence)))
    top = ", ".join(f"{p} {n}" for p, n in places.most_common(3))
    return top, named / total if total else 0.0


def diagnose(model, corpus: Corpus, e: int, env, scored, seed: int, accepted: dict, said: dict,
             home: str) -> list[dict]:
    """One row per wrong class-a answer (a view) of home ``e`` (see the module's docstring)."""
    scores = evaluate_answers(model, e, scored, rng=seed)
    answer, rooms, _ = model.answer_inputs(e)
    vocabulary = corpus.vocabulary
    rows = np.flatnonzero(scored.is_test)
    posterior = answer_concepts(answer, e, env.positions[rows], env.visual[rows],
                                view_counts=model.settings_.view_counts, rooms=rooms,
                                settings=model.hyperparameters_.answer_settings())
    theta = np.asarray(answer.word_probabilities, dtype=np.float64)[e]
    mask = np.asarray(answer.word_mask, dtype=bool)
    probs = np.where(mask[None, :], posterior @ theta, -1.0)
    n_concepts = theta.shape[0]
    stand_ins = stand_in_columns(model.vocabulary_, model.state_.channels.name_prior())
    own, elsewhere, per_home = _home_tokens(model, e, stand_ins, n_concepts)
    at_places = per_home.sum(axis=0)
    tops = np.argmax(np.where(mask[None, :], theta, -1.0), axis=1)
    here = slice(int(model.data_.offsets[e]), int(model.data_.offsets[e + 1]))
    train_concepts = np.asarray(model.state_.concepts[here])
    train_regions = np.asarray(model.state_.regions[here])
    train_places = [normalize_name(lab) if lab else None
                    for lab, test in zip(env.ground_truth.labels, env.is_test, strict=True) if not test]
    out = []
    for i, (place, name) in enumerate(zip(scores.labels, scores.predicted_names, strict=True)):
        if place is None or name in env.ground_truth.accepted(place):
            continue
        place = normalize_name(place)
        if classify_answer(place, name, accepted, said) != "a":
            continue
        concept = int(np.argmax(posterior[i]))
        share = named_share(model, corpus, e, concept, place, accepted)
        held, named = concept_places(model, corpus, e, concept, accepted)
        names = [k for k in (vocabulary.index(n) for n in env.ground_truth.accepted(place))
                 if k is not None and mask[k]]
        word = vocabulary.index(name)
        order = np.argsort(-probs[i], kind="stable")
        best = max(names, key=lambda k: probs[i, k]) if names else None
        right = [m for m in range(n_concepts) if tops[m] in names]
        same = np.array([p == place for p in train_places], dtype=bool)
        in_room = np.isin(train_regions, np.unique(train_regions[same]))
        out.append({
            "seed": seed, "home": home, "place": place, "class": "a2" if share < NAMED else "a1",
            "word": name, "p_word": float(probs[i, word]),
            "second": vocabulary.words[order[1]], "p_second": float(probs[i, order[1]]),
            "accepted": None if best is None else vocabulary.words[best],
            "p_accepted": 0.0 if best is None else float(probs[i, best]),
            "accepted_rank": None if best is None else int(np.flatnonzero(order == best)[0]) + 1,
            "concept": concept, "p_concept": float(posterior[i, concept]), "named_share": share,
            "concept_places": held, "concept_named": named,
            "tokens_here": float(own[concept].sum()), "tokens_elsewhere": float(elsewhere[concept].sum()),
            "places_tokens": float(at_places[concept].sum()), "places_word": float(at_places[concept, word]),
            "places_accepted": float(at_places[concept, names].sum()) if names else 0.0,
            "homes_word": int((per_home[:, concept, word] >= SAYS).sum()),
            "homes_accepted": int((per_home[:, concept][:, names].sum(axis=1) >= SAYS).sum()) if names else 0,
            "right_concepts": right, "p_right": float(posterior[i, right].sum()) if right else 0.0,
            "place_samples": int(same.sum()),
            "place_in_concept": int((train_concepts[same] == concept).sum()),
            "place_in_right": int(np.isin(train_concepts[same], right).sum()),
            "room_samples": int(in_room.sum()),
            "room_in_right": int(np.isin(train_concepts[in_room], right).sum()),
        })
    return out


def _print(rows: list[dict]) -> None:
    """The table: one line per (seed, home, place, class, word, concept), with its number of views."""
    groups: dict[tuple, list[dict]] = {}
    for r in rows:
        key = (r["seed"], r["home"], r["place"], r["class"], r["word"], r["concept"])
        groups.setdefault(key, []).append(r)
    print("| seed | home | place | cls | views | answer (p) | 2nd (p) | accepted (p, rank) | concept (p) | "
          "name tokens here / own elsewhere / at its places | word / accepted at its places (homes) | "
          "right concepts (p) | place's samples in concept / in right | room's in right | "
          "concept's samples elsewhere (named own place) |")
    print("|---|---|---|---|---:|---|---|---|---|---|---|---|---|---|---|")
    for (seed, home, place, cls, word, concept), group in groups.items():
        r = group[0]
        p_word = np.mean([g["p_word"] for g in group])
        p_concept = np.mean([g["p_concept"] for g in group])
        p_right = max(g["p_right"] for g in group)
        print(f"| {seed} | {home} | {place} | {cls} | {len(group)} | {word} ({p_word:.2f}) | "
              f"{r['second']} ({r['p_second']:.2f}) | "
              f"{r['accepted']} ({r['p_accepted']:.2f}, {r['accepted_rank']}) | "
              f"{concept} ({p_concept:.2f}) | {r['tokens_here']:.1f} / "
              f"{r['tokens_elsewhere']:.1f} / {r['places_tokens']:.1f} | "
              f"{r['places_word']:.1f} ({r['homes_word']}) / "
              f"{r['places_accepted']:.1f} ({r['homes_accepted']}) | {r['right_concepts']} ({p_right:.2f}) | "
              f"{r['place_in_concept']}/{r['place_samples']} / {r['place_in_right']} | "
              f"{r['room_in_right']}/{r['room_samples']} | "
              f"{r['concept_places']} ({r['concept_named']:.2f}) |")
    print(f"\nviews: {len(rows)} ({dict(Counter(r['class'] for r in rows))})")


def main() -> None:
    """Read (or fit) the fits, diagnose every class-a answer, print the table, write ``--json``."""
    parser = fit_arguments(argparse.ArgumentParser(description=__doc__.splitlines()[0]))
    args, rows = diagnosed(parser, diagnose, "class-a")
    _print(rows)
    if args.json:
        args.json.write_text(json.dumps(rows, indent=0), encoding="utf-8")


if __name__ == "__main__":
    main()
