"""Honest confidence (spco.model.confidence): `what` is as sure as it is right.

On a small problem where the truth is known the answer's probability must match its frequency; a
view with huge counts must not overrule a position that disagrees; a concept nobody named must not
name a place; an answer below the threshold is flagged unsure (library, CLI text, JSON); and on the
SIGVerse development home 1DK_8 (benchmarks/calibration/SPLIT.md) the calibration holds.
"""

from __future__ import annotations

import json
import math
import warnings
from pathlib import Path

import numpy as np
import pytest
import scipy.sparse as sp
from click.testing import CliRunner
from conftest import fit_and_adapt, synthetic_home_folders

from spco import knowledge as kn
from spco.cli.knowledge import what
from spco.data.language import Vocabulary
from spco.errors import ConfigurationError
from spco.model.answer_settings import AnswerSettings
from spco.model.confidence import (
    UNSURE_BELOW,
    answer_names,
    concept_word_counts,
    named_parameters,
)
from spco.model.parameters import ConceptParameters
from spco.model.prediction import predict_names

NAMES = ("kitchen", "dining", "bedroom")


def _ece(confidence: np.ndarray, right: np.ndarray, n_bins: int = 10) -> float:
    bins = np.minimum((confidence * n_bins).astype(int), n_bins - 1)
    return float(sum(abs(right[bins == b].mean() - confidence[bins == b].mean()) * (bins == b).mean()
                     for b in range(n_bins) if (bins == b).any()))


def _parameters(theta_v: np.ndarray, means_xy: np.ndarray, sd: float,
                word_rows: np.ndarray | None = None, global_weights: np.ndarray | None = None
                ) -> ConceptParameters:
    """One home, concept l ↔ region l ↔ name l (unless ``word_rows``), equal weights."""
    L = theta_v.shape[0]
    V = len(NAMES)
    means = np.zeros((1, L, 4))
    means[0, :, :2] = means_xy
    means[0, :, 3] = 1.0  # heading 0: (sin, cos) = (0, 1)
    cov = np.tile(np.diag([sd**2, sd**2, 0.1, 0.1]), (1, L, 1, 1))
    words = np.zeros((1, L, V))
    if word_rows is None:
        words[0, np.arange(L), np.arange(L) % V] = 1.0
    else:
        words[0] = word_rows
    return ConceptParameters(
        concept_weights=np.full((1, L), 1.0 / L), region_weights=np.eye(L)[None],
        region_means=means, region_covariances=cov, word_probabilities=words,
        visual_probabilities=theta_v[None], shared_word_probabilities=words[0],
        shared_visual_probabilities=theta_v,
        global_concept_weights=np.full(L, 1.0 / L) if global_weights is None else global_weights,
        word_mask=np.ones(V, dtype=bool), region_counts=np.full((1, L), 20),
        concept_counts=np.full((1, L), 20.0))


def _honest(params: ConceptParameters, poses: np.ndarray, views: object, *, free: np.ndarray | None = None,
            view_counts: float = 5.0, unsure_below: float = UNSURE_BELOW):
    """The one predictor (answer_names) of the named parameters; a view weight w of a few draws, as
    a knowledge estimates it."""
    L, V = params.n_concepts, params.word_probabilities.shape[-1]
    named = named_parameters(params, 0, np.zeros(L, dtype=bool) if free is None else free, np.zeros((L, V)),
                             0.01)
    return answer_names(named, 0, Vocabulary(list(NAMES)), poses, views, view_counts=view_counts,
                        weighting="none", top_k=3, unsure_below=unsure_below, settings=AnswerSettings())


