"""Why the power target lumps a new home's places in natural speech (issue 29; branch power18): a
diagnosis of the cached fits of ``benchmarks/speech_errors.py --leave-one-out`` under ``--set target=power
visual_prior=estimate``. Development configurations and seeds only; it fits nothing but reads the fits.

For each fit, the new (untaught) home's labelled training samples in the chain's last state (the *lump*)
against the *rooms* state: each of its places moved to the concept that holds the most of the other homes'
training samples of that place (the place's concept in the experienced homes; regions kept). Only the new
home's samples move and they have no words, so the words, ψ, β, θ^w and the switches of the power target's
joint (docs/model.md, "The model the sampler targets") are the same in both states; what differs:

- ``concept prior``: G_e integrated out, Dirichlet-multinomial with γ G_0 (the chain's G_0);
- ``regions``: π_{e,l} integrated out, Dirichlet-multinomial with β/K;
- ``view``: θ^v_{e,l} ~ Dir(δ^v φ^v_l) integrated out (exact given φ^v: the views enter at ω_t, real counts),
  with φ^v the chain's (``view | φ chain``) and with φ^v integrated out too given the other homes' CRT tables
  (``view | φ integrated``: :class:`spco.model.phi_evidence.ConceptGrid`, as the φ^v-marginal block move
  weighs it; the mean over ``--tables`` table draws);
- ``conditional``: the chain's G_e, π, θ^v fixed (what the next sweep sees), the same three terms.

Then the concepts' make-up: for every concept the new home uses, the other homes' places in it; and the
adjusted Rand index of every experienced home's training samples against their places (do the experienced
homes' concepts follow rooms?), and of its place words' channel (how many of each concept's tokens go to ψ).

    python benchmarks/power_lump.py --cache C --seeds 0 --set target=power visual_prior=estimate --json J
"""

from __future__ import annotations

import argparse
import json
import sys
from collections import Counter
from pathlib import Path

import numpy as np
from scipy.special import gammaln
from sklearn.metrics import adjusted_rand_score

sys.path.insert(0, str(Path(__file__).resolve().parent))

from split_evidence import dirichlet_multinomial

TERMS = ("concept prior", "regions", "view | φ chain", "view | φ integrated")


def training_labels(env) -> np.ndarray:
    """The home's training samples' place labels (normalised; "None" for an unlabelled sample)."""
    from spco.data.language import normalize_name

    labels = [lab for lab, test in zip(env.ground_truth.labels, env.is_test, strict=True) if not test]
    return np.asarray([normalize_name(x) if x is not None else "None" for x in labels], dtype=object)


def rooms_state(model, corpus, e: int) -> tuple[np.ndarray, dict[str, int]]:
    """The rooms state: the chain's concepts with each of home e's places moved to the concept holding the
    most of the other homes' training samples of that place (a place no other home has keeps its samples'
    concepts); and that map."""
    concepts = np.asarray(model.state_.concepts).copy()
    votes: dict[str, Counter] = {}
    for h, env in enumerate(corpus):
        if h == e:
            continue
        for c, label in zip(model.concepts_[h], training_labels(env), strict=True):
            if label != "None":
                votes.setdefault(label, Counter())[int(c)] += 1
    home = np.flatnonzero(model.data_.homes == e)
    labels = training_labels(corpus[e])
    chosen = {}
    for place in sorted(set(labels.tolist()) - {"None"}):
        if place in votes:
            chosen[place] = votes[place].most_common(1)[0][0]
            concepts[home[labels == place]] = chosen[place]
    return concepts, chosen


def weighted_counts(model, concepts: np.ndarray) -> np.ndarray:
    """n^v (E, L, D): Σ ω_t v_t per home and concept, the power target's real counts."""
    from spco.model.assignments import view_weights
    from spco.model.observations import HierarchicalMultinomial

    data, L = model.data_, model.state_.log_g.shape[1]
    w = view_weights(data, model.settings_.view_counts)
    w = np.ones(data.n_samples) if w is None else w
    return HierarchicalMultinomial.weighted_statistics(data.visual, w, data.homes, concepts, data.n_homes, L)


