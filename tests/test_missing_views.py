"""Samples without a view: the visual likelihood left out (marginalised), homes without any view,
and the mask through data, files, the sampler, knowledge, the command line and the experiments."""

from __future__ import annotations

import json
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
import scipy.sparse as sp
from click.testing import CliRunner
from scipy import stats
from scipy.special import softmax

from spco.data.environment import Corpus, Environment
from spco.data.plain import read_home, write_home
from spco.errors import ConfigurationError, DataFormatError
from spco.model import assignments, gibbs
from spco.model.home_shard import prepare_home
from spco.model.observations import HierarchicalMultinomial
from spco.model.state import PreparedData

P_MIN = 1e-3


# tiny problems call the compiled kernels thousands of times: one thread (conftest.py)
pytestmark = pytest.mark.usefixtures("single_numba_thread")


def _home(n: int = 24, d: int = 8, seed: int = 0, name: str = "flat") -> Environment:
    rng = np.random.default_rng(seed)
    places = np.arange(n) % 3
    centres = np.array([[0.0, 0.0], [4.0, 0.0], [0.0, 4.0]])
    theta = rng.uniform(-np.pi, np.pi, n)
    positions = np.column_stack([centres[places] + rng.normal(0, 0.3, (n, 2)), np.sin(theta), np.cos(theta)])
    profiles = rng.dirichlet(np.full(d, 0.5), size=3)
    visual = np.vstack([rng.multinomial(60, profiles[p]) for p in places])
    words = ["this is the kitchen", "this is the bath", "this is the bedroom"]
    return Environment(name=name, ids=np.arange(n), positions=positions, visual=visual,
                       sentences=tuple(words[p] for p in places), is_test=np.zeros(n, dtype=bool))


# ------------------------------------------------------------------------------ data and files
def test_environment_mask_zeroes_the_rows_and_is_checked() -> None:
    home = _home()
    mask = np.zeros(home.n_samples, dtype=bool)
    mask[[1, 5, 7]] = True
    part = home.with_views_missing(mask)
    assert part.n_views == home.n_samples - 3
    assert part.visual[[1, 5, 7]].nnz == 0 and (part.visual[[0, 2]] != home.visual[[0, 2]]).nnz == 0
    train = part.training_data()
    assert train.view_missing.tolist() == mask.tolist()
    with pytest.raises(DataFormatError, match="missing-view mask must have shape"):
        replace(home, view_missing=np.zeros(3, dtype=bool))
    with pytest.raises(DataFormatError, match="every view marked missing"):
        replace(home, visual=sp.csr_array((home.n_samples, 0)))
    none = replace(home, visual=sp.csr_array((home.n_samples, 0)),
                   view_missing=np.ones(home.n_samples, dtype=bool))
    assert none.n_features == 0 and none.with_visual_dimension(8).visual.shape == (home.n_samples, 8)
    with pytest.raises(DataFormatError, match="views of 8 features, not 5"):
        home.with_visual_dimension(5)
    corpus = Corpus([home, replace(none, name="camera-less")])  # widened to the others' dimension
    assert corpus.n_features == 8 and corpus["camera-less"].view_missing.all()


def test_plain_format_writes_and_reads_missing_views(tmp_path: Path) -> None:
    home = _home()
    mask = np.arange(home.n_samples) % 4 == 0
    write_home(home.with_views_missing(mask), tmp_path / "part")
    back = read_home(tmp_path / "part")
    assert back.view_missing.tolist() == mask.tolist()
    assert (back.visual != home.with_views_missing(mask).visual).nnz == 0
    with np.load(tmp_path / "part" / "visual.npz") as npz:
        assert npz["missing"].tolist() == mask.tolist()
    none = replace(home, visual=sp.csr_array((home.n_samples, 0)), view_missing=np.ones(home.n_samples, bool))
    write_home(none, tmp_path / "none")
    assert not (tmp_path / "none" / "visual.npz").exists()  # a home without any view: no visual file
    back = read_home(tmp_path / "none")
    assert back.n_features == 0 and back.view_missing.all()
    # a dense visual.npz with a boolean 'missing' array: the marked rows are ignored, whatever they hold
    dense = home.visual.toarray()
    np.savez(tmp_path / "part" / "visual.npz", visual=dense, missing=mask)
    back = read_home(tmp_path / "part")
    assert back.view_missing.tolist() == mask.tolist() and back.visual[np.flatnonzero(mask)].nnz == 0
    np.savez(tmp_path / "part" / "visual.npz", visual=dense, missing=np.arange(home.n_samples) % 3)
    with pytest.raises(DataFormatError, match="'missing' array must be boolean"):
        read_home(tmp_path / "part")
    np.savez(tmp_path / "part" / "visual.npz", visual=dense, missing=mask[:5])
    with pytest.raises(DataFormatError, match="one entry per sample"):
        read_home(tmp_path / "part")


