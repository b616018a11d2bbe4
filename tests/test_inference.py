"""Issue 16, inference: posterior-averaged predictions, places not learnt in a home, the CRT's
large-count branch, smooth initialisation and concentration rules, one validation path for
prediction input, and scikit-learn's parameter protocol."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.sparse as sp
from numpy.testing import assert_allclose
from scipy import stats

from spco.data.language import Vocabulary
from spco.errors import ConfigurationError
from spco.knowledge.fit import CONCENTRATION_PRIOR_SAMPLES, _concentration
from spco.knowledge.views import _visual_row
from spco.model import gibbs
from spco.model.hyperparameters import TransferHyperparameters
from spco.model.kernels.crt import sample_crt, sample_crt_totals
from spco.model.parameters import ConceptParameters
from spco.model.position_prediction import (
    LEARNT_SUPPORT,
    name_support,
    predict_positions,
    region_posterior_for_name,
)
from spco.model.posterior import ParameterAverage, thinned_sweeps
from spco.model.prediction import predict_names, validate_poses, validate_visual_counts
from spco.model.transfer import SpCoA, SpCoTransfer, clone, export_parameters

SMALL = TransferHyperparameters(n_concepts=6, n_regions=8)


# ----------------------------------------------------------------------------- 1. posterior average


def test_thinned_sweeps() -> None:
    assert thinned_sweeps(200) == list(range(154, 200, 5))
    assert thinned_sweeps(1) == [0]
    assert thinned_sweeps(3) == [2]
    assert thinned_sweeps(12) == [9, 10, 11]
    assert all(s[-1] == n - 1 for n in (1, 5, 11, 40) for s in [thinned_sweeps(n)])


def _fake_state(rng: np.random.Generator, concepts: np.ndarray, regions: np.ndarray, L: int, K: int,
                V: int, D: int) -> gibbs.GibbsState:
    def log_simplex(*shape: int) -> np.ndarray:
        return np.log(rng.dirichlet(np.ones(shape[-1]), size=shape[:-1]))

    a = rng.normal(size=(1, K, 4, 4))
    region_counts = np.bincount(regions, minlength=K)[None]
    return gibbs.GibbsState(
        concepts=concepts, regions=regions, log_g=log_simplex(1, L), log_g0=log_simplex(L),
        log_pi=log_simplex(1, L, K), means=rng.normal(size=(1, K, 4)),
        covariances=a @ np.swapaxes(a, -1, -2) + np.eye(4), log_theta_v=log_simplex(1, L, D),
        log_theta_w=log_simplex(1, L, V), log_phi_v=log_simplex(L, D), log_phi_w=log_simplex(L, V),
        word_mask=np.ones(V, dtype=bool), region_counts=region_counts)


def _relabelled(state: gibbs.GibbsState, perm_c: np.ndarray, perm_r: np.ndarray) -> gibbs.GibbsState:
    """The same state with concept l called perm_c[l] and region m called perm_r[m]."""
    inv_c, inv_r = np.argsort(perm_c), np.argsort(perm_r)
    log_pi = state.log_pi[:, inv_c][:, :, inv_r]
    return gibbs.GibbsState(
        concepts=perm_c[state.concepts], regions=perm_r[state.regions], log_g=state.log_g[:, inv_c],
        log_g0=state.log_g0, log_pi=log_pi, means=state.means[:, inv_r],
        covariances=state.covariances[:, inv_r], log_theta_v=state.log_theta_v[:, inv_c],
        log_theta_w=state.log_theta_w[:, inv_c], log_phi_v=state.log_phi_v, log_phi_w=state.log_phi_w,
        word_mask=state.word_mask, region_counts=state.region_counts[:, inv_r])


def test_average_of_relabelled_copies_is_the_state_itself() -> None:
    """Label switching between sweeps must not mix concepts: averaging a state with relabelled
    copies of itself gives back that state (in the labels of the last one)."""
    rng = np.random.default_rng(0)
    L, K, V, D, n = 5, 6, 4, 7, 40
    concepts, regions = rng.integers(0, 4, n), rng.integers(0, 5, n)  # concept 4, region 5 unused
    first = _fake_state(rng, concepts, regions, L, K, V, D)
    perm_c, perm_r = rng.permutation(L), rng.permutation(K)
    second = _relabelled(first, perm_c, perm_r)
    average = ParameterAverage(np.zeros(n, dtype=np.int64), 1.0)
    average.add(first)
    average.add(second)
    data = gibbs.PreparedData(positions=np.zeros((n, 4)), homes=np.zeros(n, dtype=np.int64),
                              visual=sp.csr_array((n, D)), words=sp.csr_array((n, V)), n_homes=1,
                              offsets=np.array([0, n]), position_scale=1.0, map_centres=np.zeros((1, 4)))
    expected = export_parameters(second, data)
    result = average.result(second)
    for name in ("concept_weights", "region_weights", "region_means", "region_covariances",
                 "word_probabilities", "visual_probabilities", "region_counts", "concept_counts"):
        assert_allclose(getattr(result, name), getattr(expected, name), rtol=1e-10, atol=1e-12, err_msg=name)


def test_average_does_not_mix_empty_concepts() -> None:
    """A home's place moves from concept 1 to concept 2 between two averaged sweeps; concepts 1, 2
    and 3 are each empty in one of them (two empty concepts per sweep). The place's parameters are
    averaged over its two labels; an empty concept keeps the draws of its own label only (its θ is a
    draw given the shared φ of that label), never those of another empty label."""
    rng = np.random.default_rng(4)
    L, K, V, D, n = 4, 3, 5, 6, 12
    regions = np.repeat([0, 1], n // 2)
    first = _fake_state(rng, np.repeat([0, 1], n // 2), regions, L, K, V, D)  # empty: 2, 3
    second = _fake_state(rng, np.repeat([0, 2], n // 2), regions, L, K, V, D)  # empty: 1, 3
    average = ParameterAverage(np.zeros(n, dtype=np.int64), 1.0)
    average.add(first)
    average.add(second)
    result = average.result(second)  # in the labels of the second sweep
    theta = [np.exp(s.log_theta_w[0]) for s in (first, second)]
    g = [np.exp(s.log_g[0]) for s in (first, second)]
    assert_allclose(result.word_probabilities[0, 0], (theta[0][0] + theta[1][0]) / 2)
    assert_allclose(result.word_probabilities[0, 2], (theta[0][1] + theta[1][2]) / 2)  # the moved place
    assert_allclose(result.word_probabilities[0, 1], theta[1][1])  # empty only in the second sweep
    assert_allclose(result.word_probabilities[0, 3], (theta[0][3] + theta[1][3]) / 2)  # empty in both
    g_expected = np.array([(g[0][0] + g[1][0]) / 2, g[1][1], (g[0][1] + g[1][2]) / 2,
                           (g[0][3] + g[1][3]) / 2])
    assert_allclose(result.concept_weights[0], g_expected / g_expected.sum())  # (renormalised)
    pi = [np.exp(s.log_pi[0]) for s in (first, second)]
    assert_allclose(result.region_weights[0, 1], pi[1][1])
    assert_allclose(result.region_weights[0, 3], (pi[0][3] + pi[1][3]) / 2)
    assert_allclose(result.concept_counts[0], [6, 0, 6, 0])  # mean counts of the matched slots
    assert_allclose(result.word_probabilities.sum(-1), 1.0)


def test_average_differs_from_one_draw_and_is_normalised() -> None:
    rng = np.random.default_rng(1)
    L, K, V, D, n = 4, 5, 3, 6, 30
    concepts, regions = rng.integers(0, L, n), rng.integers(0, K, n)
    states = [_fake_state(rng, concepts, regions, L, K, V, D) for _ in range(3)]
    average = ParameterAverage(np.zeros(n, dtype=np.int64), 1.0)
    for s in states:
        average.add(s)
    result = average.result(states[-1])
    mean_pi = np.mean([np.exp(s.log_pi) for s in states], axis=0)
    assert_allclose(result.region_weights, mean_pi)
    assert_allclose(result.region_weights.sum(-1), 1.0)
    assert_allclose(result.word_probabilities.sum(-1), 1.0)
    mu = np.stack([s.means for s in states])
    cov = np.stack([s.covariances for s in states])
    mixture_cov = cov.mean(0) + (mu[..., :, None] * mu[..., None, :]).mean(0) - (
        mu.mean(0)[..., :, None] * mu.mean(0)[..., None, :])
    assert_allclose(result.region_covariances, mixture_cov, atol=1e-12)
    np.linalg.cholesky(result.region_covariances)  # positive definite


def test_fit_predicts_from_the_average_of_thinned_sweeps(small_corpus) -> None:
    model = SpCoTransfer(SMALL, n_iterations=12, random_state=3).fit(small_corpus)
    params = model.parameters_
    last_draw = export_parameters(model.state_, model.data_)
    assert not np.allclose(params.region_weights, last_draw.region_weights)
    counts = params.concept_counts
    assert counts.shape == (len(small_corpus), SMALL.n_concepts)
    assert_allclose(counts.sum(1), [c.size for c in model.concepts_])
    assert_allclose(params.concept_weights.sum(1), 1.0)
    spcoa = SpCoA(n_iterations=6, random_state=1).fit(small_corpus, home=small_corpus.names[0])
    assert spcoa.parameters_.concept_counts.shape == (1, 15)


# ----------------------------------------------------------------------------- 1. empty concepts

VOCAB = Vocabulary(("kitchen", "dining", "this"))


def _two_concept_params(dining_concept_count: float) -> ConceptParameters:
    """Concept 0 holds the home's samples and says "kitchen"; concept 1 says "dining" and holds
    ``dining_concept_count`` samples; its π points at region 1, concept 0's at region 0."""
    theta_w = np.array([[0.6, 1e-6, 0.4 - 1e-6], [1e-6, 0.6, 0.4 - 1e-6]])[None]
    pi = np.array([[0.9, 0.1], [0.02, 0.98]])[None]
    means = np.array([[[0.0, 0.0, 0.0, 1.0], [5.0, 5.0, 1.0, 0.0]]])
    covs = np.tile(0.1 * np.eye(4), (1, 2, 1, 1))
    g = np.array([[0.8, 0.2]])
    return ConceptParameters(
        concept_weights=g, region_weights=pi, region_means=means, region_covariances=covs,
        word_probabilities=theta_w, visual_probabilities=np.full((1, 2, 3), 1 / 3),
        shared_word_probabilities=theta_w[0], shared_visual_probabilities=np.full((2, 3), 1 / 3),
        global_concept_weights=g[0], word_mask=np.ones(3, dtype=bool), region_counts=np.array([[20, 3]]),
        concept_counts=np.array([[20.0, dining_concept_count]]))


