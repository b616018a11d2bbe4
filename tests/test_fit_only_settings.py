"""A knowledge fitted with a setting of the fit only (``block_moves="phi"``: the φ^v-marginal block
moves of the joint fit) adapts, teaches and is served: a new home's sampler holds φ^v at the knowledge,
so the move has nothing to integrate there, and the home is learnt as from the same knowledge with
``block_moves="off"`` — the same draws (:func:`spco.model.home_shard.new_home_block_moves`). Each path
a user takes: the library (``fit_knowledge``, ``adapt``, ``teach``), the CLI (``spco fit --set``,
``spco adapt``, ``spco teach``) and the service's load (``LiveHome``). On tiny synthetic homes."""

from __future__ import annotations

import dataclasses
import hashlib
import warnings
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner
from conftest import synthetic_home_folders

from spco import knowledge as kn
from spco.data.environment import Corpus
from spco.data.synthetic import SyntheticConfig, generate_homes
from spco.knowledge.fit import default_hyperparameters
from spco.model.home_shard import new_home_block_moves

PHI = ["target=power", "visual_prior=estimate", "block_moves=phi"]


def _state_digest(home: kn.HomeModel) -> str:
    digest = hashlib.sha256()
    for name, value in sorted(vars(home.state).items()):
        if isinstance(value, np.ndarray):
            digest.update(name.encode() + np.ascontiguousarray(value).tobytes())
    return digest.hexdigest()


@pytest.fixture(scope="module")
def phi_knowledge():
    """A knowledge of three tiny synthetic homes fitted with the φ^v-marginal moves, and a new home."""
    envs = list(generate_homes(4, seed=2, config=SyntheticConfig(n_features=32, n_train=10, language="free"),
                               new_homes=1))
    hyper = default_hyperparameters(Corpus(envs[:3])).with_settings(PHI)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        knowledge = kn.fit_knowledge(Corpus(envs[:3]), n_iterations=4, random_state=0, hyperparameters=hyper)
    assert knowledge.hyperparameters.block_moves == "phi"
    return knowledge, envs[3]


def test_which_block_moves_a_new_home_runs(phi_knowledge) -> None:
    """The region block moves run in a new home for "adapt" and "all"; "phi" (the joint fit's move)
    and "off" run none; the power target of the knowledge is kept."""
    assert [new_home_block_moves(s) for s in ("off", "adapt", "all", "phi")] == [False, True, True, False]
    knowledge, _ = phi_knowledge
    settings = knowledge.shared_part().sampler_settings()
    assert not settings.block_moves and settings.power  # the power target kept, no block moves


def test_adapt_and_teach_run_as_with_block_moves_off(phi_knowledge) -> None:
    """Adapting (fixed and ``joint``) and teaching a home from the "phi" knowledge draw what the same
    knowledge with "off" draws; the home keeps the knowledge's setting."""
    knowledge, env = phi_knowledge
    off = dataclasses.replace(knowledge, hyperparameters=dataclasses.replace(knowledge.hyperparameters,
                                                                              block_moves="off"))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        home = kn.adapt(knowledge, env, n_iterations=3, random_state=1)
        same = kn.adapt(off, env, n_iterations=3, random_state=1)
        assert home.knowledge.hyperparameters.block_moves == "phi"
        assert _state_digest(home) == _state_digest(same)
        joint = kn.adapt(knowledge, env, n_iterations=2, random_state=1, joint=True)
        assert _state_digest(joint) == _state_digest(kn.adapt(off, env, n_iterations=2, random_state=1,
                                                              joint=True))
        taught = kn.teach(home, {int(home.ids[2]): "this is the pantry"}, random_state=1)
        also = kn.teach(same, {int(same.ids[2]): "this is the pantry"}, random_state=1)
    assert "pantry" in taught.vocabulary
    assert _state_digest(taught) == _state_digest(also)


def test_cli_fit_adapt_teach_and_the_service_with_phi_knowledge(tmp_path: Path) -> None:
    """``spco fit --set block_moves=phi`` (with the power target it needs), then ``spco adapt`` and
    ``spco teach`` of a new home, then the service's load and a teaching through it."""
    from spco.cli.knowledge import adapt, fit, teach
    from spco.service import LiveHome

    homes = synthetic_home_folders(tmp_path, 3, seed=4)
    knowledge, home, taught = tmp_path / "k.spco", tmp_path / "h.spco", tmp_path / "t.spco"
    settings = [a for s in PHI for a in ("--set", s)]
    runner = CliRunner()
    result = runner.invoke(fit, ["--data", str(homes["experienced"]), "--iterations", "3", "--seed", "0",
                                 "--out", str(knowledge), *settings], catch_exceptions=False)
    assert result.exit_code == 0, result.output
    assert kn.load_knowledge(knowledge).hyperparameters.block_moves == "phi"
    result = runner.invoke(adapt, [str(knowledge), "--home", str(homes["new"]), "--iterations", "2",
                                   "--seed", "0", "--out", str(home)], catch_exceptions=False)
    assert result.exit_code == 0, result.output
    model = kn.load_home_model(home)
    assert model.knowledge.hyperparameters.block_moves == "phi"
    result = runner.invoke(teach, [str(home), "--id", str(int(model.ids[1])), "--sentence",
                                   "this is the pantry", "--out", str(taught)], catch_exceptions=False)
    assert result.exit_code == 0, result.output
    assert "pantry" in kn.load_home_model(taught).vocabulary
    with LiveHome(home, writer="thread", seed=0) as live:
        answer = live.teach(id=int(model.ids[1]), sentence="this is the pantry")
        assert answer["teachings"] == 1 and "pantry" in answer["new_words"]
