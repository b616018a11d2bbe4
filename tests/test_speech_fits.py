"""The one fit of the speech benchmarks (``benchmarks/free_speech.py``: ``settings_hyperparameters``,
``fit_speech``; ``benchmarks/natural_speech.py``: ``configurations``, ``fit_arguments``, ``cache_path``,
``fitted``, ``fitted_runs``), which ``natural_speech.py``, ``speech_errors.py``, ``where_account.py``,
``concept_split.py`` and the diagnoses that read ``speech_errors.py``'s fits all call: on a small
synthetic corpus, against the estimator called by hand; the configurations on the development homes
(skipped without the data set)."""

from __future__ import annotations

import pickle
import sys
from pathlib import Path

import numpy as np
import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "benchmarks"))
from free_speech import fit_speech, settings_hyperparameters
from natural_speech import SIDES, cache_path, configurations, fit_arguments, fitted, fitted_runs

from spco.data import Corpus
from spco.errors import ConfigurationError
from spco.evaluation.experiments import trial_seed
from spco.model import SpCoTransfer
from spco.model.hyperparameters import TransferHyperparameters

SWEEPS = 3


def _same_fit(a: SpCoTransfer, b: SpCoTransfer) -> bool:
    """Whether two fits ended in the same state (concepts of every home and the parameters)."""
    return (all(np.array_equal(x, y) for x, y in zip(a.concepts_, b.concepts_, strict=True))
            and np.array_equal(a.parameters_.word_probabilities, b.parameters_.word_probabilities)
            and np.array_equal(a.parameters_.region_means, b.parameters_.region_means))


def test_settings_are_the_hyperparameters_of_set_over_a_base() -> None:
    assert settings_hyperparameters([]) is None  # the model's own
    base = TransferHyperparameters(view_counts=4.0)
    assert settings_hyperparameters([], base) is base
    assert settings_hyperparameters(["word_counts=none", "n_concepts=7"]) == \
        TransferHyperparameters().with_settings(["word_counts=none", "n_concepts=7"])
    over = settings_hyperparameters(("n_concepts=7",), base)  # a tuple, as fitted passes its default
    assert over.view_counts == 4.0 and over.n_concepts == 7
    with pytest.raises(ConfigurationError, match="no_such_thing"):
        settings_hyperparameters(["no_such_thing=1"])


def test_the_fit_is_the_estimator_with_the_trial_seed_of_the_configuration(small_corpus: Corpus,
                                                                            tmp_path: Path) -> None:
    """``fitted`` = SpCoTransfer+MI (exact) with the trial seed of (seed, the label's index) and the
    hyperparameters of ``--set``; with a cache, written once under :func:`cache_path` and read back."""
    labels = ["3LDK_9", "1LDK_1 (out)"]
    settings = ["n_concepts=6", "n_regions=8"]
    hyper = TransferHyperparameters().with_settings(settings)
    by_hand = SpCoTransfer(hyper, variant="exact", prune_words=True, n_iterations=SWEEPS,
                           random_state=trial_seed(2, 1)).fit(small_corpus)
    assert _same_fit(fit_speech(small_corpus, settings_hyperparameters(settings), SWEEPS, trial_seed(2, 1)),
                     by_hand)
    model = fitted(small_corpus, 2, "1LDK_1 (out)", labels, settings=settings, sweeps=SWEEPS, cache=tmp_path)
    assert _same_fit(model, by_hand)
    path = cache_path(tmp_path, settings, SWEEPS, "1LDK_1 (out)", 2)
    assert path.parent == tmp_path and path.name.endswith("-1LDK_1-s2.pkl") and path.exists()
    assert sorted(p.name for p in tmp_path.iterdir()) == [path.name]  # no temporary file left
    # the key: the settings in any order, the sweeps, the configuration's home and the seed
    assert cache_path(tmp_path, settings[::-1], SWEEPS, "1LDK_1", 2) == path
    assert len({path, cache_path(tmp_path, settings[:1], SWEEPS, "1LDK_1", 2),
                cache_path(tmp_path, settings, SWEEPS + 1, "1LDK_1", 2),
                cache_path(tmp_path, settings, SWEEPS, "3LDK_9", 2),
                cache_path(tmp_path, settings, SWEEPS, "1LDK_1", 3)}) == 5
    model.marker = "from the cache"  # read back, not fitted again
    path.write_bytes(pickle.dumps(model))
    assert fitted(small_corpus, 2, "1LDK_1 (out)", labels, settings=settings, sweeps=SWEEPS,
                  cache=tmp_path).marker == "from the cache"
    # without --set: the model's own hyperparameters
    own = SpCoTransfer(None, variant="exact", prune_words=True, n_iterations=SWEEPS,
                       random_state=trial_seed(2, 0)).fit(small_corpus)
    assert _same_fit(fitted(small_corpus, 2, "3LDK_9", labels, sweeps=SWEEPS), own)


