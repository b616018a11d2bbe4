"""Shared fixtures: where the SIGVerse data set is, a builder of tiny homes in its layout, and a
local Ray instance."""

from __future__ import annotations

import os
import sys
from collections.abc import Callable, Iterator, Sequence
from pathlib import Path

import numpy as np
import pytest
import scipy.sparse as sp
from hypothesis import settings
from scipy import stats

# In CI (CI=true, as .ci/run runs) property tests draw the same examples on every run, so a green
# build stays green; on a developer's machine they keep exploring new examples each run (a failure
# prints the example and how to reproduce it). Neither profile has a per-example deadline: tests check
# behaviour, not speed (speed is measured in benchmarks/), and a loaded machine must not fail them.
settings.register_profile("ci", derandomize=True, print_blob=True, deadline=None)
settings.register_profile("dev", deadline=None)
settings.load_profile("ci" if os.environ.get("CI") else "dev")

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "benchmarks"))
from data_paths import sigverse_path  # noqa: E402  (the benchmarks' and the tests' one definition)


@pytest.fixture(scope="session")
def sigverse_dir() -> Path:
    """The authors' SIGVerse data set; tests using it are skipped when it is absent."""
    path = sigverse_path()
    if not (path / "3LDK_9" / "position").is_dir():
        pytest.skip(f"SIGVerse dataset not found at {path} (clone is0314px/transferlearning_spco and "
                    "point SPCO_SIGVERSE at its source/gibbs_dataset/sigverse folder)")
    return path


def missing_tool(reason: str) -> None:
    """A test's tool (a program, a system package) is missing: skip it with ``reason`` — except under
    ``CI=true``, where every test must run (.ci/run installs the tools), so it fails instead."""
    if os.environ.get("CI"):
        pytest.fail(f"{reason} (CI=true: .ci/run should have installed it)", pytrace=False)
    pytest.skip(reason)


@pytest.fixture(scope="module")
def ray_session():
    """A local Ray instance of 2 CPUs for a test module (skipped without Ray), shut down after it."""
    ray = pytest.importorskip("ray", reason="Ray is not installed (pip install -e '.[ray]')")
    if not ray.is_initialized():
        ray.init(num_cpus=2, include_dashboard=False, log_to_driver=False)
    yield ray
    ray.shutdown()


