"""Prediction in a learnt home: place names from observations (p(name | pose, view)).

Everything here is a pure function of a :class:`~spco.model.parameters.ConceptParameters` sample,
a home index ``e`` and the corpus :class:`~spco.data.language.Vocabulary` (column ``k`` of the word
distributions is ``vocabulary.words[k]``). Shapes: ``n`` observations, ``L`` concepts, ``K``
regions, ``V`` words, ``D`` visual features.

Names (Hagiwara et al. 2021, "Prediction in home e" of ``docs/model.md``)::

    p(w | x, v) ∝ Σ_l Σ_m θ^w_{e,l,w} · p(v | θ^v_{e,l}) · G_{e,l} · N(x | μ_{e,m}, Σ_{e,m}) · π_{e,l,m}
    predicted name = argmax_w p(w | x, v) · I(w)

where ``I(w)`` is the mutual information between the indicator "word = w" and the concept under
``(G_e, θ^w_e)`` (:func:`mutual_information_weights`). The authors' published code instead weights
each concept's word probability by a per-concept KL score (``weighting="reference"``,
:func:`kl_scores_reference`).

Positions from place names: :mod:`spco.model.position_prediction`.

Input: every function validates its input the same way, and so does the CLI, which calls them:
poses are ``(x, y, sin θ, cos θ)`` rows with sin² + cos² = 1 (:func:`validate_poses`); visual
features are counts, whole numbers ≥ 0, sparse or dense (:func:`validate_visual_counts`; real
CNN features must first be turned into counts with a visual scale,
:func:`spco.data.plain.features_to_counts`); the home index is 0 … E − 1.

Numerics: all likelihoods are combined in log space. The visual term ``v · log θ^vᵀ`` is one
(sparse) matrix product; with ~7,000 counts its gaps between concepts are thousands of nats, so the
concept posterior is normalised with ``logsumexp``. Logarithms of probabilities are floored at
``log(tiny)`` (≈ −708) instead of −∞, so a zero entry of θ, π or G makes a term negligible but never
produces NaN; a near-singular covariance is repaired (eigenvalues clamped) before its Cholesky
factor is taken.

Confidence: those thousands of nats make p(w | x, v) sure of every answer, the wrong ones too (the
counts of one image are not independent draws). ``view_counts`` weights each view's visual term as
that many draws; ``spco.knowledge.what`` and ``ask`` answer with :func:`predict_names` on
``spco.knowledge.answer_parameters`` (free concepts' names at their posterior mean) with a view =
the model's view weight w draws (``TransferHyperparameters.view_counts``, the one the model learnt
with) and an ``unsure`` flag (:func:`spco.model.confidence.answer_names`, which the experiments call
too). ``view_counts=None`` (the default here) is the multinomial.
"""

from __future__ import annotations

import difflib
from dataclasses import dataclass
from typing import Literal

import numpy as np
import scipy.sparse as sp
from scipy.special import logsumexp

from spco.data.language import Vocabulary, normalize_name
from spco.errors import ConfigurationError, SpcoError
from spco.model.hyperparameters import NAME_PRIORS, NamePrior, view_powers
from spco.model.name_evidence import within_concepts
from spco.model.parameters import ConceptParameters
from spco.model.pruning import bernoulli_kl_scores, word_concept_mutual_information

__all__ = [
    "NamePrediction",
    "UnknownNameError",
    "concept_posterior",
    "gaussian_log_density",
    "kl_scores_reference",
    "listener_weights",
    "looks_kernel",
    "mutual_information_weights",
    "predict_names",
    "reference_kl_weights",
    "validate_poses",
    "validate_visual_counts",
    "word_posterior",
]

Weighting = Literal["mi", "none", "reference", "listener", "looks"]

_TINY = np.finfo(np.float64).tiny
_LOG_FLOOR = float(np.log(_TINY))  # ≈ -708.4: the log of "zero", finite on purpose
_LOG_2PI = float(np.log(2.0 * np.pi))

#: Tolerance on sin² θ + cos² θ = 1 for the pose columns 3–4.
_UNIT_TOLERANCE = 1e-3


