"""`spco`'s start-up: registering the commands (``spco --help``, importing :mod:`spco.cli.main`) imports
nothing heavy; the options whose defaults or choices are the library's read them when needed."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest
from click.testing import CliRunner

from spco.cli import main

SRC = Path(__file__).resolve().parents[1] / "src"

#: Packages a command's registration must not import (Numba alone took about 1 s of every command).
HEAVY = ("numba", "scipy", "numpy", "llvmlite", "spco.model", "spco.knowledge", "spco.features",
         "spco.service.teaching")


def _imported(code: str) -> list[str]:
    """The heavy modules imported by a fresh Python that runs ``code`` (spco from this tree)."""
    probe = (f"import sys\n{code}\nimport json\nheavy = {HEAVY!r}\n"
             "print(json.dumps(sorted(m for m in sys.modules if any(m == h or m.startswith(h + '.') "
             "for h in heavy))))")
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(SRC), os.environ.get("PYTHONPATH", "")])}
    done = subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True, env=env, check=True,
                          timeout=120)
    return json.loads(done.stdout.strip().splitlines()[-1])


def _help(*args: str) -> str:
    argv = [*args, "--help"]
    return f"from spco.cli.main import main\ntry:\n    main({argv!r})\nexcept SystemExit:\n    pass"


@pytest.mark.parametrize("code", ["import spco.cli.main", "import spco.cli", _help()],
                         ids=["main", "cli", "help"])
def test_registering_the_commands_imports_nothing_heavy(code: str) -> None:
    assert _imported(code) == []


def test_the_probe_sees_a_heavy_import() -> None:
    # `spco what --help` lists the colour orders of spco.features.pixels: it imports spco.features
    assert "spco.features.pixels" in _imported(_help("what"))


def test_library_defaults_and_choices_are_the_librarys() -> None:
    from spco.features.pixels import RAW_ENCODINGS
    from spco.knowledge import DEFAULT_LIMITS
    from spco.service.teaching import DEFAULT_UNDO_LIMIT

    serve = main.commands["serve"]
    ctx = serve.make_context("serve", ["home.spco"], resilient_parsing=True)
    assert ctx.params["undo_limit"] == DEFAULT_UNDO_LIMIT
    for name in ("max_sentence_words", "max_new_words", "max_home_words", "max_observations_per_minute"):
        assert ctx.params[name] == getattr(DEFAULT_LIMITS, name)
    text = CliRunner().invoke(main, ["serve", "--help"], terminal_width=200).output
    assert f"[default: {DEFAULT_UNDO_LIMIT}; x>=0]" in text
    assert f"[default: {DEFAULT_LIMITS.max_sentence_words}; x>=1]" in text
    given = serve.make_context("serve", ["home.spco", "--undo-limit", "3"], resilient_parsing=True)
    assert given.params["undo_limit"] == 3

    for command in ("what", "teach"):
        encoding = next(p for p in main.commands[command].params if p.name == "encoding")
        assert encoding.type.choices == tuple(RAW_ENCODINGS)
        refused = CliRunner().invoke(main, [command, "home.spco", "--x", "0", "--y", "0", "--theta", "0",
                                            "--encoding", "rgb9"])
        assert refused.exit_code == 2 and "'rgb9' is not one of" in refused.output


def test_what_and_teach_take_the_same_view_options() -> None:
    def view(command: str) -> list[tuple[str, ...]]:
        names = ("visual", "visual_scale", "image", "encoding", "model_file")
        return [tuple(p.opts) for p in main.commands[command].params if p.name in names]

    assert view("what") == view("teach") == [("--visual",), ("--visual-scale",), ("--image",),
                                              ("--encoding",), ("--onnx-model",)]
