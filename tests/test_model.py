"""The estimators end to end: recovery on synthetic homes, numerical soundness, reproducibility,
argument validation, and every variant and baseline fitting a small corpus."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from scipy.special import comb

from spco.data import Corpus, Environment
from spco.data.loading import load
from spco.data.synthetic import SyntheticConfig, generate_homes, teach
from spco.errors import ConfigurationError
from spco.evaluation import evaluate_home
from spco.model import (
    ConceptParameters,
    SpCoA,
    SpCoAHyperparameters,
    SpCoTransfer,
    TransferHyperparameters,
    gibbs,
    parameter_steps,
    sweep_statistics,
)
from spco.model.pruning import colocation
from spco.model.state import PreparedData


def adjusted_rand_index(a: np.ndarray, b: np.ndarray) -> float:
    """Adjusted Rand index of two labellings (Hubert & Arabie 1985)."""
    _, ai = np.unique(np.asarray(a), return_inverse=True)
    _, bi = np.unique(np.asarray(b), return_inverse=True)
    table = np.zeros((ai.max() + 1, bi.max() + 1))
    np.add.at(table, (ai, bi), 1)
    pairs = comb(table, 2).sum()
    rows, cols = comb(table.sum(1), 2).sum(), comb(table.sum(0), 2).sum()
    expected = rows * cols / comb(len(ai), 2)
    top = 0.5 * (rows + cols)
    return 1.0 if top == expected else float((pairs - expected) / (top - expected))


def homogeneity(classes: np.ndarray, clusters: np.ndarray) -> float:
    """1 − H(class | cluster) / H(class) (Rosenberg & Hirschberg 2007): 1 when every cluster holds
    a single class. ``homogeneity(clusters, classes)`` is the completeness: 1 when every class
    lies in a single cluster."""
    _, ci = np.unique(np.asarray(classes), return_inverse=True)
    _, ki = np.unique(np.asarray(clusters), return_inverse=True)
    table = np.zeros((ci.max() + 1, ki.max() + 1))
    np.add.at(table, (ci, ki), 1)
    p = table / table.sum()

    def entropy(q: np.ndarray) -> float:
        q = q[q > 0]
        return float(-(q * np.log(q)).sum())

    h_class = entropy(p.sum(1))
    return 1.0 if h_class == 0 else 1.0 - (entropy(p.ravel()) - entropy(p.sum(0))) / h_class


def test_homogeneity_helper() -> None:
    assert homogeneity([0, 0, 1, 1], [3, 4, 5, 5]) == pytest.approx(1.0)  # clusters pure
    assert homogeneity([3, 4, 5, 5], [0, 0, 1, 1]) < 1.0  # ... but class 0 is split
    assert homogeneity([0, 1, 0, 1], [0, 0, 1, 1]) == pytest.approx(0.0)


def test_adjusted_rand_index_helper() -> None:
    assert adjusted_rand_index([0, 0, 1, 1], [5, 5, 2, 2]) == pytest.approx(1.0)
    assert adjusted_rand_index([0, 0, 1, 1, 2, 2], [0, 1, 0, 1, 0, 1]) < 0
    # the textbook example: ARI of {a,a,a,b,b,b} vs {x,x,y,y,z,z}
    assert adjusted_rand_index(list("aaabbb"), list("xxyyzz")) == pytest.approx(0.24242424, abs=1e-6)


def check_parameters(params: ConceptParameters, n_homes: int, n_concepts: int, n_regions: int, n_words: int,
                     n_features: int) -> None:
    """Shapes, finiteness and normalisation of a fitted model's parameters."""
    E, L, K, V, D = n_homes, n_concepts, n_regions, n_words, n_features
    expected = {
        "concept_weights": (E, L), "region_weights": (E, L, K), "region_means": (E, K, 4),
        "region_covariances": (E, K, 4, 4), "word_probabilities": (E, L, V),
        "visual_probabilities": (E, L, D),
        "shared_word_probabilities": (L, V), "shared_visual_probabilities": (L, D),
        "global_concept_weights": (L,), "word_mask": (V,), "region_counts": (E, K), "concept_counts": (E, L),
        "name_prior": (V,), "place_word_probabilities": (L, V), "word_channel_prior": (V, 3),
    }
    for name, array in params.arrays().items():
        assert array.shape == expected[name], name
        assert np.isfinite(array).all(), f"{name} holds NaN or inf"
    for name in ("concept_weights", "region_weights", "visual_probabilities", "shared_visual_probabilities",
                 "global_concept_weights"):
        array = getattr(params, name)
        assert (array >= 0).all() and np.allclose(array.sum(-1), 1.0), name
    if V:
        for name in ("word_probabilities", "shared_word_probabilities"):
            array = getattr(params, name)
            assert (array >= 0).all() and np.allclose(array.sum(-1), 1.0), name
            assert (array[..., ~params.word_mask] == 0).all(), f"{name}: pruned words keep probability"
    assert (np.linalg.eigvalsh(params.region_covariances) > 0).all()


