"""Where the natural-speech errors come from (issue 28): every wrong ``what`` and every missed ``where``
of the development configuration of ``benchmarks/natural_speech.py``, classified.

The fits and the scores are those of ``natural_speech.py`` (same configurations, seeds, trial seeds
and scoring: the names the robot answers, ``model_answer_parameters``; ``--fit-parameters`` scores
the fit's parameters instead, every word answerable; development side only: the script has no
held-out configuration and refuses seeds outside 0–99 and 200–399). Each wrong answer
(A_n: a test view whose top name is not an accepted name of its place) and each missed ``where``
(A_p: an accepted name the vocabulary holds whose positions fall outside its place's region, score
below 0.5) is put in one class:

- **a** the answer is not a name of any place (an object, an activity, a function word, a fragment;
  what people call another place, :data:`CALLED_BUT_NOT_ACCEPTED`, is that place's name):
  the word model; split by the concept the view is drawn to (its most probable): **a1** its taught
  samples say the place's name (at least :data:`NAMED` of them: the names channel chose another
  word over the name people said), **a2** they do not (a *nameless* concept: the sampler put the
  samples whose people named the place in another concept than those whose people named only
  what is there, and the view went to the latter; its names channel holds whatever of its few
  tokens were drawn as names);
- **b** the answer is a name of another place that people do say at this place (in at least
  :data:`SAID_HERE` of the place's sentences of the development homes' people): what the speech supports;
- **c** the answer is a name of another place that people do not say here: the view or position
  went to the other place's concept, or the two places share a concept (transfer / clustering);
- **d** (A_p) the accepted name is not a name of any concept: never said by people, or said but
  drawn as a place or background word (the home's names, ``home_shard.name_words``);
- **e** the answer is what people call the place but the accepted-names file lacks it (an owner's
  room, "taro's room", or a misspelling: the file deliberately accepts no typos; it was written
  before any output and is not edited here). Which words are so is the table :data:`CALLED_BUT_NOT_ACCEPTED`,
  written by reading the subject sentences, not the outputs.

A_p misses are classified d (not a name), b (people say the name most at another place) or c.

Run (development, small)::

    nice -n 5 python benchmarks/speech_errors.py --seeds 0 1 --sweeps 60 --leave-one-out \\
        --json /tmp/speech_errors.json
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from collections import Counter, defaultdict
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from free_speech import read_names
from natural_speech import configurations, fit_arguments, fitted_runs, place_speech
from split_seeds import refuse_other_seeds

from spco.data import Corpus, Environment
from spco.data.language import normalize_name
from spco.evaluation import evaluate_answers, evaluate_home
from spco.evaluation.metrics import position_accuracy
from spco.model.answer_settings import AnswerSettings
from spco.model.home_shard import name_words, switch_tokens
from spco.model.position_prediction import predict_positions
from spco.model.prediction import UnknownNameError, concept_posterior

#: A name of another place counts as said here (class b) when at least this share of the place's
#: sentences (the development homes' people) hold it.
SAID_HERE = 0.05

#: What people call a place that the accepted-names file does not accept (class e), from reading the
#: subject sentences of the development homes: misspellings and one-word spellings of the names.
CALLED_BUT_NOT_ACCEPTED: dict[str, frozenset[str]] = {
    "living room": frozenset({"livingroom"}),  # 15 of the place's 160 sentences
    "bedroom": frozenset({"taro's room", "hanako's room", "taniguchi's room"}),  # the owners' rooms
    "bath": frozenset({"bath tub"}),  # "bathtub" in two words (12 sentences)
    "toilet": frozenset({"toiklet", "toiket"}),
}


def share_said(said: dict[str, Counter], place: str, word: str) -> float:
    """The share of ``place``'s sentences that hold ``word``."""
    c = said.get(place)
    return c[word] / c[""] if c and c[""] else 0.0


def classify_answer(place: str, word: str, accepted: dict[str, tuple[str, ...]],
                    said: dict[str, Counter]) -> str:
    """The class (a, b, c, e) of the wrong answer ``word`` at a view of ``place``."""
    if word in CALLED_BUT_NOT_ACCEPTED.get(place, frozenset()):
        return "e"
    # what people call another place counts as its name ("taro's room" is the bedroom's, class b or c)
    places = {*accepted, *CALLED_BUT_NOT_ACCEPTED}
    others = [p for p in places if p != place and word in names_of(p, accepted)]
    if not others:
        return "a"
    return "b" if share_said(said, place, word) >= SAID_HERE else "c"


