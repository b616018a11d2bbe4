"""The parameter steps of a sweep, given the statistics of its assignments
(:mod:`spco.model.sweep_statistics`): the **global step** (the shared φ^v, φ^w, G_0 and the word
channels' ψ), the **home step** (θ, G_e, π, μ, Σ of every home, and the place channel's home level),
the authors' versions of both (the reference variant), and the label swaps within each home
(:func:`swap_labels`, which relabel a home's concepts: :func:`apply_permutations`)."""

from __future__ import annotations

import numpy as np

from spco.model import allocation
from spco.model.home_place import draw_home_place, shared_place_counts
from spco.model.hyperparameters import TransferHyperparameters
from spco.model.kernels.dirichlet import log_dirichlet
from spco.model.moves import concept_swap_step
from spco.model.observations import GaussianRegions, HierarchicalMultinomial, NIWPrior
from spco.model.phi_moves import phi_after_move
from spco.model.state import GibbsState, PreparedData, SamplerSettings
from spco.model.sweep_statistics import Statistics
from spco.model.word_channels import sample_channels


def niw_prior(data: PreparedData, hyper: TransferHyperparameters, settings: SamplerSettings) -> NIWPrior:
    """The NIW prior in the sampler's units (μ0 = map centre, or 0 in the reference variant);
    its arrays are read-only."""
    key = (hyper, settings.variant)
    try:
        prior = data.niw_priors.get(key)
    except TypeError:  # hyperparameters holding lists (unhashable): no cache
        return _build_niw_prior(data, hyper, settings)
    if prior is None:
        prior = data.niw_priors[key] = _build_niw_prior(data, hyper, settings)
    return prior


def _build_niw_prior(data: PreparedData, hyper: TransferHyperparameters,
                     settings: SamplerSettings) -> NIWPrior:
    scale = np.array([data.position_scale, data.position_scale, 1.0, 1.0])
    psi0 = hyper.psi0_matrix_m2() * np.outer(scale, scale)
    if settings.variant == "reference":
        mu0 = np.zeros((data.n_homes, 4))
    elif hyper.mu0 is not None:
        mu0 = np.tile(np.asarray(hyper.mu0, dtype=float) * scale, (data.n_homes, 1))
    else:
        mu0 = data.map_centres.copy()
    mu0.flags.writeable = False
    psi0.flags.writeable = False
    return NIWPrior(mu0=mu0, kappa0=hyper.kappa0, psi0=psi0, nu0=hyper.nu0)


def global_step(stats: Statistics, state: GibbsState, hyper: TransferHyperparameters,
                rng: np.random.Generator, moved: tuple | None = None) -> None:
    """Exact: φ^v, φ^w and G_0 given CRT table counts (θ and G_e integrated out); φ^v from the
    views' weighted counts (:meth:`HierarchicalMultinomial.sample_shared_given_counts`), or after a
    φ^v-marginal block move with the other homes' tables it drew (``moved``: :mod:`spco.model.phi_moves`)."""
    if moved is not None:
        state.log_phi_v = phi_after_move(stats.visual, state.log_phi_v, hyper.delta_visual,
                                         hyper.alpha_visual, moved, rng, passes=hyper.phi_passes)
    else:
        state.log_phi_v = HierarchicalMultinomial.sample_shared_given_counts(
            stats.visual, state.log_phi_v, hyper.delta_visual, hyper.alpha_visual, rng,
            passes=hyper.phi_passes)
    tables_w = HierarchicalMultinomial.sample_tables(stats.words, state.log_phi_w, hyper.delta_word, rng)
    state.log_phi_w = HierarchicalMultinomial.sample_shared(tables_w, hyper.alpha_word, rng)
    state.log_g0 = allocation.sample_global_concept_weights(stats.concepts, state.log_g0, hyper.gamma,
                                                            hyper.gamma0, rng)
    if stats.channel is not None and state.channels is not None:
        counts = shared_place_counts(stats, state.channels, hyper, rng)  # (the home level: ψ_l's tables)
        state.channels = sample_channels(counts, state.channels, rng)


