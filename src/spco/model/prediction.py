"""Prediction in a learnt home: place names from observations, positions from place names.

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

Positions::

    p(m | w) ∝ Σ_l π_{e,l,m} θ^w_{e,l,w} G_{e,l},   m̂ = argmax_m p(m | w),   x ~ N(μ_{e,m̂}, Σ_{e,m̂}).

The sum runs over the concepts that hold training samples of home e (``concept_counts`` ≥ 1): a
concept with no sample there has π drawn from its sparse prior, which says nothing about the
home's map. The share of Σ_l θ^w_{e,l,w} G_{e,l} that those concepts hold is the name's
``support`` in the home; below :data:`LEARNT_SUPPORT` the place is reported as not learnt in this
home (``PositionPrediction.learnt`` False): its name is explained mostly by concepts of other
homes, e.g. ``dining`` in a home without a dining room.

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
that many draws; ``spco.knowledge.what`` answers with :func:`spco.model.confidence.predict_names_honestly`
(a view = :data:`~spco.model.confidence.VIEW_EFFECTIVE_COUNTS` draws, free concepts' names at their
posterior mean, an ``unsure`` flag). ``view_counts=None`` (the default here) is the multinomial;
the exact model learns, and its experiments predict, with ``TransferHyperparameters.view_counts``.
"""

from __future__ import annotations

import difflib
from dataclasses import dataclass, replace
from typing import Literal

import numpy as np
import scipy.sparse as sp
from scipy.special import logsumexp

from spco.data.language import Vocabulary, normalize_name
from spco.errors import ConfigurationError, SpcoError
from spco.model.hyperparameters import NAME_PRIORS, NamePrior
from spco.model.name_evidence import within_concepts
from spco.model.parameters import ConceptParameters
from spco.model.pruning import bernoulli_kl_scores, word_concept_mutual_information
from spco.model.unheard import resolve_name

__all__ = [
    "LEARNT_SUPPORT",
    "NamePrediction",
    "PositionPrediction",
    "UnknownNameError",
    "concept_posterior",
    "draw_poses",
    "gaussian_log_density",
    "kl_scores_reference",
    "mutual_information_weights",
    "name_support",
    "predict_names",
    "predict_positions",
    "query_indices",
    "query_name",
    "reference_kl_weights",
    "region_posterior_for_name",
    "validate_poses",
    "validate_visual_counts",
    "word_posterior",
]

Weighting = Literal["mi", "none", "reference"]
PositionMode = Literal["argmax", "mixture"]

_TINY = np.finfo(np.float64).tiny
_LOG_FLOOR = float(np.log(_TINY))  # ≈ -708.4: the log of "zero", finite on purpose
_LOG_2PI = float(np.log(2.0 * np.pi))

#: A place name is *learnt* in a home when at least this share of its probability there comes
#: from concepts that hold samples of the home (see :func:`name_support`).
LEARNT_SUPPORT = 0.5
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


