"""Homes read from their folders inside the shards (spco.model.sources.FolderHomes).

The driver fixes the vocabulary from the homes' sentences, one home at a time; each shard reads
only its homes' folders. The chain is the one of the same homes loaded in the driver
(PreparedHomes), and a missing or broken home is an error naming the file before any sweep."""

from __future__ import annotations

import numpy as np
import pytest

from spco.data.environment import Corpus
from spco.data.loading import load_homes
from spco.data.plain import write_corpus
from spco.data.synthetic import SyntheticConfig, generate_homes
from spco.engines import LocalEngine
from spco.errors import DataFormatError
from spco.model.sources import FolderHomes, PreparedHomes
from spco.model.state import PreparedData
from spco.model.transfer import SpatialConceptModel

N_SWEEPS = 8
CONFIG = SyntheticConfig(n_features=64, n_train=12)


@pytest.fixture(scope="module")
def folder(tmp_path_factory):
    root = tmp_path_factory.mktemp("homes")
    write_corpus(generate_homes(5, seed=3, config=CONFIG, new_homes=1), root)
    return root


def settings():
    model = SpatialConceptModel(variant="exact", random_state=0, prune_words=True)
    return model.checked_hyperparameters(), model.sampler_settings()


def chain(source, engine, seed: int = 4):
    """(log-joint trace, concepts, regions) after N_SWEEPS sweeps from the sharded start."""
    hyper, sampler = settings()
    run = engine.start_source(source, hyper, sampler, np.random.default_rng(seed))
    trace = run.fit(N_SWEEPS)
    state = run.state()
    run.close()
    return trace, state.concepts, state.regions


def driver_source(folder) -> PreparedHomes:
    corpus = Corpus(load_homes(folder))
    return PreparedHomes(PreparedData.from_corpus(corpus, 1.0), len(corpus.vocabulary))


def test_folder_source_matches_the_corpus_loaded_in_the_driver(folder) -> None:
    """Same names, vocabulary and sample counts as the driver's Corpus, and the same prepared data."""
    corpus = Corpus(load_homes(folder))
    source = FolderHomes.create(folder)
    assert source.names == list(corpus.names)
    assert source.vocabulary == corpus.vocabulary
    assert source.n_samples == sum(e.training_data().n_samples for e in corpus)
    whole = source.parts(1)[0].prepare()
    expected = PreparedData.from_corpus(corpus, 1.0)
    for name in ("positions", "homes", "offsets", "map_centres"):
        np.testing.assert_array_equal(getattr(whole, name), getattr(expected, name))
    for name in ("visual", "words"):
        assert (getattr(whole, name) != getattr(expected, name)).nnz == 0
    assert [p.n_homes for p in source.parts(2)] == [p.n_homes for p in driver_source(folder).parts(2)]


def test_folder_source_gives_the_chain_of_prepared_homes(folder) -> None:
    """Two local shards reading their folders: the log-joint trace and labels of the driver's data."""
    a = chain(driver_source(folder), LocalEngine(2))
    b = chain(FolderHomes.create(folder), LocalEngine(2))
    for x, y in zip(a, b, strict=True):
        np.testing.assert_array_equal(x, y)


def test_fit_knowledge_from_folders_equals_the_corpus_fit(folder) -> None:
    """fit_knowledge on a FolderHomes (view fits computed in the shards) equals the Corpus fit."""
    from spco.knowledge import fit_knowledge

    a = fit_knowledge(Corpus(load_homes(folder)), n_iterations=8, random_state=1, engine=LocalEngine(2))
    b = fit_knowledge(FolderHomes.create(folder), n_iterations=8, random_state=1, engine=LocalEngine(2))
    np.testing.assert_array_equal(a.log_phi_visual, b.log_phi_visual)
    np.testing.assert_array_equal(a.log_g0, b.log_g0)
    np.testing.assert_array_equal(a.word_mask, b.word_mask)
    assert a.provenance["view_fit"] == b.provenance["view_fit"]
    assert a.provenance["n_samples"] == b.provenance["n_samples"]
    # the default one-process engine reads the folders in the driver: the default chain
    c = fit_knowledge(Corpus(load_homes(folder)), n_iterations=4, random_state=1)
    d = fit_knowledge(FolderHomes.create(folder), n_iterations=4, random_state=1)
    np.testing.assert_array_equal(c.log_phi_visual, d.log_phi_visual)


