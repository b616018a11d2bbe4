"""Split or merge? The cut sampler's own account of a nameless concept beside a named one (issue 28, class a
of ``benchmarks/speech_errors.py``; branch split16): a diagnosis of the development fits of
``benchmarks/nameless_answers.py``.

For each case of ``nameless_answers.py``'s table (a seed, a home left out, a place, and the nameless concept A
its views are drawn to) the named concept B of the same kind of place is the concept, other than A, that holds
the most of the other homes' taught samples of that place whose sentence says one of its accepted names. The
*merge* moves every sample of A (in every home) to B, regions kept; the *split* is the fit's end-of-chain
state. Both are scored, term by term, by the log of what the cut sampler's assignment step weighs a sample by
(``spco.model.assignments.conditional_log_joint``: log G_{e,C} + log π_{e,C,R} + log N(x | R) + ω_t log
Mult(v | θ^v_{e,C}) + W^w Σ_i n_ti log Σ_c p(c | k) f_c(k | C)), in two accounts:

- ``conditional``: the chain's parameters at the end of the chain, fixed. The difference merge − split is the
  sum over the moved samples of the assignment step's log-odds of B against A: what the next sweep sees.
- ``refit``: each state's concept parameters set to the cut sampler's conditional means given its own
  assignments, as its learning steps count (θ^v from every visual count, θ^w from S^w per name token, ψ from
  each place token once, the chain's switches), with G_e and π integrated out (Dirichlet-multinomial, G_0
  and β/K the priors), every sample scored. The shared φ^v, φ^w, G_0, β, λ and the region Gaussians are the
  chain's. This is the merge's own equilibrium of the cut's alternation (assign given parameters, learn
  given assignments), so it is the comparison a merge move with the parameters redrawn would see. (G_0 is
  the chain's: the emptied A keeps its share, which costs the merge a little. ψ, θ^v and θ^w are plug-in
  means, with no Occam factor, which favours the split.)

Then the place channel alone with ψ integrated out (at tokens once, as ψ learns, and at W^w, as the
assignment weighs a token; and, as a what-if, one ψ per home and concept), the samples of A and B by home,
and the place words of A and B.

The cut sampler has no joint distribution (docs/model.md, "The model the sampler targets"), so no account
is *the* posterior ratio; these two are the sampler's own conditionals. The word term is split exactly by
channel with each token's switch posterior r: log Σ_c a_c = Σ_c r_c log f_c + Σ_c r_c (log p(c | k) − log
r_c): names (r_name log θ^w), place (r_place log ψ), background (r_bg log β), switches (the rest), each
times the token's weight W^w n_ti.

Development seeds only (0–99); seeds 0–4 were looked at on nameless16. Run::

    python benchmarks/nameless_answers.py --seeds 0 1 2 3 4 --sweeps 60 --leave-one-out \\
        --cache $FITS --json nameless.json
    python benchmarks/split_evidence.py --nameless nameless.json --sweeps 60 --cache $FITS --json split.json
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np
import scipy.sparse as sp
from scipy.special import gammaln, logsumexp

sys.path.insert(0, str(Path(__file__).resolve().parent))

#: Rounds of switch posteriors and word parameters in the refit account (:func:`refit_parameters`).
REFIT_ROUNDS = 3

#: The terms, in the order of the table.
TERMS = ("concept prior", "regions", "positions", "view", "names", "place", "background", "switches")

#: The word channels' terms (each token weighed W^w n_ti by the assignment).
WORD_TERMS = ("names", "place", "background", "switches")


def dirichlet_multinomial(counts: np.ndarray, alpha: np.ndarray) -> float:
    """Σ over rows of log ∫ Π_k p_k^{n_k} Dir(p | α) dp = log B(α + n) − log B(α) (one sequence, no
    multinomial coefficient); ``counts`` (..., K), ``alpha`` broadcast to it, entries with α = 0 and n = 0
    skipped."""
    counts = np.asarray(counts, dtype=np.float64)
    alpha = np.broadcast_to(np.asarray(alpha, dtype=np.float64), counts.shape)
    used = alpha > 0
    a = np.where(used, alpha, 1.0)
    inner = np.where(used, gammaln(a + counts) - gammaln(a), 0.0).sum(axis=-1)
    total = np.where(used, alpha, 0.0).sum(axis=-1)
    return float((inner - gammaln(total + counts.sum(axis=-1)) + gammaln(total)).sum())


def word_terms(words: sp.csr_array, homes: np.ndarray, concepts: np.ndarray, log_theta_w: np.ndarray,
               log_place: np.ndarray, log_background: np.ndarray, log_prior: np.ndarray,
               token_weight: float) -> dict[str, np.ndarray]:
    """(N,) per sample: names, place, background and switches, summing to the cut sampler's word
    log-likelihood at ``concepts`` (:func:`spco.model.word_channels.mixture_log_likelihood`): each token's
    log Σ_c p(c | k) f_c(k | l) times its counts times ``token_weight``, split by its switch posterior r."""
    first, last = int(words.indptr[0]), int(words.indptr[-1])
    rows = np.repeat(np.arange(words.shape[0]), np.diff(words.indptr))
    cols = words.indices[first:last]
    scale = words.data[first:last].astype(np.float64) * float(token_weight)
    e, c = homes[rows], concepts[rows]
    f = np.column_stack([log_theta_w[e, c, cols], _place_at(log_place, e, c, cols), log_background[cols]])
    prior = log_prior[cols]
    logits = prior + f
    log_r = logits - logsumexp(logits, axis=1, keepdims=True)
    r = np.exp(log_r)
    with np.errstate(invalid="ignore"):
        parts = {"names": r[:, 0] * f[:, 0], "place": r[:, 1] * f[:, 1], "background": r[:, 2] * f[:, 2],
                 "switches": np.where(r > 0, r * (prior - log_r), 0.0).sum(axis=1)}
    n = words.shape[0]
    return {k: np.bincount(rows, weights=scale * np.nan_to_num(v), minlength=n) for k, v in parts.items()}


def _place_at(log_place: np.ndarray, homes: np.ndarray, concepts: np.ndarray, cols: np.ndarray) -> np.ndarray:
    """log ψ of each token: ψ_l (L, V), or with the place channel's home level ψ_{e,l} (E, L, V)."""
    if log_place.ndim == 3:
        return log_place[homes, concepts, cols]
    return log_place[concepts, cols]