@dataclass(frozen=True, eq=False)
class PositionPrediction:
    """Positions predicted for one place name.

    Attributes
    ----------
    name: the normalised name (a vocabulary word).
    region: m̂ = argmax_m p(m | w).
    region_probabilities: (K,) p(m | w).
    samples: (n, 3) sampled poses ``(x, y, θ)``, metres and radians; ``θ = atan2(sin, cos)`` of
        the sampled 4-D vector, NaN when ``xy_only``. The same draws in the input convention
        ``(x, y, sin θ, cos θ)`` are :attr:`poses`.
    regions: (n,) int, the region each sample was drawn from.
    log_density: (n,) log-density of each raw draw (4-D, or x–y when ``xy_only``) under the
        whole mixture Σ_m p(m | w) N(· | μ_m, Σ_m).
    weights: (n,) that density normalised over the ``n`` samples (sums to 1).
    mode: ``"argmax"`` or ``"mixture"``.
    xy_only: whether only the x–y marginal was sampled.
    support: the share of the name's probability in the home that comes from concepts holding
        samples of the home (:func:`name_support`); 1.0 when the parameters carry no concept
        counts.
    learnt: ``support >= LEARNT_SUPPORT``; False means "no such place learnt in this home": the
        region and samples are then the best the model can say, but not knowledge of this home.
    asked: the name asked for when nobody said it and the lexicon found the known name ``name``
        for it (:func:`spco.model.unheard.resolve_name`: "restroom" asked, "toilet" used); else None.
    via: how the lexicon related them (``"synonym"``, ``"gloss"``, …), or None.
    """

    name: str
    region: int
    region_probabilities: np.ndarray
    samples: np.ndarray
    regions: np.ndarray
    log_density: np.ndarray
    weights: np.ndarray
    mode: str
    xy_only: bool
    support: float = 1.0
    learnt: bool = True
    asked: str | None = None
    via: str | None = None

    @property
    def xy(self) -> np.ndarray:
        """(n, 2) sampled x, y in metres."""
        return self.samples[:, :2]

    @property
    def poses(self) -> np.ndarray:
        """(n, 4) the samples as ``(x, y, sin θ, cos θ)``, the convention of the inputs (NaN
        columns 3–4 when ``xy_only``)."""
        theta = self.samples[:, 2]
        return np.column_stack([self.samples[:, :2], np.sin(theta), np.cos(theta)])


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
    return loglik * np.minimum(1.0, float(view_counts) / np.maximum(totals, 1.0))[:, None]


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
    theta = _word_matrix(params, e)  # (L, V)
    g = np.clip(np.asarray(params.concept_weights[e], dtype=np.float64), 0.0, None)
    g = g / g.sum() if g.sum() > 0 else np.full_like(g, 1.0 / g.size)
    info = word_concept_mutual_information(theta, g)
    info[np.ptp(theta, axis=0) == 0] = 0.0  # exactly uninformative: avoid round-off residue
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
) -> NamePrediction:
    """Rank the place names of ``n`` observations in home ``e``.

    Parameters
    ----------
    params, e, vocabulary: the model, the home and the corpus vocabulary (length V).
    positions: (n, 4) poses in metres; visual: (n, D) counts (sparse or dense).
    top_k: how many words to return per observation (fewer if fewer words survive pruning).
    weighting: ``"mi"`` — p(w|x,v)·I(w) (the paper); ``"none"`` — p(w|x,v);
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
        :attr:`NamePrediction.unsure` (``None``: never). ``spco.knowledge.what`` answers with
        :func:`spco.model.confidence.predict_names_honestly`.

    Words with ``word_mask`` False are never returned. Ties in the score are broken by p(w|x,v),
    then by vocabulary order. A word with I(w) = 0 scores 0 and is ranked after every word with a
    positive score.
    """
    if top_k < 1:
        raise ConfigurationError(f"top_k must be >= 1, got {top_k}")
    if weighting not in ("mi", "none", "reference"):
        raise ConfigurationError(f"weighting must be 'mi', 'none' or 'reference', got {weighting!r}")
    if name_prior not in NAME_PRIORS:
        raise ConfigurationError(f"name_prior must be one of {', '.join(map(repr, NAME_PRIORS))}, "
                                 f"got {name_prior!r}")
    e = _check_home(params, e)
    _check_vocabulary(params, vocabulary)
    concepts = concept_posterior(params, e, positions, visual, use_position, use_vision,
                                 active_regions_only=weighting == "reference", view_counts=view_counts)
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
    else:
        scores = concepts @ (theta_w * reference_kl_weights(params, e))
    mask = np.asarray(params.word_mask, dtype=bool)
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


# ---------------------------------------------------------------------------------- positions
def query_indices(params: ConceptParameters, vocabulary: Vocabulary, name: str) -> list[int]:
    """Columns of the usable tokens of a name asked for (see :func:`region_posterior_for_name`)."""
    _check_vocabulary(params, vocabulary)
    mask = np.asarray(params.word_mask, dtype=bool)
    known = [w for w, keep in zip(vocabulary.words, mask, strict=True) if keep]
    _, indices = vocabulary.query(name)
    usable = list(dict.fromkeys(k for k in indices if mask[k]))
    if usable:
        return usable
    if not indices:
        raise UnknownNameError(name, known)
    pruned = ", ".join(repr(vocabulary.words[k]) for k in dict.fromkeys(indices))
    raise UnknownNameError(name, known, reason=f"the word {pruned} was pruned as uninformative (it names "
                           "no place)" if len(set(indices)) == 1 else
                           f"the words {pruned} were pruned as uninformative (they name no place)")


def query_name(vocabulary: Vocabulary, params: ConceptParameters, name: str) -> str:
    """How a name asked for is understood: its usable tokens joined by ``" + "`` (``"living room"``,
    or ``"study + room"`` for a name never learnt as one term)."""
    return " + ".join(vocabulary.words[k] for k in query_indices(params, vocabulary, name))


def _occupied_concepts(params: ConceptParameters, e: int) -> np.ndarray:
    """(L,) bool: concepts holding training samples of home ``e`` (mean count ≥ 1); all True when
    the parameters carry no concept counts."""
    if params.concept_counts is None:
        return np.ones(params.n_concepts, dtype=bool)
    return np.asarray(params.concept_counts[e], dtype=np.float64) >= 1.0


