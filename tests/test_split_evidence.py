"""``benchmarks/split_evidence.py`` (split or merge, by the cut sampler's own terms) against brute force on
tiny problems: the integrated Dirichlet terms against numerical integration, the word channels' split by
term against the enumerated switches, and the conditional account against the assignment step's log-odds."""

from __future__ import annotations

import itertools
import sys
from pathlib import Path

import numpy as np
import pytest
from conftest import csr, random_word_channels
from scipy import integrate
from scipy.special import logsumexp

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "benchmarks"))
from split_evidence import TERMS, compare, dirichlet_multinomial, place_evidence, word_terms


def test_dirichlet_multinomial_is_the_integral() -> None:
    """log ∫ Π p^n Dir(p | α) dp, by quadrature on the 2- and 3-simplex (real counts, as the weighted
    tokens are), summed over rows."""
    alpha, n = np.array([0.7, 2.5]), np.array([3.0, 1.5])

    def kernel(p: float, counts: np.ndarray) -> float:
        return p ** (alpha[0] - 1 + counts[0]) * (1 - p) ** (alpha[1] - 1 + counts[1])

    beta = integrate.quad(kernel, 0, 1, args=(n,))[0] / integrate.quad(kernel, 0, 1, args=(np.zeros(2),))[0]
    assert dirichlet_multinomial(n, alpha) == pytest.approx(np.log(beta), rel=1e-7)
    a3, n3 = np.array([1.5, 2.0, 1.2]), np.array([2.0, 0.0, 1.0])

    def density(q: float, p: float, counts: np.ndarray) -> float:
        x = np.array([p, q, 1 - p - q])
        return float(np.prod(x ** (a3 - 1 + counts)))

    num = integrate.dblquad(lambda q, p: density(q, p, n3), 0, 1, 0, lambda p: 1 - p)[0]
    den = integrate.dblquad(lambda q, p: density(q, p, np.zeros(3)), 0, 1, 0, lambda p: 1 - p)[0]
    rows = np.stack([n3, np.zeros(3)])  # an empty row adds nothing
    assert dirichlet_multinomial(rows, a3) == pytest.approx(np.log(num / den), rel=1e-6)
    # a category with α = 0 and no count is left out
    assert dirichlet_multinomial(np.array([3.0, 1.5, 0.0]), np.array([0.7, 2.5, 0.0])) == pytest.approx(
        np.log(beta), rel=1e-7)
    assert place_evidence(np.zeros((2, 4)), 16.0) == 0.0


def test_word_terms_split_the_enumerated_switches() -> None:
    """Two homes, three concepts, five words: the four terms sum to the log of the sentence's probability
    with every switch enumerated (each token once), each term is the enumerated posterior's share, and at a
    token weight the sum is the sampler's own mixture likelihood."""
    from spco.model.word_channels import mixture_log_likelihood

    rng = np.random.default_rng(3)
    n_words, n_concepts = 5, 3
    channels = random_word_channels(rng, n_words, n_concepts)
    log_theta_w = np.log(rng.dirichlet(np.ones(n_words), size=(2, n_concepts)))
    dense = np.array([[1, 0, 1, 0, 1], [0, 2, 0, 0, 0], [0, 0, 0, 1, 1], [0, 0, 0, 0, 0]], dtype=float)
    words, homes, concepts = csr(dense), np.array([0, 0, 1, 1]), np.array([2, 0, 1, 1])
    prior = channels.log_prior()
    got = word_terms(words, homes, concepts, log_theta_w, channels.log_place, channels.log_background, prior,
                     1.0)
    for t in range(dense.shape[0]):
        tokens = [k for k in range(n_words) for _ in range(int(dense[t, k]))]
        e, c = homes[t], concepts[t]
        f = np.array([[log_theta_w[e, c, k], channels.log_place[c, k], channels.log_background[k]]
                      for k in tokens]).reshape(-1, 3)
        joint = {z: sum(prior[k, zi] + f[i, zi] for i, (k, zi) in enumerate(zip(tokens, z, strict=True)))
                 for z in itertools.product(range(3), repeat=len(tokens))}
        log_total = logsumexp(list(joint.values())) if tokens else 0.0
        assert sum(got[name][t] for name in ("names", "place", "background", "switches")) == pytest.approx(
            log_total, abs=1e-10)
        for channel, name in enumerate(("names", "place", "background")):  # the posterior's share of the term
            want = sum(np.exp(v - log_total)
                       * sum(f[i, channel] for i in range(len(tokens)) if z[i] == channel)
                       for z, v in joint.items())
            assert got[name][t] == pytest.approx(want, abs=1e-10)
    # the sampler's units: counts S^w per word times W^w / S^w
    scaled = csr(dense * 5000.0)
    got = word_terms(scaled, homes, concepts, log_theta_w, channels.log_place, channels.log_background, prior,
                     16 / 5000)
    mixture = mixture_log_likelihood(scaled, homes, log_theta_w,
                                     _with_weight(channels, 16 / 5000))[np.arange(4), concepts]
    assert sum(got[name] for name in ("names", "place", "background", "switches")) == pytest.approx(mixture,
                                                                                                   abs=1e-8)


def _with_weight(channels, weight: float):
    from dataclasses import replace

    return replace(channels, token_weight=weight)


@pytest.fixture(scope="module")
def small_fit(small_corpus):
    """A short fit of the synthetic corpus with the word channels (the default word model)."""
    from spco.model import SpCoTransfer

    return SpCoTransfer(n_iterations=4, random_state=0, prune_words=True).fit(small_corpus)


def test_the_conditional_account_is_the_assignment_log_odds(small_fit) -> None:
    """With the chain's parameters, merge − split is the sum over the moved samples of the assignment
    step's log-odds of B against A (regions kept); merging a concept into itself changes nothing."""
    from spco.model.assignments import concept_loglik

    model = small_fit
    data, state = model.data_, model.state_
    assert state.channels is not None
    used = np.unique(state.concepts)
    nameless, named = int(used[0]), int(used[1])
    out = compare(model, nameless, named)
    ll = concept_loglik(data, state, model.settings_.view_counts)
    moved = np.flatnonzero(state.concepts == nameless)
    h, r = data.homes[moved], state.regions[moved]
    odds = (state.log_g[h, named] - state.log_g[h, nameless] + state.log_pi[h, named, r]
            - state.log_pi[h, nameless, r] + ll[moved, named] - ll[moved, nameless])
    assert out["moved"] == moved.size > 0
    assert sum(out["conditional"].values()) == pytest.approx(float(odds.sum()), rel=1e-9, abs=1e-6)
    assert out["conditional"]["positions"] == 0.0 and out["refit"]["positions"] == 0.0
    same = compare(model, nameless, nameless)
    assert all(same[account][k] == pytest.approx(0.0, abs=1e-6) for account in ("conditional", "refit")
               for k in TERMS)
