"""Compiling spco's kernels ahead of a fit: in several processes at once on a cold cache
(``spco demo`` and the commands that fit), or loaded in this process, from the kernels and argument
types a fit calls (:data:`SIGNATURES_FILE`, written by ``python -m spco.model.precompile``).

Where the compiled kernels are cached, and the notice shown while a fit compiles them, is
:mod:`spco.model.numba_cache`'s.
"""

from __future__ import annotations

import importlib
import json
import os
import sys
import time
from collections.abc import Callable
from concurrent.futures import ProcessPoolExecutor
from multiprocessing import get_context
from multiprocessing.sharedctypes import Synchronized
from pathlib import Path

import numba

from spco.data.synthetic import generate_homes
from spco.model.kernels import dispatch
from spco.model.numba_cache import mark_announced
from spco.model.transfer import SpCoA, SpCoTransfer

#: The same kernels compiled in 2 processes at once (:func:`precompile`, as ``spco demo`` does on
#: a cold cache; 2-core machine, see benchmarks/README.md, "First run").
PRECOMPILE_SECONDS_ESTIMATE = 20


#: The kernels a fit, an adaptation and the SpCoA baseline call from Python, with the argument
#: types of each call and the seconds each took to compile (``spco demo``, cold cache, 2 cores):
#: written by ``python -m spco.model.precompile`` (:func:`write_signatures`).
SIGNATURES_FILE = Path(__file__).resolve().parent / "kernel_signatures.json"


def _numba_type(text: str):
    """The Numba type written as ``str(type)`` (arrays and scalars, as the kernels take them)."""
    from numba.core import types

    return eval(text, {"__builtins__": {}}, vars(types))  # our own file; Numba's type names only


def _compile_group(entries: list[dict]) -> float:
    """Compile (or load from the cache) the kernels of ``entries`` for their signatures, saving
    them to the on-disk cache; returns the seconds taken. Kernels called through
    :func:`~spco.model.kernels.dispatch._call_vectorised` are compiled with the SLP vectoriser on,
    as that function does."""
    from numba.core import config

    start = time.perf_counter()
    for entry in entries:
        module_name, _, name = entry["kernel"].rpartition(".")
        kernel = getattr(importlib.import_module(module_name), name)
        previous = config.SLP_VECTORIZE
        config.SLP_VECTORIZE = 1 if entry["vectorised"] else previous
        try:
            for text in entry["signatures"]:
                signature = tuple(_numba_type(t) for t in text)
                if signature not in kernel.signatures:
                    kernel.compile(signature)
        finally:
            config.SLP_VECTORIZE = previous
    return time.perf_counter() - start


#: The gamma samplers' module (``_log_gamma_row`` is called from Python too) and the modules whose
#: kernels call the same compiled (not inlined) gamma samplers (``_log_gamma_row``,
#: ``_stream_gamma``): compiled in one process, they are compiled once, not once per process.
_GAMMA_CALLERS = ("spco.model.kernels.dirichlet", "spco.model.kernels.gamma", "spco.model.kernels.niw")

#: Modules whose listed kernels call the same compiled helpers of their own (the label-swap pass
#: and its log-gamma table share ``moves._log_gamma_values``): each module's kernels are compiled
#: in one process, like the gamma sampler's callers.
_TOGETHER = ("spco.model.moves",)


def _clusters(entries: list[dict]) -> list[list[dict]]:
    """``entries`` in clusters compiled by one process each: the kernels that call the gamma sampler
    together, those of each module of :data:`_TOGETHER` together, every other kernel alone; the
    largest cluster (by the file's seconds) first, ties in the file's order."""
    clusters: dict[str, list[dict]] = {}
    for entry in entries:
        module = entry["kernel"].rpartition(".")[0]
        key = "gamma" if module in _GAMMA_CALLERS else module if module in _TOGETHER else entry["kernel"]
        clusters.setdefault(key, []).append(entry)
    return sorted(clusters.values(), key=lambda c: -sum(e["seconds"] for e in c))


def compile_in_turn(turns: Synchronized) -> float:
    """Compile the kernels listed in :data:`SIGNATURES_FILE` cluster by cluster (:func:`_clusters`,
    the largest first) into the on-disk cache, taking the next cluster not yet taken from the
    counter ``turns`` (a ``multiprocessing.Value("i", 0)`` shared by every process doing this), until
    none is left; returns the seconds taken (0 without the file). Processes that start at different
    times or do other work besides each compile as much as they have time for, and end within one
    cluster of each other; every cluster is compiled once."""
    try:
        entries = json.loads(SIGNATURES_FILE.read_text())["kernels"]
    except (OSError, ValueError, KeyError):
        return 0.0
    start = time.perf_counter()
    clusters = _clusters(entries)
    while True:
        with turns.get_lock():
            index = turns.value
            turns.value = index + 1
        if index >= len(clusters):
            return time.perf_counter() - start
        _compile_group(clusters[index])


