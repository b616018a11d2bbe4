"""The split–merge move of a teaching (``spco.model.local_update.split_merge_proposal``) against
brute force on a tiny problem: its log acceptance ratio is the ratio of the joint posterior
p(x, R | C) computed independently (each region's points by the chain rule of Student-t posterior
predictives, each concept's regions by the Pólya urn), and the Metropolis–Hastings kernel it makes
keeps that posterior, exactly, over every assignment of the points to the regions."""
from __future__ import annotations

import itertools

import numpy as np
import pytest
from scipy.stats import multivariate_t

from spco.model.local_update import split_merge_proposal
from spco.model.observations import NIWPrior

X = np.array([[0.0, 0.1], [0.3, -0.2], [2.0, 2.2], [2.4, 1.9]])
CONCEPTS = np.array([0, 1, 1, 0])
K, BETA = 3, 1.5
PRIOR = NIWPrior(mu0=np.array([[1.0, 1.0]]), kappa0=0.2, psi0=np.diag([0.3, 0.2]), nu0=4.0)


def _log_positions(points: np.ndarray) -> float:
    """log p(points) of one region by the chain rule: each point's Student-t predictive given those before."""
    d = points.shape[1]
    mu, kappa, psi, nu = PRIOR.mu0[0].copy(), PRIOR.kappa0, PRIOR.psi0.copy(), PRIOR.nu0
    total = 0.0
    for p in points:
        dof = nu - d + 1
        total += multivariate_t.logpdf(p, loc=mu, shape=psi * (kappa + 1) / (kappa * dof), df=dof)
        diff = p - mu
        psi = psi + kappa / (kappa + 1) * np.outer(diff, diff)
        mu = (kappa * mu + p) / (kappa + 1)
        kappa, nu = kappa + 1, nu + 1
    return float(total)


def _log_regions(regions: np.ndarray) -> float:
    """log p(R | C): each concept's regions drawn one after another from the Pólya urn of Dir(β/K)."""
    total = 0.0
    for c in np.unique(CONCEPTS):
        counts = np.zeros(K)
        for r in regions[CONCEPTS == c]:
            total += np.log((BETA / K + counts[r]) / (BETA + counts.sum()))
            counts[r] += 1
    return float(total)


def _log_joint(regions: np.ndarray) -> float:
    used = [k for k in range(K) if (regions == k).any()]
    return _log_regions(regions) + sum(_log_positions(X[regions == k]) for k in used)


STATES = [np.array(s) for s in itertools.product(range(K), repeat=len(X))]


OPENABLE = [np.ones(K, dtype=bool), np.array([False, True, True]), np.array([False, False, True])]


@pytest.mark.parametrize("openable", OPENABLE)
@pytest.mark.parametrize("row", [0, 1])
def test_the_acceptance_ratio_is_the_posterior_ratio_by_brute_force(row: int, openable: np.ndarray) -> None:
    offered = 0
    for regions in STATES:
        for split in (True, False):
            proposal = split_merge_proposal(X, regions, CONCEPTS, row, openable, PRIOR, split)
            if proposal is None:
                continue
            proposed, log_ratio = proposal
            offered += 1
            assert log_ratio == pytest.approx(_log_joint(proposed) - _log_joint(regions), abs=1e-9)
            # the reverse move exists and gives the state back
            back = split_merge_proposal(X, proposed, CONCEPTS, row, openable, PRIOR, not split)
            assert back is not None
            np.testing.assert_array_equal(back[0], regions)
    assert offered >= 4  # splits and merges were both offered on this problem


@pytest.mark.parametrize("openable", OPENABLE)
@pytest.mark.parametrize("row", [0, 1, 2])
def test_the_kernel_keeps_the_posterior_exactly(row: int, openable: np.ndarray) -> None:
    index = {tuple(s): i for i, s in enumerate(STATES)}
    log_p = np.array([_log_joint(s) for s in STATES])
    p = np.exp(log_p - log_p.max())
    p /= p.sum()
    T = np.zeros((len(STATES), len(STATES)))
    for i, regions in enumerate(STATES):
        for split in (True, False):
            proposal = split_merge_proposal(X, regions, CONCEPTS, row, openable, PRIOR, split)
            if proposal is None:
                continue
            proposed, log_ratio = proposal
            T[i, index[tuple(proposed)]] += 0.5 * min(1.0, float(np.exp(log_ratio)))
        T[i, i] += 1.0 - T[i].sum()
    moving = (np.diag(T) < 1.0).sum()
    assert moving >= 4  # the move changes several of the states
    np.testing.assert_allclose(p @ T, p, rtol=0, atol=1e-13)
