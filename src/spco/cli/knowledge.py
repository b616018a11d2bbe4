"""``spco fit | adapt | where | what | teach``: knowledge that travels, from the command line.

Learn once from experienced homes (``fit`` writes a knowledge file), adapt to a new home in
seconds (``adapt`` writes a home file), ask the robot (``where``, ``what``) and teach it more
(``teach``); ``spco show`` (:mod:`spco.cli.show`) draws what it knows. See :mod:`spco.knowledge`
for the model and the file formats.

Registered in :mod:`spco.cli.main` (``for command in KNOWLEDGE_COMMANDS: main.add_command(command)``).
Heavy imports happen when a command runs, so ``spco --help`` stays fast; spco's errors are
reported by the command line's ``_friendly_errors`` (one line, exit status 2).
"""

from __future__ import annotations

import json
import sys
import time
from collections import Counter
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import click

from spco.cli.common import check_out, load_home, settings_hyperparameters
from spco.cli.errors import friendly_errors

__all__ = ["KNOWLEDGE_COMMANDS", "adapt", "fit", "teach", "what", "where"]

_MODEL_NAMES = ("spcotransfer+mi", "spcotransfer", "spcotransfer-ref+mi", "spcotransfer-ref")


_friendly = friendly_errors


def _progress() -> bool:
    return sys.stderr.isatty()


def _precompile_if_cold() -> None:
    """On an empty kernel cache, say so and compile the kernels in 2 processes at once
    (:func:`spco.model.precompile.precompile_if_cold`): about 20 s instead of 30 on 2 cores."""
    from spco.model.precompile import precompile_if_cold

    precompile_if_cold(lambda text: click.echo(text, err=True))


def _names(text: str | None) -> list[str] | None:
    if text is None:
        return None
    names = [n.strip() for n in text.split(",") if n.strip()]
    if not names:
        from spco.errors import ConfigurationError

        raise ConfigurationError("--homes lists no home; give comma-separated home names")
    return names


def _image_options(func: Any) -> Any:
    """--images and --model: views as images (fit, adapt)."""
    func = click.option("--onnx-model", "model_file", type=click.Path(path_type=Path), default=None,
                        help="The .onnx network of the onnx extractor (fit: with --extractor onnx; adapt: "
                             "where the knowledge's model file is now).")(func)
    return click.option("--images", type=click.Path(path_type=Path), default=None,
                        help="Folder of the homes' camera images, <home>/<id>.jpg|png (e.g. "
                             "sigverse_images), "
                             "used as the views in place of the homes' visual counts.")(func)


class _Encodings(click.Choice):
    """The colour orders of a pixel array given with --image (:data:`spco.features.pixels.RAW_ENCODINGS`),
    read when the command's help is shown or it runs, not when it is registered (``spco --help``
    imports no array library)."""

    def __init__(self) -> None:  # the choices are a property: nothing to store
        self.case_sensitive = True

    @property  # type: ignore[override]
    def choices(self) -> tuple[str, ...]:
        from spco.features.pixels import RAW_ENCODINGS

        return tuple(RAW_ENCODINGS)


def _view_options(view: str) -> Any:
    """--visual, --visual-scale, --image, --encoding and --onnx-model: the view of what and teach
    (``view``: what the view is, e.g. "The current view"), read by :func:`_view_counts`."""
    options = [
        click.option("--visual", type=click.Path(path_type=Path), default=None,
                     help=f"{view}'s features (.csv/.txt numbers, .npy or .npz); default: position only."),
        click.option("--visual-scale", type=float, default=None,
                     help="Turn real-valued CNN features into counts: floor(max(f, 0) × scale) (the "
                          "authors: 5)."),
        click.option("--image", type=click.Path(path_type=Path), default=None,
                     help=f"{view} as a camera image (PNG/JPEG, or a .npy array of pixels: see --encoding), "
                          "for knowledge fitted on images."),
        click.option("--encoding", type=_Encodings(), default=None,
                     help="The colour order of an --image .npy array: rgb8 (PIL, matplotlib, cv_bridge "
                          "rgb8), bgr8 (OpenCV; the default), mono8, rgba8, bgra8."),
        click.option("--onnx-model", "model_file", type=click.Path(path_type=Path), default=None,
                     help="Where the knowledge's .onnx model file is now (onnx extractor), if it moved."),
    ]

    def add(command: Any) -> Any:
        for option in reversed(options):
            command = option(command)
        return command

    return add