# ----------------------------------------------------------------------------- recovery


def synthetic_corpus(seed: int = 0, word_increment: int = 5000) -> Corpus:
    """6 experienced homes (all taught) and 1 new home (nothing taught), D = 256."""
    return generate_homes(7, seed=seed, new_homes=1, config=SyntheticConfig(n_features=256),
                          specific_rooms=False, word_increment=word_increment)


def true_rooms(env) -> np.ndarray:
    """The room of every training sample: its place label and which of the place's rectangles
    holds it (a home with three bedrooms has three rooms labelled "bedroom")."""
    labels = np.array(env.ground_truth.labels, dtype=object)[~env.is_test]
    xy = env.positions[~env.is_test, :2]
    rooms = []
    for label, (x, y) in zip(labels, xy, strict=True):
        rects = np.asarray(env.ground_truth.regions.places[label])
        inside = (rects[:, 0] <= x) & (x <= rects[:, 1]) & (rects[:, 2] <= y) & (y <= rects[:, 3])
        rooms.append(f"{label}#{int(np.argmax(inside))}")
    return np.array(rooms, dtype=object)


def taught_home_ari(model: SpCoTransfer, corpus: Corpus) -> list[float]:
    """ARI between the concepts and the true rooms of each taught home's training samples.

    Rooms rather than place labels: the model is free to learn each of a home's bedrooms as its
    own concept (they are different places that share a name), and does."""
    out = []
    for e, env in enumerate(corpus):
        if env.n_taught == 0:
            continue
        out.append(adjusted_rand_index(true_rooms(env), model.concepts_[e]))
    return out


@pytest.mark.xfail(strict=True, raises=AssertionError, reason=(
    "Model property, not a sampler bug: with S^w = 5000 every word of a sentence counts 5000 times, so "
    "the posterior splits each place into one concept per sentence template ('this location is the X' vs "
    "'the X is here'): the sampler's partition has a collapsed word likelihood ~2.2e6 nats above the "
    "place partition (seed 0). Observed ARI 0.45-0.63 per home (mean 0.52), new-home A_n 0.56. The +MI "
    "model (template words pruned) recovers the places: see the next test."))
def test_exact_model_recovers_places_of_taught_homes() -> None:
    corpus = synthetic_corpus(seed=0)
    model = SpCoTransfer(n_iterations=30, random_state=0).fit(corpus)
    aris = taught_home_ari(model, corpus)
    assert np.mean(aris) >= 0.9, aris
    scores = evaluate_home(model.parameters_, len(corpus) - 1, corpus[-1], corpus.vocabulary, rng=0)
    assert scores.mean_name_accuracy >= 0.6, scores.name_accuracy


def test_exact_model_with_word_pruning_recovers_places_of_taught_homes() -> None:
    """Concepts match the true place types: every concept of a taught home holds one place
    (homogeneity w.r.t. the place labels) and every room lies in one concept (completeness w.r.t.
    the rooms). A home's several bedrooms may share one concept with several regions — the model's
    idea of a spatial concept — or get one each; both pass."""
    corpus = synthetic_corpus(seed=0)
    # the naming rule's pruning (the word channels prune nothing: tests/test_word_channels.py)
    model = SpCoTransfer(TransferHyperparameters(word_model="naming-rule"), n_iterations=30, random_state=0,
                         prune_words=True).fit(corpus)
    for e, env in enumerate(corpus):
        if env.n_taught == 0:
            continue
        labels = np.array(env.ground_truth.labels, dtype=object)[~env.is_test]
        # observed (seeds 0-2): 1.00 and 1.00 in every home
        assert homogeneity(labels, model.concepts_[e]) >= 0.95, env.name
        assert homogeneity(model.concepts_[e], true_rooms(env)) >= 0.95, env.name
    # the template words are pruned, the place names kept
    kept = {w for w, keep in zip(corpus.vocabulary.words, model.parameters_.word_mask, strict=True) if keep}
    assert {"kitchen", "bath", "toilet", "entrance", "bedroom"} <= kept
    assert not {"the", "is"} & kept


