"""The figure functions write non-empty PNG files on a tiny case."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from matplotlib.figure import Figure

from spco.data.environment import Environment, make_ground_truth
from spco.data.language import Vocabulary
from spco.data.regions import PlaceRegions
from spco.errors import ConfigurationError
from spco.evaluation import evaluate_home
from spco.model.parameters import ConceptParameters
from spco.model.prediction import predict_names
from spco.plots import concept_labels, plot_accuracy_curve, plot_home_map, plot_log_joint

PNG_MAGIC = b"\x89PNG\r\n\x1a\n"
WORDS = ("this", "is", "kitchen", "bath", "bedroom")
REGIONS = PlaceRegions({
    "kitchen": ((0.0, 2.0, 0.0, 2.0),),
    "bath": ((3.0, 5.0, 0.0, 1.5), (3.0, 4.0, 1.5, 2.5)),
    "bedroom": ((0.0, 5.0, 3.5, 6.0),),
})


def home_params() -> ConceptParameters:
    """E=1, L=3 concepts (kitchen, bath, bedroom), K=4 regions (one unused), V=5, D=4."""
    theta_w = np.array([
        [0.4, 0.3, 0.3, 0.0, 0.0],
        [0.4, 0.3, 0.0, 0.3, 0.0],
        [0.4, 0.3, 0.0, 0.0, 0.3],
    ])
    g = np.array([0.35, 0.3, 0.35])
    pi = np.array([[0.9, 0.04, 0.04, 0.02], [0.04, 0.9, 0.04, 0.02], [0.02, 0.02, 0.94, 0.02]])
    means = np.array([[1.0, 1.0, 0.0, 1.0], [4.0, 0.8, 1.0, 0.0], [2.5, 4.7, 0.0, -1.0],
                      [9.0, 9.0, 0.0, 1.0]])
    covs = np.tile(np.diag([0.15, 0.1, 0.3, 0.3]), (4, 1, 1))
    covs[2, 0, 0], covs[2, 0, 1], covs[2, 1, 0] = 0.8, 0.15, 0.15
    theta_v = np.array([[0.7, 0.1, 0.1, 0.1], [0.1, 0.7, 0.1, 0.1], [0.1, 0.1, 0.7, 0.1]])
    return ConceptParameters(g[None], pi[None], means[None], covs[None], theta_w[None], theta_v[None],
                             theta_w, theta_v, g, np.ones(5, dtype=bool), np.array([[20, 20, 20, 0]]))


def home() -> Environment:
    rng = np.random.default_rng(0)
    centres = np.array([[1.0, 1.0], [4.0, 0.8], [2.5, 4.7]])
    place = np.repeat(np.arange(3), 8)
    xy = centres[place] + rng.normal(scale=0.3, size=(place.size, 2))
    heading = rng.uniform(-np.pi, np.pi, size=place.size)
    positions = np.column_stack([xy, np.sin(heading), np.cos(heading)])
    visual = np.zeros((place.size, 4), dtype=np.int64)
    visual[np.arange(place.size), place] = 30
    is_test = np.tile(np.arange(8) >= 6, 3)
    labels = [("kitchen", "bath", "bedroom")[p] for p in place]
    return Environment(name="toy home", ids=np.arange(place.size), positions=positions, visual=visual,
                       sentences=[None] * place.size, is_test=is_test, extent=(-0.5, 6.0, -0.5, 6.5),
                       ground_truth=make_ground_truth(labels, regions=REGIONS))


def assert_png(path: Path) -> None:
    assert path.is_file() and path.stat().st_size > 1000
    assert path.read_bytes()[:8] == PNG_MAGIC


def test_plot_home_map(tmp_path: Path) -> None:
    params, env, vocab = home_params(), home(), Vocabulary(WORDS)
    scores = evaluate_home(params, 0, env, vocab, n_positions=10, rng=0)
    poses = env.positions[[6, 14, 22]]
    names = predict_names(params, 0, vocab, poses, env.visual[[6, 14, 22]])
    path = tmp_path / "map.png"
    fig = plot_home_map(params, 0, env, vocab, predicted_positions=scores.predicted_positions,
                        poses=poses, pose_names=names, path=path)
    assert isinstance(fig, Figure)
    assert_png(path)
    # on a floor-plan image, with (word, p) lists for the poses
    image = np.full((40, 40, 3), 0.9)
    path2 = tmp_path / "sub" / "map_image.png"
    plot_home_map(params, 0, env, vocab, map_image=image, map_extent=(-1, 7, -1, 7), poses=poses[:1],
                  pose_names=[[("kitchen", 0.9), ("bath", 0.1)]], path=path2)
    assert_png(path2)
    with pytest.raises(ConfigurationError):
        plot_home_map(params, 0, env, vocab, poses=poses, pose_names=[[("kitchen", 1.0)]])


def test_pose_callouts_stay_inside_the_map() -> None:
    """Callouts of poses near every edge of the map point inwards: none leaves the axes, where it
    would cover the legend drawn to their right."""
    params, env, vocab = home_params(), home(), Vocabulary(WORDS)
    x0, x1, y0, y1 = env.extent
    corners = np.array([[x0 + 0.1, y0 + 0.1, 0.0, 1.0], [x1 - 0.1, y0 + 0.1, 0.0, 1.0],
                        [x0 + 0.1, y1 - 0.1, 0.0, 1.0], [x1 - 0.1, y1 - 0.1, 0.0, 1.0]])
    names = [[("bedroom", 0.93), ("bath", 0.05), ("kitchen", 0.02)]] * len(corners)
    fig = plot_home_map(params, 0, env, vocab, poses=corners, pose_names=names)
    ax = fig.axes[0]
    from matplotlib.backends.backend_agg import FigureCanvasAgg

    canvas = FigureCanvasAgg(fig)
    canvas.draw()
    renderer = canvas.get_renderer()
    inside = ax.get_window_extent(renderer)
    callouts = [child for child in ax.get_children() if type(child).__name__ == "Annotation"]
    assert len(callouts) == len(corners)
    for callout in callouts:
        box = callout.get_bbox_patch().get_window_extent(renderer)
        assert inside.x0 - 1 <= box.x0 and box.x1 <= inside.x1 + 1, callout.get_text()
        assert inside.y0 - 1 <= box.y0 and box.y1 <= inside.y1 + 1, callout.get_text()


def test_concept_labels() -> None:
    labels = concept_labels(home_params(), 0, Vocabulary(WORDS))
    assert labels == ["c0: kitchen", "c1: bath", "c2: bedroom"]  # carrier words are skipped
    # pruned words are not shown; without informative words, the most probable ones are
    params = home_params()
    mask = np.array([False, True, True, True, True])
    pruned = type(params)(**{**params.arrays(), "word_mask": mask})
    assert concept_labels(pruned, 0, Vocabulary(WORDS), n_words=1) == ["c0: kitchen", "c1: bath",
                                                                        "c2: bedroom"]
    flat = np.full((1, 3, 5), 0.2)
    flat[0, :, 1] = 0.4
    flat[0, :, 0] = 0.0
    same = type(params)(**{**params.arrays(), "word_probabilities": flat})
    # words said alike in every concept describe none of them
    assert concept_labels(same, 0, Vocabulary(WORDS), n_words=2) == ["c0", "c1", "c2"]


def test_a_name_taught_in_one_place_labels_only_its_concept() -> None:
    """A new name keeps a small prior probability in every concept; only the concept where it was
    taught is labelled with it (before, every concept's label ended with it)."""
    params = home_params()
    words = (*WORDS, "grandma's-room")
    theta = np.concatenate([params.word_probabilities[0], np.full((3, 1), 1e-4)], axis=1)
    theta[2, -1] = 0.05  # taught in the bedroom's concept
    theta /= theta.sum(axis=1, keepdims=True)
    taught = type(params)(**{**params.arrays(), "word_probabilities": theta[None],
                             "word_mask": np.ones(6, dtype=bool)})
    assert concept_labels(taught, 0, Vocabulary(words)) == ["c0: kitchen", "c1: bath",
                                                            "c2: bedroom, grandma's room"]


def test_map_legend_has_samples_and_region_centres() -> None:
    params, env, vocab = home_params(), home(), Vocabulary(WORDS)
    fig = plot_home_map(params, 0, env, vocab)
    labels = fig.axes[0].get_legend_handles_labels()[1]
    assert "samples (robot positions)" in labels and "region centres (+)" in labels


def _boxes_overlap(a, b) -> bool:
    return min(a.x1, b.x1) - max(a.x0, b.x0) > 0 and min(a.y1, b.y1) - max(a.y0, b.y0) > 0


def test_callouts_cover_no_room_label_marker_or_other_callout() -> None:
    """Six poses close together, with the room labels and region centres around them: measured with
    the renderer's bounding boxes, no callout overlaps a room label, a marker (region centre, pose,
    predicted position) or another callout, and each stays inside the axes."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.transforms import Bbox

    params, env, vocab = home_params(), home(), Vocabulary(WORDS)
    rng = np.random.default_rng(3)
    xy = np.array([[1.0, 1.2], [1.3, 0.9], [0.8, 0.7], [4.0, 0.9], [3.7, 1.1], [2.5, 4.5]])
    poses = np.column_stack([xy, np.zeros(6), np.ones(6)])
    names = [[("kitchen", 0.91), ("bath", 0.06), ("bedroom", 0.03)]] * len(poses)
    predicted = {"kitchen": np.array([1.0, 1.0]) + rng.normal(scale=0.2, size=(10, 2))}
    fig = plot_home_map(params, 0, env, vocab, poses=poses, pose_names=names, predicted_positions=predicted)
    ax = fig.axes[0]
    canvas = FigureCanvasAgg(fig)
    canvas.draw()
    renderer = canvas.get_renderer()
    frame = ax.get_window_extent(renderer)
    callouts = [c for c in ax.get_children() if type(c).__name__ == "Annotation"]
    assert len(callouts) == len(poses)
    boxes = [c.get_bbox_patch().get_window_extent(renderer) for c in callouts]
    room_labels = [t.get_window_extent(renderer) for t in ax.texts if t.get_text() in REGIONS.places]
    assert len(room_labels) == 3
    half = 3.0 * fig.dpi / 72.0  # a marker's half size (points -> pixels)
    points = np.concatenate([params.region_means[0][:3, :2], xy, predicted["kitchen"]])
    markers = [Bbox.from_extents(x - half, y - half, x + half, y + half)
               for x, y in ax.transData.transform(points)]
    for i, box in enumerate(boxes):
        assert frame.x0 - 1 <= box.x0 and box.x1 <= frame.x1 + 1 and frame.y0 - 1 <= box.y0 \
            and box.y1 <= frame.y1 + 1
        assert not any(_boxes_overlap(box, other) for other in boxes[:i] + boxes[i + 1:]), i
        assert not any(_boxes_overlap(box, label) for label in room_labels), i
        assert not any(_boxes_overlap(box, marker) for marker in markers), i


def test_plot_accuracy_curve(tmp_path: Path) -> None:
    settings = [1, 2, 4, 8, 16]
    path = tmp_path / "curve.png"
    plot_accuracy_curve(settings, {"proposed": [0.3, 0.4, 0.5, 0.6, 0.7], "SpCoA": [0.2] * 5},
                        {"proposed": [0.05] * 5, "SpCoA": [0.02] * 5}, 0.125,
                        "number of experienced homes", "name accuracy", path)
    assert_png(path)
    path2 = tmp_path / "curve1.png"
    plot_accuracy_curve([0, 20, 40], [0.1, 0.2, 0.3], None, None, "teaching rate [%]", "A_p", path2)
    assert_png(path2)
    with pytest.raises(ConfigurationError):
        plot_accuracy_curve([0, 1], [0.1], None, None, "x", "t")


def test_plot_log_joint(tmp_path: Path) -> None:
    rng = np.random.default_rng(0)
    trace = -1e5 + np.cumsum(np.abs(rng.normal(size=200)) * 50)
    path = tmp_path / "trace.png"
    plot_log_joint(trace, path)
    assert_png(path)
    plot_log_joint(np.stack([trace, trace + 10]), tmp_path / "traces.png")
    assert_png(tmp_path / "traces.png")
    with pytest.raises(ConfigurationError):
        plot_log_joint(np.zeros((2, 2, 2)))
