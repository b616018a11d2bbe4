"""Why a home-specific room is missed: each wrong answer of a configured run put in one class
(development only).

Runs configured runs of a home-specific configuration file (``spco experiment specific``'s own fit,
as :func:`spco.evaluation.specific_config.execute_configured_run`, the same seeds and draws, so the
answers are the experiment's) and, for every room, reads the fit:

- the concept that holds the room's name in the robot's answer (``l*``: the concept whose answer
  word distribution θ^w puts most mass on the room's accepted phrases) and that concept's top name;
- the concept the robot's answer (:func:`spco.model.confidence.answer_concepts`, the room account)
  gives each test view;
- ``where <room name>`` (the robot's p(pose | name), most probable region): whether the home's
  training sample nearest each drawn pose is one of the room's own samples (a region test that needs
  no rectangles, so it applies to every room).

Every missed test view is put in the first class that applies:

1. ``not learnt`` — none of the room's accepted phrases is a name the home answers, or none is the
   top name of any concept: the name was not learnt as its own concept;
2. ``taken by general`` — the concept holding the name answers another name first (the general
   name, or another room's): the room's taught samples sit in a concept whose name is not theirs;
3. ``view to general`` — the name is its own concept's top name, but the robot's answer puts the
   test view in another concept (and answers that concept's name);
4. ``other``.

``where`` misses are counted apart (drawn poses whose nearest training sample is another room's).

    python benchmarks/specific_misses.py --data D/sigverse \
        --config benchmarks/development/specific_dev_hard.json --rates 40 --seeds 0 1 2 3 4 --out misses.jsonl
"""

from __future__ import annotations

import argparse
import json
import sys
from collections import Counter
from pathlib import Path
from typing import Any

import numpy as np

import spco.evaluation.specific_config as sc
from spco.evaluation.specific_config import ConfiguredData, ConfiguredRun, load_specific_config
from spco.model.transfer import SpatialConceptModel

CLASSES = ("not learnt", "taken by general", "view to general", "other")
CONFIG = Path(__file__).resolve().parent / "development" / "specific_dev_hard.json"
_FIT: list[Any] = []


def _keep_model(model: Any, home: str | int) -> Any:
    """The model's answer inputs, keeping the model (the run asks for them once, after its fit)."""
    _FIT[:] = [model]
    return _ANSWER_INPUTS(model, home)


def _diagnose_room(model: Any, e: int, env: Any, room: Any, scores: Any, answer: Any, rooms: Any,
                   rng: np.random.Generator) -> dict[str, Any]:
    """One room's reading of the fit (module docstring)."""
    from spco.evaluation.specific_file import normalize_phrase
    from spco.model.confidence import answer_concepts
    from spco.model.position_prediction import predict_positions
    from spco.model.prediction import UnknownNameError

    words = list(model.vocabulary_.words)
    mask = np.asarray(answer.word_mask, dtype=bool)
    theta = np.asarray(answer.word_probabilities[e], dtype=np.float64) * mask[None, :]
    cols = [k for k, w in enumerate(words) if normalize_phrase(w) in room.accepted]
    answerable = [k for k in cols if mask[k]]
    top = np.argmax(theta, axis=1)  # each concept's top name
    own = [int(c) for c in np.flatnonzero(np.isin(top, answerable))] if answerable else []
    holder = int(np.argmax(theta[:, answerable].sum(axis=1))) if answerable else -1
    ids = {int(i): r for r, i in enumerate(env.ids)}
    train_rows = {int(i): r for r, i in enumerate(env.training_data().ids)}
    concepts = np.asarray(model.concepts_[e])
    train_concepts = Counter(int(concepts[train_rows[i]]) for i in room.train_ids if i in train_rows)
    test = np.array([ids[i] for i in room.test_ids], dtype=np.int64)
    post = answer_concepts(answer, e, env.positions[test], env.visual[test],
                           view_counts=model.settings_.view_counts, rooms=rooms,
                           settings=model.hyperparameters_.answer_settings())
    test_concepts = np.argmax(post, axis=1)
    classes = []
    for j, ok in enumerate(scores.correct):
        if ok:
            continue
        if not own:
            classes.append(CLASSES[0])
        elif holder not in own:
            classes.append(CLASSES[1])
        elif int(test_concepts[j]) not in own:
            classes.append(CLASSES[2])
        else:
            classes.append(CLASSES[3])
    where_in = None
    try:
        pred = predict_positions(answer, e, model.vocabulary_, room.name, n=20, rng=rng, mode="argmax",
                                 rooms=rooms, view_counts=model.settings_.view_counts,
                                 lookup=model.parameters_.word_mask)
        train = env.training_data()
        own_rows = np.array([i in set(room.train_ids) for i in train.ids.tolist()])
        d = np.linalg.norm(train.positions[None, :, :2] - pred.samples[:, None, :2], axis=2)
        where_in = float(own_rows[np.argmin(d, axis=1)].mean())
    except UnknownNameError:
        where_in = 0.0
    return {"answered": list(scores.predicted), "correct": [int(c) for c in scores.correct],
            "classes": classes, "names": [words[k] for k in cols],
            "answerable": [words[k] for k in answerable],
            "own_concepts": own, "holder": holder,
            "holder_top": words[int(top[holder])] if holder >= 0 else None,
            "train_concepts": dict(train_concepts), "test_concepts": [int(c) for c in test_concepts],
            "test_tops": [words[int(top[c])] for c in test_concepts], "where_in_room": where_in}