def test_naming_rule_leaves_the_word_counts_alone() -> None:
    """The naming rule works on word presence; an earlier G-test set the data array it shared with
    the (float64) word counts to 1, i.e. S^w = 1 instead of 5000 for the rest of every +MI run."""
    corpus = generate_homes(4, seed=0, new_homes=1, config=SyntheticConfig(n_features=32, n_train=6))
    data = PreparedData.from_corpus(corpus, 1.0)
    before = data.words.copy()
    assert before.data.min() == corpus.word_increment == 5000
    regions = np.arange(data.n_samples) % 3
    colocation(data.words, data.homes, regions, data.n_homes, 3)
    assert (data.words != before).nnz == 0 and data.words.data.min() == 5000


def test_word_pruning_keeps_the_word_increment() -> None:
    corpus = generate_homes(4, seed=0, new_homes=1, config=SyntheticConfig(n_features=32, n_train=6))
    model = SpCoTransfer(n_iterations=2, random_state=0, prune_words=True).fit(corpus)
    expected = corpus.word_counts([s for t in corpus.training_set() for s in t.sentences])
    assert (model.data_.words != expected).nnz == 0


def test_word_pruning_learns_home_specific_names() -> None:
    """The home-specific experiment in small: 4 experienced homes, and a new home whose three
    bedrooms are taught at 40 % with names of their own ("Emma's-room" …); the +MI model must name
    the bedrooms' test samples by them, not by the transferred "bedroom"."""
    accuracies = []
    for seed in (0, 1, 2):
        corpus = generate_homes(5, seed=seed, new_homes=1, config=SyntheticConfig(n_features=256))
        new = corpus[-1]
        gt = new.ground_truth
        names = sorted({gt.specific_labels[i] for i in np.flatnonzero(gt.specific_test)})
        taught = teach(new, 40, places=names, seed=seed)
        corpus = Corpus([*list(corpus)[:-1], taught], word_increment=corpus.word_increment)
        model = SpCoTransfer(TransferHyperparameters(word_model="naming-rule"), n_iterations=30,
                             random_state=0, prune_words=True).fit(corpus)  # the naming rule's mask
        assert {"emma's room", "mother's room", "father's room"} <= {
            w for w, keep in zip(corpus.vocabulary.words, model.parameters_.word_mask, strict=True) if keep}
        scores = evaluate_home(model.parameters_, len(corpus) - 1, taught, corpus.vocabulary, specific=True,
                               rng=0)
        accuracies.append(scores.mean_name_accuracy)
    # observed: A_n 1.00, 0.90, 0.97 (chance 1/18), with the home's own names starting in free
    # concepts and one name per taught sentence; 0.33, 0.70, 0.70 before the own-name start, 0.00
    # at every seed when S^w was lost (see the test above)
    assert np.mean(accuracies) >= 0.9 and min(accuracies) >= 0.8, accuracies


def test_transfer_names_the_places_of_a_new_home() -> None:
    accuracies = []
    for seed in (0, 1, 2):
        corpus = synthetic_corpus(seed=seed)
        model = SpCoTransfer(n_iterations=30, random_state=0, prune_words=True).fit(corpus)
        scores = evaluate_home(model.parameters_, len(corpus) - 1, corpus[-1], corpus.vocabulary, rng=0)
        assert scores.name_chance < 0.1
        accuracies.append((scores.mean_name_accuracy, scores.mean_position_accuracy))
    # observed: A_n 1.00, 0.83, 0.74 and A_p 0.71, 0.83, 0.61 at 30 sweeps (chance 1/15 and 1/6).
    # A_n 0.67, 0.33, 0.38 and A_p 0.40, 0.14, 0.26 while the sampler scored the kept words by
    # unnormalised θ^w (see test_pruned_words_leave_the_kept_words_renormalised)
    name, position = np.mean(accuracies, axis=0)
    assert name >= 0.7 and position >= 0.5, accuracies