def view_term(visual: sp.csr_array, homes: np.ndarray, concepts: np.ndarray, log_theta_v: np.ndarray,
              weights: np.ndarray | None) -> np.ndarray:
    """(N,) ω_t Σ_d v_td log θ^v_{e,C_t,d} (the multinomial coefficient left out, as the sampler does)."""
    from spco.model.observations import HierarchicalMultinomial

    n_concepts = log_theta_v.shape[1]
    out = np.zeros(visual.shape[0])
    for ell in range(n_concepts):  # only each sample's own concept
        rows = np.flatnonzero(concepts == ell)
        if rows.size:
            ll = HierarchicalMultinomial.log_likelihood(sp.csr_array(visual[rows]), homes[rows],
                                                        log_theta_v[:, ell:ell + 1])
            out[rows] = ll[:, 0]
    return out if weights is None else out * weights


def terms(model, concepts: np.ndarray, params: dict, integrated: bool) -> dict[str, float]:
    """The terms of the cut sampler's conditional log joint at ``concepts`` (regions and switches the
    chain's), with the concept parameters ``params`` (log_theta_v, log_theta_w, log_place, log_g, log_pi);
    ``integrated``: G_e and π integrated out instead of read from ``params``."""
    from spco.model.assignments import view_weights
    from spco.model.observations import GaussianRegions

    data, state, hyper, settings = model.data_, model.state_, model.hyperparameters_, model.settings_
    homes, regions = data.homes, state.regions
    E, L, K = data.n_homes, state.log_g.shape[1], state.log_pi.shape[2]
    out: dict[str, float] = {}
    if integrated:
        n = np.zeros((E, L))
        np.add.at(n, (homes, concepts), 1.0)
        out["concept prior"] = dirichlet_multinomial(n, hyper.gamma * np.exp(state.log_g0)[None, :])
        m = np.zeros((E, L, K))
        np.add.at(m, (homes, concepts, regions), 1.0)
        out["regions"] = dirichlet_multinomial(m, np.full(K, hyper.beta / K))
    else:
        out["concept prior"] = float(params["log_g"][homes, concepts].sum())
        out["regions"] = float(params["log_pi"][homes, concepts, regions].sum())
    region_ll = GaussianRegions.log_likelihood(data.positions, homes, state.means, state.covariances)
    out["positions"] = float(region_ll[np.arange(data.n_samples), regions].sum())
    out["view"] = float(view_term(data.visual, homes, concepts, params["log_theta_v"],
                                  view_weights(data, settings.view_counts)).sum())
    channels = state.channels
    words = word_terms(data.words, homes, concepts, params["log_theta_w"], params["log_place"],
                       channels.log_background, channels.log_prior(), channels.token_weight)
    out.update({k: float(v.sum()) for k, v in words.items()})
    return out


