"""Knowledge that travels: spco fit / adapt / where / what / teach / show and their files.

Everything runs on a few small synthetic homes (128 visual features, a handful of sweeps): these
tests check the workflow, the file formats and the handling of bad input, not accuracy (the
accuracy bars are measured on the SIGVerse data, see the README).
"""

from __future__ import annotations

import json
import time
import warnings
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner
from conftest import synthetic_home_folders

from spco import knowledge as kn
from spco.cli.knowledge import adapt, fit, teach, what, where
from spco.cli.show import show
from spco.data.environment import Corpus
from spco.data.synthetic import SyntheticConfig, generate_homes
from spco.errors import ConfigurationError, DataFormatError, ModelFileError
from spco.model.prediction import UnknownNameError


def _invoke(command, args: list[str]):
    result = CliRunner().invoke(command, [str(a) for a in args], catch_exceptions=False)
    return result


@pytest.fixture(scope="module")
def homes(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    """Three experienced synthetic homes and one new home (nothing taught), in the plain format."""
    return synthetic_home_folders(tmp_path_factory.mktemp("knowledge"), 4, seed=3)


@pytest.fixture(scope="module")
def knowledge_file(homes: dict[str, Path]) -> Path:
    """A knowledge of 3 homes and 12 sweeps, which explains the new home's views poorly. About a
    quarter of such fits (4 of 16 seeds; 5 of 16 before every home drew from its own stream) leave
    the untaught new home absorbed by one concept learnt from that home alone; seed 3 is not one of
    them (seed 1 became one when the chain changed), so the tests below see the usual case."""
    out = homes["root"] / "knowledge.spco"
    result = _invoke(fit, ["--data", homes["experienced"], "--iterations", 12, "--seed", 3, "--out", out])
    assert result.exit_code == 0, result.output
    return out


@pytest.fixture(scope="module")
def home_file(homes: dict[str, Path], knowledge_file: Path) -> Path:
    """The new home adapted with 15 sweeps. With this weak knowledge the adapting chain too can leave
    the untaught home absorbed by a concept learnt from it alone (42 of 120 samples in a free
    concept): adapt seeds 0–39 measured, 1 of 40 on the code before and after the free concepts held
    the prior's mean (seed 31 before, seed 0 after: the chain's stream changed); seed 1 is the usual
    case on both."""
    out = homes["root"] / "home.spco"
    result = _invoke(adapt, [knowledge_file, "--home", homes["new"], "--iterations", 15, "--seed", 1,
                             "--out", out])
    assert result.exit_code == 0, result.output
    return out


def _copy(src: Path, dst: Path) -> Path:
    dst.write_bytes(src.read_bytes())
    return dst


# ----------------------------------------------------------------------------------- fit
def test_fit_writes_knowledge_with_provenance(knowledge_file: Path, homes: dict[str, Path]) -> None:
    k = kn.load_knowledge(knowledge_file)
    assert k.model == "spcotransfer+mi"
    assert len(k.provenance["homes"]) == 3
    assert k.provenance["seed"] == 3 and k.provenance["n_iterations"] == 12
    assert k.provenance["summary"]["n_samples"] == 3
    assert k.provenance["spco_version"]
    assert k.provenance["data"] == str(homes["experienced"].resolve())
    assert k.n_features == 128 and k.log_phi_words.shape == (k.n_concepts, k.n_words)
    assert np.allclose(np.exp(k.log_phi_visual).sum(1), 1.0)
    assert "kitchen" in k.vocabulary


def test_fit_refuses_to_overwrite_without_force(knowledge_file: Path, homes: dict[str, Path]) -> None:
    before = knowledge_file.read_bytes()
    result = _invoke(fit, ["--data", homes["experienced"], "--iterations", 2, "--out", knowledge_file])
    assert result.exit_code == 2
    assert "already exists" in result.output and "--force" in result.output
    assert knowledge_file.read_bytes() == before


def test_fit_force_and_home_selection(tmp_path: Path, homes: dict[str, Path]) -> None:
    out = tmp_path / "k.spco"
    out.write_text("old")
    names = sorted(p.name for p in homes["experienced"].iterdir())[:2]
    result = _invoke(fit, ["--data", homes["experienced"], "--homes", ",".join(names), "--iterations", 2,
                           "--model", "spcotransfer", "--out", out, "--force"])
    assert result.exit_code == 0, result.output
    k = kn.load_knowledge(out)
    assert k.provenance["homes"] == names and not k.prune_words and k.word_mask.all()


def test_fit_sets_hyperparameters_and_keeps_them_in_the_knowledge(tmp_path: Path,
                                                                  homes: dict[str, Path]) -> None:
    out = tmp_path / "k.spco"
    result = _invoke(fit, ["--data", homes["experienced"], "--iterations", 2, "--out", out,
                           "--set", "n_concepts=7", "--set", "kappa0=0.001", "--set", "view_counts=none"])
    assert result.exit_code == 0, result.output
    hyper = kn.load_knowledge(out).hyperparameters
    assert (hyper.n_concepts, hyper.kappa0, hyper.view_counts, hyper.n_regions) == (7, 0.001, None, 20)


def test_fit_nu0_weights_the_scaled_prior_and_prior_paper_keeps_the_papers(tmp_path: Path,
                                                                          homes: dict[str, Path]) -> None:
    """``--set nu0`` with ``--prior places`` scales Ψ0 with it (E[Σ] = Ψ0 / (ν0 − 5) stays the places'
    size); ``--prior paper`` keeps the paper's Ψ0; ν0 ≤ 5 has no scaled prior and is refused."""
    runs = {}
    for name, args in (("default", ["--prior", "places"]), ("nu0", ["--prior", "places", "--set", "nu0=40"]),
                       ("paper", ["--prior", "paper"])):
        out = tmp_path / f"{name}.spco"
        result = _invoke(fit, ["--data", homes["experienced"], "--iterations", 2, "--out", out, *args])
        assert result.exit_code == 0, result.output
        runs[name] = kn.load_knowledge(out).hyperparameters
    expected = np.diag(runs["default"].psi0_matrix_m2()) / (runs["default"].nu0 - 5.0)
    np.testing.assert_allclose(np.diag(runs["nu0"].psi0_matrix_m2()) / 35.0, expected)
    assert runs["nu0"].nu0 == 40.0 and runs["default"].nu0 == 20.0
    assert runs["paper"].psi0 == (10.0, 10.0, 0.5, 0.5) and runs["paper"].psi0_in_cm2
    assert runs["default"].psi0 != runs["paper"].psi0
    result = _invoke(fit, ["--data", homes["experienced"], "--iterations", 2, "--out", tmp_path / "low.spco",
                           "--prior", "places", "--set", "nu0=4.5"])
    assert result.exit_code != 0 and "nu0" in result.output and "Traceback" not in result.output
    assert not (tmp_path / "low.spco").exists()


@pytest.mark.parametrize("args, message", [
    (["--homes", "no_such_home"], "no home named"),
    (["--teaching-rate", "101"], "101"),
    (["--set", "n_concepts=2.5"], "n_concepts needs integer"),
    (["--set", "kapa0=0.1"], "no hyperparameter 'kapa0'"),
    (["--set", "kappa0"], "write NAME=VALUE"),
    (["--set", "nu0=2"], "nu0 must exceed"),
    (["--set", "n_regions=none"], "n_regions needs integer"),
])
def test_fit_bad_input(tmp_path: Path, homes: dict[str, Path], args: list[str], message: str) -> None:
    result = _invoke(fit, ["--data", homes["experienced"], "--iterations", 2, "--out", tmp_path / "k.spco",
                           *args])
    assert result.exit_code == 2 and message in result.output
    assert "Traceback" not in result.output and not (tmp_path / "k.spco").exists()


def test_fit_missing_data(tmp_path: Path) -> None:
    result = _invoke(fit, ["--data", tmp_path / "nowhere", "--out", tmp_path / "k.spco"])
    assert result.exit_code == 2 and "no such file or folder" in result.output


# ----------------------------------------------------------------------------------- adapt
def test_adapt_writes_home(home_file: Path, knowledge_file: Path, homes: dict[str, Path]) -> None:
    home = kn.load_home_model(home_file)
    k = kn.load_knowledge(knowledge_file)
    assert home.name == homes["new_name"]
    assert home.provenance["knowledge_checksum"] == k.checksum
    assert home.provenance["adapt"]["n_iterations"] == 15
    assert home.parameters.n_environments == 1
    assert home.n_taught == 0 and home.n_samples == home.state.concepts.size
    # the shared part is the knowledge's (kept fixed), but for the concepts the knowledge does not
    # use: those are learnt from the home
    # (and the concepts a home's own names need, appended when the knowledge has too few: the prior's mean)
    from spco.knowledge.knowledge import MIN_FREE_CONCEPTS

    L = k.n_concepts
    used = np.exp(k.log_g0) >= kn.FREE_CONCEPT_WEIGHT
    assert home.knowledge.n_concepts == max(L, int(used.sum()) + MIN_FREE_CONCEPTS)
    assert (np.exp(home.knowledge.log_g0) < kn.FREE_CONCEPT_WEIGHT).sum() >= MIN_FREE_CONCEPTS
    assert np.array_equal(home.state.log_phi_v[:L][used], k.log_phi_visual[used])
    np.testing.assert_allclose(np.exp(home.state.log_g0[:L]), np.exp(k.log_g0), rtol=1e-9, atol=1e-12)


def test_adapt_warns_when_the_home_is_an_experienced_one(tmp_path: Path, knowledge_file: Path,
                                                          homes: dict[str, Path]) -> None:
    """`spco synth` with the same --seed for the experienced and the new homes writes the same homes:
    adapting to one the knowledge learnt from is said, with what to do, not silently measured."""
    experienced = sorted(homes["experienced"].iterdir())[0]
    result = CliRunner().invoke(adapt, [str(knowledge_file), "--home", str(experienced), "--iterations", "2",
                                        "--out", str(tmp_path / "again.spco")])
    assert result.exit_code == 0, result.output
    assert f"warning: home {experienced.name!r} has the name of a home this knowledge was learnt from" \
        in result.output and "another --seed" in result.output
    result = CliRunner().invoke(adapt, [str(knowledge_file), "--home", str(homes["new"]), "--iterations", "2",
                                        "--out", str(tmp_path / "new.spco")])
    assert result.exit_code == 0 and "learnt from" not in result.output


def test_adapt_joint_refines_shared_part(tmp_path: Path, knowledge_file: Path,
                                         homes: dict[str, Path]) -> None:
    k = kn.load_knowledge(knowledge_file)
    env = next(iter(Corpus([_load(homes["new"])])))
    home = kn.adapt(k, env, n_iterations=3, random_state=0, joint=True)
    assert home.joint and not np.array_equal(home.state.log_phi_v, k.log_phi_visual)
    home.save(tmp_path / "h.spco")
    assert kn.load_home_model(tmp_path / "h.spco").joint


def _load(path: Path):
    from spco.data.loading import load_home

    return load_home(path)


@pytest.mark.parametrize("case", ["missing home", "missing knowledge", "truncated", "tampered", "home file",
                                  "out exists"])
def test_adapt_bad_input(case: str, tmp_path: Path, knowledge_file: Path, home_file: Path,
                         homes: dict[str, Path]) -> None:
    k_path, home_path, out = knowledge_file, homes["new"], tmp_path / "h.spco"
    expected = {"missing home": "no such file or folder", "missing knowledge": "no such knowledge file",
                "truncated": "truncated", "tampered": "checksum mismatch",
                "home file": "not a knowledge file", "out exists": "already exists"}[case]
    if case == "missing home":
        home_path = tmp_path / "absent"
    elif case == "missing knowledge":
        k_path = tmp_path / "absent.spco"
    elif case == "truncated":
        k_path = tmp_path / "cut.spco"
        k_path.write_bytes(knowledge_file.read_bytes()[: knowledge_file.stat().st_size // 2])
    elif case == "tampered":
        k_path = _tamper_array(knowledge_file, tmp_path / "bad.spco", "log_g0")
    elif case == "home file":
        k_path = home_file
    else:
        out.write_text("precious")
    result = _invoke(adapt, [k_path, "--home", home_path, "--iterations", 2, "--out", out])
    assert result.exit_code == 2, result.output
    assert expected in result.output and "Traceback" not in result.output
    if case == "out exists":
        assert out.read_text() == "precious"
    else:
        assert not out.exists()


def _tamper_array(src: Path, dst: Path, name: str) -> Path:
    """Rewrite ``src`` with one array changed but the header (and its checksums) kept."""
    with np.load(src, allow_pickle=False) as archive:
        arrays = {k: archive[k] for k in archive.files}
    arrays[name] = arrays[name] + 1e-3
    with open(dst, "wb") as handle:  # a handle: np.savez would add ".npz" to the name
        np.savez(handle, **arrays)
    return dst


def _rewrite_header(src: Path, dst: Path, change) -> Path:
    with np.load(src, allow_pickle=False) as archive:
        arrays = {k: archive[k] for k in archive.files}
    header = json.loads(arrays.pop("header").tobytes().decode())
    change(header)
    raw = np.frombuffer(json.dumps(header).encode(), dtype=np.uint8)
    with open(dst, "wb") as handle:
        np.savez(handle, header=raw, **arrays)
    return dst


# ----------------------------------------------------------------------------------- files
def test_knowledge_round_trip(tmp_path: Path, knowledge_file: Path) -> None:
    k = kn.load_knowledge(knowledge_file)
    k.save(tmp_path / "again.spco")
    k2 = kn.load_knowledge(tmp_path / "again.spco")
    assert k2.checksum == k.checksum
    for name in ("log_phi_visual", "log_phi_words", "log_g0", "word_mask", "concentration_visual"):
        assert np.array_equal(getattr(k, name), getattr(k2, name), equal_nan=name.startswith("conc"))
    assert k2.vocabulary == k.vocabulary and k2.hyperparameters == k.hyperparameters
    with pytest.raises(ModelFileError, match="already exists"):
        k.save(tmp_path / "again.spco")


def test_home_round_trip_predicts_the_same(tmp_path: Path, home_file: Path) -> None:
    home = kn.load_home_model(home_file)
    home.save(tmp_path / "again.spco")
    again = kn.load_home_model(tmp_path / "again.spco")
    for name, value in home.parameters.arrays().items():
        assert np.array_equal(value, getattr(again.parameters, name)), name
    assert again.sentences == home.sentences and np.array_equal(again.ids, home.ids)
    assert (again.visual != home.visual).nnz == 0
    a = kn.what(home, 0.0, 0.0, 0.5)
    b = kn.what(again, 0.0, 0.0, 0.5)
    assert np.array_equal(a.words, b.words) and np.allclose(a.probabilities, b.probabilities)


def test_files_from_a_newer_version_or_edited_header_are_refused(tmp_path: Path, knowledge_file: Path,
                                                                  home_file: Path) -> None:
    newer = _rewrite_header(knowledge_file, tmp_path / "newer.spco",
                            lambda h: h.update(format_version=kn.FORMAT_VERSION + 1))
    with pytest.raises(ModelFileError, match="newer spco"):
        kn.load_knowledge(newer)
    edited = _rewrite_header(knowledge_file, tmp_path / "edited.spco",
                             lambda h: h.update(vocabulary=list(reversed(h["vocabulary"]))))
    with pytest.raises(ModelFileError, match="checksum mismatch of the header"):
        kn.load_knowledge(edited)
    with pytest.raises(ModelFileError, match="checksum mismatch"):
        kn.load_home_model(_tamper_array(home_file, tmp_path / "h.spco", "positions"))
    with pytest.raises(ModelFileError, match="not a home file"):
        kn.load_home_model(knowledge_file)
    (tmp_path / "text.spco").write_text("hello")
    with pytest.raises(ModelFileError, match="truncated or corrupted"):
        kn.load_home_model(tmp_path / "text.spco")


def test_no_pickle_in_files(knowledge_file: Path, home_file: Path) -> None:
    for path in (knowledge_file, home_file):
        with np.load(path, allow_pickle=False) as archive:
            for name in archive.files:
                assert archive[name].dtype != object


# ----------------------------------------------------------------------------------- where
def test_where_text_and_json(home_file: Path) -> None:
    result = _invoke(where, [home_file, "kitchen", "--n", 4])
    assert result.exit_code == 0, result.output
    assert result.output.startswith("kitchen in home") and len(result.output.strip().splitlines()) == 7
    result = _invoke(where, [home_file, "Kitchen", "--n", 5, "--json"])
    assert result.exit_code == 0, result.output
    data = json.loads(result.output)
    assert data["name"] == "kitchen" and len(data["positions"]) == 5
    for p in data["positions"]:
        assert set(p) == {"x", "y", "theta", "probability"}
        assert -np.pi <= p["theta"] <= np.pi and 0 <= p["probability"] <= 1
    assert abs(sum(p["probability"] for p in data["positions"]) - 1) < 1e-9


def test_where_finds_a_name_however_it_is_written(home_file: Path) -> None:
    answers = []
    for name in ("living room", "Living Room", "living-room", "LIVING–ROOM"):
        result = _invoke(where, [home_file, name, "--n", 3, "--json"])
        assert result.exit_code == 0, result.output
        answers.append(json.loads(result.output))
    assert answers[0]["name"] == "living room"
    assert all(a == answers[0] for a in answers[1:])


def test_where_a_name_nobody_said_says_which_known_name_it_used(home_file: Path, wordnet) -> None:
    # nobody in these homes said "restroom": WordNet finds "toilet" (docs/model.md, "Names never heard")
    result = _invoke(where, [home_file, "restroom", "--n", 3])
    assert result.exit_code == 0, result.output
    assert result.output.startswith("restroom -> toilet (never said in this home;"), result.output
    said = json.loads(_invoke(where, [home_file, "toilet", "--n", 3, "--json"]).output)
    data = json.loads(_invoke(where, [home_file, "Restroom", "--n", 3, "--json"]).output)
    assert (data["asked"], data["name"]) == ("restroom", "toilet") and data["via"] in ("synonym", "gloss")
    assert data["region"] == said["region"] and said["asked"] == "toilet" and said["via"] is None
    home = kn.load_home_model(home_file)
    prior = home.parameters.name_prior  # kept in the knowledge file, extended to the home's words
    assert prior is not None and prior.shape == (len(home.vocabulary),)


def test_where_unknown_name_is_a_clear_answer(home_file: Path) -> None:
    result = _invoke(where, [home_file, "kitchn"])
    assert result.exit_code == 2
    assert "unknown place name 'kitchn'" in result.output and "did you mean 'kitchen'" in result.output
    assert "Traceback" not in result.output
    with pytest.raises(UnknownNameError):
        kn.where(kn.load_home_model(home_file), "garage")


# ----------------------------------------------------------------------------------- what
def test_what_with_and_without_vision(tmp_path: Path, home_file: Path) -> None:
    home = kn.load_home_model(home_file)
    x, y, s, c = home.positions[0]
    theta = float(np.arctan2(s, c))
    result = _invoke(what, [home_file, "--x", x, "--y", y, "--theta", theta, "--json"])
    assert result.exit_code == 0, result.output
    data = json.loads(result.output)
    assert data["vision"] is False and len(data["names"]) == 3
    assert all(0 <= n["probability"] <= 1 for n in data["names"])
    view = tmp_path / "view.csv"
    view.write_text("\n".join(str(int(v)) for v in home.visual[[0]].toarray()[0]))
    result = _invoke(what, [home_file, "--x", x, "--y", y, "--theta", theta, "--visual", view, "--json"])
    assert result.exit_code == 0, result.output
    assert json.loads(result.output)["vision"] is True
    result = _invoke(what, [home_file, "--x", x, "--y", y, "--theta", theta, "--visual", view])
    assert result.exit_code == 0 and "1. " in result.output and "position and view" in result.output


def test_what_bad_visual_file(tmp_path: Path, home_file: Path) -> None:
    view = tmp_path / "short.csv"
    view.write_text("1\n2\n3\n")
    result = _invoke(what, [home_file, "--x", 0, "--y", 0, "--theta", 0, "--visual", view])
    assert result.exit_code == 2 and "has 3 values" in result.output
    view.write_text("0.5\n" * 128)
    result = _invoke(what, [home_file, "--x", 0, "--y", 0, "--theta", 0, "--visual", view])
    assert result.exit_code == 2 and "visual scale" in result.output
    result = _invoke(what, [home_file, "--x", 0, "--y", 0, "--theta", 0, "--visual", view,
                            "--visual-scale", 5])
    assert result.exit_code == 0, result.output


# ----------------------------------------------------------------------------------- teach
def test_teach_a_new_word_in_place(tmp_path: Path, home_file: Path) -> None:
    path = _copy(home_file, tmp_path / "home.spco")
    before = kn.load_home_model(path)
    sample = int(before.ids[7])
    result = _invoke(teach, [path, "--id", sample, "--sentence", "this is Emma's-room"])
    assert result.exit_code == 0, result.output
    assert "New words: emma's room" in result.output
    after = kn.load_home_model(path)
    assert after.vocabulary.words[: len(before.vocabulary)] == before.vocabulary.words
    assert after.vocabulary.words[-1] == "emma's room"
    assert after.sentences[7] == "this is Emma's-room" and after.n_taught == 1
    assert np.array_equal(after.ids, before.ids)
    assert after.provenance["teach_updates"] == 1
    assert after.provenance["knowledge_checksum"] == before.provenance["knowledge_checksum"]
    # the new word can be learnt: its column has prior mass and, where its switch made it a name
    # (the word channels; "emma's room" has P(name) 0.21 here), the taught concept holds it
    theta = np.exp(after.state.log_theta_w[0, :, -1])
    token = after.data.words.indptr[7] + np.flatnonzero(after.data.words.indices[
        after.data.words.indptr[7]:after.data.words.indptr[8]] == len(after.vocabulary) - 1)[0]
    if after.state.switches[token] == 0:
        assert theta[after.state.concepts[7]] > 0.05
    assert np.isfinite(after.state.log_theta_w[0, :, -1]).all()


def test_a_name_taught_once_is_found_then_firmer_and_at_two_places(home_file: Path) -> None:
    """One-shot: a name taught once is usable at once (never pruned), `where` answers the region of
    that sample first; any other region it answers is one where `what` answers the name too (one
    account of which concept a name means: a room whose views the room account gives the taught
    concept is a room of that kind); more teachings there keep it the answer; the same name taught
    at a second place of the home is found at both."""
    home = kn.load_home_model(home_file)
    regions = home.state.regions
    first = 7
    once = kn.teach(home, {int(home.ids[first]): "this is the study-room"}, random_state=0)
    assert "study room" in once.known_names
    pred = kn.where(once, "study-room", n=6, random_state=0)
    region = int(once.state.regions[first])
    assert pred.region == region and pred.learnt
    assert (pred.regions == region).sum() > pred.regions.size / 2
    for other in set(pred.regions.tolist()) - {region}:
        assert "study room" in _what_at_region(once, other)
    p_once = float(pred.region_probabilities[region])
    assert 0.3 < p_once
    same_region = [i for i in np.flatnonzero(once.state.regions == region) if i != first][:2]
    assert same_region, "the sample's region holds other samples"
    more = kn.teach(once, {int(once.ids[i]): "the study-room is here" for i in same_region}, random_state=0)
    assert kn.where(more, "study-room", n=6, random_state=0).region == region  # still the answer
    # a second place, far from the first
    dist = np.linalg.norm(home.positions[:, :2] - home.positions[first, :2], axis=1)
    second = int(np.argmax(dist))
    assert regions[second] != regions[first]
    both = kn.teach(home, {int(home.ids[first]): "this is the study-room",
                           int(home.ids[second]): "this is the study-room"}, random_state=0)
    pred = kn.where(both, "study-room", n=6, random_state=0)
    found = set(pred.regions.tolist())
    assert {int(both.state.regions[first]), int(both.state.regions[second])} <= found


@pytest.mark.xfail(strict=True, reason=(
    "known (branch where2): teaching a name again in its room raises the concept's θ^w in every "
    "room of the concept as much as the room's own names, so an untaught room of the concept gains "
    "as fast as the taught one (the fixture: 0.708 -> 0.686); a room-clustered update of θ^w (a name "
    "said again in one room tells less about the concept) is what it needs (changes/where2.md)"))
def test_more_teachings_of_a_name_in_its_room_make_where_firmer(home_file: Path) -> None:
    """A name taught once, then twice more in the same region: `where` gives that region more probability."""
    home = kn.load_home_model(home_file)
    first = 7
    once = kn.teach(home, {int(home.ids[first]): "this is the study-room"}, random_state=0)
    region = int(once.state.regions[first])
    p_once = float(kn.where(once, "study-room", n=6, random_state=0).region_probabilities[region])
    same_region = [i for i in np.flatnonzero(once.state.regions == region) if i != first][:2]
    more = kn.teach(once, {int(once.ids[i]): "the study-room is here" for i in same_region}, random_state=0)
    assert float(kn.where(more, "study-room", n=6, random_state=0).region_probabilities[region]) > p_once


def test_a_taught_name_stays_in_its_room_even_where_the_knowledge_fits_poorly(home_file: Path) -> None:
    """The fixture's knowledge (3 homes, 12 sweeps) explains the new home's views poorly. With every
    visual count scored as a draw, one teaching of a new name used to make its concept, learnt from
    this home alone, gather the other rooms' views (62 % of the home outside the taught room, when a
    teaching re-ran sweeps of the whole home), and a warning said so. A teaching is a local update
    now (:mod:`spco.model.local_update`): the rest of the home is held, the name stays in its room
    and nothing needs saying — with a view weighed as ``view_counts`` draws (the default) or every
    count a draw; a teaching with a known name adds no concept of the home's own either."""
    import dataclasses

    home = kn.load_home_model(home_file)
    with warnings.catch_warnings():
        warnings.simplefilter("error", kn.OwnNamesSpreadWarning)
        kn.teach(home, {int(home.ids[7]): "this is the study room"}, random_state=0)
    knowledge = home.knowledge
    every_count = dataclasses.replace(knowledge, hyperparameters=dataclasses.replace(
        knowledge.hyperparameters, view_counts=None))
    with warnings.catch_warnings():
        warnings.simplefilter("error", kn.OwnNamesSpreadWarning)
        taught = kn.teach(dataclasses.replace(home, knowledge=every_count),
                          {int(home.ids[7]): "this is the study room"}, random_state=0)
    outside = taught.state.regions != taught.state.regions[7]
    assert (taught.state.concepts[outside] == home.state.concepts[outside]).all()
    known = next(n for n in home.known_names if n in home.knowledge.known_names)
    with warnings.catch_warnings():
        warnings.simplefilter("error", kn.OwnNamesSpreadWarning)
        kn.teach(home, {int(home.ids[7]): f"this is the {known}"}, random_state=0)


def test_a_template_word_is_never_a_name(home_file: Path) -> None:
    """Words said alike everywhere are pruned by the naming rule, in the knowledge and in the home."""
    home = kn.load_home_model(home_file)
    for word in ("this", "is", "the"):
        assert word not in home.known_names
        assert word not in home.knowledge.known_names


def test_teach_a_new_observation(tmp_path: Path, home_file: Path) -> None:
    path = _copy(home_file, tmp_path / "home.spco")
    home = kn.load_home_model(path)
    view = tmp_path / "view.npy"
    np.save(view, home.visual[[3]].toarray()[0])
    out = tmp_path / "taught.spco"
    result = _invoke(teach, [path, "--x", 0.5, "--y", -0.5, "--theta", 1.0, "--visual", view,
                             "--sentence", "the study is here", "--out", out])
    assert result.exit_code == 0, result.output
    new_id = int(home.ids.max()) + 1
    assert f"Added sample {new_id}" in result.output
    taught = kn.load_home_model(out)
    assert taught.n_samples == home.n_samples + 1 and taught.ids[-1] == new_id
    assert "study" in taught.vocabulary and taught.sentences[-1] == "the study is here"
    assert kn.load_home_model(path).n_samples == home.n_samples  # --out leaves HOME as it was


def test_teach_library_keeps_what_was_learnt(home_file: Path) -> None:
    home = kn.load_home_model(home_file)
    start = time.perf_counter()
    taught = kn.teach(home, {int(home.ids[0]): "this is the kitchen"}, random_state=0)
    assert time.perf_counter() - start < 5.0
    assert taught.vocabulary == home.vocabulary  # no new word
    used = np.exp(home.knowledge.log_g0) >= kn.FREE_CONCEPT_WEIGHT  # the knowledge's concepts: fixed
    assert np.array_equal(taught.state.log_phi_v[used], home.state.log_phi_v[used])
    # a few sweeps from the current state: most samples keep their concept
    assert (taught.state.concepts == home.state.concepts).mean() > 0.5
    forgotten = kn.teach(taught, {int(home.ids[0]): ""}, n_sweeps=1, random_state=0)
    assert forgotten.sentences[0] is None
    with pytest.raises(ConfigurationError, match="nothing to teach"):
        kn.teach(home)


@pytest.mark.parametrize("args, message", [
    (["--id", 999999, "--sentence", "this is the kitchen"], "no sample with id 999999"),
    (["--id", 1, "--id", 2, "--sentence", "kitchen"], "one sentence per id"),
    ([], "nothing to teach"),
    (["--x", 0, "--y", 0], "needs --x, --y and --theta"),
    (["--x", 0, "--y", 0, "--theta", 0, "--visual", "absent.csv", "--id", 1], "not both"),
])
def test_teach_bad_input(tmp_path: Path, home_file: Path, args: list, message: str) -> None:
    path = _copy(home_file, tmp_path / "home.spco")
    before = path.read_bytes()
    result = _invoke(teach, [path, *args])
    assert result.exit_code == 2, result.output
    assert message in result.output and "Traceback" not in result.output
    assert path.read_bytes() == before


def test_teach_refuses_existing_out(tmp_path: Path, home_file: Path) -> None:
    out = tmp_path / "mine.spco"
    out.write_text("precious")
    result = _invoke(teach, [home_file, "--id", 0, "--sentence", "this is the bath", "--out", out])
    assert result.exit_code == 2 and "already exists" in result.output
    assert out.read_text() == "precious"


# ----------------------------------------------------------------------------------- show
def test_show_writes_a_map(tmp_path: Path, home_file: Path) -> None:
    out = tmp_path / "map.png"
    result = _invoke(show, [home_file, "--out", out, "--name", "kitchen"])
    assert result.exit_code == 0, result.output
    assert out.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    result = _invoke(show, [home_file, "--out", out])
    assert result.exit_code == 2 and "already exists" in result.output
    image = tmp_path / "plan.png"
    image.write_bytes(out.read_bytes())
    result = _invoke(show, [home_file, "--out", out, "--map", image, "--extent", "-6,6,-5,5", "--force"])
    assert result.exit_code == 0, result.output
    result = _invoke(show, [home_file, "--out", tmp_path / "x.png", "--extent", "1,0,0,1"])
    assert result.exit_code == 2 and "--extent" in result.output
    result = _invoke(show, [home_file, "--out", tmp_path / "x.png", "--name", "garage"])
    assert result.exit_code == 2 and "unknown place name" in result.output


# ----------------------------------------------------------------------------------- library
def test_summary_iterations() -> None:
    assert kn.summary_iterations(200) == list(range(154, 200, 5))
    assert kn.summary_iterations(12) == [9, 10, 11]
    assert kn.summary_iterations(1) == [0]


def test_knowledge_extended_gives_new_words_prior_mass(knowledge_file: Path) -> None:
    k = kn.load_knowledge(knowledge_file)
    grown = k.extended(["this is the sauna", "this is the kitchen"])
    assert grown.vocabulary.words == (*k.vocabulary.words, "sauna")
    assert np.allclose(np.exp(grown.log_phi_words).sum(1), 1.0)
    hyper = k.hyperparameters
    assert np.allclose(np.exp(grown.log_phi_words[:, -1]) * hyper.delta_word, hyper.alpha_word, rtol=0.01)
    assert grown.word_mask[-1] and k.extended(["kitchen"]) is k


def test_adapt_rejects_other_visual_dimension(knowledge_file: Path) -> None:
    k = kn.load_knowledge(knowledge_file)
    other = generate_homes(1, seed=5, config=SyntheticConfig(n_features=64), new_homes=1,
                           specific_rooms=False)[0]
    with pytest.raises(DataFormatError, match="64 dimensions"):
        kn.adapt(k, other, n_iterations=1)


def test_reference_sampler_and_short_chains(homes: dict[str, Path]) -> None:
    from spco.data.loading import load

    k = kn.fit_knowledge(load(homes["experienced"]), model="spcotransfer-ref+mi", n_iterations=4,
                         random_state=0)
    assert k.variant == "reference" and k.provenance["summary"]["n_samples"] == 1
    # one sample has no spread: the concentrations are the defaults δ, γ (knowledge._concentration)
    np.testing.assert_allclose(k.concentration_visual, k.hyperparameters.delta_visual)
    assert k.concentration_g0 == k.hyperparameters.gamma
    env = _load(homes["new"])
    for joint in (False, True):
        home = kn.adapt(k, env, n_iterations=3, random_state=0, joint=joint)
        assert home.weighting == "reference" and home.position_scale == 100
        taught = kn.teach(home, {int(home.ids[0]): "this is the sauna"}, n_sweeps=2, random_state=0)
        assert "sauna" in taught.vocabulary
        means = taught.parameters.region_means[0, :, :2]  # metres, whatever the sampler's units
        assert np.abs(means).max() < 50
        assert kn.what(taught, 0.0, 0.0, 0.0).words.shape == (1, 3)


def _what_at_region(home: kn.HomeModel, region: int, top_k: int = 3) -> list[str]:
    """The ``top_k`` names `what` answers (the position alone) at the centre of ``region``."""
    mean = np.asarray(home.parameters.region_means[0, region], dtype=np.float64)
    theta = float(np.arctan2(mean[2], mean[3]))
    pose = np.array([[mean[0], mean[1], np.sin(theta), np.cos(theta)]])
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return [str(w) for w in kn.name_prediction(home, pose, None, top_k=top_k).words[0]]


def test_synonyms_each_find_the_place_and_the_most_used_comes_first(home_file: Path) -> None:
    """Several names for one place: each is found by `where` where it was said, or where `what`
    answers it too (one account of which concept a name means: this fixture's weak knowledge gives
    another region's views the taught room's concept); `what` puts the name said most first. (Each
    new name gets a concept of its own, so `what` lists the other name near its own samples, not
    everywhere in the room: see the README.)"""
    home = kn.load_home_model(home_file)
    first = 7
    region = home.state.regions[first]
    others = [i for i in np.flatnonzero(home.state.regions == region) if i != first][:3]
    assert len(others) == 3, "the sample's region holds other samples"
    taught = {int(home.ids[i]): "this is the tub-room" for i in (first, *others[:2])}
    taught[int(home.ids[others[2]])] = "this is the shower-room"
    after = kn.teach(home, taught, random_state=0)
    for name, said in (("tub-room", [first, *others[:2]]), ("shower-room", [others[2]])):
        pred = kn.where(after, name, n=4, random_state=0)
        for region in set(pred.regions.tolist()) - set(after.state.regions[said].tolist()):
            assert pred.name in _what_at_region(after, region), (name, region)
    x, y = home.positions[first, :2]
    theta = float(np.arctan2(home.positions[first, 2], home.positions[first, 3]))
    assert kn.what(after, float(x), float(y), theta).words[0][0] == "tub room"


def test_a_word_said_at_many_places_of_a_home_is_no_name(home_file: Path) -> None:
    """Issue 13: a word the home hears at many places ("well", said at each of six rooms) is no name —
    pruned, never `what`'s answer — while a name said once there stays usable and is answered at its
    sample. (The earlier rule kept such a word undecided whenever chance expected less than one
    same-region pair of its uses, e.g. when no two of the home's taught samples share a region.)"""
    home = kn.load_home_model(home_file)
    regions = home.state.regions
    firsts = [int(np.flatnonzero(regions == m)[0]) for m in np.unique(regions)][:6]
    assert len(firsts) == 6, "the home has six regions"
    places = ("kitchen", "bath", "toilet", "entrance", "bedroom", "study room")
    said = {int(home.ids[k]): f"well this is the {place}" for k, place in zip(firsts, places, strict=True)}
    taught = kn.teach(home, said, random_state=0)
    assert "well" in taught.vocabulary.words and "well" not in taught.known_names
    assert "study room" in taught.known_names
    answers = []
    for k in firsts:
        x, y = home.positions[k, :2]
        theta = float(np.arctan2(home.positions[k, 2], home.positions[k, 3]))
        answers.append(kn.what(taught, float(x), float(y), theta).best[0])
    assert "well" not in answers and answers[-1] == "study room", answers


def test_appended_free_concepts_hold_the_priors_mean_not_a_draw(knowledge_file: Path) -> None:
    """A knowledge holds each concept's posterior mean; a concept no experienced home used has its
    prior as posterior, so an appended one is the prior's mean — uniform φ^v, φ^w (and ψ), the same on
    every call: one draw of Dir(α^w) puts nearly all its mass on one word at random and drew
    taught samples away from their place (synthetic teaching effective 60 % instead of 95 %)."""
    from spco.knowledge.knowledge import MIN_FREE_CONCEPTS

    k = kn.load_knowledge(knowledge_file)
    free = kn.FREE_CONCEPT_WEIGHT
    a = k.with_free_concepts(n_free=MIN_FREE_CONCEPTS + k.n_concepts)
    b = k.with_free_concepts(n_free=MIN_FREE_CONCEPTS + k.n_concepts)
    L = k.n_concepts
    added = a.n_concepts - L
    assert added >= MIN_FREE_CONCEPTS and (np.exp(a.log_g0[L:]) < free).all()
    for x, y in ((a.log_phi_visual, b.log_phi_visual), (a.log_phi_words, b.log_phi_words)):
        assert np.array_equal(x, y)
        np.testing.assert_allclose(np.exp(x[L:]), 1.0 / x.shape[1], rtol=1e-12)
    assert np.array_equal(a.log_phi_visual[:L], k.log_phi_visual)
    assert np.array_equal(a.log_phi_words[:L], k.log_phi_words)
    if a.channels is not None:
        place = a.channels.channels.log_place
        np.testing.assert_allclose(np.exp(place[L:]), 1.0 / place.shape[1], rtol=1e-12)
