"""The word prior in the units of the names' proportions: δ^w and α^w estimated from the homes.

The model's δ^w = 10^4 and α^w = 0.01 were set for the cut sampler, whose θ^w counts a name token
S^w = 5,000 times (``Corpus.word_increment``): there two tokens outweigh δ^w and a home's own names
win its θ^w. Under the power likelihood (``TransferHyperparameters.target="power"``) a token counts
W^w = 16 (``word_counts``): against δ^w = 10^4, θ^w_{e,l} stays at the concept's shared φ^w_l, and a
name said in one home only (Emma's room, the workshop) cannot become that home's name
(benchmarks/README.md, "Issue 29: the power target's priors in its own units"). A Dirichlet's
concentration says how proportions spread, which has no unit, so with
``word_prior="estimate"`` δ^w and α^w are estimated from the experienced homes' name tokens by the
method of moments of :mod:`spco.model.visual_prior`, each token a one-hot "view" of one draw:

- the name tokens of home e said at samples of concept l (the start's concepts) are a multinomial
  sample of θ^w_{e,l}: their proportions M_{e,l} have a sampling variance (1 − Σ_k M²_{e,l,k}) /
  (m − 1) (m tokens), and θ^w_{e,l} ~ Dir(δ^w φ^w_l) says Σ_k Var_e θ_{e,l,k} = Σ_k φ_{l,k}(1 −
  φ_{l,k}) / (δ^w + 1): δ̂^w from the homes' spread less the sampling spread, pooled over concepts;
- α̂^w from the concepts' mean proportions φ̂_l around the uniform over the vocabulary.

Where the homes name alike (template speech: every home's bedroom "bedroom"), the spread between homes
is within the tokens' sampling noise and the moments give no finite δ^w (the data say "as alike as
can be measured"). The given δ^w then stays, in the units θ^w counts a token in
(:func:`given_delta_word`): δ^w = 10^4 was set against S^w = 5,000 counts per token — "a home's own
two name tokens weigh as much as its concept's shared names" — and the power target's θ^w counts a
token W^w times, so the same statement is δ^w W^w / S^w (32 at W^w = 16); without it, a name said in
one home only (Emma's room, Max's room) could not become that home's name under the power target.

Which tokens are names is the model's latent switch; before the chain it is the switch's prior, the
linguistic evidence p(z = name | k) (:meth:`spco.model.word_channels.WordChannels.name_prior`, which
λ does not enter): each token enters the moments with that weight (an expected name token). Each
token is one draw here, whatever W^w: the spread of proportions between homes is what δ^w states.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from spco.model.state import PreparedData
from spco.model.visual_prior import estimate_visual_prior
from spco.model.word_channels import tokens

__all__ = ["estimate_word_prior", "given_delta_word", "home_name_moments"]


def home_name_moments(data: PreparedData, concepts: np.ndarray, n_concepts: int, name_prior: np.ndarray
                      ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Each home's name tokens by concept, each token (a stored entry of ``data.words``: one per
    distinct word of a sentence) weighed by ``name_prior`` (V,) of its word, p(z = name | k):
    (m (E, L) expected name tokens, S (E, L, V) the same by word, Q (E, L) = m: a token's proportions
    are one-hot, ||e_k||² = 1)."""
    E, V = data.n_homes, data.words.shape[1]
    words = sp.csr_array(data.words)
    prior = np.asarray(name_prior, dtype=np.float64)
    if prior.shape != (V,):
        raise ValueError(f"name_prior must have shape ({V},), got {prior.shape}")
    rows, cols, _ = tokens(words)
    weight = prior[cols]
    c = np.asarray(concepts, dtype=np.int64)[rows]
    e = np.asarray(data.homes, dtype=np.int64)[rows]
    s = np.zeros((E, n_concepts, V))
    np.add.at(s, (e, c, cols), weight)
    m = s.sum(axis=2)
    return m, s, m.copy()


def estimate_word_prior(m: np.ndarray, s: np.ndarray, q: np.ndarray) -> tuple[float | None, float | None]:
    """(δ̂^w, α̂^w) from every home's name moments of :func:`home_name_moments` (m (E, L), s (E, L, V),
    q (E, L)): :func:`spco.model.visual_prior.estimate_visual_prior` on the tokens as one-hot views
    (only concepts named in two homes or more, with two expected name tokens or more each, enter
    δ̂^w); either ``None`` when nothing estimates it."""
    return estimate_visual_prior(m, s, q)


def given_delta_word(delta_word: float, channels) -> float:
    """The given δ^w in the units θ^w counts a name token in: ``delta_word`` times
    :attr:`~spco.model.word_channels.WordChannels.token_weight` (W^w / S^w) when the chain targets the
    power likelihood (``channels.power``: θ^w counts a token W^w times, δ^w was set against its S^w
    counts), unchanged otherwise (the cut sampler's θ^w counts S^w)."""
    return float(delta_word) * (float(channels.token_weight) if channels.power else 1.0)
