"""Words that are not names, in the model: every word token comes from one of three channels.

A taught sentence is a bag of word tokens (one token per distinct word of the sentence; the corpus
gives it S^w counts, ``Corpus.word_increment``). Each token i of sample t has a latent **switch**
z_ti ∈ {name, place, background} (``docs/model.md``, "Words that are not names"):

- **name** (z = 0): the word is drawn from the concept's *names*, θ^w_{e,C_t} ~ Dir(δ^w φ^w_{C_t})
  (the paper's word distribution, now of names only);
- **place** (z = 1): from the words *associated with the place* — objects, activities, people said
  there ("fridge", "cook", "guests") — ψ_{C_t} ~ Dir(α^p), one per concept, shared by all homes
  (with ``place_channel="home"``, a home level ψ_{e,C_t} ~ Dir(δ^p ψ_{C_t}): :mod:`spco.model.home_place`);
- **background** (z = 2): from a **background** β ~ Dir(α^b) shared by every place and home
  (function words, fillers, greetings).

The switch's prior comes from the **linguistic evidence** of word k, e_k = (a_k ν_k, a_k (1 − ν_k),
1 − a_k) (each to the power η, ``TransferHyperparameters.evidence_weight``, then normalised): a_k the
share of its words that are content words (:func:`spco.model.name_evidence.content_share`: function
words, numbers and fillers are not), ν_k = P(name | how word k is said and what it is) of
:func:`spco.model.name_evidence.channel_evidence` (sentence frames and WordNet, a logistic model
fitted on development data). p(z = name | k) = e_{k,0} / Σ_c e_{k,c}: the evidence itself, not
learnt. The rest is split between place and background in proportion to λ_place e_{k,1} and
λ_background e_{k,2}, with learnt shares λ ~ Beta(1, 1) (on a grid, below). As in topic models
with background and special words (Chemudugunta et al. 2006; the background switch of Twitter-LDA),
which words are names is then what the posterior says.

**Each token counts once in its switch.** The token's conditional given the concept uses one draw:

    p(z_ti = c | C_t = l, k) ∝ λ_c e_{k,c} · (θ^w_{e,l,k}, ψ_{l,k}, β_k)_c

so its prior is weighed against one likelihood, not against the S^w = 5000 counts with which a name
weighs in the concept's assignment (raised to the 5000th power, any prior on the switch would be
swamped). The tokens' channel counts — ψ's, β's and λ's statistics — count each token once.

**Each token weighs W^w in its concept.** The concept's conditional marginalises the switches:

    log p(w_t | C_t = l) = Σ_i W^w (c_ti / S^w) · log Σ_c λ̃_{k,c} (θ^w_{e,l,k}, ψ_{l,k}, β_k)_c,
    λ̃_{k,c} = λ_c e_{k,c} / Σ_c' λ_c' e_{k,c'}

with c_ti = S^w per occurrence (the word increment) and W^w the word weight
(``TransferHyperparameters.word_counts``, by default a view's weight w;
:attr:`WordChannels.token_weight` = W^w / S^w): a power likelihood on the words, as ``view_counts``
is one on the views, so that a sentence's words and its view and position are weighed on one scale
(with S^w counts per token, a sentence of object words weighed tens of thousands of nats more in a
concept of those objects alone than in the concept of the people who named the same room, against a
few nats of view and position: docs/model.md, "A word token's evidence"). A function word
(λ̃ background ≈ 1) then says nothing about the concept, a name (θ^w large at one concept) or an
object (ψ) says W^w times its per-token log ratio. θ^w | z counts the name tokens with their S^w
counts (as the paper's word statistics did), so the names' θ^w and φ^w keep their scale.

The two conditionals are not those of one joint distribution unless W^w = S^w = 1 (the switch at
power 1, the concept at power W^w, θ^w counting S^w): the sampler is a modular ("cut") Gibbs
sampler, exact for W^w = S^w = 1 (tested
against enumeration of the joint in ``tests/test_word_channels.py``). λ | z is drawn exactly on a
grid (:data:`LAMBDA_GRID` steps): its conditional p(λ | z) ∝ Π_c λ_c^{n_c} / Π_k (Σ_c λ_c e_{k,c})^{m_k}
(c ∈ {place, background}; n_c tokens in channel c, m_k such tokens of word k) is not a Beta.

The name scoring that prediction uses, p(name k | concept l) = θ^w_{e,l,k}, is
:func:`name_log_probabilities`.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np
import scipy.sparse as sp
from scipy.special import logsumexp

from spco.model.additive import AdditiveCounts
from spco.model.kernels.channels import mixture_rows, switch_rows
from spco.model.kernels.dirichlet import log_dirichlet

#: The channels of a word token.
NAME, PLACE, BACKGROUND = 0, 1, 2
CHANNELS = ("name", "place", "background")

#: Dirichlet concentration of the place words ψ_l (per word) and of the background β (per word).
ALPHA_PLACE = 0.1
ALPHA_BACKGROUND = 0.1

#: Points per side of the simplex grid on which λ | z is drawn (interior points only).
LAMBDA_GRID = 40

#: Smallest name evidence ν used (a word is never certainly a name or certainly not).
EVIDENCE_FLOOR = 1e-4


@dataclass
class WordChannels:
    """The channels' parameters (log-probabilities), shared by every home.

    log_place: (L, V) log ψ, each concept's place-associated words; log_background: (V,) log β;
    log_shares: (3,) log λ, the channels' shares; log_evidence: (V, 3) log e_k, the linguistic
    evidence (fixed: computed from the sentences before the chain starts)."""

    log_place: np.ndarray
    log_background: np.ndarray
    log_shares: np.ndarray
    log_evidence: np.ndarray
    #: True until the first statistics: the first switches are drawn from their prior alone
    #: (:func:`sample_switches`), so that ψ, β and θ^w start from the evidence, not from a θ^w of
    #: the start that counted every word as a name
    fresh: bool = False
    #: the first column of the words first heard in a home after the fit (``None``: none): their
    #: switch is drawn from its prior (:func:`switch_probabilities`) — with no token in the fit, their
    #: θ^w, ψ and β are all "a word never said" (θ^w a draw around a Dirichlet parameter α^w, e^-95 as
    #: often as e^-17), which says nothing about the channel — and is a name whenever the prior's most
    #: probable channel is the name: redrawn at every sweep, "study room" (P(name) 0.69) taught once
    #: left its concept's θ^w one sweep in three, and `what` there answered the transferred name
    prior_only_from: int | None = None
    #: W^w / S^w, the factor on a token's counts in its concept's likelihood (:func:`mixture_log_likelihood`,
    #: the place tokens of a label swap): the word weight ``TransferHyperparameters.word_counts`` over
    #: the word increment (1: S^w counts per token, as before the word weight)
    token_weight: float = 1.0
    #: the power likelihood in every step (``TransferHyperparameters.target == "power"``): a token's
    #: channel likelihood raised to s_ti = W^w n_ti in its switch and its concept alike, and θ^w, ψ
    #: and β counting it s_ti times (:func:`token_scales`); ``False``: the cut sampler of the module
    #: docstring (switch once, concept W^w, θ^w S^w)
    power: bool = False
    #: the home level of the place channel (``place_channel="home"``, :mod:`spco.model.home_place`):
    #: log ψ_{e,l} (E, L, V) of the homes of the state that holds it (home indices as its data's), used
    #: wherever ψ is read for a token; ``None``: ψ_l (``log_place``) for every home (the default model,
    #: and a home whose ψ_{e,l} is not drawn yet: ψ_l is its prior mean)
    log_place_home: np.ndarray | None = None
    #: :meth:`log_prior`, computed once per channels (every field is replaced, never changed in place)
    _log_prior: np.ndarray | None = field(default=None, init=False, repr=False, compare=False)

    @classmethod
    def initial(cls, evidence: np.ndarray, n_concepts: int, weight: float = 1.0,
                content: np.ndarray | None = None, token_weight: float = 1.0,
                power: bool = False) -> WordChannels:
        """Uniform ψ and β, equal shares, and the evidence of every word: ``evidence`` (V,) = ν_k in
        (0, 1), P(name | word), with weight η = ``weight``, and ``content`` (V,) = a_k, the share of
        its words that are content words (:func:`spco.model.name_evidence.content_share`; default 1):
        e_k = ((a_k ν_k)^η, (a_k (1 − ν_k))^η, (1 − a_k)^η), a_k kept within [0.05, 0.95]: a content
        word is a name or a place word as the evidence says, a function word background.
        ``token_weight``: :attr:`token_weight` (:func:`token_weight` of the hyperparameters);
        ``power``: :attr:`power`."""
        if not (np.isfinite(token_weight) and token_weight > 0):
            raise ValueError(f"token_weight must be a positive number, got {token_weight!r}")
        nu = np.clip(np.asarray(evidence, dtype=np.float64), EVIDENCE_FLOOR, 1.0 - EVIDENCE_FLOOR)
        V = nu.size
        a = np.ones(V) if content is None else np.asarray(content, dtype=np.float64)
        a = np.clip(a, 0.05, 0.95)
        log_e = weight * np.stack([np.log(a) + np.log(nu), np.log(a) + np.log1p(-nu), np.log1p(-a)], axis=1)
        flat = -np.log(max(V, 1))
        shares = np.array([0.0, -np.log(2.0), -np.log(2.0)])  # (the first is unused)
        return cls(np.full((n_concepts, V), flat), np.full(V, flat), shares, log_e, True,
                   token_weight=float(token_weight), power=bool(power))

    def copy(self) -> WordChannels:
        """A copy of the arrays."""
        return WordChannels(self.log_place.copy(), self.log_background.copy(), self.log_shares.copy(),
                            self.log_evidence.copy(), self.fresh, self.prior_only_from, self.token_weight,
                            self.power,
                            None if self.log_place_home is None else self.log_place_home.copy())

    def token_place(self) -> np.ndarray:
        """log ψ as a token reads it: ψ_{e,l} (E, L, V) with the home level, else ψ_l (L, V)."""
        if self.log_place_home is None:
            return self.log_place
        if self.log_place_home.shape[1:] != self.log_place.shape:
            raise ValueError(f"log_place_home has shape {self.log_place_home.shape}, not (E, "
                             f"{', '.join(map(str, self.log_place.shape))}) as log_place")
        return self.log_place_home

    @property
    def n_words(self) -> int:
        """V."""
        return int(self.log_background.size)

    def log_prior(self) -> np.ndarray:
        """(V, 3) log p(z = c | word k): the name evidence for the names channel,
        p(name | k) = e_{k,0} / Σ_c e_{k,c}, and the rest split between place and background by
        the learnt shares, ∝ λ_place e_{k,1} and λ_background e_{k,2} (``log_shares[0]`` is unused).
        Computed once (the fields are replaced, not changed in place); read-only."""
        if self._log_prior is None:
            self._log_prior = self._compute_log_prior()
            self._log_prior.flags.writeable = False
        return self._log_prior

    def name_prior(self) -> np.ndarray:
        """(V,) p(z = name | word k), the linguistic evidence's name share (the names column of
        :meth:`log_prior`): what the names said at a place and the names objects stand in for weigh
        a word by."""
        return np.exp(self.log_prior()[:, NAME])

    def _compute_log_prior(self) -> np.ndarray:
        log_e = self.log_evidence - logsumexp(self.log_evidence, axis=1, keepdims=True)
        rest = logsumexp(log_e[:, 1:], axis=1)  # log p(not a name | k)
        split = self.log_shares[None, 1:] + log_e[:, 1:]
        split = split - logsumexp(split, axis=1, keepdims=True)
        return np.column_stack([log_e[:, 0], rest[:, None] + split])

    def extended(self, n_words: int, evidence: np.ndarray | None = None, content: np.ndarray | None = None,
                 weight: float = 1.0) -> WordChannels:
        """The channels for a vocabulary grown to ``n_words`` (new words appended): new words get
        ψ and β of a word never said (α / (α V + count) as from the prior mean, here the smallest
        present value) and evidence ``evidence[V_old:]`` (default ν = 0.5) with content share
        ``content[V_old:]`` (default 0.95: a content word) and weight η = ``weight``, as
        :meth:`initial` computes it."""
        V = self.n_words
        added = n_words - V
        if added <= 0:
            return self
        nu = np.full(added, 0.5) if evidence is None else np.asarray(evidence, dtype=np.float64)[V:]
        nu = np.clip(nu, EVIDENCE_FLOOR, 1.0 - EVIDENCE_FLOOR)
        a = np.full(added, 0.95) if content is None else np.asarray(content, dtype=np.float64)[V:]
        a = np.clip(a, 0.05, 0.95)
        log_e = weight * np.stack([np.log(a) + np.log(nu), np.log(a) + np.log1p(-nu), np.log1p(-a)], axis=1)
        low_p = self.log_place.min(axis=1, keepdims=True) if V else np.zeros((self.log_place.shape[0], 1))
        low_b = self.log_background.min() if V else 0.0
        place = np.concatenate([self.log_place, np.repeat(low_p, added, axis=1)], axis=1)
        background = np.concatenate([self.log_background, np.full(added, low_b)])
        return replace(self, log_place=place - logsumexp(place, axis=1, keepdims=True), log_place_home=None,
                       log_background=background - logsumexp(background),
                       log_evidence=np.concatenate([self.log_evidence, log_e]))


def uses_word_channels(hyper, settings) -> bool:
    """Whether a fit with ``hyper`` (:class:`~spco.model.hyperparameters.TransferHyperparameters`) and
    ``settings`` (:class:`~spco.model.state.SamplerSettings`) models its words with the channels: the
    exact sampler's "+MI" models with ``word_model="channels"`` (the default)."""
    return (settings.variant == "exact" and settings.prune and settings.learn_shared
            and getattr(hyper, "word_model", "naming-rule") == "channels")