def test_a_place_whose_concept_is_empty_in_the_home_is_not_learnt() -> None:
    """`where dining` in a home without a dining room: the name is explained only by a concept
    that holds none of the home's samples; the caller sees learnt False and a low support."""
    empty = _two_concept_params(dining_concept_count=0.0)
    pred = predict_positions(empty, 0, VOCAB, "dining", n=5, rng=0)
    assert not pred.learnt
    assert pred.support < 1e-4
    assert name_support(empty, 0, VOCAB, "dining") == pytest.approx(pred.support)
    kitchen = predict_positions(empty, 0, VOCAB, "kitchen", n=5, rng=0)
    assert kitchen.learnt and kitchen.support > 0.99
    # the empty concept's π (region 1) no longer decides the answer
    assert region_posterior_for_name(empty, 0, VOCAB, "dining").argmax() == 0

    learnt = _two_concept_params(dining_concept_count=12.0)
    pred = predict_positions(learnt, 0, VOCAB, "dining", n=5, rng=0)
    assert pred.learnt and pred.support > LEARNT_SUPPORT
    assert pred.region == 1


def test_parameters_without_concept_counts_treat_every_concept_as_learnt() -> None:
    params = _two_concept_params(0.0)
    old = ConceptParameters(**{k: v for k, v in params.arrays().items() if k != "concept_counts"})
    assert old.concept_counts is None
    pred = predict_positions(old, 0, VOCAB, "dining", n=3, rng=0)
    assert pred.learnt and pred.support == 1.0 and pred.region == 1


