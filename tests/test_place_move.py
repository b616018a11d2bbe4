"""The move of a taught place's region (``spco.model.local_update.place_conditional``) against brute
force on a tiny problem: its probabilities are the joint posterior p(x, R | C) of the states it can
reach, computed independently (each region's points by the chain rule of Student-t posterior
predictives, each concept's regions by the Pólya urn), and the kernel it makes keeps that posterior,
exactly, over every assignment of the points to the regions."""
from __future__ import annotations

import itertools

import numpy as np
import pytest
from scipy.stats import multivariate_t

from spco.model.local_update import place_conditional
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


def _moves(regions: np.ndarray, row: int, openable: np.ndarray) -> list[tuple[np.ndarray, float]]:
    """(next regions, probability) of the move from ``regions``: every candidate of the block."""
    conditional = place_conditional(X, regions, CONCEPTS, row, openable, PRIOR)
    if conditional is None:
        return [(regions, 1.0)]
    candidates, log_p = conditional
    part = (regions == regions[row]) & (CONCEPTS == CONCEPTS[row])
    out = []
    for k, lp in zip(candidates, log_p, strict=True):
        moved = regions.copy()
        moved[part] = k
        out.append((moved, float(np.exp(lp))))
    return out


@pytest.mark.parametrize("openable", OPENABLE)
@pytest.mark.parametrize("row", [0, 1])
def test_the_block_conditional_is_the_posterior_by_brute_force(row: int, openable: np.ndarray) -> None:
    applied = 0
    for regions in STATES:
        moves = _moves(regions, row, openable)
        if len(moves) == 1:
            continue
        applied += 1
        log_joint = np.array([_log_joint(moved) for moved, _ in moves])
        expected = np.exp(log_joint - np.logaddexp.reduce(log_joint))
        np.testing.assert_allclose([p for _, p in moves], expected, rtol=1e-9, atol=0)
        # from every state the move reaches, it finds the same candidates (a Gibbs step of one block)
        for moved, _ in moves:
            again = _moves(moved, row, openable)
            assert sorted(tuple(m) for m, _ in again) == sorted(tuple(m) for m, _ in moves)
    assert applied >= 4


@pytest.mark.parametrize("openable", OPENABLE)
@pytest.mark.parametrize("row", [0, 1, 2])
def test_the_kernel_keeps_the_posterior_exactly(row: int, openable: np.ndarray) -> None:
    index = {tuple(s): i for i, s in enumerate(STATES)}
    log_p = np.array([_log_joint(s) for s in STATES])
    p = np.exp(log_p - log_p.max())
    p /= p.sum()
    T = np.zeros((len(STATES), len(STATES)))
    for i, regions in enumerate(STATES):
        for moved, prob in _moves(regions, row, openable):
            T[i, index[tuple(moved)]] += prob
    np.testing.assert_allclose(T.sum(axis=1), 1.0, rtol=0, atol=1e-12)
    assert (np.diag(T) < 1.0 - 1e-9).sum() >= 4  # the move changes several of the states
    np.testing.assert_allclose(p @ T, p, rtol=0, atol=1e-13)
