"""Home-specific rooms with the room account and without it, on the same fits (development only).

Issue 29 ("A room's evidence", docs/model.md). Runs the home-specific experiment of
``benchmarks/development/specific_dev.json`` (``spco experiment specific``'s own run,
:func:`spco.evaluation.specific_config.execute_configured_run`: fit, then score each configured room)
and scores every run twice from the one fit: names as the view-by-view answer gives them (what
``spco.knowledge.name_prediction(by_room=False)`` answers; the robot's answer before the room account
was the default) and as the room account gives them (``answer_rooms=spco.model.rooms.model_rooms(model,
e)``, the experiment's own score and what ``what`` answers). Prints A_n per run and the mean over the
rooms of all runs for each. Development only: ``specific_dev.json`` is the development file of
benchmarks/SPLIT.md.

    nice -n 5 python benchmarks/rooms_specific.py --data D/sigverse --rates 40 --seeds 0 1 2 --jobs 2

``--set NAME=VALUE`` (repeatable) fits with those transfer hyperparameters, read as ``spco experiment
specific --set`` reads them (:func:`spco.cli.common.settings_hyperparameters`), e.g. ``--set
warm_start=names`` for the start before issue 28's words' start.

``--diagnose`` adds to each record (``--out``) where each room is in the fit (:func:`diagnose`): the
concepts of its taught and untaught training samples, the concept the view-by-view answer puts each test
sample in and the name that concept says, the room account's concept and p(l | room k) at each test
sample, p(name | room) of the room's best accepted name each way, and the room account's answer with the
view as a draw of its room (``view_in_room``, opt-in). A diagnosis: the scores are the same with it and
without it.
"""

from __future__ import annotations

import argparse
import copy
import json
import sys
import time
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path
from typing import Any

import click
import numpy as np

import spco.evaluation.specific_config as sc
from spco.cli.common import settings_hyperparameters
from spco.evaluation.specific_config import ConfiguredData, ConfiguredRun, load_specific_config
from spco.model.rooms import model_rooms
from spco.model.transfer import SpatialConceptModel

CONFIG = Path(__file__).resolve().parent / "development" / "specific_dev.json"
_MODEL: list[Any] = []  # the run's fitted model, taken where the run asks for what the robot answers with
_ROOMS: list[Any] = []  # the room account's scores of the run
_DIAGNOSIS: list[Any] = []  # --diagnose: the run's rooms in its fit (diagnose)


def _answer_inputs(model: Any, home: str | int) -> Any:
    """:meth:`SpatialConceptModel.answer_inputs`, keeping the model and home it was asked for."""
    _MODEL[:] = [(model, model.home_index(home))]
    return _ANSWER_INPUTS(model, home)


def _score_both(params: Any, e: int, env: Any, vocabulary: Any, rooms: Any, weighting: Any, n_positions: int,
                rng: np.random.Generator, view_counts: Any, answer_params: Any = None,
                answer_rooms: Any = None, settings: Any = None) -> Any:
    """The view-by-view answer's scores (returned: the record's ``rooms``), and the room account's from
    the same fit (``_ROOMS``: the record's ``rooms_account``; the run passes ``answer_rooms``, which is
    the same :func:`~spco.model.rooms.model_rooms`)."""
    again = copy.deepcopy(rng)
    plain = _SCORE_ROOMS(params, e, env, vocabulary, rooms, weighting, n_positions, rng, view_counts,
                         answer_params, settings=settings)
    fit = copy.deepcopy(again)
    model, e_model = _MODEL[0]
    _ROOMS[:] = [_SCORE_ROOMS(params, e, env, vocabulary, rooms, weighting, n_positions, again, view_counts,
                              answer_params, model_rooms(model, e_model), settings=settings),
                 # positions from the fit's π·G account and its θ^w (the experiments' A_p before issue
                 # 29's one p(pose | name); the robot's is the room account's above)
                 _SCORE_ROOMS(params, e, env, vocabulary, rooms, weighting, n_positions, fit, view_counts,
                              settings=settings)]
    if _DIAGNOSIS:
        _DIAGNOSIS[:] = [diagnose(model, e_model, env, rooms, weighting)]
    return plain


def _accepted_columns(vocabulary: Any, room: Any) -> np.ndarray:
    """The vocabulary columns of the words that count as ``room``'s name."""
    return np.array([j for j, w in enumerate(vocabulary.words) if room.is_accepted(str(w))], dtype=np.int64)