def token_weight(word_counts: float | None, word_increment: int) -> float:
    """:attr:`WordChannels.token_weight` of the word weight W^w = ``word_counts``
    (``TransferHyperparameters.word_counts``; ``None``: S^w) and the word increment S^w: W^w / S^w."""
    return 1.0 if word_counts is None else float(word_counts) / float(word_increment)


def name_token_counts(hyper, word_increment: float) -> float:
    """The counts θ^w adds for one name token, the unit δ^w is stated in: W^w
    (``TransferHyperparameters.word_counts``) when the chain targets the power likelihood
    (``target="power"``), S^w = ``word_increment`` otherwise (the cut sampler). The answers that
    update a concept's names by a home's or a room's name tokens against δ^w
    (:func:`spco.model.confidence.place_named_parameters`, :class:`spco.model.rooms.HomeRooms`) count
    them so, as the chain that learnt δ^w's θ^w did."""
    word_counts = getattr(hyper, "word_counts", None)
    if getattr(hyper, "target", "cut") == "power" and word_counts is not None:
        return float(word_counts)
    return float(word_increment)


def rooms_concentration(hyper, word_increment: float) -> float:
    """δ^w in the S^w counts per token that a room's name tokens are read in
    (:func:`spco.model.word_channels.channel_token_counts`, ``HomeRooms.concentration``): δ^w times
    S^w over :func:`name_token_counts` (δ^w itself under the cut sampler)."""
    counts = name_token_counts(hyper, word_increment)
    if counts == float(word_increment):
        return float(hyper.delta_word)
    return float(hyper.delta_word) * float(word_increment) / counts