def _listed_kernels() -> list:
    """The kernels of :data:`SIGNATURES_FILE` (Numba dispatchers, in the file's order)."""
    entries = json.loads(SIGNATURES_FILE.read_text())["kernels"]
    return [getattr(importlib.import_module(module), name)
            for module, _, name in (entry["kernel"].rpartition(".") for entry in entries)]


def _kernel_compiled(kernel) -> bool:
    """Whether ``kernel`` (a Numba dispatcher) is compiled in this process or has an entry in Numba's
    on-disk cache valid for its source."""
    return bool(kernel.signatures) or bool(kernel._cache._cache_file._load_index())


def kernels_compiled() -> bool | None:
    """Whether Numba's on-disk cache (or this process) holds spco's sampler kernels for this source:
    every kernel of :data:`SIGNATURES_FILE`, the kernels a fit calls from Python, which
    :func:`precompile` compiles (``None``: unknown, the file or the cache unreadable).

    ``False`` means the next fit compiles them first (about half a minute on 2 cores). The kernels they
    call are compiled into them, so a kernel loaded from the cache needs none of its own (the modules
    holding only such kernels, ``kernels.normal`` and ``kernels.rng``, are not read), and the kernels only
    an opt-in setting calls (``blocks``, ``kernels.fractional``, ``kernels.phi_quadrature``) are compiled
    by the fit that needs them, not ahead.
    """
    try:
        return all(_kernel_compiled(kernel) for kernel in _listed_kernels())
    except Exception:
        return None


def precompile_if_cold(echo: Callable[[str], None], processes: int = 2) -> bool:
    """For a command line run: when the on-disk cache holds no kernel yet (:func:`kernels_compiled`),
    say so with ``echo`` and compile the kernels in ``processes`` processes at once
    (:func:`precompile`); returns whether it did. The commands call it (``spco demo``, ``fit``,
    ``adapt``, ``teach``, ``experiment``, ``bench``); library functions do not, since it starts
    processes, which a user's script without a ``__main__`` guard cannot afford."""
    if kernels_compiled() is not False:
        return False
    echo(precompile_notice(processes))
    mark_announced()
    precompile(processes=processes)
    return True


def precompile_notice(processes: int = 2) -> str:
    """What ``spco demo`` says before :func:`precompile` on a cold cache."""
    plural = "es" if processes != 1 else ""
    return (f"Compiling the sampler's Numba kernels in {processes} process{plural} (first run only, about "
            f"{PRECOMPILE_SECONDS_ESTIMATE} s on 2 cores)...")


def precompile(processes: int = 2) -> float:
    """Compile the kernels listed in :data:`SIGNATURES_FILE` in ``processes`` processes at once
    (this one and ``processes - 1`` others), taking turns (:func:`compile_in_turn`), into the
    on-disk cache; a fit afterwards loads them from there. Returns the seconds taken.

    Numba compiles one function at a time per process; the kernels are independent, so on a
    multi-core machine the first run takes about 1/``processes`` of the time. A kernel whose
    signature the file does not list (the file is stale) is compiled by the fit as before."""
    start = time.perf_counter()
    try:
        entries = json.loads(SIGNATURES_FILE.read_text())["kernels"]
    except (OSError, ValueError, KeyError):  # not installed with the package: the fit compiles as before
        return 0.0
    if processes <= 1 or not numba.config.CACHE_DIR:
        _compile_group(entries)
        return time.perf_counter() - start
    context = get_context("spawn")
    turns = context.Value("i", 0)
    with ProcessPoolExecutor(max_workers=processes - 1, mp_context=context, initializer=_share_turns,
                             initargs=(turns,)) as pool:
        others = [pool.submit(_compile_in_pool_turn) for _ in range(1, processes)]
        compile_in_turn(turns)
        for future in others:
            future.result()
    # this process now loads the others' kernels from the cache, on first call
    return time.perf_counter() - start


#: A :func:`precompile` worker's counter of turns (set by :func:`_share_turns` when it starts).
_pool_turns: Synchronized | None = None


def _share_turns(turns: Synchronized) -> None:
    global _pool_turns
    _pool_turns = turns


def _compile_in_pool_turn() -> float:
    return compile_in_turn(_pool_turns) if _pool_turns is not None else 0.0