def chain_parameters(model) -> dict:
    """The end-of-chain state's concept parameters."""
    state = model.state_
    return {"log_theta_v": state.log_theta_v, "log_theta_w": state.log_theta_w,
            "log_place": state.channels.token_place(), "log_g": state.log_g, "log_pi": state.log_pi}


def refit_parameters(model, concepts: np.ndarray, rounds: int = REFIT_ROUNDS) -> dict:
    """The cut sampler's conditional means of the concept parameters given ``concepts`` (regions the
    chain's): θ^v_{e,l} = (δ^v φ^v_l + n^v_{e,l}) / (δ^v + N^v_{e,l}) with every visual count; θ^w likewise
    with δ^w, φ^w and S^w per expected name token; ψ_l with α^p and each expected place token once. The
    kept fit holds no switches, so the tokens' channels are their switch posteriors (Rao-Blackwellised):
    first at the chain's θ^w and ψ, then ``rounds`` − 1 times at the parameters they gave (the cut's
    alternation of learning and switching, to its mean). With the place channel's home level
    (``place_channel="home"``) ψ_{e,l} = (δ^p ψ_l + its home's expected place tokens, once) / Σ around the
    chain's ψ_l (ψ_l itself not re-learnt), and the chain's account reads the chain's ψ_{e,l}."""
    from spco.model.observations import HierarchicalMultinomial
    from spco.model.word_channels import ALPHA_PLACE

    data, state, hyper = model.data_, model.state_, model.hyperparameters_
    E, L = data.n_homes, state.log_g.shape[1]
    channels = state.channels
    words = data.words
    first, last = int(words.indptr[0]), int(words.indptr[-1])
    rows = np.repeat(np.arange(words.shape[0]), np.diff(words.indptr))
    cols, counts = words.indices[first:last], words.data[first:last].astype(np.float64)
    occurrences = counts / float(model.word_increment_)

    def mean(n: np.ndarray, log_phi: np.ndarray, delta: float) -> np.ndarray:
        a = delta * np.exp(log_phi)[None] + n
        with np.errstate(divide="ignore"):
            return np.log(a) - np.log(a.sum(axis=-1, keepdims=True))

    n_v = HierarchicalMultinomial.statistics(data.visual, data.homes, concepts, E, L).astype(np.float64)
    params = {"log_theta_v": mean(n_v, state.log_phi_v, hyper.delta_visual),
              "log_theta_w": state.log_theta_w, "log_place": channels.token_place()}
    home_level = getattr(hyper, "place_channel", "shared") == "home"
    e, c = data.homes[rows], concepts[rows]
    for _ in range(rounds):
        f = np.column_stack([params["log_theta_w"][e, c, cols], _place_at(params["log_place"], e, c, cols),
                             channels.log_background[cols]])
        logits = channels.log_prior()[cols] + f
        r = np.exp(logits - logsumexp(logits, axis=1, keepdims=True))
        u = np.zeros((E, L, words.shape[1]))
        np.add.at(u, (e, c, cols), counts * r[:, 0])
        place = np.full((L, words.shape[1]), ALPHA_PLACE)
        np.add.at(place, (c, cols), occurrences * r[:, 1])
        params["log_theta_w"] = mean(u, state.log_phi_w, hyper.delta_word)
        params["log_place"] = np.log(place) - np.log(place.sum(axis=1, keepdims=True))
        if home_level:  # ψ_{e,l}'s conditional mean around the chain's ψ_l (δ^p, each token once)
            own = np.zeros((E, L, words.shape[1]))
            np.add.at(own, (e, c, cols), occurrences * r[:, 1])
            params["log_place"] = mean(own, channels.log_place, hyper.delta_place)
    params["place_counts"] = place - ALPHA_PLACE
    by_home = np.zeros((E, L, words.shape[1]))
    np.add.at(by_home, (e, c, cols), occurrences * r[:, 1])
    params["place_counts_home"] = by_home.reshape(E * L, -1)
    return params


