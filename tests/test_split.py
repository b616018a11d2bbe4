"""No test fits or scores a method on held-out data (benchmarks/SPLIT.md): tests may load held-out
files and homes, but held-out figures come from ``benchmarks/`` only.

The check reads every test module's source (nothing is run): in each function, the held-out things
it names — directly or through a module-level constant — and the fitting or scoring it calls. A
function that does both fails, unless it is listed in :data:`ALLOWED` with the reason it scores no
held-out data (and an entry that is no longer needed fails too, so the list stays true):

- held-out homes: ``1LDK_9``, ``2LDK_9``, ``2LDK_10``, ``1LDK_10``, ``1DK_8`` (SPLIT.md, "Homes");
- held-out sets: ``benchmarks/heldout/`` (``specific_heldout.json``, ``speech2/``, the spent
  ``speech_heldout.csv`` and its name lists) and the people's sentences of the natural-speech held-out
  homes (``sigverse_subject`` with ``1LDK_2``, ``1LDK_4``, ``1LDK_6``, ``1LDK_8``, ``2LDK_2``, …);
- held-out seeds: 100–119 given as a seed (``seed=``, ``random_state=``, ``--seed``, ``--seeds``) in a
  function that uses the SIGVerse data (``sigverse_dir``).
"""

from __future__ import annotations

import ast
import itertools
from dataclasses import dataclass
from pathlib import Path

TESTS = Path(__file__).resolve().parent

HELDOUT_HOMES = frozenset({"1LDK_9", "2LDK_9", "2LDK_10", "1LDK_10", "1DK_8"})
#: The homes whose people's sentences (``sigverse_subject``) are the natural-speech held-out side.
HELDOUT_SPEECH_HOMES = frozenset({"1LDK_2", "1LDK_4", "1LDK_6", "1LDK_8", "2LDK_2", "2LDK_4", "2LDK_6",
                                  "2LDK_8"})
HELDOUT_FILE_MARKS = ("specific_heldout", "speech_heldout", "_names_heldout", "speech2", "heldout/")
HELDOUT_SEEDS = range(100, 120)
SEED_KEYWORDS = frozenset({"seed", "seeds", "random_state", "rng"})
#: Calls that fit or score a method (functions, methods, and the CLI commands a test invokes).
FIT_OR_SCORE = frozenset({"fit", "fit_knowledge", "adapt", "teach", "evaluate_home", "run_experiment",
                          "run_active_experiment", "run_specific_config", "score_home", "what", "where",
                          "predict_names", "predict_positions", "run_trial", "execute_run"})
CLI_FIT_OR_SCORE = frozenset({"experiment", "general", "specific", "active", "fit", "adapt", "teach", "what",
                              "where", "ask", "demo", "bench"})

#: (module, function) -> why it scores no held-out data although it names some and fits.
ALLOWED: dict[tuple[str, str], str] = {
    ("test_confidence.py", "test_sigverse_development_home_is_calibrated"):
        "1DK_8's general test views are the calibration's development views "
        "(benchmarks/calibration/SPLIT.md) and spent for general places; its held-out home-specific "
        "rooms are not scored",
    ("test_specific_config.py", "test_cli_refuses_options_that_do_not_apply"):
        "the command refuses its options before it reads the held-out file: nothing is fitted",
    ("test_benchmark.py", "test_bench_on_sigverse_layout_homes"):
        "tiny synthetic homes in the SIGVerse layout that only borrow the paper's home names",
}


@dataclass(frozen=True)
class Finding:
    """A function that names held-out data and fits or scores."""

    module: str
    function: str
    line: int
    heldout: tuple[str, ...]
    calls: tuple[str, ...]

    def __str__(self) -> str:
        return (f"{self.module}:{self.line} {self.function}() names held-out {', '.join(self.heldout)} and "
                f"calls {', '.join(self.calls)}")


def _strings(node: ast.AST) -> list[str]:
    return [n.value for n in ast.walk(node) if isinstance(n, ast.Constant) and isinstance(n.value, str)]


def _module_constants(tree: ast.Module) -> dict[str, list[str]]:
    """Module-level names bound to expressions holding strings (tuples, paths, dicts, …)."""
    out: dict[str, list[str]] = {}
    for node in tree.body:
        targets: list[ast.expr] = []
        if isinstance(node, ast.Assign):
            targets, value = node.targets, node.value
        elif isinstance(node, ast.AnnAssign) and node.value is not None:
            targets, value = [node.target], node.value
        else:
            continue
        for t in targets:
            if isinstance(t, ast.Name):
                out[t.id] = _strings(value)
    return out


def _heldout_names(strings: list[str], uses_sigverse: bool) -> set[str]:
    found = {s for s in strings if s in HELDOUT_HOMES}
    found |= {s for s in strings if any(m in s for m in HELDOUT_FILE_MARKS)}
    if any("sigverse_subject" in s for s in strings):
        found |= {f"sigverse_subject {s}" for s in strings if s in HELDOUT_SPEECH_HOMES}
    if uses_sigverse and "heldout" in strings:
        found.add("benchmarks/heldout")
    return found


