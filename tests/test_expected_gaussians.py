"""The Gaussians a teaching answers with (``spco.model.local_update.expected_gaussians``): the posterior
mean of a region's (μ, Σ) given its points — what the average of infinitely many of the sampler's draws
gives — checked against the Student-t posterior predictive computed independently (the NIW updated one
point at a time) and against the average of many draws of the sampler's own NIW kernel."""
from __future__ import annotations

import numpy as np

from spco.model.kernels.niw import sample_niw
from spco.model.local_update import expected_gaussians
from spco.model.observations import NIWPrior

PRIOR = NIWPrior(mu0=np.array([[1.0, -0.5, 0.2]]), kappa0=0.3, psi0=np.diag([0.4, 0.2, 0.1]), nu0=5.0)
POINTS = [np.array([[0.1, 0.2, 0.0], [0.4, -0.1, 0.3], [0.2, 0.5, -0.2], [0.9, 0.0, 0.1]]),
          np.array([[2.0, 2.0, 1.0]])]


def _statistics(points: np.ndarray) -> tuple[float, np.ndarray, np.ndarray]:
    return float(points.shape[0]), points.sum(axis=0), points.T @ points


def _predictive(points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Mean and covariance of the Student-t predictive, the NIW updated point by point."""
    d = points.shape[1]
    mu, kappa, psi, nu = PRIOR.mu0[0].copy(), PRIOR.kappa0, PRIOR.psi0.copy(), PRIOR.nu0
    for p in points:
        diff = p - mu
        psi = psi + kappa / (kappa + 1) * np.outer(diff, diff)
        mu = (kappa * mu + p) / (kappa + 1)
        kappa, nu = kappa + 1, nu + 1
    dof = nu - d + 1
    shape = psi * (kappa + 1) / (kappa * dof)
    return mu, shape * dof / (dof - 2)


def test_the_expected_gaussians_are_the_posterior_predictive_moments() -> None:
    stats = [_statistics(p) for p in POINTS]
    count = np.array([s[0] for s in stats])
    total = np.stack([s[1] for s in stats])
    scatter = np.stack([s[2] for s in stats])
    means, covariances = expected_gaussians(count, total, scatter, PRIOR)
    for k, points in enumerate(POINTS):
        mean, covariance = _predictive(points)
        np.testing.assert_allclose(means[k], mean, rtol=1e-12, atol=1e-12)
        np.testing.assert_allclose(covariances[k], covariance, rtol=1e-12, atol=1e-12)


def test_the_expected_gaussians_are_what_many_draws_average_to() -> None:
    from spco.model.kernels.niw import niw_posterior

    count, total, scatter = _statistics(POINTS[0])
    mu_n, kappa_n, psi_n, nu_n = niw_posterior(np.array([count]), total[None], scatter[None], PRIOR.mu0[0],
                                               PRIOR.kappa0, PRIOR.psi0, PRIOR.nu0)
    n = 200_000
    mu, sigma = sample_niw(np.repeat(mu_n, n, axis=0), np.repeat(kappa_n, n), np.repeat(psi_n, n, axis=0),
                           np.repeat(nu_n, n), np.random.default_rng(0))
    average_mean = mu.mean(axis=0)
    average_covariance = (sigma + mu[:, :, None] * mu[:, None, :]).mean(axis=0) - np.outer(average_mean,
                                                                                           average_mean)
    means, covariances = expected_gaussians(np.array([count]), total[None], scatter[None], PRIOR)
    np.testing.assert_allclose(average_mean, means[0], atol=0.01)
    np.testing.assert_allclose(average_covariance, covariances[0], atol=0.02 * np.abs(covariances[0]).max())