def test_cache_keeps_the_mask(tmp_path: Path) -> None:
    from spco.data.cache import read_cache, write_records
    from spco.data.records import HomeRecord

    home = _home()
    mask = np.arange(home.n_samples) % 5 == 1
    none = replace(home, name="none", visual=sp.csr_array((home.n_samples, 0)),
                   view_missing=np.ones(home.n_samples, bool))
    records = [HomeRecord(home.with_views_missing(mask), None, "x"), HomeRecord(none, None, "y")]
    write_records(records, tmp_path / "cache.npz")
    part, back = read_cache(tmp_path / "cache.npz")
    assert part.view_missing.tolist() == mask.tolist() and back.view_missing.all() and back.n_features == 0


# ------------------------------------------------------------------------------ the sampler
def test_assignments_leave_the_missing_views_out_brute_force() -> None:
    """p(C_t, R_t | rest) of a sample without a view has no visual factor: the local step's draws
    match the enumeration of G π N(x) Π θ^w (and, for the others, Π θ^v too) although the masked
    samples' rows held counts before they were marked."""
    rng = np.random.default_rng(0)
    n_distinct, copies, L, K, D, V = 4, 5000, 3, 2, 4, 3
    positions = rng.normal(size=(n_distinct, 4))
    visual = rng.integers(0, 4, size=(n_distinct, D))
    words = rng.integers(0, 2, size=(n_distinct, V))
    missing = np.array([True, False, True, False])
    data = prepare_home(np.repeat(positions, copies, axis=0), sp.csr_array(np.repeat(visual, copies, axis=0)),
                        [None] * (n_distinct * copies), _vocabulary(V), 1, 1.0, np.zeros(4),
                        view_missing=np.repeat(missing, copies))
    data = replace(data, words=sp.csr_array(np.repeat(words, copies, axis=0).astype(np.int64)))
    assert data.n_views.tolist() == [2 * copies]
    state = gibbs.GibbsState(
        concepts=np.zeros(n_distinct * copies, dtype=np.int64),
        regions=np.zeros(n_distinct * copies, dtype=np.int64),
        log_g=np.log(rng.dirichlet(np.full(L, 3.0), size=1)), log_g0=np.log(np.full(L, 1 / L)),
        log_pi=np.log(rng.dirichlet(np.full(K, 2.0), size=(1, L))), means=rng.normal(size=(1, K, 4)),
        covariances=np.stack([[np.eye(4) * 0.8 for _ in range(K)]]),
        log_theta_v=np.log(rng.dirichlet(np.full(D, 1.0), size=(1, L))),
        log_theta_w=np.log(rng.dirichlet(np.full(V, 2.0), size=(1, L))),
        log_phi_v=np.log(np.full((L, D), 1 / D)), log_phi_w=np.log(np.full((L, V), 1 / V)),
        word_mask=np.ones(V, dtype=bool))
    exact = gibbs.SamplerSettings.create("exact", prune=False)
    assignments.local_step(data, state, exact, np.random.default_rng(1))
    flat = (state.concepts * K + state.regions).reshape(n_distinct, copies)
    for t in range(n_distinct):
        gauss = np.array([stats.multivariate_normal.logpdf(positions[t], state.means[0, m],
                                                           state.covariances[0, m]) for m in range(K)])
        seen = 0 if missing[t] else visual[t] @ state.log_theta_v[0].T
        concept = words[t] @ state.log_theta_w[0].T + seen
        table = state.log_g[0][:, None] + state.log_pi[0] + gauss[None, :] + concept[:, None]
        observed = np.bincount(flat[t], minlength=L * K)
        assert stats.chisquare(observed, softmax(table.ravel()) * copies).pvalue > P_MIN, t
    # the visual statistics count the views that exist and nothing else
    counts = HierarchicalMultinomial.statistics(data.visual, data.homes, state.concepts, 1, L)
    expected = np.zeros((1, L, D))
    for row, c in enumerate(state.concepts):
        if not missing[row // copies]:
            expected[0, c] += visual[row // copies]
    np.testing.assert_allclose(counts, expected)


def _vocabulary(n: int):
    from spco.data.language import Vocabulary

    return Vocabulary(tuple(f"w{i}" for i in range(n)))


def test_a_home_with_every_view_missing_runs_the_chain_of_the_home_without_a_visual_file(
        tmp_path: Path) -> None:
    """Learnt alone or adapted to knowledge with views: the same chain, draw for draw, whether its
    views are marked missing in visual.npz (counts and all) or it has no visual file at all."""
    from spco.data.loading import load_home
    from spco.knowledge import adapt, fit_knowledge

    home = _home(name="new")
    masked = tmp_path / "masked"
    write_home(home, masked)
    with np.load(masked / "visual.npz") as npz:
        arrays = dict(npz)
    np.savez(masked / "visual.npz", **arrays, missing=np.ones(home.n_samples, dtype=bool))
    bare = tmp_path / "bare"
    write_home(replace(home, visual=sp.csr_array((home.n_samples, 0)),
                       view_missing=np.ones(home.n_samples, bool)), bare)
    a, b = load_home(masked), load_home(bare)
    assert a.n_features == 8 and b.n_features == 0 and a.view_missing.all() and b.view_missing.all()
    assert Corpus([a]).n_features == 0  # no view anywhere: learnt from poses and words
    ka = fit_knowledge(Corpus([a]), n_iterations=12, random_state=3)
    kb = fit_knowledge(Corpus([b]), n_iterations=12, random_state=3)
    for name in ("log_phi_words", "log_g0", "word_mask"):
        np.testing.assert_array_equal(getattr(ka, name), getattr(kb, name))
    experienced = fit_knowledge(Corpus([_home(seed=1, name="old")]), n_iterations=8, random_state=0)
    ha = adapt(experienced, a, n_iterations=8, random_state=5)
    hb = adapt(experienced, b, n_iterations=8, random_state=5)
    np.testing.assert_array_equal(ha.state.concepts, hb.state.concepts)
    np.testing.assert_array_equal(ha.state.regions, hb.state.regions)
    np.testing.assert_array_equal(ha.state.log_theta_w, hb.state.log_theta_w)
    assert ha.view_missing.all() and hb.visual.shape == (home.n_samples, 8)


def test_knowledge_with_views_adapts_to_a_home_partly_without(tmp_path: Path) -> None:
    from spco.knowledge import Observation, adapt, fit_knowledge, load_home_model, teach, what

    knowledge = fit_knowledge(Corpus([_home(seed=1, name="old"), _home(seed=2, name="older")]),
                              n_iterations=10, random_state=0)
    home = _home(seed=3, name="new").with_views_missing(np.arange(24) % 3 == 0)
    model = adapt(knowledge, home, n_iterations=10, random_state=0)
    assert model.n_views == 16 and "16 with a view" in model.describe()
    model.save(tmp_path / "h.spco")
    back = load_home_model(tmp_path / "h.spco")
    assert back.view_missing.tolist() == model.view_missing.tolist()
    taught = teach(back, observations=[Observation(4.0, 0.0, 0.0, sentence="this is the bath")], n_sweeps=3)
    assert taught.view_missing[-1] and taught.n_samples == 25
    assert what(taught, 4.0, 0.0, 0.0).words.shape[0] == 1  # a pose alone, no view


# ------------------------------------------------------------------------------ command line, experiments
def test_command_line_learns_a_home_without_views(tmp_path: Path) -> None:
    from spco.cli import main

    home = _home()
    bare = replace(home, visual=sp.csr_array((home.n_samples, 0)), view_missing=np.ones(home.n_samples, bool))
    write_home(bare, tmp_path / "homes" / "bare")
    runner = CliRunner()
    k, h = tmp_path / "k.spco", tmp_path / "h.spco"
    result = runner.invoke(main, ["fit", "--data", str(tmp_path / "homes"), "--iterations", "10",
                                  "--model", "spcotransfer", "--out", str(k)])
    assert result.exit_code == 0, result.output
    result = runner.invoke(main, ["adapt", str(k), "--home", str(tmp_path / "homes" / "bare"),
                                  "--iterations", "5", "--out", str(h)])
    assert result.exit_code == 0, result.output
    result = runner.invoke(main, ["where", str(h), "kitchen", "--json"])
    assert result.exit_code == 0, result.output
    xy = np.array([[p["x"], p["y"]] for p in json.loads(result.output)["positions"]])
    assert np.linalg.norm(xy.mean(0)) < 1.5  # the kitchen is at (0, 0)
    result = runner.invoke(main, ["teach", str(h), "--x", "0", "--y", "4", "--theta", "0",
                                  "--sentence", "this is the bedroom"])
    assert result.exit_code == 0 and "without a view" in result.output, result.output


def test_experiment_removes_the_new_homes_views() -> None:
    from spco.evaluation.config import ExperimentConfig
    from spco.evaluation.runs import without_views

    home = _home()
    a, b = without_views(home, 30, 7), without_views(home, 70, 7)
    assert a.view_missing.sum() == round(0.3 * 24) and b.view_missing.sum() == round(0.7 * 24)
    assert (a.view_missing <= b.view_missing).all()  # a higher percentage removes a superset
    assert without_views(home, 30, 7).view_missing.tolist() == a.view_missing.tolist()
    assert without_views(home, 100, 7).view_missing.all()
    with pytest.raises(ConfigurationError, match="views_missing"):
        ExperimentConfig(views_missing=120).validated()


def test_import_bag_keeps_an_utterance_without_an_image_when_asked(tmp_path: Path) -> None:
    from spco.data.bagtour import write_tour
    from spco.data.rosbag import BagImportSettings, import_bags

    bag = tmp_path / "tour.bag"
    write_tour(bag, seconds=20, size=(64, 48), image_hz=1.0, speech_every=5.0)
    # images 3 ms after each second, utterances at 2.5, 7.5, …: none has an image within 1 ms (--at travel:
    # utterances keep the tolerance; --at images would widen it to the camera's interval)
    strict = BagImportSettings(speech_topic="/speech", every_metres=0, tolerance=0.001, at="travel")
    with pytest.raises(DataFormatError, match="no image within"):
        import_bags([bag], tmp_path / "skipped", strict)
    summary = import_bags([bag], tmp_path / "kept", replace(strict, keep_without_image=True))
    assert summary.samples == summary.without_view == 4 and summary.taught == 4
    assert "without a view kept" in summary.format()
    from spco.features import DEFAULT_EXTRACTOR, build_extractor

    home = read_home(tmp_path / "kept", extractor=build_extractor(DEFAULT_EXTRACTOR))
    assert home.view_missing.all() and home.n_taught == 4
    mixed = import_bags([bag], tmp_path / "mixed", BagImportSettings(
        speech_topic="/speech", every_metres=0, every_seconds=2.0, tolerance=0.01, at="travel",
        keep_without_image=True))
    assert mixed.without_view == 4 and mixed.samples == 14  # the samples along the way have their image
    home = read_home(tmp_path / "mixed", extractor=build_extractor(DEFAULT_EXTRACTOR))
    taught = np.array([s is not None for s in home.sentences])
    assert home.view_missing.tolist() == taught.tolist()


def test_homes_read_in_the_shards_agree_on_the_visual_dimension(tmp_path: Path) -> None:
    from spco.model.shard import HomeShard
    from spco.model.sources import FolderHomes

    home = _home(name="seen")
    write_home(home, tmp_path / "homes" / "seen")
    write_home(replace(home, name="blind", visual=sp.csr_array((home.n_samples, 0)),
                       view_missing=np.ones(home.n_samples, bool)), tmp_path / "homes" / "blind")
    source = FolderHomes.create(tmp_path / "homes")
    assert source.n_features == 8
    parts = [source.prepare_homes(0, 1), source.prepare_homes(1, 2)]
    assert {p.visual.shape[1] for p in parts} == {8}
    assert [p.n_views.tolist() for p in parts] == [[0], [24]]  # blind, seen (sorted by name)
    from spco.model.hyperparameters import TransferHyperparameters

    shard = HomeShard.start(source.prepare_homes(0, 2), len(source.vocabulary), TransferHyperparameters(),
                            gibbs.SamplerSettings.create("exact", prune=False), np.random.default_rng(0))
    assert shard.n_views().tolist() == [0, 24]  # the shard API: samples with a view per home
    blind_only = FolderHomes.create(tmp_path / "homes", names=["blind"])
    assert blind_only.n_features == 0 and blind_only.prepare_homes(0, 1).visual.shape == (24, 0)


def test_the_ray_engine_hands_the_mask_to_its_actors() -> None:
    pytest.importorskip("ray", reason="Ray is not installed (pip install -e '.[ray]')")
    from spco.engines.ray import _writable_data

    home = _home().with_views_missing(np.arange(24) % 2 == 0)
    data = PreparedData.from_corpus(Corpus([home]), 1.0)
    sent = _writable_data(data)
    assert sent.view_missing.tolist() == data.view_missing.tolist() == home.view_missing.tolist()