def home_terms(model, concepts: np.ndarray, e: int, grids: dict | None) -> dict[str, float]:
    """Home e's integrated terms (G_e, π, θ^v integrated; φ^v the chain's, and integrated by ``grids``)."""
    data, state, hyper = model.data_, model.state_, model.hyperparameters_
    L, K = state.log_g.shape[1], state.log_pi.shape[2]
    rows = data.homes == e
    c, r = concepts[rows], state.regions[rows]
    n = np.bincount(c, minlength=L).astype(np.float64)
    out = {"concept prior": dirichlet_multinomial(n, hyper.gamma * np.exp(state.log_g0))}
    m = np.zeros((L, K))
    np.add.at(m, (c, r), 1.0)
    out["regions"] = dirichlet_multinomial(m, np.full(K, hyper.beta / K))
    n_v = weighted_counts(model, concepts)[e]
    phi = np.exp(state.log_phi_v)
    delta = hyper.delta_visual
    chain = 0.0
    for ell in np.flatnonzero(n_v.sum(axis=1) > 0):
        a = delta * phi[ell]
        chain += float(np.sum(gammaln(a + n_v[ell]) - gammaln(a)) + gammaln(delta)
                       - gammaln(delta + n_v[ell].sum()))
    out["view | φ chain"] = chain
    if grids is not None:
        out["view | φ integrated"] = float(sum(grids[ell].log_predictive(n_v[ell])
                                               for ell in np.flatnonzero(n_v.sum(axis=1) > 0)))
    return out


def conditional_terms(model, concepts: np.ndarray, e: int) -> dict[str, float]:
    """Home e's terms at the chain's G_e, π and θ^v (the assignment step's own log joint, the words
    left out: home e has none)."""
    from spco.model.assignments import view_weights
    from spco.model.observations import HierarchicalMultinomial

    data, state = model.data_, model.state_
    rows = np.flatnonzero(data.homes == e)
    c, r = concepts[rows], state.regions[rows]
    ll = HierarchicalMultinomial.log_likelihood(data.visual[rows], data.homes[rows], state.log_theta_v)
    w = view_weights(data, model.settings_.view_counts)
    view = ll[np.arange(rows.size), c] * (1.0 if w is None else w[rows])
    return {"concept prior": float(state.log_g[e, c].sum()), "regions": float(state.log_pi[e, c, r].sum()),
            "view": float(view.sum())}


def phi_grids(model, e: int, concepts_list: list[np.ndarray], rng: np.random.Generator) -> dict:
    """Per used concept, φ^v's evidence grid given the other homes' counts and one CRT table draw."""
    from spco.model.observations import HierarchicalMultinomial
    from spco.model.phi_evidence import ConceptGrid

    hyper, state = model.hyperparameters_, model.state_
    stats = weighted_counts(model, concepts_list[0])
    others = np.ascontiguousarray(np.delete(stats, e, axis=0))
    tables = HierarchicalMultinomial.table_parts(others, state.log_phi_v, hyper.delta_visual, rng)
    pseudo = hyper.alpha_visual + tables[0] + tables[1]
    bound = weighted_counts(model, np.zeros_like(concepts_list[0]))[e, 0]
    used = set()
    for concepts in concepts_list:
        used |= set(np.unique(concepts[model.data_.homes == e]).tolist())
    return {ell: ConceptGrid(pseudo[ell], others[:, ell], hyper.delta_visual, bound) for ell in used}


def per_place(model, concepts: np.ndarray, e: int, labels: np.ndarray) -> dict[str, dict[int, int]]:
    """Home e's places → {concept: samples}."""
    c = concepts[model.data_.homes == e]
    return {p: dict(Counter(c[labels == p].tolist())) for p in sorted(set(labels.tolist()) - {"None"})}


def experienced_ari(model, corpus, e: int) -> list[float]:
    """ARI of each other home's training samples' concepts against their places."""
    out = []
    for h, env in enumerate(corpus):
        if h == e:
            continue
        labels = training_labels(env)
        ok = labels != "None"
        out.append(float(adjusted_rand_score(labels[ok], np.asarray(model.concepts_[h])[ok])))
    return out


def concept_makeup(model, corpus, e: int, ell: int) -> dict[str, int]:
    """The other homes' training places in concept ``ell``: place → samples."""
    out: Counter = Counter()
    for h, env in enumerate(corpus):
        if h == e:
            continue
        for c, label in zip(model.concepts_[h], training_labels(env), strict=True):
            if int(c) == ell:
                out[str(label)] += 1
    return dict(out.most_common(6))