def diagnose(model: Any, e: int, env: Any, rooms: Any, weighting: Any) -> dict[str, Any]:
    """Where each configured room of home ``e`` is in a fitted joint model, and what each answer reads.

    Per room: ``taught``/``untaught``: the sampler's concepts of the room's taught and untaught
    training samples; ``untaught_with_taught``: the share of its untaught training samples in a
    concept that holds one of its taught samples; ``view_concepts``: the view-by-view answer's most
    probable concept of each test sample (:func:`spco.model.prediction.concept_posterior` on the
    answer's parameters at the model's view weight) and ``view_concept_names``: that concept's best
    name under the answer's θ^w and its probability; ``room_concepts``/``room_concept_p``: the room
    account's most probable concept at each test sample
    (:func:`spco.model.confidence.answer_concepts` with the rooms) and its probability;
    ``room_p_accepted``/``view_p_accepted``: the mean over test samples of p(name | pose, view) of the
    room's best accepted word, each way; ``view_in_room``/``view_in_room_correct``: the room account's
    answer with the observation's view as a draw of its room
    (``answer_names(..., settings=AnswerSettings(view_in_room=True))``,
    opt-in) and whether each is the room's name; ``theta_accepted``: the answer's θ^w_{e,l} of the room's
    best accepted word in each concept holding its taught samples."""
    from spco.model.answer_settings import AnswerSettings
    from spco.model.confidence import answer_concepts, answer_names
    from spco.model.prediction import concept_posterior

    params, answer_rooms, _ = model.answer_inputs(e)
    w = model.settings_.view_counts
    answer = model.hyperparameters_.answer_settings()  # the model's (the diagnosis's view_in_room: its own)
    data = model.data_
    concepts = np.asarray(model.concepts_[e])
    words = data.words[int(data.offsets[e]):int(data.offsets[e + 1])]
    taught = np.asarray((words != 0).sum(axis=1)).ravel() > 0
    train_row = {int(i): r for r, i in enumerate(env.training_data().ids)}
    test_row = {int(i): r for r, i in enumerate(env.ids)}
    theta = np.asarray(params.word_probabilities[e], dtype=np.float64) * np.asarray(params.word_mask)[None, :]
    vocab = np.asarray(model.vocabulary_.words, dtype=str)
    out: dict[str, Any] = {}
    for room in rooms:
        rows = np.array([train_row[int(i)] for i in room.train_ids if int(i) in train_row], dtype=np.int64)
        test = np.array([test_row[int(i)] for i in room.test_ids], dtype=np.int64)
        t, u = concepts[rows[taught[rows]]], concepts[rows[~taught[rows]]]
        view = concept_posterior(params, e, env.positions[test], env.visual[test], view_counts=w)
        by_room = answer_concepts(params, e, env.positions[test], env.visual[test], view_counts=w,
                                  rooms=answer_rooms, settings=answer)
        accepted = _accepted_columns(model.vocabulary_, room)
        p = {}
        for label, r in (("view", None), ("room", answer_rooms)):
            pred = answer_names(params, e, model.vocabulary_, env.positions[test], env.visual[test], top_k=1,
                                weighting=weighting, view_counts=w, rooms=r, settings=answer)
            probs = pred.word_probabilities[:, accepted] if accepted.size else np.zeros((test.size, 1))
            p[label] = round(float(probs.max(axis=1).mean()), 4)
        in_room = answer_names(params, e, model.vocabulary_, env.positions[test], env.visual[test], top_k=1,
                               weighting=weighting, view_counts=w, rooms=answer_rooms,
                               settings=AnswerSettings(view_in_room=True))
        best_view = view.argmax(axis=1)
        out[room.name] = {
            "taught": t.tolist(), "untaught": u.tolist(),
            "untaught_with_taught": round(float(np.isin(u, t).mean()), 4) if u.size else None,
            "view_concepts": best_view.tolist(),
            "view_concept_names": [(str(vocab[int(np.argmax(theta[c]))]), round(float(theta[c].max()), 4))
                                   for c in best_view],
            "room_concepts": by_room.argmax(axis=1).tolist(),
            "room_concept_p": np.round(by_room.max(axis=1), 4).tolist(),
            "view_p_accepted": p["view"], "room_p_accepted": p["room"],
            "view_in_room": [str(x) for x in in_room.words[:, 0]],
            "view_in_room_correct": [int(room.is_accepted(str(x))) for x in in_room.words[:, 0]],
            "theta_accepted": {int(c): round(float(theta[c, accepted].max()), 4) if accepted.size else None
                               for c in np.unique(t)},
        }
    return out


_ANSWER_INPUTS = SpatialConceptModel.answer_inputs
_SCORE_ROOMS = sc.score_rooms


