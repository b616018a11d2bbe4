"""Batched random draws used by the Gibbs sampler, all vectorised or compiled.

- :func:`log_dirichlet` — many Dirichlet draws at once, returned as log-probabilities, exact even
  for tiny concentrations (α^w = 0.01, δ^w φ^w ≪ 1) where plain gamma variates underflow to 0.
- :func:`sample_niw` — a batch of Normal–inverse-Wishart draws by the Bartlett decomposition.
- :func:`sample_crt` — table counts m ~ CRT(n, a) of the Chinese restaurant process (Antoniak),
  exact Bernoulli sums for small n, moment-matched normal for the tail of large n.
- :func:`sample_categorical_log` — one categorical draw per row of a log-probability matrix.

Every function takes a :class:`numpy.random.Generator`; the compiled CRT kernel draws its own
uniforms from a counter-based hash seeded by that generator, so results do not depend on the
number of threads.
"""

from __future__ import annotations

from concurrent.futures import ThreadPoolExecutor

import numpy as np
from numba import njit, prange

# ----------------------------------------------------------------------------- Dirichlet


#: Arrays at least this large are drawn in two halves on two threads (NumPy releases the GIL).
_THREADED_SIZE = 200_000
_POOL: ThreadPoolExecutor | None = None


def _log_standard_gamma(shape: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """``log(rng.standard_gamma(shape))`` for shapes ≥ 1; large arrays are split in two fixed
    halves drawn (and logged) in parallel by two generators seeded from ``rng``, so the result
    depends on the seed only, never on timing or on the number of cores."""
    if shape.size < _THREADED_SIZE:
        return np.log(rng.standard_gamma(shape))
    global _POOL
    if _POOL is None:
        _POOL = ThreadPoolExecutor(max_workers=2, thread_name_prefix="spco-gamma")
    flat = shape.ravel()
    half = flat.size // 2
    children = [np.random.default_rng(s) for s in rng.integers(0, 2**63 - 1, size=2)]

    def draw(i: int) -> np.ndarray:
        part = flat[:half] if i == 0 else flat[half:]
        return np.log(children[i].standard_gamma(part))

    return np.concatenate(list(_POOL.map(draw, range(2)))).reshape(shape.shape)


#: log Gamma(a) variates below this are clipped (they arise for a < 1e-298 and mean "zero").
_LOG_GAMMA_FLOOR = -1e300


def log_gamma_variates(shape: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """log of Gamma(shape, 1) variates, exact in log space for any shape > 0.

    For shape < 1 uses G(a) = G(a + 1) · U^{1/a}, i.e. log G(a) = log G(a + 1) + log(U)/a, which
    stays finite where G(a) itself underflows to 0 (a = 1e-3 gives G < 1e-300 with probability
    ~0.5). A shape of exactly 0 gives -inf (a point mass at 0).
    """
    shape = np.asarray(shape, dtype=np.float64)
    small = shape < 1.0
    with np.errstate(divide="ignore"):
        out = _log_standard_gamma(np.where(small, shape + 1.0, shape), rng)
        if small.any():
            a = shape[small]
            log_u = np.log(rng.random(a.shape))
            with np.errstate(invalid="ignore"):
                out[small] += np.where(a > 0, np.maximum(log_u / np.maximum(a, 1e-300), _LOG_GAMMA_FLOOR),
                                       -np.inf)
    return out


def log_dirichlet(alpha: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """Draw Dirichlet vectors along the last axis and return their logarithms.

    Parameters
    ----------
    alpha: (..., D) non-negative concentrations; each row needs at least one positive entry.
        Entries equal to 0 give probability exactly 0 (log = -inf).

    Returns
    -------
    (..., D) log-probabilities; ``exp`` of each row sums to 1.
    """
    alpha = np.asarray(alpha, dtype=np.float64)
    if alpha.shape[-1] == 0:  # no dimension at all (e.g. no word was ever taught)
        return np.zeros(alpha.shape)
    log_g = log_gamma_variates(alpha, rng)
    return log_g - log_normaliser(log_g)


def log_normaliser(log_values: np.ndarray) -> np.ndarray:
    """log Σ exp along the last axis (keepdims), stable; rows of all -inf give -inf."""
    top = log_values.max(axis=-1, keepdims=True)
    safe_top = np.where(np.isfinite(top), top, 0.0)
    with np.errstate(divide="ignore"):
        return np.log(np.exp(log_values - safe_top).sum(axis=-1, keepdims=True)) + safe_top


def dirichlet(alpha: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """Draw Dirichlet vectors along the last axis (probabilities, see :func:`log_dirichlet`)."""
    return np.exp(log_dirichlet(alpha, rng))


def dirichlet_log_density(log_p: np.ndarray, alpha: np.ndarray) -> np.ndarray:
    """log Dir(p | α) of each row, given log p (shape (..., D)); entries with α = 0 are skipped."""
    from scipy.special import gammaln

    alpha = np.broadcast_to(alpha, log_p.shape)
    active = alpha > 0
    term = np.where(active, (alpha - 1.0) * np.where(active, log_p, 0.0), 0.0)
    return (gammaln(alpha.sum(-1)) - np.where(active, gammaln(np.where(active, alpha, 1.0)), 0.0).sum(-1)
            + term.sum(-1))


# ----------------------------------------------------------------------------- Normal–inverse-Wishart


def niw_posterior(
    count: np.ndarray, total: np.ndarray, scatter: np.ndarray,
    mu0: np.ndarray, kappa0: float, psi0: np.ndarray, nu0: float,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Posterior NIW parameters from sufficient statistics, batched over leading axes.

    Parameters
    ----------
    count: (...,) number of points n.
    total: (..., d) sum of the points Σ x.
    scatter: (..., d, d) sum of outer products Σ x xᵀ.
    mu0, kappa0, psi0, nu0: the prior (μ0 of shape (d,) or (..., d); Ψ0 of shape (d, d)).

    Returns
    -------
    (μ_n, κ_n, Ψ_n, ν_n) with κ_n = κ0 + n, ν_n = ν0 + n, μ_n = (κ0 μ0 + n x̄)/κ_n and
    Ψ_n = Ψ0 + S + (κ0 n/κ_n)(x̄ − μ0)(x̄ − μ0)ᵀ, S the centred scatter. Computed in the
    equivalent form Ψ_n = Ψ0 + Σxxᵀ + κ0 μ0μ0ᵀ − κ_n μ_n μ_nᵀ, symmetrised.
    """
    count = np.asarray(count, dtype=np.float64)
    kappa_n = kappa0 + count
    nu_n = nu0 + count
    mu0 = np.broadcast_to(mu0, total.shape)
    mu_n = (kappa0 * mu0 + total) / kappa_n[..., None]
    # Centre on μ0 for numerical stability: with y = x − μ0, Ψ_n = Ψ0 + Σyyᵀ − (Σy)(Σy)ᵀ/κ_n.
    sum_y = total - count[..., None] * mu0
    sum_yy = (scatter - total[..., :, None] * mu0[..., None, :] - mu0[..., :, None] * total[..., None, :]
              + count[..., None, None] * mu0[..., :, None] * mu0[..., None, :])
    psi_n = psi0 + sum_yy - sum_y[..., :, None] * sum_y[..., None, :] / kappa_n[..., None, None]
    psi_n = 0.5 * (psi_n + np.swapaxes(psi_n, -1, -2))
    return mu_n, kappa_n, psi_n, nu_n


def sample_niw(
    mu_n: np.ndarray, kappa_n: np.ndarray, psi_n: np.ndarray, nu_n: np.ndarray,
    rng: np.random.Generator,
) -> tuple[np.ndarray, np.ndarray]:
    """Draw (μ, Σ) ~ NIW(μ_n, κ_n, Ψ_n, ν_n) for a batch, by the Bartlett decomposition.

    Σ ~ IW(Ψ_n, ν_n) is drawn as Σ = (C A^{-T})(C A^{-T})ᵀ with C = chol(Ψ_n) and A the lower
    triangular Bartlett factor (A_ii = sqrt(χ²(ν − i)), A_ij ~ N(0, 1) below the diagonal), since
    Σ^{-1} = C^{-T} A Aᵀ C^{-1} ~ W(Ψ_n^{-1}, ν_n). Then μ ~ N(μ_n, Σ/κ_n).

    Shapes: mu_n (..., d), kappa_n (...,), psi_n (..., d, d), nu_n (...,). Returns μ (..., d) and
    Σ (..., d, d).
    """
    batch = psi_n.shape[:-2]
    d = psi_n.shape[-1]
    nu_n = np.broadcast_to(np.asarray(nu_n, dtype=np.float64), batch)
    chol_psi = np.linalg.cholesky(psi_n)
    dof = nu_n[..., None] - np.arange(d)  # χ² degrees of freedom ν − i, i = 0..d-1
    bartlett = np.zeros((*batch, d, d))
    diag = np.sqrt(rng.chisquare(dof))
    idx = np.arange(d)
    bartlett[..., idx, idx] = diag
    lower = np.tril_indices(d, -1)
    bartlett[..., lower[0], lower[1]] = rng.standard_normal((*batch, lower[0].size))
    # factor F = C A^{-T}:  solve A F' = Cᵀ  ->  F = (A^{-1} Cᵀ)ᵀ
    inv_a = np.linalg.inv(bartlett)
    factor = chol_psi @ np.swapaxes(inv_a, -1, -2)
    sigma = factor @ np.swapaxes(factor, -1, -2)
    sigma = 0.5 * (sigma + np.swapaxes(sigma, -1, -2))
    z = rng.standard_normal((*batch, d))
    mu = mu_n + np.einsum("...ij,...j->...i", factor, z) / np.sqrt(np.asarray(kappa_n))[..., None]
    return mu, sigma


def gaussian_log_density(x: np.ndarray, mean: np.ndarray, cov: np.ndarray) -> np.ndarray:
    """log N(x | mean_m, cov_m) for every point and component.

    Shapes: x (n, d); mean (K, d); cov (K, d, d). Returns (n, K).
    """
    return grouped_gaussian_log_density(x, np.zeros(x.shape[0], dtype=np.int64), mean[None], cov[None])


@njit(parallel=True, cache=True)
def _grouped_gaussian(x: np.ndarray, groups: np.ndarray, means: np.ndarray, inv_chol: np.ndarray,
                      constant: np.ndarray) -> np.ndarray:
    n, d = x.shape
    n_components = means.shape[1]
    out = np.empty((n, n_components))
    diff = np.empty(d)
    for t in prange(n):
        g = groups[t]
        diff = np.empty(d)
        for m in range(n_components):
            for i in range(d):
                diff[i] = x[t, i] - means[g, m, i]
            quad = 0.0
            for i in range(d):
                acc = 0.0
                for j in range(i + 1):
                    acc += inv_chol[g, m, i, j] * diff[j]
                quad += acc * acc
            out[t, m] = constant[g, m] - 0.5 * quad
    return out


def grouped_gaussian_log_density(x: np.ndarray, groups: np.ndarray, means: np.ndarray,
                                 covariances: np.ndarray) -> np.ndarray:
    """log N(x_t | μ_{g_t,m}, Σ_{g_t,m}) for every point and every component of its group.

    Shapes: x (n, d); groups (n,) int; means (G, K, d); covariances (G, K, d, d). Returns (n, K).
    Uses the inverse Cholesky factor, so the quadratic form is a triangular product.
    """
    chol = np.linalg.cholesky(covariances)
    d = x.shape[1]
    inv_chol = np.linalg.inv(chol)
    log_det = 2.0 * np.log(np.diagonal(chol, axis1=-2, axis2=-1)).sum(-1)
    constant = -0.5 * (log_det + d * np.log(2.0 * np.pi))
    return _grouped_gaussian(np.ascontiguousarray(x, dtype=np.float64),
                             np.ascontiguousarray(groups, dtype=np.int64), np.ascontiguousarray(means),
                             np.ascontiguousarray(inv_chol), constant)


# ----------------------------------------------------------------------------- CRT (Antoniak)

_GOLDEN = np.uint64(0x9E3779B97F4A7C15)
_MIX1 = np.uint64(0xBF58476D1CE4E5B9)
_MIX2 = np.uint64(0x94D049BB133111EB)


@njit(cache=True, inline="always")
def _splitmix(x: np.uint64) -> np.uint64:
    z = x + _GOLDEN
    z = (z ^ (z >> np.uint64(30))) * _MIX1
    z = (z ^ (z >> np.uint64(27))) * _MIX2
    return z ^ (z >> np.uint64(31))


@njit(cache=True, inline="always")
def _uniform(seed: np.uint64, j: np.uint64, i: np.uint64) -> float:
    h = _splitmix(seed ^ _splitmix(j * _GOLDEN + i))
    return (h >> np.uint64(11)) * (1.0 / 9007199254740992.0)


_XORSHIFT_MULT = np.uint64(0x2545F4914F6CDD1D)


@njit(cache=True, inline="always")
def _stream_start(seed: np.uint64, j: np.uint64) -> np.uint64:
    """Start of the random stream of entry ``j``: a counter-based seed, never zero."""
    return _splitmix(seed ^ _splitmix(j)) | np.uint64(1)


@njit(cache=True, inline="always")
def _stream_next(state: np.uint64) -> tuple[np.uint64, float]:
    """xorshift64* step: the next state and a uniform in [0, 1)."""
    state ^= state >> np.uint64(12)
    state ^= state << np.uint64(25)
    state ^= state >> np.uint64(27)
    return state, ((state * _XORSHIFT_MULT) >> np.uint64(11)) * (1.0 / 9007199254740992.0)


@njit(cache=True, inline="always")
def _digamma_large(x: float) -> float:
    # asymptotic series, accurate to ~1e-12 for x >= 6
    inv = 1.0 / x
    inv2 = inv * inv
    return (np.log(x) - 0.5 * inv
            - inv2 * (1.0 / 12 - inv2 * (1.0 / 120 - inv2 * (1.0 / 252 - inv2 * (1.0 / 240 - inv2 / 132)))))


@njit(cache=True, inline="always")
def _trigamma_large(x: float) -> float:
    inv = 1.0 / x
    inv2 = inv * inv
    return inv + 0.5 * inv2 + inv * inv2 * (1.0 / 6 - inv2 * (1.0 / 30 - inv2 * (1.0 / 42 - inv2 / 30)))


@njit(cache=True)
def _crt_tail(n: int, a: float, head: int, u1: float, u2: float) -> int:
    """Tables opened by customers head..n-1, a sum of independent Bernoulli(a/(a+i)).

    Exact mean and variance from the digamma/trigamma series; the draw is a rounded normal when
    the variance is large (>= 25), otherwise the rarer outcome (tables or non-tables) is drawn from
    the binomial with the same mean and variance (a Poisson when they coincide).
    """
    terms = n - head
    mean = a * (_digamma_large(a + n) - _digamma_large(a + head))
    var = mean - a * a * (_trigamma_large(a + head) - _trigamma_large(a + n))
    if var < 0.0:
        var = 0.0
    if mean > terms:
        mean = float(terms)
    rare_is_table = mean <= terms - mean
    rare_mean = mean if rare_is_table else terms - mean
    if var >= 25.0 or rare_mean > 50.0:
        z = np.sqrt(-2.0 * np.log(1.0 - u1)) * np.cos(2.0 * np.pi * u2)
        extra = np.floor(mean + np.sqrt(var) * z + 0.5)
        if extra < 0.0:
            extra = 0.0
        if extra > terms:
            extra = float(terms)
        return int(extra)
    if rare_mean <= 0.0:
        rare = 0
    else:
        p = 1.0 - var / rare_mean
        rare = 0
        if p < 1e-6:  # Poisson(rare_mean)
            pmf = np.exp(-rare_mean)
            cdf = pmf
            while u1 > cdf and rare < terms:
                rare += 1
                pmf *= rare_mean / rare
                cdf += pmf
        else:
            if p > 0.999:
                p = 0.999
            trials = max(int(np.floor(rare_mean / p + 0.5)), 1)
            p = min(rare_mean / trials, 1.0)
            if p >= 1.0:
                rare = trials
            else:
                pmf = (1.0 - p) ** trials
                cdf = pmf
                ratio = p / (1.0 - p)
                while u1 > cdf and rare < trials:
                    pmf *= (trials - rare) / (rare + 1.0) * ratio
                    rare += 1
                    cdf += pmf
        if rare > terms:
            rare = terms
    return rare if rare_is_table else terms - rare


@njit(parallel=True, cache=True)
def _crt_kernel(counts: np.ndarray, conc: np.ndarray, seed: np.uint64, exact_max: int,
                head: int) -> np.ndarray:
    out = np.zeros(counts.size, dtype=np.int64)
    for j in prange(counts.size):
        n = counts[j]
        a = conc[j]
        if n <= 0 or a <= 0.0:
            continue
        m = 1
        limit = n if n <= exact_max else head
        state = _stream_start(seed, np.uint64(j))
        for i in range(1, limit):
            state, u = _stream_next(state)
            if u * (a + i) < a:
                m += 1
        if n > exact_max:
            state, u1 = _stream_next(state)
            state, u2 = _stream_next(state)
            m += _crt_tail(n, a, head, u1, u2)
        out[j] = m
    return out


def sample_crt(
    counts: np.ndarray, concentration: np.ndarray, rng: np.random.Generator,
    exact_max: int = 40, head: int = 8,
) -> np.ndarray:
    """Number of tables m ~ CRT(n, a) for each entry (Chinese restaurant table distribution).

    m = Σ_{i=0}^{n-1} Bernoulli(a / (a + i)). For n ≤ ``exact_max`` the sum is drawn exactly; for
    larger n the first ``head`` terms are drawn exactly and the remaining ones by a normal with the
    exact mean a(ψ(a+n) − ψ(a+head)) and variance (mean − a²(ψ′(a+head) − ψ′(a+n))), rounded and
    clipped to its range. With ``head >= 6`` the digamma series used is accurate to 1e-12.

    Parameters
    ----------
    counts: integer array n ≥ 0, any shape.
    concentration: array a ≥ 0 broadcastable to ``counts``; a = 0 or n = 0 gives m = 0.

    Returns
    -------
    int64 array of the shape of ``counts``.
    """
    if head < 6 or exact_max < head:
        raise ValueError("sample_crt needs head >= 6 and exact_max >= head")
    counts = np.asarray(counts)
    conc = np.broadcast_to(np.asarray(concentration, dtype=np.float64), counts.shape)
    flat_n = np.ascontiguousarray(counts, dtype=np.int64).ravel()
    flat_a = np.ascontiguousarray(conc, dtype=np.float64).ravel()
    seed = np.uint64(rng.integers(0, 2**63 - 1, dtype=np.int64))
    return _crt_kernel(flat_n, flat_a, seed, int(exact_max), int(head)).reshape(counts.shape)


# ----------------------------------------------------------------------------- categorical


@njit(cache=True)
def _draw_log(log_p: np.ndarray, u: float) -> int:
    """Index drawn from unnormalised log-probabilities ``log_p`` (1-D) with the uniform ``u``;
    overwrites ``log_p`` with the shifted weights."""
    width = log_p.size
    top = -np.inf
    for j in range(width):
        if log_p[j] > top:
            top = log_p[j]
    total = 0.0
    for j in range(width):
        log_p[j] = np.exp(log_p[j] - top)
        total += log_p[j]
    target = u * total
    acc = 0.0
    for j in range(width):
        acc += log_p[j]
        if acc > target:
            return j
    return width - 1


@njit(parallel=True, cache=True)
def _categorical_rows(log_p: np.ndarray, u: np.ndarray) -> np.ndarray:
    n = log_p.shape[0]
    out = np.empty(n, dtype=np.int64)
    for t in prange(n):
        out[t] = _draw_log(log_p[t].copy(), u[t])
    return out


def sample_categorical_log(log_p: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """One draw per row from unnormalised log-probabilities ``log_p`` of shape (n, J).

    Subtracts the row maximum before exponentiating, so gaps of thousands of nats are safe. Rows
    must hold at least one finite entry. Returns int64 indices of shape (n,).
    """
    u = rng.random(log_p.shape[0])
    return _categorical_rows(np.ascontiguousarray(log_p, dtype=np.float64), u)


@njit(parallel=True, cache=True)
def _joint_assignment(log_g: np.ndarray, log_pi: np.ndarray, pi_scaled: np.ndarray, pi_row_max: np.ndarray,
                      homes: np.ndarray, concept_ll: np.ndarray, region_ll: np.ndarray, u_concept: np.ndarray,
                      u_region: np.ndarray) -> np.ndarray:
    n = homes.size
    n_concepts = log_pi.shape[1]
    n_regions = log_pi.shape[2]
    out = np.empty(n, dtype=np.int64)
    for t in prange(n):
        e = homes[t]
        r_max = -np.inf
        for m in range(n_regions):
            if region_ll[t, m] > r_max:
                r_max = region_ll[t, m]
        r = np.empty(n_regions)
        for m in range(n_regions):
            r[m] = np.exp(region_ll[t, m] - r_max)
        # marginal of C: log G + loglik + log Σ_m π_{c,m} N(x | m), Σ_m by a dot product when safe
        log_c = np.empty(n_concepts)
        for c in range(n_concepts):
            total = 0.0
            for m in range(n_regions):
                total += pi_scaled[e, c, m] * r[m]
            if total > 1e-250:
                log_sum = np.log(total)
            else:  # too small for the dot product: exact log-sum-exp
                inner_top = -np.inf
                for m in range(n_regions):
                    v = log_pi[e, c, m] - pi_row_max[e, c] + region_ll[t, m] - r_max
                    if v > inner_top:
                        inner_top = v
                acc = 0.0
                for m in range(n_regions):
                    acc += np.exp(log_pi[e, c, m] - pi_row_max[e, c] + region_ll[t, m] - r_max - inner_top)
                log_sum = inner_top + np.log(acc)
            log_c[c] = log_g[e, c] + concept_ll[t, c] + pi_row_max[e, c] + log_sum
        chosen = _draw_log(log_c, u_concept[t])
        # R | C
        for m in range(n_regions):
            r[m] = log_pi[e, chosen, m] + region_ll[t, m]
        out[t] = chosen * n_regions + _draw_log(r, u_region[t])
    return out


def sample_joint_assignment(log_g: np.ndarray, log_pi: np.ndarray, homes: np.ndarray,
                            concept_ll: np.ndarray, region_ll: np.ndarray,
                            rng: np.random.Generator) -> np.ndarray:
    """Flat index C·K + R of one draw per sample from
    p(C=l, R=m) ∝ exp(log_g[e,l] + log_pi[e,l,m] + concept_ll[t,l] + region_ll[t,m]), e = homes[t].

    Shapes: log_g (E, L), log_pi (E, L, K), homes (N,), concept_ll (N, L), region_ll (N, K).
    Drawn as C from its marginal (Σ over regions), then R | C, row by row without materialising
    the (N, L, K) table; the sum over regions is a dot product of exp-scaled factors, with an
    exact log-sum-exp wherever that product would underflow.
    """
    u = rng.random((2, homes.shape[0]))
    log_pi = np.ascontiguousarray(log_pi, dtype=np.float64)
    pi_row_max = log_pi.max(axis=2)
    pi_scaled = np.exp(log_pi - pi_row_max[:, :, None])
    return _joint_assignment(np.ascontiguousarray(log_g, dtype=np.float64), log_pi, pi_scaled, pi_row_max,
                             np.ascontiguousarray(homes, dtype=np.int64),
                             np.ascontiguousarray(concept_ll, dtype=np.float64),
                             np.ascontiguousarray(region_ll, dtype=np.float64), u[0], u[1])


# ----------------------------------------------------------------------------- sparse helpers


@njit(parallel=True, cache=True)
def _grouped_sparse_dot(indptr: np.ndarray, indices: np.ndarray, data: np.ndarray, groups: np.ndarray,
                        table: np.ndarray) -> np.ndarray:
    n = indptr.size - 1
    width = table.shape[2]
    out = np.zeros((n, width))
    for t in prange(n):
        g = groups[t]
        for p in range(indptr[t], indptr[t + 1]):
            k = indices[p]
            v = data[p]
            for c in range(width):
                out[t, c] += v * table[g, k, c]
    return out


def grouped_sparse_dot(matrix, groups: np.ndarray, table: np.ndarray) -> np.ndarray:
    """Row t of a CSR ``matrix`` (n, D) times ``table[groups[t]]`` (D, W), for every row.

    ``table`` has shape (G, D, W) (C-contiguous, float64). Returns (n, W). This is the visual and
    word log-likelihood of every sample under every concept of its own home: counts · log θᵀ.
    """
    return _grouped_sparse_dot(_as(matrix.indptr, np.int64), _as(matrix.indices, np.int64),
                               _as(matrix.data, np.float64), _as(groups, np.int64),
                               np.ascontiguousarray(table, dtype=np.float64))


def _as(array: np.ndarray, dtype: type) -> np.ndarray:
    """``array`` as a contiguous array of ``dtype``, without a copy when it already is one."""
    return np.ascontiguousarray(array, dtype=dtype)


@njit(cache=True)
def _grouped_row_sums(indptr: np.ndarray, indices: np.ndarray, data: np.ndarray, groups: np.ndarray,
                      out: np.ndarray) -> None:
    for t in range(indptr.size - 1):
        g = groups[t]
        for p in range(indptr[t], indptr[t + 1]):
            out[g, indices[p]] += np.int64(data[p])


def grouped_row_sums(matrix, groups: np.ndarray, n_groups: int) -> np.ndarray:
    """Sum of the rows of a CSR ``matrix`` (n, D) within each group: returns (n_groups, D) int64.

    Used for the count statistics n^v_{e,l,·} and n^w_{e,l,·} (group = e·L + l).
    """
    out = np.zeros((n_groups, matrix.shape[1]), dtype=np.int64)
    _grouped_row_sums(_as(matrix.indptr, np.int64), _as(matrix.indices, np.int64),
                      np.ascontiguousarray(matrix.data), _as(groups, np.int64), out)
    return out
