"""Priors that fit the map (issue 29): κ0, L and K follow the homes' spread and place sizes in their
own map units; the paper's constants stay one argument away."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.sparse as sp

from spco.errors import ConfigurationError
from spco.model.hyperparameters import (
    PLACES_NU0,
    TransferHyperparameters,
    home_scales,
    scaled_hyperparameters,
)


def _home(n_places: int, spacing: float, size: float, seed: int = 0, per: int = 6
          ) -> tuple[np.ndarray, sp.csr_array]:
    """``n_places`` places on a line ``spacing`` apart, samples within ``size`` (sd) of each; word 0
    ("this") said everywhere, word 1 + p the name of place p."""
    rng = np.random.default_rng(seed)
    place = np.repeat(np.arange(n_places), per)
    xy = np.column_stack([place * spacing, np.zeros(place.size)]) + rng.normal(0.0, size, (place.size, 2))
    said = np.zeros((place.size, n_places + 1))
    said[:, 0] = 1.0
    said[np.arange(place.size), 1 + place] = 1.0
    return xy, sp.csr_array(said)


def test_home_scales_reads_spread_place_size_and_places() -> None:
    xy, said = _home(8, 5.0, 0.3)
    spread, size, places = home_scales(xy, said)
    assert 7.0 < spread < 9.0  # sd of 0, 5, …, 35 in x, 0 in y: sqrt(107/2)
    assert 0.2 < size < 0.45  # the names' spread, not "this"'s
    assert places == 8


def test_kappa0_follows_the_ratio_of_place_to_home_whatever_the_units() -> None:
    """A flat (places 3 m apart) keeps a larger κ0 than a floor (places 15 m apart) with places of the
    same size; the same homes in centimetres give the same κ0 (the prior is in the map's units)."""
    flat = scaled_hyperparameters([_home(8, 3.0, 0.3, seed=s) for s in range(2)])
    floor = scaled_hyperparameters([_home(8, 15.0, 0.3, seed=s) for s in range(2)])
    assert floor.kappa0 < flat.kappa0 <= TransferHyperparameters().kappa0
    in_cm = scaled_hyperparameters([(xy * 100.0, said) for xy, said in (_home(8, 15.0, 0.3, seed=s)
                                                                        for s in range(2))])
    assert in_cm.kappa0 == pytest.approx(floor.kappa0, rel=1e-9)
    spread, size, _ = home_scales(*_home(8, 15.0, 0.3))
    assert floor.kappa0 == pytest.approx(min(0.05, (size / (2 * spread)) ** 2), rel=0.5)


def test_truncations_grow_with_the_places_named() -> None:
    few = scaled_hyperparameters([_home(6, 4.0, 0.3)])
    many = scaled_hyperparameters([_home(20, 4.0, 0.3)])
    assert (few.n_concepts, few.n_regions) == (15, 20)
    assert many.n_concepts >= 2 * 18 and many.n_regions == many.n_concepts


def test_without_words_the_paper_prior_stays() -> None:
    xy, _ = _home(5, 4.0, 0.3)
    hyper = scaled_hyperparameters([(xy, sp.csr_array((xy.shape[0], 3)))])
    assert hyper == TransferHyperparameters()
    assert scaled_hyperparameters([]) == TransferHyperparameters()


def test_fit_knowledge_refuses_an_unknown_prior() -> None:
    from spco.data.environment import Corpus
    from spco.data.synthetic import SyntheticConfig, generate_homes
    from spco.knowledge import fit_knowledge

    corpus = generate_homes(2, seed=0, config=SyntheticConfig(n_features=16))
    with pytest.raises(ConfigurationError, match="prior"):
        fit_knowledge(Corpus(list(corpus)), n_iterations=1, prior="cm")


def test_a_synthetic_fleet_gets_the_scaled_prior_of_the_corpus_of_its_homes() -> None:
    """A :class:`SyntheticHomes` fleet (generated in the shards) measures its homes' scales as the
    :class:`Corpus` of the same homes does, so ``fit_knowledge`` starts both from the same prior (it
    kept the paper's κ0 for the fleet: the two fits drew different chains)."""
    from spco.data.synthetic import SyntheticConfig, generate_homes
    from spco.knowledge.fit import default_hyperparameters
    from spco.model.sources import SyntheticHomes

    config = SyntheticConfig(n_features=32, n_train=12)
    source = SyntheticHomes.create(4, seed=4, config=config, new_homes=1)
    corpus = generate_homes(4, seed=4, config=config, new_homes=1, specific_rooms=False)
    expected = [home_scales(t.positions, corpus.word_counts(list(t.sentences)))
                for t in corpus.training_set()]
    np.testing.assert_array_equal(np.array(source.scales), np.array(expected))
    fleet, read = default_hyperparameters(source), default_hyperparameters(corpus)
    assert fleet == read
    assert fleet.kappa0 < TransferHyperparameters().kappa0  # the scaled prior, not the paper's


# ------------------------------------------- Ψ0 (the regions' size) follows the places: prior="places"


def _log_marginal(points: np.ndarray, prior) -> float:
    """log p(points) of one region, (μ, Σ) integrated out: the identity log p(X) = log p(X | μ, Σ) +
    log NIW(μ, Σ | prior) − log NIW(μ, Σ | posterior), at the posterior mean of (μ, Σ)."""
    from spco.model.kernels.niw import niw_posterior
    from spco.model.observations import GaussianRegions, NIWPrior

    n, d = points.shape
    mu_n, kappa_n, psi_n, nu_n = niw_posterior(np.array([[float(n)]]), points.sum(axis=0)[None, None],
                                               (points.T @ points)[None, None], prior.mu0[:, None, :],
                                               prior.kappa0, prior.psi0, prior.nu0)
    sigma = psi_n / (nu_n[..., None, None] - d - 1)
    likelihood = GaussianRegions.log_likelihood(points, np.zeros(n, dtype=np.int64), mu_n, sigma).sum()
    posterior = NIWPrior(mu0=mu_n[:, 0], kappa0=float(kappa_n[0, 0]), psi0=psi_n[0, 0], nu0=float(nu_n[0, 0]))
    return float(likelihood + GaussianRegions.log_prior(mu_n, sigma, prior)
                 - GaussianRegions.log_prior(mu_n, sigma, posterior))


def _prior(hyper: TransferHyperparameters, centre: np.ndarray):
    from spco.model.observations import NIWPrior

    return NIWPrior(mu0=np.asarray(centre, dtype=float)[None], kappa0=hyper.kappa0,
                    psi0=hyper.psi0_matrix_m2(), nu0=hyper.nu0)


def _rooms(scale: float) -> tuple[np.ndarray, np.ndarray]:
    """Two neighbouring rooms 3 m apart, 15 samples each within 0.5 m (× ``scale``), any heading."""
    rng = np.random.default_rng(7)
    first = rng.normal(0.0, 0.5, (15, 2))
    second = rng.normal(0.0, 0.5, (15, 2)) + np.array([3.0, 0.0])
    xy = np.concatenate([first, second]) * scale
    heading = rng.uniform(-np.pi, np.pi, 30)
    return np.column_stack([xy, np.sin(heading), np.cos(heading)]), np.repeat([0, 1], 15)


def test_psi0_expects_regions_of_the_places_size() -> None:
    """Ψ0 = (ν0 − 5)·diag(s²/5, s²/5, 0.1, 0.1) at the places prior's ν0 = 20: E[Σ] = Ψ0 / (ν0 − 5) is
    diag(s²/5, s²/5, h, h), a part of a place in x, y, the paper's heading."""
    floor = [_home(8, 6.0, 0.5, seed=s) for s in range(3)]
    hyper = scaled_hyperparameters(floor, psi0=True)
    size = float(np.median([home_scales(xy, said)[1] for xy, said in floor]))
    expected = np.diag(hyper.psi0_matrix_m2()) / (hyper.nu0 - 5)
    np.testing.assert_allclose(expected, [size**2 / 5, size**2 / 5, 0.1, 0.1], rtol=1e-12)
    np.testing.assert_allclose(hyper.psi0, [3 * size**2, 3 * size**2, 1.5, 1.5], rtol=1e-12)
    assert hyper.psi0_in_cm2 is False and hyper.nu0 == PLACES_NU0 == 20.0
    # ν0 given (``spco fit --set nu0=10``): the paper's weight, the same E[Σ]
    ten = scaled_hyperparameters(floor, base=TransferHyperparameters(nu0=10.0), psi0=True)
    np.testing.assert_allclose(ten.psi0, [size**2, size**2, 0.5, 0.5], rtol=1e-12)
    # the scaled prior (Ψ0 the paper's) keeps the paper's ν0
    assert scaled_hyperparameters(floor).nu0 == TransferHyperparameters().nu0
    # the paper's: (1.4 cm)², whatever the map
    paper = TransferHyperparameters()
    assert np.diag(paper.psi0_matrix_m2())[0] / (paper.nu0 - 5) == pytest.approx(0.0002)


def test_the_same_floor_in_metres_and_centimetres_gets_the_same_model() -> None:
    """Scale invariance: the floor in centimetres gets Ψ0 × 10⁴ in x, y, the same κ0, L, K; the
    posterior odds of splitting two neighbouring rooms into two regions (the positions' marginal
    likelihoods, as the local update scores a split) are the same in either unit — and with the
    paper's constants they are not (its Ψ0 is 10 cm² in any map)."""
    metres = [_home(8, 6.0, 0.5, seed=s) for s in range(3)]
    centimetres = [(xy * 100.0, said) for xy, said in metres]
    m, cm = scaled_hyperparameters(metres, psi0=True), scaled_hyperparameters(centimetres, psi0=True)
    np.testing.assert_allclose(np.diag(cm.psi0_matrix_m2()),
                               np.diag(m.psi0_matrix_m2()) * [1e4, 1e4, 1.0, 1.0], rtol=1e-9)
    assert cm.kappa0 == pytest.approx(m.kappa0, rel=1e-9)
    assert (cm.n_concepts, cm.n_regions, cm.nu0) == (m.n_concepts, m.n_regions, m.nu0)

    def split_odds(hyper: TransferHyperparameters, scale: float) -> float:
        points, room = _rooms(scale)
        prior = _prior(hyper, np.r_[points[:, :2].mean(axis=0), 0.0, 0.0])
        apart = sum(_log_marginal(points[room == r], prior) for r in (0, 1))
        return apart - _log_marginal(points, prior)

    odds_m, odds_cm = split_odds(m, 1.0), split_odds(cm, 100.0)
    assert odds_cm == pytest.approx(odds_m, abs=1e-6)
    assert odds_m > 0  # two rooms 3 m apart are two regions
    assert split_odds(TransferHyperparameters(), 1.0) < 0  # the paper's (1.4 cm)² regions merge them
    paper = TransferHyperparameters()
    assert abs(split_odds(paper, 1.0) - split_odds(paper, 100.0)) > 1.0


def test_extreme_place_sizes_are_kept_representable_or_refused() -> None:
    """A place size beyond what Ψ0 holds beside the heading (condition number ≤ 10¹²) is kept at the
    nearest it holds, with a warning; a size or ν0 that cannot make a prior is refused by name."""
    from spco.model.hyperparameters import MAX_CONDITION, scaled_psi0

    for scale in (1e-9, 1e9, 1e150):
        homes = [(xy * scale, said) for xy, said in (_home(8, 6.0, 0.5, seed=s) for s in range(2))]
        with pytest.warns(UserWarning, match="places measure"):
            hyper = scaled_hyperparameters(homes, psi0=True)
        eig = np.linalg.eigvalsh(hyper.psi0_matrix_m2())
        assert eig.max() <= MAX_CONDITION * eig.min()
    for size in (0.0, 1e-300, 1e300):
        psi, clamped = scaled_psi0(size, 10.0)
        assert clamped and np.isfinite(psi).all() and min(psi) > 0
    # positions whose squares underflow have no measurable spread: the base's prior
    tiny = [(xy * 1e-300, said) for xy, said in (_home(8, 6.0, 0.5, seed=s) for s in range(2))]
    assert scaled_hyperparameters(tiny, psi0=True).psi0 == TransferHyperparameters().psi0
    for size in (float("nan"), float("inf"), -1.0):
        with pytest.raises(ConfigurationError, match="place size"):
            scaled_psi0(size, 10.0)
    with pytest.raises(ConfigurationError, match="nu0"):
        scaled_psi0(0.3, 5.0)
    with pytest.raises(ConfigurationError, match="nu0"):
        scaled_hyperparameters([_home(8, 6.0, 0.5)], base=TransferHyperparameters(nu0=4.5), psi0=True)


def test_nu0_sets_the_weight_not_the_size() -> None:
    """A larger ν0 scales Ψ0 with it: E[Σ] stays the places' size (``spco fit --set nu0=…``)."""
    homes = [_home(8, 6.0, 0.5, seed=s) for s in range(2)]
    default = scaled_hyperparameters(homes, psi0=True)
    forty = scaled_hyperparameters(homes, base=TransferHyperparameters(nu0=40.0), psi0=True)
    np.testing.assert_allclose(np.diag(forty.psi0_matrix_m2()) / 35.0,
                               np.diag(default.psi0_matrix_m2()) / (default.nu0 - 5))
    assert forty.nu0 == 40.0


def test_every_route_of_a_home_uses_the_knowledge_scaled_prior(tmp_path) -> None:
    """fit_knowledge's scaled Ψ0 is the one adapt, teach (the local update) and a reloaded file use; the
    paper's stays one argument away."""
    import warnings

    from spco import knowledge as kn
    from spco.data.environment import Corpus
    from spco.data.synthetic import SyntheticConfig, generate_homes
    from spco.knowledge.fit import default_hyperparameters

    envs = list(generate_homes(3, seed=1, config=SyntheticConfig(n_features=16, n_train=10), new_homes=1,
                               specific_rooms=False))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        knowledge = kn.fit_knowledge(Corpus(envs[:2]), n_iterations=2, random_state=0, prior="places")
        scaled = default_hyperparameters(Corpus(envs[:2]), psi0=True)
        assert default_hyperparameters(Corpus(envs[:2])).psi0 == TransferHyperparameters().psi0  # opt-in
        assert knowledge.hyperparameters.psi0 == scaled.psi0 and not knowledge.hyperparameters.psi0_in_cm2
        assert scaled.psi0 != TransferHyperparameters().psi0
        knowledge.save(tmp_path / "k.spco")
        loaded = kn.load_knowledge(tmp_path / "k.spco")
        home = kn.adapt(loaded, envs[2], n_iterations=1, random_state=0)
        taught = kn.teach(home, {int(home.ids[0]): "this is the quokka room"}, random_state=0)
        for model in (loaded, home, taught):
            np.testing.assert_array_equal(model.hyperparameters.psi0_matrix_m2(), scaled.psi0_matrix_m2())
        paper = kn.fit_knowledge(Corpus(envs[:2]), n_iterations=1, random_state=0, prior="paper")
    assert paper.hyperparameters.psi0 == TransferHyperparameters().psi0 and paper.hyperparameters.psi0_in_cm2
