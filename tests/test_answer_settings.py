"""The answer's settings carried by the model (issue 29, item 3 "One predictor"): ``view_in_room`` and
``typical`` are hyperparameters (:class:`~spco.model.answer_settings.AnswerSettings`), written by
``to_dict`` only when not default, set by ``spco fit --set`` / ``spco adapt --set``, and read from the
model by every answer — ``spco what``, the service's predictor, ``name_prediction``, ``evaluate_home``
and ``evaluate_answers`` — which give the same probabilities; ``typical="learn"`` is learnt when a
knowledge is fitted. A default knowledge and home file are the bytes main gave."""

from __future__ import annotations

import dataclasses
import importlib.util
import json
import math
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner
from conftest import fit_and_adapt, synthetic_home_folders

from spco import knowledge as kn
from spco.cli import main
from spco.data.environment import Corpus
from spco.data.loading import load_home
from spco.errors import ConfigurationError
from spco.evaluation.metrics import evaluate_answers, evaluate_home
from spco.model.answer_settings import AnswerSettings, with_answer_settings
from spco.model.confidence import answer_names
from spco.model.hyperparameters import TransferHyperparameters
from spco.model.transfer import SpCoTransfer

#: file digests (arrays, and the header without times, checksums, versions and provenance) of the default
#: knowledge and home files of the ``cli`` fixture, made with main 08373cf's ``src`` (the fixture's
#: commands run by /work/out/onepred22/pin.py of branch onepred22): the defaults stay byte-identical
PINNED = {"knowledge": "65c992cf1dab158e/b6b55e8004d8e56d", "home": "46bf8d294551fce8/807a3b40140236f9"}
_TOOL = Path(__file__).resolve().parents[1] / "tools" / "state_digests.py"


def _file_digest(path: Path) -> str:
    """The file digest of ``tools/state_digests.py`` (one definition) without its ``/v<version>``."""
    spec = importlib.util.spec_from_file_location("_state_digests", _TOOL)
    tool = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(tool)
    return tool.file_digest(path).rsplit("/v", 1)[0]


def _run(args: list[object]) -> str:
    result = CliRunner().invoke(main, [str(a) for a in args], catch_exceptions=False)
    assert result.exit_code == 0, result.output
    return result.output


