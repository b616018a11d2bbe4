"""Observation models, one per modality: where each conditional of the sampler lives.

- :class:`GaussianRegions` — positions x = (x, y, sin θ, cos θ) from per-home Gaussian regions
  with a Normal–inverse-Wishart prior: sufficient statistics, posterior draws, log-likelihood.
- :class:`HierarchicalMultinomial` — bags of counts (words or visual features) from per-home
  θ_{e,l} ~ Dir(δ φ_l) around shared φ_l ~ Dir(α): log-likelihood, count statistics, the
  auxiliary table counts that make φ | counts conjugate, and the draws of φ and θ.

All functions work on every home at once (stacked arrays); shapes use N samples, E homes,
L concepts, K regions and D dimensions (words or visual features).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp
from scipy.special import gammaln, multigammaln

from spco.model.hyperparameters import PHI_PASSES
from spco.model.kernels.counts import (
    grouped_moments,
    grouped_row_sums,
    grouped_weighted_row_sums,
    move_rows,
)
from spco.model.kernels.crt import sample_crt_totals
from spco.model.kernels.dirichlet import log_dirichlet, log_dirichlet_hierarchical
from spco.model.kernels.fractional import FractionalCounts, fractional_log_weights_by_dimension
from spco.model.kernels.gaussian import grouped_gaussian_log_density
from spco.model.kernels.likelihood import (
    DimensionMajorCounts,
    blocked_sparse_dot,
    dimension_major_dot,
    likelihood_table,
)
from spco.model.kernels.niw import niw_posterior, sample_niw
from spco.model.kernels.special import scaled_exp

#: Log-probabilities below this are clipped in likelihoods: a count times it is still finite
#: (no -inf, hence no NaN after normalisation) and still means "impossible".
LOG_FLOOR = -1e100


@dataclass(frozen=True)
class NIWPrior:
    """Normal–inverse-Wishart prior of the region Gaussians, in the sampler's position units.

    mu0: (E, 4) prior mean per home (the map centre, or the origin in the reference variant).
    kappa0, nu0: scalars; psi0: (4, 4).
    """

    mu0: np.ndarray
    kappa0: float
    psi0: np.ndarray
    nu0: float


class GaussianRegions:
    """Positions from Gaussian regions: x_t ~ N(μ_{e,R_t}, Σ_{e,R_t}), (μ, Σ) ~ NIW."""

    @staticmethod
    def statistics(positions: np.ndarray, homes: np.ndarray, regions: np.ndarray, n_homes: int,
                   n_regions: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Sufficient statistics of every region of every home.

        Returns count (E, K), total Σx (E, K, 4) and scatter Σxxᵀ (E, K, 4, 4).
        """
        d = positions.shape[1]
        count, total, scatter = grouped_moments(positions, homes * n_regions + regions, n_homes * n_regions)
        return (count.reshape(n_homes, n_regions), total.reshape(n_homes, n_regions, d),
                scatter.reshape(n_homes, n_regions, d, d))

    @staticmethod
    def sample_posterior(count: np.ndarray, total: np.ndarray, scatter: np.ndarray, prior: NIWPrior,
                         rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
        """(μ, Σ)_{e,m} ~ NIW(μ_n, κ_n, Ψ_n, ν_n) for every region: μ (E, K, 4), Σ (E, K, 4, 4)."""
        mu0 = np.broadcast_to(prior.mu0[:, None, :], total.shape)
        mu_n, kappa_n, psi_n, nu_n = niw_posterior(count, total, scatter, mu0, prior.kappa0, prior.psi0,
                                                   prior.nu0)
        return sample_niw(mu_n, kappa_n, psi_n, nu_n, rng)

    @staticmethod
    def log_likelihood(positions: np.ndarray, homes: np.ndarray, means: np.ndarray,
                       covariances: np.ndarray) -> np.ndarray:
        """log N(x_t | μ_{e_t,m}, Σ_{e_t,m}) for every sample and region of its home: (N, K)."""
        return grouped_gaussian_log_density(positions, homes, means, covariances)

    @staticmethod
    def log_prior(means: np.ndarray, covariances: np.ndarray, prior: NIWPrior) -> float:
        """Σ_{e,m} log NIW(μ_{e,m}, Σ_{e,m} | μ0, κ0, Ψ0, ν0)."""
        d = means.shape[-1]
        chol = np.linalg.cholesky(covariances)
        log_det_sigma = 2.0 * np.log(np.diagonal(chol, axis1=-2, axis2=-1)).sum(-1)
        inv_sigma = np.linalg.inv(covariances)
        nu0 = prior.nu0
        _, log_det_psi = np.linalg.slogdet(prior.psi0)
        log_iw = (0.5 * nu0 * log_det_psi - 0.5 * nu0 * d * np.log(2.0) - multigammaln(0.5 * nu0, d)
                  - 0.5 * (nu0 + d + 1) * log_det_sigma
                  - 0.5 * np.einsum("ij,ekji->ek", prior.psi0, inv_sigma))
        diff = means - prior.mu0[:, None, :]
        quad = np.einsum("eki,ekij,ekj->ek", diff, inv_sigma, diff) * prior.kappa0
        log_normal = -0.5 * (quad + log_det_sigma - d * np.log(prior.kappa0) + d * np.log(2 * np.pi))
        return float((log_iw + log_normal).sum())


#: The power target's φ^v step (:meth:`HierarchicalMultinomial.accept_shared`): dimensions per block
#: (its passes per step: ``TransferHyperparameters.phi_passes``, default
#: :data:`~spco.model.hyperparameters.PHI_PASSES`); benchmarks/README.md, "Issue 29: an exact φ^v
#: step at fc7's size".
PHI_BLOCK_SIZE = 8

#: The last concentrations δ φ computed by :func:`shared_concentration`: (log φ, δ, a copy of
#: log φ, δ φ), most recent first.
_CONCENTRATIONS: list[tuple[np.ndarray, float, np.ndarray, np.ndarray]] = []


def shared_concentration(log_phi: np.ndarray, delta: float) -> np.ndarray:
    """δ φ from log φ (:func:`~spco.model.kernels.special.scaled_exp`), remembered for the same φ:
    the homes of a shard, each drawing its own θ and tables given the same shared φ, compute it
    once per sweep. A remembered value is used only for the same array holding the same values
    (compared with a copy), so it is exactly what ``scaled_exp`` gives. Callers must not write into
    the result."""
    for source, scale, values, result in _CONCENTRATIONS:
        if source is log_phi and scale == delta and values.shape == log_phi.shape \
                and np.array_equal(values, log_phi):
            return result
    result = scaled_exp(log_phi, delta)
    _CONCENTRATIONS.insert(0, (log_phi, float(delta), np.array(log_phi, copy=True), result))
    del _CONCENTRATIONS[4:]
    return result


class HierarchicalMultinomial:
    """Bags of counts: c_t ~ Mult(θ_{e,C_t}), θ_{e,l} ~ Dir(δ φ_l), φ_l ~ Dir(α).

    A bag may enter with a power s_t ∈ (0, 1], its likelihood Mult(c_t | θ)^{s_t} (the visual
    channel's view weight, ``docs/samplers.md``): every conditional then sees the weighted counts
    n_{e,l,k} = Σ_t s_t c_tk, real numbers (:meth:`weighted_statistics`). θ_{e,l} | n ~
    Dir(δ φ_l + n_{e,l}) is conjugate for real n as for whole ones, and with θ integrated out
    the counts weigh Π_k Γ(δ φ_{l,k} + n_{e,l,k}) / Γ(δ φ_{l,k}) (the label swaps' ratio).

    The conditional of φ given counts is not conjugate. For whole counts the exact sampler
    introduces table counts m_{e,l,k} ~ CRT(n_{e,l,k}, δ φ_{l,k}) (Teh et al. 2006), after which
    φ_l | m ~ Dir(α + Σ_e m_{e,l,·}). For real counts n = ⌊n⌋ + f, Γ(a + n)/Γ(a) =
    [Γ(a + ⌊n⌋)/Γ(a)] · [Γ(a + n)/Γ(a + ⌊n⌋)]: the first factor is augmented by CRT(⌊n⌋, a)
    tables as before, and φ_l is drawn from Dir(α + Σ_e m + Σ_{e: n < 1} n) (the second factor
    approximated by a^n where ⌊n⌋ = 0, by 1 elsewhere: the importance weights stay bounded as
    a → 0, so chains do not stick near φ = 0) and accepted by Metropolis–Hastings with the exact
    remainder, in blocks of dimensions (:meth:`accept_shared`): a valid step of the augmented chain,
    the CRT step itself when every count is whole.
    """

    @staticmethod
    def log_likelihood(counts: sp.csr_array, homes: np.ndarray, log_theta: np.ndarray,
                       by_dimension: DimensionMajorCounts | None = None) -> np.ndarray:
        """Σ_k c_tk log θ_{e_t,l,k} for every sample and concept: (N, L).

        ``log_theta`` (E, L, D); entries below :data:`LOG_FLOOR` are clipped to it. The
        multinomial coefficient, the same for every concept, is left out. ``by_dimension``: the
        same counts in the layout of :func:`~spco.model.kernels.likelihood.dimension_major` (rows in home
        blocks), which the sampler builds once per fit for the visual counts; the result is the
        same, faster.
        """
        if by_dimension is not None:
            return dimension_major_dot(by_dimension, log_theta, LOG_FLOOR)
        return blocked_sparse_dot(counts, homes, likelihood_table(log_theta, LOG_FLOOR), log_theta.shape[1])

    @staticmethod
    def statistics(counts: sp.csr_array, homes: np.ndarray, concepts: np.ndarray, n_homes: int,
                   n_concepts: int) -> np.ndarray:
        """n_{e,l,k} = Σ_{t in e: C_t = l} c_tk, shape (E, L, D), int64."""
        sums = grouped_row_sums(counts, homes * n_concepts + concepts, n_homes * n_concepts, blocks=homes)
        return sums.reshape(n_homes, n_concepts, counts.shape[1])

    @staticmethod
    def weighted_statistics(counts: sp.csr_array, weights: np.ndarray, homes: np.ndarray,
                            concepts: np.ndarray,
                            n_homes: int, n_concepts: int) -> np.ndarray:
        """n_{e,l,k} = Σ_{t in e: C_t = l} s_t c_tk for the powers ``weights`` s (N,): (E, L, D)
        float64, each entry summed in row order (the same sums whatever changed before)."""
        groups = np.asarray(homes, dtype=np.int64) * n_concepts + np.asarray(concepts, dtype=np.int64)
        sums = grouped_weighted_row_sums(sp.csr_array(counts), weights, groups, n_homes * n_concepts)
        return np.maximum(sums, 0.0).reshape(n_homes, n_concepts, counts.shape[1])

    @staticmethod
    def move_counts(n: np.ndarray, counts: sp.csr_array, rows: np.ndarray, homes: np.ndarray,
                    old: np.ndarray, new: np.ndarray) -> None:
        """Update n (E, L, D) in place for samples ``rows`` (of the CSR ``counts``) that moved from
        concept ``old`` to concept ``new`` in their home: n_{e,old} −= c_t, n_{e,new} += c_t."""
        if rows.size:
            move_rows(n, counts.indptr, counts.indices, counts.data, np.asarray(rows, dtype=np.int64),
                      np.asarray(homes, dtype=np.int64), np.asarray(old, dtype=np.int64),
                      np.asarray(new, dtype=np.int64))

    @staticmethod
    def sample_tables(n: np.ndarray, log_phi: np.ndarray, delta: float,
                      rng: np.random.Generator) -> np.ndarray:
        """Table counts summed over homes: Σ_e m_{e,l,k}, m ~ CRT(n_{e,l,k}, δ φ_{l,k}); (L, D)."""
        return sample_crt_totals(n, shared_concentration(log_phi, delta), rng)

    @staticmethod
    def table_parts(n: np.ndarray, log_phi: np.ndarray, delta: float,
                    rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(M, F, H), each (L, D), what :meth:`sample_shared_given_counts` needs from a group of homes:
        M = Σ_e m_{e,l,k}, m ~ CRT(⌊n_{e,l,k}⌋, δ φ_{l,k}); F = Σ_e of the counts below 1 (n − ⌊n⌋ where
        ⌊n⌋ = 0), the part of the fractions the proposal counts; H = the number of homes whose count
        has a fractional part (all 0 for whole counts: no Metropolis–Hastings test)."""
        whole, frac, fractional = HierarchicalMultinomial.whole_parts(n)
        return HierarchicalMultinomial.sample_tables(whole, log_phi, delta, rng), frac, fractional

    @staticmethod
    def whole_parts(n: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(⌊n⌋, F, H) of the counts n (E, L, D): ⌊n⌋ (E, L, D) int64, the counts the CRT tables are
        drawn from; F and H (L, D) as :meth:`table_parts`. Whole counts are returned as they are,
        with F = H = 0, without looking for fractions."""
        if n.dtype.kind in "iu":
            zeros = np.zeros(n.shape[1:])
            return n, zeros, zeros
        whole = np.floor(n)
        return (whole.astype(np.int64), np.where(whole == 0.0, n, 0.0).sum(axis=0),
                (n != whole).sum(axis=0).astype(np.float64))

    @staticmethod
    def fractional_log_weight(n: np.ndarray, log_phi: np.ndarray, delta: float) -> np.ndarray:
        """(L,) Σ_e Σ_k [ln Γ(a + n) − ln Γ(a + ⌊n⌋) − [⌊n⌋ = 0] n ln a], a = δ φ_{l,k}, over the
        entries n_{e,l,k} (E, L, D) with a fractional part: the log ratio of the exact
        Dirichlet–multinomial weight of φ to what the proposal of
        :meth:`sample_shared_given_counts` counts (0 for whole counts). An a that underflows to 0
        where a count is fractional gives −inf (a proposal there is refused)."""
        return HierarchicalMultinomial.fractional_log_weight_terms(n, log_phi, delta).sum(axis=1)

    @staticmethod
    def fractional_log_ratio(n: np.ndarray, log_phi_old: np.ndarray, log_phi_new: np.ndarray,
                             delta: float) -> np.ndarray:
        """(L,) w(φ_new) − w(φ_old), w = :meth:`fractional_log_weight`: a proposal's log acceptance
        ratio from the counts ``n``."""
        return (HierarchicalMultinomial.fractional_log_weight(n, log_phi_new, delta)
                - HierarchicalMultinomial.fractional_log_weight(n, log_phi_old, delta))

    @staticmethod
    def fractional_log_weight_terms(n: np.ndarray, log_phi: np.ndarray, delta: float) -> np.ndarray:
        """(L, D): the terms of :meth:`fractional_log_weight` at ``log_phi`` summed over the homes of the
        counts ``n`` (E, L, D) but kept per dimension, w_{l,k}; Σ_k w_{l,k} is the weight (all 0 for
        whole counts)."""
        if n.dtype.kind in "iu":
            return np.zeros(np.shape(log_phi))
        return fractional_log_weights_by_dimension(n, log_phi, delta)

    @staticmethod
    def fractional_log_weight_evaluator(n: np.ndarray, delta: float) -> Callable[[np.ndarray], np.ndarray]:
        """log φ (L, D) ↦ :meth:`fractional_log_weight_terms` (n, log φ, δ) (L, D), to the bit, with the
        fractional entries of the counts n (E, L, D) gathered once
        (:class:`~spco.model.kernels.fractional.FractionalCounts`) at the first evaluation: what the
        blocked φ^v step evaluates at its start and once a pass. The counts must not change while it
        is used."""
        if n.dtype.kind in "iu":
            return lambda log_phi: np.zeros(np.shape(log_phi))
        gathered: list[FractionalCounts] = []

        def evaluate(log_phi: np.ndarray) -> np.ndarray:
            if not gathered:
                gathered.append(FractionalCounts([n]))
            return gathered[0].log_weights(log_phi, delta)
        return evaluate

    @staticmethod
    def sample_shared_given_counts(n: np.ndarray, log_phi: np.ndarray, delta: float, prior,
                                   rng: np.random.Generator, passes: int | None = None) -> np.ndarray:
        """log φ_l | n (θ integrated out) for every concept, from the counts n (E, L, D) of all
        homes concerned: the table counts M and fractional parts F of :meth:`table_parts`, then
        :meth:`accept_shared` (the blocked Metropolis–Hastings step for φ with target
        ∝ Dir(φ | prior + M + F) exp(w(φ)), w = :meth:`fractional_log_weight`). For whole counts F = 0,
        w = 0 and this is the CRT step, drawing the same numbers. ``prior``: α, a number or (L, D);
        ``passes``: the blocked step's passes (``TransferHyperparameters.phi_passes``; ``None``:
        :data:`~spco.model.hyperparameters.PHI_PASSES`)."""
        tables, frac, fractional = HierarchicalMultinomial.table_parts(n, log_phi, delta, rng)
        return HierarchicalMultinomial.accept_shared(
            HierarchicalMultinomial.fractional_log_weight_evaluator(n, delta),
            log_phi, prior, tables, frac, rng, fractional, passes=passes)

    @staticmethod
    def accept_shared(log_weights, log_phi: np.ndarray, prior, tables: np.ndarray, frac: np.ndarray,
                      rng: np.random.Generator, fractional=True, block_size: int | None = None,
                      passes: int | None = None) -> np.ndarray:
        """log φ (L, D) given the tables: a draw of Dir(c), c = prior + tables + frac, for every concept
        without a fractional count (the CRT step: exact), and for the others the blocked
        Metropolis–Hastings step below, which leaves their target
        p(φ) ∝ Π_k φ_k^{c_k − 1} exp(w_k(φ_k)) on the simplex invariant. No fractional count at all:
        the proposal itself (the CRT step, nothing else drawn).

        ``log_weights(log φ)`` → (L, D): the weight's terms w_{l,k}(φ_{l,k}) per dimension, summed over
        every home concerned (:meth:`fractional_log_weight_terms`): the target over the proposal's
        density, which factors over dimensions. ``fractional``: which entries have a fractional part
        (an array (L, D) or (L,), or a bool for every concept).

        The step. One draw of the whole vector, accepted with exp(Σ_k w_k(φ'_k) − w_k(φ_k)), is never
        accepted at D = 4,096 (the sum over dimensions spreads over thousands of nats). The density
        factors over dimensions given the simplex, so φ moves in blocks: each of ``passes`` passes
        splits the dimensions into blocks B of ``block_size`` (a fresh uniform random partition each
        pass, drawn independently of φ), keeps each block's total S_B = Σ_{k∈B} φ_k and proposes its
        proportions u'_B = φ'_B / S_B ~ Dir(c_B). Given the totals, φ_B = S_B u_B has density
        ∝ Π_{k∈B} u_k^{c_k − 1} exp(w_k(S_B u_k)) (the Jacobian S_B^{|B|−1} and S_B^{c_k − 1} are
        constants), the blocks are independent, and the proposal is the first factor, so the
        independence-sampler ratio of block B is

            r_B = exp(Σ_{k∈B} w_k(S_B u'_k) − w_k(S_B u_k)),

        accepted with probability min(1, r_B), each block on its own uniform. Each pass is
        Metropolis–Hastings for p(φ | the totals) and so leaves p(φ) invariant; the totals move
        between passes because the partitions change (a mixture over partitions chosen independently
        of φ is invariant too). The proportions of a block are drawn from one Dir(c) draw of the whole
        vector renormalised within the block (the Dirichlet's aggregation property: the blocks'
        proportions are independent Dir(c_B)). One block of every dimension is the independence
        sampler of the whole vector."""
        concentration = prior + tables + frac
        proposal = log_dirichlet(concentration, rng)
        n_concepts, n_dims = log_phi.shape
        if isinstance(fractional, bool | np.bool_):
            rows = np.full(n_concepts, bool(fractional))
        else:
            rows = np.asarray(fractional).reshape(n_concepts, -1).any(axis=1)
        if not rows.any():
            return proposal
        size = PHI_BLOCK_SIZE if block_size is None else block_size
        passes = PHI_PASSES if passes is None else passes
        if size < 2 or passes < 1:
            raise ValueError(f"accept_shared: block_size must be at least 2 and passes at least 1, "
                             f"got block_size={size}, passes={passes}")
        concentration = np.broadcast_to(concentration, log_phi.shape)
        current = np.where(rows[:, None], log_phi, proposal)
        weights = log_weights(current)
        n_blocks = max(1, n_dims // size)
        starts = np.linspace(0, n_dims, n_blocks + 1).astype(np.int64)[:-1]
        sizes = np.diff(np.append(starts, n_dims))
        chosen = np.flatnonzero(rows)
        every = chosen.size == n_concepts  # every row moves: the pass gathers columns only

        def gather(x: np.ndarray, order: np.ndarray) -> np.ndarray:
            """x's chosen rows, columns in ``order`` (C order, as the blocks' sums read them)."""
            return np.take(x, order, axis=1) if every else x[np.ix_(chosen, order)]

        for step in range(passes):
            draw = proposal if step == 0 else log_dirichlet(concentration[chosen], rng)
            if step == 0 and not every:
                draw = draw[chosen]
            order = rng.permutation(n_dims)
            draw = np.take(draw, order, axis=1)
            moved = draw + np.repeat(_block_logsumexp(gather(current, order), starts)
                                     - _block_logsumexp(draw, starts), sizes, axis=1)
            at = (slice(None), order) if every else np.ix_(chosen, order)
            candidate = current.copy()
            candidate[at] = moved
            new_weights = log_weights(candidate)
            delta_w = gather(new_weights, order) - gather(weights, order)
            with np.errstate(invalid="ignore"):
                ratio = np.add.reduceat(delta_w, starts, axis=1)
                accept = np.log(rng.random(ratio.shape)) < ratio
            take = np.zeros(log_phi.shape, dtype=bool)
            take[at] = np.repeat(accept, sizes, axis=1)
            current = np.where(take, candidate, current)
            weights = np.where(take, new_weights, weights)
        current[chosen] -= _logsumexp_last(current[chosen])  # rounding of the blocks' totals
        return current

    @staticmethod
    def sample_shared(pseudo_counts: np.ndarray, alpha: float, rng: np.random.Generator) -> np.ndarray:
        """log φ_l ~ Dir(α + pseudo_counts_l) for every concept; (L, D)."""
        return log_dirichlet(alpha + pseudo_counts, rng)

    @staticmethod
    def sample_specific(n: np.ndarray, log_phi: np.ndarray, delta: float, rng: np.random.Generator,
                        out: np.ndarray | None = None) -> np.ndarray:
        """log θ_{e,l} ~ Dir(δ φ_l + n_{e,l}) for every home and concept (n whole or real); (E, L, D). ``out``
        (optional): an array of that shape to draw into, such as the previous draw."""
        return log_dirichlet_hierarchical(shared_concentration(log_phi, delta), n, rng, out=out)

    @staticmethod
    def log_prior_specific(log_theta: np.ndarray, log_phi: np.ndarray, delta: float,
                           mask: np.ndarray | None = None) -> float:
        """Σ_{e,l} log Dir(θ_{e,l} | δ φ_l), over the dimensions in ``mask`` (all by default)."""
        if mask is not None:
            log_theta = log_theta[..., mask]
            log_phi = log_phi[..., mask]
            log_theta = log_theta - _logsumexp_last(log_theta)
            log_phi = log_phi - _logsumexp_last(log_phi)
        a = delta * np.exp(log_phi)  # (L, D)
        normaliser = gammaln(a.sum(-1)) - np.where(a > 0, gammaln(np.where(a > 0, a, 1.0)), 0.0).sum(-1)
        weighted = np.where(a[None] > 0, (a[None] - 1.0) * np.maximum(log_theta, LOG_FLOOR), 0.0)
        return float(log_theta.shape[0] * normaliser.sum() + weighted.sum())

    @staticmethod
    def log_prior_shared(log_phi: np.ndarray, alpha: float, mask: np.ndarray | None = None) -> float:
        """Σ_l log Dir(φ_l | α) over the dimensions in ``mask`` (all by default)."""
        if mask is not None:
            log_phi = log_phi[..., mask]
            log_phi = log_phi - _logsumexp_last(log_phi)
        d = log_phi.shape[-1]
        return float(log_phi.shape[0] * (gammaln(alpha * d) - d * gammaln(alpha))
                     + (alpha - 1.0) * np.maximum(log_phi, LOG_FLOOR).sum())


def _block_logsumexp(x: np.ndarray, starts: np.ndarray) -> np.ndarray:
    """(L, J) ln Σ exp over the column blocks of x (L, D) that begin at ``starts`` (J,)."""
    top = np.maximum.reduceat(x, starts, axis=1)
    top = np.where(np.isfinite(top), top, 0.0)
    sizes = np.diff(np.append(starts, x.shape[1]))
    return top + np.log(np.add.reduceat(np.exp(x - np.repeat(top, sizes, axis=1)), starts, axis=1))


def _logsumexp_last(x: np.ndarray) -> np.ndarray:
    from scipy.special import logsumexp

    return logsumexp(x, axis=-1, keepdims=True)
