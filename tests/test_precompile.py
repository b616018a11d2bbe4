"""The first run's parallel compilation: the list of kernels and signatures it compiles
(``src/spco/model/kernel_signatures.json``) names real kernels and types, and its split into
processes keeps every kernel exactly once."""

from __future__ import annotations

import json

from numba.core.registry import CPUDispatcher

from spco.model import numba_cache, precompile


def _entries() -> list[dict]:
    return json.loads(precompile.SIGNATURES_FILE.read_text())["kernels"]


def test_signature_file_names_compiled_kernels_and_numba_types():
    entries = _entries()
    assert entries
    for entry in entries:
        module_name, _, name = entry["kernel"].rpartition(".")
        kernel = getattr(__import__(module_name, fromlist=[name]), name)
        assert isinstance(kernel, CPUDispatcher), entry["kernel"]
        for signature in entry["signatures"]:
            types = [precompile._numba_type(text) for text in signature]
            assert [repr(t) for t in types] == signature


def test_compiling_in_turn_takes_every_cluster_once_the_largest_first(monkeypatch):
    """Two callers of ``compile_in_turn`` on one counter (the demo's two processes) compile every
    listed kernel exactly once between them, the clusters in order of their seconds, the gamma
    sampler's callers in one cluster."""
    import multiprocessing

    compiled: list[list[str]] = []
    turns = multiprocessing.get_context("spawn").Value("i", 0)
    monkeypatch.setattr(precompile, "_compile_group",
                        lambda entries: compiled.append([e["kernel"] for e in entries]) or 0.0)
    with turns.get_lock():
        turns.value = 1  # the other process took the first (largest) cluster
    precompile.compile_in_turn(turns)
    clusters = precompile._clusters(_entries())
    assert compiled == [[e["kernel"] for e in c] for c in clusters[1:]]
    precompile.compile_in_turn(turns)  # nothing left: compiles nothing
    assert len(compiled) == len(clusters) - 1
    names = [n for group in [[e["kernel"] for e in clusters[0]], *compiled] for n in group]
    assert sorted(names) == sorted(e["kernel"] for e in _entries())
    seconds = [sum(e["seconds"] for e in c) for c in clusters]
    assert seconds == sorted(seconds, reverse=True)
    gamma = [i for i, c in enumerate(clusters) for e in c
             if e["kernel"].rpartition(".")[0] in precompile._GAMMA_CALLERS]
    assert len(set(gamma)) == 1
    assert turns.value == len(clusters) + 2  # one look past the end per call


def test_a_fit_on_an_empty_cache_says_it_compiles_once(tmp_path, monkeypatch, capsys):
    """The notice on stderr when the cache holds no kernel yet, and none when it does."""
    import numba

    monkeypatch.setattr(numba.config, "CACHE_DIR", str(tmp_path))
    monkeypatch.setattr(numba_cache, "_announced", False)
    numba_cache.announce_compilation()
    err = capsys.readouterr().err
    assert "compiling the sampler's kernels for this machine, once" in err
    assert f"about {numba_cache.COMPILE_SECONDS_ESTIMATE} s" in err and str(tmp_path) in err
    numba_cache.announce_compilation()  # once per process
    assert capsys.readouterr().err == ""
    (tmp_path / "kernel.nbi").write_bytes(b"")
    monkeypatch.setattr(numba_cache, "_announced", False)
    numba_cache.announce_compilation()
    assert capsys.readouterr().err == ""


def test_demo_on_an_empty_cache_says_it_compiles_in_two_processes(monkeypatch):
    """``spco demo`` on a cold cache prints its notice, then runs in 2 processes that compile a
    share of the kernels each first (the demo stubbed here: the notice and the layout asked for
    are checked, not the compilation or its time)."""
    from click.testing import CliRunner

    import spco.synthetic_transfer
    from spco.cli import main

    calls: list[dict] = []

    class Stop(Exception):
        pass

    def stop(**kwargs: object) -> None:
        calls.append(kwargs)
        raise Stop

    monkeypatch.setattr(precompile, "kernels_compiled", lambda: False)
    monkeypatch.setattr(spco.synthetic_transfer, "run_demo", stop)
    monkeypatch.setattr("os.cpu_count", lambda: 2)
    result = CliRunner().invoke(main, ["demo", "--out", "unused"])
    assert isinstance(result.exception, Stop)
    assert precompile.precompile_notice(2) in result.stderr
    assert f"about {precompile.PRECOMPILE_SECONDS_ESTIMATE} s" in result.stderr
    assert [(c["processes"], c["compile_first"]) for c in calls] == [(2, True)]


def test_fit_and_adapt_on_an_empty_cache_precompile_in_two_processes(monkeypatch, tmp_path):
    """``spco fit`` and ``spco adapt`` on a cold cache say so and precompile in 2 processes, as the
    demo does (stubbed: the notice and the call are checked); with a cache, neither."""
    from click.testing import CliRunner

    from spco.cli.knowledge import adapt, fit
    from spco.data.plain import write_corpus
    from spco.data.synthetic import SyntheticConfig, generate_homes

    corpus = generate_homes(3, seed=2, config=SyntheticConfig(n_features=16, n_train=6, n_test=2),
                            new_homes=1, specific_rooms=False)
    write_corpus(list(corpus)[:2], tmp_path / "experienced")
    write_corpus(list(corpus)[2:], tmp_path / "new")
    calls: list[int] = []
    monkeypatch.setattr(precompile, "precompile", lambda processes: calls.append(processes) or 0.0)
    monkeypatch.setattr(precompile, "kernels_compiled", lambda: False)
    kfile = tmp_path / "k.spco"
    result = CliRunner().invoke(fit, ["--data", str(tmp_path / "experienced"), "--iterations", "2",
                                      "--out", str(kfile)])
    assert result.exit_code == 0, result.output
    assert precompile.precompile_notice(2) in result.stderr and calls == [2]
    home = next((tmp_path / "new").iterdir())
    result = CliRunner().invoke(adapt, [str(kfile), "--home", str(home), "--iterations", "2",
                                        "--out", str(tmp_path / "h.spco")])
    assert result.exit_code == 0, result.output
    assert calls == [2, 2]
    monkeypatch.setattr(precompile, "kernels_compiled", lambda: True)
    result = CliRunner().invoke(adapt, [str(kfile), "--home", str(home), "--iterations", "2",
                                        "--out", str(tmp_path / "h2.spco")])
    assert result.exit_code == 0 and calls == [2, 2] and "Compiling" not in result.stderr