def _pixels(image: Path, encoding: str | None) -> Any:
    """--image as the extractor takes it: a .npy array of pixels (with --encoding), or the file's path."""
    import numpy as np

    from spco.errors import ConfigurationError, DataFormatError

    if image.suffix.lower() != ".npy":
        if encoding is not None:
            raise ConfigurationError(f"--encoding is the colour order of a .npy array of pixels; {image} "
                                     "carries its own")
        return image
    try:
        return np.load(image, allow_pickle=False)
    except (OSError, ValueError) as exc:
        raise DataFormatError(image, f"not a readable .npy array of pixels ({exc})") from None


def _view_counts(home: Any, knowledge_file: Path, visual: Path | None, image: Path | None,
                 visual_scale: float | None, model: Path | None, encoding: str | None = None) -> Any:
    """The view's counts for what/teach (:func:`spco.knowledge.views.view_counts`): --visual features
    read from their file, or --image (a file, or a .npy array of pixels in --encoding) through the
    knowledge's extractor (its --model file); --visual is refused for knowledge fitted on images."""
    from spco.errors import ConfigurationError
    from spco.knowledge import read_visual_vector, view_counts

    knowledge = home.knowledge
    if visual is not None and image is None:
        if knowledge.fitted_on_images:
            from spco.features import ExtractorSpec

            raise ConfigurationError(f"{knowledge_file}: its knowledge was fitted on images (extractor "
                                     f"{ExtractorSpec.from_dict(knowledge.extractor).describe()}): give the "
                                     "view as --image, not as --visual features")
        visual = read_visual_vector(visual, knowledge.n_features, visual_scale)
    elif image is not None and visual is None:
        image = _pixels(image, encoding)
    return view_counts(knowledge, visual, image, encoding,
                       extractor=lambda: knowledge.image_extractor(model_path=model))


def _seconds(value: float) -> str:
    return f"{value * 1000:.0f} ms" if value < 1 else f"{value:.1f} s"


# ------------------------------------------------------------------------------------ fit
def _on_the_prior(training: Any, prior: str, settings: tuple[str, ...], checked: Any) -> Any:
    """``--set`` applied on top of the scaled prior of ``training`` (``checked``: the settings on the
    paper's constants, checked before the homes were read; kept for ``--prior paper``). A ``nu0``
    setting is the scaled Ψ0's weight: Ψ0 is scaled with it, so E[Σ] stays the places' size."""
    if not settings or prior == "paper":
        return checked
    from spco.knowledge.fit import default_hyperparameters
    from spco.model.hyperparameters import TransferHyperparameters

    nu0 = [s for s in settings if s.partition("=")[0].strip() == "nu0"]
    base = TransferHyperparameters().with_settings(nu0) if nu0 else None
    return default_hyperparameters(training, base, psi0=prior == "places").with_settings(settings)


@click.command(name="fit")
@click.option("--data", "data", required=True, type=click.Path(path_type=Path),
              help="The experienced homes: a folder of homes (SIGVerse or plain layout) or an "
                   "`spco import` cache file.")
@click.option("--homes", default=None,
              help="Comma-separated names of the homes to learn from (default: every home in --data).")
@click.option("--teaching-rate", "-r", default=100, show_default=True, type=click.IntRange(0, 100),
              help="Percentage of taught samples to use in each home.")
@click.option("--model", default="spcotransfer+mi", show_default=True, type=click.Choice(_MODEL_NAMES),
              help="The transfer model (exact or the authors' reference sampler, with or without "
                   "mutual-information word pruning).")
@click.option("--iterations", default=200, show_default=True, type=click.IntRange(1),
              help="Gibbs sweeps.")
@click.option("--seed", default=0, show_default=True, type=click.IntRange(0), help="Random seed.")
@click.option("--out", "-o", required=True, type=click.Path(path_type=Path),
              help="The knowledge file to write (e.g. knowledge.spco).")
@click.option("--force", is_flag=True, help="Replace --out if it exists.")
@click.option("--engine", default="local", show_default=True, type=click.Choice(["local", "ray"]),
              help="Where the homes' shards run: this process, or Ray actors (pip install 'spco[ray]').")
@click.option("--shards", default=None, type=click.IntRange(1),
              help="Home shards (default: 1 with the local engine, 2 with Ray). The same seed and "
                   "shards give the same result on either engine.")