def test_pruned_words_leave_the_kept_words_renormalised() -> None:
    """With pruning, the word likelihood of a sample is taken over the kept words with θ^w
    renormalised over them (docs/model.md: pruned words set to 0, rows renormalised).

    Concept 0 is the kitchen of this home (θ^w: "kitchen" 0.2, the template word "this" 0.8);
    concept 1 is empty here, its θ^w a draw around a sparse prior with all its mass on "kitchen".
    With "this" pruned both give the sentence's kept words probability 1, so words must not tell
    them apart; scoring by the unnormalised θ^w gave concept 1 5000 · log 5 ≈ 8,000 nats more, and
    whole places jumped into empty concepts on every sweep (new-home A_n 0.46 in the test above)."""
    from types import SimpleNamespace

    import scipy.sparse as sp

    from spco.model.assignments import concept_loglik
    from spco.model.kernels.likelihood import dimension_major

    words = sp.csr_array(np.array([[5000.0, 5000.0]]))  # "kitchen", "this": S^w = 5000 each
    visual = sp.csr_array(np.array([[3.0, 1.0]]))
    data = SimpleNamespace(visual=visual, homes=np.zeros(1, dtype=np.int64), words=words,
                           visual_by_dimension=dimension_major(visual, np.array([0, 1])))
    log_theta_w = np.log(np.array([[[0.2, 0.8], [1.0 - 1e-12, 1e-12]]]))
    log_theta_v = np.log(np.full((1, 2, 2), 0.5))
    state = SimpleNamespace(log_theta_v=log_theta_v, log_theta_w=log_theta_w,
                            word_mask=np.array([True, False]))
    loglik = concept_loglik(data, state)
    assert loglik.shape == (1, 2)
    assert abs(loglik[0, 0] - loglik[0, 1]) < 1e-6, loglik
    state.word_mask = np.array([True, True])  # nothing pruned: the full θ^w, unchanged
    loglik = concept_loglik(data, state)
    expected = 4.0 * np.log(0.5) + 5000.0 * log_theta_w[0].sum(axis=1)
    np.testing.assert_allclose(loglik[0], expected, rtol=1e-9)


# ----------------------------------------------------------------------------- numerical soundness


@pytest.fixture(scope="module")
def realistic_counts() -> Corpus:
    """S^w = 5000 and D = 4096 with ~7,000 visual counts per image; few samples, so that most of
    the L = 15 concepts and K = 20 regions are empty."""
    config = SyntheticConfig(n_features=4096, n_train=4, n_test=2)
    corpus = generate_homes(3, seed=0, new_homes=1, config=config, specific_rooms=False)
    per_image = np.concatenate([np.asarray(env.visual.sum(1)).ravel() for env in corpus])
    assert 6000 < per_image.mean() < 8500
    return corpus


@pytest.mark.parametrize(("variant", "prune"), [("exact", False), ("exact", True), ("reference", False),
                                                ("reference", True)])
def test_large_counts_stay_finite(realistic_counts: Corpus, variant: str, prune: bool) -> None:
    corpus = realistic_counts
    model = SpCoTransfer(n_iterations=6, random_state=1, variant=variant, prune_words=prune).fit(corpus)
    check_parameters(model.parameters_, len(corpus), 15, 20, len(corpus.vocabulary), 4096)
    assert model.log_joint_.shape == (6,) and np.isfinite(model.log_joint_).all()
    for name, value in vars(model.state_).items():
        if isinstance(value, np.ndarray) and value.dtype.kind == "f":
            assert not np.isnan(value).any(), name
            assert not np.isposinf(value).any(), name


def test_large_counts_stay_finite_spcoa(realistic_counts: Corpus) -> None:
    for prune in (False, True):
        model = SpCoA(n_iterations=6, random_state=2, prune_words=prune).fit(realistic_counts,
                                                                            home=realistic_counts.names[0])
        check_parameters(model.parameters_, 1, 15, 20, len(realistic_counts.vocabulary), 4096)
        assert np.isfinite(model.log_joint_).all()