# ----------------------------------------------------------------------------- 2. CRT at large counts


def _exact_crt(n: int, a: float, size: int, rng: np.random.Generator) -> np.ndarray:
    """Exact CRT(n, a) draws: sums of independent Bernoulli(a / (a + i)), i = 0 … n − 1."""
    p = a / (a + np.arange(n))
    return (rng.random((size, n)) < p).sum(axis=1)


@pytest.mark.parametrize("n,a", [(41, 0.3), (120, 2.0), (400, 7.5), (900, 60.0), (2000, 0.05)])
def test_crt_large_count_branch_matches_exact_draws(n: int, a: float) -> None:
    """Above ``exact_max`` = 40 terms the CRT draw is moment-matched; compare it with exact
    Bernoulli sums: mean and variance against the exact values, and the distributions by KS."""
    size = 4000
    approx = sample_crt(np.full(size, n), np.full(size, a), np.random.default_rng(1))
    exact = _exact_crt(n, a, size, np.random.default_rng(2))
    i = np.arange(n)
    mean = (a / (a + i)).sum()
    var = (a * i / (a + i) ** 2).sum()
    assert abs(approx.mean() - mean) < 4.5 * np.sqrt(var / size)
    assert approx.var(ddof=1) == pytest.approx(var, rel=0.15, abs=0.05)
    assert approx.min() >= 1 and approx.max() <= n
    assert stats.ks_2samp(approx, exact).pvalue > 1e-3