@click.option("--address", default=None,
              help="The Ray cluster to join (e.g. 'auto' or HOST:PORT; default: start Ray locally).")
@click.option("--checkpoint-every", default=10, show_default=True, type=click.IntRange(1),
              help="Ray engine: sweeps between checkpoints (a lost actor restarts from the last one).")
@click.option("--checkpoint-dir", default=None, type=click.Path(file_okay=False, path_type=Path),
              help="Ray engine: keep the checkpoints in this directory (each actor writes its own "
                   "shard's file) instead of the driver's memory; on a cluster, shared storage.")
@_image_options
@click.option("--extractor", default=None,
              help="Image extractor when the views are images (default: colour-hog; bovw-orb, bovw-sift "
                   "learn their codebook here, from the homes' training images; onnx needs --onnx-model).")
@click.option("--set", "settings", multiple=True, metavar="NAME=VALUE",
              help="A hyperparameter of the model instead of the paper's value (repeatable): n_concepts, "
                   "n_regions, kappa0, nu0, alpha_visual, alpha_word, delta_visual, delta_word, gamma, "
                   "gamma0, "
                   "beta, mi_threshold, view_counts (a view's weight w, default 16; none: every count a "
                   "draw; estimate: learnt from the homes), warm_start (things, the "
                   "default; names or words: the start of a fit that learns its words with the word "
                   "channels), place_channel (shared or home: the place words one vocabulary per "
                   "concept, or each home's own around it; delta_place its concentration), and the answer's "
                   "name_answer (said or listener), view_in_room (true: the view as a draw of its room) "
                   "and typical (off, ρ within (0, 1] or learn: ρ learnt from the homes' place labels). "
                   "E.g. a large floor: --set n_concepts=30 --set n_regions=30 --set kappa0=0.001. "
                   "Kept in the knowledge file.")
@click.option("--prior", default="places", show_default=True,
              type=click.Choice(["scaled", "places", "paper"]),
              help="places: the position prior's κ0 and the numbers of concepts and regions follow the "
                   "homes' spread and place sizes (a flat or a university floor, in any map units), "
                   "and Ψ0 the places' size; scaled: the same with the paper's Ψ0; paper: the paper's "
                   "constants (Ψ0 = diag(10 cm², 10 cm², 0.5, 0.5), κ0 = 0.05, L = 15, K = 20), for the "
                   "reproduction. --set applies on top (nu0 with places: Ψ0 is scaled with it).")
@click.option("--text-language", default="auto", show_default=True,
              type=click.Choice(["auto", "ja", "zh", "spaced"]),
              help="Japanese or Chinese written without spaces: segment it into words (ja: pip install "
                   "'spco[ja]', zh: 'spco[zh]'), decide from the text (auto), or never (spaced: the words "
                   "are separated by spaces). Recorded in the knowledge file for adapt, teach, what, where.")