def one_sample_odds(model, lump: np.ndarray, rooms: np.ndarray, e: int, grids: dict, per_place: int,
                    labels: np.ndarray) -> dict[str, list[float]]:
    """For up to ``per_place`` samples of each place of home e whose room concept differs from its lump
    concept: the log-odds of the one-sample step moving it from its lump concept to its room concept, all
    else held at the lump (G_e and π integrated: the counts of the home's other samples), with the view
    (1) at the chain's θ^v_{e,l} (what the sampler's step sees), (2) with θ^v integrated given the chain's
    φ^v, (3) with θ^v and φ^v integrated given the other homes' tables (``grids``)."""
    from spco.model.assignments import view_weights
    from spco.model.observations import HierarchicalMultinomial

    data, state, hyper = model.data_, model.state_, model.hyperparameters_
    K = state.log_pi.shape[2]
    home = np.flatnonzero(data.homes == e)
    n_v = weighted_counts(model, lump)[e]
    w = view_weights(data, model.settings_.view_counts)
    w = np.ones(data.n_samples) if w is None else w
    g = hyper.gamma * np.exp(state.log_g0)
    n_c = np.bincount(lump[home], minlength=g.size).astype(np.float64)
    m = np.zeros((g.size, K))
    np.add.at(m, (lump[home], state.regions[home]), 1.0)
    phi, delta = np.exp(state.log_phi_v), hyper.delta_visual
    chain_ll = HierarchicalMultinomial.log_likelihood(data.visual[home], data.homes[home], state.log_theta_v)
    out: dict[str, list[float]] = {"chain θ": [], "θ integrated": [], "θ, φ integrated": [],
                                   "prior (G_e, π)": []}
    taken: Counter = Counter()
    for i, t in enumerate(home):
        a, b = int(lump[t]), int(rooms[t])
        if a == b or labels[i] == "None" or taken[labels[i]] >= per_place:
            continue
        taken[labels[i]] += 1
        x = w[t] * data.visual[[t]].toarray().ravel()
        r = int(state.regions[t])
        prior = (np.log(n_c[b] + g[b]) - np.log(n_c[a] - 1 + g[a])
                 + np.log(m[b, r] + hyper.beta / K) - np.log(n_c[b] + hyper.beta)
                 - np.log(m[a, r] - 1 + hyper.beta / K) + np.log(n_c[a] - 1 + hyper.beta))

        def fixed(ell: int, n: np.ndarray, x: np.ndarray = x) -> float:
            q = delta * phi[ell] + n
            return float(np.sum(gammaln(q + x) - gammaln(q)) - gammaln(q.sum() + x.sum()) + gammaln(q.sum()))

        out["chain θ"].append(float(prior + w[t] * (chain_ll[i, b] - chain_ll[i, a])))
        out["θ integrated"].append(float(prior + fixed(b, n_v[b]) - fixed(a, n_v[a] - x)))
        grid_a, grid_b = grids[a], grids[b]
        view = (grid_b.log_predictive(n_v[b] + x) - grid_b.log_predictive(n_v[b])
                - grid_a.log_predictive(n_v[a]) + grid_a.log_predictive(np.maximum(n_v[a] - x, 0.0)))
        out["θ, φ integrated"].append(float(prior + view))
        out["prior (G_e, π)"].append(float(prior))
        if len(out["chain θ"]) == 1:  # the one-sample odds are the collapsed joint's difference of two states
            moved = lump.copy()
            moved[t] = b
            before, after = home_terms(model, lump, e, grids), home_terms(model, moved, e, grids)
            for key, terms in (("θ integrated", ("concept prior", "regions", "view | φ chain")),
                               ("θ, φ integrated", ("concept prior", "regions", "view | φ integrated"))):
                check = sum(after[k] - before[k] for k in terms)
                if not np.isclose(out[key][0], check, atol=1e-6 * max(1.0, abs(check))):
                    raise RuntimeError(f"one-sample odds {key} {out[key][0]} against the joint's {check}")
    return out