def test_empty_concepts_and_regions() -> None:
    """A tiny home (12 training samples) with L = 15, K = 20: most concepts and regions are empty."""
    config = SyntheticConfig(n_features=64, n_train=2, n_test=1)
    corpus = generate_homes(2, seed=1, new_homes=1, config=config, specific_rooms=False)
    assert min(env.n_train for env in corpus) < 20
    for model in (SpCoTransfer(n_iterations=8, random_state=3),
                  SpCoTransfer(n_iterations=8, random_state=3, variant="reference", prune_words=True)):
        model.fit(corpus)
        params = model.parameters_
        check_parameters(params, 2, 15, 20, len(corpus.vocabulary), 64)
        assert (params.region_counts == 0).any()
        used = {int(c) for concepts in model.concepts_ for c in concepts}
        assert len(used) < 15
        assert np.isfinite(model.log_joint_).all()
    spcoa = SpCoA(n_iterations=8, random_state=3).fit(corpus, home=corpus.names[0])
    check_parameters(spcoa.parameters_, 1, 15, 20, len(corpus.vocabulary), 64)


# ----------------------------------------------------------------------------- reproducibility


SMALL = TransferHyperparameters(n_concepts=6, n_regions=8)


def test_same_seed_same_model_different_seed_different_model(small_corpus: Corpus) -> None:
    first = SpCoTransfer(SMALL, n_iterations=5, random_state=7).fit(small_corpus)
    again = SpCoTransfer(SMALL, n_iterations=5, random_state=7).fit(small_corpus)
    other = SpCoTransfer(SMALL, n_iterations=5, random_state=8).fit(small_corpus)
    for name, array in first.parameters_.arrays().items():
        np.testing.assert_array_equal(array, getattr(again.parameters_, name), err_msg=name)
    np.testing.assert_array_equal(first.log_joint_, again.log_joint_)
    for a, b in zip(first.concepts_, again.concepts_, strict=True):
        np.testing.assert_array_equal(a, b)
    assert not np.array_equal(first.parameters_.visual_probabilities, other.parameters_.visual_probabilities)
    assert not np.array_equal(first.log_joint_, other.log_joint_)
    # a Generator is used as given (and advanced), an int seeds a fresh one
    gen = SpCoTransfer(SMALL, n_iterations=5, random_state=np.random.default_rng(7)).fit(small_corpus)
    np.testing.assert_array_equal(gen.parameters_.concept_weights, first.parameters_.concept_weights)


# ----------------------------------------------------------------------------- bad arguments


@pytest.mark.parametrize(("changes", "message"), [
    ({"alpha_visual": 0.0}, "alpha_visual must be a positive number"),
    ({"alpha_word": -0.01}, "alpha_word must be a positive number"),
    ({"delta_visual": float("nan")}, "delta_visual must be a positive number"),
    ({"gamma": 0}, "gamma must be a positive number"),
    ({"gamma0": float("inf")}, "gamma0 must be a positive number"),
    ({"beta": -3.0}, "beta must be a positive number"),
    ({"kappa0": 0.0}, "kappa0 must be a positive number"),
    ({"psi0": (10.0, -10.0, 0.5, 0.5)}, "psi0 must be symmetric positive definite"),
    ({"psi0": ((1.0, 2.0, 0, 0), (2.0, 1.0, 0, 0), (0, 0, 1.0, 0), (0, 0, 0, 1.0))},
     "psi0 must be symmetric positive definite"),
    ({"psi0": (1.0, 2.0)}, "psi0 must be 4 positive values"),
    ({"n_concepts": 0}, "n_concepts must be an integer >= 1"),
    ({"n_regions": 0}, "n_regions must be an integer >= 1"),
    ({"n_concepts": 2.5}, "n_concepts must be an integer >= 1"),
    ({"nu0": 3.0}, "nu0 must exceed"),
    ({"nu0": 2.0}, "nu0 must exceed"),
    ({"mi_threshold": -0.1}, "mi_threshold must be >= 0"),
])
def test_bad_hyperparameters(changes: dict, message: str) -> None:
    with pytest.raises(ConfigurationError, match=message):
        TransferHyperparameters(**changes)


