"""The power target's lumping with θ^v AND φ^v integrated out: the evidence a block move of the new
home's places would see (issue 29, branch phimarg15; development only).

General places (benchmarks/general_places.py): the 16 experienced homes' fc7 views, 3LDK_9 taught
nothing, the power target (``--set target=power --set visual_prior=estimate``), seed
``trial_seed(0, 0)``, 60 sweeps. After the fit, for the new home e (its training samples' weighted
counts n_{e,l} = Σ_t ω_t v_t, ω_t = min(1, w / Σ_d v_td)) and two assignments of its samples to
concepts (the chain's own, "lumped", and the "true rooms": each place in the concept most of the
experienced homes' samples of that place hold), the view evidence

    ln p(n_e | n_{−e}) = Σ_l ln E_{φ_l | n_{−e,l}} [ B(δ φ_l + n_{e,l}) / B(δ φ_l) ]

(θ^v_{e,l} ~ Dir(δ φ_l) integrated exactly; the multinomial coefficients, the same for every
assignment, left out). φ_l's posterior given the other homes' counts is the mixture over table
counts M (CRT of ⌊n_{−e}⌋) of Dir(α + M + F) · w(φ) / Z_M: F the fractions below one (the proposal
of the library's φ^v step), w the fractional weight of its Metropolis–Hastings test. So
E[H | M] = E_q[H w] / E_q[w], q = Dir(α + M + F) (:class:`ConceptGrid`): exact for real counts
(``--proposal-only`` leaves w out, to measure what it changes). The tables are drawn by running the
library's own φ^v step on the other homes' counts alone (a chain for p(φ, M | n_{−e})), and each
Dirichlet expectation of a product over dimensions is computed by a saddlepoint over independent
gammas conditioned on their sum (:func:`log_dirichlet_expectation`), checked against brute force by
``check`` and tests/test_phi_marginal_evidence.py. The estimate per concept is the log of the mean
over table draws (Rao–Blackwellised); its standard error by batch means. ``table`` adds the G_e and π
terms a block move also sees (:func:`assignment_prior`).

    python benchmarks/phi_marginal_evidence.py fit --out DIR --seed 0   # the fit, dumped (~7 s CPU)
    python benchmarks/phi_marginal_evidence.py evidence --out DIR --draws 40 --burn 30
    python benchmarks/phi_marginal_evidence.py table --out DIR          # with the G_e, π terms
    python benchmarks/phi_marginal_evidence.py check --out DIR          # the brute-force checks
    python benchmarks/phi_marginal_evidence.py move --out DIR --passes 3  # the library's move on the fit
    python benchmarks/phi_marginal_evidence.py chain --out DIR --seed 0 --more 20 --every 1  # sweeps after
    python benchmarks/phi_marginal_evidence.py phi-accept --seed 0     # the φ^v step's acceptance in the fit
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from collections import Counter
from pathlib import Path

import numpy as np
import scipy.sparse as sp
from data_paths import SIGVERSE
from scipy.special import gammaln, logsumexp

from spco.model.phi_evidence import (  # noqa: F401  (the one implementation, used here and by the tests)
    ConceptGrid,
    log_dirichlet_expectation,
    log_h_dm,
    log_h_power,
)

FIT_FILE = "fit.npz"


# ----------------------------------------------------------------------------- brute force (checks)

def _simplex3_rule(a: np.ndarray, points: int = 400) -> tuple[np.ndarray, np.ndarray]:
    """Nodes φ (P, 3) and weights (P,) integrating over Dir(a) on the 3-simplex: stick-breaking
    φ1 = v1, φ2 = (1 − v1) v2 with v1 ~ Beta(a1, a2 + a3), v2 ~ Beta(a2, a3) independent, integrated
    in their quantiles by Gauss–Legendre (the singular corners of a < 1 become smooth there)."""
    from scipy.stats import beta

    x, wt = np.polynomial.legendre.leggauss(points)
    qs, ws = (x + 1) / 2, wt / 2
    v1 = beta.ppf(qs, a[0], a[1] + a[2])
    v2 = beta.ppf(qs, a[1], a[2])
    p1 = np.repeat(v1, points)
    p2 = (1 - p1) * np.tile(v2, points)
    phi = np.stack([p1, p2, np.maximum(1 - p1 - p2, 0.0)], axis=1)
    return phi, np.outer(ws, ws).ravel()


def _log_ratio(phi: np.ndarray, n: np.ndarray, delta: float) -> np.ndarray:
    """ln B(δ φ + n) / B(δ φ) for rows φ (P, D) and counts n (D,)."""
    x = delta * phi
    return (gammaln(x + n) - gammaln(x)).sum(1) + gammaln(delta) - gammaln(delta + n.sum())


def brute_log_expectation(a: np.ndarray, n: np.ndarray, delta: float) -> float:
    """ln E_{Dir(a)} Π_d Γ(δ φ_d + n_d)/Γ(δ φ_d) on the 3-simplex by quadrature."""
    phi, wt = _simplex3_rule(a)
    x = delta * phi
    with np.errstate(divide="ignore"):
        lh = (gammaln(x + n) - gammaln(x)).sum(1)
    return float(logsumexp(lh, b=wt))


def brute_predictive(alpha: float, delta: float, others: np.ndarray, new: np.ndarray) -> float:
    """ln p(n_new | n_others) = ln ∫ Dir(φ|α) Π_e R_e R_new / ∫ Dir(φ|α) Π_e R_e, R = B(δφ + n)/B(δφ),
    on the 3-simplex by quadrature: the exact value the table mixture approximates."""
    phi, wt = _simplex3_rule(np.full(3, alpha))
    base = sum(_log_ratio(phi, o, delta) for o in others)
    return float(logsumexp(base + _log_ratio(phi, new, delta), b=wt) - logsumexp(base, b=wt))


def check(seed: int = 0) -> dict:
    """The checks: (1) the saddlepoint against exact B(a + n)/B(a) at D = 4,096; (2) against
    quadrature on the 3-simplex and Monte Carlo at D = 20 for the Dirichlet–multinomial factor;
    (3) the whole estimate (table chain + saddlepoint) against the exact predictive on the
    3-simplex, whole and real counts."""
    rng = np.random.default_rng(seed)
    out: dict = {"power_D4096": [], "dm_D3": [], "dm_D20_mc": [], "predictive_D3": []}
    for alpha in (0.23, 3.0):
        a = alpha + rng.poisson(2.0, 4096) * (rng.random(4096) < 0.3)
        n = rng.random(4096) * 3 * (rng.random(4096) < 0.5)
        sp_ = log_dirichlet_expectation(a, n, 1.0, log_h_power)["value"]
        exact = gammaln(a + n).sum() - gammaln((a + n).sum()) - gammaln(a).sum() + gammaln(a.sum())
        out["power_D4096"].append({"alpha": alpha, "saddle": sp_, "exact": float(exact),
                                   "error": sp_ - exact})
    for a, n, delta in ((np.array([0.3, 1.2, 2.5]), np.array([1.7, 0.0, 3.2]), 5.0),
                        (np.array([0.23, 0.23, 4.0]), np.array([0.4, 2.0, 6.0]), 50.0),
                        (np.array([2.0, 3.0, 1.0]), np.array([12.5, 0.3, 0.0]), 20.0)):
        sp_ = log_dirichlet_expectation(a, n, delta)["value"]
        bf = brute_log_expectation(a, n, delta)
        out["dm_D3"].append({"a": a.tolist(), "n": n.tolist(), "delta": delta, "saddle": sp_, "brute": bf,
                             "error": sp_ - bf})
    for alpha, delta in ((0.3, 20.0), (1.0, 100.0)):
        a = alpha + rng.poisson(3.0, 20).astype(float)
        n = rng.random(20) * 2 * (rng.random(20) < 0.6)
        sp_ = log_dirichlet_expectation(a, n, delta)["value"]
        phi = rng.dirichlet(a, size=2_000_000)
        lh = _log_ratio(phi, n, delta) - gammaln(delta) + gammaln(delta + n.sum())
        m = logsumexp(lh) - np.log(lh.size)
        w = np.exp(lh - lh.max())
        se = float(w.std() / np.sqrt(w.size) / w.mean())
        out["dm_D20_mc"].append({"alpha": alpha, "delta": delta, "saddle": sp_, "mc": float(m), "mc_se": se,
                                 "error": sp_ - float(m)})
    # at larger D, by importance sampling from Dir(a + n) (weights H(φ) B(a + n)/B(a) / Π φ^n; plain
    # Monte Carlo from Dir(a) fails here: a view's ln H spreads by tens of nats over φ draws)
    out["dm_large_D_is"] = []
    for d, k, delta, size in ((300, 60, 500.0, 400_000), (4096, 400, 4990.0, 20_000)):
        a = 0.23 + rng.poisson(4.0, d) * (rng.random(d) < 0.4)
        n = np.zeros(d)
        n[rng.choice(np.flatnonzero(a > 1), k, replace=False)] = rng.random(k) * 3
        sp_ = log_dirichlet_expectation(a, n, delta)["value"]
        lb = gammaln(a + n).sum() - gammaln((a + n).sum()) - gammaln(a).sum() + gammaln(a.sum())
        parts = []
        for _ in range(10):
            phi = rng.dirichlet(a + n, size=size // 10)
            parts.append(_log_ratio(phi, n, delta) - gammaln(delta) + gammaln(delta + n.sum())
                         - (n * np.log(phi)).sum(1) + lb)
        lw = np.concatenate(parts)
        w = np.exp(lw - lw.max())
        est = float(logsumexp(lw) - np.log(lw.size))
        out["dm_large_D_is"].append({"D": d, "active": k, "saddle": sp_, "importance": est,
                                     "se": float(w.std() / np.sqrt(w.size) / w.mean()),
                                     "spread_of_log_weight": float(lw.std()), "error": sp_ - est})
    for frac in (False, True):
        alpha, delta = 0.4, 6.0
        others = rng.integers(0, 5, size=(2, 3)).astype(float)
        new = rng.integers(0, 4, size=3).astype(float)
        if frac:
            others = others + np.round(rng.random((2, 3)), 2)
            new = new + np.round(rng.random(3), 2)
        exact = brute_predictive(alpha, delta, list(others), new)
        row = {"fractional": frac, "others": others.tolist(), "new": new.tolist(), "exact": exact}
        for exact_fractions in (True, False):
            est = predictive_estimates(others[:, None, :], np.zeros((1, 3)), {"x": new[None, :]}, delta,
                                       alpha,
                                       np.random.default_rng(seed), 3000, 200,
                                       exact_fractions=exact_fractions)["variants"]["x"]
            key = "estimate" if exact_fractions else "proposal_only"
            row[key], row[key + "_se"], row[key + "_error"] = est["value"], est["se"], est["value"] - exact
        out["predictive_D3"].append(row)
    return out


# ----------------------------------------------------------------------------- the estimate

def table_draws(n_others: np.ndarray, log_phi: np.ndarray, delta: float, alpha,
                rng: np.random.Generator, draws: int, burn: int) -> np.ndarray:
    """Dirichlet parameters α + M + F (draws, L, D) of φ's posterior given the other homes' counts
    n_others (E', L, D): the library's φ^v step run on those counts alone from ``log_phi``, each
    step's table counts M (CRT of ⌊n⌋) and fractions F recorded after ``burn`` steps."""
    from spco.model.observations import HierarchicalMultinomial as HM

    out = np.empty((draws, *log_phi.shape))
    for i in range(burn + draws):
        tables, frac, fractional = HM.table_parts(n_others, log_phi, delta, rng)
        if i >= burn:
            out[i - burn] = alpha + tables + frac
        log_phi = HM.accept_shared(lambda phi: HM.fractional_log_weight_terms(n_others, phi, delta),
                                   log_phi, alpha, tables, frac, rng, fractional > 0)
    return out


def log_mean_with_se(values: np.ndarray, batches: int = 10) -> tuple[float, float]:
    """ln mean exp(values) and its standard error by batch means (delta method)."""
    m = values.max()
    w = np.exp(values - m)
    mean = w.mean()
    k = len(w) // batches
    if k < 1:
        return float(m + np.log(mean)), float("nan")
    bm = w[: k * batches].reshape(batches, k).mean(1)
    return float(m + np.log(mean)), float(bm.std(ddof=1) / np.sqrt(batches) / mean)


def predictive_estimates(n_others: np.ndarray, log_phi: np.ndarray, variants: dict[str, np.ndarray],
                         delta: float, alpha, rng: np.random.Generator, draws: int, burn: int,
                         exact_fractions: bool = True, log=None) -> dict:
    """ln p(n_new | n_others) = Σ_l ln E_{φ_l | n_others}[B(δ φ_l + n_new,l)/B(δ φ_l)] for each
    assignment of ``variants`` (name → n_new (L, D)), on the same table draws (:func:`table_draws`):
    per concept the log of the mean over draws of E[· | M] (:class:`ConceptGrid`, exact for real counts;
    ``exact_fractions=False``: the proposal Dir(α + M + F) alone, w left out), its standard error by
    batch means (concepts independent). Also the paired differences of every variant to the first."""
    params = table_draws(n_others, np.array(log_phi, dtype=float), delta, alpha, rng, draws, burn)
    names = list(variants)
    concepts = sorted({int(c) for v in variants.values() for c in np.flatnonzero(v.sum(1) > 0)})
    vals = {name: {} for name in names}
    worst_end = 0.0
    for c in concepts:
        bound = np.max([v[c] for v in variants.values()], axis=0)
        per = {name: [] for name in names}
        for j, p in enumerate(params):
            others = n_others[:, c] if exact_fractions else np.floor(n_others[:, c])
            grid = ConceptGrid(p[c], others, delta, bound)
            cache: dict[bytes, float] = {}
            for name in names:
                key = variants[name][c].tobytes()
                if key not in cache:
                    r = grid.log_expectation(variants[name][c])
                    cache[key] = r["value"]
                    worst_end = max(worst_end, r["grid_end_mass"])
                per[name].append(cache[key])
            if log:
                log(f"concept {c} draw {j}: " + " ".join(f"{k} {per[k][-1]:.2f}" for k in names))
        for name in names:
            vals[name][c] = np.asarray(per[name])
    out: dict = {"draws": draws, "burn": burn, "grid_end_mass": worst_end, "variants": {}}
    for name in names:
        total, var, per_c = 0.0, 0.0, {}
        for c in concepts:
            n_l = variants[name][c]
            if n_l.sum() == 0:
                continue
            v, se = log_mean_with_se(vals[name][c])
            v += gammaln(delta) - gammaln(delta + n_l.sum())
            per_c[c] = {"value": v, "se": se, "spread_over_draws": float(vals[name][c].std())}
            total += v
            var += se**2
        out["variants"][name] = {"value": total, "se": float(np.sqrt(var)), "per_concept": per_c}
    return out


def predictive_estimate(n_others: np.ndarray, log_phi: np.ndarray, n_new: np.ndarray, delta: float,
                        alpha, rng: np.random.Generator, draws: int, burn: int) -> dict:
    """:func:`predictive_estimates` of one assignment: its value and standard error."""
    r = predictive_estimates(n_others, log_phi, {"x": n_new}, delta, alpha, rng, draws, burn)
    r = r["variants"]["x"]
    return {"value": r["value"], "se": r["se"]}

def load_fit(out: Path) -> dict:
    """The dumped fit: counts, the new home's samples, the statistics of every home."""
    from spco.model.observations import HierarchicalMultinomial as HM

    f = np.load(out / FIT_FILE, allow_pickle=False)
    visual = sp.csr_array((f["data"], f["indices"], f["indptr"]), shape=tuple(f["shape"]))
    homes, concepts, weights = f["homes"], f["concepts"], f["weights"]
    n_homes, n_concepts = int(homes.max()) + 1, int(f["log_phi_v"].shape[0])
    stats = HM.weighted_statistics(visual, weights, homes, concepts, n_homes, n_concepts)
    return {"visual": visual, "homes": homes, "concepts": concepts, "weights": weights,
            "labels": f["labels"].astype(str), "delta": float(f["delta"]), "alpha": f["alpha"],
            "log_phi_v": f["log_phi_v"], "phi_summary": f["phi_summary"], "stats": stats,
            "n_homes": n_homes, "n_concepts": n_concepts, "seed": int(f["seed"]), "sweeps": int(f["sweeps"])}


MOVED = ("bath", "dining", "living room")


def assignments(fit: dict) -> tuple[dict[str, np.ndarray], dict[str, int]]:
    """The new home's assignments compared: "lumped" (the chain's concepts), "true rooms" (every
    labelled place in the concept most of the experienced homes' samples of that place hold; the
    unlabelled samples where the chain has them), "lumped, X own" (one place of :data:`MOVED` moved
    from the lump to its own concept) and "true, X lumped" (the reverse: one place moved into the
    concept holding most of the new home's samples). Returns {name: concepts of the new home's
    samples} and the place → concept map."""
    new = fit["homes"] == fit["n_homes"] - 1
    labels, chain = fit["labels"], fit["concepts"]
    own = {}
    for place in sorted(set(labels[new]) - {"None"}):
        exp = (~new) & (labels == place)
        own[place] = int(Counter(chain[exp].tolist()).most_common(1)[0][0])
    lumped = chain[new].copy()
    lump = int(Counter(lumped.tolist()).most_common(1)[0][0])
    true = lumped.copy()
    for place, c in own.items():
        true[labels[new] == place] = c
    out = {"lumped": lumped, "true rooms": true}
    for place in MOVED:
        moved = lumped.copy()
        moved[labels[new] == place] = own[place]
        out[f"lumped, {place} own"] = moved
    for place in MOVED:
        back = true.copy()
        back[labels[new] == place] = lump
        out[f"true, {place} lumped"] = back
    return out, own


def new_home_counts(fit: dict, concepts_new: np.ndarray) -> np.ndarray:
    """n^v of the new home (L, D) for its samples in ``concepts_new``."""
    from spco.model.observations import HierarchicalMultinomial as HM

    new = np.flatnonzero(fit["homes"] == fit["n_homes"] - 1)
    return HM.weighted_statistics(fit["visual"][new], fit["weights"][new], np.zeros(new.size, dtype=np.int64),
                                  concepts_new, 1, fit["n_concepts"])[0]


def given_phi(n_new: np.ndarray, log_phi: np.ndarray, delta: float) -> float:
    """collapse9's evidence: θ^v integrated out, φ^v given: Σ_l ln B(δφ_l + n_l) − ln B(δφ_l)."""
    x = delta * np.exp(log_phi)
    used = n_new.sum(1) > 0
    with np.errstate(divide="ignore", invalid="ignore"):
        t = np.where(n_new > 0, gammaln(x + n_new) - gammaln(np.where(x > 0, x, 1.0)), 0.0)
        t = np.where((n_new > 0) & (x == 0), -np.inf, t)
    return float(t[used].sum() + (gammaln(delta) - gammaln(delta + n_new.sum(1)))[used].sum())


def evidence(out: Path, draws: int, burn: int, seed: int, exact_fractions: bool = True) -> dict:
    """The table: every assignment's view evidence with θ^v and φ^v integrated out given the other
    homes' counts (and, for reference, given the chain's φ^v draw and φ^v's summary).
    ``exact_fractions=False``: φ^v's conditional given the tables taken as the proposal Dir(α + M + F)
    alone (the cheaper form a move could use), to measure what the fractional weight w changes."""
    fit = load_fit(out)
    variants_c, own = assignments(fit)
    variants = {k: new_home_counts(fit, v) for k, v in variants_c.items()}
    others = np.ascontiguousarray(fit["stats"][:-1])
    alpha = fit["alpha"] if fit["alpha"].ndim else float(fit["alpha"])
    t0 = time.process_time()
    logf = open(out / "evidence.log", "a", encoding="utf-8")

    def log(msg: str) -> None:
        logf.write(f"{time.strftime('%H:%M:%S', time.gmtime())} {msg}\n")
        logf.flush()

    est = predictive_estimates(others, fit["log_phi_v"], variants, fit["delta"], alpha,
                               np.random.default_rng(seed), draws, burn, exact_fractions=exact_fractions,
                               log=log)
    est["exact_fractions"] = exact_fractions
    est["cpu_seconds"] = time.process_time() - t0
    est["place_concepts"] = own
    est["fit_seed"], est["fit_sweeps"], est["evidence_seed"] = fit["seed"], fit["sweeps"], seed
    est["delta"], est["alpha"] = fit["delta"], float(np.mean(fit["alpha"]))
    base = est["variants"]["lumped"]
    for name, v in est["variants"].items():
        v["concepts_used"] = dict(Counter(variants_c[name].tolist()))
        v["given_phi_draw"] = given_phi(variants[name], fit["log_phi_v"], fit["delta"])
        with np.errstate(divide="ignore"):
            v["given_phi_summary"] = given_phi(variants[name], np.log(fit["phi_summary"]), fit["delta"])
        v["minus_lumped"] = v["value"] - base["value"]
    return est

def _fitted(sweeps: int, seed_index: int):
    """General places fitted as benchmarks/general_places.py fits them (power target, 3LDK_9 taught
    nothing, seed ``trial_seed(seed_index, 0)``): the model, every training sample's place, the seed."""
    sys.path.insert(0, str(Path(__file__).parent))
    from general_places import MODEL, new_home

    from spco.data import Corpus
    from spco.data.loading import load
    from spco.evaluation.config import PAPER_EXPERIENCED_HOMES, trial_seed
    from spco.evaluation.models import MODELS
    from spco.model.hyperparameters import TransferHyperparameters

    sig = SIGVERSE
    hyper = TransferHyperparameters().with_settings(["target=power", "visual_prior=estimate"])
    knowledge = [load(sig / h)[h] for h in PAPER_EXPERIENCED_HOMES]
    env = new_home(sig, sig.parent / "sigverse_regions.json", "3LDK_9", False)
    run_seed = trial_seed(seed_index, 0)
    model = MODELS[MODEL].build(sweeps, run_seed, hyper, False)
    corpus = Corpus([*knowledge, env])
    t0 = time.process_time()
    model.fit(corpus)
    print(f"fit: {time.process_time() - t0:.1f} s CPU", flush=True)
    data = model.data_
    labels = []
    for e in corpus:
        lab = np.asarray(e.ground_truth.labels, dtype=object)[~np.asarray(e.is_test, dtype=bool)]
        labels.extend(str(x) for x in lab)
    labels = np.asarray(labels)
    if labels.shape[0] != data.n_samples:
        raise SystemExit(f"labels {labels.shape[0]} != training samples {data.n_samples}")
    return model, labels, run_seed


def fit(out: Path, sweeps: int, seed_index: int) -> None:
    """Fit general places (:func:`_fitted`) and dump what the evidence needs: the weighted view counts
    of every home and concept, the new home's training views and weights, the chain's concepts, every
    training sample's place, δ^v, α^v, log φ^v."""
    from spco.model.assignments import view_weights

    model, labels, run_seed = _fitted(sweeps, seed_index)
    data, state, h = model.data_, model.state_, model.hyperparameters_
    weights = view_weights(data, model.settings_.view_counts)
    visual = sp.csr_array(data.visual)
    out.mkdir(parents=True, exist_ok=True)
    np.savez_compressed(
        out / FIT_FILE, data=visual.data, indices=visual.indices, indptr=visual.indptr,
        shape=np.asarray(visual.shape), weights=weights, homes=data.homes, concepts=state.concepts,
        labels=labels, delta=float(h.delta_visual), alpha=np.asarray(h.alpha_visual, dtype=float),
        log_phi_v=state.log_phi_v, phi_summary=model.parameters_.shared_visual_probabilities,
        seed=run_seed, sweeps=sweeps, regions=state.regions, log_g0=state.log_g0, gamma=float(h.gamma),
        beta=float(h.beta), n_regions=int(h.n_regions))
    print(f"dumped {out / FIT_FILE}: delta {h.delta_visual:.1f}, alpha {np.mean(h.alpha_visual):.4f}, "
          f"new home's concepts {Counter(state.concepts[data.homes == data.homes.max()].tolist())}")


def assignment_prior(fit_file: Path, concepts_new: np.ndarray) -> dict[str, float]:
    """The rest of what a block move of the new home's samples sees (regions held): G_e ~ Dir(γ G_0)
    and π_{e,l} ~ Dir(β/K) integrated out, ln Γ(γ)/Γ(γ + N) Π_l Γ(γG_0l + n_l)/Γ(γG_0l) and
    Σ_l ln Γ(β)/Γ(β + n_l) Π_k Γ(β/K + n_lk)/Γ(β/K); the Gaussians and words do not change
    (regions held, the new home untaught)."""
    f = np.load(fit_file)
    new = f["homes"] == f["homes"].max()
    regions = f["regions"][new]
    g0 = np.exp(f["log_g0"])
    gamma, beta, k = float(f["gamma"]), float(f["beta"]), int(f["n_regions"])
    n_l = np.bincount(concepts_new, minlength=g0.size)
    used = n_l > 0
    g_term = gammaln(gamma) - gammaln(gamma + n_l.sum()) + float(
        (gammaln(gamma * g0[used] + n_l[used]) - gammaln(gamma * g0[used])).sum())
    pi_term = 0.0
    for c in np.flatnonzero(used):
        n_lk = np.bincount(regions[concepts_new == c], minlength=k)
        pi_term += gammaln(beta) - gammaln(beta + n_lk.sum()) + float(
            (gammaln(beta / k + n_lk) - gammaln(beta / k)).sum())
    return {"G_e": float(g_term), "pi": float(pi_term)}


def table(out: Path) -> None:
    """Print evidence.json with the assignment prior's terms (:func:`assignment_prior`)."""
    r = json.loads((out / "evidence.json").read_text())
    fit = load_fit(out)
    variants_c, _ = assignments(fit)
    if "regions" in np.load(out / FIT_FILE).files:
        base = assignment_prior(out / FIT_FILE, variants_c["lumped"])
        for name, v in r["variants"].items():
            terms = assignment_prior(out / FIT_FILE, variants_c[name])
            v["assignment_prior_minus_lumped"] = {k: terms[k] - base[k] for k in terms}
        (out / "evidence.json").write_text(json.dumps(r, indent=1))
    print_table(r)


def print_table(r: dict) -> None:
    """The evidence as a markdown table (nats; ± one standard error)."""
    print(f"draws {r['draws']} (burn {r['burn']}), CPU {r['cpu_seconds']:.0f} s, grid end mass "
          f"{r['grid_end_mass']:.1e}, place concepts {r['place_concepts']}")
    print("| assignment | concepts used | ln p(n_e | n_-e), θ^v and φ^v integrated | − lumped "
          "| given φ^v draw (− lumped) | given φ^v summary (− lumped) | G_e, π terms (− lumped) |")
    print("|---|---|---|---|---|---|---|")
    b = r["variants"]["lumped"]
    for name, v in r["variants"].items():
        print(f"| {name} | {len(v['concepts_used'])} | {v['value']:.1f} ± {v['se']:.2f} | "
              f"{v['minus_lumped']:+.1f} | {v['given_phi_draw'] - b['given_phi_draw']:+.1f} | "
              f"{v['given_phi_summary'] - b['given_phi_summary']:+.1f} | "
              + (f"{v['assignment_prior_minus_lumped']['G_e']:+.1f}, "
                 f"{v['assignment_prior_minus_lumped']['pi']:+.1f} |"
                 if "assignment_prior_minus_lumped" in v else "– |"))
    for name, v in r["variants"].items():
        print(name, {k: (round(x["value"], 2), round(x["se"], 3), round(x["spread_over_draws"], 2))
                     for k, x in v["per_concept"].items()})


def move(out: Path, passes: int, seed: int) -> dict:
    """The library's φ^v-marginal block move (:mod:`spco.model.phi_moves`) on the dumped fit's new
    home: the other homes' tables drawn once given the fit's φ^v (seed ``seed``), then ``passes``
    passes over the new home's blocks given them (each an exact Metropolis–Hastings pass for
    p(C_e | M_{−e}), the regions and the other homes held); the new home's places' concepts before and
    after, the moves accepted and the CPU seconds."""
    from spco.model.observations import HierarchicalMultinomial as HM
    from spco.model.phi_moves import HomeMove, home_pass

    fit_ = load_fit(out)
    f = np.load(out / FIT_FILE)
    rng = np.random.default_rng(seed)
    e = fit_["n_homes"] - 1
    new = np.flatnonzero(fit_["homes"] == e)
    stats = fit_["stats"]
    others = np.ascontiguousarray(stats[:-1])
    alpha = fit_["alpha"] if fit_["alpha"].ndim else float(fit_["alpha"])
    t0 = time.process_time()
    tables = HM.table_parts(others, fit_["log_phi_v"], fit_["delta"], rng)
    g = float(f["gamma"]) * np.exp(f["log_g0"])
    concepts = fit_["concepts"][new].copy()
    regions = f["regions"][new]
    labels = fit_["labels"][new]
    before = {p: dict(Counter(concepts[labels == p].tolist())) for p in sorted(set(labels))}
    move_ = HomeMove(stats[e], others, alpha + tables[0] + tables[1], fit_["delta"],
                     np.bincount(concepts, minlength=fit_["n_concepts"]), g, float(f["beta"]))
    history = []
    for i in range(passes):
        t1 = time.process_time()
        concepts, accepted = home_pass(move_, fit_["visual"][new], fit_["weights"][new], concepts, regions,
                                       np.zeros((new.size, fit_["n_concepts"])), int(f["n_regions"]), rng)
        history.append({"pass": i, "accepted": accepted, "cpu_seconds": time.process_time() - t1,
                        "concepts_used": len(set(concepts.tolist())), "grids": len(move_.grids)})
        print(history[-1], flush=True)
    after = {p: dict(Counter(concepts[labels == p].tolist())) for p in sorted(set(labels))}
    return {"seed": seed, "fit_seed": fit_["seed"], "passes": history, "before": before, "after": after,
            "concepts_used_before": len(set(fit_["concepts"][new].tolist())),
            "concepts_used_after": len(set(concepts.tolist())), "cpu_seconds": time.process_time() - t0}


def chain(sweeps: int, seed_index: int, more: int, every: int, seed: int) -> dict:
    """The fit (:func:`_fitted`), then ``more`` sweeps of the library's single-process sweep
    (:func:`spco.model.gibbs.sweep`) from its final state, twice from the same state and seed: without
    the φ^v-marginal block move, and with it every ``every`` sweeps (on the new home, the one taught
    nothing). Per sweep: the new home's labelled samples' adjusted Rand index against their places,
    the concepts its samples use, the CPU seconds."""
    import copy
    from dataclasses import replace

    from sklearn.metrics import adjusted_rand_score

    from spco.model import gibbs

    model, labels, run_seed = _fitted(sweeps, seed_index)
    data, h = model.data_, model.hyperparameters_
    new = data.homes == data.n_homes - 1
    labelled = new & (labels != "None")
    out: dict = {"fit_seed": run_seed, "sweeps": sweeps, "more": more, "every": every, "seed": seed,
                 "start": {"ari": adjusted_rand_score(labels[labelled], model.state_.concepts[labelled]),
                           "concepts_used": len(set(model.state_.concepts[new].tolist()))}}
    for variant in ("without", "with"):
        state = copy.deepcopy(model.state_)
        rng = np.random.default_rng(seed)
        trace = []
        for i in range(more):
            settings = replace(model.settings_, phi_moves=variant == "with" and i % every == 0)
            t0 = time.process_time()
            gibbs.sweep(data, state, h, settings, rng, swaps=gibbs.swaps_due(sweeps + i))
            trace.append({"sweep": sweeps + i, "move": settings.phi_moves, "cpu": time.process_time() - t0,
                          "ari": adjusted_rand_score(labels[labelled], state.concepts[labelled]),
                          "concepts_used": len(set(state.concepts[new].tolist()))})
            print(variant, trace[-1], flush=True)
        by_place = {p: dict(Counter(state.concepts[new & (labels == p)].tolist()))
                    for p in sorted(set(labels[new]))}
        out[variant] = {"trace": trace, "final_by_place": by_place,
                        "cpu_seconds": float(sum(t["cpu"] for t in trace))}
    return out


def phi_acceptance(sweeps: int, seed_index: int) -> dict:
    """The power target's φ^v step during the fit (:func:`_fitted`): per sweep and concept the share of
    dimensions the step moved (:meth:`HierarchicalMultinomial.accept_shared`, blocked: a block is moved
    when its proposal is accepted, so this is the blocks' acceptance rate over the step's passes, each
    dimension counted once), recorded by wrapping it (the sharded fit's global step calls it), and the
    CPU seconds of the wrapped steps."""
    import time

    from spco.model.observations import HierarchicalMultinomial as HM

    original = HM.accept_shared
    moved, used, cpu = [], [], []

    def recorded(log_weights, log_phi, prior, tables, frac, rng, fractional=True, **kw):
        start = time.process_time()
        out = original(log_weights, log_phi, prior, tables, frac, rng, fractional, **kw)
        cpu.append(time.process_time() - start)
        moved.append((out != log_phi).mean(axis=1))
        used.append((np.asarray(tables) + frac).sum(axis=1) > 0)
        return out

    HM.accept_shared = staticmethod(recorded)
    try:
        _fitted(sweeps, seed_index)
    finally:
        HM.accept_shared = staticmethod(original)
    mv, use = np.array(moved), np.array(used)
    cols = np.flatnonzero(use.all(axis=0))
    return {"sweeps": len(mv), "concepts_with_tables": cols.tolist(),
            "share_moved_per_concept_mean": np.round(mv[:, cols].mean(axis=0), 3).tolist(),
            "share_moved_per_concept_last_40": np.round(mv[-40:, cols].mean(axis=0), 3).tolist(),
            "steps_moving_nothing_per_concept": (mv[:, cols] == 0).sum(axis=0).tolist(),
            "phi_step_cpu_seconds_total": round(float(sum(cpu)), 2)}


def main(argv: list[str] | None = None) -> int:
    """Command line: ``fit``, ``evidence``, ``table``, ``check`` or ``move``."""
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("what", choices=("fit", "evidence", "check", "table", "move", "chain", "phi-accept"))
    p.add_argument("--out", type=Path, default=Path("phimarg"))
    p.add_argument("--sweeps", type=int, default=60)
    p.add_argument("--seed", type=int, default=0, help="development seed (trial_seed(seed, 0))")
    p.add_argument("--draws", type=int, default=40, help="table draws of φ^v given the other homes")
    p.add_argument("--burn", type=int, default=30, help="φ^v steps before the first kept draw")
    p.add_argument("--evidence-seed", type=int, default=0, help="seed of the table draws")
    p.add_argument("--passes", type=int, default=3, help="move: passes over the new home's blocks")
    p.add_argument("--more", type=int, default=20, help="chain: sweeps after the fit, each variant")
    p.add_argument("--every", type=int, default=1, help="chain: the move every this many sweeps")
    p.add_argument("--proposal-only", action="store_true",
                   help="evidence: φ^v given the tables as the proposal Dir(α + M + F), w left out")
    a = p.parse_args(argv)
    if a.what == "fit":
        fit(a.out, a.sweeps, a.seed)
    elif a.what == "evidence":
        result = evidence(a.out, a.draws, a.burn, a.evidence_seed, not a.proposal_only)
        name = "evidence_proposal_only.json" if a.proposal_only else "evidence.json"
        (a.out / name).write_text(json.dumps(result, indent=1))
        print_table(result)
    elif a.what == "table":
        table(a.out)
    elif a.what == "chain":
        result = chain(a.sweeps, a.seed, a.more, a.every, a.evidence_seed)
        a.out.mkdir(parents=True, exist_ok=True)
        (a.out / f"chain_{a.seed}_every{a.every}.json").write_text(json.dumps(result, indent=1))
        for variant in ("without", "with"):
            last = result[variant]["trace"][-1]
            print(variant, f"ARI {last['ari']:.3f}", f"concepts {last['concepts_used']}",
                  f"CPU {result[variant]['cpu_seconds']:.1f} s", result[variant]["final_by_place"])
    elif a.what == "phi-accept":
        print(json.dumps(phi_acceptance(a.sweeps, a.seed), indent=1))
    elif a.what == "move":
        result = move(a.out, a.passes, a.evidence_seed)
        (a.out / f"move_{a.evidence_seed}.json").write_text(json.dumps(result, indent=1))
        print(json.dumps({k: result[k] for k in ("before", "after", "concepts_used_before",
                                                  "concepts_used_after", "cpu_seconds")}, indent=1))
    elif a.what == "check":
        result = check()
        print(json.dumps(result, indent=1))
        if a.out:
            a.out.mkdir(parents=True, exist_ok=True)
            (a.out / "check.json").write_text(json.dumps(result, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
