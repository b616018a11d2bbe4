"""Writing the home folder of ``spco import-bag`` (:mod:`spco.data.rosbag`): where it may be written,
the chosen camera images as files, ``samples.csv``, ``home.json`` and ``visual.npz``, and the
finished folder moved into place in one rename. ``settings`` and ``summary`` below are the import's
:class:`~spco.data.rosbag.BagImportSettings` and :class:`~spco.data.rosbag.BagImportSummary`."""

from __future__ import annotations

import csv
import json
import os
import shutil
import uuid
from collections import Counter, defaultdict
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from spco.data.bagreading import RAW_ENCODINGS, _Bag, _Sample, _Streams
from spco.errors import ConfigurationError, DataFormatError
from spco.features.pixels import ImageError, ImageTooLargeError, decode_compressed, pixels_from_buffer, to_bgr


def _check_out(out: Path, bags: Sequence[Path], overwrite: bool) -> None:
    if out.exists() and not out.is_dir():
        raise ConfigurationError(f"{out} exists and is not a folder (--out names the home folder to write)")
    resolved = out.resolve()
    for bag in bags:
        b = bag.resolve()
        if b == resolved or resolved in b.parents:
            raise ConfigurationError(
                f"--out {out} would hold or replace the bag {bag}; choose another folder"
            )
    if out.is_dir() and any(out.iterdir()):
        if not overwrite:
            raise ConfigurationError(f"{out} is not empty; pass --force to replace the home folder it holds")
        if not ((out / "samples.csv").is_file() or (out / "samples.jsonl").is_file()):
            raise ConfigurationError(
                f"{out} holds files but no home (samples.csv); spco replaces only a home "
                "folder, even with --force: choose another --out"
            )
    for parent in resolved.parents:  # missing folders are made; one that is a file cannot be
        if parent.exists():
            if not parent.is_dir():
                raise ConfigurationError(f"cannot write {out}: {parent} is a file, not a folder")
            break


def _move_into_place(tmp: Path, out: Path) -> None:
    """Rename the finished folder ``tmp`` to ``out`` (replacing an old home folder there)."""
    if not out.exists():
        os.replace(tmp, out)
        return
    if out.is_dir() and not any(out.iterdir()):
        out.rmdir()
        os.replace(tmp, out)
        return
    old = out.parent / f".{out.name}.old.{uuid.uuid4().hex[:8]}"
    os.replace(out, old)
    try:
        os.replace(tmp, out)
    except OSError:
        os.replace(old, out)
        raise
    shutil.rmtree(old, ignore_errors=True)


def _decode_image(bag: _Bag, connection: Any, msg: Any, image_format: str) -> tuple[bytes, str] | str:
    """(file bytes, extension) of an image message, or the reason it cannot be used."""
    import cv2

    if connection.msgtype == "sensor_msgs/msg/CompressedImage":
        data = np.asarray(msg.data, dtype=np.uint8)
        fmt = str(msg.format).lower()
        if "compresseddepth" in fmt:
            raise DataFormatError(
                bag.path,
                f"{connection.topic}: depth images ({msg.format!r}) are not views; "
                "give a colour image topic (--image-topic)",
            )
        head = bytes(data[:8])
        if head.startswith(b"\xff\xd8"):
            ext = "jpg"
        elif head.startswith(b"\x89PNG"):
            ext = "png"
        elif data.size == 0:
            return "empty image"
        else:
            raise DataFormatError(
                bag.path,
                f"{connection.topic}: compressed image format {msg.format!r} is not supported (JPEG or PNG)",
            )
        try:
            decode_compressed(data)  # its size checked from its header first
        except ImageTooLargeError as exc:
            return f"image too large ({exc.problem})"
        except ImageError:
            return "image could not be decoded"
        return data.tobytes(), ext
    encoding = str(msg.encoding).lower()
    if encoding not in RAW_ENCODINGS:
        raise DataFormatError(
            bag.path,
            f"{connection.topic}: image encoding {msg.encoding!r} is not supported "
            f"({', '.join(RAW_ENCODINGS)}); record a colour or grey 8-bit image",
        )
    try:
        pixels = pixels_from_buffer(msg.data, msg.height, msg.width, msg.step, encoding)
    except DataFormatError:
        return "image data do not match its size"
    if encoding == "rgb8":
        pixels = to_bgr(pixels, encoding)
    ok, encoded = cv2.imencode(
        f".{image_format}",
        np.ascontiguousarray(pixels),
        [cv2.IMWRITE_JPEG_QUALITY, 95] if image_format == "jpg" else [],
    )
    if not ok:
        return "image could not be encoded"
    return encoded.tobytes(), image_format