def load_kernels() -> float:
    """Load the kernels listed in :data:`SIGNATURES_FILE` from the on-disk cache, compiling any it
    lacks, in this process, without a fit (cheaper than :func:`warm_up`: ~0.3 s of CPU on a warm
    cache against a 4-home fit); returns the seconds taken. Without the file, :func:`warm_up`."""
    try:
        entries = json.loads(SIGNATURES_FILE.read_text())["kernels"]
    except (OSError, ValueError, KeyError):
        return warm_up()
    return _compile_group(entries)


def warm_up() -> float:
    """Compile (or load from Numba's cache) the kernels with a small fit (3 sweeps on 4 homes, every
    kernel a demo-sized fit uses, checked by their signatures; ``spco demo`` runs it first); returns
    the seconds taken."""
    start = time.perf_counter()
    # four homes of 1,024 features: batches large enough for the threaded variants of the kernels too
    tiny = generate_homes(4, seed=0, new_homes=1, specific_rooms=False)
    SpCoTransfer(prune_words=True, n_iterations=3, random_state=0, progress=False).fit(tiny)
    SpCoA(prune_words=True, n_iterations=3, random_state=0, progress=False).fit(tiny, home=tiny[3].name)
    return time.perf_counter() - start


def used_signatures() -> dict[str, set[tuple[str, ...]]]:
    """The compiled signatures of every kernel of spco's imported modules in this process, by
    kernel name (``module.qualname``), each a tuple of Numba type names as in
    :data:`SIGNATURES_FILE`. In a fresh process whose kernels came from the on-disk cache, these
    are exactly the kernels called from Python and their argument types (a kernel loaded from the
    cache loads no callee)."""
    from numba.core.registry import CPUDispatcher

    used: dict[str, set[tuple[str, ...]]] = {}
    for name, module in list(sys.modules.items()):
        if not name.startswith("spco.") or module is None:
            continue
        for value in list(vars(module).values()):
            if isinstance(value, CPUDispatcher) and value.signatures:
                function = value.py_func
                used.setdefault(f"{function.__module__}.{function.__qualname__}", set()).update(
                    tuple(repr(t) for t in signature) for signature in value.signatures)
    return used


#: What :func:`called_signatures` runs in a fresh process.
_CALLED_SIGNATURES = ("import json, spco.model.precompile as n; n.warm_up(); "
                      "print(json.dumps({k: sorted(v) for k, v in n.used_signatures().items()}))")


def called_signatures() -> dict[str, set[tuple[str, ...]]]:
    """The kernels and argument types the demo's warm-up fit (:func:`warm_up`) calls from Python:
    :func:`used_signatures` after it, in a fresh Python process (compiling first if the cache is cold)."""
    import subprocess

    proc = subprocess.run([sys.executable, "-c", _CALLED_SIGNATURES], capture_output=True, text=True,
                          check=True, env=dict(os.environ))
    return {k: {tuple(s) for s in v} for k, v in json.loads(proc.stdout.strip().splitlines()[-1]).items()}


def write_signatures(path: Path = SIGNATURES_FILE) -> None:
    """Run the demo's warm-up fit (:func:`warm_up`) on a cold cache noting each kernel's compile CPU
    seconds (this thread's, callees included in their first caller), then write to ``path`` the
    kernels and argument types it calls from Python (:func:`called_signatures`) with those seconds
    (0 for a kernel first compiled as another's callee)."""
    from numba.core import event

    seconds: dict[str, float] = {}
    started: list[float] = []

    class _Listener(event.Listener):
        def on_start(self, ev) -> None:
            started.append(time.thread_time())

        def on_end(self, ev) -> None:
            elapsed = time.thread_time() - started.pop()
            if started:  # a callee compiled inside another kernel
                return
            function = ev.data["dispatcher"].py_func
            name = f"{function.__module__}.{function.__qualname__}"
            seconds[name] = seconds.get(name, 0.0) + elapsed

    event.register("numba:compile", _Listener())
    warm_up()
    vectorised = {f"{k.py_func.__module__}.{k.py_func.__qualname__}" for k, _ in dispatch._VECTORISED_READY}
    called = called_signatures()
    kernels = [{"kernel": name, "seconds": round(seconds.get(name, 0.0), 2), "vectorised": name in vectorised,
                "signatures": [list(s) for s in sorted(called[name])]} for name in sorted(called)]
    path.write_text(json.dumps({"kernels": kernels}, indent=1) + "\n")


if __name__ == "__main__":
    write_signatures()