def place_evidence(place_counts: np.ndarray, scale: float) -> float:
    """Σ_l log ∫ Π_k ψ_{l,k}^{s n_{l,k}} Dir(ψ_l | α^p) dψ_l: the place channel with ψ integrated out, each
    expected place token counted ``scale`` times (1: as ψ's conditional counts it; W^w: as the assignment
    weighs it)."""
    from spco.model.word_channels import ALPHA_PLACE

    return dirichlet_multinomial(scale * place_counts, np.full(place_counts.shape[1], ALPHA_PLACE))


def named_concept(model, corpus, e: int, place: str, nameless: int, accepted: dict) -> tuple[int, int]:
    """B: the concept other than ``nameless`` holding the most of the other homes' taught samples of
    ``place`` whose sentence says an accepted name of it; with that number."""
    from speech_errors import names_of

    from spco.data.language import normalize_name

    names = names_of(place, accepted)
    votes: dict[int, int] = {}
    for h, env in enumerate(corpus):
        if h == e:
            continue
        labels = [lab for lab, test in zip(env.ground_truth.labels, env.is_test, strict=True) if not test]
        for c, label, sentence in zip(model.concepts_[h], labels, env.training_data().sentences, strict=True):
            if (c != nameless and sentence is not None and label is not None
                    and normalize_name(label) == place and names & set(corpus.vocabulary.tokenize(sentence))):
                votes[int(c)] = votes.get(int(c), 0) + 1
    if not votes:
        return -1, 0
    best = max(votes, key=lambda c: (votes[c], -c))
    return best, votes[best]


def compare(model, nameless: int, named: int) -> dict:
    """Merge − split by term, in both accounts, and the samples moved (all homes; the new home's). The
    split's terms with the chain's parameters are checked against the sampler's own conditional log joint
    (:func:`spco.model.gibbs.log_joint`)."""
    from spco.model.gibbs import log_joint

    concepts = np.asarray(model.state_.concepts)
    merged = np.where(concepts == nameless, named, concepts)
    moved = concepts == nameless
    e = model.data_.n_homes - 1
    out = {"moved": int(moved.sum()), "moved_here": int((moved & (model.data_.homes == e)).sum()),
           "in_named": int((concepts == named).sum())}
    chain = chain_parameters(model)
    split = terms(model, concepts, chain, False)
    check = log_joint(model.data_, model.state_, model.hyperparameters_, model.settings_)
    if not np.isclose(sum(split.values()), check, rtol=1e-9, atol=1e-6 * abs(check)):
        raise RuntimeError(f"the terms sum to {sum(split.values())}, the sampler's log joint is {check}")
    split, merge = terms(model, concepts, chain, False), terms(model, merged, chain, False)
    out["conditional"] = {k: merge[k] - split[k] for k in TERMS}
    refit_split, refit_merge = refit_parameters(model, concepts), refit_parameters(model, merged)
    split = terms(model, concepts, refit_split, True)
    merge = terms(model, merged, refit_merge, True)
    out["refit"] = {k: merge[k] - split[k] for k in TERMS}
    weight = float(model.word_increment_) * float(model.state_.channels.token_weight)  # W^w
    out["place_integrated"] = {
        f"x{scale:g}": place_evidence(refit_merge["place_counts"], scale)
        - place_evidence(refit_split["place_counts"], scale) for scale in (1.0, weight)}
    out["place_by_home"] = {  # a what-if: ψ per home and concept (each Dir(α^p)), not per concept
        f"x{scale:g}": place_evidence(refit_merge["place_counts_home"], scale)
        - place_evidence(refit_split["place_counts_home"], scale) for scale in (1.0, weight)}
    out["place_plugin_once"] = out["refit"]["place"] / weight
    out["refit_words_once"] = sum(v / weight if k in WORD_TERMS else v for k, v in out["refit"].items())
    counts = refit_split["place_counts"]
    for key, concept in (("words_nameless", nameless), ("words_named", named)):  # its place words
        top = np.argsort(-counts[concept], kind="stable")[:5]
        out[key] = [(model.vocabulary_.words[k], round(float(counts[concept, k]), 1)) for k in top]
    homes = model.data_.homes
    out["homes_nameless"] = np.bincount(homes[concepts == nameless], minlength=model.data_.n_homes).tolist()
    out["homes_named"] = np.bincount(homes[concepts == named], minlength=model.data_.n_homes).tolist()
    return out


