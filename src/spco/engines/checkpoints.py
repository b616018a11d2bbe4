"""Checkpoints of a sharded fit on disk: one file per shard, written by the shard itself, and one
driver file that commits them.

A checkpoint of sweep i is the files ``shard-<s>-<i>.npz`` (each worker's
:class:`~spco.model.gibbs.GibbsState` without its count cache, and its homes' generator states)
and ``driver.npz`` (the sweep i, the driver's generator, the shared parameters and the log-joint
trace so far). Every file is written to a temporary name in the same directory and renamed into
place (atomic on POSIX); the driver file is written last, so it always names a complete set of
shard files. Files carry a format name and version and are read without pickle. With the place
channel's home level (``place_channel="home"``) a shard's file holds its homes' own ψ_{e,l} beside
their θ^w, so that a fit resumed from it continues the same chain.
"""

from __future__ import annotations

import json
import os
import tempfile
from dataclasses import fields
from pathlib import Path

import numpy as np

from spco.model.gibbs import GibbsState
from spco.model.state import SharedParameters
from spco.model.word_channels import WordChannels

FORMAT = "spco-checkpoint"
#: 2: a generator state per home; 3: the word channels; 4: the homes' own place words ψ_{e,l}
#: (``channels.log_place_home``, ``place_channel="home"``). A file without ψ_{e,l} is written as
#: version 3 (what it is: the default model's checkpoints are unchanged), one with it as version 4,
#: which an spco that would drop ψ_{e,l} refuses; both are read.
VERSION = 4
#: The versions this spco reads.
READABLE_VERSIONS = (3, 4)

#: The arrays of a :class:`~spco.model.word_channels.WordChannels`, stored as ``channels.<name>``.
_CHANNEL_ARRAYS = ("log_place", "log_background", "log_shares", "log_evidence")
#: The array of the homes' own ψ_{e,l} (:attr:`~spco.model.word_channels.WordChannels.log_place_home`),
#: present only when the state holds it.
_HOME_PLACE = "channels.log_place_home"


def _put(arrays: dict, name: str, value) -> None:
    if name == "channels":
        for part in _CHANNEL_ARRAYS:
            arrays[f"channels.{part}"] = np.asarray(getattr(value, part))
        arrays["channels.fresh"] = np.asarray(value.fresh)
        arrays["channels.token_weight"] = np.asarray(value.token_weight)
        arrays["channels.power"] = np.asarray(value.power)
        if value.log_place_home is not None:  # the place channel's home level: every home's own ψ_{e,l}
            arrays[_HOME_PLACE] = np.asarray(value.log_place_home)
    else:
        arrays[name] = np.asarray(value)


def _get(arrays, name: str):
    if name == "channels":
        if "channels.log_place" not in arrays:
            return None
        return WordChannels(*(arrays[f"channels.{part}"] for part in _CHANNEL_ARRAYS),
                            fresh=bool(arrays["channels.fresh"]),
                            token_weight=float(arrays["channels.token_weight"])
                            if "channels.token_weight" in arrays else 1.0,
                            power=bool(arrays["channels.power"]) if "channels.power" in arrays else False,
                            log_place_home=arrays.get(_HOME_PLACE))
    return arrays[name] if name in arrays else None
DRIVER_FILE = "driver.npz"


class CheckpointError(ValueError):
    """A checkpoint file that cannot be read (names the file and the problem)."""


def shard_path(directory: str | os.PathLike, shard: int, iteration: int) -> Path:
    """The file of shard ``shard``'s checkpoint at sweep ``iteration``."""
    return Path(directory) / f"shard-{shard}-{iteration:07d}.npz"


def _write_atomically(path: Path, arrays: dict[str, np.ndarray], meta: dict) -> int:
    path.parent.mkdir(parents=True, exist_ok=True)
    version = VERSION if _HOME_PLACE in arrays else 3  # (module: the lowest version that holds the file)
    arrays = dict(arrays, meta=np.array(json.dumps({"format": FORMAT, "version": version, **meta})))
    descriptor, temporary = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.", suffix=".tmp")
    try:
        with os.fdopen(descriptor, "wb") as f:
            np.savez(f, **arrays)
            f.flush()
            os.fsync(f.fileno())
        os.replace(temporary, path)
    except BaseException:
        Path(temporary).unlink(missing_ok=True)
        raise
    return path.stat().st_size


