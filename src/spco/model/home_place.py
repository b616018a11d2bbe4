"""A home level for the word channels' place channel (``place_channel="home"``; issue 28, class a).

The default place channel is one vocabulary per concept for every home, ψ_l ~ Dir(α^p)
(:mod:`spco.model.word_channels`). Homes differ in their furniture and their people in their object
words ("sofa" and "cushions" in one living room, "desk" and "table" in another), so a shared ψ_l makes
one home's object words a concept of their own (benchmarks/README.md, branch split16). With the home
level, as θ^w has around φ^w:

    ψ_l ~ Dir(α^p),    ψ_{e,l} ~ Dir(δ^p ψ_l)

and a place token of home e at concept l is drawn from ψ_{e,l}. The steps:

- **the switch and the concept** read ψ_{e,l} wherever they read ψ (:attr:`WordChannels.log_place_home`);
- **ψ_{e,l} | ψ_l, tokens** ~ Dir(δ^p ψ_l + n_{e,l}), n_{e,l} home e's place tokens at l counted as ψ
  learns them (each token once; the power target: s_ti times) — :func:`draw_home_place`, in the home
  step (:func:`spco.model.parameter_steps.home_step`), so every sampler that runs it (the fit's shards, a new
  home's shard in ``adapt`` and ``teach``'s learnt homes) draws its homes' own;
- **ψ_l | the homes' tokens, ψ_{e,l} integrated out**: table counts m_{e,l,k} ~ CRT(n_{e,l,k}, δ^p ψ_{l,k})
  (Teh et al. 2006), then ψ_l ~ Dir(α^p + Σ_e m_{e,l}) — :func:`place_tables`, the same step the
  θ^w/φ^w pair takes. The tables add up over homes, so a shard sends them in place of its place counts
  (:class:`~spco.model.word_channels.ChannelCounts` ``place``), and the driver's step
  (:func:`~spco.model.word_channels.sample_channels`) is unchanged. ψ_l is drawn from its conditional
  given the tokens with ψ_{e,l} integrated out, and ψ_{e,l} is redrawn right after, from its full
  conditional: a partially collapsed Gibbs order that keeps the target (van Dyk & Park 2008) — the
  power target's joint, and under the cut sampler the same conditionals the cut's ψ learns by;
- **label swaps** (:mod:`spco.model.moves`) integrate the home's ψ_{e,l} out: swapping concepts a and b
  of home e adds log DM(n_{e,a} | δ^p ψ_b) + log DM(n_{e,b} | δ^p ψ_a) − log DM(n_{e,a} | δ^p ψ_a)
  − log DM(n_{e,b} | δ^p ψ_b) (Dirichlet–multinomial of the tokens in ψ's units, as θ^w's terms are in
  θ^w's), and the homes that changed redraw ψ_{e,l} (:func:`swap_place_terms`);
- **a new home** (``adapt``, ``teach``: one home's shard with the shared part fixed) draws its
  ψ_{e,l} ~ Dir(δ^p ψ_l + its tokens) around the knowledge's ψ_l (its conditional mean given the fit's
  tables, what the knowledge keeps); before its first home step, and where no ψ_{e,l} is held (the
  answers after a fit, a knowledge file), ψ_l — ψ_{e,l}'s prior mean — is read.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import scipy.sparse as sp
from scipy.special import gammaln, logsumexp

from spco.model.observations import HierarchicalMultinomial
from spco.model.word_channels import PLACE, ChannelCounts, WordChannels, token_scales, tokens


def uses_home_place(hyper) -> bool:
    """Whether ``hyper`` (:class:`~spco.model.hyperparameters.TransferHyperparameters`) asks for the
    home level of the place channel (``place_channel="home"``)."""
    return getattr(hyper, "place_channel", "shared") == "home"


def home_place_counts(words: sp.csr_array, homes: np.ndarray, concepts: np.ndarray, switches: np.ndarray,
                      n_homes: int, n_concepts: int, scales: np.ndarray | None = None) -> np.ndarray:
    """(E, L, V) int64 the place tokens of every home, concept and word, counted as ψ learns them:
    each token once, or ``scales`` (nnz,) times (the power target's s_ti,
    :func:`~spco.model.word_channels.token_scales`). Summed over homes: ``ChannelCounts.place``."""
    rows, cols, _ = tokens(words)
    weight = (np.ones(rows.size, dtype=np.int64) if scales is None
              else np.rint(np.asarray(scales, dtype=np.float64)).astype(np.int64))
    out = np.zeros((n_homes, n_concepts, words.shape[1]), dtype=np.int64)
    is_place = np.asarray(switches) == PLACE
    r = rows[is_place]
    np.add.at(out, (np.asarray(homes, dtype=np.int64)[r], np.asarray(concepts, dtype=np.int64)[r],
                    cols[is_place]), weight[is_place])
    return out


def place_tables(counts: np.ndarray, log_place: np.ndarray, delta: float,
                 rng: np.random.Generator) -> np.ndarray:
    """(L, V) int64 Σ_e m_{e,l,k}, m ~ CRT(n_{e,l,k}, δ^p ψ_{l,k}): the homes' table counts given
    ``counts`` n (E, L, V) and log ψ_l ``log_place`` (L, V); ψ_l | tables ~ Dir(α^p + tables)."""
    tables = HierarchicalMultinomial.sample_tables(counts, log_place, float(delta), rng)
    return np.asarray(tables, dtype=np.int64)


def draw_home_place(channels: WordChannels, counts: np.ndarray, delta: float, rng: np.random.Generator,
                    homes: np.ndarray | None = None) -> WordChannels:
    """``channels`` with log ψ_{e,l} ~ Dir(δ^p ψ_l + n_{e,l}) drawn for every home of ``counts`` n
    (E, L, V), or only for ``homes`` (the others keep theirs: the label swaps' changed homes)."""
    if homes is None or channels.log_place_home is None:
        drawn = HierarchicalMultinomial.sample_specific(counts, channels.log_place, float(delta), rng)
    else:
        drawn = channels.log_place_home.copy()
        homes = np.asarray(homes, dtype=np.int64)
        if homes.size:
            drawn[homes] = HierarchicalMultinomial.sample_specific(counts[homes], channels.log_place,
                                                                   float(delta), rng)
    return replace(channels, log_place_home=drawn)


def log_dirichlet_multinomial(counts: np.ndarray, concentration: np.ndarray) -> np.ndarray:
    """log ∫ Π_k ψ_k^{n_k} Dir(ψ | a) dψ = ln Γ(A) − ln Γ(A + N) + Σ_k [ln Γ(a_k + n_k) − ln Γ(a_k)]
    over the last axis (the tokens in order: no multinomial coefficient); broadcasts."""
    n = np.asarray(counts, dtype=np.float64)
    a = np.asarray(concentration, dtype=np.float64)
    a, n = np.broadcast_arrays(a, n)
    terms = np.where(n > 0, gammaln(a + n) - gammaln(np.where(n > 0, a, 1.0)), 0.0)
    return gammaln(a.sum(-1)) - gammaln(a.sum(-1) + n.sum(-1)) + terms.sum(-1)


def swap_place_terms(counts: np.ndarray, log_place: np.ndarray, delta: float,
                     pairs: np.ndarray) -> np.ndarray:
    """(E, P) the place channel's part of the log acceptance ratio of swapping the concepts of each
    pair (E, P, 2) of every home, ψ_{e,l} integrated out: the Dirichlet–multinomials of the home's
    place tokens ``counts`` (E, L, V) under δ^p ψ (``log_place`` (L, V)) after the swap minus before."""
    a_, b_ = pairs[..., 0], pairs[..., 1]
    homes = np.arange(counts.shape[0])[:, None]
    conc = np.maximum(float(delta) * np.exp(log_place), 1e-300)  # (L, V); a ψ that underflows: tiny
    n_a, n_b = counts[homes, a_], counts[homes, b_]  # (E, P, V)
    after = log_dirichlet_multinomial(n_a, conc[b_]) + log_dirichlet_multinomial(n_b, conc[a_])
    before = log_dirichlet_multinomial(n_a, conc[a_]) + log_dirichlet_multinomial(n_b, conc[b_])
    return after - before


def home_place_statistics(data, state, hyper, n_homes: int, n_concepts: int) -> np.ndarray | None:
    """(E, L, V) the place tokens of ``data``'s homes (:func:`home_place_counts`, in ψ's units: the
    power target's s_ti, else once) when ``hyper`` asks for the home level; ``None`` otherwise."""
    if not uses_home_place(hyper) or state.channels is None:
        return None
    scales = token_scales(data.words, state.channels) if state.channels.power else None
    return home_place_counts(data.words, data.homes, state.concepts, state.switches, n_homes, n_concepts,
                             scales)


def shared_place_counts(stats, channels: WordChannels, hyper, rng: np.random.Generator) -> ChannelCounts:
    """The switches' counts that ψ_l is drawn from (:func:`~spco.model.word_channels.sample_channels`):
    ``stats.channel`` as it is, or with the home level its ``place`` replaced by the homes' CRT
    tables given ψ_l (:func:`place_tables`; the only draw, so without the home level the chain is
    unchanged)."""
    if stats.home_place is None:
        return stats.channel
    tables = place_tables(stats.home_place, channels.log_place, hyper.delta_place, rng)
    return replace(stats.channel, place=tables)


def draw_home_place_of(channels: WordChannels, counts: np.ndarray, delta: float, concepts: np.ndarray,
                       rng: np.random.Generator) -> WordChannels:
    """``channels`` with log ψ_{e,l} ~ Dir(δ^p ψ_l + n_{e,l}) drawn for the ``concepts`` of every home of
    ``counts`` n (E, L, V) and kept for the others (a teaching's affected concepts, as θ^w:
    :mod:`spco.model.local_update`); a state that holds no ψ_{e,l} yet has ψ_l, its prior mean, for the
    others. A new array: ``channels`` is not changed."""
    concepts = np.asarray(concepts, dtype=np.int64)
    E = counts.shape[0]
    held = channels.log_place_home
    base = np.repeat(channels.log_place[None], E, axis=0) if held is None else held.copy()
    if concepts.size:
        base[:, concepts] = HierarchicalMultinomial.sample_specific(counts[:, concepts],
                                                                    channels.log_place[concepts],
                                                                    float(delta), rng)
    return replace(channels, log_place_home=base)


def grown_home_place(log_place_home: np.ndarray | None, log_place: np.ndarray) -> np.ndarray | None:
    """log ψ_{e,l} (E, L, V_old) grown to the vocabulary of ``log_place`` (L, V) — ψ_l of the grown
    vocabulary (:meth:`spco.knowledge.KnowledgeChannels.extended`): a word never said in the home takes
    ψ_l's value (ψ_{e,l}'s prior mean given ψ_l) and the old words share the rest in their proportions,
    as ψ_l's old words do. ``None`` stays ``None``; an array of the full width is returned as it is."""
    if log_place_home is None:
        return None
    V_old, V = log_place_home.shape[2], log_place.shape[1]
    if V_old == V:
        return log_place_home
    if V_old > V:
        raise ValueError(f"log_place_home has {V_old} words, more than log_place's {V}")
    old_mass = logsumexp(log_place[:, :V_old], axis=1)  # (L,) log(1 − ψ_l's new words)
    E = log_place_home.shape[0]
    return np.concatenate([log_place_home + old_mass[None, :, None],
                           np.broadcast_to(log_place[None, :, V_old:], (E, *log_place[:, V_old:].shape))],
                          axis=2)


def home_place_mean(counts: np.ndarray, log_place: np.ndarray, delta: float) -> np.ndarray:
    """(E, L, V) log E[ψ_{e,l} | ψ_l, n_{e,l}] = log (δ^p ψ_l + n_{e,l}) − log (δ^p + N_{e,l}): the mean of
    ψ_{e,l}'s conditional (:func:`draw_home_place`) given the homes' place tokens ``counts`` n
    (E, L, V) and log ψ_l ``log_place`` (L, V)."""
    a = float(delta) * np.exp(np.asarray(log_place, dtype=np.float64))[None] + np.asarray(counts, np.float64)
    with np.errstate(divide="ignore"):
        return np.log(a) - np.log(a.sum(axis=-1, keepdims=True))
