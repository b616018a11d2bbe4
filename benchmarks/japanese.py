"""Japanese speech written without spaces against the same speech with its words spaced.

Two data sets, each learnt twice — once with the sentences as a recogniser prints Japanese (no
spaces: spco segments them, :mod:`spco.data.segmentation`) and once with the same characters
separated into words by spaces (nothing to segment) — and the accuracies printed side by side:

``sigverse``
    The paper's general experiment (``spco experiment general``, 16 experienced homes, new homes
    1LDK_9, 2LDK_9, 3LDK_9, model ``spcotransfer+mi``) on SIGVerse homes whose English template
    sentences are replaced by their Japanese translations
    (``benchmarks/development/sigverse_sentences_ja.csv``: three variants per template, one drawn
    per sample with ``--seed``, the same draw for both writings). A_n counts a predicted name right
    when it is one of the place's Japanese names (``place_names_ja.json``); A_p asks ``where`` for
    each of them the vocabulary holds. ``--english`` adds the original English homes.
``cc4f``
    The CC4F_turtlebot2 recording (a real robot, 100 poses, spoken Japanese in hiragana, no camera):
    learnt on its own (``spcotransfer+mi``, one home), 5 folds × ``--trials`` seeds; each fold's 20
    samples (4 per place where possible) are untaught test samples. A_n: the share of a place's
    test samples whose predicted name (from the pose alone) is one of its names in ``answers.json``
    (romaji, compared in hiragana), averaged over places; A_p: for each name, the share of 10
    positions drawn by ``where`` whose nearest recorded sample belongs to a place of that name,
    averaged over names. Without spaces the sentences are the recording's with its spaces removed.

    python benchmarks/japanese.py sigverse --data ../shared/datasets/sigverse \\
        --regions ../shared/datasets/sigverse_regions.json --trials 5 --out /tmp/ja-sigverse
    python benchmarks/japanese.py cc4f --data ../shared/datasets/cc4f_turtlebot2 --trials 4

Needs the Japanese segmenter (``pip install -e '.[ja]'``).
"""

from __future__ import annotations

import argparse
import csv
import json
import math
import shutil
import time
import zlib
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np

from spco.data.environment import Environment, make_ground_truth
from spco.data.language import normalize_name

DEVELOPMENT = Path(__file__).resolve().parent / "development"

# ------------------------------------------------------------------------------------- SIGVerse


def _translations() -> dict[str, list[tuple[str, str]]]:
    """English template (normalised) -> its Japanese variants as (unspaced, spaced)."""
    out: dict[str, list[tuple[str, str]]] = {}
    with open(DEVELOPMENT / "sigverse_sentences_ja.csv", encoding="utf-8", newline="") as handle:
        for row in csv.DictReader(handle):
            out.setdefault(" ".join(row["template_en"].split()), []).append(
                (row["sentence_ja"], row["sentence_ja_spaced"]))
    return out


def _japanese_names() -> dict[str, list[str]]:
    names = json.loads((DEVELOPMENT / "place_names_ja.json").read_text(encoding="utf-8"))
    places = {k: v for k, v in names.items() if not k.startswith("_")}
    places.update(names["_home_specific"])
    return places


def write_japanese_homes(data: Path, homes: list[str], new_homes: list[str], out: Path, seed: int) -> None:
    """Write ``homes`` of the SIGVerse folder ``data`` twice in the plain format, under
    ``out/unspaced`` and ``out/spaced``, their sentences replaced by Japanese (one of the three
    variants of each template, drawn per sample from ``seed``), with the places' Japanese names as
    accepted names."""
    from spco.data.loading import read_records
    from spco.data.plain import write_home

    translations = _translations()
    accepted = _japanese_names()
    records = read_records(data, names=[*homes, *new_homes])
    for name, record in zip([*homes, *new_homes], records, strict=True):
        env = record.at_rate(0 if name in new_homes else 100)
        rng = np.random.default_rng(np.random.SeedSequence(seed, spawn_key=(zlib.crc32(name.encode()),)))
        draws = rng.integers(0, 3, size=env.n_samples)
        gt = env.ground_truth
        assert gt is not None and gt.labels is not None
        ground = make_ground_truth(labels=gt.labels, specific_labels=gt.specific_labels,
                                   specific_test=gt.specific_test,
                                   accepted_names={p: accepted[p] for p in accepted})
        for k, kind in enumerate(("unspaced", "spaced")):
            sentences = []
            for sentence, draw in zip(env.sentences, draws, strict=True):
                if sentence is None:
                    sentences.append(None)
                    continue
                variants = translations.get(" ".join(sentence.split()))
                if variants is None:
                    raise SystemExit(f"{name}: no Japanese translation of {sentence!r}")
                sentences.append(variants[int(draw) % len(variants)][k])
            write_home(replace(env, sentences=tuple(sentences), ground_truth=ground, source=None),
                       out / kind / name)