def _read(path: Path, kind: str) -> tuple[dict[str, np.ndarray], dict]:
    try:
        with np.load(path, allow_pickle=False) as f:
            arrays = {name: f[name] for name in f.files}
    except (OSError, ValueError) as error:
        raise CheckpointError(f"{path}: not a readable checkpoint ({error})") from error
    try:
        meta = json.loads(str(arrays.pop("meta")))
    except (KeyError, ValueError) as error:
        raise CheckpointError(f"{path}: no checkpoint header") from error
    if meta.get("format") != FORMAT or meta.get("kind") != kind:
        raise CheckpointError(f"{path}: not a {kind} checkpoint of spco")
    if meta.get("version") not in READABLE_VERSIONS:
        raise CheckpointError(f"{path}: checkpoint format version {meta.get('version')}, this spco reads "
                              f"versions {', '.join(map(str, READABLE_VERSIONS))}")
    return arrays, meta


def save_shard(path: str | os.PathLike, state: GibbsState, rng_state: list[dict]) -> int:
    """Write a worker's state (its homes' joined states) and its homes' generator states to ``path``
    atomically; returns the bytes written."""
    arrays, absent = {}, []
    for f in fields(state):
        if f.name in ("visual_cache", "words_cache", "switches"):  # rebuilt exactly from the state
            continue  # (the switches: drawn afresh by the next local step, before anything reads them)
        value = getattr(state, f.name)
        if value is None:
            absent.append(f.name)
        else:
            _put(arrays, f.name, value)
    return _write_atomically(Path(path), arrays, {"kind": "shard", "rng": rng_state, "absent": absent})


def load_shard(path: str | os.PathLike) -> tuple[GibbsState, list[dict]]:
    """The state and generator states written by :func:`save_shard`."""
    arrays, meta = _read(Path(path), "shard")
    values = {f.name: _get(arrays, f.name)
              for f in fields(GibbsState) if f.name not in ("visual_cache", "words_cache", "switches")}
    missing = [name for name, v in values.items() if v is None and name not in meta["absent"]]
    if missing:
        raise CheckpointError(f"{path}: the shard checkpoint lacks {', '.join(missing)}")
    return GibbsState(**values), meta["rng"]


def save_driver(directory: str | os.PathLike, iteration: int, rng_state: dict, shared: SharedParameters,
                trace: np.ndarray, n_shards: int) -> int:
    """Commit the checkpoint of sweep ``iteration`` (its shard files written before)."""
    arrays = {"trace": np.asarray(trace)}
    for f in fields(shared):
        if getattr(shared, f.name) is not None:
            _put(arrays, f.name, getattr(shared, f.name))
    return _write_atomically(Path(directory) / DRIVER_FILE, arrays,
                             {"kind": "driver", "iteration": int(iteration), "rng": rng_state,
                              "shards": int(n_shards)})


def load_driver(directory: str | os.PathLike) -> tuple[int, dict, SharedParameters, np.ndarray, list[Path]]:
    """The last committed checkpoint: sweep, driver generator state, shared parameters, trace, and
    the shard files (in shard order)."""
    arrays, meta = _read(Path(directory) / DRIVER_FILE, "driver")
    # (a field that was None is absent: name_words before any pruning)
    shared = SharedParameters(*(_get(arrays, f.name) for f in fields(SharedParameters)))
    iteration = int(meta["iteration"])
    paths = [shard_path(directory, s, iteration) for s in range(int(meta["shards"]))]
    for p in paths:
        if not p.exists():
            raise CheckpointError(f"{p}: missing (named by {Path(directory) / DRIVER_FILE})")
    return iteration, meta["rng"], shared, arrays["trace"], paths


def remove_older(directory: str | os.PathLike, iteration: int) -> None:
    """Delete the shard files of checkpoints before sweep ``iteration`` (superseded)."""
    for p in Path(directory).glob("shard-*-*.npz"):
        try:
            if int(p.stem.rsplit("-", 1)[1]) < iteration:
                p.unlink(missing_ok=True)
        except ValueError:
            continue
