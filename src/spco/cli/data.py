"""Commands about homes on disk: ``spco inspect`` (homes, knowledge and home files), ``spco import``
(a folder of homes into one cache file) and ``spco synth`` (synthetic homes). Registered in
:mod:`spco.cli.main`."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import click

from spco.cli.errors import friendly_errors

__all__ = ["DATA_COMMANDS", "import_", "inspect", "synth"]


@click.command()
@click.argument("path", type=click.Path(path_type=Path))
@click.option("--teaching-rate", "-r", default=100, show_default=True, type=click.IntRange(0, 100),
              help="Percentage of taught samples to load (SIGVerse: the sentence/per_XX folder).")
@click.option("--json", "as_json", is_flag=True, help="Print a JSON list instead of a table.")
@friendly_errors
def inspect(path: Path, teaching_rate: int, as_json: bool) -> None:
    """Summarise the homes in PATH (a home, a folder of homes or a cache file), or a knowledge or
    home file (visual dimension, extractor, vocabulary, kept names, homes, provenance).

    A home that holds no sentences for the chosen teaching rate (the SIGVerse experienced homes
    have only per_100) is listed with its taught count as "-" (null in JSON).
    """
    from spco.data.language import Vocabulary
    from spco.data.loading import read_records
    from spco.errors import DataFormatError
    from spco.knowledge import model_file_format

    if model_file_format(path) is not None:
        _inspect_model_file(path, as_json)
        return
    from spco.data.loading import views_are_images

    extractor = None
    if views_are_images(path):  # views as images (spco import-bag): read them to count them
        from spco.features import DEFAULT_EXTRACTOR, build_extractor

        extractor = build_extractor(DEFAULT_EXTRACTOR)
    records = read_records(path, progress=not as_json, extractor=extractor)
    rows = []
    missing = []
    vocabulary_sentences: list[str | None] = []
    for record in records:
        try:
            env = record.at_rate(teaching_rate)
            taught: int | None = env.n_taught
        except DataFormatError:
            env, taught = record.environment, None
            missing.append(env.name)
        gt = env.ground_truth
        places = len(gt.places) if gt is not None and gt.labels is not None else None
        words = _home_vocabulary(env) if taught is not None else set()
        if taught is not None:
            vocabulary_sentences.extend(env.training_data().sentences)
        rows.append({
            "home": env.name,
            "samples": env.n_samples,
            "train": env.n_train,
            "test": env.n_test,
            "taught": taught,
            "places": places,
            "vocabulary": len(words) if taught is not None else None,
        })
    if as_json:
        click.echo(json.dumps(rows, indent=1))
        return
    header = ["home", "samples", "train", "test", "taught", "places", "vocabulary"]
    table = [[str(r[h]) if r[h] is not None else "-" for h in header] for r in rows]
    widths = [max(len(h), *(len(t[i]) for t in table)) for i, h in enumerate(header)]
    click.echo("  ".join(h.ljust(w) for h, w in zip(header, widths, strict=True)))
    for t in table:
        click.echo("  ".join(c.ljust(w) for c, w in zip(t, widths, strict=True)))
    total = sum(r["samples"] for r in rows)
    shared = len(Vocabulary.from_sentences(vocabulary_sentences))
    click.echo(f"{len(rows)} homes, {total} samples, {shared} words in the shared vocabulary "
               f"(teaching rate {teaching_rate}%)")
    if missing:
        click.echo(f"{len(missing)} homes hold no sentences for {teaching_rate}% (taught: -): "
                   f"{', '.join(missing)}")


def _inspect_model_file(path: Path, as_json: bool) -> None:
    """``spco inspect`` of a knowledge or home file."""
    from spco.knowledge import describe_model_file, fit_range_text, view_fit_warning

    info = describe_model_file(path)
    if info["kind"] == "home":  # a served home: the file, and what its journal holds beyond it
        from spco.service.teaching import pending_teachings

        pending = pending_teachings(path)
        if pending:
            click.echo(f"note: this is the last compacted state of {path}; its journal holds {pending} more "
                       "teaching(s) (served by spco serve; `spco where`/`what`/`show` answer with them)",
                       err=True)
    if as_json:
        click.echo(json.dumps(info, indent=1, default=str))
        return
    p = info["provenance"]
    if info["kind"] == "home":
        click.echo(f"{path}: home file of home {info['home']}: {info['samples']} samples, {info['taught']} "
                   f"taught, model {info['model']}")
    else:
        click.echo(f"{path}: knowledge file, model {info['model']}")
    if info["extractor"]:
        from spco.features import ExtractorSpec

        extractor = f"images, {ExtractorSpec.from_dict(info['extractor']).describe()}"
    else:
        extractor = "none recorded (count vectors given as they are)"
    click.echo(f"views: {info['visual_dimension']} features per view; extractor: {extractor}")
    click.echo(f"vocabulary ({len(info['vocabulary'])} words): {', '.join(info['vocabulary'])}")
    if info.get("text"):
        click.echo(f"text written without spaces: {info['text']}")
    click.echo(f"place names ({len(info['kept_names'])}): {', '.join(info['kept_names'])}")
    click.echo(f"experienced homes ({len(info['homes'])}): {', '.join(info['homes'])}")
    view = info["view_fit"]
    if info["kind"] == "knowledge" and view:
        values = [v for v in view["homes"].values() if v is not None]
        if values:
            click.echo(f"fit of the views: {fit_range_text(values)} nats per count above a "
                       f"uniform guess in the experienced homes; a new home below {view['warn_below']:.2f} "
                       f"is warned about")
    elif info["kind"] == "home" and view:
        click.echo(f"fit of the views: {view['value']:.2f} nats per count above a uniform guess "
                   f"(experienced homes {fit_range_text(view['experienced_range'])})")
        if not view["fits"]:
            click.echo(f"warning: {view_fit_warning(info['home'], view)}", err=True)
    keys = ("seed", "n_iterations", "created", "updated", "spco_version", "data", "teaching_rate",
            "knowledge_file", "home_path", "teach_updates", "adapt")
    shown = {k: p[k] for k in keys if k in p}
    click.echo("provenance: " + json.dumps(shown, default=str))


def _home_vocabulary(env: Any) -> set[str]:
    from spco.data.language import Vocabulary

    return set(Vocabulary.from_sentences(env.training_data().sentences).words)


@click.command(name="import")
@click.argument("src", type=click.Path(path_type=Path))
@click.argument("out", type=click.Path(path_type=Path))
@click.option("--teaching-rate", "-r", default=None, type=click.IntRange(0, 100),
              help="Keep only this teaching rate (default: every rate the source holds).")
@click.option("--force", is_flag=True, help="Overwrite OUT if it exists.")
@friendly_errors
def import_(src: Path, out: Path, teaching_rate: int | None, force: bool) -> None:
    """Convert the homes in SRC (either layout) into one compact cache file OUT."""
    from spco.data.loading import write_cache

    summary = write_cache(src, out, teaching_rate=teaching_rate, overwrite=force, progress=True)
    click.echo(summary)


@click.command()
@click.argument("out", type=click.Path(path_type=Path))
@click.option("--homes", "-n", default=8, show_default=True, type=click.IntRange(1, 10000),
              help="Number of homes to generate.")
@click.option("--seed", default=0, show_default=True, type=int, help="Random seed.")
@click.option("--force", is_flag=True, help="Write into OUT even if it holds homes already.")
@click.option("--language", type=click.Choice(["templates", "free"]), default="templates", show_default=True,
              help="Sentences: the paper's five templates, or 'free' (people talking freely: synonyms, "
                   "multi-word names, objects, fillers, typos; accepted_names.json lists each place's "
                   "accepted names).")
@friendly_errors
def synth(out: Path, homes: int, seed: int, force: bool, language: str) -> None:
    """Generate synthetic homes into folder OUT (plain format, with ground-truth regions).

    Homes are named synthetic_<layout>_<i> for seed 0 and synthetic_s<seed>_<layout>_<i> otherwise,
    so that homes generated with different seeds (experienced and new ones) never share a name.
    """
    from spco.data.plain import write_corpus
    from spco.data.synthetic import SyntheticConfig, generate_homes

    corpus = generate_homes(homes, seed=seed, config=SyntheticConfig(language=language),
                            name_prefix="synthetic" if seed == 0 else f"synthetic_s{seed}")
    write_corpus(corpus, out, overwrite=force)
    click.echo(f"wrote {len(corpus)} synthetic homes ({sum(e.n_samples for e in corpus)} samples) "
               f"to {out}")


#: The commands to register in :mod:`spco.cli.main`.
DATA_COMMANDS = (inspect, import_, synth)