def _name_concept_weights(params: ConceptParameters, e: int, words: list[int]) -> np.ndarray:
    """(L,) G_{e,l} Π_i θ^w_{e,l,w_i}: how much each concept of home e explains the words said together,
    scaled by the largest concept's Π_i θ (several small θ multiply); a concept in which a word has
    probability 0 keeps weight 0."""
    log_theta = _safe_log(_word_matrix(params, e)[:, words]).sum(axis=1)  # (L,)
    top = float(log_theta.max())
    theta_w = np.exp(log_theta - top) if top > _LOG_FLOOR else np.zeros_like(log_theta)
    g = np.clip(np.asarray(params.concept_weights[e], dtype=np.float64), 0.0, None)
    return g * theta_w


def concept_stand_ins(params: ConceptParameters, e: int) -> np.ndarray:
    """(L,) int: the concept of home ``e`` that stands in for each concept when a name is looked for.

    A concept holding samples of the home (``concept_counts`` ≥ 1) stands for itself. A concept with
    none has no place in this home (its π there is its prior), yet it may carry a name the other
    homes say at a place this home has under another concept: people call the bath "bath",
    "bathroom" or "shower", each household its own way, and the sampler learns one concept per name
    (a synonym's samples keep to the concept whose θ^w gives it the most). Such a concept is looked
    for where the home keeps the concept its views would be assigned to: the occupied concept l
    maximising Σ_d φ^v_{l',d} log θ^v_{e,l,d}, the log-likelihood per count of the concept's shared
    view profile φ^v_{l'} (a typical view of it). Views carry thousands of counts per sample, so that
    assignment is a hard choice and this one is too. Identity when no concept is occupied or the
    parameters carry no concept counts.
    """
    e = _check_home(params, e)
    n_concepts = params.n_concepts
    occupied = _occupied_concepts(params, e)
    stand_in = np.arange(n_concepts)
    if occupied.all() or not occupied.any():
        return stand_in
    phi_v = np.clip(np.asarray(params.shared_visual_probabilities, dtype=np.float64), 0.0, None)  # (L, D)
    log_theta_v = _safe_log(np.asarray(params.visual_probabilities[e], dtype=np.float64))  # (L, D)
    fit = phi_v[~occupied] @ log_theta_v[occupied].T  # (unoccupied, occupied)
    stand_in[~occupied] = np.flatnonzero(occupied)[np.argmax(fit, axis=1)]
    return stand_in


def name_support(params: ConceptParameters, e: int, vocabulary: Vocabulary, name: str) -> float:
    """Share of p(name | home e) = Σ_l G_{e,l} θ^w_{e,l,w} held by concepts with samples of home e.

    Near 1: the name belongs to places the home's samples were assigned to. Near 0: the name is
    explained by concepts that hold no sample of this home (their θ^w and π come from the prior,
    i.e. from the other homes): no such place was learnt in this home. Returns a float in [0, 1]
    (0 if the name has probability 0 in every concept).
    """
    e = _check_home(params, e)
    weights = _name_concept_weights(params, e, query_indices(params, vocabulary, name))
    total = weights.sum()
    return float(weights[_occupied_concepts(params, e)].sum() / total) if total > 0 else 0.0


def region_posterior_for_name(
    params: ConceptParameters, e: int, vocabulary: Vocabulary, name: str
) -> np.ndarray:
    """p(m | w) ∝ Σ_l π_{e,l,m} θ^w_{e,l,w} G_{e,l} for the place name ``name``.

    ``name`` is tokenised like a sentence (:meth:`~spco.data.language.Vocabulary.tokenize`:
    ``"Living Room"``, ``"living-room"`` → the token ``"living room"``). A name of several tokens
    (``"study room"`` never learnt as one term) is understood as all its known, unpruned tokens said
    together: p(m | w_1 … w_n) ∝ Σ_l π_{e,l,m} G_{e,l} Π_i θ^w_{e,l,w_i}; its unknown or pruned tokens
    are left out. The sum runs over the concepts holding samples of home ``e`` (``concept_counts``
    ≥ 1), or over all concepts if the name has no probability in those (see :func:`name_support`).
    Returns (K,) float64 summing to 1. Raises :class:`UnknownNameError` if no token of the name is
    known and unpruned, or the name has probability 0 in every concept of home ``e``.
    """
    e = _check_home(params, e)
    ws = query_indices(params, vocabulary, name)
    concept_weights = _name_concept_weights(params, e, ws)  # (L,)
    # a concept without samples of this home is looked for where its stand-in is (synonyms)
    concept_weights = np.bincount(concept_stand_ins(params, e), weights=concept_weights,
                                  minlength=concept_weights.size)
    occupied = _occupied_concepts(params, e)
    if (concept_weights[occupied] > 0).any():
        concept_weights = np.where(occupied, concept_weights, 0.0)
    pi = np.clip(np.asarray(params.region_weights[e], dtype=np.float64), 0.0, None)  # (L, K)
    weights = concept_weights @ pi  # (K,)
    total = weights.sum()
    if not total > 0:
        mask = np.asarray(params.word_mask, dtype=bool)
        known = [v for v, keep in zip(vocabulary.words, mask, strict=True) if keep]
        shown = " + ".join(vocabulary.words[w] for w in ws)
        raise UnknownNameError(name, known, reason=f"the name {shown!r} has "
                               f"probability 0 in every concept of home {e}")
    return weights / total