def home_step(data: PreparedData, state: GibbsState, stats: Statistics, hyper: TransferHyperparameters,
              settings: SamplerSettings, rng: np.random.Generator) -> None:
    """θ^v, θ^w, G_e, π and the region Gaussians of every home, given φ, G_0 and the assignments."""
    K, L = hyper.n_regions, hyper.n_concepts
    if settings.hierarchical:
        # drawn into the previous θ^v's memory: no new (E, L, D) array per sweep
        state.log_theta_v = HierarchicalMultinomial.sample_specific(
            stats.visual, state.log_phi_v, hyper.delta_visual, rng, out=state.log_theta_v)
        state.log_theta_w = HierarchicalMultinomial.sample_specific(stats.words, state.log_phi_w,
                                                                    hyper.delta_word, rng)
        state.log_g = allocation.sample_home_concept_weights(stats.concepts, state.log_g0, hyper.gamma, rng)
    else:  # SpCoA: θ_l ~ Dir(α + n), G ~ Dir(γ/L + n)
        state.log_theta_v = log_dirichlet(hyper.alpha_visual + stats.visual, rng)
        state.log_theta_w = log_dirichlet(hyper.alpha_word + stats.words, rng)
        state.log_g = log_dirichlet(hyper.gamma / L + stats.concepts, rng)
        state.log_phi_v = _log_mean(state.log_theta_v)  # exported as the shared part
        state.log_phi_w = _log_mean(state.log_theta_w)
        state.log_g0 = _log_mean(state.log_g)
    if stats.home_place is not None and state.channels is not None:  # ψ_{e,l} | ψ_l, tokens
        state.channels = draw_home_place(state.channels, stats.home_place, hyper.delta_place, rng)
    state.log_pi = allocation.sample_region_weights(stats.regions_by_concept, hyper.beta / K, rng)
    state.means, state.covariances = GaussianRegions.sample_posterior(
        stats.region_count, stats.region_total, stats.region_scatter, niw_prior(data, hyper, settings), rng)
    state.region_counts = stats.region_count.astype(np.int64)


def home_step_reference(data: PreparedData, state: GibbsState, stats: Statistics,
                        hyper: TransferHyperparameters, settings: SamplerSettings,
                        rng: np.random.Generator, regions_too: bool = True) -> None:
    """The authors' per-home updates: NIW (empty regions re-seeded), θ | previous φ, π, G_e."""
    if regions_too:
        means, covs = GaussianRegions.sample_posterior(stats.region_count, stats.region_total,
                                                       stats.region_scatter, niw_prior(data, hyper, settings),
                                                       rng)
        empty = stats.region_count == 0
        n_empty = int(empty.sum())
        if n_empty:
            box = np.array([6.0, 6.0, 1.0, 1.0])
            means[empty] = rng.uniform(-box, box, size=(n_empty, 4))
            covs[empty] = 100.0 * np.eye(4)
        state.means, state.covariances = means, covs
    state.log_theta_v = HierarchicalMultinomial.sample_specific(
        stats.visual, state.log_phi_v, hyper.delta_visual, rng, out=state.log_theta_v)
    state.log_theta_w = HierarchicalMultinomial.sample_specific(stats.words, state.log_phi_w,
                                                                hyper.delta_word, rng)
    state.log_pi = allocation.sample_region_weights(stats.regions_by_concept, hyper.beta, rng)
    state.log_g = allocation.sample_home_concept_weights(stats.concepts, state.log_g0, hyper.gamma, rng,
                                                         extra=50.0)
    state.region_counts = stats.region_count.astype(np.int64)


def global_step_reference(stats: Statistics, state: GibbsState, hyper: TransferHyperparameters,
                          rng: np.random.Generator) -> None:
    """The authors' shared updates: φ ~ Dir(α + pooled counts), G_0 ~ Dir(γ0 + Σ_e n_e)."""
    state.log_phi_v = log_dirichlet(hyper.alpha_visual + stats.visual.sum(0), rng)
    state.log_phi_w = log_dirichlet(hyper.alpha_word + stats.words.sum(0), rng)
    state.log_g0 = log_dirichlet(hyper.gamma0 + stats.concepts.sum(0), rng)