def run(config: str, data: str, key: ConfiguredRun, iterations: int) -> dict[str, Any]:
    """One configured run and its rooms' readings."""
    SpatialConceptModel.answer_inputs = _keep_model  # type: ignore[method-assign]
    file = load_specific_config(config)
    loaded = ConfiguredData(file, data, file.select([key.configuration]))
    record = sc.execute_configured_run(loaded, key, iterations, sc.DEFAULT_POSITIONS)
    model = _FIT[0]
    e = len(model.data_.offsets) - 2
    conf = file.configuration(key.configuration)
    env = loaded.new_home(conf, sc.teaching_sentences(file, conf, key.rate, key.seed))
    answer, rooms, _ = model.answer_inputs(e)
    rng = np.random.default_rng([key.seed, 2])
    record["diagnosis"] = {}
    for room in conf.rooms:
        s = record["rooms"][room.name]
        scores = sc.RoomScores(np.array(s["correct"], dtype=bool), tuple(s["predicted"]), {})
        record["diagnosis"][room.name] = _diagnose_room(model, e, env, room, scores, answer, rooms, rng)
    return record


_ANSWER_INPUTS = SpatialConceptModel.answer_inputs


def main(argv: list[str] | None = None) -> int:
    """Command line: see the module docstring."""
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--data", required=True, help="the SIGVerse folder")
    parser.add_argument("--config", default=str(CONFIG))
    parser.add_argument("--configurations", nargs="*", default=None)
    parser.add_argument("--rates", type=int, nargs="+", default=[40])
    parser.add_argument("--seeds", type=int, nargs="+", default=[0])
    parser.add_argument("--iterations", type=int, default=200)
    parser.add_argument("--model", default="spcotransfer+mi")
    parser.add_argument("--out", type=Path, default=None, help="JSON lines, one record per run")
    args = parser.parse_args(argv)
    file = load_specific_config(args.config)
    keys = [ConfiguredRun(c.id, r, s, args.model) for c in file.select(args.configurations)
            for r in args.rates for s in args.seeds]
    total: Counter[str] = Counter()
    for key in keys:
        record = run(args.config, args.data, key, args.iterations)
        for name, d in record["diagnosis"].items():
            total.update(d["classes"])
            print(f"{key.configuration} seed {key.seed} {name!r}: A_n {np.mean(d['correct']):.2f} "
                  f"where-in-room {d['where_in_room']} answered {Counter(d['answered'])} misses "
                  f"{Counter(d['classes'])} | own {d['own_concepts']} holder {d['holder']} "
                  f"({d['holder_top']}) train {d['train_concepts']} test {Counter(d['test_tops'])}",
                  flush=True)
        if args.out is not None:
            with args.out.open("a") as fh:
                fh.write(json.dumps(record) + "\n")
    print(f"\nmisses by class: {dict(total)}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