def diagnose(model, corpus, tables: int, seed: int, n_odds: int = 3) -> dict:
    """The comparison of one fit."""
    e = len(corpus) - 1
    data = model.data_
    rows = data.homes == e
    if data.words[np.flatnonzero(rows)].nnz:
        return {}  # a taught new home (3LDK_9): the words would differ too; not this diagnosis
    labels = training_labels(corpus[e])
    lump = np.asarray(model.state_.concepts).copy()
    rooms, chosen = rooms_state(model, corpus, e)
    ok = labels != "None"
    out = {"ari_lump": float(adjusted_rand_score(labels[ok], lump[rows][ok])),
           "ari_rooms": float(adjusted_rand_score(labels[ok], rooms[rows][ok])),
           "places_lump": per_place(model, lump, e, labels), "rooms_map": chosen,
           "experienced_ari": experienced_ari(model, corpus, e)}
    rng = np.random.default_rng(seed)
    integrated = {"lump": [], "rooms": []}
    for _ in range(tables):
        grids = phi_grids(model, e, [lump, rooms], rng)
        integrated["lump"].append(home_terms(model, lump, e, grids))
        integrated["rooms"].append(home_terms(model, rooms, e, grids))
    mean = {k: {t: float(np.mean([d[t] for d in v])) for t in TERMS} for k, v in integrated.items()}
    out["integrated"] = {t: mean["rooms"][t] - mean["lump"][t] for t in TERMS}
    pairs = zip(integrated["rooms"], integrated["lump"], strict=True)
    out["phi_fit"] = {k: mean[k]["view | φ chain"] - mean[k]["view | φ integrated"] for k in mean}
    key = "view | φ integrated"
    out["integrated_sd"] = float(np.std([r[key] - m[key] for r, m in pairs]))
    out["one_sample"] = one_sample_odds(model, lump, rooms, e, grids, n_odds, labels)
    # and back: from the rooms state, one sample into its lump concept ("chain θ" is not the chain's here)
    out["one_sample_back"] = one_sample_odds(model, rooms, lump, e, grids, n_odds, labels)
    cl, cr = conditional_terms(model, lump, e), conditional_terms(model, rooms, e)
    out["conditional"] = {t: cr[t] - cl[t] for t in cl}
    used = sorted(set(lump[rows].tolist()) | set(rooms[rows].tolist()))
    out["makeup"] = {int(ell): concept_makeup(model, corpus, e, ell) for ell in used}
    return out


def clusters(model, corpus, seed: int, label: str) -> dict:
    """The new home's ARI and concepts used, each experienced home's ARI (printed)."""
    e = len(corpus) - 1
    labels = training_labels(corpus[e])
    ok = labels != "None"
    concepts = np.asarray(model.state_.concepts)[model.data_.homes == e][ok]
    r = {"seed": seed, "home": label, "new_ari": float(adjusted_rand_score(labels[ok], concepts)),
         "new_used": len(set(concepts.tolist())), "experienced_ari": experienced_ari(model, corpus, e)}
    print(f"seed {seed} {label}: new home ARI {r['new_ari']:.2f} ({r['new_used']} concepts), experienced "
          f"{np.round(r['experienced_ari'], 2).tolist()}", flush=True)
    return r