#: A concept is nameless for a place (class a2) when fewer than this share of the taught samples it
#: holds say a name of the place (accepted, or :data:`CALLED_BUT_NOT_ACCEPTED`).
NAMED = 0.1


def names_of(place: str, accepted: dict[str, tuple[str, ...]]) -> set[str]:
    """What people may call ``place`` (normalised): its accepted names and :data:`CALLED_BUT_NOT_ACCEPTED`."""
    return set(accepted.get(place, ())) | CALLED_BUT_NOT_ACCEPTED.get(place, frozenset())


def training_places(env: Environment, vocabulary, accepted: dict[str, tuple[str, ...]]
                    ) -> list[tuple[str | None, bool | None]]:
    """(place, whether its sentence says a name of it) of every training sample of ``env``, in the
    fit's order: the place ``None`` for a sample without a label, the second ``None`` for a sample
    without a sentence."""
    labels = [label for label, test in zip(env.ground_truth.labels, env.is_test, strict=True) if not test]
    out: list[tuple[str | None, bool | None]] = []
    for label, sentence in zip(labels, env.training_data().sentences, strict=True):
        place = normalize_name(label) if label else None
        names = names_of(place, accepted) if place else set()
        out.append((place, None if sentence is None else bool(names & set(vocabulary.tokenize(sentence)))))
    return out


def named_share(model, corpus: Corpus, e: int, concept: int, place: str,
                accepted: dict[str, tuple[str, ...]]) -> float:
    """The share of the taught samples of the other homes in ``concept`` whose sentence says a name
    of ``place``."""
    names = names_of(normalize_name(place), accepted)
    said = total = 0
    for h, env in enumerate(corpus):
        if h == e:
            continue
        concepts = model.concepts_[h]
        for c, sentence in zip(concepts, env.training_data().sentences, strict=True):
            if c != concept or sentence is None:
                continue
            total += 1
            said += bool(names & set(corpus.vocabulary.tokenize(sentence)))
    return said / total if total else 0.0


def classify_miss(place: str, name: str, k: int | None, names_mask: np.ndarray,
                  said: dict[str, Counter]) -> str:
    """The coarse class (b, c, d) of the missed ``where name`` of ``place``: d not a name of the home,
    b people say the name most at another place, c the rest (:func:`where_miss_class` splits them)."""
    if k is None or not names_mask[k]:
        return "d"
    shares = {p: share_said(said, p, name) for p in said}
    best = max(shares, key=shares.get)
    return "b" if best != place and shares[best] > 0 else "c"


class NearestAreas:
    """A home's places as the areas nearest its labelled samples (each point belongs to the place of
    the nearest training sample, a Voronoi partition of the map): the ``where`` of a development home
    held out of the knowledge, which has no drawn regions (``--where-out``). Duck-types
    :class:`spco.data.regions.PlaceRegions` for :func:`spco.evaluation.metrics.position_accuracy`."""

    def __init__(self, xy: np.ndarray, labels: list[str | None]) -> None:
        keep = np.array([label is not None for label in labels], dtype=bool)
        self.xy = np.asarray(xy, dtype=np.float64)[keep, :2]
        self.labels = np.array([normalize_name(label) for label in labels if label is not None], dtype=object)
        self.places = dict.fromkeys(self.labels.tolist())

    def nearest(self, xy: np.ndarray) -> np.ndarray:
        """(n,) the place of the labelled sample nearest each point of ``xy`` (n, 2)."""
        xy = np.asarray(xy, dtype=np.float64)[:, :2]
        d2 = ((xy[:, None, :] - self.xy[None, :, :]) ** 2).sum(axis=2)
        return self.labels[np.argmin(d2, axis=1)]

    def contains(self, place: str, xy: np.ndarray) -> np.ndarray:
        """Whether the labelled sample nearest each point of ``xy`` is of ``place`` (NaN: outside)."""
        xy = np.asarray(xy, dtype=np.float64)
        inside = np.zeros(len(xy), dtype=bool)
        ok = np.isfinite(xy[:, :2]).all(axis=1)
        if ok.any():
            inside[ok] = self.nearest(xy[ok]) == normalize_name(place)
        return inside