@_friendly
def fit(data: Path, homes: str | None, teaching_rate: int, model: str, iterations: int, seed: int,
        out: Path, force: bool, engine: str, shards: int | None, address: str | None, checkpoint_every: int,
        checkpoint_dir: Path | None, images: Path | None, model_file: Path | None,
        extractor: str | None, settings: tuple[str, ...], text_language: str, prior: str) -> None:
    """Learn knowledge from experienced homes and write a knowledge file.

    The knowledge is the shared, home-independent part of the transfer model — the concepts'
    visual and word distributions, their global weights, the vocabulary, the hyperparameters —
    averaged over the posterior samples of the last quarter of the chain, with its provenance.
    Give it to `spco adapt` to learn a new home. Homes whose views are images (a plain home's
    images/, or --images) are turned into counts by an image extractor, which the knowledge file
    keeps, so that adapt, teach and what compute views the same way.
    """
    from spco.data.environment import Corpus
    from spco.data.loading import load_homes, views_are_images
    from spco.engines import make_engine
    from spco.knowledge import fit_knowledge

    check_out(out, force)
    hyperparameters = settings_hyperparameters(settings)
    _precompile_if_cold()
    if engine == "ray":
        try:
            import ray  # noqa: F401
        except ImportError:
            raise click.UsageError("--engine ray needs Ray: pip install 'spco[ray]'") from None
    elif address is not None:
        raise click.UsageError("--address is for --engine ray")
    elif checkpoint_dir is not None:
        raise click.UsageError("--checkpoint-dir is for --engine ray")
    runner = make_engine(engine, shards, address, checkpoint_every,
                         None if checkpoint_dir is None else str(checkpoint_dir))
    names = _names(homes)
    image_extractor = None
    if images is not None or extractor is not None or model_file is not None \
            or views_are_images(Path(data)):
        image_extractor = _fit_extractor(data, names, images, extractor, model_file, seed)
    if image_extractor is None and Path(data).is_dir() and (engine == "ray" or (shards or 1) > 1):
        # the shards read their own homes: the driver reads one home at a time for the vocabulary
        from spco.model.sources import FolderHomes

        training: Corpus | FolderHomes = FolderHomes.create(data, names, teaching_rate, progress=_progress(),
                                                            language=text_language)
        summary = (f"{training.n_homes} homes ({training.n_samples} training samples, {training.n_taught} "
                   f"taught, {training.n_words} words; each shard reads its own homes)")
    else:
        start_views = time.perf_counter()
        envs = load_homes(data, names=names, teaching_rate=teaching_rate, progress=_progress(),
                          extractor=image_extractor, images=images)
        if image_extractor is not None:
            n_views = sum(e.n_samples for e in envs)
            seconds = time.perf_counter() - start_views
            click.echo(f"Views from {n_views} images with {image_extractor.spec().describe()}: "
                       f"{n_views / max(seconds, 1e-9):.0f} images/s (reading the homes included)", err=True)
        training = Corpus(envs, language=text_language)
        summary = (f"{len(envs)} homes ({sum(e.n_train for e in envs)} training samples, "
                   f"{sum(e.n_taught for e in envs)} taught, {len(training.vocabulary)} words)")
    hyperparameters = _on_the_prior(training, prior, settings, hyperparameters)
    click.echo(f"Learning from {summary} with {model}, {iterations} sweeps...", err=True)
    start = time.perf_counter()
    knowledge = fit_knowledge(training, model=model, n_iterations=iterations, random_state=seed,
                              hyperparameters=hyperparameters, progress=_progress(), engine=runner,
                              prior=prior,
                              provenance={"data": str(Path(data).expanduser().resolve()),
                                          "teaching_rate": teaching_rate},
                              extractor=image_extractor)
    knowledge.save(out, overwrite=force)
    click.echo(knowledge.describe())
    click.echo(f"Wrote {out} in {_seconds(time.perf_counter() - start)}.")


def _fit_extractor(data: Path, names: list[str] | None, images: Path | None, name: str | None,
                   model_file: Path | None, seed: int) -> Any:
    """The image extractor of ``spco fit``; a codebook is learnt from the homes' training images."""
    from spco.data.loading import training_image_files
    from spco.features import DEFAULT_EXTRACTOR, build_extractor

    chosen = name or ("onnx" if model_file is not None else DEFAULT_EXTRACTOR)
    extractor = build_extractor(chosen, model_path=None if model_file is None else str(model_file))
    if extractor.needs_fit:
        files = training_image_files(data, names, images)
        click.echo(f"Learning the {chosen} codebook from {len(files)} training images (seed {seed})...",
                   err=True)
        extractor = extractor.fitted(files, random_state=seed)
    return extractor


# ------------------------------------------------------------------------------------ adapt
@click.command(name="adapt")
@click.argument("knowledge_file", metavar="KNOWLEDGE", type=click.Path(path_type=Path))
@click.option("--home", "home_path", required=True, type=click.Path(path_type=Path),
              help="The new home: a home folder (SIGVerse or plain layout), or a folder/cache with --name.")
@click.option("--name", default=None, help="Which home of --home to use when it holds several.")
@click.option("--teaching-rate", "-r", default=100, show_default=True, type=click.IntRange(0, 100),
              help="Percentage of the home's taught samples to use (a new home may have none).")
@click.option("--iterations", default=100, show_default=True, type=click.IntRange(1), help="Gibbs sweeps.")
@click.option("--seed", default=0, show_default=True, type=click.IntRange(0), help="Random seed.")
@click.option("--joint", is_flag=True,
              help="Refine the shared part too, with the knowledge as its prior (default: keep it fixed).")
@click.option("--out", "-o", required=True, type=click.Path(path_type=Path),
              help="The home file to write (e.g. home.spco).")