def test_probability_of_the_answer_matches_its_frequency() -> None:
    """Views whose 2,000 counts are 500 copies of each of 4 draws from the concept's θ^v (counts of
    one image are not independent draws): with the view's evidence counted as 4 draws the posterior
    is the true one, and the answers' probabilities match their frequencies; counting every count
    as a draw makes every answer sure, the wrong ones too."""
    rng = np.random.default_rng(7)
    L, D, n = 3, 12, 4000
    theta_v = rng.dirichlet(np.full(D, 0.7), size=L)
    params = _parameters(theta_v, np.array([[0.0, 0.0], [1.0, 0.0], [2.0, 0.0]]), sd=0.8)
    truth = rng.integers(0, L, n)
    poses = np.zeros((n, 4))
    poses[:, :2] = params.region_means[0, truth, :2] + rng.normal(0.0, 0.8, (n, 2))
    poses[:, 3] = 1.0
    draws = np.stack([rng.multinomial(4, theta_v[t]) for t in truth])
    views = sp.csr_array(draws * 500)

    honest = _honest(params, poses, views, view_counts=4.0)
    right = np.array(honest.best) == np.array(NAMES)[truth]
    assert 0.6 < right.mean() < 0.95  # a problem where confidence matters
    assert _ece(honest.confidence, right) < 0.03
    sure = honest.confidence >= 0.99
    assert (~right[sure]).sum() <= 0.1 * max(1, (~right).sum())

    naive = predict_names(params, 0, Vocabulary(list(NAMES)), poses, views, top_k=3, weighting="none")
    naive_right = np.array(naive.best) == np.array(NAMES)[truth]
    assert _ece(naive.confidence, naive_right) > 0.05
    assert (naive.confidence[~naive_right] >= 0.99).mean() > 0.5


def test_huge_counts_do_not_overrule_a_position_that_disagrees() -> None:
    """A kitchen pose (4 σ from the bedroom) with a view like the bedroom's: the model's multinomial
    says "bedroom" at p = 1 from 10^5 counts; counted as a few draws the view cannot, and the answer
    does not depend on how many counts the extractor gives (× 1 or × 1,000)."""
    theta_v = np.array([[0.5, 0.3, 0.1, 0.1], [0.3, 0.5, 0.1, 0.1], [0.1, 0.1, 0.4, 0.4]])
    params = _parameters(theta_v, np.array([[0.0, 0.0], [5.0, 0.0], [2.5, 4.0]]), sd=1.0)
    pose = np.array([[1.0, 0.0, 0.0, 1.0]])  # 1 m from the kitchen, 4 m from the dining room
    view = np.array([[0, 0, 50_000, 50_000]])  # the bedroom's look, 10^5 counts
    naive = predict_names(params, 0, Vocabulary(list(NAMES)), pose, view, weighting="none")
    assert naive.best[0] == "bedroom" and naive.confidence[0] > 0.999

    honest = _honest(params, pose, view)
    p = dict(zip(honest.words[0], honest.probabilities[0], strict=True))
    assert p["bedroom"] < 0.99 and p["kitchen"] > 0.05
    scaled = _honest(params, pose, view * 1000)
    assert np.allclose(scaled.word_probabilities, honest.word_probabilities)
    few = _honest(params, pose, np.array([[0, 0, 1, 1]]))  # fewer counts than n_eff: as given, weaker
    few_p = dict(zip(few.words[0], few.probabilities[0], strict=True))
    assert few_p["bedroom"] < p["bedroom"]


def test_a_concept_nobody_named_does_not_name_a_place() -> None:
    """A free concept (unused by the knowledge) whose averaged θ^w is a sparse prior draw
    ("dining" at 0.999): with nothing taught there its names are uniform, the answer at a view of
    it is unsure; a name taught there (word counts) is its name."""
    theta_v = np.array([[0.7, 0.1, 0.1, 0.1], [0.1, 0.7, 0.1, 0.1], [0.1, 0.1, 0.4, 0.4]])
    words = np.array([[1.0, 0.0, 0.0], [0.0, 0.999, 0.001], [0.0, 0.0, 1.0]])
    params = _parameters(theta_v, np.array([[0.0, 0.0], [6.0, 0.0], [3.0, 6.0]]), sd=1.0,
                         word_rows=words)
    free = np.array([False, True, False])
    pose, view = np.array([[6.0, 0.0, 0.0, 1.0]]), np.array([[10, 700, 10, 10]])
    before = _honest(params, pose, view)  # without the free mask: the prior draw answers
    assert before.best[0] == "dining" and before.confidence[0] > 0.99
    honest = _honest(params, pose, view, free=free)
    assert honest.confidence[0] < UNSURE_BELOW and honest.unsure[0]
    assert honest.word_probabilities[0].max() - honest.word_probabilities[0].min() < 0.1

    counts = np.zeros((3, 3))
    counts[1, 0] = 5000.0  # one sentence saying "kitchen" in that concept (S^w = 5000)
    taught = named_parameters(params, 0, free, counts, alpha_word=0.01)
    assert taught.word_probabilities[0, 1].argmax() == 0 and taught.word_probabilities[0, 1, 0] > 0.99
    assert np.array_equal(taught.word_probabilities[0, 0], params.word_probabilities[0, 0])


