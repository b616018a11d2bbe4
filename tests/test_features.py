"""Images to features: the extractors, views as images in the plain format and the commands.

The homes are small synthetic ones whose views are drawn as little images (a colour and stripes
per place); the ONNX extractor runs a tiny network that the test builds with onnx.helper.
"""

from __future__ import annotations

import json
from pathlib import Path

import cv2
import numpy as np
import pytest
import scipy.sparse as sp
from click.testing import CliRunner

from spco import knowledge as kn
from spco.cli import inspect as inspect_command
from spco.cli.features import features
from spco.cli.knowledge import adapt, fit, teach, what
from spco.data.loading import load_home
from spco.data.plain import write_corpus
from spco.data.synthetic import SyntheticConfig, generate_homes
from spco.errors import ConfigurationError, DataFormatError
from spco.features import DEFAULT_EXTRACTOR, ExtractorSpec, build_extractor, read_image
from spco.knowledge.files import _content_checksum

PLACE_COLOURS = {}


def _view(label: str | None, rng: np.random.Generator, size: tuple[int, int] = (48, 64)) -> np.ndarray:
    """A BGR image for a place: its colour, stripes at its angle, noise."""
    key = label or "?"
    if key not in PLACE_COLOURS:
        k = len(PLACE_COLOURS)
        PLACE_COLOURS[key] = (np.array([(37 * k) % 256, (91 * k + 60) % 256, (151 * k + 120) % 256]), k)
    colour, k = PLACE_COLOURS[key]
    h, w = size
    yy, xx = np.mgrid[0:h, 0:w]
    stripes = (np.sin((xx * np.cos(k) + yy * np.sin(k)) / 3.0) > 0)[..., None] * 60
    image = colour[None, None, :] + stripes + rng.normal(0, 12, (h, w, 3))
    return np.clip(image, 0, 255).astype(np.uint8)


def _image_home(env, folder: Path, rng: np.random.Generator) -> None:
    """Replace a written plain home's visual.npz by images/<id>.png (some .jpg)."""
    (folder / "visual.npz").unlink()
    (folder / "images").mkdir()
    labels = env.ground_truth.labels if env.ground_truth is not None else [None] * env.n_samples
    for k, (sample, label) in enumerate(zip(env.ids.tolist(), labels, strict=True)):
        suffix = ".jpg" if k % 3 == 0 else ".png"
        assert cv2.imwrite(str(folder / "images" / f"{sample}{suffix}"), _view(label, rng))