def draw_poses(params: ConceptParameters, e: int, region_probabilities: np.ndarray, regions: np.ndarray,
               rng: np.random.Generator, xy_only: bool = False) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Poses drawn from the Gaussians of ``regions`` (n,) of home ``e``, one per entry.

    Returns ``samples`` (n, 3) = (x, y, θ) (θ NaN when ``xy_only``: the x–y marginal is drawn),
    ``log_density`` (n,) of each raw draw under the mixture Σ_m p(m) N(· | μ_m, Σ_m) with
    p(m) = ``region_probabilities``, and ``weights`` (n,), that density normalised over the draws.
    """
    n = regions.size
    d = 2 if xy_only else 4
    means = np.asarray(params.region_means[e], dtype=np.float64)[:, :d]
    covs = np.asarray(params.region_covariances[e], dtype=np.float64)[:, :d, :d]
    z = rng.standard_normal((n, d))
    draws = means[regions] + np.einsum("nij,nj->ni", _cholesky(covs)[regions], z)
    if not n:
        return np.empty((0, 3)), np.empty(0), np.empty(0)
    theta = np.full(n, np.nan) if xy_only else np.arctan2(draws[:, 2], draws[:, 3])
    samples = np.column_stack([draws[:, 0], draws[:, 1], theta])
    log_mixture = _safe_log(region_probabilities)[None, :] + gaussian_log_density(draws, means, covs)
    log_density = logsumexp(log_mixture, axis=1)
    return samples, log_density, np.exp(log_density - logsumexp(log_density))


def predict_positions(
    params: ConceptParameters,
    e: int,
    vocabulary: Vocabulary,
    name: str,
    n: int = 10,
    rng: np.random.Generator | int | None = None,
    mode: PositionMode = "argmax",
    xy_only: bool = False,
    unheard: bool = True,
) -> PositionPrediction:
    """Sample ``n`` poses where the place ``name`` is, in home ``e``.

    Parameters
    ----------
    mode: ``"argmax"`` — draw from N(μ_m̂, Σ_m̂) with m̂ = argmax p(m | w) (the paper);
        ``"mixture"`` — draw each sample's region from p(m | w) first.
    xy_only: draw from the x–y marginal only (the authors' code); θ is then NaN.
    rng: a Generator (advanced by the draws) or a seed.
    unheard: a name that is not a usable token is first looked up in the lexicon
        (:func:`spco.model.unheard.resolve_name`; ``asked`` and ``via`` of the result say so); False:
        only the name's own known tokens are used.

    Returns a :class:`PositionPrediction` with samples (n, 3) = (x, y, θ) (``poses``: the same
    as (x, y, sin θ, cos θ)), the name's ``support`` in the home and ``learnt`` (see the module
    docstring: False means no such place was learnt in this home).
    """
    if n < 0:
        raise ConfigurationError(f"the number of positions must be >= 0, got {n}")
    if mode not in ("argmax", "mixture"):
        raise ConfigurationError(f"mode must be 'argmax' or 'mixture', got {mode!r}")
    e = _check_home(params, e)
    resolved = (resolve_name(vocabulary, params.word_mask, name, params.name_prior,
                             information=mutual_information_weights(params, e)) if unheard else None)
    if resolved is not None:  # a name nobody said: the known name the lexicon finds for it
        pred = predict_positions(params, e, vocabulary, resolved.name, n, rng, mode, xy_only, unheard=False)
        return replace(pred, asked=resolved.asked, via=resolved.how)
    probs = region_posterior_for_name(params, e, vocabulary, name)
    support = name_support(params, e, vocabulary, name)
    best = int(np.argmax(probs))
    gen = np.random.default_rng(rng)
    if mode == "argmax":
        regions = np.full(n, best, dtype=np.int64)
    else:
        regions = gen.choice(probs.size, size=n, p=probs).astype(np.int64)
    samples, log_density, weights = draw_poses(params, e, probs, regions, gen, xy_only)
    return PositionPrediction(
        name=query_name(vocabulary, params, name),
        region=best,
        region_probabilities=probs,
        samples=samples,
        regions=regions,
        log_density=log_density,
        weights=weights,
        mode=mode,
        xy_only=bool(xy_only),
        support=support,
        learnt=support >= LEARNT_SUPPORT,
    )