@pytest.fixture(scope="session")
def _tour_home_source(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A home file made as a robot would (``ros_harness.tour_home``: three tours fitted, a fourth
    adapted), whose kitchen is the bedroom's colour with red and blue swapped; built once.

    Seed 1: the tests check the node's plumbing through answers that need the adapted tour's three
    rooms apart, and a few seeds leave two rooms in one region (measured on this tour with
    ``tour_home(seed=s, colours=SWAPPED_ROOM_COLOURS)``, s = 0…11, ``where`` of each room: with the
    exact model's view weight of 16 counts, seeds 0 and 4 (and partly 6) mix rooms; with every count
    a draw, seed 6). That is the sampler on a tiny home, not the node, and is reported in
    ``docs/model.md``.
    """
    from ros_harness import SWAPPED_ROOM_COLOURS, tour_home

    return tour_home(tmp_path_factory.mktemp("tour_home"), seed=1, colours=SWAPPED_ROOM_COLOURS)


@pytest.fixture(scope="module")
def tour_home_file(_tour_home_source: Path, tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A copy of the tour home for a test module (nodes and servers teach it and journal beside it)."""
    import shutil

    folder = tmp_path_factory.mktemp("tour_home_copy")
    return Path(shutil.copy2(_tour_home_source, folder / "home.spco"))


SigverseBuilder = Callable[..., Path]


@pytest.fixture
def make_sigverse_home(tmp_path: Path) -> SigverseBuilder:
    """Factory writing a tiny home in the SIGVerse layout under ``tmp_path``; returns its folder.

    ``make_sigverse_home("home", n=6, test=(4, 5), rates={100: range(4)})`` writes 6 samples with
    4,096-line visual files, sentences at the given rates for the given samples, name labels, a test
    list and an Environment_parameter.txt.
    """

    def build(name: str = "home", n: int = 6, test: tuple[int, ...] = (4, 5),
              rates: dict[int, range | tuple[int, ...]] | None = None, params: bool = True,
              dim: int = 4096, root: Path | None = None) -> Path:
        home = (root or tmp_path) / name
        rng = np.random.default_rng(len(name) + n)
        for sub in ("position", "vision_fc7_normalized", "name_label"):
            (home / sub).mkdir(parents=True)
        for i in range(n):
            theta = rng.uniform(-np.pi, np.pi)
            (home / "position" / f"{i}.txt").write_text(
                f"{rng.uniform(-3, 3):.4f} {rng.uniform(-2, 2):.4f}\n{np.sin(theta):.4f} {np.cos(theta):.4f}")
            counts = np.where(rng.random(dim) < 0.2, rng.integers(1, 300, dim), 0)
            (home / "vision_fc7_normalized" / f"{i}.csv").write_text("\n".join(map(str, counts)) + "\n")
            (home / "name_label" / f"word{i}.txt").write_text("kitchen " if i % 2 else "living-room ")
        for rate, samples in (rates if rates is not None else {100: range(n - len(test))}).items():
            folder = home / "sentence" / f"per_{rate}"
            folder.mkdir(parents=True)
            for i in samples:
                place = "kitchen" if i % 2 else "living-room"
                (folder / f"sentence{i}.txt").write_text(f"this is the {place}")
        (home / "test_num.txt").write_text("".join(f"{i}," for i in test) if test else "999")
        if params:
            (home / "Environment_parameter.txt").write_text(
                "Max_x_value_of_map 4.0\nMax_y_value_of_map 3.0\nMin_x_value_of_map -4.0\n"
                f"Min_y_value_of_map -3.0\nNumber_of_place 40\nInitial_data_number 0\n"
                f"Last_data_number {n - 1} #comment\n")
        return home

    return build


@pytest.fixture(scope="session")
def wordnet():
    """The WordNet lexicon (spco[words] + Debian's wordnet-base); skipped when missing, except under
    CI=true, where .ci/run installs both and a missing lexicon is a failure."""
    from spco.data.lexicon import lexicon, lexicon_unavailable_reason

    reason = lexicon_unavailable_reason()
    if reason is not None:
        if os.environ.get("CI"):
            pytest.fail(f"the lexicon must be available under CI: {reason}")
        pytest.skip(f"{reason}: pip install -e '.[words]' and apt-get install wordnet-base")
    return lexicon()


@pytest.fixture
def phi_passes(monkeypatch) -> list[int]:
    """Each pass of the φ^v-marginal block moves (:func:`spco.model.phi_moves.home_pass`) the test runs,
    as its number of accepted moves, in order (the list fills while the test runs)."""
    from spco.model import phi_moves

    passes: list[int] = []
    original = phi_moves.home_pass

    def counted(*args, **kwargs):
        concepts, accepted = original(*args, **kwargs)
        passes.append(accepted)
        return concepts, accepted

    monkeypatch.setattr(phi_moves, "home_pass", counted)
    return passes


@pytest.fixture
def single_numba_thread() -> Iterator[None]:
    """One Numba thread for a test (``pytestmark = pytest.mark.usefixtures("single_numba_thread")``):
    tiny problems call the compiled kernels thousands of times, and one thread avoids the OpenMP
    start-up cost of every call (results do not depend on the number of threads)."""
    import numba

    before = numba.get_num_threads()
    numba.set_num_threads(1)
    yield
    numba.set_num_threads(before)


@pytest.fixture(scope="module")
def small_corpus():
    """Two taught synthetic homes and a new one, 5 training and 2 test samples each, D = 64."""
    from spco.data.synthetic import SyntheticConfig, generate_homes

    return generate_homes(3, seed=4, new_homes=1, config=SyntheticConfig(n_features=64, n_train=5, n_test=2),
                          specific_rooms=False)


def synthetic_home_folders(root: Path, n_homes: int, seed: int, n_features: int = 128) -> dict[str, Path]:
    """``n_homes`` synthetic homes (no home-specific rooms) in the plain format: all but the last
    under ``root/experienced``, the last (nothing taught) under ``root/new``. Returns the paths
    ``root``, ``experienced``, ``new`` (the new home's folder) and its name, ``new_name``."""
    from spco.data.plain import write_corpus
    from spco.data.synthetic import SyntheticConfig, generate_homes

    corpus = generate_homes(n_homes, seed=seed, config=SyntheticConfig(n_features=n_features), new_homes=1,
                            specific_rooms=False)
    write_corpus(list(corpus)[:-1], root / "experienced")
    write_corpus(list(corpus)[-1:], root / "new")
    return {"root": root, "experienced": root / "experienced", "new": root / "new" / corpus.names[-1],
            "new_name": corpus.names[-1]}  # type: ignore[dict-item]


def fit_and_adapt(folders: dict[str, Path], fit_args: Sequence[object], adapt_args: Sequence[object],
                  knowledge: str = "knowledge.spco", home: str = "home.spco") -> tuple[Path, Path, str]:
    """``spco fit`` on the experienced homes of :func:`synthetic_home_folders`, then ``spco adapt``
    of that knowledge to its new home, each with the extra arguments given; returns the knowledge
    file, the home file (both in ``folders["root"]``) and what ``adapt`` printed."""
    from click.testing import CliRunner

    from spco.cli import main

    def run(args: Sequence[object]) -> str:
        result = CliRunner().invoke(main, [str(a) for a in args], catch_exceptions=False)
        assert result.exit_code == 0, result.output
        return result.output

    knowledge_file, home_file = folders["root"] / knowledge, folders["root"] / home
    run(["fit", "--data", folders["experienced"], *fit_args, "--out", knowledge_file])
    output = run(["adapt", knowledge_file, "--home", folders["new"], *adapt_args, "--out", home_file])
    return knowledge_file, home_file, output


def fit_twice_and_adapt(hyperparameters):
    """Knowledge of three synthetic homes (seed 3, D = 64; 4 sweeps, seed 0) fitted twice with
    ``hyperparameters``, and the fourth home (nothing taught) adapted from the first fit (3 sweeps);
    returns ``(experienced corpus, [first fit, second fit], adapted home)``: for the priors estimated
    at the fit (the same seed gives the same numbers; an adapted home keeps them)."""
    import warnings

    import spco.knowledge as kn
    from spco.data.environment import Corpus
    from spco.data.synthetic import SyntheticConfig, generate_homes

    corpus = generate_homes(4, seed=3, config=SyntheticConfig(n_features=64), new_homes=1,
                            specific_rooms=False)
    experienced, new = Corpus(list(corpus)[:-1]), list(corpus)[-1]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        fits = [kn.fit_knowledge(experienced, n_iterations=4, random_state=0, hyperparameters=hyperparameters)
                for _ in range(2)]
        home = kn.adapt(fits[0], new, n_iterations=3, random_state=0)
    return experienced, fits, home


def chisquare_p(observed: np.ndarray, probs: np.ndarray, min_expected: float = 5.0) -> float:
    """Chi-square goodness-of-fit p-value of draws ``observed`` (counts) against ``probs``, with small
    expected cells pooled; a draw in a cell of (relatively) zero probability fails outright."""
    observed = np.asarray(observed, dtype=float).ravel()
    expected = np.asarray(probs, dtype=float).ravel() * observed.sum()
    assert observed[expected < 1e-12 * observed.sum()].sum() == 0, "draws in a cell of probability 0"
    keep = expected >= min_expected
    obs, exp = observed[keep], expected[keep]
    if expected[~keep].sum() > 0:
        obs = np.append(obs, observed[~keep].sum())
        exp = np.append(exp, expected[~keep].sum())
    if obs.size < 2:
        return 1.0
    return float(stats.chisquare(obs, exp * obs.sum() / exp.sum()).pvalue)


def csr(dense: np.ndarray) -> sp.csr_array:
    """Counts in the layout the sampler uses (float64 data, int64 indices)."""
    out = sp.csr_array(np.asarray(dense, dtype=np.float64))
    out.indices = out.indices.astype(np.int64)
    out.indptr = out.indptr.astype(np.int64)
    return out


def random_word_channels(rng: np.random.Generator, n_words: int, n_concepts: int):
    """Word channels of a tiny brute-force problem, drawn from ``rng``: ψ (place words) per concept,
    the background, the channels' shares (the names' log share 0) and each word's linguistic evidence."""
    from spco.model.word_channels import WordChannels

    return WordChannels(
        log_place=np.log(rng.dirichlet(np.ones(n_words), size=n_concepts)),
        log_background=np.log(rng.dirichlet(np.ones(n_words))),
        log_shares=np.concatenate([[0.0], np.log(rng.dirichlet(np.ones(2)))]),
        log_evidence=np.log(np.column_stack([p := rng.uniform(0.05, 0.95, n_words), 1 - p, 1 - p])))


#: The development homes whose people's sentences (``sigverse_subject``) teach the knowledge of the
#: natural-speech tests (benchmarks/SPLIT.md, "Natural speech").
DEVELOPMENT_SPEECH_HOMES = ("1LDK_1", "1LDK_3", "1LDK_5", "1LDK_7", "2LDK_1", "2LDK_3", "2LDK_5", "2LDK_7")


@pytest.fixture(scope="session")
def development_speech_fit(sigverse_dir: Path):
    """(corpus, model): the 8 development homes taught with their people's sentences and ``3LDK_9``
    taught nothing, fitted once per session (SpCoTransfer+MI, 30 sweeps, seed 0); skipped without
    ``sigverse_subject`` beside the data set."""
    from spco.data import Corpus
    from spco.data.loading import load
    from spco.data.sigverse import read_indexed_texts
    from spco.model import SpCoTransfer

    subject = sigverse_dir.parent / "sigverse_subject"
    if not subject.is_dir():
        pytest.skip(f"people's sentences not found at {subject}")
    homes = []
    for name in DEVELOPMENT_SPEECH_HOMES:
        env = load(sigverse_dir / name)[name]
        texts = read_indexed_texts(subject / name / "per_100", "sentence", env.n_samples, strict=False)
        homes.append(env.with_sentences([None if t else s for s, t in zip(texts, env.is_test, strict=True)]))
    new = load(sigverse_dir / "3LDK_9")["3LDK_9"]
    corpus = Corpus([*homes, new.with_sentences((None,) * new.n_samples)])
    return corpus, SpCoTransfer(n_iterations=30, random_state=0, prune_words=True).fit(corpus)
