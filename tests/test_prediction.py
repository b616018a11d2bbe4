"""Prediction on hand-built parameters: names from observations, positions from names."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.sparse as sp
from hypothesis import given, settings
from hypothesis import strategies as st
from numpy.testing import assert_allclose
from scipy.stats import multivariate_normal

from spco.data.language import Vocabulary
from spco.errors import ConfigurationError, SpcoError
from spco.model.parameters import ConceptParameters
from spco.model.position_prediction import predict_positions, region_posterior_for_name
from spco.model.prediction import (
    NamePrediction,
    UnknownNameError,
    concept_posterior,
    gaussian_log_density,
    kl_scores_reference,
    mutual_information_weights,
    predict_names,
    reference_kl_weights,
    word_posterior,
)

WORDS = ("this", "is", "kitchen", "bath", "living room")
VOCAB = Vocabulary(WORDS)
MEANS_XY = np.array([[0.0, 0.0], [3.0, 0.0], [0.0, 3.0]])  # region m of concept m


def make_params(n_features: int = 6, seed: int = 0, word_mask: np.ndarray | None = None) -> ConceptParameters:
    """E=1 home, L=3 concepts (kitchen, bath, living-room), K=3 regions, V=5 words.

    "this" and "is" have the same probability in every concept (uninformative); concept l lives
    mostly in region l; each concept has its own visual distribution.
    """
    rng = np.random.default_rng(seed)
    theta_w = np.array([
        [0.35, 0.35, 0.30, 0.00, 0.00],
        [0.35, 0.35, 0.00, 0.30, 0.00],
        [0.35, 0.35, 0.00, 0.00, 0.30],
    ])
    g = np.array([0.4, 0.35, 0.25])
    pi = np.full((3, 3), 0.05) + np.eye(3) * 0.85
    means = np.zeros((3, 4))
    means[:, :2] = MEANS_XY
    means[:, 2:] = [[0.0, 1.0], [1.0, 0.0], [0.0, -1.0]]
    covs = np.empty((3, 4, 4))
    for m in range(3):
        a = rng.normal(size=(4, 4)) * 0.1
        covs[m] = a @ a.T + np.diag([0.2, 0.15, 0.05, 0.05])
    theta_v = rng.dirichlet(np.full(n_features, 2.0), size=3)
    mask = np.ones(5, dtype=bool) if word_mask is None else word_mask
    return ConceptParameters(
        concept_weights=g[None],
        region_weights=pi[None],
        region_means=means[None],
        region_covariances=covs[None],
        word_probabilities=theta_w[None],
        visual_probabilities=theta_v[None],
        shared_word_probabilities=theta_w,
        shared_visual_probabilities=theta_v,
        global_concept_weights=g,
        word_mask=mask,
        region_counts=np.array([[20, 20, 20]]),
    )


def observations(params: ConceptParameters, n: int, seed: int = 1) -> tuple[np.ndarray, np.ndarray]:
    rng = np.random.default_rng(seed)
    positions = np.column_stack([rng.uniform(-1, 4, size=(n, 2)), rng.normal(size=(n, 2))])
    positions[:, 2:] /= np.linalg.norm(positions[:, 2:], axis=1, keepdims=True)
    visual = rng.integers(0, 4, size=(n, params.visual_probabilities.shape[-1]))
    return positions, visual


def brute_force_word_posterior(params: ConceptParameters, positions: np.ndarray,
                               visual: np.ndarray) -> np.ndarray:
    e = 0
    n_words = params.word_probabilities.shape[-1]
    out = np.zeros((positions.shape[0], n_words))
    for i in range(positions.shape[0]):
        for w in range(n_words):
            total = 0.0
            for c in range(params.n_concepts):
                vis = np.prod(params.visual_probabilities[e, c] ** visual[i])
                for m in range(params.n_regions):
                    gauss = multivariate_normal.pdf(positions[i], params.region_means[e, m],
                                                    params.region_covariances[e, m])
                    total += (params.word_probabilities[e, c, w] * vis * params.concept_weights[e, c]
                              * gauss * params.region_weights[e, c, m])
            out[i, w] = total
    return out / out.sum(axis=1, keepdims=True)


# ------------------------------------------------------------------------- word posterior
def test_word_posterior_matches_double_loop() -> None:
    params = make_params()
    positions, visual = observations(params, 7)
    expected = brute_force_word_posterior(params, positions, visual)
    assert_allclose(word_posterior(params, 0, positions, visual), expected, rtol=1e-9, atol=1e-12)
    # sparse counts give the same answer
    assert_allclose(word_posterior(params, 0, positions, sp.csr_array(visual)), expected, rtol=1e-9,
                    atol=1e-12)


def test_concept_posterior_rows_and_modalities() -> None:
    params = make_params()
    positions, visual = observations(params, 5)
    post = concept_posterior(params, 0, positions, visual)
    assert post.shape == (5, 3)
    assert_allclose(post.sum(axis=1), 1.0)
    # without vision, the visual counts are not needed
    no_vision = concept_posterior(params, 0, positions, None, use_vision=False)
    assert_allclose(no_vision.sum(axis=1), 1.0)
    only_prior = concept_posterior(params, 0, positions, None, use_position=False, use_vision=False)
    assert_allclose(only_prior, np.broadcast_to(params.concept_weights[0], (5, 3)))
    with pytest.raises(ConfigurationError):
        concept_posterior(params, 0, positions, None)
    with pytest.raises(ConfigurationError):
        concept_posterior(params, 0, positions, visual[:, :3])
    with pytest.raises(ConfigurationError):
        concept_posterior(params, 3, positions, visual)


def test_huge_visual_counts_stay_finite() -> None:
    """~7,000 counts over 4,096 dims: log-likelihood gaps of thousands of nats."""
    d = 4096
    params = make_params(n_features=d, seed=3)
    rng = np.random.default_rng(4)
    theta_v = rng.dirichlet(np.full(d, 0.5), size=3)
    theta_v[1, :100] = 0.0  # some zero entries
    theta_v[1] /= theta_v[1].sum()
    covs = params.region_covariances.copy()
    covs[0, 2] = np.diag([1e-3, 1e-3, 0.0, 0.0])  # a singular region
    covs[0, 2, 2, 3] = covs[0, 2, 3, 2] = 1e-18
    params = ConceptParameters(**{**params.arrays(), "visual_probabilities": theta_v[None],
                                  "region_covariances": covs})
    n = 30
    concepts = rng.integers(0, 3, size=n)
    visual = np.stack([rng.multinomial(7000, theta_v[c]) for c in concepts])
    visual[:, :100] += 1  # counts where concept 1 has probability 0
    visual[:, 4000] += 5000 * 4  # a huge single count (S^w scale)
    positions, _ = observations(params, n, seed=5)
    positions[0, :2] = [1e3, -1e3]  # far from every region
    positions[1] = [0.0, 3.0, 0.0, -1.0]  # right on the singular region
    for vis in (sp.csr_array(visual), visual):
        probs = word_posterior(params, 0, positions, vis)
        assert np.isfinite(probs).all()
        assert_allclose(probs.sum(axis=1), 1.0)
        post = concept_posterior(params, 0, positions, vis)
        assert np.isfinite(post).all()
        assert_allclose(post.sum(axis=1), 1.0)
        assert (post[:, 1] < 1e-100).all()  # concept 1 cannot explain the counts in its zero dims
    pred = predict_names(params, 0, VOCAB, positions, sp.csr_array(visual))
    assert np.isfinite(pred.scores).all()


def test_gaussian_log_density_matches_scipy_and_survives_singular() -> None:
    params = make_params()
    x = np.random.default_rng(0).normal(size=(9, 4))
    got = gaussian_log_density(x, params.region_means[0], params.region_covariances[0])
    for m in range(3):
        assert_allclose(got[:, m], multivariate_normal.logpdf(x, params.region_means[0, m],
                                                              params.region_covariances[0, m]))
    singular = np.zeros((2, 4, 4))
    singular[1] = np.eye(4)
    assert np.isfinite(gaussian_log_density(x, np.zeros((2, 4)), singular)).all()


# ------------------------------------------------------------------------- weights
def test_mutual_information_weights() -> None:
    params = make_params()
    info = mutual_information_weights(params, 0)
    assert info.shape == (5,)
    assert info[0] == 0.0 and info[1] == 0.0
    g = params.concept_weights[0]
    theta = params.word_probabilities[0]
    for w in range(2, 5):  # the explicit 2 × L table {word = w, word ≠ w} × {concept}
        joint = np.stack([g * theta[:, w], g * (1 - theta[:, w])])
        outer = joint.sum(axis=1, keepdims=True) * joint.sum(axis=0, keepdims=True)
        nz = joint > 0
        assert info[w] == pytest.approx(float((joint[nz] * np.log(joint[nz] / outer[nz])).sum()))
        assert info[w] > 0
    # a pruned word has weight 0; θ = 1 is safe
    mask = np.array([True, True, True, True, False])
    assert mutual_information_weights(make_params(word_mask=mask), 0)[4] == 0.0
    ones = make_params()
    tw = np.zeros((1, 3, 5))
    tw[0, :, 2] = 1.0
    ones = ConceptParameters(**{**ones.arrays(), "word_probabilities": tw})
    assert np.isfinite(mutual_information_weights(ones, 0)).all()


def test_uninformative_words_are_never_predicted() -> None:
    params = make_params()
    positions, visual = observations(params, 200)
    pred = predict_names(params, 0, VOCAB, positions, visual, weighting="mi")
    assert not set(pred.best) & {"this", "is"}
    # without the MI weighting the frequent carrier word wins
    plain = predict_names(params, 0, VOCAB, positions, visual, weighting="none")
    assert set(plain.best) <= {"this", "is"}


def test_reference_kl_scores_match_brute_force() -> None:
    params = make_params()
    positions, visual = observations(params, 4)
    g = params.concept_weights[0]
    theta = params.word_probabilities[0]
    marginal = g @ theta
    kl = reference_kl_weights(params, 0)
    for c in range(3):
        for w in range(5):
            a, b = theta[c, w], marginal[w]
            expected = (a * np.log(a / b) if a > 0 else 0.0) + (1 - a) * np.log((1 - a) / (1 - b))
            assert kl[c, w] == pytest.approx(expected, abs=1e-12)
    post = concept_posterior(params, 0, positions, visual, active_regions_only=True)
    scores = kl_scores_reference(params, 0, positions, visual)
    assert_allclose(scores, post @ (theta * kl))
    pred = predict_names(params, 0, VOCAB, positions, visual, weighting="reference")
    assert_allclose(pred.scores[:, 0], scores.max(axis=1))


# ------------------------------------------------------------------------- names
def region_observation(params: ConceptParameters, m: int, scale: int = 50) -> tuple[np.ndarray, np.ndarray]:
    pos = params.region_means[0, m][None].copy()
    vis = np.round(params.visual_probabilities[0, m] * scale)[None].astype(int)
    return pos, vis


@pytest.mark.parametrize("weighting", ["mi", "reference"])
def test_observation_in_a_concepts_region_predicts_its_name(weighting: str) -> None:
    params = make_params()
    for m, word in enumerate(("kitchen", "bath", "living room")):
        pos, vis = region_observation(params, m)
        pred = predict_names(params, 0, VOCAB, pos, vis, top_k=3, weighting=weighting)  # type: ignore[arg-type]
        assert isinstance(pred, NamePrediction)
        assert pred.best == [word]
        assert pred.words.shape == (1, 3) and pred.scores.shape == (1, 3)
        assert (np.diff(pred.scores[0]) <= 0).all()
        assert_allclose(pred.word_probabilities.sum(axis=1), 1.0)
        assert_allclose(pred.probabilities[0, 0], pred.word_probabilities[0, VOCAB.index(word)])


def test_masked_words_are_never_returned_and_top_k_is_clamped() -> None:
    mask = np.array([True, False, True, False, True])
    params = make_params(word_mask=mask)
    positions, visual = observations(params, 20)
    pred = predict_names(params, 0, VOCAB, positions, visual, top_k=10)
    assert pred.words.shape == (20, 3)
    assert not {"is", "bath"} & set(pred.words.ravel().tolist())
    assert_allclose(pred.word_probabilities[:, ~mask], 0.0)
    with pytest.raises(ConfigurationError):
        predict_names(params, 0, VOCAB, positions, visual, top_k=0)
    with pytest.raises(ConfigurationError):
        predict_names(params, 0, Vocabulary(("a", "b")), positions, visual)
    with pytest.raises(ConfigurationError):
        predict_names(params, 0, VOCAB, positions, visual, weighting="bogus")  # type: ignore[arg-type]


def test_empty_batch() -> None:
    params = make_params()
    pred = predict_names(params, 0, VOCAB, np.empty((0, 4)), np.empty((0, 6)))
    assert pred.words.shape == (0, 3) and pred.best == []


# ------------------------------------------------------------------------- positions
def test_region_posterior_matches_brute_force() -> None:
    params = make_params()
    for word in ("kitchen", "bath", "living room", "this"):
        w = VOCAB.index(word)
        expected = np.zeros(3)
        for m in range(3):
            for c in range(3):
                expected[m] += (params.region_weights[0, c, m] * params.word_probabilities[0, c, w]
                                * params.concept_weights[0, c])
        expected /= expected.sum()
        assert_allclose(region_posterior_for_name(params, 0, VOCAB, word), expected)
    # names are normalised like vocabulary words
    assert_allclose(region_posterior_for_name(params, 0, VOCAB, "Living Room"),
                    region_posterior_for_name(params, 0, VOCAB, "living room"))


def test_a_name_of_several_known_words_combines_them() -> None:
    params = make_params()
    words = [VOCAB.index("this"), VOCAB.index("kitchen")]
    expected = np.zeros(3)
    for m in range(3):
        for c in range(3):
            theta = params.word_probabilities[0, c]
            expected[m] += (params.region_weights[0, c, m] * params.concept_weights[0, c]
                            * theta[words[0]] * theta[words[1]])
    expected /= expected.sum()
    assert_allclose(region_posterior_for_name(params, 0, VOCAB, "this kitchen"), expected)
    # (with unheard=True, the default, a name never said as one token is first looked up in WordNet
    # when the lexicon is installed: tests/test_names.py)
    combined = predict_positions(params, 0, VOCAB, "This Kitchen", n=2, rng=0, unheard=False)
    assert combined.name == "this + kitchen"
    # unknown words of the name are left out; a name of unknown words only is unknown
    assert_allclose(region_posterior_for_name(params, 0, VOCAB, "kitchen corner"),
                    region_posterior_for_name(params, 0, VOCAB, "kitchen"))
    with pytest.raises(UnknownNameError, match="never taught"):
        region_posterior_for_name(params, 0, VOCAB, "garden shed")


def test_positions_concentrate_at_the_named_region() -> None:
    params = make_params()
    pred = predict_positions(params, 0, VOCAB, "Bath", n=4000, rng=0)
    assert pred.name == "bath" and pred.region == 1
    assert pred.samples.shape == (4000, 3)
    assert_allclose(pred.samples[:, :2].mean(axis=0), MEANS_XY[1], atol=0.05)
    assert_allclose(np.cov(pred.samples[:, :2].T), params.region_covariances[0, 1, :2, :2], atol=0.03)
    assert (np.abs(pred.samples[:, 2]) <= np.pi).all()
    assert (pred.regions == 1).all()
    assert_allclose(pred.weights.sum(), 1.0)
    assert np.isfinite(pred.log_density).all()
    # the same seed gives the same samples
    again = predict_positions(params, 0, VOCAB, "bath", n=4000, rng=0)
    assert_allclose(again.samples, pred.samples)


def test_mixture_mode_and_xy_only() -> None:
    params = make_params()
    probs = region_posterior_for_name(params, 0, VOCAB, "kitchen")
    pred = predict_positions(params, 0, VOCAB, "kitchen", n=20000, rng=1, mode="mixture")
    freq = np.bincount(pred.regions, minlength=3) / 20000
    assert_allclose(freq, probs, atol=0.01)
    xy = predict_positions(params, 0, VOCAB, "kitchen", n=50, rng=2, xy_only=True)
    assert np.isnan(xy.samples[:, 2]).all() and np.isfinite(xy.samples[:, :2]).all()
    assert xy.xy.shape == (50, 2)
    empty = predict_positions(params, 0, VOCAB, "kitchen", n=0)
    assert empty.samples.shape == (0, 3)
    with pytest.raises(ConfigurationError):
        predict_positions(params, 0, VOCAB, "kitchen", mode="best")  # type: ignore[arg-type]


def test_unknown_name_raises_with_suggestion() -> None:
    params = make_params()
    with pytest.raises(UnknownNameError) as info:
        predict_positions(params, 0, VOCAB, "kitchn")
    err = info.value
    assert isinstance(err, SpcoError)
    assert err.suggestions[0] == "kitchen"
    assert "did you mean 'kitchen'" in str(err)
    assert "known names" in str(err)
    with pytest.raises(UnknownNameError):
        region_posterior_for_name(params, 0, VOCAB, "garage")
    pruned = make_params(word_mask=np.array([True, True, True, False, True]))
    with pytest.raises(UnknownNameError, match="pruned"):
        region_posterior_for_name(pruned, 0, VOCAB, "bath")


# ------------------------------------------------------------------------- robustness
@settings(max_examples=40, deadline=None)
@given(seed=st.integers(0, 2**31 - 1), scale=st.sampled_from([1, 100, 10_000]),
       zero_fraction=st.floats(0.0, 0.5))
def test_posteriors_are_finite_and_normalised(seed: int, scale: int, zero_fraction: float) -> None:
    """Random parameters with zero entries and counts up to ~10^5: rows stay finite and sum to 1."""
    rng = np.random.default_rng(seed)
    n_concepts, n_regions, n_words, d = 4, 5, 6, 30
    theta_v = rng.dirichlet(np.full(d, 0.3), size=n_concepts)
    theta_v[rng.random(theta_v.shape) < zero_fraction] = 0.0
    theta_w = rng.dirichlet(np.full(n_words, 0.5), size=n_concepts)
    theta_w[rng.random(theta_w.shape) < zero_fraction] = 0.0
    pi = rng.dirichlet(np.full(n_regions, 0.2), size=n_concepts)
    a = rng.normal(size=(n_regions, 4, 4)) * rng.uniform(0.0, 1.0, size=(n_regions, 1, 1))
    covs = a @ np.swapaxes(a, 1, 2)  # possibly singular
    g = rng.dirichlet(np.ones(n_concepts))
    params = ConceptParameters(g[None], pi[None], rng.normal(size=(1, n_regions, 4)) * 3, covs[None],
                               theta_w[None], theta_v[None], theta_w, theta_v, g,
                               np.ones(n_words, dtype=bool), np.ones((1, n_regions), dtype=int))
    positions = rng.normal(size=(8, 4)) * 5
    positions[:, 2:] /= np.linalg.norm(positions[:, 2:], axis=1, keepdims=True)  # (sin θ, cos θ)
    visual = rng.integers(0, scale + 1, size=(8, d))
    post = concept_posterior(params, 0, positions, visual)
    assert np.isfinite(post).all()
    assert_allclose(post.sum(axis=1), 1.0)
    words = word_posterior(params, 0, positions, sp.csr_array(visual))
    assert np.isfinite(words).all()
    sums = words.sum(axis=1)
    assert np.all((np.abs(sums - 1.0) < 1e-9) | (sums == 0.0))
    assert np.isfinite(mutual_information_weights(params, 0)).all()
    assert np.isfinite(kl_scores_reference(params, 0, positions, visual)).all()