class UnknownNameError(SpcoError, LookupError):
    """A place name that the model cannot use: never taught, or pruned as uninformative.

    Attributes
    ----------
    name: the name as given.
    suggestions: close matches among the known names (possibly empty).
    """

    def __init__(self, name: str, known: list[str], reason: str | None = None) -> None:
        self.name = name
        normalised = normalize_name(name)
        self.suggestions = difflib.get_close_matches(normalised, known, n=3, cutoff=0.6)
        parts = [reason or f"unknown place name {name!r}: it was never taught in any home"]
        if self.suggestions:
            parts.append("did you mean " + " or ".join(repr(s) for s in self.suggestions) + "?")
        if known:
            shown = ", ".join(known[:10]) + (", …" if len(known) > 10 else "")
            parts.append(f"known names: {shown}")
        else:
            parts.append("the model knows no names (nothing was taught)")
        super().__init__("; ".join(parts))


# ---------------------------------------------------------------------------------- dataclasses
@dataclass(frozen=True, eq=False)
class NamePrediction:
    """Names predicted for ``n`` observations.

    Attributes
    ----------
    words: (n, k) str, the ``k`` best words of each observation, best first.
    indices: (n, k) int, their vocabulary columns.
    scores: (n, k) the ranking scores (``p(w|x,v)·I(w)`` for ``"mi"``, ``p(w|x,v)`` for ``"none"``,
        the authors' KL-weighted score for ``"reference"``); not normalised.
    probabilities: (n, k) ``p(w | x, v)`` of those words (normalised over the vocabulary).
    word_probabilities: (n, V) the full ``p(w | x, v)``.
    weighting: the weighting used.
    unsure_below: the threshold of :attr:`unsure` (``None``: no answer is flagged).
    """

    words: np.ndarray
    indices: np.ndarray
    scores: np.ndarray
    probabilities: np.ndarray
    word_probabilities: np.ndarray
    weighting: str
    unsure_below: float | None = None

    @property
    def confidence(self) -> np.ndarray:
        """(n,) the probability ``p(w | x, v)`` of each observation's answer (its best-ranked
        word); 0 where the model knows no words."""
        if self.words.shape[1] == 0:
            return np.zeros(self.words.shape[0])
        return np.asarray(self.probabilities[:, 0], dtype=np.float64)

    @property
    def unsure(self) -> np.ndarray:
        """(n,) bool: the answer's probability is below :attr:`unsure_below` (all False if that is
        ``None``). See :mod:`spco.model.confidence`."""
        if self.unsure_below is None:
            return np.zeros(self.words.shape[0], dtype=bool)
        return self.confidence < self.unsure_below

    @property
    def best(self) -> list[str | None]:
        """The predicted name of each observation (``None`` if the model knows no words)."""
        if self.words.shape[1] == 0:
            return [None] * self.words.shape[0]
        return [str(w) for w in self.words[:, 0]]

    def __len__(self) -> int:
        return int(self.words.shape[0])


# ---------------------------------------------------------------------------------- helpers
def _safe_log(a: np.ndarray) -> np.ndarray:
    """log(a) with entries ≤ 0 (and underflows) mapped to the finite floor ``log(tiny)``."""
    a = np.asarray(a, dtype=np.float64)
    return np.log(np.maximum(a, _TINY))


def _check_home(params: ConceptParameters, e: int) -> int:
    n_env = params.n_environments
    if isinstance(e, bool) or not isinstance(e, int | np.integer) or not 0 <= int(e) < n_env:
        raise ConfigurationError(f"home index {e!r} is out of range: the model holds {n_env} homes, "
                                 f"indices 0 to {n_env - 1}")
    return int(e)


def _check_vocabulary(params: ConceptParameters, vocabulary: Vocabulary) -> None:
    n_words = params.word_probabilities.shape[-1]
    if len(vocabulary) != n_words:
        raise ConfigurationError(f"the vocabulary has {len(vocabulary)} words but the model was "
                                 f"learnt with {n_words}; use the corpus vocabulary of the model")


