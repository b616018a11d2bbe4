"""Posterior summaries of the home parameters: an average over thinned sweeps, not the last draw.

Predictions (``predict_names``, ``predict_positions``, ``where``, ``what``) use the parameters of
every home — θ^v, θ^w, G_e, π, μ, Σ. One Gibbs draw of them carries the draw's noise: a concept
with no sample in a home has its π drawn from the sparse prior Dir(β/K), and one such draw can
send a place name to an arbitrary region. The estimators therefore export a summary of the chain:

- which sweeps: :func:`thinned_sweeps` — every ``every``-th of the last ``fraction`` of the chain
  (default the last quarter, every 5th sweep, ending with the last sweep; the step is shortened so
  that a short chain still gives up to three samples), as :func:`spco.knowledge.fit_knowledge`
  does for the shared part;
- alignment: a Gibbs chain may relabel a home's concepts (the label-swap moves) or regions between
  sweeps, which leaves predictions unchanged but would mix different concepts in an average. Each
  sample's labels are matched, home by home, to those of the first averaged sample by the overlap
  of their assignments (Hungarian algorithm on the table of samples with reference label j and
  current label l; unused labels keep their number), and the result is expressed in the labels of
  the last sample, so that it agrees with the exported assignments and φ, G_0;
- empty concepts: a concept holding no sample of a home has no place there to be matched by; its
  θ, G_e and π in that home are draws given the shared φ and G_0 of *its own* label (what `where`
  falls back on for a name the home never said). A matching of a home's labels is a permutation,
  so when a place moves from concept a to an empty concept b, the empty b of the reference is
  matched to the now empty a: its average would mix the draws of two different shared concepts.
  The per-concept parameters (θ^v, θ^w, G_e, π) are therefore averaged in two parts: a concept
  with samples of the home, over the sweeps in which the matched concept had samples there; a
  concept without, by its own label, over the sweeps in which that label had none. Each concept
  of the last sample takes the part that fits it (tested with several empty concepts);
- probabilities (θ^v, θ^w, G_e, π) are averaged as probabilities (the Monte Carlo estimate of
  their posterior mean); pruned words (the mask of the last sweep) get 0 and rows are
  renormalised afterwards;
- each region's Gaussian is the Gaussian with the mean and covariance of the mixture of the
  sampled Gaussians (μ̄ = mean of μ^(s), Σ̄ = mean of Σ^(s) + μ^(s)μ^(s)ᵀ − μ̄μ̄ᵀ), i.e. the
  moments of the posterior predictive density of a new pose in that region, estimated from the
  samples;
- ``concept_counts`` (E, L) and ``region_counts`` (E, K) are the mean numbers of training
  samples assigned (region counts rounded to whole samples); a concept with a mean count below 1
  holds no sample of that home: prediction treats a name whose probability comes from such
  concepts as not learnt there (see :func:`spco.model.position_prediction.region_posterior_for_name`).

The shared φ^v, φ^w and G_0 exported with the home parameters are those of the last sample (they
are not used for prediction; :func:`spco.knowledge.fit_knowledge` averages them for transfer).
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import replace

import numpy as np
from scipy.optimize import linear_sum_assignment

from spco.model.parameters import ConceptParameters


def thinned_sweeps(n_iterations: int, fraction: float = 0.25, every: int = 5) -> list[int]:
    """The sweeps (0-based) whose samples are averaged: every ``every``-th of the last
    ``fraction`` of the chain, ending with the last sweep, with the step shortened so that a short
    chain still gives up to three samples (1 sweep: that sweep; 3: the last; 12: the last three;
    200: 154, 159, …, 199)."""
    window = max(1, int(n_iterations * fraction))
    step = max(1, min(every, window // 3))
    return sorted(range(n_iterations - 1, n_iterations - 1 - window, -step))


def _match_labels(reference: np.ndarray, current: np.ndarray, n_labels: int) -> np.ndarray:
    """perm (n_labels,): reference slot j takes current label perm[j], maximising the number of
    samples whose labels agree (ties — labels used by no sample — keep their number)."""
    overlap = np.zeros((n_labels, n_labels))
    np.add.at(overlap, (reference, current), 1.0)
    overlap[np.diag_indices(n_labels)] += 0.5  # less than one sample: only breaks ties
    rows, cols = linear_sum_assignment(overlap, maximize=True)
    perm = np.empty(n_labels, dtype=np.int64)
    perm[rows] = cols
    return perm


def masked_rows(log_p: np.ndarray, mask: np.ndarray) -> np.ndarray:
    """Probabilities from log-probabilities (rows of any scale), pruned words (mask False) set
    to 0 and rows renormalised in log space: never NaN, even if every kept entry underflows."""
    if log_p.shape[-1] == 0:  # no words
        return np.exp(log_p)
    allowed = np.ones(log_p.shape[-1], dtype=bool) if mask.all() or not mask.any() else mask
    kept = np.where(allowed, log_p, -np.inf)
    top = kept.max(axis=-1, keepdims=True)
    p = np.exp(kept - np.where(np.isfinite(top), top, 0.0))  # (a row of -inf: no NaN from -inf − -inf)
    total = p.sum(axis=-1, keepdims=True)
    # a row with no finite kept entry (nothing known of it) is uniform over the kept words
    p = np.where(total > 0, p, np.broadcast_to(allowed, p.shape).astype(np.float64))
    return p / p.sum(axis=-1, keepdims=True)


class ParameterAverage:
    """Accumulates the home parameters of thinned sweeps (see the module docstring).

    ``add(state)`` after each sweep to average; ``result(state)`` (the state of the last sweep)
    gives the :class:`ConceptParameters` in metres. ``homes`` (N,) home of each sample,
    ``position_scale`` sampler units per metre.
    """

    #: the per-concept parameters averaged in two parts (occupied by matched slot, empty by label)
    BY_CONCEPT = ("concept_weights", "region_weights")

    def __init__(self, homes: np.ndarray, position_scale: float) -> None:
        self.homes = np.asarray(homes)
        self.scale = np.array([position_scale, position_scale, 1.0, 1.0])
        self.n_samples = 0
        self._sums: dict[str, np.ndarray] = {}
        self._log_sums: dict[str, np.ndarray] = {}  # θ: summed in log space (entries underflow)
        self._empty_sums: dict[str, np.ndarray] = {}  # concepts without samples, by their own label
        self._empty_log_sums: dict[str, np.ndarray] = {}
        self._occupied_n: np.ndarray | None = None  # (E, L) sweeps the matched slot had samples
        self._empty_n: np.ndarray | None = None  # (E, L) sweeps the label had none
        self._occupied_last: np.ndarray | None = None
        self._reference: tuple[np.ndarray, np.ndarray] | None = None
        self._perms: tuple[np.ndarray, np.ndarray] | None = None

    def _permutations(self, concepts: np.ndarray, regions: np.ndarray, n_homes: int, n_concepts: int,
                      n_regions: int) -> tuple[np.ndarray, np.ndarray]:
        if self._reference is None:
            self._reference = (concepts.copy(), regions.copy())
        ref_c, ref_r = self._reference
        perm_c = np.tile(np.arange(n_concepts), (n_homes, 1))
        perm_r = np.tile(np.arange(n_regions), (n_homes, 1))
        for e in range(n_homes):  # a loop over homes; each step is one small assignment problem
            rows = self.homes == e
            perm_c[e] = _match_labels(ref_c[rows], concepts[rows], n_concepts)
            perm_r[e] = _match_labels(ref_r[rows], regions[rows], n_regions)
        return perm_c, perm_r

    def add(self, state, visual: Iterable[np.ndarray] | None = None) -> None:
        """Add the parameters of ``state`` (a :class:`~spco.model.gibbs.GibbsState`), aligned.
        ``visual``: each home's log θ^v (L, D) in home order, read instead of ``state.log_theta_v``
        (which may then be ``None``), so that no (E, L, D) copy of it is made."""
        E, L, K = state.log_pi.shape
        perm_c, perm_r = self._permutations(state.concepts, state.regions, E, L, K)
        homes = np.arange(E)[:, None]
        means = state.means / self.scale
        covariances = state.covariances / np.outer(self.scale, self.scale)
        concept_counts = np.zeros((E, L))
        np.add.at(concept_counts, (self.homes, state.concepts), 1.0)
        occupied = concept_counts > 0  # (E, L) in this sample's labels
        matched = occupied[homes, perm_c]  # (E, L) by reference slot: its matched label has samples
        pi_current = np.take_along_axis(np.exp(state.log_pi), perm_r[:, None, :], axis=2)  # regions to ref
        pi = pi_current[homes, perm_c]  # concepts to reference slots
        mu = means[homes, perm_r]
        by_concept = {  # (matched, by reference slot; empty, by the sample's own label)
            "concept_weights": (np.exp(state.log_g)[homes, perm_c], np.exp(state.log_g)),
            "region_weights": (pi, pi_current),
        }
        terms = {
            "region_means": mu,
            "region_second_moments": covariances[homes, perm_r] + mu[..., :, None] * mu[..., None, :],
            "concept_counts": concept_counts[homes, perm_c],
            "region_counts": np.asarray(state.region_counts, dtype=np.float64)[homes, perm_r],
        }

        def where(mask: np.ndarray, value: np.ndarray, fill: float) -> np.ndarray:
            return np.where(mask.reshape(mask.shape + (1,) * (value.ndim - 2)), value, fill)

        for name, (value, own) in by_concept.items():
            terms[name] = where(matched, value, 0.0)
            empty = where(~occupied, own, 0.0)
            self._empty_sums[name] = self._empty_sums[name] + empty if name in self._empty_sums else empty
        for name, value in terms.items():
            if name in self._sums:
                self._sums[name] += value
            else:
                self._sums[name] = np.array(value, dtype=np.float64)
        if visual is None:
            log_values = (("word_probabilities", state.log_theta_w),
                          ("visual_probabilities", state.log_theta_v))
        else:
            log_values = (("word_probabilities", state.log_theta_w),)
            self._add_log_rows("visual_probabilities", visual, perm_c, matched, occupied)
        for name, log_value in log_values:
            # one (E, L, ·) temporary at a time: matched concepts by reference slot, then empty ones
            for sums, masked in ((self._log_sums, ~matched), (self._empty_log_sums, occupied)):
                value = (log_value[homes, perm_c].astype(np.float64, copy=False)
                         if sums is self._log_sums  # (a new array either way: filled in place)
                         else np.array(log_value, dtype=np.float64))
                value[masked] = -np.inf
                if name in sums:
                    np.logaddexp(sums[name], value, out=sums[name])
                else:
                    sums[name] = value
                del value
        self._occupied_n = matched.astype(np.int64) + (0 if self._occupied_n is None else self._occupied_n)
        self._empty_n = (~occupied).astype(np.int64) + (0 if self._empty_n is None else self._empty_n)
        self._occupied_last = occupied
        self.n_samples += 1
        self._perms = (perm_c, perm_r)

    def _add_log_rows(self, name: str, rows: Iterable[np.ndarray], perm_c: np.ndarray, matched: np.ndarray,
                      occupied: np.ndarray) -> None:
        """What :meth:`add` does with an (E, L, D) log-probability array, home by home from its
        (L, D) ``rows``: the same sums, with one home's temporary at a time."""
        for e, log_value in enumerate(rows):
            for sums, value in ((self._log_sums, log_value[perm_c[e]].astype(np.float64)),
                                (self._empty_log_sums, np.array(log_value, dtype=np.float64))):
                value[~matched[e] if sums is self._log_sums else occupied[e]] = -np.inf
                if name not in sums:
                    sums[name] = np.empty((perm_c.shape[0], *value.shape))
                if self.n_samples == 0:
                    sums[name][e] = value
                else:
                    np.logaddexp(sums[name][e], value, out=sums[name][e])

    def result(self, state, release: bool = False) -> ConceptParameters:
        """The averaged parameters in the labels of ``state``, the last sample added. ``release``:
        build the probability arrays in the sums' own memory and drop the sums (the average can
        then take no more samples nor give its result again; a fit's end, where the (E, L, D) sums
        are the largest arrays)."""
        if self.n_samples == 0 or self._perms is None:
            raise ValueError("no sample was added to the average")
        perm_c, perm_r = self._perms
        E = perm_c.shape[0]
        homes = np.arange(E)[:, None]
        mean = {name: total / self.n_samples for name, total in self._sums.items()}

        def to_current(a: np.ndarray, perm: np.ndarray) -> np.ndarray:
            out = np.empty_like(a)
            out[homes, perm] = a  # reference slot j holds current label perm[j]
            return out

        occupied = self._occupied_last  # (E, L) the last sample's concepts with samples of each home
        occupied_n = to_current(self._occupied_n, perm_c)  # ≥ 1 where occupied (the last sample counts)
        empty_n = self._empty_n  # ≥ 1 where not occupied

        def split_mean(name: str) -> np.ndarray:
            """Occupied concepts: the matched average; empty ones: the average of their own label."""
            full = occupied.reshape(occupied.shape + (1,) * (self._sums[name].ndim - 2))
            with np.errstate(invalid="ignore", divide="ignore"):
                matched = to_current(self._sums[name], perm_c) / np.maximum(
                    occupied_n.reshape(full.shape), 1)
                empty = self._empty_sums[name] / np.maximum(empty_n.reshape(full.shape), 1)
            return np.where(full, matched, empty)

        def split_log_mean(name: str) -> np.ndarray:
            # in place, one (E, L, D) array at a time beside the sums (with release: in the sums)
            if release:
                out = self._log_sums.pop(name)
                for e in range(E):  # to_current, one home's rows at a time
                    out[e, perm_c[e]] = out[e].copy()
            else:
                out = to_current(self._log_sums[name], perm_c)
            out -= np.log(np.maximum(occupied_n, 1))[..., None]
            empty = ~occupied
            out[empty] = self._empty_log_sums[name][empty] - np.log(np.maximum(empty_n[empty], 1))[:, None]
            if release:
                del self._empty_log_sums[name]
            return out

        pi = split_mean("region_weights")  # regions still in the reference order
        pi_out = np.empty_like(pi)
        np.put_along_axis(pi_out, np.broadcast_to(perm_r[:, None, :], pi.shape), pi, axis=2)
        mu = to_current(mean["region_means"], perm_r)
        second = to_current(mean["region_second_moments"], perm_r)
        covariances = second - mu[..., :, None] * mu[..., None, :]
        covariances = 0.5 * (covariances + np.swapaxes(covariances, -1, -2))
        mask = np.asarray(state.word_mask, dtype=bool)
        log_theta_w = split_log_mean("word_probabilities")  # rows renormalised below
        visual = split_log_mean("visual_probabilities")
        np.exp(visual, out=visual)  # in place: one (E, L, D) array, not two, at a fit's end
        g = split_mean("concept_weights")  # occupied and empty parts averaged apart: renormalised
        g = g / np.maximum(g.sum(axis=-1, keepdims=True), np.finfo(float).tiny)
        return ConceptParameters(
            concept_weights=g,
            region_weights=pi_out,
            region_means=mu,
            region_covariances=covariances,
            word_probabilities=masked_rows(log_theta_w, mask),
            visual_probabilities=visual,
            shared_word_probabilities=masked_rows(state.log_phi_w, mask),
            shared_visual_probabilities=np.exp(state.log_phi_v),
            global_concept_weights=np.exp(state.log_g0),
            word_mask=mask.copy(),
            region_counts=np.rint(to_current(mean["region_counts"], perm_r)).astype(np.int64),
            concept_counts=to_current(mean["concept_counts"], perm_c),
        )


def untaught_concepts_name_nothing(params: ConceptParameters, taught: np.ndarray) -> ConceptParameters:
    """``params`` with the word distribution of every concept that no taught sentence of any home
    was assigned to (``taught`` (L,) bool False) made uniform over the kept words, in every home.

    Such a concept's θ^w is a draw from the prior around a φ^w no word was ever counted for: with
    α^w = 0.01 the draw is sparse, and a random word ("bath") can hold half its mass. A home
    whose room, untaught, sits in such a concept would then be answered "bath" there, and ``where
    bath`` would send the robot into it. With the distribution uniform the concept names nothing:
    its views are named by the taught concepts that share them, and a name's regions come from
    the concepts it was said with. (The posterior mean of θ^w given no word is the prior mean,
    uniform; one draw is not.)
    """
    taught = np.asarray(taught, dtype=bool)
    if taught.all() or params.word_probabilities.shape[-1] == 0:
        return params
    mask = np.asarray(params.word_mask, dtype=bool)
    uniform = mask / mask.sum() if mask.any() else np.full(mask.size, 1.0 / mask.size)
    theta = np.array(params.word_probabilities, dtype=np.float64, copy=True)
    theta[:, ~taught, :] = uniform
    return replace(params, word_probabilities=theta)