def test_crt_totals_large_count_branch_matches_exact_draws() -> None:
    """The summed-over-homes CRT (the shared step's) above 40 Bernoulli terms, against exact sums."""
    size, counts, a = 3000, np.array([30, 25, 60]), 4.0
    grid = np.broadcast_to(counts[:, None, None], (3, size, 1)).copy()
    approx = sample_crt_totals(grid, np.full((size, 1), a), np.random.default_rng(3))[:, 0]
    rng = np.random.default_rng(4)
    exact = sum(_exact_crt(int(n), a, size, rng) for n in counts)
    assert abs(approx.mean() - exact.mean()) < 4.5 * np.sqrt(exact.var() * 2 / size)
    assert approx.var() == pytest.approx(exact.var(), rel=0.2)
    assert stats.ks_2samp(approx, exact).pvalue > 1e-3


# ----------------------------------------------------------------------------- 3. smooth rules


def test_initial_home_weights_have_no_cliff() -> None:
    w = gibbs.initial_home_weights
    below, above = w(np.array([1.0, 0.49])), w(np.array([1.0, 0.51]))
    assert below[0] == above[0] == 1.0
    assert 0 < above[1] - below[1] < 0.03  # was 0 → 1 at 50 %
    assert w(np.array([1.0, 0.0]))[1] == pytest.approx(0.02 / 1.02)  # a new home: ~dropped
    assert_allclose(w(np.zeros(3)), 1.0)  # nobody taught: every home counts
    assert_allclose(w(np.array([0.001, 0.0])), [1.0, 0.02 / 0.021])  # continuous at "nobody"
    assert_allclose(w(np.full(4, 0.3)), 1.0)


def test_warm_start_weights_a_partly_taught_home_smoothly(small_corpus, monkeypatch) -> None:
    """The homes' statistics enter the initial shared part scaled by their weights (not dropped
    below 50 %): record the weights warm_start uses."""
    seen = []
    original = gibbs.initial_home_weights
    monkeypatch.setattr(gibbs, "initial_home_weights", lambda f: seen.append(f) or original(f))
    SpCoTransfer(SMALL, n_iterations=1, random_state=0).fit(small_corpus)
    (fractions,) = seen
    assert fractions[-1] == 0.0 and fractions[:-1].min() > 0.5  # the new home is untaught


