"""Figures: a home's map with its learnt spatial concepts, accuracy curves and the log-joint trace.

All functions draw on :class:`matplotlib.figure.Figure` objects created without ``pyplot`` (no
display, no global figure registry, safe in threads and batch jobs) and save PNGs with
``fig.savefig(path, dpi=120)`` when a ``path`` is given; a bare Figure renders with the Agg canvas,
so importing this module never changes the pyplot backend of the caller. Each returns the Figure.
"""

from __future__ import annotations

import functools
import warnings
from collections.abc import Callable, Mapping, Sequence
from pathlib import Path
from typing import Any, TypeVar

import matplotlib
import matplotlib.image
import numpy as np
from matplotlib.axes import Axes
from matplotlib.figure import Figure
from matplotlib.patches import Ellipse, Rectangle
from scipy.special import gammaincinv

from spco.data.environment import Environment
from spco.data.language import Vocabulary
from spco.errors import ConfigurationError
from spco.model.parameters import ConceptParameters
from spco.model.prediction import NamePrediction, mutual_information_weights

__all__ = ["concept_labels", "plot_accuracy_curve", "plot_home_map", "plot_log_joint"]

DPI = 120
_CHI2_95_2D = float(2.0 * gammaincinv(1.0, 0.95))  # χ²₂'s 95 % quantile ≈ 5.991, as scipy.stats computes it
_MARKERS = ("o", "s", "^", "D", "v", "P", "X", "*", "<", ">", "h", "p")

PathLike = str | Path
_F = TypeVar("_F", bound=Callable[..., Any])
#: Fonts with Japanese and Chinese glyphs, tried in order after matplotlib's own (names in such
#: scripts are drawn with the first one installed; Debian: fonts-noto-cjk or fonts-ipafont-gothic).
CJK_FONTS = ("Noto Sans CJK JP", "Noto Sans CJK SC", "IPAexGothic", "IPAGothic", "IPAPGothic",
             "TakaoGothic", "VL Gothic", "WenQuanYi Zen Hei", "Droid Sans Fallback")


@functools.cache
def _installed_cjk_fonts() -> tuple[str, ...]:
    from matplotlib import font_manager

    names = {f.name for f in font_manager.fontManager.ttflist}
    return tuple(f for f in CJK_FONTS if f in names)


def _with_cjk_fonts(func: _F) -> _F:
    """Draw with a font for Japanese and Chinese names after matplotlib's default when one is
    installed; without one, such names come out as boxes and one warning says so (not one per
    missing glyph)."""

    @functools.wraps(func)
    def wrapper(*args: Any, **kwargs: Any) -> Any:
        fallback = _installed_cjk_fonts()
        family = [*matplotlib.rcParams["font.sans-serif"][:1], *fallback]
        with matplotlib.rc_context({"font.family": family}), \
                warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            result = func(*args, **kwargs)
        missing = [w for w in caught if "missing from font" in str(w.message)]
        for w in caught:
            if w not in missing:
                warnings.warn_explicit(w.message, w.category, w.filename, w.lineno)
        if missing:
            warnings.warn("no installed font has the Japanese or Chinese characters of the names: they are "
                          "drawn as boxes; install one (Debian: apt install fonts-noto-cjk)", UserWarning,
                          stacklevel=2)
        return result

    return wrapper  # type: ignore[return-value]


def _new_axes(ax: Axes | None, figsize: tuple[float, float]) -> tuple[Figure, Axes]:
    if ax is not None:
        return ax.figure, ax  # type: ignore[return-value]
    fig = Figure(figsize=figsize, layout="constrained")
    return fig, fig.add_subplot()


def _save(fig: Figure, path: PathLike | None) -> None:
    if path is not None:
        Path(path).parent.mkdir(parents=True, exist_ok=True)
        fig.savefig(path, dpi=DPI)


#: name -> (region, p(region | name)): where the robot's ``where`` goes for each place (a map's labels).
PlaceLabels = Mapping[str, tuple[int, float]]