def run(args: tuple[str, str, ConfiguredRun, int, tuple[str, ...], bool]) -> dict[str, Any]:
    """One configured run, scored both ways (fitted with the hyperparameters of the ``--set`` options)."""
    config, data, key, iterations, settings, diagnosis = args
    _DIAGNOSIS[:] = [None] if diagnosis else []
    SpatialConceptModel.answer_inputs = _answer_inputs  # type: ignore[method-assign]
    sc.score_rooms = _score_both  # type: ignore[assignment]
    file = load_specific_config(config)
    loaded = ConfiguredData(file, data, file.select([key.configuration]))
    record = sc.execute_configured_run(loaded, key, iterations, sc.DEFAULT_POSITIONS,
                                       hyperparameters=settings_hyperparameters(settings))
    record["rooms_account"] = {name: {"correct": [int(c) for c in s.correct], "predicted": list(s.predicted),
                                      "name_accuracy": round(s.name_accuracy, 6),
                                      "positions": s.position_accuracy}
                               for name, s in _ROOMS[0].items()}
    record["positions_fit_account"] = {name: s.position_accuracy for name, s in _ROOMS[1].items()}
    if diagnosis:
        record["diagnosis"] = _DIAGNOSIS[0]
    return record


def main(argv: list[str] | None = None) -> int:
    """Command line: see the module docstring."""
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--data", required=True, help="the SIGVerse folder")
    parser.add_argument("--config", default=str(CONFIG))
    parser.add_argument("--rates", type=int, nargs="+", default=[40])
    parser.add_argument("--seeds", type=int, nargs="+", default=[0, 1, 2])
    parser.add_argument("--iterations", type=int, default=200)
    parser.add_argument("--model", default="spcotransfer+mi")
    parser.add_argument("--jobs", type=int, default=1)
    parser.add_argument("--out", type=Path, default=None, help="JSON lines, one record per run")
    parser.add_argument("--diagnose", action="store_true",
                        help="add where each room is in the fit to each record (see the module docstring)")
    parser.add_argument("--set", dest="settings", action="append", default=[], metavar="NAME=VALUE",
                        help="a transfer hyperparameter on its default (spco experiment's --set), repeatable")
    args = parser.parse_args(argv)
    try:
        settings_hyperparameters(args.settings)  # a bad setting fails here, naming it, not in a worker
    except click.BadParameter as exc:
        parser.error(exc.format_message())
    file = load_specific_config(args.config)
    keys = [ConfiguredRun(c.id, r, s, args.model) for c in file.configurations for r in args.rates
            for s in args.seeds]
    start = time.perf_counter()
    per_room: dict[str, list[float]] = {"view": [], "rooms": [], "A_p fit": [], "A_p robot": []}
    with ProcessPoolExecutor(args.jobs) as pool:
        for record in pool.map(run, [(args.config, args.data, k, args.iterations, tuple(args.settings),
                                      args.diagnose) for k in keys]):
            view = {n: r["name_accuracy"] for n, r in record["rooms"].items()}
            by_room = {n: r["name_accuracy"] for n, r in record["rooms_account"].items()}
            per_room["view"].extend(view.values())
            per_room["rooms"].extend(by_room.values())
            if "diagnosis" in record:
                per_room.setdefault("view in room", []).extend(
                    float(np.mean(d["view_in_room_correct"])) for d in record["diagnosis"].values())
            a_p = {n: (record["positions_fit_account"][n]["argmax"], r["positions"]["argmax"])
                   for n, r in record["rooms_account"].items()}
            per_room["A_p fit"].extend(v[0] for v in a_p.values() if v[0] is not None)
            per_room["A_p robot"].extend(v[1] for v in a_p.values() if v[1] is not None)
            print(f"{record['configuration']} {record['rate']} % seed {record['seed']}: view-by-view "
                  f"{view} | room account {by_room} | A_p (argmax) fit's account -> robot's {a_p}",
                  flush=True)
            if args.out is not None:
                with args.out.open("a") as fh:
                    fh.write(json.dumps(record) + "\n")
    print(f"\n{len(keys)} runs, {len(per_room['view'])} rooms, {time.perf_counter() - start:.0f} s: mean A_n "
          f"view-by-view {np.mean(per_room['view']):.3f}, room account {np.mean(per_room['rooms']):.3f}; "
          f"mean A_p (argmax) the fit's π·G account {np.mean(per_room['A_p fit']):.3f}, the robot's (room "
          f"account) {np.mean(per_room['A_p robot']):.3f}")
    if "view in room" in per_room:
        print(f"mean A_n room account with the view as a draw of its room (view_in_room) "
              f"{np.mean(per_room['view in room']):.3f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