def test_concentration_shrinks_smoothly_from_default_to_moment_match() -> None:
    rng = np.random.default_rng(0)
    phi, true_a, default = rng.dirichlet(np.ones(20)), 500.0, 3e5
    samples = rng.dirichlet(true_a * phi, size=400)[:, None, :]  # (S, 1, D)
    assert _concentration(samples[:1], default)[0] == pytest.approx(default)
    values = [_concentration(samples[:s], default)[0] for s in (1, 2, 3, 4, 12, 400)]
    assert all(default >= v > 0 for v in values)
    assert values[-1] == pytest.approx(true_a, rel=0.15)
    # 2 → 3 samples (n_iterations 11 → 12) fell from δ (no spread known) to the moment match;
    # now both follow one rule: the pooled variance of the samples and the default's spread
    two = samples[:2]
    mean = two.mean(0)[0]
    spread = (mean * (1 - mean)).sum()
    nu = CONCENTRATION_PRIOR_SAMPLES
    pooled = (two.var(axis=0, ddof=1).sum() + nu * spread / (default + 1)) / (1 + nu)
    assert values[1] == pytest.approx(spread / pooled - 1)
    assert values[1] < default / 2 and values[2] < default / 2  # the samples count from the second on
    one_hot = np.zeros((3, 1, 4))
    one_hot[:, 0, 0] = 1.0
    assert _concentration(one_hot, 7.0)[0] == 7.0


# ----------------------------------------------------------------------------- 4. validation


def _params() -> ConceptParameters:
    return _two_concept_params(10.0)


@pytest.mark.parametrize("visual,message", [
    (sp.csr_array(np.array([[1.0, np.nan, 2.0]])), "NaN"),
    (sp.csr_array(np.array([[1.0, -1.0, 2.0]])), "whole numbers >= 0"),
    (sp.csr_array(np.array([[1.0, 0.5, 2.0]])), "whole numbers >= 0"),
    (np.array([[0.12, 0.7, 0.31]]), "CNN"),
    (np.array([[1, 2]]), "dimensions"),
])
def test_bad_visual_counts_are_refused(visual, message: str) -> None:
    pose = np.array([[0.0, 0.0, 0.0, 1.0]])
    with pytest.raises(ConfigurationError, match=message):
        predict_names(_params(), 0, VOCAB, pose, visual)
    if message != "dimensions":
        with pytest.raises(ConfigurationError, match=message):  # the home-model path: the same checks
            _visual_row(visual, 3)


def test_good_visual_counts_pass() -> None:
    assert validate_visual_counts(np.array([1, 0, 3]), 3).shape == (1, 3)
    assert validate_visual_counts(sp.csr_array(np.array([[1.0, 0.0, 3.0]])), 3).nnz == 2


def test_poses_must_carry_sin_and_cos() -> None:
    with pytest.raises(ConfigurationError, match="sin θ and cos θ"):
        predict_names(_params(), 0, VOCAB, np.array([[0.0, 0.0, 1.57, 0.0]]), None, use_vision=False)
    with pytest.raises(ConfigurationError, match="row 1"):
        validate_poses(np.array([[0.0, 0.0, 0.0, 1.0], [1.0, 1.0, 0.5, 0.5]]))
    assert validate_poses([1.0, 2.0, np.sin(0.3), np.cos(0.3)]).shape == (1, 4)


@pytest.mark.parametrize("home", [-1, 1, 1.0, True])
def test_bad_home_index_is_refused(home) -> None:
    with pytest.raises(ConfigurationError, match="out of range"):
        predict_positions(_params(), home, VOCAB, "kitchen", n=1)


# ----------------------------------------------------------------------------- 6. scikit-learn protocol


def test_get_params_set_params_and_clone() -> None:
    model = SpCoTransfer(SMALL, prune_words=True, n_iterations=7, random_state=5)
    params = model.get_params()
    assert params == {"hyperparameters": SMALL, "variant": "exact", "prune_words": True, "n_iterations": 7,
                      "random_state": 5, "progress": False, "record_log_joint": True}
    assert model.set_params(n_iterations=9) is model and model.n_iterations == 9
    with pytest.raises(ConfigurationError, match="invalid parameter 'n_iter'"):
        model.set_params(n_iter=3)
    copy = clone(model)
    assert type(copy) is SpCoTransfer and copy.get_params() == model.get_params() and copy is not model
    assert "variant" not in SpCoA().get_params()
    assert "n_iterations=9" in repr(model)