def _cholesky(covariances: np.ndarray) -> np.ndarray:
    """Lower Cholesky factors of a stack ``(K, d, d)`` of covariances, repairing bad ones.

    A covariance that is not numerically positive definite (near-singular, slightly asymmetric) has
    its eigenvalues clamped at ``1e-10 × (largest eigenvalue)`` (at least ``1e-12``) first.
    """
    cov = np.asarray(covariances, dtype=np.float64)
    if not np.isfinite(cov).all():
        raise ConfigurationError("a region covariance holds NaN or inf; the model parameters are corrupt")
    cov = 0.5 * (cov + np.swapaxes(cov, -1, -2))
    try:
        chol = np.linalg.cholesky(cov)
        diag = np.diagonal(chol, axis1=-2, axis2=-1)
        if np.isfinite(chol).all() and (diag > 1e-150).all():
            return chol
    except np.linalg.LinAlgError:
        pass
    eigval, eigvec = np.linalg.eigh(cov)
    top = np.maximum(np.abs(eigval).max(axis=-1, keepdims=True), 1e-12)
    floor = np.maximum(1e-10 * top, 1e-12)
    bad = (eigval < floor).any(axis=-1)
    clamped = np.maximum(eigval, floor)
    repaired = (eigvec * clamped[..., None, :]) @ np.swapaxes(eigvec, -1, -2)
    repaired = 0.5 * (repaired + np.swapaxes(repaired, -1, -2))
    cov = np.where(bad[..., None, None], repaired, cov)
    jitter = np.zeros_like(top)
    for _ in range(8):  # at most a few tries; each adds a little more to the diagonal
        try:
            return np.linalg.cholesky(cov + jitter[..., None] * np.eye(cov.shape[-1]))
        except np.linalg.LinAlgError:
            jitter = np.where(jitter == 0, floor, jitter * 100.0)
    raise ConfigurationError("a region covariance could not be made positive definite")


def gaussian_log_density(points: np.ndarray, means: np.ndarray, covariances: np.ndarray) -> np.ndarray:
    """log N(x_i | μ_m, Σ_m) for every point and component.

    Parameters
    ----------
    points: (n, d)
    means: (K, d)
    covariances: (K, d, d)

    Returns
    -------
    (n, K) float64, finite (near-singular covariances are repaired, see :func:`_cholesky`).
    """
    x = np.asarray(points, dtype=np.float64)
    mu = np.asarray(means, dtype=np.float64)
    chol = _cholesky(covariances)
    d = mu.shape[-1]
    inv_chol = np.linalg.inv(chol)  # (K, d, d), lower triangular
    diff = x[:, None, :] - mu[None, :, :]  # (n, K, d)
    z = np.einsum("kij,nkj->nki", inv_chol, diff)
    maha = np.einsum("nki,nki->nk", z, z)
    log_det = 2.0 * np.log(np.diagonal(chol, axis1=-2, axis2=-1)).sum(axis=-1)  # (K,)
    return -0.5 * (maha + log_det[None, :] + d * _LOG_2PI)


def validate_visual_counts(visual: object, n_features: int | None = None) -> sp.csr_array:
    """Visual features of ``n`` views as an (n, D) float64 CSR array of counts, or an error.

    ``visual``: SciPy sparse or dense (n, D), or a (D,) vector for one view. The values must be
    finite whole numbers ≥ 0 (the model's visual likelihood is a multinomial over counts); real
    CNN features are refused with a hint to convert them with a visual scale. ``n_features``:
    the model's D, checked if given. Raises :class:`~spco.errors.ConfigurationError`.
    """
    if sp.issparse(visual):
        counts = sp.csr_array(visual)
        values = counts.data
    else:
        dense = np.asarray(visual)
        if dense.dtype == object or not (np.issubdtype(dense.dtype, np.number)
                                         or dense.dtype == np.bool_):
            raise ConfigurationError(f"visual features must be numbers, got an array of {dense.dtype}")
        if dense.ndim == 1:
            dense = dense[None, :]
        if dense.ndim != 2:
            raise ConfigurationError(f"visual features must have shape (n, D), got {dense.shape}")
        counts = sp.csr_array(dense)
        values = dense
    if n_features is not None and counts.shape[1] != n_features:
        raise ConfigurationError(f"visual features have {counts.shape[1]} dimensions, the model "
                                 f"{n_features}")
    values = np.asarray(values, dtype=np.float64)
    if not np.isfinite(values).all():
        raise ConfigurationError("visual features hold NaN or inf")
    if (values < 0).any() or (values != np.floor(values)).any():
        raise ConfigurationError("visual features must be counts, whole numbers >= 0; for real-valued CNN "
                                 "features convert them first: counts = floor(max(f, 0) × scale) "
                                 "(spco.data.plain.features_to_counts, or a visual scale on the CLI)")
    return sp.csr_array(counts, dtype=np.float64)