def token_rows(words: sp.csr_array) -> np.ndarray:
    """The sample (row) of every token (stored entry) of ``words``: (nnz,)."""
    return np.repeat(np.arange(words.shape[0]), np.diff(words.indptr))


def tokens(words: sp.csr_array) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Row, column and count of every token (stored entry): (nnz,) each (a CSR's buffers may be
    longer than its entries: they are cut to ``indptr``)."""
    first, last = int(words.indptr[0]), int(words.indptr[-1])
    return token_rows(words), words.indices[first:last], words.data[first:last]


def mixture_log_likelihood(words: sp.csr_array, homes: np.ndarray, log_theta_w: np.ndarray,
                           channels: WordChannels) -> np.ndarray:
    """Σ_i ω c_ti log Σ_c p(z = c | k) p(k | c, l) for every sample and concept of its home: (N, L).

    The switches marginalised; each token weighed by its count c_ti (S^w per word) times
    ω = :attr:`WordChannels.token_weight` (W^w / S^w: W^w counts per word)."""
    n_samples, n_concepts = words.shape[0], log_theta_w.shape[1]
    out = np.zeros((n_samples, n_concepts))
    if not words.nnz:
        return out
    if channels.power:
        terms = _power_token_terms(words, homes, log_theta_w, channels)  # (nnz, L)
        rows = token_rows(words)
        gather = sp.csr_array((np.ones(rows.size), (rows, np.arange(rows.size))),
                              shape=(n_samples, rows.size))
        return np.asarray(gather @ terms)
    out = mixture_rows(words, homes, log_theta_w, channels.token_place(), channels.log_background,
                       channels.log_prior())
    return out if channels.token_weight == 1.0 else out * channels.token_weight


def switch_probabilities(words: sp.csr_array, homes: np.ndarray, concepts: np.ndarray,
                         log_theta_w: np.ndarray, channels: WordChannels) -> np.ndarray:
    """p(z_ti = c | C_t, w_ti) of every token, each token counted once: (nnz, 3). The tokens of the
    words from ``channels.prior_only_from`` on (first heard in a home) get their prior, the name
    channel alone where it is the prior's most probable (:attr:`WordChannels.prior_only_from`)."""
    if not words.nnz:
        return np.zeros((0, 3))
    if channels.power:
        logits = _power_channel_logits(words, homes, log_theta_w, channels, concepts)  # (nnz, 3)
        p = np.exp(logits - logsumexp(logits, axis=1, keepdims=True))
    else:
        p = switch_rows(words, homes, concepts, log_theta_w, channels.token_place(), channels.log_background,
                        channels.log_prior())
    if channels.prior_only_from is not None:  # words first heard in a home: the prior (see the field)
        _, cols, _ = tokens(words)
        new = cols >= channels.prior_only_from
        if new.any():
            p = np.array(p, copy=True)
            prior = np.exp(channels.log_prior()[cols[new]])
            named = np.argmax(prior, axis=1) == NAME
            prior[named] = np.eye(3)[NAME]
            p[new] = prior
    return p


