"""Initialisation inside the shards (spco.model.shard_init, spco.model.sources) and checkpoints on
disk (spco.engines.checkpoints).

Each shard prepares and starts its own homes and the warm start runs as map → reduce steps; every
home draws from its own stream, so the start depends on the seed only: any number of shards, on
the local or the Ray engine, gives the same chain from it. The Ray tests start a local Ray instance
(2 CPUs) themselves."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.sparse as sp

from spco.data.synthetic import SyntheticConfig, generate_homes
from spco.engines import LocalEngine
from spco.model import alignment, gibbs
from spco.model.sources import PreparedHomes, SyntheticHomes, concatenate_data
from spco.model.state import PreparedData
from spco.model.transfer import SpatialConceptModel

N_SWEEPS = 12
CONFIG = SyntheticConfig(n_features=64, n_train=12)


@pytest.fixture(scope="module")
def source() -> SyntheticHomes:
    return SyntheticHomes.create(5, seed=2, config=CONFIG, new_homes=1)


def model_settings(prune: bool = True, variant: str = "exact"):
    model = SpatialConceptModel(variant=variant, random_state=0, prune_words=prune)
    return model.checked_hyperparameters(), model.sampler_settings()


run_of: list = []  # the run of the last chain() (for its callbacks)


def chain(source, engine, prune: bool = True, variant: str = "exact", seed: int = 5, after_sweep=None):
    """(log-joint trace, concepts, regions, the run) after N_SWEEPS sweeps from the sharded start."""
    hyper, settings = model_settings(prune, variant)
    run = engine.start_source(source, hyper, settings, np.random.default_rng(seed))
    run_of[:] = [run]
    trace = run.fit(N_SWEEPS, after_sweep)
    state = run.state()
    run.close()
    return trace, state.concepts, state.regions, run


def test_synthetic_source_makes_the_homes_generate_homes_makes(source) -> None:
    """Each part generates its homes alone, from the seed and their indices: joined, the parts are
    the data of generate_homes' corpus (same vocabulary, counts, positions, map centres)."""
    corpus = generate_homes(5, seed=2, new_homes=1, config=CONFIG, specific_rooms=False)
    whole = PreparedData.from_corpus(corpus, 1.0)
    assert source.vocabulary.words == corpus.vocabulary.words
    parts = [p.prepare() for p in source.parts(2)]
    assert [p.n_homes for p in parts] == [2, 3]
    joined = concatenate_data(parts)
    assert (joined.visual != whole.visual).nnz == 0 and (joined.words != whole.words).nnz == 0
    for name in ("positions", "homes", "offsets", "map_centres"):
        np.testing.assert_array_equal(getattr(joined, name), getattr(whole, name))


@pytest.mark.parametrize("with_names", [False, True])
def test_streaming_alignment_equals_align_homes(with_names: bool) -> None:
    """align_in_order, fed the homes' counts in small batches as the sharded start fetches them,
    gives the permutations of gibbs.align_homes on all homes' counts in memory (names: synonyms
    matched by views included)."""
    rng = np.random.default_rng(3)
    E, L, D, V = 9, 6, 40, 12
    visual = rng.poisson(rng.gamma(0.5, 4.0, size=(E, L, D))).astype(np.int64)
    words = rng.poisson(rng.gamma(0.3, 3.0, size=(E, L, V))) * 5000
    words[rng.random((E, L)) < 0.3] = 0  # concepts without words (matched by their views)
    words[4] = 0  # an untaught home
    names = None
    if with_names:
        names = (rng.random((E, L, V)) < 0.15) * rng.integers(1, 4, size=(E, L, V)).astype(float)
        names[:, :, :2] = 0.0
        names[6, 1, 0] = names[7, 2, 0] = 5.0  # a synonym two later homes say, the first ones not
    expected = gibbs.align_homes(visual, words, 0.1, 0.05, names)

    def fetch(homes):
        return [alignment.HomeCounts(sp.csr_array(visual[e]), words[e],
                                     None if names is None else names[e]) for e in homes]

    said = None if names is None else names.sum(axis=1) > 0
    got = alignment.align_in_order(fetch, words.sum(axis=(1, 2)), said, 0.1, 0.05, L, batch=2)
    np.testing.assert_array_equal(got, expected)
    assert not (expected == np.arange(L)).all()  # the homes were relabelled: the test has teeth


@pytest.mark.parametrize("prune", [True, False])
def test_sharded_start_is_reproducible(source, prune: bool) -> None:
    """Same seed: the same chain again and with another number of shards (every home's own
    stream); a finite log joint after the first sweep; another seed: another chain."""
    first = chain(source, LocalEngine(2), prune)
    again = chain(source, LocalEngine(2), prune)
    np.testing.assert_array_equal(first[0], again[0])
    np.testing.assert_array_equal(first[1], again[1])
    assert np.isfinite(first[0]).all() and first[3].initialisation.bytes_received > 0
    other = chain(source, LocalEngine(3), prune)
    for a, b in zip(first[:3], other[:3], strict=True):
        np.testing.assert_array_equal(a, b)
    reseeded = chain(source, LocalEngine(2), prune, seed=6)
    assert not np.array_equal(first[0], reseeded[0])


