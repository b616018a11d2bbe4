"""Priors that fit the map (issue 29): κ0, L and K follow the homes' spread and place sizes in their
own map units; the paper's constants stay one argument away."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.sparse as sp

from spco.errors import ConfigurationError
from spco.model.hyperparameters import TransferHyperparameters, home_scales, scaled_hyperparameters


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