def expected_tokens(words: sp.csr_array, homes: np.ndarray, concepts: np.ndarray, log_theta_w: np.ndarray,
                    channels: WordChannels) -> np.ndarray:
    """(V, 3) each word's expected tokens per channel (name, place, background) given the concepts:
    the switch probabilities of its tokens summed (:func:`switch_probabilities`, each token once) —
    the Rao-Blackwellised counts of the switches, which a drawn switch only estimates."""
    out = np.zeros((words.shape[1], 3))
    if not words.nnz:
        return out
    p = switch_probabilities(words, homes, concepts, log_theta_w, channels)
    _, cols, _ = tokens(words)
    np.add.at(out, cols, p)
    return out


def token_scales(words: sp.csr_array, channels: WordChannels) -> np.ndarray:
    """s_ti = c_ti · :attr:`WordChannels.token_weight` = W^w n_ti of every token (n_ti its occurrences
    in the sentence, c_ti = S^w n_ti its counts): (nnz,), the power of its channel likelihood and its
    counts in θ^w, ψ and β when the chain targets the power likelihood (:attr:`WordChannels.power`)."""
    _, _, counts = tokens(words)
    return counts.astype(np.float64) * float(channels.token_weight)


def _power_channel_logits(words: sp.csr_array, homes: np.ndarray, log_theta_w: np.ndarray,
                          channels: WordChannels, concepts: np.ndarray | None = None) -> np.ndarray:
    """log p(z = c | k) + s_ti log p(k | c, l) of every token: (nnz, L, 3) for every concept l of the
    token's home, or (nnz, 3) at its sample's concept ``concepts`` (power likelihood)."""
    rows, cols, _ = tokens(words)
    scale = token_scales(words, channels)
    prior = channels.log_prior()[cols]  # (nnz, 3)
    e = homes[rows]
    home_place = channels.log_place_home
    pe = None if home_place is None else _place_homes(home_place, e)
    if concepts is None:
        name = log_theta_w[e, :, cols]  # (nnz, L)
        place = channels.log_place[:, cols].T if home_place is None else home_place[pe, :, cols]
        background = np.broadcast_to(channels.log_background[cols][:, None], name.shape)
        stacked = np.stack([name, place, background], axis=-1)  # (nnz, L, 3)
        return prior[:, None, :] + scale[:, None, None] * stacked
    c = concepts[rows]
    place_c = channels.log_place[c, cols] if home_place is None else home_place[pe, c, cols]
    stacked = np.column_stack([log_theta_w[e, c, cols], place_c,
                               channels.log_background[cols]])
    return prior + scale[:, None] * stacked


