"""A first hour that works: knowledge that says when it does not fit a home, outputs that explain
themselves, and the small frictions a new user meets (issue 16 points 7–9, issue 14 point 5).

Small synthetic homes (128 visual features, a few sweeps): these tests check behaviour, not accuracy.
"""

from __future__ import annotations

import json
import re
import warnings
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
import scipy.sparse as sp
from click.testing import CliRunner
from conftest import fit_and_adapt, synthetic_home_folders

from spco import knowledge as kn
from spco.cli import main
from spco.data.environment import Environment
from spco.data.plain import write_corpus
from spco.data.synthetic import SyntheticConfig, generate_homes
from spco.errors import ConfigurationError, DataFormatError
from spco.knowledge.home import _copy_state
from spco.model.prediction import predict_names

CONFIG = SyntheticConfig(n_features=128)


def _run(args: list[object]):
    return CliRunner().invoke(main, [str(a) for a in args], catch_exceptions=False)


@pytest.fixture(scope="module")
def files(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    """A knowledge file from four synthetic homes, a new home of the same generator and its home file."""
    folders = synthetic_home_folders(tmp_path_factory.mktemp("first_hour"), 5, seed=3)
    knowledge, home, output = fit_and_adapt(folders, ["--iterations", 20, "--seed", 1], ["--iterations", 15])
    return {"root": folders["root"], "knowledge": knowledge, "home": home, "new": folders["new"],
            "adapt_output": output}  # type: ignore[dict-item]


def _hand_built_home(n_features: int, seed: int = 1) -> Environment:
    """Four rooms whose views come from another distribution than the synthetic generator's."""
    rng = np.random.default_rng(seed)
    centres = {"kitchen": (2.0, 2.0), "bedroom": (-2.0, 2.0), "living-room": (-2.0, -2.0),
               "bath": (2.0, -2.0)}
    positions, visual, sentences = [], [], []
    for name, (cx, cy) in centres.items():
        prototype = rng.dirichlet(np.full(n_features, 0.05))
        for k in range(15):
            theta = rng.uniform(-np.pi, np.pi)
            positions.append([cx + rng.normal(0, 0.5), cy + rng.normal(0, 0.5), np.sin(theta), np.cos(theta)])
            visual.append(rng.multinomial(200, prototype))
            sentences.append(f"this is the {name}" if k < 5 else None)
    n = len(sentences)
    return Environment(name="hand-built", ids=np.arange(n), positions=np.array(positions),
                       visual=sp.csr_array(np.array(visual)), sentences=tuple(sentences),
                       is_test=np.zeros(n, dtype=bool), extent=(-4.0, 4.0, -4.0, 4.0))


# ------------------------------------------------------------------ point 7: knowledge that does not fit


def test_knowledge_records_the_fit_of_its_experienced_homes(files: dict[str, Path]) -> None:
    k = kn.load_knowledge(files["knowledge"])
    view = k.provenance["view_fit"]
    assert set(view["homes"]) == set(k.provenance["homes"])
    values = list(view["homes"].values())
    assert all(v > 0 for v in values)  # better than a uniform guess in every experienced home
    assert view["warn_below"] == pytest.approx(kn.VIEW_FIT_WARN_FRACTION * min(values), abs=1e-4)


def test_hand_built_home_from_another_distribution_is_warned_about(files: dict[str, Path]) -> None:
    k = kn.load_knowledge(files["knowledge"])
    with pytest.warns(kn.KnowledgeMismatchWarning, match="does not fit home 'hand-built'"):
        home = kn.adapt(k, _hand_built_home(k.n_features), n_iterations=2, random_state=0)
    assert home.provenance["view_fit"]["fits"] is False
    assert home.provenance["view_fit"]["value"] < k.provenance["view_fit"]["warn_below"]


def test_new_home_from_the_same_generator_is_not_warned_about(files: dict[str, Path]) -> None:
    k = kn.load_knowledge(files["knowledge"])
    new = generate_homes(2, seed=11, config=CONFIG, new_homes=1, specific_rooms=False)[1]
    with warnings.catch_warnings():
        warnings.simplefilter("error", kn.KnowledgeMismatchWarning)
        home = kn.adapt(k, new, n_iterations=2, random_state=0)
    assert home.provenance["view_fit"]["fits"] is True
    assert "it fits" in files["adapt_output"] and "warning" not in files["adapt_output"]


def test_another_visual_world_is_warned_about(files: dict[str, Path]) -> None:
    """Homes of the same generator but another visual world (other place appearances) do not fit."""
    k = kn.load_knowledge(files["knowledge"])
    other = generate_homes(2, seed=11, config=SyntheticConfig(n_features=128, world_seed=99), new_homes=1,
                           specific_rooms=False)[1]
    with pytest.warns(kn.KnowledgeMismatchWarning):
        kn.adapt(k, other, n_iterations=2, random_state=0)


def test_cli_adapt_and_inspect_warn(files: dict[str, Path]) -> None:
    root = files["root"]
    k = kn.load_knowledge(files["knowledge"])
    write_corpus([_hand_built_home(k.n_features)], root / "hand")
    out = root / "hand.spco"
    result = _run(["adapt", files["knowledge"], "--home", root / "hand" / "hand-built", "--iterations", 2,
                   "--out", out])
    assert result.exit_code == 0
    assert "warning: the knowledge does not fit home 'hand-built'" in result.output
    assert "DOES NOT FIT" in result.output
    inspected = _run(["inspect", out])
    assert inspected.exit_code == 0
    assert "warning: the knowledge does not fit" in inspected.output
    asked = _run(["what", out, "--x", 2, "--y", 2, "--theta", 0])
    assert asked.exit_code == 0 and "warning: the knowledge does not fit" in asked.output


def test_view_fit_measure() -> None:
    """Views drawn from the mixture score above 0; views from elsewhere below; empty views are skipped."""
    rng = np.random.default_rng(0)
    phi = rng.dirichlet(np.full(50, 0.1), size=3)
    g0 = np.array([0.5, 0.3, 0.2])
    own = np.stack([rng.multinomial(300, phi[rng.choice(3, p=g0)]) for _ in range(40)])
    other = rng.multinomial(300, rng.dirichlet(np.full(50, 0.1)), size=40)
    fit_own = kn.view_fit(np.log(phi), np.log(g0), own)
    fit_other = kn.view_fit(np.log(phi), np.log(g0), other)
    assert fit_own is not None and fit_other is not None
    assert fit_own > 0.5 > fit_other
    assert kn.view_fit(np.log(phi), np.log(g0), np.zeros((3, 50))) is None
    uniform = np.full((1, 50), 1 / 50)
    assert kn.view_fit(np.log(uniform), np.zeros(1), own) == pytest.approx(0.0, abs=1e-12)


def test_dimension_mismatch_says_what_is_needed(files: dict[str, Path]) -> None:
    k = kn.load_knowledge(files["knowledge"])
    other = generate_homes(1, seed=5, config=SyntheticConfig(n_features=64), new_homes=1,
                           specific_rooms=False)[0]
    with pytest.raises(DataFormatError, match=r"64 dimensions but the knowledge needs 128.*same feature ext"):
        kn.adapt(k, other, n_iterations=1)


# ------------------------------------------------------------------ point 8: outputs explain themselves


def test_what_ranks_by_the_score_it_prints(files: dict[str, Path]) -> None:
    result = _run(["what", files["home"], "--x", 0.5, "--y", 0.5, "--theta", 0, "--top", 5])
    assert result.exit_code == 0, result.output
    assert "ranked by score" in result.output
    assert re.search(r"^score: p\(name \| pose, view\)", result.output, flags=re.M)
    rows = re.findall(r"^\s+\d\. (\S+)\s+([0-9.]+)\s+([0-9.]+)$", result.output, flags=re.M)
    assert len(rows) >= 2
    scores = [float(r[1]) for r in rows]
    assert scores == sorted(scores, reverse=True)
    data = json.loads(_run(["what", files["home"], "--x", 0.5, "--y", 0.5, "--theta", 0, "--json",
                            "--top", 5]).output)
    shares = [n["score_share"] for n in data["names"]]
    assert shares == sorted(shares, reverse=True) and "ranked_by" in data


def test_where_explains_its_region_probability(files: dict[str, Path]) -> None:
    home = kn.load_home_model(files["home"])
    result = _run(["where", files["home"], home.known_names[0], "-n", 3])
    assert result.exit_code == 0, result.output
    assert f"p(region | {home.known_names[0]})" in result.output and "share of" in result.output
    assert len(re.findall(r"^\s+-?\d+\.\d{3}\s", result.output, flags=re.M)) == 3


@pytest.mark.parametrize("which", ["knowledge", "home"])
def test_inspect_reads_model_files(files: dict[str, Path], which: str) -> None:
    result = _run(["inspect", files[which]])
    assert result.exit_code == 0, result.output
    k = kn.load_knowledge(files["knowledge"])
    assert "128 features per view" in result.output and "extractor" in result.output
    assert ", ".join(k.known_names) in result.output
    assert k.provenance["homes"][0] in result.output and "provenance" in result.output
    data = json.loads(_run(["inspect", files[which], "--json"]).output)
    assert data["kind"] == which and data["visual_dimension"] == 128
    assert data["kept_names"] == k.known_names and data["homes"] == k.provenance["homes"]


# ------------------------------------------------------------------ point 9 and issue 14 point 5


def test_theta_in_degrees_is_refused_with_a_hint(files: dict[str, Path]) -> None:
    result = _run(["what", files["home"], "--x", 0, "--y", 0, "--theta", 90])
    assert result.exit_code == 2
    assert "radians" in result.output and "1.5708" in result.output


@pytest.mark.parametrize("x", [1e308, -1e308, 1e6])
def test_pose_far_outside_the_map_is_refused_without_nan(files: dict[str, Path], x: float) -> None:
    result = _run(["what", files["home"], "--x", x, "--y", 1, "--theta", 0])
    assert result.exit_code == 2
    assert result.output.startswith("error: ") and "outside the map" in result.output
    assert "nan" not in result.output.lower() and "RuntimeWarning" not in result.output


def test_pose_just_off_the_map_is_answered_with_a_warning(files: dict[str, Path]) -> None:
    home = kn.load_home_model(files["home"])
    _, x1, y0, y1 = kn.map_bounds(home)
    result = _run(["what", files["home"], "--x", x1 + 0.5, "--y", (y0 + y1) / 2, "--theta", 0])
    assert result.exit_code == 0
    assert "warning: the pose" in result.output and "1." in result.output


def test_library_prediction_far_away_is_an_error_not_nan(files: dict[str, Path]) -> None:
    home = kn.load_home_model(files["home"])
    with pytest.raises(ConfigurationError, match="undefined"):
        predict_names(home.parameters, 0, home.vocabulary, np.array([[1e308, 1.0, 0.0, 1.0]]), None,
                      use_vision=False)
    with pytest.raises(ConfigurationError, match="outside the map"):
        kn.what(home, 1e308, 1.0, 0.0)


def test_unquoted_comma_in_a_sentence_gets_a_hint(tmp_path: Path) -> None:
    home = tmp_path / "h"
    home.mkdir()
    (home / "samples.csv").write_text("id,x,y,theta,sentence\n0,1,2,0,well, this is emma's room\n")
    np.save(home / "visual.npy", np.ones((1, 4)))
    result = _run(["inspect", home])
    assert result.exit_code == 2
    assert "must be quoted" in result.output and "\"well, this is emma's room\"" in result.output


def test_a_word_taught_once_says_what_to_do(files: dict[str, Path], tmp_path: Path) -> None:
    taught = tmp_path / "taught.spco"
    home = kn.load_home_model(files["home"])
    result = _run(["teach", files["home"], "--id", int(home.ids[0]), "--sentence", "this is the zorblax",
                   "--out", taught])
    assert result.exit_code == 0, result.output
    updated = kn.load_home_model(taught)
    index = updated.vocabulary.index("zorblax")
    if kn.unused_word_hint(updated, "zorblax") is None:  # kept in this home: prune it as a home might
        assert "note:" not in result.output
        state = _copy_state(updated.state)
        state.word_mask[index] = False
        posterior = updated.posterior
        if posterior is not None:  # predictions read the posterior average's mask
            mask = np.array(posterior.word_mask, dtype=bool)
            mask[index] = False
            posterior = replace(posterior, word_mask=mask)
        updated = replace(updated, state=state, posterior=posterior)
        updated.save(taught, overwrite=True)
    else:
        assert "note: the word 'zorblax' is not used as a place name yet" in result.output
        assert f"spco teach {taught} --id" in result.output
    hint = kn.unused_word_hint(updated, "zorblax")
    assert hint is not None and "taught at 1 sample(s)" in hint and "--id" in hint
    assert kn.unused_word_hint(updated, "this") is not None and "experienced homes" in kn.unused_word_hint(
        updated, "this")
    # "this": taught here, a background word of the knowledge's word channels (said alike everywhere):
    # never a name, and the hint says to teach the place by its name
    this = updated.vocabulary.index("this")
    assert updated.knowledge.channels is not None and not updated.name_mask[this]
    assert "background words" in kn.unused_word_hint(updated, "this")
    asked = _run(["where", taught, "zorblax"])
    drawn = _run(["show", taught, "--out", tmp_path / "map.png", "--name", "zorblax"])
    if updated.said_words[index]:  # no name, but a word of the place (the channels): `where` finds it
        assert asked.exit_code == 0 and drawn.exit_code == 0
    else:
        assert asked.exit_code == 2 and "teach it at a few more samples" in asked.output
        assert drawn.exit_code == 0 and "warning: no positions drawn for 'zorblax'" in drawn.output
    assert (tmp_path / "map.png").is_file()
    assert _run(["show", taught, "--out", tmp_path / "map2.png", "--name", "garage"]).exit_code == 2


def test_synth_with_another_seed_does_not_reuse_names(tmp_path: Path) -> None:
    assert _run(["synth", tmp_path / "a", "--homes", 3, "--seed", 0]).exit_code == 0
    assert _run(["synth", tmp_path / "b", "--homes", 3, "--seed", 7]).exit_code == 0
    first = {p.name for p in (tmp_path / "a").iterdir()}
    second = {p.name for p in (tmp_path / "b").iterdir()}
    assert len(first) == 3 and len(second) == 3 and not first & second
    assert all(name.startswith("synthetic_s7_") for name in second)


def test_demo_knows_whether_its_kernels_are_compiled() -> None:
    from spco.model.precompile import kernels_compiled
    from spco.synthetic_transfer import load_kernels

    load_kernels()  # what the demo does first: the kernels are in memory now
    assert kernels_compiled() is True


# ------------------------------------------------------------------ point 10: room outlines in spco show


def test_show_draws_the_rooms_of_the_home(files: dict[str, Path], tmp_path: Path) -> None:
    from spco.cli.show import _room_outlines

    home = kn.load_home_model(files["home"])
    rooms = _room_outlines(home, None)  # the regions.json of the folder the home was adapted from
    assert rooms is not None and set(rooms.places) >= set(home.known_names) - {"emma's-room"}
    every = tmp_path / "regions.json"
    every.write_text(json.dumps({"homes": {home.name: {"kitchen": [[0, 1, 0, 1]]}}}))
    assert set(_room_outlines(home, every).places) == {"kitchen"}
    result = _run(["show", files["home"], "--out", tmp_path / "map.png", "--regions", every])
    assert result.exit_code == 0 and (tmp_path / "map.png").stat().st_size > 1000
    other = tmp_path / "other.json"
    other.write_text(json.dumps({"homes": {"elsewhere": {"kitchen": [[0, 1, 0, 1]]}}}))
    result = _run(["show", files["home"], "--out", tmp_path / "map2.png", "--regions", other])
    assert result.exit_code == 2 and f"no regions for home {home.name!r}" in result.output


def test_a_name_of_two_words_taught_once_is_found_and_answered(files: dict[str, Path],
                                                               tmp_path: Path) -> None:
    """Issue 13's check from the command line: one `teach` of "this is the study room", then
    `where "study room"` answers with poses in that sample's room, and `what` at that sample's pose
    puts "study room" first (never "room" alone)."""
    home = kn.load_home_model(files["home"])
    regions = json.loads((files["new"] / "regions.json").read_text())
    labels = dict(line.split(",")[:2] for line in (files["new"] / "labels.csv").read_text().splitlines()[1:])
    k = int(np.flatnonzero(np.array([s is None for s in home.sentences]))[0])
    sample = int(home.ids[k])
    room = labels[str(sample)]
    taught = tmp_path / "taught.spco"
    result = _run(["teach", files["home"], "--id", sample, "--sentence", "this is the study room",
                   "--out", taught])
    assert result.exit_code == 0, result.output
    where = _run(["where", taught, "study room", "-n", 5, "--json"])
    assert where.exit_code == 0, where.output
    answer = json.loads(where.output)
    assert answer["name"] == "study room"
    inside = [any(x0 <= p["x"] <= x1 and y0 <= p["y"] <= y1 for x0, x1, y0, y1 in regions[room])
              for p in answer["positions"]]
    assert sum(inside) >= 4, (room, answer["positions"])
    x, y = home.positions[k, :2]
    theta = float(np.arctan2(home.positions[k, 2], home.positions[k, 3]))
    what = _run(["what", taught, "--x", float(x), "--y", float(y), "--theta", theta, "--json"])
    assert what.exit_code == 0, what.output
    names = [n["name"] for n in json.loads(what.output)["names"]]
    assert names[0] == "study room" and "room" not in names


def test_demo_leaves_the_files_a_robot_serves(tmp_path: Path) -> None:
    """The README's first command ends with a home file that `spco where` and `spco serve` take, and
    says how: the path from the demo's output to a served home."""
    out = tmp_path / "demo"
    result = CliRunner().invoke(main, ["demo", "--homes", "4", "--iterations", "20", "--out", str(out)])
    assert result.exit_code == 0, result.output
    assert f"spco serve {out / 'home.spco'}" in result.output
    home = kn.load_home_model(out / "home.spco")
    experienced = kn.load_knowledge(out / "knowledge.spco").provenance["homes"]
    assert len(experienced) == 4 and home.name not in experienced  # learnt without the new home
    answer = kn.where(home, home.known_names[0], 3, random_state=0)
    assert answer.samples.shape == (3, 3) and np.isfinite(answer.samples[:, :2]).all()
