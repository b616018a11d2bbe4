"""The first run's parallel compilation: the list of kernels and signatures it compiles
(``src/spco/model/kernel_signatures.json``) names real kernels and types, and its split into
processes keeps every kernel exactly once."""

from __future__ import annotations

import json

from numba.core.registry import CPUDispatcher

from spco.model import numba_cache


def _entries() -> list[dict]:
    return json.loads(numba_cache.SIGNATURES_FILE.read_text())["kernels"]


def test_signature_file_names_compiled_kernels_and_numba_types():
    entries = _entries()
    assert entries
    for entry in entries:
        module_name, _, name = entry["kernel"].rpartition(".")
        kernel = getattr(__import__(module_name, fromlist=[name]), name)
        assert isinstance(kernel, CPUDispatcher), entry["kernel"]
        for signature in entry["signatures"]:
            types = [numba_cache._numba_type(text) for text in signature]
            assert [repr(t) for t in types] == signature


def test_split_keeps_each_kernel_once_and_gamma_callers_together():
    entries = _entries()
    groups = numba_cache._split(entries, 2)
    names = [e["kernel"] for group in groups for e in group]
    assert sorted(names) == sorted(e["kernel"] for e in entries)
    gamma_groups = {i for i, group in enumerate(groups) for e in group
                    if e["kernel"].rpartition(".")[0] in numba_cache._GAMMA_CALLERS}
    assert len(gamma_groups) == 1
    loads = [sum(e["seconds"] for e in group) for group in groups]
    assert loads == sorted(loads, reverse=True)  # this process takes the larger share


def test_a_head_start_gives_that_share_less_to_compile():
    """With seconds of other work for share 0 (the demo's first process looks up WordNet and draws
    the figures), share 0 compiles less, by about that much: compilation plus the head start differ
    by no more than the largest single kernel's seconds, and the shares keep their order."""
    entries = _entries()
    even = [sum(e["seconds"] for e in group) for group in numba_cache._split(entries, 2)]
    for head in (2.0, 6.0):
        groups = numba_cache._split(entries, 2, (head, 0.0))
        assert sorted(e["kernel"] for g in groups for e in g) == sorted(e["kernel"] for e in entries)
        loads = [sum(e["seconds"] for e in group) for group in groups]
        assert loads[0] < min(even)
        largest = max(e["seconds"] for e in entries if e["kernel"].rpartition(".")[0]
                      not in numba_cache._GAMMA_CALLERS)
        assert abs(loads[0] + head - loads[1]) <= largest
        gamma_groups = {i for i, group in enumerate(groups) for e in group
                        if e["kernel"].rpartition(".")[0] in numba_cache._GAMMA_CALLERS}
        assert len(gamma_groups) == 1


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

    monkeypatch.setattr(numba_cache, "kernels_compiled", lambda: False)
    monkeypatch.setattr(spco.synthetic_transfer, "run_demo", stop)
    monkeypatch.setattr("os.cpu_count", lambda: 2)
    result = CliRunner().invoke(main, ["demo", "--out", "unused"])
    assert isinstance(result.exception, Stop)
    assert numba_cache.precompile_notice(2) in result.stderr
    assert f"about {numba_cache.PRECOMPILE_SECONDS_ESTIMATE} s" in result.stderr
    assert [(c["processes"], c["compile_first"]) for c in calls] == [(2, True)]


def test_compile_shares_are_the_split_of_precompile(monkeypatch):
    """Share i of n compiles exactly group i of the split (each kernel in one share)."""
    compiled: list[list[str]] = []
    monkeypatch.setattr(numba_cache, "_compile_group",
                        lambda entries: compiled.append([e["kernel"] for e in entries]) or 0.0)
    numba_cache.compile_share(0, 2)
    numba_cache.compile_share(1, 2)
    groups = numba_cache._split(_entries(), 2)
    assert compiled == [[e["kernel"] for e in group] for group in groups]


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
    monkeypatch.setattr(numba_cache, "precompile", lambda processes: calls.append(processes) or 0.0)
    monkeypatch.setattr(numba_cache, "kernels_compiled", lambda: False)
    kfile = tmp_path / "k.spco"
    result = CliRunner().invoke(fit, ["--data", str(tmp_path / "experienced"), "--iterations", "2",
                                      "--out", str(kfile)])
    assert result.exit_code == 0, result.output
    assert numba_cache.precompile_notice(2) in result.stderr and calls == [2]
    home = next((tmp_path / "new").iterdir())
    result = CliRunner().invoke(adapt, [str(kfile), "--home", str(home), "--iterations", "2",
                                        "--out", str(tmp_path / "h.spco")])
    assert result.exit_code == 0, result.output
    assert calls == [2, 2]
    monkeypatch.setattr(numba_cache, "kernels_compiled", lambda: True)
    result = CliRunner().invoke(adapt, [str(kfile), "--home", str(home), "--iterations", "2",
                                        "--out", str(tmp_path / "h2.spco")])
    assert result.exit_code == 0 and calls == [2, 2] and "Compiling" not in result.stderr


def test_signature_file_lists_exactly_what_the_demo_s_warm_up_calls():
    """Every kernel and argument types the demo's warm-up fit calls from Python is in the file
    (else a first run compiles it after the 2-process compilation, alone), and nothing else (else
    the first run compiles what no fit calls). Checked in a fresh process: kernels loaded from the
    on-disk cache load no callee, so its compiled signatures are the ones called from Python."""
    used = numba_cache.called_signatures()
    listed = {e["kernel"]: {tuple(s) for s in e["signatures"]} for e in _entries()}
    hint = "regenerate it: SPCO_CACHE_DIR=$(mktemp -d) python -m spco.model.numba_cache"
    assert {k: v - listed.get(k, set()) for k, v in used.items() if v - listed.get(k, set())} == {}, hint
    assert {k: v - used.get(k, set()) for k, v in listed.items() if v - used.get(k, set())} == {}, hint