def _place_homes(home_place: np.ndarray, homes: np.ndarray) -> np.ndarray:
    """The rows of a home-level ψ_{e,l} (E, L, V) that the homes ``homes`` read (one row: every home)."""
    return homes if home_place.shape[0] > 1 else np.zeros_like(homes)


def _power_token_terms(words: sp.csr_array, homes: np.ndarray, log_theta_w: np.ndarray,
                       channels: WordChannels) -> np.ndarray:
    """log Σ_c p(z = c | k) p(k | c, l)^{s_ti} of every token and concept (nnz, L): the token's
    likelihood with its switch marginalised under the power likelihood."""
    return _logsumexp_last(_power_channel_logits(words, homes, log_theta_w, channels))


def _logsumexp_last(a: np.ndarray) -> np.ndarray:
    """``scipy.special.logsumexp(a, axis=-1)`` for real ``a``, to the bit: SciPy's operations on the
    same values (the largest entries apart, ln(1 + Σ e^(a − max) / m) + ln m + max, m the number of
    largest; the direct ln Σ e^a where that is not finite), with fewer temporaries — the power
    likelihood's tokens (nnz, L, 3) in every local step."""
    a_max = a.max(axis=-1, keepdims=True)
    mask = a == a_max
    m = mask.sum(axis=-1, keepdims=True, dtype=a.dtype)
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        rest = np.where(mask, -np.inf, a)
        rest -= a_max
        np.exp(rest, out=rest)
        s = rest.sum(axis=-1, keepdims=True, dtype=a.dtype)
        s = np.where(s == 0, s, s / m)
        out = np.log1p(s) + np.log(m) + a_max
        out[np.sign(s + 1) * np.sign(m) < 0] = np.nan
        rows = np.nonzero(~np.isfinite(out[..., 0]))
        if rows[0].size:
            out[rows] = np.log(np.exp(a[rows]).sum(axis=-1, keepdims=True))
    return out[..., 0]


def sample_switches(words: sp.csr_array, homes: np.ndarray, concepts: np.ndarray, log_theta_w: np.ndarray,
                    channels: WordChannels, rng: np.random.Generator) -> np.ndarray:
    """Draw every token's switch given its sample's concept: (nnz,) int8 in {0, 1, 2}. Fresh channels
    (:attr:`WordChannels.fresh`): from the switch's prior alone (the start)."""
    if channels.fresh:
        _, cols, _ = tokens(words)
        p = np.exp(channels.log_prior()[cols])
    else:
        p = switch_probabilities(words, homes, concepts, log_theta_w, channels)
    u = rng.random(p.shape[0])
    return (u[:, None] > np.cumsum(p, axis=1)[:, :2]).sum(axis=1).astype(np.int8)


@dataclass
class ChannelCounts(AdditiveCounts):
    """The switches' statistics, adding up over homes: place tokens per concept and word (L, V),
    background tokens per word (V,), tokens per word and channel (V, 3); each token counted once."""

    place: np.ndarray
    background: np.ndarray
    by_word: np.ndarray


def channel_counts(words: sp.csr_array, concepts: np.ndarray, switches: np.ndarray,
                   n_concepts: int, scales: np.ndarray | None = None) -> ChannelCounts:
    """:class:`ChannelCounts` of the tokens of ``words`` with their switches (nnz,). ``scales``
    (nnz,), whole numbers: each token's counts in ψ and β (:func:`token_scales`, the power
    likelihood; default once each); ``by_word``, the switch prior's statistic, counts each token once."""
    V = words.shape[1]
    rows, cols, _ = tokens(words)
    weight = (np.ones(rows.size, dtype=np.int64) if scales is None
              else np.rint(np.asarray(scales, dtype=np.float64)).astype(np.int64))
    place = np.zeros((n_concepts, V), dtype=np.int64)
    is_place = switches == PLACE
    np.add.at(place, (concepts[rows[is_place]], cols[is_place]), weight[is_place])
    is_background = switches == BACKGROUND
    background = np.bincount(cols[is_background], weights=weight[is_background],
                             minlength=V).astype(np.int64)
    by_word = np.zeros((V, 3), dtype=np.int64)
    np.add.at(by_word, (cols, switches.astype(np.int64)), 1)
    return ChannelCounts(place, background, by_word)


def channel_token_counts(words: sp.csr_array, homes: np.ndarray, concepts: np.ndarray,
                         log_theta_w: np.ndarray, channels: WordChannels
                         ) -> tuple[sp.csr_array, sp.csr_array]:
    """(N, V) each sample's expected name tokens and (N, V) its expected tokens said as words of the
    place: every token's counts (S^w) times its switch probabilities given its sample's concept
    (:func:`switch_probabilities`, Rao-Blackwellised as :func:`expected_tokens`)."""
    if not words.nnz:
        empty = sp.csr_array(words.shape, dtype=np.float64)
        return empty, empty.copy()
    p = switch_probabilities(words, homes, concepts, log_theta_w, channels)  # (nnz, 3)
    rows, cols, counts = tokens(words)
    counts = np.asarray(counts, dtype=np.float64)
    return tuple(sp.csr_array((counts * p[:, c], (rows, cols)), shape=words.shape)  # type: ignore[return-value]
                 for c in (NAME, PLACE))


