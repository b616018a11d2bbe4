"""One definition of a view's weight and of the "unsure" threshold across src/ (issue 29: "grep finds
one place where a view's weight or an unsure threshold is defined"): what, ask, the service, the ROS
node, the page and the experiments read them from there."""

from __future__ import annotations

import ast
from pathlib import Path

from click.testing import CliRunner

import spco
from spco.cli import main
from spco.model.confidence import UNSURE_BELOW
from spco.model.hyperparameters import VIEW_COUNTS

SRC = Path(spco.__file__).parent


def _modules() -> list[tuple[str, ast.Module]]:
    return [(str(path.relative_to(SRC)), ast.parse(path.read_text(encoding="utf-8")))
            for path in sorted(SRC.rglob("*.py"))]


def _number(node: ast.AST) -> bool:
    return isinstance(node, ast.Constant) and isinstance(node.value, int | float) \
        and not isinstance(node.value, bool)


def _about_views(node: ast.AST) -> bool:
    """An expression naming a view's counts or totals (a weight of views, not e.g. of CPUs)."""
    names = {getattr(n, "id", getattr(n, "attr", "")) for n in ast.walk(node)}
    return any("view" in n or "total" in n or "count" in n for n in names)


def test_the_unsure_threshold_is_defined_once() -> None:
    defined, literal_defaults = [], []
    for name, tree in _modules():
        top = set(map(id, tree.body))
        for node in ast.walk(tree):
            targets = node.targets if isinstance(node, ast.Assign) else \
                [node.target] if isinstance(node, ast.AnnAssign) and node.value is not None else []
            for target in targets:  # a module's constant, or a number written into an "unsure" name
                if isinstance(target, ast.Name | ast.Attribute) and "unsure" in getattr(
                        target, "id", getattr(target, "attr", "")).lower() \
                        and (id(node) in top or _number(node.value)):  # type: ignore[union-attr]
                    defined.append((name, getattr(target, "id", getattr(target, "attr", ""))))
            if isinstance(node, ast.FunctionDef | ast.AsyncFunctionDef):
                args = node.args.args + node.args.kwonlyargs
                defaults = [None] * (len(node.args.args) - len(node.args.defaults)) + node.args.defaults \
                    + node.args.kw_defaults
                for arg, default in zip(args, defaults, strict=True):
                    if "unsure" in arg.arg and default is not None and _number(default):
                        literal_defaults.append((name, node.name, arg.arg))
    assert defined == [("model/confidence.py", "UNSURE_BELOW")]
    assert literal_defaults == []  # every unsure_below defaults to UNSURE_BELOW


def test_a_views_weight_is_defined_once() -> None:
    """min(1, w / Σ_d v_d) is written in one function (hyperparameters.view_powers), the default w in
    one constant (VIEW_COUNTS); the sampler, the answers and the view fit call them."""
    powers, constants = [], []
    for name, tree in _modules():
        for node in ast.walk(tree):
            if isinstance(node, ast.Call) and len(node.args) == 2 and _number(node.args[0]) \
                    and node.args[0].value == 1 and isinstance(node.args[1], ast.BinOp) \
                    and isinstance(node.args[1].op, ast.Div) and _about_views(node.args[1]):
                func = node.func
                called = func.attr if isinstance(func, ast.Attribute) else getattr(func, "id", "")
                if called in ("min", "minimum"):
                    powers.append(name)
            if isinstance(node, ast.Assign) and any(isinstance(t, ast.Name) and t.id == "VIEW_COUNTS"
                                                    for t in node.targets):
                constants.append(name)
    assert powers == ["model/hyperparameters.py"]
    assert constants == ["model/hyperparameters.py"] and VIEW_COUNTS > 0


def test_the_command_lines_say_the_threshold_they_use() -> None:
    said = f"{UNSURE_BELOW:g}"
    for command in (["what", "--help"], ["ask", "--help"]):
        result = CliRunner().invoke(main, command, terminal_width=200)
        assert result.exit_code == 0, result.output
        assert f"below {said}" in " ".join(result.output.split()) or f"default {said}" in result.output


def test_the_docs_state_the_targets_as_the_code_runs_them() -> None:
    """README's power target states a view's power as view_powers computes it (min(1, w/Σv), w and W^w
    the code's defaults); the exact "+MI" sampler's words are the word channels (no pruning) unless
    the speech has no English, as docs/samplers.md's table says."""
    import numpy as np

    from spco.model.hyperparameters import WORD_COUNTS, TransferHyperparameters, view_powers
    from spco.model.state import SamplerSettings
    from spco.model.word_channels import uses_word_channels

    root = SRC.parents[1]
    readme = " ".join((root / "README.md").read_text(encoding="utf-8").split())
    assert f"raised to min(1, w/Σv) (w = {VIEW_COUNTS:g} counts)" in readme
    assert f"W^w = {WORD_COUNTS:g} times its occurrences" in readme
    assert np.allclose(view_powers(np.array([8.0, 16.0, 64.0]), VIEW_COUNTS), [1.0, 1.0, 0.25])
    assert uses_word_channels(TransferHyperparameters(), SamplerSettings.create("exact", True))
    samplers = (root / "docs" / "samplers.md").read_text(encoding="utf-8")
    assert "the word channels ([names](model.md): no word pruned)" in samplers


def test_the_held_out_definitions_say_which_views_were_spent() -> None:
    """1DK_8's test views helped choose how sure `what` is (benchmarks/SPLIT.md): README's and
    docs/results.md's definitions of held-out say so where they list specific_heldout.json."""
    root = SRC.parents[1]
    split = " ".join((root / "benchmarks" / "SPLIT.md").read_text(encoding="utf-8").split())
    assert "its home-specific test views (ids 160–179) are among the views that choice was made on" in split
    for page in ("README.md", "docs/results.md"):
        text = " ".join((root / page).read_text(encoding="utf-8").split())
        listed = text.index("specific_heldout.json`")
        assert "but for the two in `1DK_8`" in text[listed:listed + 200], page