@pytest.fixture(scope="module")
def image_homes(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    root = tmp_path_factory.mktemp("image_homes")
    corpus = generate_homes(3, seed=5, config=SyntheticConfig(n_features=16, n_train=6, n_test=2),
                            new_homes=1, specific_rooms=False)
    rng = np.random.default_rng(0)
    write_corpus(list(corpus)[:2], root / "experienced")
    write_corpus(list(corpus)[2:], root / "new")
    for env in list(corpus)[:2]:
        _image_home(env, root / "experienced" / env.name, rng)
    new = corpus[2]
    _image_home(new, root / "new" / new.name, rng)
    # a count-vector home and knowledge to check that each kind refuses the other
    write_corpus(list(corpus)[:2], root / "counts")
    return {"root": root, "experienced": root / "experienced", "new": root / "new" / new.name,
            "counts": root / "counts"}


def _invoke(command, args):
    return CliRunner().invoke(command, [str(a) for a in args], catch_exceptions=False)


# ----------------------------------------------------------------------------- extractors
@pytest.mark.parametrize("name", [DEFAULT_EXTRACTOR, "bovw-orb"])
def test_extractor_counts_are_fixed_length_non_negative_deterministic(name: str, tmp_path: Path) -> None:
    rng = np.random.default_rng(1)
    images = [_view(p, rng, (120, 160)) for p in ("a", "b", "c", "a", "b", "c")]
    extractor = build_extractor(ExtractorSpec(name, settings={"words": 8} if name == "bovw-orb" else {}))
    if extractor.needs_fit:
        with pytest.raises(ConfigurationError, match="codebook"):
            extractor.extract(images[0])
        extractor = extractor.fitted(images, random_state=0)
        again = build_extractor(ExtractorSpec(name, settings={"words": 8})).fitted(images, random_state=0)
        assert again.checksum == extractor.checksum  # same seed, same codebook
    grey = cv2.cvtColor(images[0], cv2.COLOR_BGR2GRAY)
    odd = cv2.resize(images[1], (333, 97))
    cv2.imwrite(str(tmp_path / "v.png"), images[2])
    cv2.imwrite(str(tmp_path / "v.jpg"), images[2])
    cv2.imwrite(str(tmp_path / "g.png"), grey)
    inputs = [images[0], grey, odd, tmp_path / "v.png", tmp_path / "v.jpg", str(tmp_path / "g.png"),
              images[0][:, :, ::-1].astype(np.float32) / 255.0]
    rows = [extractor.extract(x) for x in inputs]
    for row in rows:
        assert row.shape == (extractor.n_features,) and row.dtype == np.int64
        assert (row >= 0).all() and row.sum() > 0
    assert np.array_equal(rows[0], extractor.extract(images[0]))
    many = extractor.extract_many(inputs, jobs=2)
    assert sp.issparse(many) and np.array_equal(many.toarray(), np.vstack(rows))
    spec = extractor.spec()
    rebuilt = build_extractor(spec.to_dict(), extractor.arrays)
    assert np.array_equal(rebuilt.extract(images[0]), rows[0])


def test_corrupt_or_missing_image_is_a_clear_error(tmp_path: Path) -> None:
    bad = tmp_path / "broken.jpg"
    bad.write_bytes(b"\xff\xd8\xff\xe0 not really a jpeg")
    with pytest.raises(DataFormatError, match=r"broken\.jpg: not a readable image"):
        read_image(bad)
    (tmp_path / "empty.png").write_bytes(b"")
    with pytest.raises(DataFormatError, match=r"empty\.png"):
        build_extractor(DEFAULT_EXTRACTOR).extract(tmp_path / "empty.png")
    with pytest.raises(DataFormatError, match=r"nothere\.png: no such image"):
        read_image(tmp_path / "nothere.png")
    with pytest.raises(DataFormatError, match="grey, colour or colour with alpha"):
        read_image(np.zeros((10, 10, 2), np.uint8))


def test_codebook_checksum_mismatch_and_unknown_extractor_are_refused() -> None:
    rng = np.random.default_rng(2)
    images = [_view(p, rng, (120, 160)) for p in ("a", "b", "c")]
    ext = build_extractor(ExtractorSpec("bovw-orb", settings={"words": 6})).fitted(images, random_state=0)
    codebook = ext.arrays["codebook"].copy()
    codebook[0, 0] += 1.0
    with pytest.raises(ConfigurationError, match="do not match"):
        build_extractor(ext.spec(), {"codebook": codebook})
    with pytest.raises(ConfigurationError, match="missing"):
        build_extractor(ext.spec(), {})
    with pytest.raises(ConfigurationError, match="unknown image extractor"):
        build_extractor("sift-9000")
    with pytest.raises(ConfigurationError, match="version 99"):
        build_extractor({"name": DEFAULT_EXTRACTOR, "version": 99, "settings": {}})
    with pytest.raises(ConfigurationError, match="no setting"):
        build_extractor(ExtractorSpec(DEFAULT_EXTRACTOR, settings={"bins": 3}))


# ----------------------------------------------------------------------------- ONNX
def _tiny_onnx(path: Path, n_out: int = 5) -> tuple[np.ndarray, np.ndarray]:
    """Global average pool over (1, 3, H, W), then a 3 -> n_out linear layer (no ReLU: negative
    activations must become 0 counts). Returns the weights and bias."""
    onnx = pytest.importorskip("onnx")
    from onnx import TensorProto, helper, numpy_helper

    rng = np.random.default_rng(3)
    weight = rng.normal(0, 2, (3, n_out)).astype(np.float32)
    bias = rng.normal(0, 1, n_out).astype(np.float32)
    graph = helper.make_graph(
        [helper.make_node("GlobalAveragePool", ["image"], ["pooled"]),
         helper.make_node("Flatten", ["pooled"], ["flat"], axis=1),
         helper.make_node("Gemm", ["flat", "W", "b"], ["logits"])],
        "tiny", [helper.make_tensor_value_info("image", TensorProto.FLOAT, ["N", 3, 32, 32])],
        [helper.make_tensor_value_info("logits", TensorProto.FLOAT, ["N", n_out])],
        initializer=[numpy_helper.from_array(weight, "W"), numpy_helper.from_array(bias, "b")])
    model = helper.make_model(graph, opset_imports=[helper.make_opsetid("", 13)])
    model.ir_version = 8
    onnx.checker.check_model(model)
    onnx.save(model, str(path))
    return weight, bias


def test_onnx_extractor_turns_activations_into_counts(tmp_path: Path) -> None:
    pytest.importorskip("onnxruntime")
    weight, bias = _tiny_onnx(tmp_path / "tiny.onnx")
    ext = build_extractor(ExtractorSpec("onnx", settings={"model_path": str(tmp_path / "tiny.onnx")}))
    assert ext.n_features == 5 and ext.settings["scale"] == 5.0
    image = _view("kitchen", np.random.default_rng(4), (40, 50))
    counts = ext.extract(image)
    small = cv2.resize(image, (32, 32), interpolation=cv2.INTER_AREA)
    rgb = cv2.cvtColor(small, cv2.COLOR_BGR2RGB).astype(np.float32) / 255.0
    rgb = (rgb - np.array([0.485, 0.456, 0.406], np.float32)) / np.array([0.229, 0.224, 0.225], np.float32)
    expected = np.floor(np.maximum(rgb.mean((0, 1)) @ weight + bias, 0) * 5.0)
    assert np.array_equal(counts, expected.astype(np.int64))
    assert (counts >= 0).all()
    assert np.array_equal(ext.extract_many([image, image]).toarray(), np.vstack([counts, counts]))
    # the description names the model by its checksum: another network is refused
    spec = ext.spec()
    _tiny_onnx(tmp_path / "other.onnx", n_out=5)
    other = tmp_path / "other.onnx"
    other.write_bytes(other.read_bytes() + b"")  # same content: accepted
    assert build_extractor(spec, model_path=str(other)).checksum == spec.checksum
    w2 = tmp_path / "w2.onnx"
    _tiny_onnx(w2, n_out=4)
    with pytest.raises(ConfigurationError, match="do not match"):
        build_extractor(spec, model_path=str(w2))
    # spco features takes the network as --model or, like fit/adapt/what/teach, --onnx-model
    views = tmp_path / "views"
    views.mkdir()
    cv2.imwrite(str(views / "0.png"), image)
    for option in ("--model", "--onnx-model"):
        result = _invoke(features, [views, "--extractor", "onnx", option, tmp_path / "tiny.onnx",
                                    "--out", tmp_path / f"v{option}.npz"])
        assert result.exit_code == 0, result.output
        assert np.array_equal(sp.load_npz(tmp_path / f"v{option}.npz").toarray(), counts[None, :])
    with pytest.raises(DataFormatError, match=r"gone\.onnx: no such ONNX model file .*--onnx-model"):
        build_extractor(spec, model_path=str(tmp_path / "gone.onnx"))  # a moved model: say how to give it
    (tmp_path / "junk.onnx").write_bytes(b"junk")
    with pytest.raises(DataFormatError, match=r"junk\.onnx: not a usable ONNX model"):
        build_extractor(ExtractorSpec("onnx", settings={"model_path": str(tmp_path / "junk.onnx")}))


def test_features_command_writes_counts_and_reports_speed(tmp_path: Path) -> None:
    rng = np.random.default_rng(5)
    folder = tmp_path / "views"
    folder.mkdir()
    for i in (0, 2, 10):
        cv2.imwrite(str(folder / f"{i}.jpg"), _view(str(i), rng))
    result = _invoke(features, [folder, "--out", tmp_path / "v.npz"])
    assert result.exit_code == 0, result.output
    assert "images/s" in result.output and DEFAULT_EXTRACTOR in result.output
    counts = sp.load_npz(tmp_path / "v.npz")
    ext = build_extractor(DEFAULT_EXTRACTOR)
    assert np.array_equal(counts.toarray(), np.vstack([ext.extract(folder / f"{i}.jpg") for i in (0, 2, 10)]))
    (folder / "3.png").write_bytes(b"garbage")
    result = CliRunner().invoke(features, [str(folder), "--out", str(tmp_path / "w.npz")])
    assert result.exit_code == 2 and "3.png: not a readable image" in result.output
    assert not (tmp_path / "w.npz").exists()
    pytest.importorskip("onnxruntime")
    _tiny_onnx(tmp_path / "tiny.onnx")
    result = _invoke(features, [folder / "0.jpg", "--out", tmp_path / "o.npz",
                                "--model", tmp_path / "tiny.onnx"])
    assert result.exit_code == 0, result.output
    assert sp.load_npz(tmp_path / "o.npz").shape == (1, 5)


# ----------------------------------------------------------------------------- homes with images
def test_plain_home_with_images_needs_an_extractor(image_homes: dict[str, Path]) -> None:
    with pytest.raises(DataFormatError, match="views as images/"):
        load_home(image_homes["new"])
    ext = build_extractor(DEFAULT_EXTRACTOR)
    env = load_home(image_homes["new"], extractor=ext)
    assert env.n_features == ext.n_features and env.visual.sum() > 0
    first = sorted((image_homes["new"] / "images").iterdir(), key=lambda p: int(p.stem))[0]
    assert np.array_equal(env.visual[[0]].toarray()[0], ext.extract(first))
    with pytest.raises(DataFormatError, match="missing: the views must be images"):
        load_home(image_homes["counts"] / sorted(p.name for p in image_homes["counts"].iterdir())[0],
                  extractor=ext)


def test_fit_adapt_what_teach_with_images(image_homes: dict[str, Path], tmp_path: Path) -> None:
    kfile, hfile = tmp_path / "k.spco", tmp_path / "h.spco"
    result = _invoke(fit, ["--data", image_homes["experienced"], "--iterations", 4, "--out", kfile])
    assert result.exit_code == 0, result.output
    knowledge = kn.load_knowledge(kfile)
    assert knowledge.fitted_on_images and knowledge.extractor["name"] == DEFAULT_EXTRACTOR
    assert "views: images" in knowledge.describe()
    result = _invoke(adapt, [kfile, "--home", image_homes["new"], "--iterations", 4, "--out", hfile])
    assert result.exit_code == 0, result.output
    home = kn.load_home_model(hfile)
    assert home.knowledge.extractor == knowledge.extractor
    for file in (kfile, hfile):  # spco inspect names the extractor (it once said "none recorded")
        shown = _invoke(inspect_command, [file])
        assert shown.exit_code == 0 and f"extractor: images, {DEFAULT_EXTRACTOR}" in shown.output
        shown = _invoke(inspect_command, [file, "--json"])
        assert json.loads(shown.output)["extractor"] == knowledge.extractor
    view = tmp_path / "view.png"
    cv2.imwrite(str(view), _view("kitchen", np.random.default_rng(9)))
    result = _invoke(what, [hfile, "--x", 0.5, "--y", 0.5, "--theta", 0, "--image", view, "--json"])
    assert result.exit_code == 0, result.output
    answer = json.loads(result.output)
    assert answer["vision"] is True and abs(sum(n["probability"] for n in answer["names"])) <= 1.0 + 1e-9
    n_before = home.n_samples
    result = _invoke(teach, [hfile, "--x", 0.5, "--y", 0.5, "--theta", 0, "--image", view,
                             "--sentence", "this is the study", "--sweeps", 2])
    assert result.exit_code == 0, result.output
    taught = kn.load_home_model(hfile)
    assert taught.n_samples == n_before + 1 and "study" in taught.vocabulary
    assert np.array_equal(taught.visual[[n_before]].toarray()[0],
                          knowledge.image_extractor().extract(view))
    # count vectors for a knowledge fitted on images are refused, and the other way round
    np.savetxt(tmp_path / "v.csv", np.ones(knowledge.n_features, dtype=int), fmt="%d")
    result = CliRunner().invoke(what, [str(hfile), "--x", "0", "--y", "0", "--theta", "0",
                                       "--visual", str(tmp_path / "v.csv")])
    assert result.exit_code == 2 and "fitted on images" in result.output and "--image" in result.output
    broken = tmp_path / "broken.jpg"
    broken.write_bytes(b"nope")
    result = CliRunner().invoke(what, [str(hfile), "--x", "0", "--y", "0", "--theta", "0",
                                       "--image", str(broken)])
    assert result.exit_code == 2 and "broken.jpg: not a readable image" in result.output


def test_count_vector_knowledge_refuses_images(image_homes: dict[str, Path], tmp_path: Path) -> None:
    kfile, hfile = tmp_path / "k.spco", tmp_path / "h.spco"
    assert _invoke(fit, ["--data", image_homes["counts"], "--iterations", 3, "--out", kfile]).exit_code == 0
    assert not kn.load_knowledge(kfile).fitted_on_images
    result = CliRunner().invoke(adapt, [str(kfile), "--home", str(image_homes["new"]), "--out", str(hfile)])
    assert result.exit_code == 2 and "fitted on visual count vectors" in result.output
    home_dir = sorted(p for p in image_homes["counts"].iterdir() if p.is_dir())[0]
    assert _invoke(adapt, [kfile, "--home", home_dir, "--iterations", 3, "--out", hfile]).exit_code == 0
    view = tmp_path / "view.png"
    cv2.imwrite(str(view), _view("kitchen", np.random.default_rng(9)))
    result = CliRunner().invoke(what, [str(hfile), "--x", "0", "--y", "0", "--theta", "0",
                                       "--image", str(view)])
    assert result.exit_code == 2 and "fitted on visual count vectors" in result.output
    result = CliRunner().invoke(teach, [str(hfile), "--x", "0", "--y", "0", "--theta", "0", "--image",
                                        str(view)])
    assert result.exit_code == 2 and "fitted on visual count vectors" in result.output


def test_version_1_knowledge_files_are_read_as_count_vectors(image_homes: dict[str, Path],
                                                             tmp_path: Path) -> None:
    kfile = tmp_path / "k.spco"
    # (a model without word pruning: spcotransfer+mi files older than version 4 are refused, being
    # learnt with the naming rule — tests/test_channels_robot.py)
    assert _invoke(fit, ["--data", image_homes["counts"], "--iterations", 2, "--model", "spcotransfer",
                         "--out", kfile]).exit_code == 0
    with np.load(kfile, allow_pickle=False) as archive:
        arrays = {k: archive[k] for k in archive.files}
    header = json.loads(arrays.pop("header").tobytes().decode())
    assert header["format_version"] == 2 and header["extractor"] is None  # 3: segmented text only
    del header["extractor"]
    header["format_version"] = 1
    header["checksum"] = _content_checksum(header)
    old = tmp_path / "old.spco"
    with open(old, "wb") as handle:
        np.savez(handle, header=np.frombuffer(json.dumps(header).encode(), dtype=np.uint8), **arrays)
    loaded = kn.load_knowledge(old)
    assert loaded.extractor is None and not loaded.fitted_on_images
    with pytest.raises(ConfigurationError, match="count vectors"):
        loaded.image_extractor()


def test_sigverse_home_with_its_images(sigverse_dir: Path) -> None:
    """The SIGVerse loader takes the views from sigverse_images/<home>/<i>.jpg in place of fc7."""
    images = sigverse_dir.parent / "sigverse_images"
    if not (images / "1DK_8").is_dir():
        pytest.skip(f"sigverse_images not found at {images}")
    ext = build_extractor(DEFAULT_EXTRACTOR)
    env = load_home(sigverse_dir / "1DK_8", extractor=ext, images=images)
    fc7 = load_home(sigverse_dir / "1DK_8")
    assert env.n_samples == fc7.n_samples and env.n_features == ext.n_features
    assert np.array_equal(env.positions, fc7.positions) and env.sentences == fc7.sentences
    assert np.array_equal(env.visual[[3]].toarray()[0], ext.extract(images / "1DK_8" / "3.jpg"))
    with pytest.raises(DataFormatError, match="--images"):
        load_home(sigverse_dir / "1DK_8", extractor=ext)


def test_fit_learns_a_codebook_for_sigverse_homes_with_images(make_sigverse_home, tmp_path: Path) -> None:
    """--images DIR gives SIGVerse-layout homes their views; bovw-orb's codebook goes into the knowledge."""
    data, images = tmp_path / "data", tmp_path / "img"
    rng = np.random.default_rng(6)
    for name in ("home_a", "home_b"):
        make_sigverse_home(name, n=8, test=(6, 7), root=data)
        (images / name).mkdir(parents=True)
        for i in range(8):
            texture = cv2.resize(rng.integers(0, 256, (30, 40, 3), dtype=np.uint8), (160, 120),
                                 interpolation=cv2.INTER_NEAREST)
            cv2.imwrite(str(images / name / f"{i}.jpg"), texture)
    kfile, hfile = tmp_path / "k.spco", tmp_path / "h.spco"
    result = _invoke(fit, ["--data", data, "--images", images, "--extractor", "bovw-orb", "--iterations", 2,
                           "--seed", 3, "--out", kfile])
    assert result.exit_code == 0, result.output
    knowledge = kn.load_knowledge(kfile)
    assert knowledge.extractor["name"] == "bovw-orb" and knowledge.n_features == 512
    assert knowledge.extractor_arrays["codebook"].shape == (512, 256)
    assert knowledge.image_extractor().checksum == knowledge.extractor["checksum"]
    result = _invoke(adapt, [kfile, "--home", data / "home_b", "--images", images, "--iterations", 2,
                             "--out", hfile])
    assert result.exit_code == 0, result.output
    home = kn.load_home_model(hfile)  # the home file carries the codebook too
    assert home.knowledge.image_extractor().checksum == knowledge.extractor["checksum"]
    view = images / "home_b" / "7.jpg"
    counts = knowledge.image_extractor().extract(view)
    assert np.array_equal(kn.what(home, 0.0, 0.0, 0.0, image=view).probabilities,
                          kn.what(home, 0.0, 0.0, 0.0, visual=counts).probabilities)
    result = CliRunner().invoke(adapt, [str(kfile), "--home", str(data / "home_b"), "--out",
                                        str(tmp_path / "h2.spco")])
    assert result.exit_code == 2 and "--images" in result.output


def test_experiment_images_need_real_homes(tmp_path: Path) -> None:
    from spco.evaluation.experiments import ExperimentConfig, load_experiment_data

    with pytest.raises(ConfigurationError, match="synthetic homes have no images"):
        load_experiment_data(ExperimentConfig(data="synthetic", images=tmp_path, trials=1))


def test_inspect_reads_homes_whose_views_are_images(image_homes: dict[str, Path]) -> None:
    """`spco inspect` of a home folder holding images/ (e.g. from spco import-bag) summarises it
    instead of asking for an extractor (it reads the views with the default one to count them)."""
    from spco.cli import inspect

    result = CliRunner().invoke(inspect, [str(image_homes["experienced"]), "--json"])
    assert result.exit_code == 0, result.output
    rows = json.loads(result.output)  # one object per home
    assert len(rows) == 2 and all(r["samples"] > 0 and r["taught"] > 0 for r in rows)


def test_experiment_with_images_extracts_once_for_its_workers(tmp_path: Path) -> None:
    """`spco experiment --images --jobs 2`: the workers read the views the parent extracted (a cache
    file in a temporary folder of the output, removed afterwards) and give the runs of one process;
    the extractor's full description is part of the experiment's identity."""
    from spco.evaluation.experiments import ExperimentConfig, run_experiment

    corpus = generate_homes(3, seed=5, config=SyntheticConfig(n_features=16, n_train=6, n_test=2),
                            new_homes=1, specific_rooms=False)
    root = tmp_path / "homes"
    write_corpus(list(corpus), root)
    rng = np.random.default_rng(0)
    for env in corpus:
        _image_home(env, root / env.name, rng)
    names = [env.name for env in corpus]
    config = dict(experiment="general", data=root, images=root, settings=(1, 2), trials=2, iterations=3,
                  models=("spcotransfer+mi",), experienced_homes=tuple(names[:2]), new_homes=(names[2],),
                  seed=4)
    serial = run_experiment(ExperimentConfig(**config, jobs=1), tmp_path / "serial")
    parallel = run_experiment(ExperimentConfig(**config, jobs=2), tmp_path / "parallel")
    assert not list((tmp_path / "parallel").glob(".views-*"))

    def runs(out: Path) -> list[tuple]:
        lines = [json.loads(line) for line in (out / "runs.jsonl").read_text().splitlines()]
        return sorted((r["setting"], r["trial"], r["home"], r["mean_name_accuracy"],
                       r["mean_position_accuracy"]) for r in lines)

    assert len(runs(tmp_path / "serial")) == 4 and runs(tmp_path / "serial") == runs(tmp_path / "parallel")
    views = serial.results["config"]["data"]["views"]
    assert views["extractor_spec"] == build_extractor(DEFAULT_EXTRACTOR).spec().to_dict()
    assert parallel.results["config"]["fingerprint"] == serial.results["config"]["fingerprint"]
    # what the workers are given: the counts as a cache file, no images to extract
    from spco.evaluation.experiments import RunKey, _build_data, _data_spec, _views_for_workers

    full = ExperimentConfig(**config, jobs=2).validated()
    spec = _data_spec(full)
    data = _build_data(spec, full.settings)
    pending = [RunKey(1, 0, names[2], "spcotransfer+mi"), RunKey(2, 0, names[2], "spcotransfer+mi")]
    with _views_for_workers(data, spec, tmp_path, pending, 2, "local") as worker_spec:
        assert worker_spec.images is None and worker_spec.extractor is None
        assert Path(worker_spec.source).name == "views.npz"
        rebuilt = _build_data(worker_spec, full.settings)
        pairs = [(data.experienced_home(n), rebuilt.experienced_home(n)) for n in names[:2]]
        pairs.append((data.new_home(names[2]), rebuilt.new_home(names[2])))
        for given, read in pairs:
            assert np.array_equal(given.visual.toarray(), read.visual.toarray())
            assert given.sentences == read.sentences
        assert rebuilt.vocabulary.words == data.vocabulary.words
    assert not list(tmp_path.glob(".views-*"))
    with _views_for_workers(data, spec, tmp_path, pending, 1, "local") as worker_spec:
        assert worker_spec is spec  # one process: nothing to hand over