def name_tokens(words: sp.csr_array, switches: np.ndarray, scale: float = 1.0) -> sp.csr_array:
    """The counts of the name tokens only (N, V): what θ^w | z counts (S^w per token; times ``scale``,
    rounded to whole counts: :attr:`WordChannels.token_weight` under the power likelihood, W^w per
    occurrence)."""
    first, last = int(words.indptr[0]), int(words.indptr[-1])
    keep = switches == NAME
    kept_before = np.concatenate([[0], np.cumsum(keep)])  # name tokens before each token
    indptr = kept_before[words.indptr - first].astype(words.indptr.dtype)
    data = words.data[first:last][keep]
    if scale != 1.0:
        data = np.rint(data * float(scale)).astype(np.int64)
    out = sp.csr_array((data, words.indices[first:last][keep], indptr), shape=words.shape)
    out.sort_indices()  # (a no-op when the words' indices are sorted, as a canonical CSR's are)
    return out


def place_token_counts(words: sp.csr_array, homes: np.ndarray, concepts: np.ndarray, switches: np.ndarray,
                       n_homes: int, n_concepts: int, token_weight: float = 1.0) -> np.ndarray:
    """Place tokens per home, concept and word, with their counts c_ti times ``token_weight``
    (:attr:`WordChannels.token_weight`) (E, L, V): the place channel's part of a label swap's ratio,
    weighed as the concept's likelihood weighs them."""
    out = np.zeros((n_homes, n_concepts, words.shape[1]), dtype=np.float64)
    rows, cols, counts = tokens(words)
    is_place = switches == PLACE
    r = rows[is_place]
    np.add.at(out, (homes[r], concepts[r], cols[is_place]), counts[is_place] * float(token_weight))
    return out


def lambda_grid(points: int = LAMBDA_GRID) -> np.ndarray:
    """The shares (λ_place, λ_background) on a grid of ``points`` steps: (points − 1, 2), the interior
    points i/points, rows summing to 1."""
    i = np.arange(1, points, dtype=np.float64) / points
    return np.column_stack([i, 1.0 - i])


def lambda_log_posterior(by_word: np.ndarray, log_evidence: np.ndarray, grid: np.ndarray) -> np.ndarray:
    """log p(λ | z) up to a constant at every grid point (uniform prior): (G,).

    Only the tokens that are not names depend on λ: Σ_c n_c log λ_c − Σ_k m_k log Σ_c λ_c e_{k,c} over
    c ∈ {place, background}, n_c the tokens in channel c, m_k the place and background tokens of
    word k."""
    rest = by_word[:, 1:].astype(np.float64)  # (V, 2)
    n = rest.sum(axis=0)
    m = rest.sum(axis=1)
    log_grid = np.log(grid)
    used = m > 0
    norm = logsumexp(log_grid[:, None, :] + log_evidence[None, used, 1:], axis=2)  # (G, V_used)
    return log_grid @ n - norm @ m[used]


def sample_channels(counts: ChannelCounts, channels: WordChannels, rng: np.random.Generator,
                    alpha_place: float = ALPHA_PLACE,
                    alpha_background: float = ALPHA_BACKGROUND) -> WordChannels:
    """ψ ~ Dir(α^p + place counts), β ~ Dir(α^b + background counts), λ | z on the grid. With the
    home level (:mod:`spco.model.home_place`) ``counts.place`` holds the homes' CRT tables, and the
    result is the shared part alone (no ψ_{e,l}: each home draws its own)."""
    grid = lambda_grid()
    log_post = lambda_log_posterior(counts.by_word, channels.log_evidence, grid)
    p = np.exp(log_post - log_post.max())
    choice = rng.choice(grid.shape[0], p=p / p.sum())
    return replace(channels, fresh=False, log_place_home=None,
                   log_place=log_dirichlet(alpha_place + counts.place.astype(np.float64), rng),
                   log_background=log_dirichlet(alpha_background + counts.background.astype(np.float64), rng),
                   log_shares=np.concatenate([[0.0], np.log(grid[choice])]))


def place_mean(counts: ChannelCounts, alpha_place: float = ALPHA_PLACE) -> np.ndarray:
    """(L, V) log E[ψ | place counts]: the mean of ψ's conditional Dir(α^p + place counts)
    (:func:`sample_channels` draws from it); a concept with no place token gets 1/V."""
    pseudo = alpha_place + np.asarray(counts.place, dtype=np.float64)
    return np.log(pseudo) - np.log(pseudo.sum(axis=-1, keepdims=True))