@click.option("--force", is_flag=True, help="Replace --out if it exists.")
@click.option("--set", "settings", multiple=True, metavar="NAME=VALUE",
              help="Set an answer's hyperparameter for this home (repeatable): name_answer, view_in_room "
                   "(true/false) or typical (off or ρ within (0, 1]); they change how the home answers, not "
                   "its fit. The fit's settings are the knowledge's (spco fit --set).")
@_image_options
@_friendly
def adapt(knowledge_file: Path, home_path: Path, name: str | None, teaching_rate: int, iterations: int,
          seed: int, joint: bool, out: Path, force: bool, settings: tuple[str, ...], images: Path | None,
          model_file: Path | None) -> None:
    """Learn a new home with the knowledge of KNOWLEDGE as its prior; write a home file.

    Learns the home's regions, concept weights, visual and word distributions and the concepts
    and regions of its samples. Words the knowledge never heard are added to the vocabulary.
    """
    from spco.data.loading import load_home, load_homes, views_are_images
    from spco.errors import ConfigurationError
    from spco.knowledge import adapt as adapt_home
    from spco.knowledge import load_knowledge

    check_out(out, force)
    knowledge = load_knowledge(knowledge_file)
    if settings:
        from dataclasses import replace

        from spco.model.answer_settings import with_answer_settings

        try:
            hyper = with_answer_settings(knowledge.hyperparameters, list(settings))
        except ConfigurationError as exc:
            raise click.BadParameter(str(exc), param_hint="--set") from None
        knowledge = replace(knowledge, hyperparameters=hyper)
    _precompile_if_cold()
    extractor = None
    if knowledge.fitted_on_images:
        extractor = knowledge.image_extractor(model_path=model_file)
    elif images is not None or views_are_images(Path(home_path)):
        raise ConfigurationError(f"{knowledge_file}: its knowledge was fitted on visual count vectors, "
                                 "not on images, so it cannot use a home whose views are images: fit a "
                                 "knowledge on homes with images (spco fit), or give the home's visual.npz")
    if name is not None:
        env = load_homes(home_path, names=[name], teaching_rate=teaching_rate, extractor=extractor,
                         images=images)[0]
    else:
        env = load_home(home_path, teaching_rate=teaching_rate, extractor=extractor, images=images)
    home = adapt_home(knowledge, env, n_iterations=iterations, random_state=seed, joint=joint,
                      progress=_progress(),
                      provenance={"knowledge_file": str(Path(knowledge_file).expanduser().resolve()),
                                  "home_path": str(Path(home_path).expanduser().resolve()),
                                  "teaching_rate": teaching_rate})
    home.save(out, overwrite=force)
    seconds = home.provenance["adapt"]["seconds"]
    click.echo(home.describe())
    view = home.provenance.get("view_fit")
    if view and view.get("value") is not None and view.get("experienced_range"):
        from spco.knowledge import fit_range_text

        click.echo(f"The knowledge explains this home's views by {view['value']:.2f} nats per count better "
                   f"than a uniform guess (experienced homes: {fit_range_text(view['experienced_range'])}); "
                   f"{'it fits' if view['fits'] else 'IT DOES NOT FIT (see the warning)'}.")
    new_words = home.provenance["adapt"]["new_words"]
    if new_words:
        click.echo(f"New words learnt in this home: {', '.join(new_words)}")
    click.echo(f"Adapted in {_seconds(seconds)} ({iterations} sweeps); wrote {out}.")


# ------------------------------------------------------------------------------------ where
@click.command(name="where")
@click.argument("home_file", metavar="HOME", type=click.Path(path_type=Path))
@click.argument("name")
@click.option("--n", "-n", "n", default=10, show_default=True, type=click.IntRange(1, 10000),
              help="Number of positions.")
@click.option("--seed", default=0, show_default=True, type=click.IntRange(0), help="Random seed.")
@click.option("--json", "as_json", is_flag=True,
              help="Print a JSON object whose `positions` lists {x, y, theta, probability}.")