def test_the_runs_are_every_seed_of_every_configuration_in_order(small_corpus: Corpus) -> None:
    """Seeds first, then configurations; a configuration's trial seed is its index in ``labels`` (not
    in the chosen ones); a home held out is scored on every sample."""
    homes = list(small_corpus)
    configs = [("new (out)", homes[:1], homes[2]), ("new", homes[:2], homes[2])]
    labels = ["other", "new", "new (out)"]
    runs = list(fitted_runs(configs, labels, [5, 1], sweeps=SWEEPS))
    assert [(r[0], r[1]) for r in runs] == [(5, "new (out)"), (5, "new"), (1, "new (out)"), (1, "new")]
    for seed, label, env, corpus, model, e, scored in runs:
        config = next(c for c in configs if c[0] == label)
        assert env is config[2] and corpus.names == [*(h.name for h in config[1]), env.name]
        assert e == len(corpus) - 1
        assert scored.is_test.all() if label.endswith("(out)") else scored is env
        by_hand = SpCoTransfer(None, variant="exact", prune_words=True, n_iterations=SWEEPS,
                               random_state=trial_seed(seed, labels.index(label))).fit(corpus)
        assert _same_fit(model, by_hand)
    assert not homes[2].is_test.all()


def test_the_fit_options_and_their_defaults() -> None:
    import argparse

    args = fit_arguments(argparse.ArgumentParser()).parse_args(["--set", "a=1", "--set", "b=2", "c=3"])
    assert (args.seeds, args.sweeps, args.set, args.cache) == ([0], 60, ["a=1", "b=2", "c=3"], None)
    natural = fit_arguments(argparse.ArgumentParser(), seeds=(0, 1, 2), sweeps=200, cache=False
                            ).parse_args([])
    assert (natural.seeds, natural.sweeps, natural.set) == ([0, 1, 2], 200, [])
    assert not hasattr(natural, "cache")


def test_the_development_configurations(sigverse_dir: Path) -> None:
    """3LDK_9 with the 8 development homes, then each development home held out of the knowledge,
    untaught, with the accepted names; only development homes."""
    if not (sigverse_dir.parent / "sigverse_subject").is_dir():
        pytest.skip(f"people's sentences not found beside {sigverse_dir}")
    accepted = {"kitchen": ("kitchen",)}
    knowledge, configs = configurations(sigverse_dir, accepted, leave_one_out=True)
    development = SIDES["development"]["knowledge"]
    assert [env.name for env in knowledge] == list(development)
    assert [c[0] for c in configs] == ["3LDK_9", *(f"{h} (out)" for h in development)]
    assert configs[0][1] == knowledge and configs[0][2].ground_truth.regions is not None
    for label, homes, env in configs[1:]:
        assert env.name == label.split()[0] and env.name not in [h.name for h in homes] and len(homes) == 7
        assert all(s is None for s in env.sentences) and env.ground_truth.accepted_names == accepted
    assert len(configurations(sigverse_dir, accepted)[1]) == 1