def test_bad_fit_arguments(small_corpus: Corpus) -> None:
    with pytest.raises(ConfigurationError, match="n_iterations must be an integer >= 1"):
        SpCoTransfer(SMALL, n_iterations=0).fit(small_corpus)
    with pytest.raises(ConfigurationError, match="n_iterations must be an integer >= 1"):
        SpCoTransfer(SMALL, n_iterations=2.5).fit(small_corpus)
    with pytest.raises(ConfigurationError, match="variant must be 'exact' or 'reference'"):
        SpCoTransfer(SMALL, variant="fast", n_iterations=1).fit(small_corpus)
    with pytest.raises(ConfigurationError, match=r"expects a spco\.data\.Corpus"):
        SpCoTransfer(SMALL, n_iterations=1).fit(list(small_corpus))
    with pytest.raises(ConfigurationError, match=r"expects a spco\.data\.Corpus"):
        SpCoA(n_iterations=1).fit("homes/")
    with pytest.raises(ConfigurationError, match="TransferHyperparameters"):
        SpCoTransfer({"n_concepts": 3}, n_iterations=1).fit(small_corpus)
    with pytest.raises(ConfigurationError, match="pass home=NAME"):
        SpCoA(n_iterations=1).fit(small_corpus)
    with pytest.raises(ConfigurationError, match="no home named"):
        SpCoA(n_iterations=1).fit(small_corpus, home="nowhere")
    with pytest.raises(ConfigurationError, match="not fitted"):
        SpCoTransfer().predict_names(0, np.zeros((1, 4)), np.zeros((1, 64)))


def test_corpus_without_training_data(small_corpus: Corpus) -> None:
    env = small_corpus[0]
    all_test = Environment(name="all-test", ids=env.ids, positions=env.positions, visual=env.visual,
                           sentences=env.sentences, is_test=np.ones(env.n_samples, dtype=bool))
    corpus = Corpus([small_corpus[1], all_test], vocabulary=small_corpus.vocabulary)
    with pytest.raises(ConfigurationError, match="'all-test' has no training samples"):
        SpCoTransfer(SMALL, n_iterations=1).fit(corpus)
    with pytest.raises(ConfigurationError, match="no training samples"):
        SpCoA(n_iterations=1).fit(corpus, home="all-test")


# ----------------------------------------------------------------------------- every variant fits


@pytest.mark.parametrize(("variant", "prune"), [("exact", False), ("exact", True), ("reference", False),
                                                ("reference", True)])
def test_transfer_variants_fit(small_corpus: Corpus, variant: str, prune: bool) -> None:
    model = SpCoTransfer(SMALL, variant=variant, prune_words=prune, n_iterations=4, random_state=0)
    model.fit(small_corpus)
    V, D = len(small_corpus.vocabulary), small_corpus.n_features
    check_parameters(model.parameters_, len(small_corpus), 6, 8, V, D)
    assert model.settings_.variant == variant and model.settings_.prune == prune
    assert model.home_names_ == small_corpus.names and model.n_iter_ == 4
    assert model.log_joint_.shape == (4,) and np.isfinite(model.log_joint_).all()
    for env, concepts, regions, ids in zip(small_corpus, model.concepts_, model.regions_, model.training_ids_,
                                           strict=True):
        assert concepts.shape == regions.shape == (env.n_train,)
        assert concepts.min() >= 0 and concepts.max() < 6 and regions.min() >= 0 and regions.max() < 8
        np.testing.assert_array_equal(ids, env.ids[~env.is_test])


@pytest.mark.parametrize("prune", [False, True])
def test_spcoa_baselines_fit(small_corpus: Corpus, prune: bool) -> None:
    home = small_corpus.names[1]
    model = SpCoA(SpCoAHyperparameters(n_concepts=5, n_regions=7), prune_words=prune, n_iterations=4,
                  random_state=0).fit(small_corpus, home=home)
    check_parameters(model.parameters_, 1, 5, 7, len(small_corpus.vocabulary), small_corpus.n_features)
    assert model.home_names_ == [home] and model.settings_.variant == "spcoa"
    assert isinstance(SpCoA()._default_hyperparameters(), SpCoAHyperparameters)


# ----------------------------------------------------------------------------- the real data, if present


