"""``spco features IMAGES… --out FILE``: camera images to visual count vectors.

Registered in :mod:`spco.cli.main`. Heavy imports (OpenCV, ONNX Runtime) happen when the command runs.
"""

from __future__ import annotations

import re
import time
from collections.abc import Sequence
from pathlib import Path

import click

from spco.cli.errors import friendly_errors

__all__ = ["features", "parse_settings"]


def _natural_key(path: Path) -> tuple[object, ...]:
    return tuple(int(t) if t.isdigit() else t for t in re.split(r"(\d+)", path.name))


def expand_images(paths: Sequence[Path]) -> list[Path]:
    """Image files of ``paths`` in order; a folder gives its .jpg/.jpeg/.png files in natural order
    (2.jpg before 10.jpg). Raises DataFormatError for a missing path or a folder without images."""
    from spco.errors import DataFormatError
    from spco.features import IMAGE_SUFFIXES

    files: list[Path] = []
    for path in paths:
        if path.is_dir():
            found = sorted((p for p in path.iterdir() if p.suffix.lower() in IMAGE_SUFFIXES and p.is_file()),
                           key=_natural_key)
            if not found:
                raise DataFormatError(path, "holds no .jpg, .jpeg or .png images")
            files += found
        elif path.is_file():
            files.append(path)
        else:
            raise DataFormatError(path, "no such image file or folder")
    return files


def parse_settings(pairs: Sequence[str]) -> dict[str, object]:
    """``key=value`` extractor settings (numbers become int or float)."""
    from spco.errors import ConfigurationError

    out: dict[str, object] = {}
    for pair in pairs:
        key, sep, value = pair.partition("=")
        if not sep or not key.strip():
            raise ConfigurationError(f"--setting takes key=value, got {pair!r}")
        parsed: object = value
        for kind in (int, float):
            try:
                parsed = kind(value)
                break
            except ValueError:
                continue
        out[key.strip()] = parsed
    return out


@click.command(name="features")
@click.argument("images", nargs=-1, required=True, type=click.Path(path_type=Path))
@click.option("--out", "-o", required=True, type=click.Path(path_type=Path),
              help="The .npz to write: an (N, D) sparse count matrix (scipy.sparse.save_npz), row k for "
                   "image k — usable as a plain home's visual.npz.")
@click.option("--extractor", default=None,
              help="colour-hog (default), bovw-orb, bovw-sift, or onnx (with --model).")
@click.option("--model", "--onnx-model", "model", type=click.Path(path_type=Path), default=None,
              help="The .onnx network of the onnx extractor (needs the [onnx] extra).")
@click.option("--knowledge", "knowledge_file", type=click.Path(path_type=Path), default=None,
              help="Use the extractor (and codebook) stored in this knowledge file, as adapt/what/teach do.")
@click.option("--setting", "settings", multiple=True, help="Extractor setting key=value (repeatable).")
@click.option("--seed", default=0, show_default=True, type=click.IntRange(0),
              help="Seed of a codebook learnt from IMAGES (bovw extractors without --knowledge).")
@click.option("--jobs", "-j", default=None, type=click.IntRange(1), help="Threads (default: the CPUs).")
@click.option("--force", is_flag=True, help="Replace --out if it exists.")
@friendly_errors
def features(images: Sequence[Path], out: Path, extractor: str | None, model: Path | None,
             knowledge_file: Path | None, settings: Sequence[str], seed: int, jobs: int | None,
             force: bool) -> None:
    """Turn camera images (files or folders of PNG/JPEG) into visual count vectors.

    \b
    spco features views/ --out visual.npz                      # the default extractor
    spco features views/ --out visual.npz --extractor onnx --model resnet18.onnx
    spco features view.jpg --out v.npz --knowledge knowledge.spco

    Prints the extractor's description and the speed in images per second.
    """
    import scipy.sparse as sp

    from spco.cli.common import check_out
    from spco.errors import ConfigurationError
    from spco.features import DEFAULT_EXTRACTOR, ExtractorSpec, build_extractor
    from spco.model.archive import file_mode

    check_out(out, force)
    if out.suffix != ".npz":
        raise ConfigurationError(f"--out {out}: the counts are written as a .npz file")
    files = expand_images(images)
    if knowledge_file is not None:
        if extractor is not None or settings:
            raise ConfigurationError("--knowledge fixes the extractor: leave out --extractor and --setting")
        from spco.knowledge import load_knowledge

        ext = load_knowledge(knowledge_file).image_extractor(model_path=model)
    else:
        name = extractor or ("onnx" if model is not None else DEFAULT_EXTRACTOR)
        ext = build_extractor(ExtractorSpec(name, settings=parse_settings(settings)),
                              model_path=None if model is None else str(model))
        if ext.needs_fit:
            click.echo(f"Learning the {ext.name} codebook from {len(files)} images (seed {seed})...",
                       err=True)
            ext = ext.fitted(files, random_state=seed)
    start = time.perf_counter()
    counts = ext.extract_many(files, jobs=jobs)
    seconds = time.perf_counter() - start
    import os
    import tempfile

    fd, tmp = tempfile.mkstemp(dir=out.expanduser().resolve().parent, prefix=f".{out.name}.", suffix=".npz")
    os.close(fd)
    try:
        sp.save_npz(tmp, sp.csr_matrix(counts), compressed=True)
        os.chmod(tmp, file_mode(out))
        os.replace(tmp, out)
    finally:
        if os.path.exists(tmp):
            os.unlink(tmp)
    click.echo(f"extractor {ext.spec().describe()}")
    click.echo(f"{len(files)} images -> {counts.shape[0]}×{counts.shape[1]} counts "
               f"({counts.sum() / max(1, counts.shape[0]):.0f} per image) in {seconds:.2f} s: "
               f"{len(files) / max(seconds, 1e-9):.0f} images/s; wrote {out}")
