"""How much is a room's evidence worth, and what would a room-level account of the views answer?
Development views only (``benchmarks/calibration/SPLIT.md``, ``development-new``).

Two measurements (benchmarks/README.md, "Issue 29: the view-weight estimate and a room's evidence"):

1. ``--units``: on the experienced homes of each ``development-new`` knowledge (the paper's first N
   homes without 2LDK_3 and 1LDK_3), with their ground-truth place labels, the view weight w of least
   leave-one-home-out log loss (:func:`spco.model.view_fit.view_weight_losses`) with the *view* as
   the unit, and with the *room* as the unit (a home's views of one place pooled into one count
   vector, its proportions counted as w draws).
2. ``--models OUT`` (the ``--out`` of a ``benchmarks/calibration.py --sets development-new`` run):
   every training sample of the two new homes answered by its *region* of the adapted home (or its
   ground-truth room): the region's views pooled, their proportions counted as w draws under each
   concept's φ^v of the knowledge (prior G_0), names from the knowledge's φ^w — a room-level
   answer — beside ``what``'s answers from the run's ``predictions.jsonl``.

    python benchmarks/calibration_rooms.py --data D/sigverse --images D/sigverse_images --units
    python benchmarks/calibration_rooms.py --data D/sigverse --images D/sigverse_images \\
        --models /tmp/cal --weights colour-hog:4=8,colour-hog:6=11.3
"""

from __future__ import annotations

import argparse
import json
import sys
import warnings
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np
import scipy.sparse as sp
from scipy.special import logsumexp

sys.path.insert(0, str(Path(__file__).resolve().parent))
import calibration as cal

NEW_HOMES = cal.SETS["development-new"]["homes"]
SIZES = cal.SETS["development-new"]["sizes"]


def _prepared(rows: list[Any], labels: list[str], homes: list[int], n_homes: int) -> tuple[Any, np.ndarray]:
    from spco.model.state import PreparedData

    names = sorted(set(labels))
    concepts = np.array([names.index(name) for name in labels])
    visual = sp.csr_array(sp.vstack(rows).astype(np.int64))
    n = visual.shape[0]
    words = sp.csr_array((np.ones(n, dtype=np.int64), (np.arange(n), concepts)), shape=(n, len(names)))
    home_of = np.asarray(homes)
    data = PreparedData(positions=np.zeros((n, 4)), homes=home_of, visual=visual, words=words,
                        n_homes=n_homes, offsets=np.searchsorted(home_of, np.arange(n_homes + 1)),
                        position_scale=1.0, map_centres=np.zeros((n_homes, 4)))
    return data, concepts


def unit_weights(homes: Sequence[Any], alpha_visual: float, alpha_word: float) -> dict[str, float | None]:
    """The leave-one-home-out view weight with the view and with the room (pooled) as the unit."""
    from spco.model.view_fit import estimate_view_weight, home_concept_totals, view_weight_losses

    units: dict[str, tuple[list, list, list]] = {"view": ([], [], []), "room": ([], [], [])}
    for e, home in enumerate(homes):
        train = np.flatnonzero(~home.is_test & (np.asarray(home.visual.sum(axis=1)).ravel() > 0))
        labels = [home.labels()[i] for i in train]
        keep = [i for i, name in zip(train, labels, strict=True) if name is not None]
        names = [home.labels()[i] for i in keep]
        visual = sp.csr_array(home.visual)[keep]
        units["view"][0].append(visual)
        units["view"][1].extend(names)
        units["view"][2].extend([e] * len(names))
        for name in sorted(set(names)):
            rows = [j for j, other in enumerate(names) if other == name]
            units["room"][0].append(sp.csr_array(visual[rows].sum(axis=0)[None, :]))
            units["room"][1].append(name)
            units["room"][2].append(e)
    out: dict[str, float | None] = {}
    for unit, (rows, labels, home_of) in units.items():
        data, concepts = _prepared(rows, labels, home_of, len(homes))
        totals, taught, words = home_concept_totals(data, concepts, int(concepts.max()) + 1)
        losses, used = view_weight_losses(data, concepts, totals, taught, words, alpha_visual, alpha_word)
        out[unit] = estimate_view_weight(losses, used)
    return out


def _ece(confidence: np.ndarray, right: np.ndarray, bins: int = 10) -> float:
    index = np.minimum((confidence * bins).astype(int), bins - 1)
    return float(sum(abs(right[index == b].mean() - confidence[index == b].mean()) * (index == b).sum()
                     for b in range(bins) if (index == b).any()) / confidence.size)