@pytest.mark.sigverse
def test_sigverse_homes_fit_finite(sigverse_dir: Path) -> None:
    """Two taught SIGVerse homes and an untaught one (the real fc7 × 5 counts, S^w = 5000; the
    development home 3LDK_9 taught nothing: a test fits no held-out home, benchmarks/SPLIT.md)."""
    homes = [load(sigverse_dir / name)[name] for name in ("1LDK_1", "1LDK_2", "3LDK_9")]
    homes[-1] = homes[-1].with_sentences((None,) * homes[-1].n_samples)
    corpus = Corpus(homes)
    model = SpCoTransfer(n_iterations=5, random_state=0, prune_words=True).fit(corpus)
    check_parameters(model.parameters_, 3, 15, 20, len(corpus.vocabulary), 4096)
    assert np.isfinite(model.log_joint_).all()


def test_label_swaps_relabel_state_and_count_cache_consistently(monkeypatch: pytest.MonkeyPatch) -> None:
    """An accepted swap relabels the samples, G_e and π of its home, redraws that home's θ only,
    and carries the visual count cache along: the next counts equal a recount."""
    from spco.model import moves
    from spco.model.observations import HierarchicalMultinomial

    corpus = generate_homes(4, seed=2, new_homes=1, config=SyntheticConfig(n_features=32, n_train=6))
    model = SpCoTransfer(n_iterations=2, random_state=0).fit(corpus)
    data, state, hyper = model.data_, model.state_, model.hyperparameters_
    E, L = data.n_homes, hyper.n_concepts
    settings = gibbs.SamplerSettings.create("exact", prune=False)
    perms = np.tile(np.arange(L), (E, 1))
    perms[1, [0, 1]] = [1, 0]  # home 1: concepts 0 and 1 trade places
    monkeypatch.setattr(parameter_steps, "concept_swap_step", lambda *args, **kwargs: perms.copy())
    stats = sweep_statistics.sufficient_statistics(data, state, hyper, None)
    concepts, log_g = state.concepts.copy(), state.log_g.copy()
    theta_v, theta_w = state.log_theta_v.copy(), state.log_theta_w.copy()
    parameter_steps.swap_labels(data, state, stats, hyper, settings, np.random.default_rng(3))
    home1 = data.homes == 1
    swapped = {0: 1, 1: 0}
    expected = np.array([swapped.get(c, c) if h else c for c, h in zip(concepts, home1, strict=True)])
    assert np.array_equal(state.concepts, expected)
    assert np.array_equal(state.log_g[1, [0, 1]], log_g[1, [1, 0]])
    others = np.arange(E) != 1
    assert np.array_equal(state.log_theta_v[others], theta_v[others])
    assert np.array_equal(state.log_theta_w[others], theta_w[others])
    assert not np.array_equal(state.log_theta_v[1], theta_v[1]) and np.isfinite(state.log_theta_v[1]).all()
    counts = sweep_statistics.sufficient_statistics(data, state, hyper, None).visual
    recount = HierarchicalMultinomial.statistics(data.visual, data.homes, state.concepts, E, L)
    assert np.array_equal(counts, recount)
    assert not counts.flags.writeable
    assert moves.concept_swap_step is not parameter_steps.concept_swap_step  # (only the sampler's patched)


def test_visual_counts_follow_the_assignments_exactly() -> None:
    """The sampler keeps n^v between sweeps and moves only the rows of samples that changed
    concept; whatever the change (a few samples, many, a relabelling), the counts equal a recount
    and cannot be modified by the steps that read them."""
    from spco.model.observations import HierarchicalMultinomial

    corpus = generate_homes(4, seed=0, new_homes=1, config=SyntheticConfig(n_features=32, n_train=6))
    model = SpCoTransfer(n_iterations=3, random_state=0).fit(corpus)
    data, state, hyper = model.data_, model.state_, model.hyperparameters_
    E, L = data.n_homes, hyper.n_concepts
    rng = np.random.default_rng(0)
    for n_changed in (0, 1, 3, data.n_samples // 2, data.n_samples):
        rows = rng.choice(data.n_samples, size=n_changed, replace=False)
        state.concepts = state.concepts.copy()
        state.concepts[rows] = rng.integers(0, L, size=n_changed)
        counts = sweep_statistics.sufficient_statistics(data, state, hyper, None).visual
        assert np.array_equal(counts, HierarchicalMultinomial.statistics(data.visual, data.homes,
                                                                         state.concepts, E, L))
        assert not counts.flags.writeable