@_friendly
def where(home_file: Path, name: str, n: int, seed: int, as_json: bool) -> None:
    """Positions (x, y, θ) to go to for the place NAME in the home of HOME.

    Draws N poses from the regions at least half as probable for NAME as the most probable one, in
    proportion to their probability (a name taught at two places finds both); each pose's
    probability is its share of the density p(pose | NAME) among the N poses. A name the robot never
    heard is looked up in WordNet (with spco[words] and Debian's wordnet-base) and answered for the
    known name it stands for ("restroom -> toilet"); if none is found, it is answered with the names
    the robot knows (exit status 2).
    """
    from spco.service.answers import where_answer

    home = load_home(home_file)
    _warn_if_knowledge_does_not_fit(home)
    answer = where_answer(home, name, n=n, seed=seed)
    positions = answer["positions"]
    if as_json:
        click.echo(json.dumps(answer, indent=1))
        return
    name = answer["name"]
    if not answer["learnt"]:
        there = (f"the poses below are at the place that looks most like a {name} of the experienced homes, "
                 f"which `what` calls {answer['called']!r} here" if answer.get("called") else
                 f"the poses below are at the place that looks most like a {name} of the experienced homes")
        click.echo(f"warning: no such place learnt in this home: nobody said {name!r} here and only "
                   f"{answer['support']:.0%} of its probability comes from concepts holding the home's "
                   f"samples; {there} — a guess (teach it to make it sure)", err=True)
    if answer["via"] is not None:  # a name nobody said, found through the lexicon
        from spco.model.unheard import PLACE_WORD, SAID_WORDS

        via = str(answer["via"])
        how = ("its words this home says, the kinds of place left out" if via == SAID_WORDS
               else f"a word said at a place here, {via.removeprefix(PLACE_WORD).strip()} in WordNet"
               if via.startswith(PLACE_WORD) else f"{via} in WordNet")
        click.echo(f"{answer['asked']} -> {name} (never said in this home; {how})")
    click.echo(f"{name} in home {home.name}: region {answer['region']} of the home's map, "
               f"p(region | {name}) = {answer['region_probability']:.2f} (the most probable "
               f"region; the rest is spread over others)")
    # the regions the answer's poses were drawn from (the same draws: same home, name, n and seed)
    from spco.knowledge import where as where_name

    pred = where_name(home, name, n=n, random_state=seed)
    order = sorted(range(pred.samples.shape[0]), key=lambda i: -float(pred.weights[i]))
    regions = [int(pred.regions[i]) for i in order]
    click.echo(_where_drawn_from(regions, name))
    several = len(set(regions)) > 1
    click.echo(f"{'x':>8} {'y':>8} {'theta':>7}  probability" + ("  region" if several else ""))
    for region, p in zip(regions, positions, strict=True):
        click.echo(f"{p['x']:8.3f} {p['y']:8.3f} {p['theta']:7.3f}  {p['probability']:.3f}"
                   + (f"        {region:>6}" if several else ""))


def _where_drawn_from(regions: Sequence[int], name: str) -> str:
    """The line of ``spco where`` that says which regions its poses were drawn from."""
    share = f"probability: each pose's share of p(pose | {name}) among them"
    counts = Counter(int(r) for r in regions)
    if len(counts) == 1:
        return f"{len(regions)} poses drawn from the region's Gaussian; {share}"
    parts = ", ".join(f"region {r}: {c}" for r, c in counts.most_common())
    return (f"{len(regions)} poses drawn from {len(counts)} regions in proportion to p(region | {name}) "
            f"({parts}); {share}")


# ------------------------------------------------------------------------------------ what
@click.command(name="what")
@click.argument("home_file", metavar="HOME", type=click.Path(path_type=Path))
@click.option("--x", "x", required=True, type=float, help="x on the map, metres.")
@click.option("--y", "y", required=True, type=float, help="y on the map, metres.")
@click.option("--theta", "theta", required=True, type=float, help="Heading, radians.")
@_view_options("The current view")
@click.option("--top", default=3, show_default=True, type=click.IntRange(1, 100), help="Names to list.")
@click.option("--unsure-below", default=None, type=click.FloatRange(0.0, 1.0),
              help="Say the robot is unsure when the best name's probability p is below this "
                   "(default 0.7, spco.model.confidence.UNSURE_BELOW).")