def main() -> None:
    """Read the fits, diagnose, print, write ``--json``."""
    from free_speech import read_names
    from natural_speech import configurations, fit_arguments, fitted
    from split_seeds import refuse_other_seeds

    from spco.data import Corpus

    parser = fit_arguments(argparse.ArgumentParser(description=__doc__.splitlines()[0]))
    parser.add_argument("--homes", nargs="*", default=None, help="only these configurations (e.g. 1LDK_1)")
    parser.add_argument("--tables", type=int, default=3, help="CRT table draws for φ^v integrated")
    parser.add_argument("--clusters-only", action="store_true",
                        help="only the adjusted Rand indices (new home, each experienced home): for any fit, "
                        "the cut's too")
    parser.add_argument("--json", type=Path, default=None)
    args = parser.parse_args()
    refuse_other_seeds(parser, args.seeds)
    _, configs = configurations(args.sigverse, read_names(args.accepted), leave_one_out=True)
    labels = [c[0] for c in configs]
    rows = []
    for seed in args.seeds:
        for label, homes, env in configs:
            if args.homes and label.split()[0] not in args.homes:
                continue
            corpus = Corpus([*homes, env])
            model = fitted(corpus, seed, label, labels, settings=args.set, sweeps=args.sweeps,
                           cache=args.cache)
            if args.clusters_only:
                rows.append(clusters(model, corpus, seed, label))
                continue
            r = {"seed": seed, "home": label, **diagnose(model, corpus, args.tables, seed)}
            if "ari_lump" not in r:
                continue
            rows.append(r)
            print(f"\n## seed {seed} {label}: ARI lump {r['ari_lump']:.2f}, rooms {r['ari_rooms']:.2f}; "
                  f"experienced homes' ARI {np.round(r['experienced_ari'], 2).tolist()}")
            print("places → concepts (lump):", r["places_lump"], "| rooms map:", r["rooms_map"])
            print("rooms − lump, integrated:", {k: round(v, 1) for k, v in r["integrated"].items()},
                  f"(sd over table draws {r['integrated_sd']:.1f})")
            print("rooms − lump, conditional:", {k: round(v, 1) for k, v in r["conditional"].items()})
            back = ("back, θ, φ integrated", r["one_sample_back"]["θ, φ integrated"])
            for k, v in [*r["one_sample"].items(), back]:
                if v:
                    print(f"one-sample log-odds room vs lump, {k}: median {np.median(v):.1f}, "
                          f"max {np.max(v):.1f}, positive {int(np.sum(np.asarray(v) > 0))} of {len(v)}")
            for ell, mk in r["makeup"].items():
                print(f"  concept {ell}: {mk}")
            sys.stdout.flush()
    if args.clusters_only:
        new = [r["new_ari"] for r in rows]
        old = [np.mean(r["experienced_ari"]) for r in rows]
        print(f"\nover {len(rows)} fits: the new home's ARI {np.mean(new):.3f}, the experienced homes' "
              f"mean ARI "
              f"{np.mean(old):.3f} (min of a home {np.min([min(r['experienced_ari']) for r in rows]):.2f})")
    else:
        _table(rows)
    if args.json:
        args.json.write_text(json.dumps(rows, indent=0), encoding="utf-8")


def _table(rows: list[dict]) -> None:
    """One line a fit: rooms − lump by term (integrated), the totals, the one-sample odds."""
    print("\n| seed | configuration | places → concepts (lump) | ARI lump → rooms | concept prior | "
          "regions | "
          "view, φ chain | view, φ integrated | total, φ chain | total, φ integrated | φ fit to the lump "
          "(chain − integrated, lump / rooms) | one-sample odds, median: chain θ / θ int. / θ, φ int. "
          "(positive of n) | of which G_e, π (median) | back from the rooms, θ, φ int. (positive) |")
    print("|---|---|---|---|---:|---:|---:|---:|---:|---:|---|---|---:|---|")
    for r in rows:
        d = r["integrated"]
        base = d["concept prior"] + d["regions"]
        used = len({c for p in r["places_lump"].values() for c in p})
        odds = r["one_sample"]
        views = [odds[k] for k in ("chain θ", "θ integrated", "θ, φ integrated")]
        cells = " / ".join(f"{np.median(v):.0f}" if v else "–" for v in views)
        pos = sum(int(np.sum(np.asarray(v) > 0)) for v in views)
        prior = f"{np.median(odds['prior (G_e, π)']):.1f}" if odds["prior (G_e, π)"] else "–"
        back = np.asarray(r["one_sample_back"]["θ, φ integrated"])
        back_cell = f"{np.median(back):+.0f} ({int(np.sum(back > 0))} of {back.size})" if back.size else "–"
        n = len(odds["θ, φ integrated"])
        print(f"| {r['seed']} | {r['home']} | {len(r['places_lump'])} → {used} | {r['ari_lump']:.2f} → "
              f"{r['ari_rooms']:.2f} | {d['concept prior']:+.0f} | {d['regions']:+.0f} | "
              f"{d['view | φ chain']:+.0f} | {d['view | φ integrated']:+.0f} | "
              f"{base + d['view | φ chain']:+.0f} | {base + d['view | φ integrated']:+.0f} | "
              f"{r['phi_fit']['lump']:+.0f} / {r['phi_fit']['rooms']:+.0f} | "
              f"{cells} ({pos} of {3 * n}) | {prior} | {back_cell} |")


if __name__ == "__main__":
    main()