def _seeds(func: ast.AST) -> set[str]:
    """Seeds 100–119 given as a keyword seed or after ``--seed``/``--seeds`` in an argument list."""
    found = set()
    for node in ast.walk(func):
        if isinstance(node, ast.keyword) and node.arg in SEED_KEYWORDS:
            for c in ast.walk(node.value):
                if isinstance(c, ast.Constant) and isinstance(c.value, int) and c.value in HELDOUT_SEEDS:
                    found.add(f"seed {c.value}")
        if isinstance(node, ast.List | ast.Tuple):
            items = node.elts
            for a, b in itertools.pairwise(items):
                if not (isinstance(a, ast.Constant) and isinstance(b, ast.Constant)):
                    continue
                if a.value in ("--seed", "--seeds"):
                    try:
                        value = int(b.value)
                    except (TypeError, ValueError):
                        continue
                    if value in HELDOUT_SEEDS:
                        found.add(f"seed {value}")
    return found


def _calls(func: ast.AST) -> set[str]:
    found = set()
    for node in ast.walk(func):
        if not isinstance(node, ast.Call):
            continue
        name = node.func.attr if isinstance(node.func, ast.Attribute) else getattr(node.func, "id", None)
        if name in FIT_OR_SCORE:
            found.add(name)
        elif name == "invoke":  # CliRunner().invoke(command, [args]): fitting commands only
            words = {getattr(a, "id", None) for a in node.args} | set(_strings(node))
            hits = sorted(w for w in words if w in CLI_FIT_OR_SCORE or w in {"active_command", "experiment"})
            if hits:
                found.add(f"invoke({hits[0]})")
    return found


def scan(source: str, module: str) -> list[Finding]:
    """Every function of ``source`` that names held-out data and fits or scores (see the docstring)."""
    tree = ast.parse(source)
    constants = _module_constants(tree)
    findings = []
    for func in ast.walk(tree):
        if not isinstance(func, ast.FunctionDef | ast.AsyncFunctionDef):
            continue
        names = {n.id for n in ast.walk(func) if isinstance(n, ast.Name)}
        args = {a.arg for a in func.args.args + func.args.kwonlyargs}
        strings = _strings(func)
        for name in names:
            strings += constants.get(name, [])
        docstring = ast.get_docstring(func)
        if docstring is not None:
            strings = [s for s in strings if s != docstring and s != func.body[0].value.value]  # type: ignore
        uses_sigverse = "sigverse_dir" in args | names
        heldout = _heldout_names(strings, uses_sigverse)
        if uses_sigverse:
            heldout |= _seeds(func)
        calls = _calls(func)
        if heldout and calls:
            findings.append(Finding(module, func.name, func.lineno, tuple(sorted(heldout)),
                                    tuple(sorted(calls))))
    return findings


def test_no_test_fits_or_scores_held_out_data() -> None:
    findings = [f for path in sorted(TESTS.glob("*.py")) if path.name != Path(__file__).name
                for f in scan(path.read_text(encoding="utf-8"), path.name)]
    wrong = [str(f) for f in findings if (f.module, f.function) not in ALLOWED]
    assert not wrong, ("tests must not fit or score held-out homes, sets or seeds (benchmarks/SPLIT.md); "
                       "use a development home (3LDK_9, 2LDK_1, 3LDK_9_original, a synthetic home) and seeds "
                       "0-99:\n" + "\n".join(wrong))
    stale = sorted(set(ALLOWED) - {(f.module, f.function) for f in findings})
    assert not stale, f"ALLOWED entries no longer needed (remove them): {stale}"


def test_the_scan_finds_each_kind_of_violation() -> None:
    home = '''
def test_x(sigverse_dir):
    env = load(sigverse_dir / "2LDK_10")["2LDK_10"]
    SpCoTransfer(n_iterations=2).fit(Corpus([env]))
'''
    seed = '''
def test_x(sigverse_dir):
    homes = load_homes(sigverse_dir, names=["3LDK_1", "3LDK_9"])
    fit_knowledge(Corpus(homes), random_state=104)
'''
    cli = '''
HELDOUT = ROOT / "benchmarks" / "heldout" / "specific_heldout.json"

def test_x(tmp_path):
    CliRunner().invoke(experiment, ["specific", "--config", str(HELDOUT), "--out", str(tmp_path)])
'''
    speech = '''
HOMES = ("1LDK_2", "1LDK_4")

def test_x(sigverse_dir):
    subject = sigverse_dir.parent / "sigverse_subject"
    corpus = Corpus([read(subject / h) for h in HOMES])
    evaluate_home(SpCoTransfer().fit(corpus).parameters_, 0, corpus[0], corpus.vocabulary)
'''
    for source, mark in ((home, "2LDK_10"), (seed, "seed 104"), (cli, "specific_heldout"),
                         (speech, "sigverse_subject 1LDK_2")):
        (finding,) = scan(source, "t.py")
        assert any(mark in h for h in finding.heldout), (finding, mark)


def test_the_scan_lets_loading_and_development_data_pass() -> None:
    loading = '''
def test_x(sigverse_dir):
    env = load(sigverse_dir / "2LDK_10")["2LDK_10"]
    assert env.n_samples == 180
'''
    development = '''
def test_x(sigverse_dir):
    """Not 2LDK_9: a held-out home."""
    homes = load_homes(sigverse_dir, names=["3LDK_1", "3LDK_9"])
    fit_knowledge(Corpus(homes), random_state=4)
    CliRunner().invoke(experiment, ["general", "--seed", "1", "--new-homes", "3LDK_9"])
'''
    synthetic_seed = '''
def test_x():
    SpCoTransfer(n_iterations=2, random_state=101).fit(generate_homes(3, seed=0))
'''
    for source in (loading, development, synthetic_seed):
        assert scan(source, "t.py") == []
