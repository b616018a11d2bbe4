"""The view weight w: one number, estimated from the experienced homes, used by the sampler and by
every answer (``spco.model.view_fit.estimate_view_weight``; docs/model.md, "A view's evidence")."""

from __future__ import annotations

import dataclasses
import math
import warnings

import numpy as np
import pytest
import scipy.sparse as sp

import spco.knowledge as kn
from spco.errors import ConfigurationError
from spco.model.answer_settings import AnswerSettings
from spco.model.hyperparameters import ESTIMATE, VIEW_COUNTS, TransferHyperparameters
from spco.model.state import PreparedData, SamplerSettings
from spco.model.view_fit import (
    VIEW_WEIGHT_GRID,
    estimate_view_weight,
    home_concept_totals,
    view_weight_losses,
)


def _homes(rng: np.random.Generator, n_homes: int, spread: float | None, n_views: int = 12,
           total: int = 2000, D: int = 60, L: int = 3) -> tuple[PreparedData, np.ndarray]:
    """``n_homes`` homes of L places, every view taught. A place's views are ``total`` counts from
    its own distribution η ~ Dir(spread · θ_l) around its concept's θ_l (``spread=None``: η = θ_l,
    the counts independent draws from the concept)."""
    base = rng.dirichlet(np.full(D, 2.0))
    theta = 0.9 * base + 0.1 * rng.dirichlet(np.full(D, 2.0), size=L)  # concepts alike: few counts decide
    rows, homes, concepts = [], [], []
    for e in range(n_homes):
        for c in range(L):
            eta = theta[c] if spread is None else rng.dirichlet(spread * theta[c] + 1e-3)
            for _ in range(n_views):
                rows.append(rng.multinomial(total, eta))
                homes.append(e)
                concepts.append(c)
    n = len(rows)
    visual = sp.csr_array(np.array(rows, dtype=np.int64))
    words = sp.csr_array((np.ones(n, dtype=np.int64), (np.arange(n), np.array(concepts))), shape=(n, L))
    offsets = np.arange(0, n + 1, L * n_views)
    data = PreparedData(positions=np.zeros((n, 4)), homes=np.array(homes), visual=visual, words=words,
                        n_homes=n_homes, offsets=offsets, position_scale=1.0,
                        map_centres=np.zeros((n_homes, 4)))
    return data, np.array(concepts)


def _estimate(data: PreparedData, concepts: np.ndarray) -> float | None:
    """The estimate of w from ``data`` with the sampler's concepts ``concepts``."""
    totals, taught, words = home_concept_totals(data, concepts, int(concepts.max()) + 1)
    losses, used = view_weight_losses(data, concepts, totals, taught, words, alpha_visual=3.0,
                                      alpha_word=0.01)
    assert used == data.n_samples
    return estimate_view_weight(losses, used)


def test_the_estimate_follows_how_much_a_view_is_worth() -> None:
    """Views whose 2,000 counts are independent draws from their concept get a weight of about
    their counts (every count a draw is right for them); views of places that each look their own
    way (η around θ with a concentration c) get fewer, the fewer the smaller c: the
    leave-one-home-out loss tells them apart, and the estimate is a value of the grid."""
    rng = np.random.default_rng(0)
    independent = _estimate(*_homes(rng, 4, None))
    loose = _estimate(*_homes(rng, 4, 20.0))
    tight = _estimate(*_homes(rng, 4, 200.0))
    assert independent is not None and loose is not None and tight is not None
    assert {independent, loose, tight} <= set(VIEW_WEIGHT_GRID)
    assert loose <= 4 < tight <= 128 < 512 <= independent


def _replicated_homes(rng: np.random.Generator, n_homes: int, draws: int, copies: int, n_views: int = 30,
                      D: int = 40, L: int = 3) -> tuple[PreparedData, np.ndarray]:
    """Homes whose views carry a known number of draws: each view is ``draws`` independent draws
    from its place's θ_l, every draw counted ``copies`` times (``draws × copies`` correlated counts
    that hold exactly ``draws`` draws' information). Scored at w = ``draws`` the power likelihood
    of a view is the multinomial likelihood of its draws: the weight to recover."""
    base = rng.dirichlet(np.full(D, 2.0))
    theta = 0.7 * base + 0.3 * rng.dirichlet(np.full(D, 2.0), size=L)
    rows, homes, concepts = [], [], []
    for e in range(n_homes):
        for c in range(L):
            for _ in range(n_views):
                rows.append(copies * rng.multinomial(draws, theta[c]))
                homes.append(e)
                concepts.append(c)
    n = len(rows)
    visual = sp.csr_array(np.array(rows, dtype=np.int64))
    words = sp.csr_array((np.ones(n, dtype=np.int64), (np.arange(n), np.array(concepts))), shape=(n, L))
    data = PreparedData(positions=np.zeros((n, 4)), homes=np.array(homes), visual=visual, words=words,
                        n_homes=n_homes, offsets=np.arange(0, n + 1, L * n_views), position_scale=1.0,
                        map_centres=np.zeros((n_homes, 4)))
    return data, np.array(concepts)


