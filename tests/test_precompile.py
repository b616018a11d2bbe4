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