def room_answers(models: Path, data: Path, images: Path | None, features: str, size: int,
                 seeds: Sequence[int], weight: float | None) -> dict[str, tuple[np.ndarray, np.ndarray]]:
    """(confidence, right) of every training sample of the new homes: by its adapted region, by its
    ground-truth room (both room-level answers at ``weight``, default the knowledge's w), and
    ``what``'s (the run's predictions)."""
    import spco.knowledge as kn

    answers: dict[str, tuple[list, list]] = {"region": ([], []), "room": ([], []), "what": ([], [])}
    predictions = [json.loads(line) for line in (models / "predictions.jsonl").read_text().splitlines()]
    for seed in seeds:
        knowledge = kn.load_knowledge(models / "models" / f"knowledge_{features}_{size}_{seed}.spco")
        w = weight if weight is not None else knowledge.hyperparameters.view_weight()
        words = list(knowledge.vocabulary.words)
        names = np.flatnonzero(knowledge.name_mask)
        phi_w = np.exp(knowledge.log_phi_words)[:, names]
        phi_w /= phi_w.sum(axis=1, keepdims=True)
        for name in NEW_HOMES:
            model = kn.load_home_model(models / "models" / f"home_{features}_{size}_{seed}_{name}.spco")
            home = cal._load(data, images, [name], features, 0)[0]
            labels = np.array(home.labels(), dtype=object)
            visual = sp.csr_array(model.visual, dtype=np.float64)
            for unit, groups in (("region", np.asarray(model.state.regions)), ("room", labels)):
                for group in set(groups.tolist()):
                    rows = np.flatnonzero(groups == group)
                    pooled = np.asarray(visual[rows].sum(axis=0)).ravel()
                    log_post = min(1.0, w / max(pooled.sum(), 1.0)) * (knowledge.log_phi_visual @ pooled)
                    log_post = log_post + knowledge.log_g0
                    p_names = np.exp(log_post - logsumexp(log_post)) @ phi_w
                    best = int(np.argmax(p_names))
                    for t in rows:
                        answers[unit][0].append(p_names[best])
                        answers[unit][1].append(words[names[best]] == labels[t])
        for row in predictions:
            if (row["features"], row["size"], row["seed"]) == (features, size, seed):
                answers["what"][0].append(row["p_after"])
                answers["what"][1].append(row["after"] == row["label"])
    return {k: (np.asarray(c, dtype=np.float64), np.asarray(r, dtype=bool)) for k, (c, r) in answers.items()}


def main(argv: Sequence[str] | None = None) -> None:
    """Print the measurements (module docstring)."""
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--data", type=Path, required=True)
    parser.add_argument("--images", type=Path, default=None)
    parser.add_argument("--features", default="colour-hog,fc7")
    parser.add_argument("--sizes", default=",".join(map(str, SIZES)))
    parser.add_argument("--units", action="store_true",
                        help="the view and room weights of the experienced homes")
    parser.add_argument("--models", type=Path, default=None, help="a calibration.py --out (development-new)")
    parser.add_argument("--seeds", type=int, default=3, help="seeds 0..N-1 of --models")
    parser.add_argument("--weights", default="", help="features:size=w of the room-level answer "
                                                       "(default: the knowledge's w)")
    args = parser.parse_args(argv)
    warnings.filterwarnings("ignore")
    from spco.evaluation.config import PAPER_EXPERIENCED_HOMES
    from spco.model.hyperparameters import TransferHyperparameters

    hyper = TransferHyperparameters()
    features = [f for f in args.features.split(",") if f]
    sizes = [int(s) for s in args.sizes.split(",") if s]
    items = [item.split("=") for item in args.weights.split(",") if item]
    weights = {key: float(value) for key, value in items}
    for f in features:
        for size in sizes:
            if args.units:
                names = [h for h in PAPER_EXPERIENCED_HOMES[:size] if h not in NEW_HOMES]
                homes = cal._load(args.data, args.images, names, f, 100)
                w = unit_weights(homes, hyper.alpha_visual, hyper.alpha_word)
                print(f"{f}, {len(names)} experienced homes: least leave-one-home-out loss at w = "
                      f"{w['view']:.3g} (a view), {w['room']:.3g} (a room's views pooled)", flush=True)
            if args.models is not None:
                weight = weights.get(f"{f}:{size}")
                for way, (conf, right) in room_answers(args.models, args.data, args.images, f, size,
                                                       range(args.seeds), weight).items():
                    wrong = ~right
                    used = weight if weight is not None and way != "what" else "the model's"
                    print(f"{f}, {size} homes, {way:6s} (w {used}): "
                          f"{conf.size} answers, ECE {_ece(conf, right):.3f}, accuracy {right.mean():.3f}, "
                          f"mean confidence {conf.mean():.3f}, wrong at p >= 0.99: "
                          f"{(wrong & (conf >= 0.99)).sum()} of {wrong.sum()}", flush=True)


if __name__ == "__main__":
    main()