@pytest.mark.parametrize("draws", [8, 32, 128])
def test_the_estimate_recovers_a_known_weight(draws: int) -> None:
    """Views of ``draws`` draws each, every draw counted 50 times (the counts of a view correlated,
    as an image's are): the estimate is within a factor 2 of ``draws`` — not the views' 50× larger
    count, and not a fixed number. (It is at or one step below ``draws`` in seeds 0–7: φ^v is itself
    estimated from the other homes, so a little less evidence predicts best.)"""
    data, concepts = _replicated_homes(np.random.default_rng(draws), 6, draws, copies=50)
    w = _estimate(data, concepts)
    assert w is not None and draws / 2 <= w <= 2 * draws


@pytest.mark.parametrize("scale, alpha", [(1, 1e-300), (10 ** 12, 3.0), (10 ** 15, 1e-300), (1, 1e300)])
def test_the_estimate_is_finite_at_extremes(scale: int, alpha: float) -> None:
    """Views of one count or of 10^15, α^v from 10^-300 to 10^300, a feature no other home ever saw,
    views left empty (not scored): every loss on the grid is finite, and the estimate is a value of
    the grid."""
    rng = np.random.default_rng(7)
    data, concepts = _replicated_homes(rng, 3, 1, copies=scale, n_views=4)
    visual = data.visual.toarray()
    visual[0] = 0
    visual[0, -1] = scale  # seen by this home only: φ^v of it is α^v / (…) in every other's prediction
    visual[1:, -1] = 0
    data = dataclasses.replace(data, visual=sp.csr_array(visual))
    totals, taught, words = home_concept_totals(data, concepts, 3)
    losses, used = view_weight_losses(data, concepts, totals, taught, words, alpha_visual=alpha,
                                      alpha_word=alpha)
    assert used == int((data.view_totals > 0).sum()) > 0
    assert np.isfinite(losses).all()
    assert estimate_view_weight(losses, used) in VIEW_WEIGHT_GRID


@pytest.mark.parametrize("draws", [8, 128])
def test_the_estimate_predicts_the_words_not_the_start_s_concepts(draws: int) -> None:
    """The start may put one place's taught views in several concepts (as it does on synthetic homes
    with few sweeps: 14 concepts for 8 places). Scored on which of them a view is in — a guess
    whatever the view says — the weight was pushed towards "views say nothing" (a factor 2–3 lower
    here, 1.4 on those homes); scored on the words, the estimate is the same as with one concept
    per place."""
    rng = np.random.default_rng(draws)
    data, concepts = _replicated_homes(rng, 6, draws, copies=50)
    split = concepts + 3 * rng.integers(0, 3, concepts.size)  # each place over 3 concepts at random
    whole, thirds = _estimate(data, concepts), _estimate(data, split)
    assert whole is not None and thirds is not None
    assert whole / math.sqrt(2) - 1e-9 <= thirds <= whole * math.sqrt(2) + 1e-9


def test_nothing_to_estimate_from() -> None:
    """No taught view (or none with a count): no estimate; one home alone is left to the driver."""
    data, concepts = _homes(np.random.default_rng(1), 2, 20.0)
    silent = dataclasses.replace(data, words=sp.csr_array(data.words.shape, dtype=np.int64))
    totals, taught, words = home_concept_totals(silent, concepts, 3)
    losses, used = view_weight_losses(silent, concepts, totals, taught, words, 3.0, 0.01)
    assert used == 0 and estimate_view_weight(losses, used) is None


def test_the_setting_reads_and_resolves() -> None:
    """``view_counts`` is a number (default :data:`VIEW_COUNTS`), none or ``estimate``, which the
    sampler starts from as :data:`VIEW_COUNTS`; anything else is refused naming the field."""
    hyper = TransferHyperparameters()
    assert hyper.view_counts == VIEW_COUNTS and hyper.view_weight() == VIEW_COUNTS
    assert TransferHyperparameters(view_counts=ESTIMATE).view_weight() == VIEW_COUNTS
    assert SamplerSettings.create("exact", True, view_counts=ESTIMATE).view_counts == VIEW_COUNTS
    assert hyper.with_settings(["view_counts=8"]).view_weight() == 8.0
    assert hyper.with_settings(["view_counts=none"]).view_weight() is None
    assert hyper.with_settings(["view_counts=8", "view_counts=estimate"]).view_counts == ESTIMATE
    estimate = hyper.with_settings(["view_counts=estimate"])
    assert TransferHyperparameters.from_dict(estimate.to_dict()).view_counts == ESTIMATE
    for bad in ("sometimes", -1.0, 0.0, math.inf):
        with pytest.raises(ConfigurationError, match="view_counts"):
            TransferHyperparameters(view_counts=bad)