def channel_parameters(channels: WordChannels,
                       log_place_mean: np.ndarray | None = None) -> dict[str, np.ndarray]:
    """The channels as fields of :class:`~spco.model.parameters.ConceptParameters`: the place words ψ
    (L, V) and the switch's prior (V, 3), as probabilities. ``log_place_mean``: log E[ψ | the last
    sweep's place tokens] (:func:`place_mean`), exported instead of the draw ``channels.log_place``
    when given (``None``: the draw)."""
    log_place = channels.log_place if log_place_mean is None else log_place_mean
    return {"place_word_probabilities": np.exp(log_place),
            "word_channel_prior": np.exp(channels.log_prior())}


def name_log_probabilities(log_theta_w: np.ndarray) -> np.ndarray:
    """log p(name k | concept): the names channel θ^w, rows normalised (…, V).

    The one function prediction calls to score a word as a place's name: with the channels the
    words of the other two channels are not in θ^w (it counts name tokens only), so θ^w itself is
    the names' distribution."""
    log_theta_w = np.asarray(log_theta_w, dtype=np.float64)
    if log_theta_w.shape[-1] == 0:
        return log_theta_w
    return log_theta_w - logsumexp(log_theta_w, axis=-1, keepdims=True)


#: a of :func:`place_names`: a token counts as a name said at its place by its switch's posterior name
#: probability times its prior name probability (the linguistic evidence) to this power (docs/model.md,
#: "Names said at a concept's places"; chosen on development data: benchmarks/README.md, "Natural
#: speech: the evidence of a name said at a place").
NAME_EVIDENCE_POWER = 0.5


def place_names(words: sp.csr_array, homes: np.ndarray, concepts: np.ndarray, regions: np.ndarray,
                log_theta_w: np.ndarray, channels: WordChannels, n_concepts: int,
                rows: np.ndarray | None = None, stand_ins: np.ndarray | None = None,
                evidence_power: float = NAME_EVIDENCE_POWER) -> np.ndarray:
    """(L, V) the names said by each concept's samples and at their places: for every sample t (of
    ``rows``, default all), its own name tokens plus the name tokens per sample of its region — the
    names its region's samples say, whatever their concept, summed over the region's samples and
    divided by their number — added to the row of t's concept. A token of word k counts as a name by
    its switch's posterior name probability given its sample's concept (:func:`switch_probabilities`,
    each token once) times the word's prior name probability p_0(name | k)^a (the linguistic
    evidence, :meth:`WordChannels.log_prior`; a = ``evidence_power``): the posterior is read against
    the concept's own names θ^w, which its tokens built — in a concept of object talk an object drawn
    as a name ("couch", "chair") is the concept's one name and its posterior is near 1 whatever the
    word is — while the evidence is what the word's kind and frames say about any place; the
    factor lowers objects more than names (development natural speech, 3LDK_9, seed 0: "living room"
    p_0 0.70, × 0.84; "kitchen" 0.55, × 0.74; "chair" 0.07, × 0.27; "sofa" 0.04, × 0.20). With
    ``stand_ins``, an object said at the place (a token drawn as a place word) also counts for the
    name it stands in for, by its place-word probability times that name's prior name probability
    (the linguistic evidence, :meth:`WordChannels.log_prior`): "by the dining table" counts for
    "dining room" (people name the dining area by its table far more often than by its name).

    A concept whose people named only what is there ("near the refrigerator") shares its regions
    with the concept of the people who named the room: its row holds the room's names, in
    proportion to how often they are said there, where its own names channel θ^w holds the few
    object tokens drawn as names; a concept whose people named the room holds its own names twice,
    as its samples' and as its places' (docs/model.md, "Names said at a concept's places"). A region
    is a (home, region) pair of ``homes`` and ``regions``.

    Parameters
    ----------
    words: (N, V) the samples' word counts; homes, concepts, regions: (N,) each sample's home, concept
        and region (the region's index within its home).
    log_theta_w, channels: the names channel (E, L, V) and the word channels the switches are drawn with.
    n_concepts: L.
    rows: the samples that count (their regions' names and their concepts' rows); default every one.
    stand_ins: (V,) int, the column of the name each word stands in for, −1 for none
        (:func:`spco.model.unheard.stand_in_columns`); ``None``: none.
    evidence_power: a ≥ 0, the power of the prior name probability on a token's name probability
        (default :data:`NAME_EVIDENCE_POWER`; 0: the posterior alone).

    Returns
    -------
    (L, V) float64, expected name tokens: the concept's own plus, for each of its samples, its
    region's per sample.
    """
    if not (np.isfinite(evidence_power) and evidence_power >= 0):
        raise ValueError(f"evidence_power must be a number >= 0, got {evidence_power!r}")
    n, n_words = words.shape
    out = np.zeros((n_concepts, n_words))
    selected = np.ones(n, dtype=bool) if rows is None else np.isin(np.arange(n), np.asarray(rows, np.int64))
    if not words.nnz or not selected.any():
        return out
    token_row, cols, _ = tokens(words)
    p = switch_probabilities(words, homes, concepts, log_theta_w, channels)
    prior_name = channels.name_prior()
    named = p[:, NAME] * prior_name[cols] ** float(evidence_power)
    if stand_ins is not None:
        stand_ins = np.asarray(stand_ins, dtype=np.int64)
        if stand_ins.shape != (n_words,):
            raise ValueError(f"stand_ins must have shape ({n_words},), got {stand_ins.shape}")
        objects = np.flatnonzero(stand_ins[cols] >= 0)  # the objects' tokens, counted for their names
        token_row = np.concatenate([token_row, token_row[objects]])
        named = np.concatenate([named, p[objects, PLACE] * prior_name[stand_ins[cols[objects]]]])
        cols = np.concatenate([cols, stand_ins[cols[objects]]])
    keep = selected[token_row]
    homes = np.asarray(homes, dtype=np.int64)
    regions = np.asarray(regions, dtype=np.int64)
    _, place = np.unique(np.stack([homes, regions], axis=1), axis=0, return_inverse=True)
    place = place.reshape(-1)
    n_places = int(place.max()) + 1
    by_place = np.zeros((n_places, n_words))
    np.add.at(by_place, (place[token_row[keep]], cols[keep]), named[keep])
    size = np.bincount(place[selected], minlength=n_places).astype(np.float64)
    per_sample = by_place / np.maximum(size, 1.0)[:, None]
    concepts = np.asarray(concepts, dtype=np.int64)
    counted = np.zeros((n_concepts, n_places))
    np.add.at(counted, (concepts[selected], place[selected]), 1.0)
    out = counted @ per_sample
    np.add.at(out, (concepts[token_row[keep]], cols[keep]), named[keep])  # the samples' own names
    return out