@click.option("--json", "as_json", is_flag=True, help="Print a JSON object.")
@_friendly
def what(home_file: Path, x: float, y: float, theta: float, visual: Path | None, visual_scale: float | None,
         image: Path | None, encoding: str | None, model_file: Path | None, top: int,
         unsure_below: float | None, as_json: bool) -> None:
    """The most probable place names at a pose of the home of HOME, with their probabilities.

    With --visual (or --image) the view is used too; without, the position alone. Names are ranked
    by a score, printed as a share of its sum over the usable names beside `p` = p(name | pose, view)
    itself (its sum over all words, template words included, is 1): with the default model
    (spcotransfer+mi: the word channels, or the naming rule for speech without English function
    words) the score is p over the home's names — never a word said as an object or a function word;
    without pruning it is p × I(name), I the name's mutual
    information with the concepts (so that "this" or "is", said everywhere, are never answered); the
    output's last line says which. A pose off the home's map is answered with a warning, one far off it is
    refused.

    p is honest: a view counts as a few independent draws, not as its thousands of counts, and a
    concept nobody named has no name (docs/model.md, "Confidence"). When the best name's p is below
    --unsure-below (default 0.7, the one threshold of what and ask) the answer says the robot is unsure
    (JSON: "unsure": true).
    """
    from spco.knowledge.requests import Pose, View, What
    from spco.model.confidence import UNSURE_BELOW
    from spco.service.answers import what_answer

    unsure_below = UNSURE_BELOW if unsure_below is None else unsure_below
    pose = Pose(x, y, theta)  # checked before the home is read
    home = load_home(home_file)
    _warn_if_knowledge_does_not_fit(home)
    counts = _view_counts(home, home_file, visual, image, visual_scale, model_file, encoding)
    request = What(pose, None if counts is None else View(visual=counts), top)
    answer = what_answer(home, request, unsure_below=unsure_below)
    names = answer["names"]
    if "warning" in answer:
        click.echo(f"warning: {answer['warning']}", err=True)
    if as_json:
        click.echo(json.dumps(answer, indent=1))
        return
    click.echo(f"At ({x:g}, {y:g}, θ={theta:g}) in home {home.name} "
               f"({'position and view' if counts is not None else 'position only'}), ranked by score:")
    if not names:
        click.echo("  the robot knows no place names yet (nothing was taught); teach it with `spco teach`")
        return
    width = max(max(len(n["name"]) for n in names), len("name"))
    click.echo(f"     {'name':<{width}}  score      p")
    for rank, n in enumerate(names, 1):
        click.echo(f"  {rank}. {n['name']:<{width}}  {n['score_share']:.3f}  {n['probability']:.3f}")
    click.echo(f"score: {answer['ranked_by']}, as a share of its sum over the usable names; "
               f"p: p(name | {'pose, view' if counts is not None else 'pose'}) over all words")
    if answer["unsure"]:
        click.echo(f"unsure: the best name, {names[0]['name']!r}, has p = {names[0]['probability']:.3f} "
                   f"< {unsure_below:g}; ask what this place is called (spco teach)")


def _warn_if_knowledge_does_not_fit(home: Any) -> None:
    """One ``warning:`` line when ``adapt`` found that the knowledge does not fit the home's views."""
    from spco.knowledge import view_fit_warning

    view = home.provenance.get("view_fit")
    if view and not view.get("fits", True):
        click.echo(f"warning: {view_fit_warning(home.name, view)}", err=True)


# ------------------------------------------------------------------------------------ teach
@click.command(name="teach")
@click.argument("home_file", metavar="HOME", type=click.Path(path_type=Path))
@click.option("--id", "ids", type=int, multiple=True,
              help="A sample of the home to (re)name; repeat with --sentence for several.")
@click.option("--sentence", "sentences", multiple=True,
              help="What the user said there (\"\" forgets the sample's sentence).")
@click.option("--x", "x", type=float, default=None, help="New observation: x on the map, metres.")
@click.option("--y", "y", type=float, default=None, help="New observation: y, metres.")
@click.option("--theta", "theta", type=float, default=None, help="New observation: heading, radians.")
@_view_options("New observation: the view")
@click.option("--sweeps", default=10, show_default=True, type=click.IntRange(0, 10000),
              help="Gibbs sweeps from the home's current state.")
@click.option("--seed", default=0, show_default=True, type=click.IntRange(0), help="Random seed.")
@click.option("--out", "-o", type=click.Path(path_type=Path), default=None,
              help="Write the updated home here instead of updating HOME in place.")