@pytest.fixture(scope="module")
def fitted():
    """A knowledge of 3 synthetic homes (w estimated: ``view_counts="estimate"``) and a new home
    adapted from it."""
    from spco.data.environment import Corpus
    from spco.data.synthetic import SyntheticConfig, generate_homes

    corpus = generate_homes(4, seed=3, config=SyntheticConfig(n_features=128), new_homes=1,
                            specific_rooms=False)
    experienced, new = list(corpus)[:-1], list(corpus)[-1]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        knowledge = kn.fit_knowledge(Corpus(experienced), n_iterations=6, random_state=0,
                                     hyperparameters=TransferHyperparameters(view_counts=ESTIMATE))
        home = kn.adapt(knowledge, new, n_iterations=4, random_state=0)
    return knowledge, home, experienced


def test_the_knowledge_carries_the_estimate_and_every_answer_uses_it(fitted) -> None:
    """The fit estimates w from its homes and the knowledge file holds the number (and the curve
    it came from); the home adapted from it holds the same w, and `what` scores a view as that
    many draws: its probabilities are the model's p(name | pose, view) at w, and differ from those
    at another weight."""
    knowledge, home, _ = fitted
    record = knowledge.provenance["view_weight"]
    w = knowledge.hyperparameters.view_counts
    assert record["estimated"] is True and record["view_counts"] == w and w in VIEW_WEIGHT_GRID
    assert record["views"] > 0 and len(record["mean_log_loss"]) == len(VIEW_WEIGHT_GRID)
    assert min(record["mean_log_loss"]) == pytest.approx(record["mean_log_loss"][VIEW_WEIGHT_GRID.index(w)],
                                                         abs=1e-3)
    assert home.hyperparameters.view_counts == w
    pose = home.positions[0]
    view = home.visual[[0]].toarray()[0]
    answer = kn.what(home, float(pose[0]), float(pose[1]), math.atan2(pose[2], pose[3]), visual=view)
    from spco.knowledge.queries import home_rooms
    from spco.model.confidence import answer_names

    params = kn.answer_parameters(home)
    rooms = home_rooms(home)  # the robot's answer: the room account (docs/model.md, "A room's evidence")
    same = answer_names(params, 0, home.vocabulary, pose[None], view[None], weighting=home.weighting,
                        view_counts=w, rooms=rooms, settings=AnswerSettings())
    other = answer_names(params, 0, home.vocabulary, pose[None], view[None], weighting=home.weighting,
                         view_counts=None, rooms=rooms, settings=AnswerSettings())
    assert np.allclose(answer.word_probabilities, same.word_probabilities)
    assert not np.allclose(same.word_probabilities, other.word_probabilities)


def test_a_given_weight_is_kept(fitted) -> None:
    """A number given for ``view_counts`` (the default's too) is used as it is: nothing is estimated
    or recorded."""
    from spco.data.environment import Corpus

    _, _, experienced = fitted
    hyper = TransferHyperparameters(view_counts=3.0)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        knowledge = kn.fit_knowledge(Corpus(experienced), hyperparameters=hyper, n_iterations=3,
                                     random_state=0)
    assert knowledge.hyperparameters.view_counts == 3.0
    assert "view_weight" not in knowledge.provenance


def test_the_estimate_is_the_same_for_any_number_of_shards() -> None:
    """Each shard scores its own homes against all homes' totals; summed in home order, the estimate
    and the chain after it are the same with one worker or two."""
    from spco.data.synthetic import SyntheticConfig
    from spco.model.driver import LocalEngine
    from spco.model.sources import SyntheticHomes
    from spco.model.transfer import SpatialConceptModel

    source = SyntheticHomes.create(5, seed=2, config=SyntheticConfig(n_features=64, n_train=12), new_homes=1)
    model = SpatialConceptModel(TransferHyperparameters(view_counts=ESTIMATE), variant="exact",
                                random_state=0, prune_words=True)
    hyper, settings = model.checked_hyperparameters(), model.sampler_settings()
    runs = []
    for shards in (1, 2):
        run = LocalEngine(shards).start_source(source, hyper, settings, np.random.default_rng(5))
        runs.append((run.view_weight, run.fit(3), run.hyper.view_counts, run.settings.view_counts))
        run.close()
    (first, trace1, h1, s1), (second, trace2, h2, s2) = runs
    assert first == second and first["estimated"] and h1 == s1 == first["view_counts"] == h2 == s2
    np.testing.assert_array_equal(trace1, trace2)
