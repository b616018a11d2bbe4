"""Single teachings of a home, measured as a person teaching a robot would judge them.

Each teaching starts from a fresh copy of the home (the adapted home, untouched) and teaches one
new name ("this is the <word> room", a word the home never heard) for either

- ``sample``: a recorded training sample (a sentence for its id), or
- ``pose``: a new observation at a recorded sample's pose moved by up to 0.3 m, without a view.

After the teaching it measures

- **effective**: how many of 10 poses of ``where <taught name>`` land in the taught room (the room
  of the 5 nearest training samples, by ground truth); a teaching is effective with ≥ 8 of 10;
- **local**: the share of the *other* rooms' training samples (pose and view, ``what``) whose top
  name changed;
- **why not effective** (:func:`failure_class`): the taught pose at a room's edge, the taught
  sample's region after the teaching mostly another room's or mixed, or ``where``'s best region not
  the taught sample's;
- **same seed**: the teaching repeated with the same seed gives the same home (every array of the
  state and of the posterior equal);
- **undo**: ``--undo`` trials (each its own sequence of ``--undo-teachings`` teachings, default 12,
  through the service's writer and journal, :mod:`spco.service.teaching`, compacted every 5), one of
  them undone at random: every answer (``what`` at
  every training sample with its view, ``where`` of every name of the vocabulary) and the vocabulary
  compared with the home taught the same sequence without it; max |Δp|.

Homes: synthetic new homes (6 experienced synthetic homes as knowledge; ``--home-seed``: the
``generate_homes`` seeds, default 3) and, with ``--sigverse-home``, SIGVerse 3LDK_9 adapted from the
16-home knowledge (one or more home files built as in ``benchmarks/serve_latency.py``, e.g. several
adapt seeds). Seeds 0–99 (development, benchmarks/SPLIT.md).

    python benchmarks/teaching.py --n 100 [--home-seed 3 5 7] [--sigverse-home home_s0.spco …] [--json o.json]
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import signal
import time
import warnings
from pathlib import Path
from typing import Any

import numpy as np
from data_paths import SIGVERSE

from spco import knowledge as kn
from spco.data.environment import Corpus, Environment

NEW_WORDS = (
    "quokka",
    "zephyr",
    "marimba",
    "tundra",
    "saffron",
    "obsidian",
    "lagoon",
    "juniper",
    "falcon",
    "meadow",
    "cobalt",
    "harbour",
    "walnut",
    "ember",
    "glacier",
    "orchid",
)


def synthetic_home(seed: int = 3, psi0_xy: float | None = None,
                   prior: str = "places", nu0: float | None = None,
                   n_regions: int | None = None,
                   settings: tuple[str, ...] = ()) -> tuple[kn.HomeModel, Environment]:
    """A synthetic new home adapted from 6 experienced synthetic homes, and its environment.
    ``psi0_xy``: Ψ0's x and y entries in m² (an experiment with the position prior; default the
    knowledge's own); ``prior``: ``fit_knowledge``'s (``"places"``: Ψ0 from the homes' places);
    ``nu0``: an experiment with the prior's weight ν0 (the scaled priors keep E[Σ] and scale Ψ0);
    ``n_regions``: an experiment with the truncation L of the regions; ``settings``: ``NAME=VALUE``
    transfer hyperparameters (as ``spco fit --set``) over the knowledge's own."""
    from dataclasses import replace

    from spco.data.synthetic import generate_homes
    from spco.model.hyperparameters import TransferHyperparameters

    corpus = generate_homes(7, seed=seed, new_homes=1, specific_rooms=False)
    envs = list(corpus)
    hyper = None
    if nu0 is not None:
        from spco.knowledge.fit import default_hyperparameters

        base = replace(TransferHyperparameters(), nu0=nu0)
        hyper = (base if prior == "paper"
                 else default_hyperparameters(Corpus(envs[:6]), base=base, psi0=prior == "places"))
    if psi0_xy is not None:
        from spco.knowledge.fit import default_hyperparameters

        base = default_hyperparameters(Corpus(envs[:6]), psi0=prior == "places") if hyper is None else hyper
        psi = np.diag(base.psi0_matrix_m2()).copy()
        psi[:2] = psi0_xy
        hyper = replace(base, psi0=tuple(float(v) for v in psi), psi0_in_cm2=False)
    if n_regions is not None:
        from spco.knowledge.fit import default_hyperparameters

        base = default_hyperparameters(Corpus(envs[:6]), psi0=prior == "places") if hyper is None else hyper
        hyper = replace(base, n_regions=n_regions)
    if settings:
        from spco.knowledge.fit import default_hyperparameters

        base = default_hyperparameters(Corpus(envs[:6]), psi0=prior == "places") if hyper is None else hyper
        hyper = base.with_settings(list(settings))
    knowledge = kn.fit_knowledge(Corpus(envs[:6]), n_iterations=30, random_state=0, hyperparameters=hyper,
                                 prior=prior)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        home = kn.adapt(knowledge, envs[6], n_iterations=30, random_state=0)
    return home, envs[6]


def sigverse_env(name: str = "3LDK_9") -> Environment:
    """The SIGVerse home ``name`` as the adapted home saw it (its ground truth for scoring)."""
    from spco.data import load

    root = Path(os.environ["SPCO_DATASETS"]) / "sigverse" if os.environ.get("SPCO_DATASETS") else SIGVERSE
    return next(iter(load(root / name)))


def room_labels(env: Environment, home: kn.HomeModel) -> tuple[np.ndarray, np.ndarray]:
    """(xy of the labelled training samples, their room labels)."""
    labels = env.ground_truth.labels if env.ground_truth is not None else None
    if labels is None:
        raise SystemExit(f"{env.name}: no ground-truth room labels")
    by_id = dict(zip(env.ids.tolist(), labels, strict=True))
    keep = [k for k, i in enumerate(home.ids.tolist()) if by_id.get(i) is not None]
    return home.positions[keep, :2], np.array([by_id[int(home.ids[k])] for k in keep], dtype=object)


def room_at(xy: np.ndarray, train_xy: np.ndarray, train_rooms: np.ndarray, k: int = 5) -> list[str]:
    """The room of each point: the most common room of its ``k`` nearest training samples."""
    out = []
    for p in np.atleast_2d(xy):
        near = np.argsort(((train_xy - p) ** 2).sum(axis=1))[:k]
        rooms, counts = np.unique(train_rooms[near], return_counts=True)
        out.append(str(rooms[np.argmax(counts)]))
    return out


def top_names(home: kn.HomeModel) -> np.ndarray:
    """The top name of ``what`` at every training sample of ``home`` (its pose and its view)."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        pred = kn.name_prediction(home, home.positions, home.visual, top_k=1)
    return np.array([w[0] for w in pred.words], dtype=object)


def answers(home: kn.HomeModel, rows: np.ndarray) -> dict[str, Any]:
    """Every answer compared by the undo measure: ``what`` probabilities at the training samples
    ``rows`` (pose and view) and ``where`` region probabilities of every usable name."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        pred = kn.name_prediction(home, home.positions[rows], home.visual[rows], top_k=5)
        out: dict[str, Any] = {
            "what_words": [tuple(w) for w in pred.words],
            "what_p": np.asarray(pred.probabilities, dtype=float),
            "vocabulary": tuple(home.vocabulary.words),
        }
        for name in home.known_names:
            try:
                out["where " + name] = np.asarray(
                    kn.where(home, name, n=10, random_state=0).region_probabilities
                )
            except Exception as error:  # a name the home cannot answer: its error is the answer
                out["where " + name] = repr(error)
    return out


def max_difference(a: dict[str, Any], b: dict[str, Any]) -> float:
    """max |Δp| between two :func:`answers` (1.0 for a different word, name or vocabulary)."""
    if a.keys() != b.keys() or a["vocabulary"] != b["vocabulary"] or a["what_words"] != b["what_words"]:
        return 1.0
    worst = 0.0
    for key, value in a.items():
        other = b[key]
        if isinstance(value, np.ndarray):
            if value.shape != other.shape:
                return 1.0
            worst = max(worst, float(np.max(np.abs(value - other))) if value.size else 0.0)
        elif value != other:
            return 1.0
    return worst


def same_home(a: kn.HomeModel, b: kn.HomeModel) -> bool:
    """Whether two homes hold the same state, posterior, samples and vocabulary."""
    if a.vocabulary.words != b.vocabulary.words or a.sentences != b.sentences:
        return False
    for name in vars(a.state):
        x, y = getattr(a.state, name), getattr(b.state, name)
        if isinstance(x, np.ndarray) and not np.array_equal(x, y):
            return False
    if (a.posterior is None) != (b.posterior is None):
        return False
    if a.posterior is not None:
        for name, x in a.posterior.arrays().items():
            if not np.array_equal(x, getattr(b.posterior, name)):
                return False
    return True


def new_word(home: kn.HomeModel, t: int) -> str:
    words = set(home.vocabulary.words)
    for k in range(len(NEW_WORDS)):
        w = NEW_WORDS[(t + k) % len(NEW_WORDS)]
        if w not in words:
            return w
    raise SystemExit("every benchmark word is in the home's vocabulary")


def one_teaching(home: kn.HomeModel, env: Environment, t: int, kind: str) -> dict[str, Any]:
    """Teach one new name (seed ``t``) and measure it."""
    rng = np.random.default_rng(t)
    train_xy, train_rooms = room_labels(env, home)
    pick = int(rng.integers(0, train_xy.shape[0]))
    room = str(train_rooms[pick])
    row = int(np.flatnonzero((home.positions[:, :2] == train_xy[pick]).all(axis=1))[0])
    word = new_word(home, t)
    sentence = f"this is the {word} room"
    before = top_names(home)
    start = time.perf_counter()
    if kind == "sample":
        taught = kn.teach(home, {int(home.ids[row]): sentence}, random_state=t)
        again = kn.teach(home, {int(home.ids[row]): sentence}, random_state=t)
    else:
        x, y = home.positions[row, :2] + rng.uniform(-0.3, 0.3, size=2)
        theta = float(np.arctan2(home.positions[row, 2], home.positions[row, 3]))
        obs = kn.Observation(x=float(x), y=float(y), theta=theta, sentence=sentence)
        taught = kn.teach(home, observations=[obs], random_state=t)
        again = kn.teach(home, observations=[obs], random_state=t)
    seconds = time.perf_counter() - start
    top_region = -1
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        try:
            answer = kn.where(taught, f"{word} room", n=10, random_state=t)
            in_room = sum(r == room for r in room_at(answer.samples[:, :2], train_xy, train_rooms))
            top_region = int(answer.region)
        except Exception:
            in_room = 0
    after = top_names(taught)[: home.n_samples]
    rooms_all = np.array(room_at(home.positions[:, :2], train_xy, train_rooms), dtype=object)
    others = rooms_all != room
    changed = float(np.mean(before[others] != after[others])) if others.any() else 0.0
    taught_row = row if kind == "sample" else taught.n_samples - 1
    region = int(taught.state.regions[taught_row])
    mates = rooms_all[taught.state.regions[: home.n_samples] == region]
    share = float(np.mean(mates == room)) if mates.size else 1.0
    near = np.argsort(((train_xy - taught.positions[taught_row, :2]) ** 2).sum(axis=1))[:5]
    return {
        "kind": kind,
        "seed": t,
        "room": room,
        "in_room": in_room,
        "effective": in_room >= 8,
        "changed_elsewhere": changed,
        "same_seed": same_home(taught, again),
        "seconds": seconds / 2,
        "failure": None if in_room >= 8 else failure_class(top_region, region, share,
                                                           bool((train_rooms[near] != room).any())),
        "region": region,
        "region_share_of_room": share,
    }


#: The classes of an ineffective teaching (:func:`failure_class`), in the order the table lists them.
FAILURES = ("edge", "other room's region", "mixed region", "where elsewhere")


def failure_class(top_region: int, region: int, share: float, at_edge: bool) -> str:
    """Why ``where`` of a taught name left the taught room: ``edge`` — the taught pose's 5 nearest
    training samples include another room; ``other room's region`` — the taught sample's region
    after the teaching holds mostly (≥ half) other rooms' samples; ``mixed region`` — it holds the
    room's and others'; ``where elsewhere`` — ``where``'s best region is not the taught sample's
    (or ``where`` failed)."""
    if at_edge:
        return "edge"
    if top_region != region:
        return "where elsewhere"
    return "other room's region" if share < 0.5 else "mixed region"


def _library_teaching(home: kn.HomeModel, record: dict[str, Any]) -> kn.HomeModel:
    """One journal record applied with the library alone (``spco.knowledge.teach``, its seed)."""
    seed, sweeps = int(record["seed"]), int(record["sweeps"])
    if record["op"] == "sentence":
        return kn.teach(home, {int(record["id"]): record["sentence"]}, n_sweeps=sweeps, random_state=seed)
    obs = kn.Observation(
        x=record["x"], y=record["y"], theta=record["theta"], sentence=record["sentence"], id=int(record["id"])
    )
    return kn.teach(home, observations=[obs], n_sweeps=sweeps, random_state=seed)


def undo_trial(home: kn.HomeModel, t: int, folder: Path, n_teach: int = 12, compact_records: int = 5) -> dict:
    """``n_teach`` teachings through the service's writer (journalled, compacted every
    ``compact_records``), one of them undone; the home after the undo, and after a restart of the
    writer, compared with the home the library gives for the same teachings (their recorded seeds)
    without the undone one: max |Δp| over every answer (:func:`answers`)."""
    from spco.knowledge.requests import Pose, Teach, Undo
    from spco.service.writer import HomeWriter

    rng = np.random.default_rng(1000 + t)
    path = folder / f"undo-{t}.spco"
    for suffix in ("", ".journal", ".undo", ".lock"):
        Path(str(path) + suffix).unlink(missing_ok=True)
    home.save(path)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        writer = HomeWriter(path, seed=t, compact_records=compact_records)
        for _ in range(n_teach):
            row = int(rng.integers(0, home.n_samples))
            word = NEW_WORDS[int(rng.integers(0, len(NEW_WORDS)))]
            if rng.random() < 0.5:
                request = Teach(sentence=f"this is the {word} room", id=int(home.ids[row]))
            else:
                x, y = (float(v) for v in home.positions[row, :2] + rng.uniform(-0.3, 0.3, size=2))
                request = Teach(sentence=f"this is the {word} room", pose=Pose(x, y, 0.0))
            result = writer.handle([request])[0]
            assert result["ok"], result
        seqs = sorted(k for k, e in writer.history.items() if e["op"] != "undo")
        undone = seqs[int(rng.integers(0, len(seqs)))]
        result = writer.handle([Undo(undone)])[0]
        if not result["ok"]:  # refused (a later teaching named the sample it added): said, not measured
            writer.close()
            return {"seq": undone, "refused": result["error"]}
        after = writer.snapshot()
        records = [writer.history[k]["record"] for k in seqs if k != undone]
        writer.close()
        restarted = HomeWriter(path, seed=t).snapshot()
        expected = home
        for record in records:
            expected = _library_teaching(expected, record)
    rows = np.arange(home.n_samples)
    want = answers(expected, rows)
    return {
        "seq": undone,
        "of": len(seqs),
        "max_dp": max_difference(answers(after, rows), want),
        "max_dp_restarted": max_difference(answers(restarted, rows), want),
    }


def _start_serving(home_file: Path, folder: Path) -> tuple[Any, str, Path]:
    """``spco serve`` on a fresh copy of ``home_file`` in ``folder``: the process, its URL, the copy."""
    from spco.service.client import ServeProcess

    served = folder / "served.spco"
    for suffix in ("", ".journal", ".lock", ".undo"):
        Path(str(served) + suffix).unlink(missing_ok=True)
    shutil.copyfile(home_file, served)
    server = ServeProcess(served, "--port", "0", "--seed", "0")
    return server.process, server.url, served


def _served_answers(client: Any, home: Any) -> dict[str, Any]:
    """``what`` (top 5) at every sample's pose and view counts, and ``where`` of every name."""
    out: dict[str, Any] = {}
    for k in range(home.n_samples):
        row = home.visual[[k]]
        answer = client.what(
            float(home.positions[k, 0]),
            float(home.positions[k, 1]),
            float(np.arctan2(home.positions[k, 2], home.positions[k, 3])),
            visual=row.toarray()[0],
            top=5,
        )
        out[f"what {k}"] = [(a["name"], a["probability"]) for a in answer["names"]]
    for name in client.regions()["names"]:
        out[f"where {name}"] = [
            (p["x"], p["y"], p["probability"]) for p in client.where(name)["positions"]
        ]
    return out


def _answers_difference(a: dict[str, Any], b: dict[str, Any]) -> float:
    """max |Δ| of the numbers of two :func:`_served_answers`, 1 where their names or lengths differ."""
    if a.keys() != b.keys():
        return 1.0
    worst = 0.0
    for key in a:
        if len(a[key]) != len(b[key]):
            return 1.0
        for x, y in zip(a[key], b[key], strict=True):
            if x[0] != y[0] and isinstance(x[0], str):
                return 1.0
            worst = max(
                worst,
                max(
                    abs(float(u) - float(v)) for u, v in zip(x, y, strict=True) if not isinstance(u, str)
                ),
            )
    return worst


def http_trials(home_file: Path, env: Environment, n: int, folder: Path) -> dict[str, Any]:
    """``n`` teachings over HTTP (``spco serve`` on a fresh copy of ``home_file``, ``spco.service.client``):
    each a new name, for a recorded sample or at a pose without a view, then undone. Per teaching:
    ``where`` of the name in the taught room (≥ 8 of 10 poses), and after the undo max |Δp| of
    ``what`` at every training sample (pose and view counts) and ``where`` of every name, against
    the answers before the teaching — an exact undo makes every teaching one on a fresh home."""
    from spco.service.client import Client

    process, url, served = _start_serving(home_file, folder)
    home = kn.load_home_model(served)
    train_xy, train_rooms = room_labels(env, home)
    client = Client(url)
    results = []
    try:
        before = _served_answers(client, home)
        for t in range(n):
            rng = np.random.default_rng(500 + t)
            pick = int(rng.integers(0, train_xy.shape[0]))
            room = str(train_rooms[pick])
            row = int(np.flatnonzero((home.positions[:, :2] == train_xy[pick]).all(axis=1))[0])
            word = new_word(home, t)
            sentence = f"this is the {word} room"
            if t % 2 == 0:
                taught = client.teach(id=int(home.ids[row]), sentence=sentence)
            else:
                x, y = home.positions[row, :2] + rng.uniform(-0.3, 0.3, size=2)
                theta = float(np.arctan2(home.positions[row, 2], home.positions[row, 3]))
                taught = client.teach(x=float(x), y=float(y), theta=theta, sentence=sentence)
            poses = [(p["x"], p["y"]) for p in client.where(f"{word} room", n=10, seed=t)["positions"]]
            in_room = sum(r == room for r in room_at(np.array(poses), train_xy, train_rooms))
            client.undo(taught["seq"])
            results.append(
                {
                    "kind": "sample" if t % 2 == 0 else "pose",
                    "room": room,
                    "in_room": in_room,
                    "undo_max_dp": _answers_difference(_served_answers(client, home), before),
                }
            )
    finally:
        process.send_signal(signal.SIGINT)
        process.wait(120)
    return {
        "teachings": results,
        "effective_share": float(np.mean([r["in_room"] >= 8 for r in results])),
        "undo_exact_share": float(np.mean([r["undo_max_dp"] == 0 for r in results])),
    }


def summarise(results: list[dict[str, Any]]) -> dict[str, Any]:
    eff = np.array([r["effective"] for r in results])
    changed = np.array([r["changed_elsewhere"] for r in results])
    seconds = np.array([r["seconds"] for r in results]) * 1000
    return {
        "n": len(results),
        "effective_share": float(eff.mean()),
        "in_room_mean": float(np.mean([r["in_room"] for r in results])),
        "changed_elsewhere_mean": float(changed.mean()),
        "changed_elsewhere_p95": float(np.percentile(changed, 95)),
        "changed_elsewhere_max": float(changed.max()),
        "same_seed_share": float(np.mean([r["same_seed"] for r in results])),
        "teach_ms_p50": float(np.percentile(seconds, 50)),
        "teach_ms_p99": float(np.percentile(seconds, 99)),
        "failures": {k: sum(r.get("failure") == k for r in results) for k in FAILURES},
    }


def _check_settings(parser: argparse.ArgumentParser, settings: list[str]) -> None:
    """``parser.error`` naming ``--set`` when ``settings`` are not transfer hyperparameters."""
    from spco.errors import ConfigurationError
    from spco.model.hyperparameters import TransferHyperparameters

    try:
        TransferHyperparameters().with_settings(list(settings))
    except ConfigurationError as exc:
        parser.error(f"--set: {exc}")


def main() -> None:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("--n", type=int, default=100, help="teachings per home and kind")
    parser.add_argument("--undo", type=int, default=0, help="undo trials per home")
    parser.add_argument("--undo-teachings", type=int, default=12,
                        help="teachings in each undo trial's sequence, one of them undone at random (the "
                             "service keeps the last 100 undoable)")
    parser.add_argument("--sigverse-home", type=Path, nargs="+", default=[],
                        help="adapted SIGVerse 3LDK_9 home files (several: e.g. several adapt seeds)")
    parser.add_argument(
        "--http",
        type=int,
        default=0,
        help="teachings over HTTP on the SIGVerse home (each undone and checked)",
    )
    parser.add_argument("--no-synthetic", action="store_true")
    parser.add_argument(
        "--home-seed",
        type=int,
        nargs="+",
        default=[3],
        help="seeds of the synthetic homes (generate_homes; 3: the table's home)",
    )
    parser.add_argument("--psi0-xy", type=float, default=None,
                        help="an experiment: the synthetic knowledge fitted with Ψ0's x, y entries in m²")
    parser.add_argument("--prior", default="places", choices=["scaled", "places", "paper"],
                        help="fit_knowledge's prior of the synthetic knowledge (places, the default: Ψ0 "
                             "from the places; scaled: the paper's Ψ0)")
    parser.add_argument("--nu0", type=float, default=None,
                        help="an experiment: the synthetic knowledge fitted with this ν0 (E[Σ] kept)")
    parser.add_argument("--n-regions", type=int, default=None,
                        help="an experiment: the synthetic knowledge fitted with this truncation L (regions)")
    parser.add_argument("--set", nargs="+", action="extend", default=[], metavar="NAME=VALUE",
                        help="an experiment: the synthetic knowledge fitted (and its homes answering) with "
                             "these transfer hyperparameters, as spco fit --set, e.g. name_answer=looks")
    parser.add_argument("--json", type=Path, default=None)
    args = parser.parse_args()
    _check_settings(parser, args.set)
    homes: list[tuple[str, kn.HomeModel, Environment]] = []
    if not args.no_synthetic:
        for seed in args.home_seed:
            home, env = synthetic_home(seed, args.psi0_xy, args.prior, args.nu0, args.n_regions,
                                       tuple(args.set))
            homes.append(("synthetic" if seed == 3 else f"synthetic (seed {seed})", home, env))
    for path in args.sigverse_home:
        home = kn.load_home_model(path)
        homes.append((f"SIGVerse 3LDK_9 ({path.name})", home, sigverse_env("3LDK_9")))
    report: dict[str, Any] = {}
    print(
        "| home | kind | teachings | effective (≥ 8/10 in room) | mean in room | other places' top name "
        "changed: mean / p95 / max | same seed | teach ms p50 / p99 | failures: " + ", ".join(FAILURES) + " |"
    )
    print("|---|---|---|---|---|---|---|---|---|")
    for label, home, env in homes:
        for kind in ("sample", "pose") if args.n else ():
            results = [one_teaching(home, env, t, kind) for t in range(args.n)]
            s = summarise(results)
            report[f"{label} {kind}"] = {"summary": s, "teachings": results}
            print(
                f"| {label} | {kind} | {s['n']} | {s['effective_share']:.0%} | {s['in_room_mean']:.1f} | "
                f"{s['changed_elsewhere_mean']:.2%} / {s['changed_elsewhere_p95']:.2%} / "
                f"{s['changed_elsewhere_max']:.2%} | {s['same_seed_share']:.0%} | "
                f"{s['teach_ms_p50']:.0f} / {s['teach_ms_p99']:.0f} | "
                f"{' / '.join(str(s['failures'][k]) for k in FAILURES)} |",
                flush=True,
            )
        if args.undo:
            import tempfile

            with tempfile.TemporaryDirectory() as folder:
                trials = [undo_trial(home, t, Path(folder), n_teach=args.undo_teachings)
                          for t in range(args.undo)]
            report[f"{label} undo"] = trials
            done = [r for r in trials if "max_dp" in r]
            exact = np.mean([r["max_dp"] == 0 and r["max_dp_restarted"] == 0 for r in done]) if done else 0.0
            worst = max((max(r["max_dp"], r["max_dp_restarted"]) for r in done), default=0.0)
            print(
                f"| {label} | undo | {len(done)} undone ({len(trials) - len(done)} refused) | max abs dp = 0 "
                f"in {exact:.0%} (worst {worst:.3g}), also after a restart | | | | | |",
                flush=True,
            )
    if args.http and args.sigverse_home:
        import tempfile

        with tempfile.TemporaryDirectory() as folder:
            served = args.sigverse_home[0].resolve()
            http = http_trials(served, sigverse_env("3LDK_9"), args.http, Path(folder))
        report["SIGVerse 3LDK_9 http"] = http
        print(
            f"| SIGVerse 3LDK_9 | over HTTP, each undone | {len(http['teachings'])} | "
            f"{http['effective_share']:.0%} | "
            f"{np.mean([r['in_room'] for r in http['teachings']]):.1f} | undo max abs dp = 0 in "
            f"{http['undo_exact_share']:.0%} | | |",
            flush=True,
        )
    if args.json:
        args.json.write_text(json.dumps(report, indent=1, default=str))


if __name__ == "__main__":
    main()
