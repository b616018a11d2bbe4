"""Where Numba keeps spco's compiled kernels, and the notice shown while they compile.

The kernels are compiled on first use (about 30 s on 2 cores) and cached on disk. The cache
lives in ``$SPCO_CACHE_DIR`` (default ``~/.cache/spco``, or ``$XDG_CACHE_HOME/spco``) under a
name made of a digest of the kernels' source files (``numba-<digest>``), not in the package's
``__pycache__``:

- a kernel inlines the kernels it calls, but Numba checks only the calling file's time stamp, so
  a change in ``kernels/normal.py`` would leave the already compiled gamma kernels with the old
  normal; a new digest is a new, empty cache;
- a new virtual environment or ``pip install -e`` of the same sources finds the cache of the
  previous one.

``NUMBA_CACHE_DIR``, when set, is respected as it is. Importing this module (``spco.model`` does,
before any kernel) configures Numba. Compiling the kernels ahead of a fit, in several processes at
once, is :mod:`spco.model.precompile`'s.
"""

from __future__ import annotations

import hashlib
import os
import re
import sys
from pathlib import Path

import numba

#: The measured first compilation, in one process, of every kernel a fit and an adaptation use
#: (``python -m spco.model.precompile`` on a cold cache on the 2-core development machine: 27 s
#: at load 3; see benchmarks/README.md, "First run").
COMPILE_SECONDS_ESTIMATE = 30

_MODEL_DIR = Path(__file__).resolve().parent


#: A compiled kernel's decorator at the start of a line (the kernels are ``@njit`` functions).
_KERNEL_DECORATOR = re.compile(r"^[ \t]*@(?:numba\.)?n?jit\b", re.MULTILINE)


def kernel_sources() -> list[Path]:
    """The source files of the compiled kernels, sorted: every module of :mod:`spco.model` (any depth)
    that defines an ``@njit`` kernel, found by reading the sources (no import), and every module of
    :mod:`spco.model.kernels` (its ``dispatch`` decides how kernels are compiled)."""
    found = {path for path in _MODEL_DIR.rglob("*.py")
             if _KERNEL_DECORATOR.search(path.read_text(encoding="utf-8"))}
    return sorted(found | set((_MODEL_DIR / "kernels").glob("*.py")))


def source_digest() -> str:
    """A digest of the kernels' sources (16 hex digits)."""
    digest = hashlib.sha256()
    for path in kernel_sources():
        digest.update(path.relative_to(_MODEL_DIR).as_posix().encode())
        digest.update(path.read_bytes())
    return digest.hexdigest()[:16]


def cache_dir() -> Path:
    """The directory of this source version's compiled kernels."""
    base = os.environ.get("SPCO_CACHE_DIR")
    if not base:
        base = Path(os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache") / "spco"
    return Path(base) / f"numba-{source_digest()}"


def configure() -> None:
    """Point Numba's cache at :func:`cache_dir` (unless ``NUMBA_CACHE_DIR`` is set or the
    directory cannot be created, when Numba's default next to the sources is used)."""
    if os.environ.get("NUMBA_CACHE_DIR"):
        return
    path = cache_dir()
    try:
        path.mkdir(parents=True, exist_ok=True)
    except OSError:
        return
    numba.config.CACHE_DIR = str(path)


_announced = False


def mark_announced() -> None:
    """Note that the caller has told the user about the compilation itself (no second notice)."""
    global _announced
    _announced = True


def announce_compilation() -> None:
    """Say on stderr, once per process, that the kernels are being compiled, when the cache holds
    none yet (the first run of these sources)."""
    global _announced
    if _announced:
        return
    _announced = True
    directory = Path(numba.config.CACHE_DIR) if numba.config.CACHE_DIR else None
    if directory is None or any(directory.rglob("*.nbi")):
        return
    print(f"spco: compiling the sampler's kernels for this machine, once: about {COMPILE_SECONDS_ESTIMATE} s "
          f"(cached in {directory})", file=sys.stderr, flush=True)


configure()