def test_sklearn_clone_works_if_installed() -> None:
    base = pytest.importorskip("sklearn.base")
    model = SpCoA(prune_words=True, n_iterations=3)
    assert base.clone(model).get_params() == model.get_params()


def test_a_generator_random_state_is_not_advanced(small_corpus) -> None:
    gen = np.random.default_rng(11)
    before = gen.bit_generator.state
    first = SpCoTransfer(SMALL, n_iterations=2, random_state=gen).fit(small_corpus)
    assert gen.bit_generator.state == before
    again = SpCoTransfer(SMALL, n_iterations=2, random_state=gen).fit(small_corpus)
    assert_allclose(first.parameters_.region_means, again.parameters_.region_means)
    name = next(w for w, k in zip(first.vocabulary_.words, first.parameters_.word_mask, strict=True) if k)
    first.predict_positions(0, name, n=3, random_state=gen)
    assert gen.bit_generator.state == before


def test_predicted_poses_use_the_input_convention() -> None:
    pred = predict_positions(_params(), 0, VOCAB, "kitchen", n=6, rng=0)
    assert pred.samples.shape == (6, 3) and pred.poses.shape == (6, 4)
    assert_allclose(np.arctan2(pred.poses[:, 2], pred.poses[:, 3]), pred.samples[:, 2])
    names = predict_names(_params(), 0, VOCAB, pred.poses, None, use_vision=False)  # round trip
    assert len(names) == 6


def test_home_model_predicts_from_its_posterior_average_and_keeps_it_in_its_file(small_corpus,
                                                                                 tmp_path) -> None:
    from spco.knowledge import adapt, fit_knowledge, load_home_model, teach

    knowledge = fit_knowledge(small_corpus, n_iterations=6, random_state=0, hyperparameters=SMALL)
    home = adapt(knowledge, small_corpus[-1], n_iterations=8, random_state=0)
    # the posterior average, with the knowledge's name prior (spco.model.name_evidence) attached
    assert home.posterior is not None and home.parameters.concept_weights is home.posterior.concept_weights
    assert home.parameters.concept_counts.sum() == pytest.approx(home.n_samples)
    path = home.save(tmp_path / "home.spco")
    loaded = load_home_model(path)
    for name, array in home.posterior.arrays().items():
        np.testing.assert_array_equal(array, getattr(loaded.posterior, name), err_msg=name)
    # (the word channels: prediction's parameters add ψ, the switch's prior and the home's said words)
    for name, array in home.parameters.arrays().items():
        np.testing.assert_array_equal(array, getattr(loaded.parameters, name), err_msg=name)
    sample = int(home.ids[0])
    taught = teach(home, {sample: "this is the kitchen"}, n_sweeps=4, random_state=1)
    assert taught.posterior is not None
    assert taught.posterior.word_probabilities.shape[-1] == len(taught.vocabulary)
    # no sweeps: a local update still (the home's average where the teaching did not reach, the
    # state's own values where it did), not the state's draw for the whole home
    unswept = teach(home, {sample: "this is the kitchen"}, n_sweeps=0, random_state=1).posterior
    assert unswept is not None
    same = [c for c in range(unswept.n_concepts)
            if np.array_equal(unswept.visual_probabilities[0, c], home.posterior.visual_probabilities[0, c])]
    assert 0 < len(same) < unswept.n_concepts


def test_masked_rows_never_nan() -> None:
    """A row whose kept entries are all -inf (nothing known of it) becomes uniform over the kept
    words instead of NaN; pruned words stay 0."""
    from spco.model.posterior import masked_rows

    log_p = np.array([[-1.0, -2.0, -np.inf], [-np.inf, -np.inf, -3.0]])
    mask = np.array([True, True, False])
    with np.errstate(all="raise"):
        p = masked_rows(log_p, mask)
    assert np.isfinite(p).all()
    np.testing.assert_allclose(p.sum(axis=1), 1.0)
    np.testing.assert_allclose(p[1], [0.5, 0.5, 0.0])
    assert p[0, 2] == 0.0 and p[0, 0] > p[0, 1]