def _write_images(
    bags: list[_Bag], topic: str, streams: _Streams, samples: list[_Sample], folder: Path, image_format: str
) -> dict[int, str]:
    """Second pass: decode the chosen images, write ``folder/images/<row>.<ext>``; returns failures."""
    wanted: dict[tuple[int, int], list[int]] = defaultdict(list)  # (bag, ordinal) -> sample rows
    for row, sample in enumerate(samples):
        if sample.image >= 0:
            wanted[streams.images.values[sample.image]].append(row)
    images = folder / "images"
    images.mkdir()
    failures: dict[int, str] = {}
    for index, bag in enumerate(bags):
        todo = {ordinal for b, ordinal in wanted if b == index}
        if not todo:
            continue
        last = max(todo)
        for ordinal, (connection, _, raw) in enumerate(bag.messages([topic])):
            if ordinal in todo:
                result = _decode_image(bag, connection, bag.deserialize(raw, connection), image_format)
                for row in wanted[(index, ordinal)]:
                    if isinstance(result, str):
                        failures[row] = result
                    else:
                        (images / f"{row}.{result[1]}").write_bytes(result[0])
            if ordinal >= last:
                break
    return failures


def _drop_failed_images(
    samples: list[_Sample], failures: dict[int, str], folder: Path, summary: Any
) -> list[_Sample]:
    """Remove samples whose image could not be used and renumber the image files to the new rows."""
    if not failures:
        return samples
    skipped = Counter(summary.skipped)
    kept: list[_Sample] = []
    images = folder / "images"
    for row, sample in enumerate(samples):
        if row in failures:
            kind = "utterance" if sample.sentence is not None else "along the way"
            skipped[f"{kind}: {failures[row]}"] += 1
            continue
        if row != len(kept):
            for ext in ("jpg", "png"):
                if (images / f"{row}.{ext}").exists():
                    os.replace(images / f"{row}.{ext}", images / f"{len(kept)}.{ext}")
        kept.append(sample)
    summary.skipped = dict(skipped)
    return kept


def _write_home_files(
    folder: Path,
    samples: list[_Sample],
    streams: _Streams,
    settings: Any,
    target: Path,
    summary: Any,
    where: str,
) -> None:
    """samples.csv, home.json and (with a visual topic) visual.npz."""
    with open(folder / "samples.csv", "w", encoding="utf-8", newline="") as fh:
        fh.write("id,x,y,theta,sentence\n")
        writer = csv.writer(fh, lineterminator="\n", quoting=csv.QUOTE_NONNUMERIC)
        for row, s in enumerate(samples):
            writer.writerow([row, round(s.x, 4), round(s.y, 4), round(s.theta, 4), s.sentence or ""])
    xy = np.array([[s.x, s.y] for s in samples])
    margin = 0.5
    meta: dict[str, Any] = {
        "name": settings.name or target.resolve().name,
        "extent": [
            round(float(xy[:, 0].min()) - margin, 3),
            round(float(xy[:, 0].max()) + margin, 3),
            round(float(xy[:, 1].min()) - margin, 3),
            round(float(xy[:, 1].max()) + margin, 3),
        ],
    }
    if "visual" in summary.topics:
        import scipy.sparse as sp

        vectors = [streams.visual.values[s.visual] for s in samples if s.visual >= 0]
        sizes = Counter(v.size for v in vectors)
        if len(sizes) > 1:
            raise DataFormatError(
                where,
                f"{summary.topics['visual']}: feature vectors of different lengths "
                f"({', '.join(map(str, sorted(sizes)))})",
            )
        matrix = np.vstack(vectors) if vectors else np.zeros((0, 0))
        if not np.isfinite(matrix).all():
            raise DataFormatError(where, f"{summary.topics['visual']}: feature vectors hold NaN or infinity")
        if settings.visual_scale is None:
            if (matrix < 0).any() or (matrix != np.round(matrix)).any():
                raise DataFormatError(
                    where,
                    f"{summary.topics['visual']}: features are not counts (negative or "
                    "fractional values); give --visual-scale (the authors used 5)",
                )
            matrix = matrix.astype(np.int64)
        else:
            meta["visual_scale"] = settings.visual_scale
        missing = np.array([s.visual < 0 for s in samples], dtype=bool)
        if not missing.any():
            sp.save_npz(folder / "visual.npz", sp.csr_array(matrix), compressed=True)
        elif vectors:  # rows of the samples without a view: zeros, marked missing (the plain format)
            full = np.zeros((len(samples), matrix.shape[1]), dtype=matrix.dtype)
            full[~missing] = matrix
            counts = sp.csr_array(full)
            np.savez_compressed(folder / "visual.npz", format=np.array("csr"),
                                shape=np.array(counts.shape), data=counts.data, indices=counts.indices,
                                indptr=counts.indptr, missing=missing)
    (folder / "home.json").write_text(json.dumps(meta, indent=1, ensure_ascii=False) + "\n", encoding="utf-8")
