"""Why `what` was sure of its wrong answers: the evidence, on the development views only.

Reads the development home files that ``benchmarks/calibration.py`` kept in ``--models`` (new homes
1DK_8 and 3LDK_9, see ``benchmarks/calibration/SPLIT.md``) and prints, per view kind and
experienced-home set:

- the median gap (nats) between the best and the second concept given the view alone, under
  (a) the model's multinomial (every count a draw), (b) a Dirichlet-multinomial with θ^v's own
  posterior uncertainty (concentration δ^v + the concept's visual counts in the home), (c) a
  Dirichlet-multinomial with a precision s fitted by maximum likelihood to the home's training views
  (in-sample overdispersion), (d) the view counted as the model's view weight w draws
  (``view_counts``, 16 by default);
  and the share of test views whose concept is decided at P(l | view) ≥ 0.99 under each;
- of the wrong answers of the model's own p(w | x, v): how many have the right name's concept
  ahead given the position alone (the view overruled the position), and how many come from a
  concept the knowledge does not use (G_0 < FREE_CONCEPT_WEIGHT: its name is a prior draw).

    python benchmarks/calibration_cause.py --data ../shared/datasets/sigverse \\
        --images ../shared/datasets/sigverse_images --models results/calibration/models
"""

from __future__ import annotations

import argparse
import re
import warnings
from collections import defaultdict
from pathlib import Path
from typing import Any

import numpy as np
import scipy.sparse as sp
from scipy.optimize import minimize_scalar
from scipy.special import gammaln, logsumexp

DEVELOPMENT_HOMES = ("1DK_8", "3LDK_9")


def dirichlet_multinomial(counts: sp.csr_array, theta: np.ndarray, precision: np.ndarray) -> np.ndarray:
    """(n, L) log DirMult(v | precision_l θ_l) without the multinomial coefficient (the same for
    every concept). counts (n, D) CSR; theta (L, D); precision (L,)."""
    totals = np.asarray(counts.sum(axis=1)).ravel()
    out = np.empty((counts.shape[0], theta.shape[0]))
    for i in range(counts.shape[0]):
        lo, hi = counts.indptr[i], counts.indptr[i + 1]
        idx, v = counts.indices[lo:hi], counts.data[lo:hi]
        a = precision[:, None] * theta[:, idx]
        out[i] = (gammaln(a + v) - gammaln(a)).sum(1) + gammaln(precision) - gammaln(precision + totals[i])
    return out


def fitted_precision(counts: sp.csr_array, theta: np.ndarray, concepts: np.ndarray) -> float:
    """Maximum-likelihood precision s of DirMult(v_i | s θ_{c_i}) over a home's training views."""
    def loss(log_s: float) -> float:
        ll = dirichlet_multinomial(counts, theta, np.full(theta.shape[0], np.exp(log_s)))
        return -float(ll[np.arange(concepts.size), concepts].sum())

    return float(np.exp(minimize_scalar(loss, bounds=(0.0, 14.0), method="bounded").x))


def _gap(loglik: np.ndarray) -> tuple[float, float]:
    top = np.sort(loglik, axis=1)
    post = np.exp(loglik - logsumexp(loglik, axis=1, keepdims=True)).max(axis=1)
    return float(np.median(top[:, -1] - top[:, -2])), float((post >= 0.99).mean())


#: The row of the view counted as the model's view weight draws.
TEMPERED = "w = the model's view weight"


def _test_views(data: Path, images: Path | None, features: str, name: str) -> tuple:
    """The test views of the development home ``name`` with ``features``: positions, visual counts and
    the labels."""
    from spco.data.loading import load_homes
    from spco.features import build_extractor

    kw = {} if features == "fc7" else {"extractor": build_extractor(features), "images": images}
    home = load_homes(data, names=[name], teaching_rate=0, **kw)[0]
    labels = np.array([lab for lab, t in zip(home.labels(), home.is_test, strict=True) if t])
    return (*home.test_observations(), labels)


