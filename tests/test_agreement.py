"""What a person reads agrees: `where`'s "learnt" warning with `what` at its poses, `ask`'s numbers
with `what` and with its confidence, the view-fit summaries with their numbers (issue 30)."""

from __future__ import annotations

import json
import shutil
import warnings
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner
from serve_helpers import build_home

from spco import knowledge as kn
from spco.cli.ask import confidence_note
from spco.cli.main import main
from spco.knowledge.queries import answer_inputs, answered_at_region
from spco.model import position_prediction


@pytest.fixture(scope="module")
def built(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return build_home(tmp_path_factory.mktemp("agreement"))


def _answers_quietly(home: kn.HomeModel, name: str):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return kn.where(home, name, n=5, random_state=0)


def test_where_is_learnt_exactly_when_what_agrees_or_the_home_holds_it(built: Path) -> None:
    home = kn.load_home_model(built)
    assert home.known_names
    for name in home.known_names:
        answer = _answers_quietly(home, name)
        there = answered_at_region(home, answer.region)
        if answer.learnt:
            assert answer.called is None
            assert answer.support >= 0.5 or there == answer.name, name
        else:  # not learnt: `what` does not answer the name where the poses are, and says what it does
            assert there != answer.name and answer.called == there, name


def _unoccupied(home: kn.HomeModel, name: str) -> kn.HomeModel:
    """The home with the concepts that carry most of ``name`` — G_l p(name | l) as ``where``'s support
    reads it, as a name or a word of the place (ψ) — holding none of its samples, most first, until
    those that still hold samples carry under half of it (as a transferred name whose place the home
    keeps under another concept: the tutorial's kitchen, called dining). The concept of the name's
    largest θ^w alone is not enough since a knowledge's ψ is the posterior mean: a name said as a word
    of a place keeps its support through the occupied concepts' ψ."""
    params, _ = answer_inputs(home)
    forms = position_prediction.query_forms(params, home.vocabulary, name, home.parameters.word_mask)
    weights = position_prediction._name_concept_weights(params, 0, forms)
    counts = np.array(home.parameters.concept_counts, dtype=np.float64)
    for concept in np.argsort(-weights, kind="stable"):
        if weights[counts[0] >= 1].sum() < 0.5 * weights.sum():
            break
        counts[0, concept] = 0.0
    posterior = replace(home.posterior, concept_counts=counts)
    moved = replace(home, posterior=posterior)
    moved.__dict__.pop("parameters", None)
    return moved


def test_a_name_not_learnt_says_what_the_home_calls_the_place_of_its_poses(
        built: Path, tmp_path: Path) -> None:
    home = kn.load_home_model(built)
    checked = 0
    for name in home.known_names:
        moved = _unoccupied(home, name)
        answer = _answers_quietly(moved, name)
        if answer.learnt:  # other concepts still carry it, or `what` answers it there: where and what agree
            assert answer.support >= 0.5 or answered_at_region(moved, answer.region) == answer.name
            continue
        checked += 1
        assert answer.support < 0.5
        assert answer.called == answered_at_region(moved, answer.region) != answer.name
        # and `spco where` says it, in the warning and in --json
        path = tmp_path / f"{checked}.spco"
        moved.save(path)
        runner = CliRunner()
        result = runner.invoke(main, ["where", str(path), name, "-n", "3"])
        assert result.exit_code == 0, result.output
        assert "no such place learnt" in result.output
        assert f"`what` calls {answer.called!r} here" in result.output
        shown = json.loads(runner.invoke(main, ["where", str(path), name, "--json"]).output)
        assert shown["learnt"] is False and shown["called"] == answer.called
    assert checked, "no name of the home could be made a name not learnt"


def test_asks_numbers_are_whats_and_its_confidence_is_explained(built: Path, tmp_path: Path) -> None:
    home = kn.load_home_model(built)
    questions = kn.ask(home, n=5)
    assert questions
    for q in questions:
        row = int(np.flatnonzero(home.ids == q.id)[0])
        said = kn.what(home, q.x, q.y, q.theta, visual=home.visual[[row]].toarray()[0], top_k=3)
        for (name, p), word, prob in zip(q.names, said.words[0], said.probabilities[0], strict=False):
            assert name == word and p == pytest.approx(prob, abs=1e-9)
        # no number in the reason contradicts the answer line: a name it quotes has what's p
        for name, p in q.names:
            if f"{name} " in q.reason and "the model says" in q.reason:
                assert f"{name} {p:.2f}" in q.reason
        note = confidence_note(q.to_dict())
        if q.own_name > 0 and q.names and abs(q.names[0][1] * (1 - q.own_name) - q.confidence) < 5e-3:
            assert f"{q.names[0][1]:.2f} × {1 - q.own_name:.2f}" in note
    path = tmp_path / "home.spco"
    shutil.copyfile(built, path)
    result = CliRunner().invoke(main, ["ask", str(path), "-n", "3"])
    assert result.exit_code == 0, result.output
    for q in questions[:3]:
        assert f"confidence {q.confidence:.2f}" in result.output


def test_confidence_note_says_how_the_number_is_made() -> None:
    q = {"names": [{"name": "bedroom", "p": 0.78}], "own_name": 0.5, "confidence": 0.39}
    assert confidence_note(q) == " = bedroom 0.78 × 0.50, the chance that the room has no name of its own"
    assert confidence_note({**q, "own_name": 0.0, "confidence": 0.78}) == ""
    assert "taught in this room" in confidence_note({**q, "confidence": 0.6})


def test_view_fit_ranges_never_print_one_number_twice() -> None:
    assert kn.fit_range_text([2.5512, 2.5488]) == "2.55"
    assert kn.fit_range_text([0.42, 0.65]) == "0.42…0.65"
    assert kn.fit_range_text([]) == "unknown"
    text = kn.view_fit_warning("h", {"value": 0.1, "experienced_range": [2.55, 2.55], "warn_below": 1.0})
    assert "against 2.55 in its experienced homes" in text and "2.55…2.55" not in text


def test_a_teachings_positions_are_scored_by_the_regions_posterior_predictive(built: Path) -> None:
    """log p(x | a region's samples) = log m(samples ∪ {x}) − log m(samples), m the NIW marginal; and
    that is the Student t of the NIW posterior (scipy's multivariate_t, an independent form)."""
    from scipy.stats import multivariate_t

    from spco.model import parameter_steps
    from spco.model.kernels.niw import niw_posterior
    from spco.model.local_update import _log_marginal, _RegionStatistics
    from spco.model.state import SamplerSettings

    def _log_marginal_positions(points: np.ndarray, prior) -> float:  # log p(points) of one region
        return float(_log_marginal(np.array([float(points.shape[0])]), points.sum(axis=0)[None],
                                   (points.T @ points)[None], prior)[0])

    home = kn.load_home_model(built)
    shared = home.knowledge.shared_part()
    settings = SamplerSettings.create(shared.variant, shared.prune_words, learn_shared=False,
                                      view_counts=shared.hyperparameters.view_counts)
    prior = parameter_steps.niw_prior(home.data, shared.hyperparameters, settings)
    state, x = home.state, home.data.positions
    regions = np.unique(state.regions)
    counted = np.ones(home.n_samples, dtype=bool)
    counted[0] = False
    stats = _RegionStatistics(home.data, state, counted, regions, prior)
    got = stats.log_predictive(x[0])
    for k, region in enumerate(regions):
        members = x[counted & (state.regions == region)]
        want = (_log_marginal_positions(np.vstack([members, x[:1]]), prior)
                - (_log_marginal_positions(members, prior) if len(members) else 0.0))
        assert got[k] == pytest.approx(want, rel=1e-8, abs=1e-8)
        mu_n, kappa_n, psi_n, nu_n = niw_posterior(
            np.array([float(len(members))]), members.sum(axis=0)[None], (members.T @ members)[None],
            prior.mu0[0], prior.kappa0, prior.psi0, prior.nu0)
        dof = float(nu_n[0]) - x.shape[1] + 1.0
        student = multivariate_t(mu_n[0], psi_n[0] * (kappa_n[0] + 1.0) / (kappa_n[0] * dof), df=dof)
        assert got[k] == pytest.approx(student.logpdf(x[0]), rel=1e-8, abs=1e-8)
    stats.add(0, x[0])  # counted in the first region: its predictive is that of the region with it
    members = np.vstack([x[counted & (state.regions == regions[0])], x[:1]])
    with_x1 = _log_marginal_positions(np.vstack([members, x[1:2]]), prior)
    assert stats.log_predictive(x[1])[0] == pytest.approx(with_x1 - _log_marginal_positions(members, prior),
                                                           rel=1e-8)