def concept_labels(params: ConceptParameters, e: int, vocabulary: Vocabulary, n_words: int = 2) -> list[str]:
    """A short label per concept: ``"c3: kitchen, dining"``, with only words that describe it.

    A word w describes concept l when it is informative (I(w) > 0, the mutual-information weight of
    name prediction, so carrier words such as "this" never do) and said more in l than in the home
    on average, θ^w_{e,l,w} ≥ 1.2 Σ_c G_{e,c} θ^w_{e,c,w}, and by a factor 2 or reaching half its
    largest θ^w over the concepts (a name of a concept that holds most of the home). So a name
    taught in one place labels that place's concept only, not every concept in which it keeps its
    small prior probability. Of those words, the ``n_words`` with the
    highest θ^w · I(w) are shown. Returns L strings (``"c3"`` alone if no word describes it).
    """
    theta = np.asarray(params.word_probabilities[e], dtype=float) * np.asarray(params.word_mask)[None, :]
    info = mutual_information_weights(params, e)
    g = np.clip(np.asarray(params.concept_weights[e], dtype=float), 0.0, None)
    g = g / g.sum() if g.sum() > 0 else np.full(theta.shape[0], 1.0 / theta.shape[0])
    average = g @ theta  # (V,) Σ_c G_c θ_{c,w}
    describes = ((info[None, :] > 0) & (theta >= 1.2 * average[None, :])
                 & ((theta >= 2.0 * average[None, :]) | (theta >= 0.5 * theta.max(axis=0, keepdims=True))))
    score = np.where(describes, theta * info[None, :], 0.0)
    order = np.argsort(-score, axis=1, kind="stable")[:, :n_words]
    labels = []
    for c in range(theta.shape[0]):
        words = [vocabulary.words[k] for k in order[c] if score[c, k] > 0] if len(vocabulary) else []
        labels.append(f"c{c}: " + ", ".join(words) if words else f"c{c}")
    return labels


def _default_colors(n: int) -> list[tuple[float, float, float, float]]:
    """n distinguishable colours: tab10, or tab20 with its dark shades first when n > 10."""
    if n <= 10:
        cmap = matplotlib.colormaps["tab10"]
        return [cmap(i) for i in range(n)]
    cmap = matplotlib.colormaps["tab20"]
    order = [*range(0, 20, 2), *range(1, 20, 2)]
    return [cmap(order[i % 20]) for i in range(n)]