#: The fine classes of a missed ``where`` (:func:`where_miss_class`), in the table's order.
WHERE_CLASSES = ("not a name", "shared name", "other concept", "one concept, two places", "region spills",
                 "empty region")


def place_of_samples(regions, place_names: list[str], xy: np.ndarray) -> np.ndarray:
    """(n,) the place holding each position of ``xy`` (n, 2): the smallest of the places whose area
    holds it (a room inside "bedroom" is the room), ``""`` for none; with :class:`NearestAreas` the
    nearest labelled sample's place."""
    if isinstance(regions, NearestAreas):
        return regions.nearest(xy)
    areas = {p: sum((r[1] - r[0]) * (r[3] - r[2]) for r in np.asarray(regions.places[p]).reshape(-1, 4))
             for p in place_names}
    out = np.full(len(xy), "", dtype=object)
    for p in sorted(place_names, key=areas.get, reverse=True):  # smaller places overwrite larger ones
        out[regions.contains(p, xy)] = p
    return out


def where_miss_class(place: str, name: str, accepted: dict[str, tuple[str, ...]], is_name: bool,
                     region: int, sample_regions: np.ndarray, sample_concepts: np.ndarray,
                     sample_places: np.ndarray) -> str:
    """The fine class of the missed ``where name`` of ``place`` (one of :data:`WHERE_CLASSES`):

    - **not a name**: the name is no name of any concept of the home (never said, or drawn as a
      place or background word);
    - **empty region**: the region ``where`` chose holds no training sample of the home;
    - **shared name**: the accepted names of the place whose samples fill that region hold it too,
      and that place is not this one;
    - **other concept**: the region's samples are mostly of a concept other than the one most of the
      place's samples are in (the name was learnt for another place's concept);
    - **one concept, two places**: the region's samples are of the place's own concept, but mostly of
      another place: one concept holds both, and ``where`` chose the other's region;
    - **region spills**: the region's samples are of the place and its concept, but fewer than half
      of the poses drawn from its Gaussian fall inside the place's area.

    ``sample_regions``, ``sample_concepts``, ``sample_places``: the home's training samples' region,
    concept (the sampler's state) and place (:func:`place_of_samples`)."""
    if not is_name:
        return "not a name"
    in_region = sample_regions == region
    if not in_region.any():
        return "empty region"
    region_places = Counter(sample_places[in_region])
    landed = region_places.most_common(1)[0][0]
    if landed not in (place, "") and name in accepted.get(landed, ()):
        return "shared name"
    here = sample_places == place
    own = Counter(sample_concepts[here]).most_common(1)[0][0] if here.any() else -1
    if Counter(sample_concepts[in_region]).most_common(1)[0][0] != own:
        return "other concept"
    return "one concept, two places" if landed != place else "region spills"


def _parser() -> argparse.ArgumentParser:
    """The command line."""
    parser = fit_arguments(argparse.ArgumentParser(description=__doc__.splitlines()[0]))
    parser.add_argument("--leave-one-out", action="store_true")
    parser.add_argument("--homes", nargs="*", default=None,
                        help="only these configurations (3LDK_9, or a development home held out)")
    parser.add_argument("--fit-parameters", action="store_true",
                        help="score the names of the fit's parameters (every word answerable) instead of "
                        "the names the robot answers (the home's names, model_answer_parameters, as "
                        "natural_speech.py and spco experiment)")
    parser.add_argument("--where-out", action="store_true",
                        help="also score the where of each development home held out of the knowledge "
                        "(--leave-one-out), which has no drawn regions, against the areas nearest its "
                        "labelled training samples (NearestAreas); reported apart from 3LDK_9's regions")
    parser.add_argument("--view-in-room", action="store_true",
                        help="answer names with the room account's view as a draw of its room "
                        "(AnswerSettings(view_in_room=True), evaluate_answers' override; the opt-in of "
                        "docs/model.md, \"Opt-in: the view "
                        "as a draw of its room\"); the fits and the where are unchanged")
    parser.add_argument("--json", type=Path, default=None)
    return parser