def _log_mean(log_p: np.ndarray) -> np.ndarray:
    """log of the mean over the first axis of exp(log_p)."""
    if log_p.shape[0] == 1:
        return log_p[0].copy()
    top = log_p.max(axis=0)
    return np.log(np.exp(log_p - top).mean(axis=0)) + top


def swap_labels(data: PreparedData, state: GibbsState, stats: Statistics, hyper: TransferHyperparameters,
                settings: SamplerSettings, rng: np.random.Generator) -> None:
    """Metropolis–Hastings label swaps within each home, θ marginalised (see
    :mod:`spco.model.moves`), then θ of the homes that changed redrawn from its conditional."""
    place = place_home = None
    if stats.home_place is not None and state.channels is not None:  # ψ_{e,l} integrated out
        place_home = (stats.home_place, state.channels.log_place, hyper.delta_place)
    elif stats.place_tokens is not None and state.channels is not None:
        place = (stats.place_tokens, state.channels.log_place)
    perms = concept_swap_step(stats.visual, state.log_phi_v, hyper.delta_visual, stats.words,
                              state.log_phi_w, hyper.delta_word, state.log_g, state.log_g0, hyper.gamma,
                              state.word_mask, rng, place=place, place_home=place_home)
    changed = np.flatnonzero((perms != np.arange(perms.shape[1])).any(axis=1))
    if changed.size == 0:
        return
    # θ of the homes that changed is redrawn below and the others keep theirs: no need to permute it
    apply_permutations(data, state, perms, theta=False)
    slots = (changed[:, None], perms[changed])
    visual, words = stats.visual[slots], stats.words[slots]
    _relabel_visual_cache(data, state, perms, changed, visual)
    state.log_theta_v[changed] = HierarchicalMultinomial.sample_specific(visual, state.log_phi_v,
                                                                         hyper.delta_visual, rng)
    state.log_theta_w[changed] = HierarchicalMultinomial.sample_specific(words, state.log_phi_w,
                                                                         hyper.delta_word, rng)
    if place_home is not None:  # the changed homes' ψ_{e,l} redrawn, as θ^w (their tokens relabelled)
        relabelled = stats.home_place[np.arange(perms.shape[0])[:, None], perms]
        state.channels = draw_home_place(state.channels, relabelled, hyper.delta_place, rng, changed)


def _relabel_visual_cache(data: PreparedData, state: GibbsState, perms: np.ndarray, changed: np.ndarray,
                          visual: np.ndarray) -> None:
    """Carry the visual count cache through a relabelling (``visual``: the changed homes' counts in
    their new slot order), so that the next sweep moves only the rows of samples that change
    concept again instead of recounting the relabelled homes."""
    cache = state.visual_cache
    if cache is None or cache.visual is not data.visual or cache.concepts.shape != state.concepts.shape:
        return
    inverse = np.argsort(perms, axis=1)
    cache.concepts = inverse[data.homes, cache.concepts]
    cache.counts.flags.writeable = True
    cache.counts[changed] = visual
    cache.counts.flags.writeable = False


def apply_permutations(data: PreparedData, state: GibbsState, perms: np.ndarray, theta: bool = True) -> None:
    """Relabel concepts within each home: slot j of home e takes its old concept perms[e, j].
    ``theta=False`` leaves θ^v, θ^w as they are (for a caller that redraws them)."""
    if (perms == np.arange(perms.shape[1])).all():
        return
    homes = np.arange(perms.shape[0])[:, None]
    if theta:
        state.log_theta_v = state.log_theta_v[homes, perms]
        state.log_theta_w = state.log_theta_w[homes, perms]
    state.log_g = state.log_g[homes, perms]
    state.log_pi = state.log_pi[homes, perms]
    inverse = np.argsort(perms, axis=1)  # old concept -> new slot
    state.concepts = inverse[data.homes, state.concepts]