def run_sigverse(args: argparse.Namespace) -> None:
    """The general experiment on the Japanese SIGVerse homes, unspaced and spaced."""
    from spco.evaluation.experiments import (
        PAPER_EXPERIENCED_HOMES,
        PAPER_NEW_HOMES,
        ExperimentConfig,
        run_experiment,
    )

    out = Path(args.out)
    homes_dir = out / "homes"
    if homes_dir.exists():
        shutil.rmtree(homes_dir)
    write_japanese_homes(Path(args.data), list(PAPER_EXPERIENCED_HOMES), list(PAPER_NEW_HOMES), homes_dir,
                         args.seed)
    sources = {"unspaced": homes_dir / "unspaced", "spaced": homes_dir / "spaced"}
    if args.english:
        sources["english"] = Path(args.data)
    rows = []
    for kind, source in sources.items():
        config = ExperimentConfig(experiment="general", settings=(16,), data=source, regions=args.regions,
                                  trials=args.trials, models=("spcotransfer+mi",),
                                  iterations=args.iterations, seed=args.seed, jobs=args.jobs,
                                  experienced_homes=PAPER_EXPERIENCED_HOMES, new_homes=PAPER_NEW_HOMES)
        start = time.perf_counter()
        result = run_experiment(config, out / kind, force=True)
        seconds = time.perf_counter() - start
        runs = [r for r in result.results["runs"] if r["place"] == "mean"]
        a_n = np.array([r["name_accuracy"] for r in runs], dtype=float)
        a_p = np.array([r["position_accuracy"] for r in runs], dtype=float)
        vocabulary = result.results["config"]["data"]["vocabulary"]
        rows.append((kind, a_n, a_p, len(vocabulary), seconds))
        print(f"{kind}: vocabulary ({len(vocabulary)}): {', '.join(vocabulary)}", flush=True)
    _table(rows, "new homes × trials")


# ------------------------------------------------------------------------------------- CC4F
_KANA = {
    "kya": "きゃ", "kyu": "きゅ", "kyo": "きょ", "sha": "しゃ", "shu": "しゅ", "sho": "しょ",
    "cha": "ちゃ", "chu": "ちゅ", "cho": "ちょ", "nya": "にゃ", "nyu": "にゅ", "nyo": "にょ",
    "hya": "ひゃ", "hyu": "ひゅ", "hyo": "ひょ", "rya": "りゃ", "ryu": "りゅ", "ryo": "りょ",
    "gya": "ぎゃ", "gyu": "ぎゅ", "gyo": "ぎょ", "ja": "じゃ", "ju": "じゅ", "jo": "じょ",
    "shi": "し", "chi": "ち", "tsu": "つ", "fu": "ふ", "ji": "じ",
    **{c + v: k for c, row in {
        "": "あいうえお", "k": "かきくけこ", "s": "さ_すせそ", "t": "た__てと", "n": "なにぬねの",
        "h": "はひ_へほ", "m": "まみむめも", "y": "や_ゆ_よ", "r": "らりるれろ", "w": "わ___を",
        "g": "がぎぐげご", "z": "ざ_ずぜぞ", "d": "だぢづでど", "b": "ばびぶべぼ", "p": "ぱぴぷぺぽ",
    }.items() for v, k in zip("aiueo", row, strict=True) if k != "_"},
    "N": "ん", "q": "っ",
}


def romaji_to_hiragana(text: str) -> str:
    """CC4F's romaji (``hagiwarakeN``, ``raqkukeN``) in hiragana, as its recogniser prints words."""
    out, i = [], 0
    while i < len(text):
        for length in (3, 2, 1):
            kana = _KANA.get(text[i:i + length])
            if kana is not None:
                out.append(kana)
                i += length
                break
        else:
            raise ValueError(f"cannot read {text!r} at {text[i:]!r}")
    return "".join(out)