def _answers(model, corpus: Corpus, e: int, env: Environment, scored: Environment, scores,
             accepted: dict, said: dict, out: Counter, words: Counter, home: str) -> None:
    """Classify the wrong answers of one fit into ``out`` (class counts) and ``words``."""
    rows = np.flatnonzero(scored.is_test)
    posterior = concept_posterior(model.parameters_, e, env.positions[rows], env.visual[rows], True, True,
                                  view_counts=model.settings_.view_counts)
    gt = env.ground_truth
    for place, name, view in zip(scores.labels, scores.predicted_names, posterior, strict=True):
        if place is None or name in gt.accepted(place):
            continue
        cls = classify_answer(normalize_name(place), name, accepted, said)
        if cls == "a":  # a nameless concept, or a concept whose people name the place
            share = named_share(model, corpus, e, int(np.argmax(view)), place, accepted)
            cls = "a2" if share < NAMED else "a1"
        out[f"A_n {cls}"] += 1
        words[f"A_n {cls}"][f"{home}: {place} -> {name}"] += 1
    out["A_n views"] += sum(p is not None for p in scores.labels)


def _misses(model, corpus: Corpus, e: int, env: Environment, scores, said: dict, seed: int, out: Counter,
            words: Counter, home: str, accepted: dict, where_out: bool = False) -> None:
    """Classify the missed ``where`` of one fit (homes with regions) into ``out`` and ``words``: the
    coarse classes (d, b, c) and the fine ones (:func:`where_miss_class`). ``where_out``: a home
    without drawn regions is scored against the areas nearest its labelled samples
    (:class:`NearestAreas`)."""
    gt = env.ground_truth
    areas = gt.regions
    if areas is None and where_out:
        train = ~env.is_test
        areas = NearestAreas(env.positions[train], [lab for lab, t in zip(gt.labels, train, strict=True)
                                                    if t])
    if areas is None:
        return
    mask = name_words(switch_tokens(model.data_, model.state_))
    # the robot's where, as evaluate_answers scores it (one p(pose | name): the answer's names and rooms)
    answer, rooms, _ = model.answer_inputs(e)
    places = [normalize_name(p) for p in areas.places]
    sample_places = place_of_samples(areas, places, env.training_data().positions[:, :2])
    for place in scores.places:
        if place not in areas.places:
            continue
        names = [n for i, n in enumerate(gt.accepted(place))
                 if i == 0 or corpus.vocabulary.index(n) is not None]
        if len(names) > 1 and corpus.vocabulary.index(place) is None:
            names = names[1:]
        for name in names:
            pred = None
            try:
                pred = predict_positions(answer, e, corpus.vocabulary, name, n=10, rng=seed, unheard=False,
                                         rooms=rooms, view_counts=model.settings_.view_counts,
                                         lookup=model.parameters_.word_mask)
                score = position_accuracy({place: pred.samples}, areas)[place]
            except UnknownNameError:
                score = 0.0
            out["A_p names"] += 1
            out["A_p hits"] += score >= 0.5
            if score < 0.5:
                k = corpus.vocabulary.index(name)
                cls = classify_miss(normalize_name(place), name, k, mask, said)
                out[f"A_p {cls}"] += 1
                words[f"A_p {cls}"][f"{home}: where {name} ({place})"] += 1
                is_name = pred is not None and k is not None and bool(mask[k])
                fine = where_miss_class(normalize_name(place), name, accepted, is_name,
                                        -1 if pred is None else pred.region, rooms.regions, rooms.concepts,
                                        sample_places)
                out[f"where {fine}"] += 1
                there = Counter() if pred is None else Counter(sample_places[rooms.regions == pred.region])
                landed = "nothing" if pred is None else (there.most_common(1) or [("no sample",)])[0][0]
                words[f"where {fine}"][f"{home}: where {name} ({place}) -> {landed or 'no place'}"] += 1


CLASSES = ("A_n a1", "A_n a2", "A_n b", "A_n c", "A_n e", "A_p d", "A_p b", "A_p c")