def test_concept_word_counts_and_bad_arguments() -> None:
    words = sp.csr_array(np.array([[5000, 0], [0, 0], [5000, 5000]]))
    counts = concept_word_counts(words, np.array([2, 0, 2]), 3)
    assert counts.tolist() == [[0, 0], [0, 0], [10000, 5000]]
    theta_v = np.full((3, 4), 0.25)
    params = _parameters(theta_v, np.zeros((3, 2)), sd=1.0)
    with pytest.raises(ConfigurationError, match="free"):
        named_parameters(params, 0, np.zeros(2, dtype=bool), np.zeros((3, 3)), 0.01)
    with pytest.raises(ConfigurationError, match="word_counts"):
        named_parameters(params, 0, np.ones(3, dtype=bool), np.zeros((3, 2)), 0.01)
    with pytest.raises(ConfigurationError, match="unsure_below"):
        _honest(params, np.array([[0.0, 0.0, 0.0, 1.0]]), None, unsure_below=1.5)
    with pytest.raises(ConfigurationError, match="view_counts"):
        _honest(params, np.array([[0.0, 0.0, 0.0, 1.0]]), np.ones((1, 4)), view_counts=0.0)


# ------------------------------------------------------------------------- what: library, CLI, JSON
@pytest.fixture(scope="module")
def home_file(tmp_path_factory: pytest.TempPathFactory) -> Path:
    folders = synthetic_home_folders(tmp_path_factory.mktemp("confidence"), 4, seed=5, n_features=64)
    return fit_and_adapt(folders, ["--iterations", 12, "--seed", 1], ["--iterations", 15])[1]