def test_a_broken_home_is_named_before_any_shard_starts(folder, tmp_path) -> None:
    import shutil

    broken = tmp_path / "homes"
    shutil.copytree(folder, broken)
    home = sorted(p for p in broken.iterdir() if p.is_dir())[2]
    (home / "samples.csv").write_text("id,x,y\n1,oops\n")
    with pytest.raises(DataFormatError, match=r"samples\.csv"):
        FolderHomes.create(broken)
    (home / "visual.npz").unlink()
    (home / "images").mkdir()
    with pytest.raises(DataFormatError, match="views as images"):
        FolderHomes.create(broken)
    with pytest.raises(DataFormatError, match="no such file"):
        FolderHomes.create(tmp_path / "missing")
    with pytest.raises(DataFormatError, match="no home named"):
        FolderHomes.create(folder, names=["nowhere"])


def test_fit_command_reads_homes_in_the_shards_and_names_a_broken_home(folder, tmp_path) -> None:
    """`spco fit --shards 2` on a folder: the shards read the homes, the knowledge is the Corpus
    fit's; a broken home is a one-line error naming its file, exit 2, before any sweep."""
    import shutil

    from click.testing import CliRunner

    from spco.cli import main
    from spco.knowledge import Knowledge, fit_knowledge

    out = tmp_path / "k.spco"
    result = CliRunner().invoke(main, ["fit", "--data", str(folder), "--out", str(out), "--iterations", "6",
                                       "--seed", "2", "--shards", "2"])
    assert result.exit_code == 0, result.output
    assert "each shard reads its own homes" in result.output
    expected = fit_knowledge(Corpus(load_homes(folder)), n_iterations=6, random_state=2,
                             engine=LocalEngine(2))
    np.testing.assert_array_equal(Knowledge.load(out).log_phi_visual, expected.log_phi_visual)
    broken = tmp_path / "homes"
    shutil.copytree(folder, broken)
    home = sorted(p for p in broken.iterdir() if p.is_dir())[1]
    (home / "visual.npz").write_bytes(b"not a zip")
    result = CliRunner().invoke(main, ["fit", "--data", str(broken), "--out", str(tmp_path / "b.spco"),
                                       "--shards", "2"])
    assert result.exit_code == 2
    assert "error:" in result.output and str(home / "visual.npz") in result.output
    assert "Traceback" not in result.output and "sweep" not in result.output


def test_ray_actors_reading_their_folders_give_the_driver_data_chain(folder, ray_session) -> None:
    """Ray actors that read their own homes' folders: the chain of the driver-loaded PreparedHomes."""
    from spco.engines.ray import RayEngine

    a = chain(driver_source(folder), RayEngine(2))
    b = chain(FolderHomes.create(folder), RayEngine(2))
    for x, y in zip(a, b, strict=True):
        np.testing.assert_array_equal(x, y)


def test_fit_command_on_ray_reads_homes_in_the_actors(folder, tmp_path, ray_session) -> None:
    """`spco fit --engine ray --shards 2` on a folder: the knowledge of two local shards."""
    from click.testing import CliRunner

    from spco.cli import main
    from spco.knowledge import Knowledge, fit_knowledge

    out = tmp_path / "k.spco"
    result = CliRunner().invoke(main, ["fit", "--data", str(folder), "--out", str(out), "--iterations", "6",
                                       "--seed", "2", "--engine", "ray", "--shards", "2"])
    assert result.exit_code == 0, result.output
    expected = fit_knowledge(Corpus(load_homes(folder)), n_iterations=6, random_state=2,
                             engine=LocalEngine(2))
    fitted = Knowledge.load(out)
    np.testing.assert_array_equal(fitted.log_phi_visual, expected.log_phi_visual)
    assert fitted.provenance["view_fit"] == expected.provenance["view_fit"]


def test_folder_source_reads_sigverse_homes_as_the_driver_does(sigverse_dir) -> None:
    """SIGVerse layout (skipped without the data set): the same vocabulary and prepared data."""
    from spco.data.loading import find_homes

    names = [h.name for h in find_homes(sigverse_dir)][:2]
    source = FolderHomes.create(sigverse_dir, names=names)
    corpus = Corpus(load_homes(sigverse_dir, names=names))
    assert source.names == names and source.vocabulary == corpus.vocabulary
    whole, expected = source.parts(1)[0].prepare(), PreparedData.from_corpus(corpus, 1.0)
    np.testing.assert_array_equal(whole.positions, expected.positions)
    assert (whole.visual != expected.visual).nnz == 0 and (whole.words != expected.words).nnz == 0