def _print_table(table: dict[str, Counter], words: dict[str, Counter], runs: list[dict],
                 seeds: list[int]) -> None:
    """The table of classes per home, the mean A_n per seed, and the errors with their words."""
    print("\n| home | views | " + " | ".join(CLASSES) + " | A_p names |")
    print("|---|---:|" + "---:|" * len(CLASSES) + "---:|")
    total: Counter = Counter()
    for home, c in table.items():
        total.update(c)
        print(f"| {home} | {c['A_n views']} | " + " | ".join(str(c[k]) for k in CLASSES)
              + f" | {c['A_p names']} |")
    print(f"| all | {total['A_n views']} | " + " | ".join(str(total[k]) for k in CLASSES)
          + f" | {total['A_p names']} |")
    per_seed = [np.mean([r["A_n"] for r in runs if r["seed"] == s]) for s in seeds]
    print(f"\nA_n, mean over the configurations, per seed: {np.round(per_seed, 3).tolist()}, "
          f"mean {np.mean(per_seed):.3f}")
    for cls in CLASSES:
        if words[cls]:
            print(f"\n{cls}: {dict(words[cls].most_common(25))}")
    fine = [f"where {c}" for c in WHERE_CLASSES]
    print("\n| home | A_p names | missed | " + " | ".join(WHERE_CLASSES) + " |")
    print("|---|---:|---:|" + "---:|" * len(WHERE_CLASSES))
    out: Counter = Counter()
    for home, c in table.items():
        if c["A_p names"]:
            print(f"| {home} | {c['A_p names']} | {sum(c[k] for k in fine)} | "
                  + " | ".join(str(c[k]) for k in fine) + " |")
            if home != "3LDK_9":
                out.update(c)
    if out["A_p names"]:
        print(f"| homes out (nearest-sample areas) | {out['A_p names']} | {sum(out[k] for k in fine)} | "
              + " | ".join(str(out[k]) for k in fine) + " |")
    for cls in fine:
        if words[cls]:
            print(f"\n{cls}: {dict(words[cls].most_common(25))}")


def main() -> None:
    """Fit, score, classify; print the table per home and the errors with their words."""
    parser = _parser()
    args = parser.parse_args()
    refuse_other_seeds(parser, args.seeds)
    if args.view_in_room and args.fit_parameters:
        parser.error("--view-in-room: the room account's answer, not with --fit-parameters (no rooms)")
    accepted = read_names(args.accepted)
    knowledge, configs = configurations(args.sigverse, accepted, args.leave_one_out)
    labels = [c[0] for c in configs]  # natural_speech.py's order: the trial seed's index
    if args.homes:
        configs = [c for c in configs if c[0].split()[0] in args.homes]
    table: dict[str, Counter] = defaultdict(Counter)
    words: dict[str, Counter] = defaultdict(Counter)
    runs = []
    started = time.perf_counter()
    fits = fitted_runs(configs, labels, args.seeds, settings=args.set, sweeps=args.sweeps, cache=args.cache)
    for seed, label, env, corpus, model, e, scored in fits:
        if args.fit_parameters:  # the fit's own parameters, MI weighting (a diagnosis, not an answer)
            view_counts = model.settings_.view_counts
            scores = evaluate_home(model.parameters_, e, scored, corpus.vocabulary, rng=seed,
                                   **({} if view_counts is None else {"view_counts": view_counts}))
        else:  # as the robot answers
            override = AnswerSettings(view_in_room=True) if args.view_in_room else None
            scores = evaluate_answers(model, e, scored, rng=seed, settings=override)
        said = place_speech(knowledge, corpus)  # every development home's people
        home = label.split()[0]
        hits, asked = table[home]["A_p hits"], table[home]["A_p names"]
        _answers(model, corpus, e, env, scored, scores, accepted, said, table[home], words, home)
        _misses(model, corpus, e, env, scores, said, seed, table[home], words, home, accepted,
                args.where_out)
        runs.append({"seed": seed, "home": label, "A_n": scores.mean_name_accuracy,
                     "A_p": scores.mean_position_accuracy,
                     "where": [table[home]["A_p hits"] - hits, table[home]["A_p names"] - asked]})
        print(f"seed {seed} {label}: A_n {scores.mean_name_accuracy:.3f} "
              f"A_p {scores.mean_position_accuracy:.3f} ({time.perf_counter() - started:.0f} s)",
              flush=True)
    _print_table(table, words, runs, args.seeds)
    if args.json:
        args.json.write_text(json.dumps({"seeds": args.seeds, "sweeps": args.sweeps, "runs": runs,
                                         "table": {h: dict(c) for h, c in table.items()},
                                         "errors": {k: dict(v) for k, v in words.items()}}, indent=1),
                             encoding="utf-8")


if __name__ == "__main__":
    main()