def test_signature_file_lists_exactly_what_the_demo_s_warm_up_calls():
    """Every kernel and argument types the demo's warm-up fit calls from Python is in the file
    (else a first run compiles it after the 2-process compilation, alone), and nothing else (else
    the first run compiles what no fit calls). Checked in a fresh process: kernels loaded from the
    on-disk cache load no callee, so its compiled signatures are the ones called from Python."""
    used = precompile.called_signatures()
    listed = {e["kernel"]: {tuple(s) for s in e["signatures"]} for e in _entries()}
    hint = "regenerate it: SPCO_CACHE_DIR=$(mktemp -d) python -m spco.model.precompile"
    assert {k: v - listed.get(k, set()) for k, v in used.items() if v - listed.get(k, set())} == {}, hint
    assert {k: v - used.get(k, set()) for k, v in listed.items() if v - used.get(k, set())} == {}, hint


def _kernel_modules(inlined: bool = False) -> dict[str, list[CPUDispatcher]]:
    """Every module of ``spco.model`` that defines Numba kernels cached on disk and compiled on their
    own (not ``inline="always"``; ``inlined``: those too), with those kernels."""
    import importlib
    import pkgutil

    import spco.model

    found: dict[str, list[CPUDispatcher]] = {}
    for info in pkgutil.walk_packages(spco.model.__path__, "spco.model."):
        module = importlib.import_module(info.name)
        kernels = [v for v in vars(module).values() if isinstance(v, CPUDispatcher)
                   and v.py_func.__module__ == info.name
                   and (inlined or v.targetoptions.get("inline") != "always")]
        if kernels:
            found[info.name] = kernels
    return found


#: The kernel modules whose kernels no fit with the default settings calls from Python, so that
#: ``kernels_compiled`` does not read them (see its docstring): called only from other kernels, or
#: only with an opt-in setting (the region block move, the power target, φ^v's quadrature).
_NOT_READ = {"spco.model.kernels.normal", "spco.model.blocks", "spco.model.kernels.fractional",
             "spco.model.kernels.phi_quadrature"}


def test_kernels_compiled_reads_every_kernel_module_a_fit_calls(monkeypatch):
    """``kernels_compiled`` is False as soon as the kernels of any one module a fit calls are neither
    in memory nor in the cache, for every such module; a new kernel module fails here until the
    signature file lists it (regenerated) or it is added to the modules not read, with its reason."""
    listed = {e["kernel"].rpartition(".")[0] for e in _entries()}
    modules = _kernel_modules()
    assert set(modules) - listed == _NOT_READ, "a kernel module neither checked nor known to be opt-in"
    assert listed <= set(modules)
    import pathlib

    source = pathlib.Path(precompile.__file__).resolve().parents[1]  # src/spco: no kernel outside model
    outside = [p for p in source.rglob("*.py") if "@njit" in p.read_text(encoding="utf-8")
               and "model" not in p.relative_to(source).parts[:1]]
    assert outside == []
    for module in sorted(listed):
        monkeypatch.setattr(precompile, "_kernel_compiled", lambda k, m=module: k.py_func.__module__ != m)
        assert precompile.kernels_compiled() is False, module
    monkeypatch.setattr(precompile, "_kernel_compiled", lambda k: True)
    assert precompile.kernels_compiled() is True
    monkeypatch.setattr(precompile, "SIGNATURES_FILE", precompile.SIGNATURES_FILE.with_name("missing.json"))
    assert precompile.kernels_compiled() is None


def test_kernels_compiled_is_false_on_an_empty_cache(tmp_path):
    """A fresh process with an empty cache holds no kernel: ``kernels_compiled`` says so."""
    import os
    import subprocess
    import sys

    env = {**os.environ, "SPCO_CACHE_DIR": str(tmp_path)}
    env.pop("NUMBA_CACHE_DIR", None)
    proc = subprocess.run([sys.executable, "-c", "from spco.model.precompile import kernels_compiled; "
                           "print(kernels_compiled())"], capture_output=True, text=True, env=env, check=True)
    assert proc.stdout.strip() == "False"


def test_kernel_sources_hold_every_kernel_module():
    """The cache's digest (``numba_cache.kernel_sources``) reads every module that defines a kernel,
    found here by importing them (inlined kernels too), and besides them only ``spco.model.kernels``'
    ``__init__`` and ``dispatch`` (how the kernels are compiled)."""
    import importlib
    from pathlib import Path

    modules = _kernel_modules(inlined=True)
    defining = {Path(importlib.import_module(name).__file__).resolve() for name in modules}
    sources = set(numba_cache.kernel_sources())
    assert defining - sources == set(), "a kernel module the cache's digest does not read"
    kernels = Path(numba_cache.__file__).resolve().parent / "kernels"
    assert sources - defining == {kernels / "__init__.py", kernels / "dispatch.py"}