def cc4f_home(folder: Path, spaced: bool) -> tuple[Environment, np.ndarray, list[set[str]]]:
    """CC4F as a home (sentences spaced as recorded, or with the spaces removed), the place of each
    sample and the names (hiragana) of each place. The recording has no camera: every view is
    missing (an all-zero count vector)."""
    from spco.data.loading import load_home

    env = load_home(folder)  # no visual file: every view missing
    if not spaced:
        env = env.with_sentences([None if s is None else s.replace(" ", "") for s in env.sentences])
    places, names = cc4f_answers(folder)
    labels = [f"place {p}" for p in places]
    accepted = {f"place {p}": sorted(names[p]) for p in range(len(names))}
    return replace(env, ground_truth=make_ground_truth(labels=labels, accepted_names=accepted)), places, names


def cc4f_answers(folder: Path) -> tuple[np.ndarray, list[set[str]]]:
    """The place of each sample and the names (hiragana) of each place, from ``answers.json``.

    ``names_of_place_romaji`` has 20 entries and ``place_of_sample`` uses 15 place numbers; from
    place 5 on, entry ``p`` is not what the samples of place ``p`` were called (place 5's samples
    say にしかわけん, entry 5 is taniguchikeN, entry 6 nishikawakeN). Each place gets the entry whose
    names its samples' sentences say most often (its own entry on a tie); realigned places are
    printed."""
    answers = json.loads((folder / "answers.json").read_text(encoding="utf-8"))
    places = np.asarray(answers["place_of_sample"], dtype=int)
    entries = [{romaji_to_hiragana(n.strip()) for n in text.split(",")}
               for text in answers["names_of_place_romaji"]]
    with open(folder / "samples.csv", encoding="utf-8", newline="") as handle:
        words = [set((r["sentence"] or "").split()) for r in csv.DictReader(handle)]
    names: list[set[str]] = [set() for _ in range(max(len(entries), int(places.max()) + 1))]
    for p in np.unique(places):
        said = [words[i] for i in np.flatnonzero(places == p)]
        votes = [sum(bool(entry & w) for w in said) for entry in entries]
        best = max(range(len(entries)), key=lambda j: (votes[j], j == p))
        if best != p:
            print(f"answers.json: the samples of place {p} say {sorted(entries[best])} (entry {best}), "
                  f"not entry {p} {sorted(entries[p]) if p < len(entries) else ''}")
        names[p] = entries[best]
    return places, names


def cc4f_scores(env: Environment, places: np.ndarray, names: list[set[str]], fold: int, seed: int,
                iterations: int, said: set[str], hyper: Any = None,
                model_answer: bool = False) -> tuple[float, float]:
    """A_n and A_p of one fold (test samples: every 5th sample of each place, from ``fold``).
    ``hyper``: the fit's transfer hyperparameters (default the model's own); ``model_answer``: names
    with the model's own weighting (:meth:`~spco.model.transfer.SpatialConceptModel.name_weighting`,
    e.g. ``name_answer=looks``) instead of :func:`~spco.model.prediction.predict_names`' default MI."""
    from spco.data.environment import Corpus
    from spco.model.position_prediction import predict_positions
    from spco.model.prediction import UnknownNameError, predict_names
    from spco.model.transfer import SpCoTransfer

    rank = np.zeros(len(places), dtype=int)
    for p in np.unique(places):
        rows = np.flatnonzero(places == p)
        rank[rows] = np.arange(rows.size)
    is_test = rank % 5 == fold
    home = replace(env, is_test=is_test).without_test_sentences()
    corpus = Corpus([home])
    model = SpCoTransfer(hyper, prune_words=True, n_iterations=iterations, random_state=seed,
                         record_log_joint=False).fit(corpus)
    params, vocabulary = model.parameters_, corpus.vocabulary
    rows = np.flatnonzero(is_test)
    weighting = ({"weighting": model.name_weighting(), "view_counts": model.settings_.view_counts}
                 if model_answer else {})
    predicted = predict_names(params, 0, vocabulary, home.positions[rows], home.visual[rows], top_k=1,
                              **weighting).best
    right: dict[int, list[bool]] = {}
    for row, word in zip(rows, predicted, strict=True):
        right.setdefault(int(places[row]), []).append(word is not None and normalize_name(word)
                                                      in names[places[row]])
    a_n = float(np.mean([np.mean(v) for v in right.values()]))
    rng = np.random.default_rng(seed)
    all_names = sorted(n for n in set().union(*names) if n in said)  # a name never said is not asked
    xy = home.positions[:, :2]
    scores = []
    for name in all_names:  # asked as said: without spaces
        try:
            drawn = predict_positions(params, 0, vocabulary, name, n=10, rng=rng).samples[:, :2]
        except UnknownNameError:
            scores.append(0.0)
            continue
        nearest = np.argmin(((drawn[:, None, :] - xy[None, :, :]) ** 2).sum(-1), axis=1)
        scores.append(float(np.mean([name in names[places[i]] for i in nearest])))
    return a_n, float(np.mean(scores))


