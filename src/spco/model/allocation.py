"""Allocation models: how samples pick concepts (an HDP over homes) and regions (per concept).

- Concepts: G_0 ~ Dir(γ0/L) (weak-limit GEM(γ0)), G_e ~ Dir(γ G_0), C_t ~ Cat(G_e). Given the
  concept counts n_{e,l}, table counts m_{e,l} ~ CRT(n_{e,l}, γ G_{0,l}) make G_0 conjugate:
  G_0 | m ~ Dir(γ0/L + Σ_e m_{e,·}); then G_e | G_0, n ~ Dir(γ G_0 + n_{e,·}).
- Regions: π_{e,l} ~ Dir(β/K), R_t ~ Cat(π_{e,C_t}); π_{e,l} | n ~ Dir(β/K + n_{e,l,·}).
- The local step: the joint conditional of (C_t, R_t), or the two blocks R | C and C | R used by the
  authors.
"""

from __future__ import annotations

import numpy as np

from spco.model.kernels.categorical import sample_categorical_log, sample_joint_assignment
from spco.model.kernels.crt import sample_crt
from spco.model.kernels.dirichlet import log_dirichlet


def concept_counts(homes: np.ndarray, concepts: np.ndarray, n_homes: int, n_concepts: int) -> np.ndarray:
    """n_{e,l}: samples of home e in concept l, shape (E, L)."""
    return np.bincount(homes * n_concepts + concepts, minlength=n_homes * n_concepts).reshape(
        n_homes, n_concepts)


def region_counts(homes: np.ndarray, concepts: np.ndarray, regions: np.ndarray, n_homes: int,
                  n_concepts: int, n_regions: int) -> np.ndarray:
    """n_{e,l,m}: samples of home e in concept l and region m, shape (E, L, K)."""
    flat = (homes * n_concepts + concepts) * n_regions + regions
    return np.bincount(flat, minlength=n_homes * n_concepts * n_regions).reshape(
        n_homes, n_concepts, n_regions)


def sample_global_concept_weights(n_el: np.ndarray, log_g0: np.ndarray, gamma: float, gamma0: float,
                                  rng: np.random.Generator) -> np.ndarray:
    """log G_0 | concept counts, by table counts m_{e,l} ~ CRT(n_{e,l}, γ G_{0,l}); returns (L,)."""
    tables = sample_crt(n_el, gamma * np.exp(log_g0)[None, :], rng).sum(axis=0)
    n_concepts = n_el.shape[1]
    return log_dirichlet(gamma0 / n_concepts + tables, rng)


def sample_home_concept_weights(n_el: np.ndarray, log_g0: np.ndarray, gamma: float,
                                rng: np.random.Generator, extra: float = 0.0) -> np.ndarray:
    """log G_e ~ Dir(γ G_0 + n_{e,·} + extra) for every home; (E, L). ``extra`` = 50 in the
    authors' code (reference variant), 0 in the model."""
    return log_dirichlet(gamma * np.exp(log_g0)[None, :] + n_el + extra, rng)


def sample_region_weights(n_elm: np.ndarray, concentration: float, rng: np.random.Generator) -> np.ndarray:
    """log π_{e,l} ~ Dir(concentration + n_{e,l,·}); (E, L, K). The model uses β/K, the authors β."""
    return log_dirichlet(concentration + n_elm, rng)


def sample_assignments_joint(
    log_g: np.ndarray, log_pi: np.ndarray, homes: np.ndarray, concept_loglik: np.ndarray,
    region_loglik: np.ndarray, rng: np.random.Generator,
) -> tuple[np.ndarray, np.ndarray]:
    """Draw (C_t, R_t) jointly for every sample.

    p(C_t = l, R_t = m) ∝ G_{e,l} π_{e,l,m} N(x_t | μ_{e,m}, Σ_{e,m}) p(v_t, w_t | θ_{e,l}).

    Shapes: log_g (E, L), log_pi (E, L, K), homes (N,), concept_loglik (N, L) (visual + word
    log-likelihood), region_loglik (N, K). Returns C (N,) and R (N,).
    """
    n_regions = log_pi.shape[2]
    flat = sample_joint_assignment(log_g, log_pi, homes, concept_loglik, region_loglik, rng)
    return flat // n_regions, flat % n_regions


def sample_regions_given_concepts(log_pi: np.ndarray, homes: np.ndarray, concepts: np.ndarray,
                                  region_loglik: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """R_t | C_t: p(R_t = m) ∝ π_{e,C_t,m} N(x_t | μ_{e,m}, Σ_{e,m}); returns (N,)."""
    return sample_categorical_log(log_pi[homes, concepts] + region_loglik, rng)


def sample_concepts_given_regions(log_g: np.ndarray, log_pi: np.ndarray, homes: np.ndarray,
                                  regions: np.ndarray, concept_loglik: np.ndarray,
                                  rng: np.random.Generator) -> np.ndarray:
    """C_t | R_t: p(C_t = l) ∝ G_{e,l} π_{e,l,R_t} p(v_t, w_t | θ_{e,l}); returns (N,)."""
    logp = log_g[homes] + log_pi[homes, :, regions] + concept_loglik
    return sample_categorical_log(logp, rng)