def _print(rows: list[dict]) -> None:
    """The two accounts' tables, then the place channel with ψ integrated and the homes of A and B."""
    for account in ("conditional", "refit"):
        print(f"\n{account}: merge − split, nats (positive: the merge wins)\n")
        once = account == "refit"  # and the total with each token once (the word terms over W^w)
        print("| seed | home | place | A → B (B's named samples) | moved (here) | " + " | ".join(TERMS)
              + " | total |" + (" words once |" if once else ""))
        print("|---|---|---|---|---:|" + "---:|" * (len(TERMS) + 1 + once))
        for r in rows:
            d = r[account]
            print(f"| {r['seed']} | {r['home']} | {r['place']} | {r['nameless']} → {r['named']} "
                  f"({r['named_votes']}) | {r['moved']} ({r['moved_here']}) | "
                  + " | ".join(f"{d[k]:+.0f}" for k in TERMS) + f" | {sum(d.values()):+.0f} |"
                  + (f" {r['refit_words_once']:+.0f} |" if once else ""))
    print("\nplace channel, merge − split: plug-in at tokens once (refit / W^w), ψ integrated at tokens once "
          "and at W^w; samples of A and B by home (the new home last)\n")
    print("| seed | home | place | plug-in once | integrated once | integrated W^w | per home once | "
          "per home W^w | A's samples by home | B's samples by home |")
    print("|---|---|---|---:|---:|---:|---:|---:|---|---|")
    for r in rows:
        once, heavy = r["place_integrated"].values()
        home_once, home_heavy = r["place_by_home"].values()
        print(f"| {r['seed']} | {r['home']} | {r['place']} | {r['place_plugin_once']:+.1f} | {once:+.1f} | "
              f"{heavy:+.0f} | {home_once:+.1f} | {home_heavy:+.0f} | "
              f"{' '.join(map(str, r['homes_nameless']))} | "
              f"{' '.join(map(str, r['homes_named']))} |")
    print("\nplace words (expected place tokens, each once) of A and of B, the split's refit\n")
    print("| seed | home | place | A | B |\n|---|---|---|---|---|")
    for r in rows:
        a, b = (", ".join(f"{w} {n:g}" for w, n in r[k]) for k in ("words_nameless", "words_named"))
        print(f"| {r['seed']} | {r['home']} | {r['place']} | {a} | {b} |")


def main() -> None:
    """Read the fits of ``nameless_answers.py``'s cases, compare split and merge, print, write ``--json``."""
    from free_speech import read_names
    from natural_speech import configurations, fit_arguments, fitted
    from split_seeds import refuse_other_seeds

    from spco.data import Corpus

    parser = fit_arguments(argparse.ArgumentParser(description=__doc__.splitlines()[0]))
    parser.add_argument("--nameless", type=Path, required=True, help="nameless_answers.py's --json")
    parser.add_argument("--json", type=Path, default=None)
    args = parser.parse_args()
    cases = sorted({(r["seed"], r["home"], r["place"], r["concept"])
                    for r in json.loads(args.nameless.read_text(encoding="utf-8"))},
                   key=lambda c: (c[0], c[1], c[2], c[3]))
    refuse_other_seeds(parser, [s for s, *_ in cases])
    accepted = read_names(args.accepted)
    _, configs = configurations(args.sigverse, accepted, leave_one_out=True)
    labels = [c[0] for c in configs]
    rows = []
    for seed, home, place, nameless in cases:
        label, homes, env = next(c for c in configs if c[0].split()[0] == home)
        corpus = Corpus([*homes, env])
        model = fitted(corpus, seed, label, labels, settings=args.set, sweeps=args.sweeps, cache=args.cache)
        e = len(corpus) - 1
        named, votes = named_concept(model, corpus, e, place, nameless, accepted)
        row = {"seed": seed, "home": home, "place": place, "nameless": nameless, "named": named,
               "named_votes": votes}
        if named >= 0:
            row.update(compare(model, nameless, named))
        rows.append(row)
        print(f"seed {seed} {home} {place}: {row.get('refit')}", flush=True)
    _print([r for r in rows if r["named"] >= 0])
    if args.json:
        args.json.write_text(json.dumps(rows, indent=0), encoding="utf-8")


if __name__ == "__main__":
    main()
