"""Numerically sound at the edges (issue 29, point 4): positions, counts and hyperparameters from
1e-300 to 1e308 through fit, adapt and teach give a clear error (a :class:`~spco.errors.SpcoError`
naming the problem) or a correct result (finite parameters, probabilities that sum to one) — never a
traceback from a kernel."""

from __future__ import annotations

import dataclasses
import warnings

import numpy as np
import pytest
import scipy.sparse as sp

from spco import knowledge as kn
from spco.data.environment import MAX_COUNT, MAX_SPAN, Corpus, Environment
from spco.errors import SpcoError
from spco.model.hyperparameters import TransferHyperparameters

NAMES = ("kitchen", "bedroom", "toilet")


def _home(name: str, seed: int, scale: float = 1.0, count_scale: float = 1.0) -> Environment:
    """Three places 4 m apart (× ``scale``), 8 samples each, views of 24 features (counts × ``count_scale``),
    every sample taught "this is the <place>"."""
    rng = np.random.default_rng(seed)
    n_per, D = 8, 24
    place = np.repeat(np.arange(3), n_per)
    xy = np.array([[0.0, 0.0], [4.0, 0.0], [0.0, 4.0]])[place] + rng.normal(0.0, 0.5, (place.size, 2))
    heading = rng.uniform(-np.pi, np.pi, place.size)
    positions = np.column_stack([xy * scale, np.sin(heading), np.cos(heading)])
    looks = rng.dirichlet(np.full(D, 0.3), size=3)
    counts = np.stack([rng.multinomial(200, looks[p]) for p in place]).astype(np.float64) * count_scale
    return Environment(name=name, ids=np.arange(place.size), positions=positions,
                       visual=sp.csr_array(counts), sentences=tuple(f"this is the {NAMES[p]}" for p in place),
                       is_test=np.zeros(place.size, dtype=bool))


def _finite(home: kn.HomeModel) -> None:
    params = home.parameters
    for field in ("region_means", "region_covariances", "visual_probabilities", "word_probabilities",
                  "concept_weights", "region_weights"):
        assert np.isfinite(np.asarray(getattr(params, field))).all(), field
    answer = kn.what(home, float(home.positions[0, 0]), float(home.positions[0, 1]), 0.0,
                     visual=home.visual[[0]].toarray()[0])
    assert np.isfinite(answer.word_probabilities).all()
    total = float(answer.word_probabilities.sum())
    # names that sum to one, or none at all when a short chain pruned every word (no usable name)
    assert abs(total - 1.0) < 1e-9 or (total == 0.0 and answer.words.shape[1] == 0)


def _learn(scale: float = 1.0, count_scale: float = 1.0,
           hyper: TransferHyperparameters | None = None) -> kn.HomeModel:
    """fit (2 homes) → adapt (a third) → teach one sample: the whole path a user takes."""
    homes = [_home(f"h{i}", i, scale, count_scale) for i in range(3)]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        knowledge = kn.fit_knowledge(Corpus(homes[:2]), n_iterations=2, random_state=0, hyperparameters=hyper)
        home = kn.adapt(knowledge, homes[2], n_iterations=1, random_state=0)
        return kn.teach(home, {int(home.ids[0]): "this is the kitchen"}, n_sweeps=1, random_state=0)


@pytest.mark.parametrize("scale", [1e-300, 1e-150, 1e-9, 1.0, 1e3, 1e5, 1e7, 1e150, 1e307])
def test_positions_of_every_magnitude(scale: float) -> None:
    """Positions × 10^k: learnt (finite parameters, names that sum to one) while the home's span is
    within ``MAX_SPAN``; refused with a message naming the span beyond it."""
    if 8.0 * scale > MAX_SPAN:  # the places span ~6 m × scale
        with pytest.raises(SpcoError, match=r"span|beyond"):
            _learn(scale=scale)
        return
    _finite(_learn(scale=scale))


@pytest.mark.parametrize("count_scale", [1e9, 1e15, 1e300])
def test_view_counts_of_every_magnitude(count_scale: float) -> None:
    """Counts × 10^k are the same view (the model observes its proportions as S^v draws): learnt,
    finite, up to ``MAX_COUNT`` per feature; beyond it refused with a message (int64 sums)."""
    if 400 * count_scale > MAX_COUNT:  # ~200 counts per view before scaling
        with pytest.raises(SpcoError, match="counts above"):
            _learn(count_scale=count_scale)
        return
    _finite(_learn(count_scale=count_scale))


def test_fractional_tiny_counts_are_refused_clearly() -> None:
    """Counts of 1e-300 are not counts: refused at load with a message, not learnt as zeros."""
    with pytest.raises(SpcoError):
        _learn(count_scale=1e-300)


@pytest.mark.parametrize("field", ["kappa0", "alpha_visual", "alpha_word", "delta_visual", "delta_word",
                                   "gamma", "gamma0", "beta"])
@pytest.mark.parametrize("value", [1e-300, 1e308])
def test_hyperparameters_of_every_magnitude(field: str, value: float) -> None:
    """Each positive hyperparameter at 1e-300 … 1e308: refused by name, or learnt with finite
    parameters."""
    try:
        hyper = dataclasses.replace(TransferHyperparameters(), **{field: value})
        home = _learn(hyper=hyper)
    except SpcoError as exc:
        assert field in str(exc) or "hyperparameter" in str(exc)
        return
    _finite(home)


@pytest.mark.parametrize("value", [1e-300, 1e308])
def test_nu0_and_psi0_at_the_extremes(value: float) -> None:
    """ν0 and Ψ0 at the extremes: refused by name, or learnt with finite parameters."""
    for changes in ({"nu0": 3.0 + value}, {"psi0": (value, value, 0.5, 0.5)}):
        try:
            home = _learn(hyper=dataclasses.replace(TransferHyperparameters(), **changes))
        except SpcoError as exc:
            assert next(iter(changes)) in str(exc), exc
            continue
        _finite(home)