@pytest.fixture(scope="module")
def cli(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    """Knowledge and home files of ``spco fit`` + ``spco adapt``: the defaults, ``--set view_in_room=true``
    at the fit (same seeds), and the default knowledge adapted with ``--set typical=0.9``."""
    folders = synthetic_home_folders(tmp_path_factory.mktemp("answer_settings"), 4, seed=5, n_features=64)
    fit, adapt = ["--iterations", 12, "--seed", 1], ["--iterations", 15]
    knowledge, home, _ = fit_and_adapt(folders, fit, adapt)
    in_room_k, in_room, _ = fit_and_adapt(folders, [*fit, "--set", "view_in_room=true"], adapt,
                                          knowledge="in_room.knowledge.spco", home="in_room.home.spco")
    typical = folders["root"] / "typical.home.spco"
    _run(["adapt", knowledge, "--home", folders["new"], *adapt, "--set", "typical=0.9", "--out", typical])
    return {"knowledge": knowledge, "home": home, "in_room_knowledge": in_room_k, "in_room": in_room,
            "typical": typical, "new": folders["new"], "experienced": folders["experienced"]}


def test_default_files_are_the_bytes_main_wrote(cli: dict[str, Path]) -> None:
    assert _file_digest(cli["knowledge"]) == PINNED["knowledge"]
    assert _file_digest(cli["home"]) == PINNED["home"]


def test_an_answer_setting_changes_no_fit_and_is_kept_in_the_files(cli: dict[str, Path]) -> None:
    """``--set view_in_room=true`` at the fit: the knowledge's arrays and the adapted home's state are the
    default's bit for bit, the hyperparameters differ by the setting alone; ``adapt --set typical=0.9``
    likewise keeps the home's state and writes ρ into its file."""
    plain, in_room = kn.load_knowledge(cli["knowledge"]), kn.load_knowledge(cli["in_room_knowledge"])
    for name in ("log_phi_visual", "log_phi_words", "log_g0", "word_mask", "concentration_visual"):
        assert np.array_equal(getattr(plain, name), getattr(in_room, name)), name
    assert in_room.hyperparameters == dataclasses.replace(plain.hyperparameters, view_in_room=True)
    assert in_room.hyperparameters.to_dict() == {**plain.hyperparameters.to_dict(), "view_in_room": True}
    assert "view_in_room" not in plain.hyperparameters.to_dict()
    assert "typical" not in plain.hyperparameters.to_dict()
    homes = {k: kn.load_home_model(cli[k]) for k in ("home", "in_room", "typical")}
    for k in ("in_room", "typical"):
        assert np.array_equal(homes[k].state.concepts, homes["home"].state.concepts)
        assert np.array_equal(homes[k].state.log_theta_w, homes["home"].state.log_theta_w)
    assert homes["typical"].hyperparameters.answer_settings() == AnswerSettings(typical=0.9)
    assert homes["in_room"].hyperparameters.answer_settings() == AnswerSettings(view_in_room=True)
    assert homes["home"].hyperparameters.answer_settings() == AnswerSettings()


@pytest.mark.parametrize("which", ["in_room", "typical"])
def test_what_the_service_and_the_experiments_give_the_same_probabilities(cli: dict[str, Path], which: str,
                                                                           tmp_path: Path) -> None:
    """A home whose model holds an answer setting answers with it through ``spco what --json`` (CLI),
    the service's predictor (``what_answer``: ``spco serve``'s /what and the ROS node), ``name_prediction``
    and ``evaluate_home`` with the home's settings: the same probabilities, equal to ``answer_names`` with
    the setting given explicitly and unlike the answer without it."""
    from spco.knowledge.queries import answer_inputs
    from spco.knowledge.requests import Pose, View, What
    from spco.service.answers import what_answer

    home = kn.load_home_model(cli[which])
    settings = home.hyperparameters.answer_settings()
    assert settings != AnswerSettings()
    env = load_home(cli["new"])
    test = np.flatnonzero(env.is_test)
    poses, views = env.positions[test], env.visual[test]
    params, rooms = answer_inputs(home)
    w = home.hyperparameters.view_weight()
    explicit = answer_names(params, 0, home.vocabulary, poses, views, view_counts=w, weighting=home.weighting,
                            rooms=rooms, settings=settings, top_k=len(home.vocabulary))
    without = answer_names(params, 0, home.vocabulary, poses, views, view_counts=w, weighting=home.weighting,
                           rooms=rooms, settings=AnswerSettings(), top_k=len(home.vocabulary))
    assert not np.allclose(explicit.word_probabilities, without.word_probabilities)
    robot = kn.name_prediction(home, poses, views, top_k=len(home.vocabulary))
    assert np.array_equal(robot.word_probabilities, explicit.word_probabilities)
    scored = evaluate_home(params, 0, env, home.vocabulary, weighting=home.weighting, view_counts=w,
                           answer_params=params, answer_rooms=rooms, settings=settings, rng=0)
    assert np.array_equal(scored.name_predictions.word_probabilities[:, :],
                          kn.name_prediction(home, poses, views, top_k=3).word_probabilities)
    words = list(home.vocabulary.words)
    for i in range(min(3, test.size)):
        x, y, s, c = (float(v) for v in poses[i])
        view = views[[i]].toarray()[0]
        np.save(tmp_path / "view.npy", view)
        printed = json.loads(_run(["what", cli[which], "--x", x, "--y", y, "--theta", math.atan2(s, c),
                                   "--visual", tmp_path / "view.npy", "--top", 5, "--json"]))
        served = what_answer(home, What(Pose(x, y, math.atan2(s, c)), View(visual=view), 5))
        assert printed["names"] == served["names"]
        for entry in served["names"]:
            want = explicit.word_probabilities[i, words.index(entry["name"])]
            assert entry["probability"] == pytest.approx(want, rel=1e-9, abs=1e-12)


@pytest.mark.parametrize("settings", [AnswerSettings(view_in_room=True), AnswerSettings(typical=0.9)])
def test_evaluate_answers_reads_the_fits_settings(small_corpus, settings: AnswerSettings) -> None:
    """A joint fit whose hyperparameters hold an answer setting: ``evaluate_answers`` scores what
    ``predict_names`` answers, ``answer_names`` with the setting given explicitly; the fit is the
    default's (the setting is read by the answers only), and the override ``AnswerSettings()`` scores
    the default fit's answers from the same fit."""
    e = len(small_corpus) - 1
    env = small_corpus[e]
    test = env.is_test
    hyper = TransferHyperparameters(**dataclasses.asdict(settings))
    model = SpCoTransfer(hyper, prune_words=True, n_iterations=5, random_state=0).fit(small_corpus)
    plain = SpCoTransfer(prune_words=True, n_iterations=5, random_state=0).fit(small_corpus)
    assert np.array_equal(model.state_.concepts, plain.state_.concepts)
    params, rooms, weighting = model.answer_inputs(e)
    explicit = answer_names(params, e, model.vocabulary_, env.positions[test], env.visual[test], top_k=3,
                            weighting=weighting, view_counts=model.settings_.view_counts, rooms=rooms,
                            settings=settings)
    scored = evaluate_answers(model, e, env, rng=0)
    robot = model.predict_names(e, env.positions[test], env.visual[test])
    assert np.array_equal(scored.name_predictions.word_probabilities, explicit.word_probabilities)
    assert np.array_equal(robot.word_probabilities, explicit.word_probabilities)
    default = evaluate_answers(model, e, env, rng=0, settings=AnswerSettings())
    assert np.array_equal(default.name_predictions.word_probabilities,
                          evaluate_answers(plain, e, env, rng=0).name_predictions.word_probabilities)
    assert not np.allclose(default.name_predictions.word_probabilities, explicit.word_probabilities)


def test_typical_learn_is_learnt_at_fit_time_and_held(small_corpus, tmp_path: Path) -> None:
    """``typical="learn"``: the knowledge holds ρ as a number, the one :func:`learnt_typicality` gives
    from the experienced homes with the knowledge's φ^w, G_0 and w (recorded in its provenance); its
    file and a home adapted from it answer with it; the fit's arrays are the default's."""
    from spco.knowledge.fit import learnt_typicality

    homes = Corpus(list(small_corpus)[:2])
    learnt = kn.fit_knowledge(homes, n_iterations=6, random_state=0,
                              hyperparameters=TransferHyperparameters(typical="learn"))
    plain = kn.fit_knowledge(homes, n_iterations=6, random_state=0, hyperparameters=TransferHyperparameters())
    assert np.array_equal(learnt.log_phi_visual, plain.log_phi_visual)
    rho, used = learnt_typicality(list(homes), learnt.log_phi_words, learnt.log_g0,
                                  list(learnt.vocabulary.words), plain.hyperparameters)
    assert isinstance(learnt.hyperparameters.typical, float) and 0.0 < learnt.hyperparameters.typical <= 1.0
    assert learnt.hyperparameters.typical == rho and used > 0
    assert learnt.provenance["typical"] == {"learnt": rho, "samples": used}
    assert "typical" not in plain.provenance
    assert f"answers: rooms typical with ρ = {rho:g} (learnt from {used} samples)" in learnt.describe()
    assert "answers:" not in plain.describe()
    again = kn.load_knowledge(learnt.save(tmp_path / "k.spco"))
    assert again.hyperparameters.typical == rho
    home = kn.adapt(again, small_corpus[2], n_iterations=3, random_state=0)
    assert home.hyperparameters.answer_settings() == AnswerSettings(typical=rho)
    unlabelled = Corpus([dataclasses.replace(env, ground_truth=None) for env in homes])
    with pytest.raises(ConfigurationError, match=r"typical='learn'.*has none"):
        kn.fit_knowledge(unlabelled, n_iterations=2, random_state=0,
                         hyperparameters=TransferHyperparameters(typical="learn"))
    with pytest.raises(ConfigurationError, match="typical='learn'"):
        SpCoTransfer(TransferHyperparameters(typical="learn"), n_iterations=2).fit(small_corpus)


def test_settings_are_checked_once_naming_the_field() -> None:
    hyper = TransferHyperparameters()
    assert hyper.with_settings(["view_in_room=true"]).view_in_room is True
    assert hyper.with_settings(["view_in_room=false"]) == hyper
    assert hyper.with_settings(["typical=0.25"]).typical == 0.25
    assert hyper.with_settings(["typical=learn"]).typical == "learn"
    assert hyper.with_settings(["typical=0.25", "typical=off"]) == hyper
    for bad, field in (("view_in_room=1", "view_in_room"), ("view_in_room=yes", "view_in_room"),
                       ("typical=0", "typical"), ("typical=1.5", "typical"), ("typical=nan", "typical"),
                       ("typical=often", "typical")):
        with pytest.raises(ConfigurationError, match=field):
            hyper.with_settings([bad])
    with pytest.raises(ConfigurationError, match="view_in_room"):
        hyper.with_settings(["view_in_room=true", "typical=0.5"])
    for bad in ({"view_in_room": 1}, {"typical": True}, {"typical": "learnt"}, {"typical": -0.1}):
        with pytest.raises(ConfigurationError, match=next(iter(bad))):
            TransferHyperparameters(**bad)
    with pytest.raises(ConfigurationError, match="typical"):
        AnswerSettings(typical="learn")  # type: ignore[arg-type]
    with pytest.raises(ConfigurationError, match="typical='learn'"):
        TransferHyperparameters(typical="learn").answer_settings()
    kept = TransferHyperparameters(view_in_room=True)
    assert TransferHyperparameters.from_dict(kept.to_dict()) == kept
    ρ = TransferHyperparameters(typical=0.5)
    assert ρ.to_dict()["typical"] == 0.5 and TransferHyperparameters.from_dict(ρ.to_dict()) == ρ
    # after the fit only the answer's settings are set (spco adapt --set), ρ given as a number
    assert with_answer_settings(hyper, ["name_answer=listener", "typical=0.5"]).typical == 0.5
    with pytest.raises(ConfigurationError, match="only the answer's settings"):
        with_answer_settings(hyper, ["n_concepts=3"])
    with pytest.raises(ConfigurationError, match="learnt"):
        with_answer_settings(hyper, ["typical=learn"])
    # the model's numbers are plain Python (JSON-ready) whatever they were given as
    numpy = TransferHyperparameters(view_in_room=np.bool_(True))
    assert numpy.view_in_room is True and json.dumps(numpy.to_dict())
    assert type(TransferHyperparameters(typical=np.float32(0.5)).typical) is float


def test_adapt_set_refuses_a_fit_setting(cli: dict[str, Path]) -> None:
    result = CliRunner().invoke(main, ["adapt", str(cli["knowledge"]), "--home", str(cli["new"]), "--set",
                                       "n_concepts=3", "--out", str(cli["new"].parent / "x.spco")])
    assert result.exit_code != 0 and "only the answer's settings" in result.output