def _add_view_gaps(row: dict[str, list[float]], model: Any, visual: sp.csr_array) -> None:
    """The best-second concept gap and the share decided at P ≥ 0.99, given the view alone, under each
    view likelihood."""
    from spco.model.prediction import _visual_log_likelihood

    theta = model.parameters.visual_probabilities[0]
    in_concept = np.zeros(theta.shape[0])
    np.add.at(in_concept, model.state.concepts, np.asarray(model.visual.sum(axis=1)).ravel())
    for key, loglik in (
        ("multinomial", _visual_log_likelihood(theta, visual)),
        ("theta uncertainty", dirichlet_multinomial(
            visual, theta, model.hyperparameters.delta_visual + in_concept)),
        ("in-sample DirMult", dirichlet_multinomial(
            visual, theta, np.full(theta.shape[0], fitted_precision(
                sp.csr_array(model.visual, dtype=np.float64), theta, model.state.concepts)))),
        (TEMPERED, _visual_log_likelihood(theta, visual, model.hyperparameters.view_weight())),
    ):
        gap, decided = _gap(loglik)
        row[key + " gap"].append(gap)
        row[key + " decided"].append(decided)


def _add_wrong_answers(row: dict[str, list[float]], model: Any, positions: np.ndarray, visual: sp.csr_array,
                       labels: np.ndarray) -> None:
    """Of the wrong answers of the model's p(w | x, v): at p ≥ 0.99, the position alone favouring the
    right name, answered from a free concept."""
    from spco.model.home_shard import FREE_CONCEPT_WEIGHT
    from spco.model.prediction import concept_posterior, predict_names

    params = model.parameters
    before = predict_names(params, 0, model.vocabulary, positions, visual, top_k=1,
                           weighting=model.weighting)  # type: ignore[arg-type]
    wrong = np.array(before.best) != labels
    by_position = concept_posterior(params, 0, positions, None, use_vision=False)
    both = concept_posterior(params, 0, positions, visual)
    words = np.asarray(model.vocabulary.words)
    theta_w = params.word_probabilities[0] * params.word_mask[None, :]
    names = words[theta_w.argmax(axis=1)]  # each concept's name
    free = np.exp(model.knowledge.log_g0) < FREE_CONCEPT_WEIGHT
    for i in np.flatnonzero(wrong):
        right_concepts = names == labels[i]
        chosen = int(both[i].argmax())
        row["wrong"].append(1)
        row["position favoured the right name"].append(
            float(by_position[i, right_concepts].sum() > by_position[i, chosen]))
        row["from a free concept"].append(float(free[chosen]))
        row["wrong at p >= 0.99"].append(float(before.confidence[i] >= 0.99))


def _print_table(table: dict[tuple[str, int], dict[str, list[float]]]) -> None:
    for (features, size), row in sorted(table.items()):
        print(f"\n{features}, {size} experienced homes ({len(row['multinomial gap'])} home files)")
        for key in ("multinomial", "theta uncertainty", "in-sample DirMult", TEMPERED):
            gap = np.median(row[key + " gap"])
            print(f"  view alone, {key:<18}: median best-second gap {gap:9.2f} nats; "
                  f"views decided at P >= 0.99: {np.mean(row[key + ' decided']):.2f}")
        count = {k: int(sum(v)) for k, v in row.items() if not k.endswith(("gap", "decided"))}
        print(f"  wrong answers of the model's p: {count.get('wrong', 0)}; at p >= 0.99: "
              f"{count.get('wrong at p >= 0.99', 0)}; the position alone favoured the right name: "
              f"{count.get('position favoured the right name', 0)}; answered from a concept the knowledge "
              f"does not use: {count.get('from a free concept', 0)}")


def main() -> None:
    """Print the evidence table."""
    import spco.knowledge as kn

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--data", type=Path, required=True)
    parser.add_argument("--images", type=Path, default=None)
    parser.add_argument("--models", type=Path, required=True, help="calibration.py's --out/models")
    args = parser.parse_args()
    warnings.filterwarnings("ignore")
    pattern = re.compile(r"home_(colour-hog|fc7)_(\d+)_(\d+)_(.+)\.spco")
    table: dict[tuple[str, int], dict[str, list[float]]] = defaultdict(lambda: defaultdict(list))
    views: dict[tuple[str, str], tuple] = {}
    for path in sorted(args.models.glob("home_*.spco")):
        match = pattern.fullmatch(path.name)
        if not match or match.group(4) not in DEVELOPMENT_HOMES:
            continue
        features, size, name = match.group(1), int(match.group(2)), match.group(4)
        if (features, name) not in views:
            views[features, name] = _test_views(args.data, args.images, features, name)
        positions, visual, labels = views[features, name]
        visual = sp.csr_array(visual, dtype=np.float64)
        model = kn.load_home_model(path)
        _add_view_gaps(table[features, size], model, visual)
        _add_wrong_answers(table[features, size], model, positions, visual, labels)
    _print_table(table)


if __name__ == "__main__":
    main()