def test_what_says_when_it_is_unsure(home_file: Path) -> None:
    """Over the home's own poses and views (a small, briefly learnt home) some answers are sure and
    some are not; `unsure` is the answer's probability below the threshold, and the CLI says so in
    text and in JSON."""
    home = kn.load_home_model(home_file)
    answers = []
    for i in range(home.n_samples):
        x, y, s, c = home.positions[i]
        answers.append(kn.what(home, float(x), float(y), math.atan2(s, c), visual=home.visual[[i]]))
    confidence = np.array([a.confidence[0] for a in answers])
    unsure = np.array([a.unsure[0] for a in answers])
    assert np.array_equal(unsure, confidence < UNSURE_BELOW)
    assert confidence.max() > 0.95 and confidence.min() < UNSURE_BELOW  # both kinds occur
    best = answers[int(confidence.argmax())]
    assert best.confidence[0] == pytest.approx(best.probabilities[0, 0])
    i = int(confidence.argmax())
    x, y, s, c = home.positions[i]
    theta = math.atan2(s, c)
    assert kn.what(home, float(x), float(y), theta, visual=home.visual[[i]], unsure_below=1.0).unsure[0]
    from spco.knowledge.requests import Pose, View, What
    from spco.service.answers import what_answer  # spco serve's /what and the ROS node answer with it

    request = What(Pose(float(x), float(y), theta), View(visual=home.visual[[i]].toarray()[0]))
    served = what_answer(home, request)
    assert served["confidence"] == pytest.approx(float(confidence[i])) and served["unsure"] is False
    assert served["answer"] == best.best[0]
    assert what_answer(home, request, unsure_below=1.0)["unsure"] is True
    view = home_file.parent / "view.npy"
    np.save(view, home.visual[[i]].toarray()[0])
    args = [str(home_file), "--x", str(x), "--y", str(y), "--theta", str(theta), "--visual", str(view)]
    result = CliRunner().invoke(what, [*args, "--json", "--unsure-below", "1"], catch_exceptions=False)
    out = json.loads(result.output)
    assert out["unsure"] is True and out["unsure_below"] == 1.0
    assert out["answer"] == out["names"][0]["name"] and out["confidence"] == out["names"][0]["probability"]
    result = CliRunner().invoke(what, [*args, "--json"], catch_exceptions=False)
    assert json.loads(result.output)["unsure"] is False
    text = CliRunner().invoke(what, [*args, "--unsure-below", "1"], catch_exceptions=False).output
    assert "unsure: the best name" in text
    assert "unsure" not in CliRunner().invoke(what, args, catch_exceptions=False).output
    j = int(confidence.argmin())
    x, y, s, c = home.positions[j]
    np.save(view, home.visual[[j]].toarray()[0])
    low = [str(home_file), "--x", str(x), "--y", str(y), "--theta", str(math.atan2(s, c)),
           "--visual", str(view)]
    low_json = CliRunner().invoke(what, [*low, "--json"], catch_exceptions=False).output
    assert json.loads(low_json)["unsure"] is True
    assert "unsure: the best name" in CliRunner().invoke(what, low, catch_exceptions=False).output
    bad = CliRunner().invoke(what, [str(home_file), "--x", "0", "--y", "0", "--theta", "0",
                                    "--unsure-below", "2"])
    assert bad.exit_code == 2 and "--unsure-below" in bad.output


# ------------------------------------------------------------------------- SIGVerse development home
@pytest.mark.parametrize("features", ["fc7", "colour-hog"])
def test_sigverse_development_home_is_calibrated(sigverse_dir: Path, features: str) -> None:
    """4 experienced homes and the validation home 1DK_8 (development data of
    benchmarks/calibration/SPLIT.md; 60 sweeps), views from fc7 or from the camera images: on its 70
    test views `what` is right on most and its probabilities are calibrated (ECE ≤ 0.05, no wrong
    answer at p ≥ 0.99; with colour-hog the model's own p gave its 3 wrong answers at p = 1)."""
    from spco.data.environment import Corpus
    from spco.data.loading import load_homes
    from spco.evaluation.config import PAPER_EXPERIENCED_HOMES
    from spco.features import build_extractor

    kw = {}
    if features != "fc7":
        images = sigverse_dir.parent / "sigverse_images"
        if not (images / "1DK_8").is_dir():
            pytest.skip(f"sigverse_images not found at {images}")
        kw = {"extractor": build_extractor(features), "images": images}
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        corpus = Corpus(load_homes(sigverse_dir, names=list(PAPER_EXPERIENCED_HOMES[:4]), **kw))
        knowledge = kn.fit_knowledge(corpus, n_iterations=60, random_state=0,
                                     extractor=kw.get("extractor"))
        new = load_homes(sigverse_dir, names=["1DK_8"], teaching_rate=0, **kw)[0]
        home = kn.adapt(knowledge, new, n_iterations=40, random_state=0)
    positions, visual = new.test_observations()
    labels = [lab for lab, t in zip(new.labels(), new.is_test, strict=True) if t]
    conf, right = [], []
    for i, label in enumerate(labels):
        pred = kn.what(home, positions[i, 0], positions[i, 1], math.atan2(positions[i, 2], positions[i, 3]),
                       visual=visual[[i]].toarray()[0])
        conf.append(pred.confidence[0])
        right.append(pred.best[0] == label)
    conf_a, right_a = np.array(conf), np.array(right)
    assert len(labels) == 70 and right_a.mean() >= 0.9
    assert _ece(conf_a, right_a) <= 0.05
    assert not (conf_a[~right_a] >= 0.99).any()