def test_sharded_start_aligns_the_homes(source) -> None:
    """After the start, each place type takes one concept across the taught homes: the labels agree
    across homes (far more often than in the homes' own first states, whose labels are random)."""
    corpus = generate_homes(5, seed=2, new_homes=1, config=CONFIG, specific_rooms=False)
    hyper, settings = model_settings(prune=True)
    places = np.array([label for env in corpus
                       for label, test in zip(env.ground_truth.labels, env.is_test, strict=True) if not test])

    def agreement(state, n_homes: int) -> float:
        data = source.parts(1)[0].prepare()
        taught = data.homes < n_homes - 1
        agree = 0
        for place in np.unique(places[taught]):
            rows = taught & (places == place)
            agree += np.bincount(state.concepts[rows]).max()
        return agree / taught.sum()

    run = LocalEngine(2).start_source(source, hyper, settings, np.random.default_rng(5))
    sharded = agreement(run.state(), 5)
    data = PreparedData.from_corpus(corpus, 1.0)
    alone = gibbs.initialize(data, len(corpus.vocabulary), hyper, settings, np.random.default_rng(5))
    assert agreement(alone, 5) < 0.3
    assert sharded > 0.8


def test_prepared_source_and_reference_variant(source) -> None:
    """Data prepared in the driver as the source; the reference variant starts too (G_0 drawn by
    the driver, the same in every shard)."""
    data = source.parts(1)[0].prepare()
    prepared = PreparedHomes(data, source.n_words)
    trace, *_ = chain(prepared, LocalEngine(2), variant="reference")
    assert np.isfinite(trace).all()
    hyper, settings = model_settings(variant="reference")
    run = LocalEngine(2).start_source(prepared, hyper, settings, np.random.default_rng(1))
    g0 = [s.state.log_g0 for s in run.shards]
    np.testing.assert_array_equal(g0[0], g0[1])


def test_checkpoint_files_round_trip_and_refuse_bad_files(tmp_path, source) -> None:
    """A shard checkpoint reads back every array and the generator; a foreign or newer file is
    refused with its name."""
    from spco.engines import checkpoints

    hyper, settings = model_settings()
    run = LocalEngine(1).start_source(source, hyper, settings, np.random.default_rng(5))
    run.sweep(0)
    shard = run.shards[0]
    path = tmp_path / "s.npz"
    checkpoints.save_shard(path, shard.state, shard.rng_states())
    state, rng_state = checkpoints.load_shard(path)
    assert rng_state == shard.rng_states() and len(rng_state) == source.n_homes  # one per home
    for name in ("concepts", "regions", "log_theta_v", "log_phi_w", "word_mask", "region_counts"):
        np.testing.assert_array_equal(getattr(state, name), getattr(shard.state, name))
    assert state.candidate_words is None and not list(tmp_path.glob(".*tmp"))
    np.savez(tmp_path / "other.npz", x=np.zeros(2))
    with pytest.raises(checkpoints.CheckpointError, match=r"other\.npz"):
        checkpoints.load_shard(tmp_path / "other.npz")
    newer = tmp_path / "newer.npz"
    checkpoints._write_atomically(newer, {}, {"kind": "shard"})
    data = dict(np.load(newer))
    assert '"version": 3' in str(data["meta"])  # (no ψ_{e,l}: the version that holds the file)
    data["meta"] = np.array(str(data["meta"]).replace('"version": 3', '"version": 99'))
    np.savez(newer, **data)
    with pytest.raises(checkpoints.CheckpointError, match="version 99"):
        checkpoints.load_shard(newer)


# ----------------------------------------------------------------------------- Ray


def test_ray_actors_start_their_homes_as_local_shards_do(source, ray_session) -> None:
    """Actors that generate and initialise their own homes: the chain of as many local shards."""
    from spco.engines.ray import RayEngine

    local = chain(source, LocalEngine(2))
    seconds = []
    remote = chain(source, RayEngine(2, checkpoint_every=5),
                   after_sweep=lambda i, _: None if seconds else seconds.extend(run_of[0].setup_seconds()))
    for a, b in zip(local[:3], remote[:3], strict=True):
        np.testing.assert_array_equal(a, b)
    assert [sorted(s) for s in seconds] == [["initialise", "prepare"]] * 2


def test_ray_restarts_a_killed_actor_from_checkpoints_on_disk(tmp_path, source, ray_session) -> None:
    """Checkpoints in a directory (each actor writes its own file): killing an actor after sweep 7
    restarts the shards from the files of sweep 5, and the fit ends where the fault-free one ends."""
    from spco.engines import checkpoints
    from spco.engines.ray import RayEngine

    hyper, settings = model_settings()
    run = RayEngine(2, checkpoint_every=5, checkpoint_dir=tmp_path).start_source(
        source, hyper, settings, np.random.default_rng(5))
    killed = []

    def kill_once(iteration: int, _: float) -> None:
        if iteration == 7 and not killed:
            killed.append(True)
            ray_session.kill(run.actors[1])

    trace = run.fit(N_SWEEPS, kill_once)
    state = run.state()
    run.close()
    assert run.restarts == 1
    iteration, *_, paths = checkpoints.load_driver(tmp_path)
    assert iteration == 10 and all(p.exists() for p in paths)
    assert sorted(p.name for p in tmp_path.glob("shard-*")) == [p.name for p in paths]  # older removed
    local = chain(source, LocalEngine(2))
    np.testing.assert_array_equal(trace, local[0])
    np.testing.assert_array_equal(state.concepts, local[1])