def run_cc4f(args: argparse.Namespace) -> None:
    """CC4F learnt alone, 5 folds × trials, unspaced and spaced."""
    rows = []
    for kind, spaced in (("unspaced", False), ("spaced", True)):
        env, places, names = cc4f_home(Path(args.data), spaced)
        said = {w for s in cc4f_home(Path(args.data), True)[0].sentences if s for w in s.split()}
        start = time.perf_counter()
        a_n, a_p = [], []
        for trial in range(args.trials):
            for fold in range(5):
                n, p = cc4f_scores(env, places, names, fold, args.seed + trial, args.iterations, said,
                                   args.hyper, args.model_answer)
                a_n.append(n)
                a_p.append(p)
        from spco.data.language import Vocabulary

        vocabulary = Vocabulary.from_sentences(env.sentences)
        print(f"{kind}: vocabulary of all 100 sentences ({len(vocabulary)}): {', '.join(vocabulary.words)}",
              flush=True)
        rows.append((kind, np.array(a_n), np.array(a_p), len(vocabulary), time.perf_counter() - start))
    _table(rows, "folds × trials")


# ------------------------------------------------------------------------------------- output
def mean_interval(values: np.ndarray) -> str:
    """``mean ± half-width of the 95 % interval of the mean`` of the finite ``values``."""
    values = values[np.isfinite(values)]
    if values.size < 2:
        return f"{values.mean():.3f}"
    half = 1.96 * values.std(ddof=1) / math.sqrt(values.size)
    return f"{values.mean():.3f} ± {half:.3f}"


def _table(rows: list[tuple[str, np.ndarray, np.ndarray, int, float]], over: str) -> None:
    print(f"\n| text | runs ({over}) | A_n | A_p | words | seconds |")
    print("|---|---:|---:|---:|---:|---:|")
    for kind, a_n, a_p, words, seconds in rows:
        print(f"| {kind} | {a_n.size} | {mean_interval(a_n)} | {mean_interval(a_p)} | {words} "
              f"| {seconds:.0f} |")
    base = {kind: (a_n.mean(), a_p.mean()) for kind, a_n, a_p, *_ in rows}
    if "unspaced" in base and "spaced" in base:
        dn = base["unspaced"][0] - base["spaced"][0]
        dp = base["unspaced"][1] - base["spaced"][1]
        print(f"\nunspaced − spaced: A_n {dn:+.3f}, A_p {dp:+.3f} (target: within ±0.05)")
    print("(mean ± half-width of the 95 % interval of the mean, normal approximation)")


def main() -> None:
    """Parse the command line and run one of the two benchmarks."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    sub = parser.add_subparsers(dest="which", required=True)
    sig = sub.add_parser("sigverse", help="the general experiment on Japanese SIGVerse homes")
    sig.add_argument("--data", required=True, help="the SIGVerse folder")
    sig.add_argument("--regions", required=True, help="sigverse_regions.json")
    sig.add_argument("--out", required=True, help="folder for the Japanese homes and the results")
    sig.add_argument("--trials", type=int, default=5)
    sig.add_argument("--iterations", type=int, default=200)
    sig.add_argument("--jobs", type=int, default=1)
    sig.add_argument("--seed", type=int, default=0)
    sig.add_argument("--english", action="store_true", help="also the original English homes")
    cc = sub.add_parser("cc4f", help="CC4F learnt alone")
    cc.add_argument("--data", required=True, help="the cc4f_turtlebot2 folder")
    cc.add_argument("--trials", type=int, default=4)
    cc.add_argument("--iterations", type=int, default=200)
    cc.add_argument("--seed", type=int, default=0)
    cc.add_argument("--set", nargs="+", action="extend", default=[], metavar="NAME=VALUE",
                    help="transfer hyperparameters of the fit (as spco fit --set), e.g. place_channel=home")
    cc.add_argument("--model-answer", action="store_true",
                    help="names with the model's own weighting (e.g. name_answer=looks) instead of MI")
    args = parser.parse_args()
    if args.which == "cc4f":
        from spco.errors import ConfigurationError
        from spco.model.hyperparameters import TransferHyperparameters

        try:
            args.hyper = TransferHyperparameters().with_settings(list(args.set)) if args.set else None
        except ConfigurationError as exc:
            parser.error(f"--set: {exc}")
    (run_sigverse if args.which == "sigverse" else run_cc4f)(args)


if __name__ == "__main__":
    main()