def validate_poses(positions: object) -> np.ndarray:
    """Poses as an (n, 4) float64 array ``(x, y, sin θ, cos θ)``, or an error.

    A (4,) vector is one pose. Columns 3–4 must be sin θ and cos θ (sin² + cos² = 1 within 1e-3):
    a pose given as (x, y, θ, …) is refused. Raises :class:`~spco.errors.ConfigurationError`.
    """
    try:
        x = np.asarray(positions, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise ConfigurationError(f"positions must be numbers: {exc}") from None
    if x.ndim == 1:
        x = x[None, :]
    if x.ndim != 2 or x.shape[1] != 4:
        raise ConfigurationError(f"positions must have shape (n, 4) (x, y, sin θ, cos θ), got {x.shape}")
    if not np.isfinite(x).all():
        raise ConfigurationError("positions hold NaN or inf")
    norm = x[:, 2] ** 2 + x[:, 3] ** 2
    bad = np.flatnonzero(np.abs(norm - 1.0) > _UNIT_TOLERANCE)
    if bad.size:
        i = int(bad[0])
        raise ConfigurationError(f"positions: columns 3–4 must be sin θ and cos θ (sin² + cos² = 1), but row "
                                 f"{i} has sin² + cos² = {norm[i]:.6g} ({bad.size} such rows); give poses "
                                 "as (x, y, sin θ, cos θ)")
    return x


def _visual_log_likelihood(theta_v: np.ndarray, visual: object, view_counts: float | None = None
                           ) -> np.ndarray:
    """(n, L) ``v · log θ^vᵀ`` for counts ``visual`` (n, D), sparse or dense (validated).

    ``view_counts``: the evidence of one view, in counts: a view with more counts is weighted by
    ``view_counts / Σ_d v_d`` (its proportions scored as that many draws, as the exact sampler
    does, :attr:`~spco.model.hyperparameters.TransferHyperparameters.view_counts`); ``None``:
    every count is a draw (the model's multinomial)."""
    log_theta = _safe_log(theta_v)  # (L, D), finite
    counts = validate_visual_counts(visual, log_theta.shape[1])
    loglik = np.asarray(counts @ log_theta.T)
    if view_counts is None:
        return loglik
    if not view_counts > 0:
        raise ConfigurationError(f"view_counts must be > 0, got {view_counts!r}")
    totals = np.asarray(counts.sum(axis=1), dtype=np.float64).ravel()
    return loglik * view_powers(totals, float(view_counts))[:, None]


def _as_positions(positions: object) -> np.ndarray:
    return validate_poses(positions)


def _n_rows(positions: object, visual: object) -> int:
    if positions is not None:
        return _as_positions(positions).shape[0]
    if visual is not None:
        return validate_visual_counts(visual).shape[0]
    raise ConfigurationError("give positions, visual features or both")


def _log_concept_posterior(
    params: ConceptParameters,
    e: int,
    positions: np.ndarray | None,
    visual: object,
    use_position: bool,
    use_vision: bool,
    active_regions_only: bool,
    view_counts: float | None = None,
) -> np.ndarray:
    """(n, L) normalised log P(l | x, v)."""
    e = _check_home(params, e)
    if use_position or use_vision:
        n = _n_rows(positions if use_position else None, visual if use_vision else None)
    else:  # neither modality: the prior G_e, one row per observation
        n = _n_rows(positions, visual)
    log_post = np.broadcast_to(_safe_log(params.concept_weights[e])[None, :],
                               (n, params.n_concepts)).copy()
    if use_vision:
        if visual is None:
            raise ConfigurationError("use_vision=True needs visual features")
        vis = _visual_log_likelihood(params.visual_probabilities[e], visual, view_counts)
        if vis.shape[0] != n:
            raise ConfigurationError(f"{n} positions but {vis.shape[0]} visual feature rows")
        log_post += vis
    if use_position:
        if positions is None:
            raise ConfigurationError("use_position=True needs positions")
        x = _as_positions(positions)
        with np.errstate(over="ignore", invalid="ignore"):  # far positions: checked below
            log_n = gaussian_log_density(x, params.region_means[e], params.region_covariances[e])  # (n, K)
        if active_regions_only:
            active = np.asarray(params.region_counts[e]) > 0
            if active.any():
                log_n = np.where(active[None, :], log_n, -np.inf)
        log_pi = _safe_log(params.region_weights[e])  # (L, K)
        with np.errstate(invalid="ignore"):
            log_post += logsumexp(log_pi[None, :, :] + log_n[:, None, :], axis=2)
    undefined = np.isnan(log_post).any(axis=1) | ~np.isfinite(log_post).any(axis=1)
    if undefined.any():  # e.g. a position ~1e308 m away: every density is 0 (or inf - inf) in float64
        i = int(np.flatnonzero(undefined)[0])
        where = f" at {tuple(float(v) for v in x[i, :2])}" if use_position else ""
        raise ConfigurationError(f"observation {i}{where}: every concept's likelihood is 0 in floating "
                                 f"point, so p(concept | observation) is undefined; is the position on "
                                 f"the home's map, in metres?")
    return log_post - logsumexp(log_post, axis=1, keepdims=True)


# ---------------------------------------------------------------------------------- names
def concept_posterior(
    params: ConceptParameters,
    e: int,
    positions: np.ndarray | None,
    visual: object,
    use_position: bool = True,
    use_vision: bool = True,
    active_regions_only: bool = False,
    view_counts: float | None = None,
) -> np.ndarray:
    """P(l | x, v) ∝ G_{e,l} · p(v | θ^v_{e,l}) · Σ_m π_{e,l,m} N(x | μ_{e,m}, Σ_{e,m}).

    Parameters
    ----------
    params, e: the model and the home index.
    positions: (n, 4) poses ``(x, y, sin θ, cos θ)`` in metres (may be ``None`` without position).
    visual: (n, D) visual counts, SciPy sparse or dense (may be ``None`` without vision).
    use_position, use_vision: drop a modality from the likelihood.
    active_regions_only: sum only over regions with training samples (``region_counts > 0``), as
        the authors' code does; ignored if no region has any.
    view_counts: the evidence of one view in counts: each view's log-likelihood is weighted by
        ``min(1, view_counts / Σ_d v_d)``; ``None`` (default): every count a draw.

    Returns
    -------
    (n, L) float64, rows sum to 1, never NaN.
    """
    return np.exp(_log_concept_posterior(params, e, positions, visual, use_position, use_vision,
                                         active_regions_only, view_counts))


def _word_matrix(params: ConceptParameters, e: int) -> np.ndarray:
    """(L, V) θ^w_e with pruned words (word_mask False) set to 0."""
    theta = np.clip(np.asarray(params.word_probabilities[e], dtype=np.float64), 0.0, 1.0)
    return theta * np.asarray(params.word_mask, dtype=bool)[None, :]


def listener_weights(theta_w: np.ndarray, concept_weights: np.ndarray) -> np.ndarray:
    """(L, V) L(l | w) ∝ G_l θ^w_{l,w}: the concept a listener takes word w to mean (each column sums to
    1; a word no concept says: 0), in log space. ``theta_w`` (L, V) a home's θ^w, ``concept_weights``
    (L,) the concepts' prior G. The pragmatic speaker's weight of ``weighting="listener"``
    (:func:`predict_names`): S(w | x, v) ∝ Σ_l P(l | x, v) θ^w_{l,w} L(l | w)."""
    theta_w = np.asarray(theta_w, dtype=np.float64)
    with np.errstate(divide="ignore"):
        log_joint = np.log(np.clip(np.asarray(concept_weights, dtype=np.float64), 0.0, None))[:, None] \
            + np.log(np.clip(theta_w, 0.0, None))
    total = logsumexp(log_joint, axis=0, keepdims=True)
    out = np.zeros_like(theta_w)
    said = np.isfinite(total).ravel()
    out[:, said] = np.exp(log_joint[:, said] - total[:, said])
    return out


def looks_kernel(shared_visual: np.ndarray, view_counts: float | None) -> np.ndarray:
    """(L, L) s(l, l') = BC(φ^v_l, φ^v_l')^n: how alike two concepts look, the Bhattacharyya coefficient
    BC = Σ_d sqrt(φ^v_{l,d} φ^v_{l',d}) of their views' distributions (``shared_visual`` (L, D) φ^v,
    rows summing to 1) raised to n = ``view_counts``, the evidence of one view in counts (``None``: 1),
    so s is the coefficient of two views of n draws each (1 on the diagonal, in [0, 1] elsewhere,
    symmetric; the power taken in log space). The listener of ``weighting="looks"``
    (:func:`predict_names`) takes two concepts that look alike as one referent:
    S(w | x, v) ∝ Σ_l P(l | x, v) θ^w_{l,w} Σ_l' s(l, l') L(l' | w)."""
    phi = np.asarray(shared_visual, dtype=np.float64)
    if phi.ndim != 2:
        raise ConfigurationError(f"shared_visual must be (L, D), got shape {phi.shape}")
    n = 1.0 if view_counts is None else float(view_counts)
    if not (np.isfinite(n) and n > 0):
        raise ConfigurationError(f"view_counts must be a positive number or None, got {view_counts!r}")
    root = np.sqrt(np.clip(phi, 0.0, None))
    bc = root @ root.T  # (L, L): sums of products ≥ 0, no cancellation; O(L² D) time, O(L²) memory
    with np.errstate(divide="ignore"):
        log_bc = np.minimum(np.log(bc), 0.0)  # rounding: BC ≤ 1; a coefficient of 0 stays 0 (log −∞)
    np.fill_diagonal(log_bc, 0.0)
    return np.exp(n * log_bc)  # the power in log space: BC^n underflows to 0, never overflows


def _words_from_concepts(concepts: np.ndarray, theta_w: np.ndarray) -> np.ndarray:
    probs = concepts @ theta_w  # (n, V)
    total = probs.sum(axis=1, keepdims=True)
    return np.divide(probs, total, out=np.zeros_like(probs), where=total > 0)


def word_posterior(
    params: ConceptParameters,
    e: int,
    positions: np.ndarray | None,
    visual: object,
    use_position: bool = True,
    use_vision: bool = True,
    active_regions_only: bool = False,
    view_counts: float | None = None,
) -> np.ndarray:
    """p(w | x, v) ∝ Σ_l θ^w_{e,l,w} P(l | x, v) (= the double sum over l and m of the model).

    Arguments as :func:`concept_posterior`. Returns (n, V) float64; each row sums to 1 (a row is all
    zeros only if every word was pruned). Pruned words have probability 0.
    """
    e = _check_home(params, e)
    concepts = concept_posterior(params, e, positions, visual, use_position, use_vision,
                                 active_regions_only, view_counts)
    return _words_from_concepts(concepts, _word_matrix(params, e))


def mutual_information_weights(params: ConceptParameters, e: int) -> np.ndarray:
    """I(w): mutual information (nats) between the indicator "word = w" and the concept C.

    Under p(c) = G_{e,c} and p(word = w | c) = θ^w_{e,c,w}:
    ``I(w) = h(Σ_c G_c θ_{c,w}) − Σ_c G_c h(θ_{c,w})`` with h the binary entropy (0·log 0 = 0).
    Returns (V,) float64 ≥ 0; a word whose θ is the same in every concept, and a pruned word, get 0.
    """
    e = _check_home(params, e)
    return concept_information(params, e, _word_matrix(params, e))


def concept_information(params: ConceptParameters, e: int, words: np.ndarray) -> np.ndarray:
    """(V,) mutual information (nats) between the indicator "word = w" and the concept of home ``e``
    (p(c) = G_{e,c}, normalised; uniform if G_e is all zero) with p(word = w | c) = ``words[c, w]``
    ((L, V), in [0, 1]): :func:`mutual_information_weights` with θ^w, and
    :func:`spco.model.position_prediction.place_word_information` with the words as ``where`` reads
    them. A word whose column is the same in every concept, and a pruned word, get 0."""
    g = np.clip(np.asarray(params.concept_weights[e], dtype=np.float64), 0.0, None)
    g = g / g.sum() if g.sum() > 0 else np.full_like(g, 1.0 / g.size)
    info = word_concept_mutual_information(words, g)
    info[np.ptp(words, axis=0) == 0] = 0.0  # exactly uninformative: avoid round-off residue
    info[~np.asarray(params.word_mask, dtype=bool)] = 0.0
    return info


def reference_kl_weights(params: ConceptParameters, e: int) -> np.ndarray:
    """KL_l(w) = KL(Bern(θ^w_{e,l,w}) ‖ Bern(Σ_c G_{e,c} θ^w_{e,c,w})), as in the authors' code.

    Returns (L, V) float64, finite and ≥ 0 (logs floored at log(tiny)); 0 for pruned words.
    """
    e = _check_home(params, e)
    theta = _word_matrix(params, e)  # (L, V)
    g = np.clip(np.asarray(params.concept_weights[e], dtype=np.float64), 0.0, None)
    kl = bernoulli_kl_scores(theta, g)
    kl[:, ~np.asarray(params.word_mask, dtype=bool)] = 0.0
    return kl


def kl_scores_reference(
    params: ConceptParameters,
    e: int,
    positions: np.ndarray | None,
    visual: object,
    use_position: bool = True,
    use_vision: bool = True,
    view_counts: float | None = None,
) -> np.ndarray:
    """The authors' name score: score(w) = Σ_l P(l | x, v) θ^w_{e,l,w} KL_l(w).

    P(l | x, v) is :func:`concept_posterior` over the regions with training samples only, as in the
    authors' ``predict_name.py``; KL_l(w) is :func:`reference_kl_weights`. Returns (n, V), not
    normalised (the argmax is what matters).
    """
    e = _check_home(params, e)
    concepts = concept_posterior(params, e, positions, visual, use_position, use_vision,
                                 active_regions_only=True, view_counts=view_counts)
    return concepts @ (_word_matrix(params, e) * reference_kl_weights(params, e))


#: How many of each observation's best words :func:`_with_stand_ins` looks up.
STAND_IN_CANDIDATES = 3


def _with_stand_ins(scores: np.ndarray, probs: np.ndarray, params: ConceptParameters, vocabulary: Vocabulary,
                    mask: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``scores`` and ``probs`` (n, V) with the score and probability of each object among the best
    :data:`STAND_IN_CANDIDATES` words of an observation added to the place name that stands in for
    it (:func:`spco.model.unheard.stand_in_names`: "door" → "entrance"), the object's set to 0.
    Models with the word channels only (their switch prior says which words are objects)."""
    from spco.model.unheard import stand_in_names

    ranked = np.where(mask[None, :], scores, -np.inf)
    n_best = min(STAND_IN_CANDIDATES, int(mask.sum()))
    if n_best < 1 or not scores.size:
        return scores, probs
    best = np.argpartition(-ranked, n_best - 1, axis=1)[:, :n_best]
    stand_in = stand_in_names(vocabulary, mask, np.asarray(params.word_channel_prior)[:, 0], best)
    if not stand_in:
        return scores, probs
    scores, probs = scores.copy(), probs.copy()
    for k, j in stand_in.items():
        scores[:, j] += scores[:, k]
        probs[:, j] += probs[:, k]
        scores[:, k] = 0.0
        probs[:, k] = 0.0
    return scores, probs


def predict_names(
    params: ConceptParameters,
    e: int,
    vocabulary: Vocabulary,
    positions: np.ndarray | None,
    visual: object,
    top_k: int = 3,
    weighting: Weighting = "mi",
    use_position: bool = True,
    use_vision: bool = True,
    view_counts: float | None = None,
    name_prior: NamePrior = "off",
    unsure_below: float | None = None,
    concepts: np.ndarray | None = None,
) -> NamePrediction:
    """Rank the place names of ``n`` observations in home ``e``.

    Parameters
    ----------
    params, e, vocabulary: the model, the home and the corpus vocabulary (length V).
    positions: (n, 4) poses in metres; visual: (n, D) counts (sparse or dense).
    top_k: how many words to return per observation (fewer if fewer words survive pruning).
    weighting: ``"mi"`` — p(w|x,v)·I(w) (the paper); ``"none"`` — p(w|x,v); ``"listener"`` — the
        pragmatic speaker Σ_l P(l|x,v) θ^w_{e,l,w} L(l|w), L(l|w) ∝ G_0,l θ^w_{e,l,w}
        (:func:`listener_weights`: a name said here that mostly means another concept ranks lower);
        ``"looks"`` — the same speaker with a listener that takes concepts that look alike as one
        referent, Σ_l P(l|x,v) θ^w_{e,l,w} Σ_l' s(l, l') L(l'|w) (:func:`looks_kernel`, with
        ``view_counts``);
        ``"reference"`` — the authors' KL-weighted score (:func:`kl_scores_reference`), with the
        concept posterior over used regions only.
    use_position, use_vision: drop a modality.
    view_counts: the evidence of one view in counts (see :func:`concept_posterior`); pass the
        model's (``TransferHyperparameters.view_counts`` for the exact sampler) to predict as it
        learnt. ``None``: every count a draw.
    name_prior: ``"off"`` (default) or ``"wordnet"``: with ``"mi"``, the words of each concept
        compete by how name-like they are (``params.name_prior``, :mod:`spco.model.name_evidence`:
        sentence positions and WordNet) before the concepts are mixed; a model without a name
        prior (no naming rule) keeps the MI order. Opt-in: on the held-out speech set it lowered
        A_n (a weak name such as "dining" lost its concept to "kitchen"; docs/model.md).
    unsure_below: stored in the result: an answer whose probability is below it is
        :attr:`NamePrediction.unsure` (``None``: never); ``spco.knowledge.what`` passes
        :data:`spco.model.confidence.UNSURE_BELOW`.
    concepts: (n, L) P(l | observation) computed by the caller (the room-level answer,
        :func:`spco.model.rooms.concepts_by_room`) in place of :func:`concept_posterior`.

    Words with ``word_mask`` False are never returned. Ties in the score are broken by p(w|x,v),
    then by vocabulary order. A word with I(w) = 0 scores 0 and is ranked after every word with a
    positive score.
    """
    if top_k < 1:
        raise ConfigurationError(f"top_k must be >= 1, got {top_k}")
    if weighting not in ("mi", "none", "reference", "listener", "looks"):
        raise ConfigurationError(f"weighting must be 'mi', 'none', 'reference', 'listener' or 'looks', "
                                 f"got {weighting!r}")
    if name_prior not in NAME_PRIORS:
        raise ConfigurationError(f"name_prior must be one of {', '.join(map(repr, NAME_PRIORS))}, "
                                 f"got {name_prior!r}")
    e = _check_home(params, e)
    _check_vocabulary(params, vocabulary)
    if concepts is None:
        concepts = concept_posterior(params, e, positions, visual, use_position, use_vision,
                                     active_regions_only=weighting == "reference", view_counts=view_counts)
    else:
        concepts = np.asarray(concepts, dtype=np.float64)
        if concepts.ndim != 2 or concepts.shape[1] != params.n_concepts:
            raise ConfigurationError(f"concepts must be (n, {params.n_concepts}), got {concepts.shape}")
    theta_w = _word_matrix(params, e)
    probs = _words_from_concepts(concepts, theta_w)  # (n, V)
    if weighting == "mi" and name_prior == "wordnet" and params.name_prior is not None:
        # the words said at each place compete by how name-like they are (spco.model.name_evidence)
        named = within_concepts(theta_w * mutual_information_weights(params, e)[None, :], params.name_prior)
        scores = concepts @ named
    elif weighting == "mi":
        scores = probs * mutual_information_weights(params, e)[None, :]
    elif weighting == "none":
        scores = probs.copy()
    elif weighting == "listener":
        scores = concepts @ (theta_w * listener_weights(theta_w, params.global_concept_weights))
    elif weighting == "looks":
        kernel = looks_kernel(params.shared_visual_probabilities, view_counts)
        scores = concepts @ (theta_w * (kernel @ listener_weights(theta_w, params.global_concept_weights)))
    else:
        scores = concepts @ (theta_w * reference_kl_weights(params, e))
    mask = np.asarray(params.word_mask, dtype=bool)
    if (params.word_channel_prior is not None and weighting != "reference"
            and np.shape(params.word_channel_prior)[0] == scores.shape[1]):
        scores, probs = _with_stand_ins(scores, probs, params, vocabulary, mask)
    k = min(int(top_k), int(mask.sum()))
    ranked = np.where(mask[None, :], scores, -np.inf)
    tie = np.where(mask[None, :], probs, -np.inf)
    order = np.lexsort((-tie, -ranked), axis=-1)[:, :k]  # primary key last
    words = np.asarray(vocabulary.words, dtype=str)
    return NamePrediction(
        words=words[order],
        indices=order,
        scores=np.take_along_axis(scores, order, axis=1),
        probabilities=np.take_along_axis(probs, order, axis=1),
        word_probabilities=probs,
        weighting=weighting,
        unsure_below=unsure_below,
    )