@click.option("--force", is_flag=True, help="Replace --out if it exists.")
@_friendly
def teach(home_file: Path, ids: Sequence[int], sentences: Sequence[str], x: float | None, y: float | None,
          theta: float | None, visual: Path | None, visual_scale: float | None, image: Path | None,
          encoding: str | None, model_file: Path | None, sweeps: int, seed: int, out: Path | None,
          force: bool) -> None:
    """Teach the robot in the home of HOME: a sentence for a sample, or a new observation.

    \b
    spco teach home.spco --id 12 --sentence "this is Emma's room"
    spco teach home.spco --x 1.2 --y -0.4 --theta 1.57 --visual view.csv --sentence "the study is here"
    spco teach home.spco --x 1.2 --y -0.4 --theta 1.57 --image view.jpg --sentence "the study is here"
    spco teach home.spco --x 1.2 --y -0.4 --theta 1.57 --sentence "the study is here"   (no view)

    An incremental update (a few sweeps from the current state; everything learnt so far is
    kept); new words grow the vocabulary. HOME is updated in place (atomically) unless --out is given.
    The file is locked while it is read, updated and replaced: concurrent `teach` runs on the same
    home wait for each other (at most $SPCO_LOCK_TIMEOUT seconds, default 60) and every teaching is kept.
    """
    from spco.errors import ConfigurationError
    from spco.knowledge import Observation
    from spco.knowledge import teach as teach_home
    from spco.knowledge.locking import locked

    pose = (x, y, theta)
    new_observation = any(v is not None for v in (*pose, visual, image))
    if new_observation:
        if ids:
            raise ConfigurationError("give either --id with --sentence (a known sample) or --x/--y/--theta/"
                                     "--visual or --image (a new observation), not both")
        if any(v is None for v in pose):
            raise ConfigurationError("a new observation needs --x, --y and --theta (and its view as --visual "
                                     "or --image, if the camera saw it)")
        if len(sentences) > 1:
            raise ConfigurationError("a new observation takes at most one --sentence")
    elif not ids:
        raise ConfigurationError("nothing to teach: give --id ID --sentence TEXT, or a new observation "
                                 "(--x, --y, --theta, --visual)")
    elif len(ids) != len(sentences):
        raise ConfigurationError(f"{len(ids)} --id but {len(sentences)} --sentence: give one sentence per id")
    target = out if out is not None else home_file
    if out is not None:
        check_out(out, force)
    _precompile_if_cold()  # before the lock: a concurrent teach does not wait for the compilation
    # read, update and replace under the file's write lock: a concurrent `teach` waits, then
    # builds on this one's result (no teaching is lost)
    with locked(target):
        home = load_home(home_file)  # with the teachings of a journal its server left (spco serve)
        if new_observation:
            counts = _view_counts(home, home_file, visual, image, visual_scale, model_file, encoding)
            obs = Observation(x=x, y=y, theta=theta, visual=counts,  # type: ignore[arg-type]
                              sentence=sentences[0] if sentences else None)
            updated = teach_home(home, observations=[obs], n_sweeps=sweeps, random_state=seed)
        else:
            updated = teach_home(home, dict(zip(ids, sentences, strict=True)), n_sweeps=sweeps,
                                 random_state=seed)
        updated.save(target, overwrite=True if out is None else force)
    last = updated.provenance["last_teach"]
    if new_observation:
        click.echo(f"Added sample {int(updated.ids[-1])} at ({x:g}, {y:g}, θ={theta:g})"
                   + ("" if visual is not None or image is not None else " without a view")
                   + (f": {sentences[0]!r}" if sentences and sentences[0].strip() else ""))
    else:
        for i, s in zip(ids, sentences, strict=True):
            click.echo(f"Sample {i}: {s!r}" if s.strip() else f"Sample {i}: sentence forgotten")
    if last["new_words"]:
        click.echo(f"New words: {', '.join(last['new_words'])}")
    click.echo(f"Updated home {updated.name} in {_seconds(last['seconds'])} ({sweeps} sweeps): "
               f"{updated.n_samples} samples, {updated.n_taught} taught; wrote {target}.")
    from spco.knowledge import unused_word_hint

    for word in dict.fromkeys(w for s in sentences for w in updated.vocabulary.tokenize(s)):
        index = updated.vocabulary.index(word)
        hint = unused_word_hint(updated, word)
        if hint is not None and index is not None and index >= updated.n_knowledge_words:  # a home's own word
            click.echo(f"note: {hint}".replace("spco teach HOME", f"spco teach {target}"))


KNOWLEDGE_COMMANDS = (fit, adapt, where, what, teach)