def _ellipse_geometry(cov2: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Widths, heights and angles (degrees) of 95% ellipses of a stack (K, 2, 2) of covariances."""
    cov2 = 0.5 * (cov2 + np.swapaxes(cov2, -1, -2))
    eigval, eigvec = np.linalg.eigh(cov2)  # ascending
    eigval = np.maximum(eigval, 0.0)
    width = 2.0 * np.sqrt(_CHI2_95_2D * eigval[:, 1])
    height = 2.0 * np.sqrt(_CHI2_95_2D * eigval[:, 0])
    angle = np.degrees(np.arctan2(eigvec[:, 1, 1], eigvec[:, 0, 1]))
    return width, height, angle


@_with_cjk_fonts
def _concept_colors(colors: Sequence[Any] | None, n_concepts: int) -> Sequence[Any]:
    """A colour per concept: those given (at least one per concept) or the default ones."""
    if colors is None:
        return _default_colors(n_concepts)
    if len(colors) < n_concepts:
        raise ConfigurationError(f"{len(colors)} colours for {n_concepts} concepts")
    return colors


def _draw_floor_plan(ax: Any, map_image: Any, extent: Sequence[float] | None) -> None:
    """The floor plan (a file or an array; grey levels drawn grey) under everything else."""
    image = matplotlib.image.imread(str(map_image)) if isinstance(map_image, str | Path) \
        else np.asarray(map_image)
    grey = {"cmap": "gray", "vmin": 0, "vmax": 255 if image.dtype == np.uint8 else 1.0} \
        if image.ndim == 2 else {}
    ax.imshow(image, extent=extent, origin="upper", zorder=0, alpha=0.9, **grey)


def _draw_regions(ax: Any, params: ConceptParameters, e: int, vocabulary: Any, concept_colors: Sequence[Any],
                  label_regions: bool, place_labels: PlaceLabels | None = None) -> np.ndarray:
    """The home's learnt regions: an ellipse per used region in its concept's colour (the concept's
    names in the legend, and on the map with ``label_regions``: each of ``place_labels`` at its region,
    or without them the concepts' names) and its centre (+). Returns the centres (n, 2)."""
    counts = np.asarray(params.region_counts[e])
    used = np.flatnonzero(counts >= max(NEGLIGIBLE_REGION * counts.sum(), 1e-12))
    hidden = int(np.count_nonzero(counts > 0)) - used.size
    means = np.asarray(params.region_means[e], dtype=float)
    if not used.size:
        return np.zeros((0, 2))
    covs = np.asarray(params.region_covariances[e], dtype=float)[:, :2, :2]
    joint = np.asarray(params.region_weights[e], dtype=float) * np.asarray(
        params.concept_weights[e], dtype=float)[:, None]  # (L, K)
    owner = np.argmax(joint, axis=0)  # (K,)
    labels = concept_labels(params, e, vocabulary)
    width, height, angle = _ellipse_geometry(covs[used])
    shown: set[int] = set()
    for j, m in enumerate(used):  # one patch per region (K ≤ a few tens)
        c = int(owner[m])
        colour = concept_colors[c]
        ax.add_patch(Ellipse((means[m, 0], means[m, 1]), width[j], height[j], angle=angle[j],
                             facecolor=colour, alpha=0.25, edgecolor=colour, linewidth=2.0,
                             zorder=3, label=labels[c] if c not in shown else "_nolegend_"))
        shown.add(c)
    if label_regions and place_labels is not None:
        _label_places(ax, place_labels, means, owner, concept_colors)
    elif label_regions:
        _label_regions(ax, used, counts, means, owner, labels, concept_colors)
    ax.scatter(means[used, 0], means[used, 1], marker="+", s=60, color="k", linewidths=1.2,
               zorder=4, label="region centres (+)" + (
                   f"; {hidden} region(s) under {NEGLIGIBLE_REGION:.0%} of the samples not drawn"
                   if hidden else ""))
    return means[used, :2]


def _draw_predicted(ax: Any, predicted_positions: Mapping[str, Any]) -> list[np.ndarray]:
    """Each place name's predicted positions, one marker and colour per name; returns their (x, y)."""
    cmap = matplotlib.colormaps["Dark2"]
    points = []
    for i, (name, pts) in enumerate(predicted_positions.items()):
        xy = np.atleast_2d(np.asarray(pts, dtype=float))
        if xy.size == 0:
            continue
        points.append(xy[:, :2])
        ax.scatter(xy[:, 0], xy[:, 1], marker=_MARKERS[i % len(_MARKERS)], s=36,
                   color=cmap(i % 8), edgecolors="k", linewidths=0.5, zorder=5,
                   label=f"predicted: {name}")
    return points


def _draw_rooms(ax: Any, regions: Any, extent: Sequence[float] | None) -> list[Any]:
    """The rooms' rectangles, each drawn once and labelled (inside, kept within the map) with the
    names of the places it is the first rectangle of: "bedroom / emma's-room" where both share it.
    Returns the labels' text artists."""
    first_of: dict[tuple[float, ...], list[str]] = {}
    for name, rects in regions.places.items():
        for i, rect in enumerate(rects):
            names_here = first_of.setdefault(tuple(rect), [])
            if i == 0:
                names_here.append(name)
    room_labels = []
    for (x0, x1, y0, y1), names_here in first_of.items():
        ax.add_patch(Rectangle((x0, y0), x1 - x0, y1 - y0, fill=False, edgecolor="0.35",
                               linewidth=1.0, linestyle="-", zorder=1))
        if names_here:
            tx = x0 if extent is None else min(max(x0, extent[0]), extent[1])
            ty = y1 if extent is None else max(min(y1, extent[3]), extent[2])
            room_labels.append(ax.text(
                    tx + 0.08, ty - 0.08, " / ".join(names_here), fontsize=8, color="0.15", ha="left",
                    va="top", zorder=4.5, clip_on=True,
                    bbox={"boxstyle": "square,pad=0.15", "fc": "white", "ec": "none", "alpha": 0.7}))
    return room_labels


def _pose_callouts(p: np.ndarray, pose_names: Any) -> list[tuple[float, float, str]]:
    """(x, y, text) of each pose's callout: its top three names with their probabilities."""
    if isinstance(pose_names, NamePrediction):
        entries = [list(zip(w, pr, strict=True)) for w, pr in
                   zip(pose_names.words.tolist(), pose_names.probabilities.tolist(), strict=True)]
    else:
        entries = [list(row) for row in pose_names]
    if len(entries) != p.shape[0]:
        raise ConfigurationError(f"{len(entries)} name lists for {p.shape[0]} poses")
    return [(float(x), float(y), "\n".join(f"{w} ({float(pr):.2f})" for w, pr in row[:3]) or "(no name)")
            for (x, y, _, _), row in zip(p, entries, strict=True)]


def plot_home_map(
    params: ConceptParameters,
    e: int,
    environment: Environment | None,
    vocabulary: Vocabulary,
    ax: Axes | None = None,
    map_image: np.ndarray | PathLike | None = None,
    map_extent: Sequence[float] | None = None,
    predicted_positions: Mapping[str, np.ndarray] | None = None,
    poses: np.ndarray | None = None,
    pose_names: NamePrediction | Sequence[Sequence[tuple[str, float]]] | None = None,
    concept_colors: Sequence[object] | None = None,
    show_ground_truth: bool | None = None,
    show_samples: bool = True,
    label_regions: bool = False,
    title: str | None = None,
    path: PathLike | None = None,
    place_labels: PlaceLabels | None = None,
) -> Figure:
    """Draw home ``e``: floor plan, learnt regions, predicted positions and named poses.

    Parameters
    ----------
    params, e, vocabulary: the model, the home index and the corpus vocabulary.
    environment: the home (its samples, extent and ground-truth regions), or ``None``.
    ax: draw into these axes (default: a new 8×7 inch figure).
    map_image: floor-plan image (array or file path) drawn with ``imshow(extent=map_extent)``; a grey
        image (2-D, such as a ROS map's PGM) is drawn in grey.
    map_extent: ``(x_min, x_max, y_min, y_max)`` in metres covered by the image (default: the
        environment's extent).
    predicted_positions: name -> (P, 2 or 3) sampled positions, drawn as markers with a legend.
    poses: (n, 4) poses ``(x, y, sin θ, cos θ)`` drawn as arrows.
    pose_names: for each pose, its top names with probabilities — a
        :class:`~spco.model.prediction.NamePrediction` of those poses or lists of ``(word, p)``.
    concept_colors: one colour per concept (default: ``tab10``, or ``tab20`` for more than 10).
    show_ground_truth: outline and label the ground-truth rectangles (default: when no image).
    show_samples: draw the home's training positions as small grey dots.
    label_regions: write the places on the map: each of ``place_labels`` at its region, or without
        them the names that describe each region's concept, once, at its largest region.
    title: axes title (default: the home's name).
    path: save the figure there as PNG.
    place_labels: name -> (region, p(region | name)), where the robot's ``where`` goes for each place
        (``spco show`` passes :func:`spco.knowledge.places`' learnt names: the map's labels and
        ``where`` are one answer).

    Each learnt region that matters — at least :data:`NEGLIGIBLE_REGION` of the home's training
    samples (``region_counts``) — is a 95% ellipse of the x–y marginal of Σ, coloured by its most
    probable concept argmax_l π_{e,l,m} G_{e,l}, with its mean marked ``+``; the regions left out
    are counted in the legend. With ``label_regions`` each place is named once: where ``where`` goes
    for it (``place_labels``), or at its concept's largest region. The axes cover ``map_extent`` and
    every room outline drawn, in metres, with a scale bar.
    """
    fig, ax = _new_axes(ax, (8.0, 7.0))
    concept_colors = _concept_colors(concept_colors, params.n_concepts)
    extent = tuple(map_extent) if map_extent is not None else (
        environment.extent if environment is not None else None)
    if map_image is not None:
        _draw_floor_plan(ax, map_image, extent)
    if show_ground_truth is None:
        show_ground_truth = map_image is None
    gt = environment.ground_truth if environment is not None else None
    room_labels = []
    if show_ground_truth and gt is not None and gt.regions is not None:
        room_labels = _draw_rooms(ax, gt.regions, extent)
    if show_samples and environment is not None:
        xy = environment.positions[~environment.is_test, :2]
        ax.scatter(xy[:, 0], xy[:, 1], s=4, color="0.6", alpha=0.6, linewidths=0, zorder=2,
                   label="samples (robot positions)")

    centres = _draw_regions(ax, params, e, vocabulary, concept_colors, label_regions, place_labels)
    marker_points = [centres] if centres.size else []
    if predicted_positions:
        marker_points += _draw_predicted(ax, predicted_positions)

    # poses with their top names
    callouts: list[tuple[float, float, str]] = []
    if poses is not None:
        p = np.atleast_2d(np.asarray(poses, dtype=float))
        if p.shape[1] != 4:
            raise ConfigurationError(f"poses must have shape (n, 4), got {p.shape}")
        ax.quiver(p[:, 0], p[:, 1], p[:, 3], p[:, 2], angles="xy", scale_units="xy", scale=2.5,
                  width=0.006, color="crimson", zorder=6)
        marker_points.append(p[:, :2])
        if pose_names is not None:
            callouts = _pose_callouts(p, pose_names)

    if extent is not None:
        x0, x1, y0, y1 = extent
        if show_ground_truth and gt is not None and gt.regions is not None:  # no room clipped off
            for rects in gt.regions.places.values():
                for rx0, rx1, ry0, ry1 in rects:
                    x0, x1, y0, y1 = min(x0, rx0), max(x1, rx1), min(y0, ry0), max(y1, ry1)
        ax.set_xlim(x0, x1)
        ax.set_ylim(y0, y1)
    else:
        ax.autoscale_view()
    ax.set_aspect("equal")
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
    _scale_bar(ax)
    ax.set_title(title if title is not None else (environment.name if environment is not None
                                                  else f"home {e}"))
    handles, _ = ax.get_legend_handles_labels()
    if handles:
        ax.legend(loc="upper left", bbox_to_anchor=(1.01, 1.0), fontsize=8, frameon=False)
    if callouts:
        points = np.concatenate(marker_points) if marker_points else np.zeros((0, 2))
        _place_callouts(fig, ax, callouts, room_labels, points)
    _save(fig, path)
    return fig


#: A region with less than this share of the home's samples is not drawn by :func:`plot_home_map`.
NEGLIGIBLE_REGION = 0.01


def _scale_bar(ax: Axes) -> None:
    """A scale bar (1, 2, 5 … m: about a fifth of the axes' width) in the axes' lower right corner."""
    from mpl_toolkits.axes_grid1.anchored_artists import AnchoredSizeBar

    x0, x1 = ax.get_xlim()
    target = abs(x1 - x0) / 5
    length = next((s for s in (0.5, 1, 2, 5, 10, 20, 50, 100) if s >= target / 2), 100)
    ax.add_artist(AnchoredSizeBar(ax.transData, length, f"{length:g} m", "lower right", pad=0.4,
                                  color="0.15", frameon=True, size_vertical=abs(x1 - x0) / 200,
                                  fontproperties={"size": 8}))


def _label_regions(ax: Axes, used: np.ndarray, counts: np.ndarray, means: np.ndarray, owner: np.ndarray,
                   labels: Sequence[str], colours: Sequence[object]) -> None:
    """Write each place's names (its concept's words) once, at the centre of its largest region."""
    placed: set[str] = set()
    for m in sorted(used.tolist(), key=lambda k: -counts[k]):
        c = int(owner[m])
        words = labels[c].partition(": ")[2]
        centre = means[m, :2]
        if not words or words in placed:
            continue
        placed.add(words)
        ax.text(centre[0], centre[1], words.replace(", ", "\n"), fontsize=8, ha="center", va="bottom",
                color="0.1", zorder=4.6, clip_on=True,
                bbox={"boxstyle": "round,pad=0.2", "fc": "white", "ec": colours[c], "alpha": 0.8})


def _label_places(ax: Axes, place_labels: PlaceLabels, means: np.ndarray, owner: np.ndarray,
                  colours: Sequence[object]) -> None:
    """Write each place of ``place_labels`` (name -> (region, p(region | name)): where ``where`` goes
    for it) at the centre of its region, the places of one region together, most probable first."""
    by_region: dict[int, list[tuple[str, float]]] = {}
    for name, (region, p) in place_labels.items():
        by_region.setdefault(int(region), []).append((name, float(p)))
    for m, here in sorted(by_region.items()):
        here.sort(key=lambda item: -item[1])
        text = "\n".join(f"{name} {p:.2f}" for name, p in here)
        ax.text(means[m, 0], means[m, 1], text, fontsize=8, ha="center", va="bottom", color="0.1", zorder=4.6,
                clip_on=True, bbox={"boxstyle": "round,pad=0.2", "fc": "white", "ec": colours[int(owner[m])],
                                    "alpha": 0.8})


#: Offsets (points) tried for a callout, nearest first; 8 directions at each distance.
_CALLOUT_DISTANCES = (12.0, 24.0, 40.0, 60.0, 85.0)
_CALLOUT_DIRECTIONS = ((1, 1), (-1, 1), (1, -1), (-1, -1), (1, 0), (-1, 0), (0, 1), (0, -1))


def _place_callouts(fig: Figure, ax: Axes, callouts: Sequence[tuple[float, float, str]],
                    room_labels: Sequence[object], points: np.ndarray) -> None:
    """Put each pose's callout where it covers no room label, marker or earlier callout and stays
    inside the axes: the first free offset of :data:`_CALLOUT_DISTANCES` × :data:`_CALLOUT_DIRECTIONS`
    (directions towards the middle of the map first), or the one overlapping least.

    The layout is computed first and then frozen, so that the boxes measured are the ones drawn.
    """
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.transforms import Bbox

    if not isinstance(fig.canvas, FigureCanvasAgg):
        FigureCanvasAgg(fig)
    fig.draw_without_rendering()
    if fig.get_layout_engine() is not None:
        fig.set_layout_engine("none")  # freeze the positions measured below
    renderer = fig.canvas.get_renderer()
    frame = ax.get_window_extent(renderer)
    scale = fig.dpi / 72.0
    obstacles = [label.get_window_extent(renderer).padded(2 * scale) for label in room_labels]  # type: ignore[attr-defined]
    marker_size = 5.0 * scale
    for x, y in ax.transData.transform(points) if points.size else []:
        obstacles.append(Bbox.from_extents(x - marker_size, y - marker_size,
                                           x + marker_size, y + marker_size))
    x_mid, y_mid = frame.x0 + 0.5 * frame.width, frame.y0 + 0.5 * frame.height

    def cost(box: Bbox) -> float:
        outside = (max(frame.x0 - box.x0, 0) + max(box.x1 - frame.x1, 0) + max(frame.y0 - box.y0, 0)
                   + max(box.y1 - frame.y1, 0))
        overlap = 0.0
        for other in obstacles:
            w = min(box.x1, other.x1) - max(box.x0, other.x0)
            h = min(box.y1, other.y1) - max(box.y0, other.y0)
            if w > 0 and h > 0:
                overlap += w * h
        return 1e6 * outside + overlap

    for x, y, text in callouts:
        px, py = ax.transData.transform((x, y))
        towards = (1 if px < x_mid else -1, 1 if py < y_mid else -1)
        directions = sorted(_CALLOUT_DIRECTIONS, key=lambda d: -(d[0] * towards[0] + d[1] * towards[1]))
        best: tuple[float, object, Bbox] | None = None
        for distance in _CALLOUT_DISTANCES:
            for dx, dy in directions:
                callout = ax.annotate(
                    text, (x, y), xytext=(dx * distance, dy * distance), textcoords="offset points",
                    ha={1: "left", -1: "right", 0: "center"}[dx],
                    va={1: "bottom", -1: "top", 0: "center"}[dy],
                    fontsize=7, zorder=7,
                    bbox={"boxstyle": "round,pad=0.3", "fc": "white", "ec": "crimson", "alpha": 0.85},
                    arrowprops={"arrowstyle": "-", "color": "crimson", "lw": 0.6})
                # the box around the text, sized and placed as drawing it would, without rendering
                # the text and clipping the arrow for every candidate (most of a map's time)
                callout.update_positions(renderer)
                callout.update_bbox_position_size(renderer)
                box = callout.get_bbox_patch().get_window_extent(renderer).padded(1.5 * scale)
                score = cost(box)
                if best is None or score < best[0]:
                    if best is not None:
                        best[1].remove()  # type: ignore[attr-defined]
                    best = (score, callout, box)
                else:
                    callout.remove()
                if score == 0.0:
                    break
            if best is not None and best[0] == 0.0:
                break
        assert best is not None
        obstacles.append(best[2])


@_with_cjk_fonts
def plot_accuracy_curve(
    settings: Sequence[float],
    means: Sequence[float] | Mapping[str, Sequence[float]],
    stds: Sequence[float] | Mapping[str, Sequence[float]] | None,
    chance: float | None,
    xlabel: str,
    title: str,
    path: PathLike | None = None,
    ylabel: str = "accuracy",
) -> Figure:
    """Accuracy against a setting (number of experienced homes, teaching rate), mean ± std bands.

    Parameters
    ----------
    settings: (S,) the x values.
    means: (S,) one curve, or method name -> (S,) several curves.
    stds: the same shape as ``means`` (or ``None`` for no band).
    chance: the chance level, drawn as a dashed line (``None``: not drawn).
    """
    x = np.asarray(settings, dtype=float)
    curves = dict(means) if isinstance(means, Mapping) else {"": means}
    if stds is None:
        spreads: dict[str, Sequence[float] | None] = dict.fromkeys(curves)
    elif isinstance(stds, Mapping):
        spreads = {k: stds.get(k) for k in curves}
    else:
        spreads = {k: stds for k in curves}
    fig, ax = _new_axes(None, (6.0, 4.0))
    for i, (label, mean) in enumerate(curves.items()):
        m = np.asarray(mean, dtype=float)
        if m.shape != x.shape:
            raise ConfigurationError(f"curve {label!r} has {m.size} values for {x.size} settings")
        line = ax.plot(x, m, marker=_MARKERS[i % len(_MARKERS)], label=label or None)[0]
        if spreads[label] is not None:
            s = np.asarray(spreads[label], dtype=float)
            ax.fill_between(x, m - s, m + s, color=line.get_color(), alpha=0.2, linewidth=0)
    if chance is not None:
        ax.axhline(chance, color="0.3", linestyle="--", linewidth=1.0, label="chance")
    ax.set_xlabel(xlabel)
    ax.set_ylabel(ylabel)
    ax.set_title(title)
    ax.set_ylim(0.0, 1.02)
    ax.set_xticks(x)
    ax.grid(alpha=0.3)
    if ax.get_legend_handles_labels()[0]:
        ax.legend(fontsize=8)
    _save(fig, path)
    return fig


@_with_cjk_fonts
def plot_log_joint(
    trace: Sequence[float] | np.ndarray | Mapping[str, Sequence[float]],
    path: PathLike | None = None,
    title: str = "log joint probability",
) -> Figure:
    """The sampler's log joint probability per iteration.

    ``trace``: (T,) one chain, (C, T) several chains, or label -> (T,) traces.
    """
    if isinstance(trace, Mapping):
        chains = {k: np.asarray(v, dtype=float).ravel() for k, v in trace.items()}
    else:
        arr = np.asarray(trace, dtype=float)
        if arr.ndim == 1:
            chains = {"": arr}
        elif arr.ndim == 2:
            chains = {f"chain {i}": row for i, row in enumerate(arr)}
        else:
            raise ConfigurationError(f"trace must be 1-D or 2-D, got shape {arr.shape}")
    fig, ax = _new_axes(None, (6.0, 3.5))
    for label, values in chains.items():
        ax.plot(np.arange(1, values.size + 1), values, linewidth=1.0, label=label or None)
    ax.set_xlabel("iteration")
    ax.set_ylabel("log p(data, parameters)")
    ax.set_title(title)
    ax.grid(alpha=0.3)
    if ax.get_legend_handles_labels()[0]:
        ax.legend(fontsize=8)
    _save(fig, path)
    return fig