def concept_name_tokens(words: sp.csr_array, homes: np.ndarray, concepts: np.ndarray, log_theta_w: np.ndarray,
                        channels: WordChannels, n_concepts: int) -> np.ndarray:
    """(L, V) the expected name tokens of each concept and word over the samples of ``words``: each
    token's switch probability of being a name given its sample's concept (:func:`switch_probabilities`,
    each token once), summed by concept."""
    out = np.zeros((n_concepts, words.shape[1]))
    if not words.nnz:
        return out
    p = switch_probabilities(words, homes, concepts, log_theta_w, channels)
    token_row, cols, _ = tokens(words)
    np.add.at(out, (np.asarray(concepts, dtype=np.int64)[token_row], cols), p[:, NAME])
    return out


def warm_start_settings(settings, hyper, evidence: tuple[np.ndarray, np.ndarray], vocabulary,
                        word_increment: int, lexicon: object | None = None):
    """``settings`` (:class:`~spco.model.state.SamplerSettings`) for the warm start of a fit that learns
    its words with the channels, from the channels' ``evidence`` (ν, a) of ``vocabulary``'s words, as
    ``hyper`` (:class:`~spco.model.hyperparameters.TransferHyperparameters`) asks by ``warm_start``:

    - ``"things"`` (the default): the words the evidence calls objects (name prior p(name | k),
      :meth:`WordChannels.name_prior`, below :data:`spco.model.unheard.OBJECT_BELOW`) whose head word
      WordNet calls a thing (:meth:`spco.data.lexicon.Lexicon.is_thing`: "fridge", "kettle", "towel";
      not a word WordNet does not know, "dormitorio", nor "dining", nor a thing WordNet also calls by a
      room's word, "tub" and "bathtub" — bathtub.n.01 is also "bath") mark no place at the start
      (``start_not_names``): a sample that says only such words takes the place of its region, and such
      a word said in two rooms does not join their names as synonyms
      (:func:`spco.model.synonyms.same_place_names`). The token weight stays as given.
    - ``"words"``: the start's independent sweeps weigh a word token as the chain does (``word_weight``
      W^w / S^w, :func:`token_weight`; :func:`spco.model.shard_init.initialise` then holds a partly
      taught home's own names in place through them and weighs its words S^w), and the objects that
      cannot denote a room (no noun sense a room or an area of a building in WordNet,
      :meth:`spco.data.lexicon.Lexicon.room_share`: "table", "sofa", "bed"; "toilet" and "bathroom"
      can) mark no place.
    - ``"names"``: the settings as they are.

    ``lexicon``: a :class:`~spco.data.lexicon.Lexicon` (default :func:`spco.data.lexicon.lexicon`);
    without WordNet no word is left out."""
    from spco.data.lexicon import lexicon as default_lexicon
    from spco.model.unheard import OBJECT_BELOW

    start = getattr(hyper, "warm_start", "names")
    if start not in ("words", "things"):
        return settings
    n_concepts, evidence_weight, word_counts = hyper.n_concepts, hyper.evidence_weight, hyper.word_counts
    rooms = default_lexicon() if lexicon is None else lexicon
    objects: tuple[int, ...] = ()
    if rooms is not None and vocabulary is not None and len(vocabulary):
        prior = WordChannels.initial(evidence[0], n_concepts, evidence_weight, evidence[1]).name_prior()
        words = list(vocabulary.words)
        # a term by its head word ("hanako's bed": "bed")
        if start == "things":
            objects = tuple(int(k) for k in np.flatnonzero(prior < OBJECT_BELOW)
                            if rooms.is_thing(words[k].split()[-1]))  # type: ignore[attr-defined]
        else:
            objects = tuple(int(k) for k in np.flatnonzero(prior < OBJECT_BELOW)
                            if not rooms.room_share(words[k].split()[-1]) > 0.0)  # type: ignore[attr-defined]
    if start == "things":
        return replace(settings, start_not_names=objects)
    return replace(settings, word_weight=token_weight(word_counts, word_increment), start_not_names=objects)
