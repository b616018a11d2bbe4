"""The documentation: the MkDocs site builds without a warning, and the README stays a short guide.

``mkdocs build --strict`` fails on any warning: a page in ``nav`` that does not exist, a link to a
missing page or anchor, an include (``--8<--``) of a missing file, or a docstring that mkdocstrings
cannot render (a parameter documented but not in the signature, a malformed section). The README is
not part of the site, so its links are checked here.
"""

from __future__ import annotations

import importlib.util
import os
import re
import socket
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
README = ROOT / "README.md"
README_MAX_LINES = 300
#: The install-and-test command of the README, which ``.ci/run`` runs as it is.
TEST_COMMAND = 'pip install -e ".[test]" && pytest -q'

_LINK = re.compile(r"(?<!!)\[[^\]]*\]\(([^)\s]+)\)|!\[[^\]]*\]\(([^)\s]+)\)")
_FENCE = re.compile(r"^(```|~~~)")


def _require_mkdocs() -> None:
    """Skip without MkDocs outside CI; under CI (``CI=true``) its absence is a failure."""
    missing = [m for m in ("mkdocs", "material", "mkdocstrings") if importlib.util.find_spec(m) is None]
    if missing:
        reason = f"{', '.join(missing)} not installed (pip install -e '.[docs]')"
        if os.environ.get("CI"):
            pytest.fail(reason)
        pytest.skip(reason)


def _slug(heading: str) -> str:
    """The anchor GitHub and MkDocs give a Markdown heading (lower case, punctuation dropped)."""
    text = re.sub(r"[`*_]", "", heading.strip().lower())
    text = re.sub(r"[^\w\- ]", "", text)
    return text.replace(" ", "-")


def _anchors(path: Path) -> set[str]:
    anchors, fenced = set(), False
    for line in path.read_text(encoding="utf-8").splitlines():
        if _FENCE.match(line):
            fenced = not fenced
        elif not fenced and line.startswith("#"):
            anchors.add(_slug(line.lstrip("#")))
    return anchors


def _links(path: Path) -> list[str]:
    """The link and image targets of a Markdown file, outside code blocks and inline code."""
    targets, fenced = [], False
    for line in path.read_text(encoding="utf-8").splitlines():
        if _FENCE.match(line):
            fenced = not fenced
            continue
        if fenced:
            continue
        line = re.sub(r"`[^`]*`", "", line)
        targets += [a or b for a, b in _LINK.findall(line)]
    return targets


def broken_links(path: Path) -> list[str]:
    """Relative links of ``path`` whose file, or whose anchor in a Markdown file, does not exist."""
    broken = []
    for target in _links(path):
        if re.match(r"^[a-z][a-z0-9+.-]*:", target):  # http:, https:, mailto:
            continue
        file, _, anchor = target.partition("#")
        dest = (path.parent / file).resolve() if file else path
        if not dest.exists():
            broken.append(f"{target}: no such file")
        elif anchor and dest.suffix == ".md" and anchor not in _anchors(dest):
            broken.append(f"{target}: no such heading in {dest.name}")
    return broken


def test_readme_is_a_short_guide() -> None:
    lines = README.read_text(encoding="utf-8").splitlines()
    assert len(lines) <= README_MAX_LINES, f"README.md has {len(lines)} lines (at most {README_MAX_LINES})"


def test_readme_test_command_is_what_ci_runs() -> None:
    assert TEST_COMMAND in README.read_text(encoding="utf-8")
    assert TEST_COMMAND in (ROOT / ".ci" / "run").read_text(encoding="utf-8")


@pytest.mark.parametrize("name", ["README.md", "CHANGELOG.md", "benchmarks/README.md"])
def test_links_resolve(name: str) -> None:
    assert broken_links(ROOT / name) == []


def test_link_checker_finds_broken_links(tmp_path: Path) -> None:
    (tmp_path / "other.md").write_text("# A heading\n\ntext\n")
    page = tmp_path / "page.md"
    page.write_text("[ok](other.md#a-heading) [gone](missing.md) [bad](other.md#nope) "
                    "[web](https://example.org/x) `[code](missing.md)`\n```\n[fenced](missing.md)\n```\n")
    assert broken_links(page) == ["missing.md: no such file", "other.md#nope: no such heading in other.md"]


def test_mkdocs_build_strict(tmp_path: Path) -> None:
    _require_mkdocs()
    site = tmp_path / "site"
    result = subprocess.run(
        [sys.executable, "-m", "mkdocs", "build", "--strict", "--config-file", str(ROOT / "mkdocs.yml"),
         "--site-dir", str(site)],
        cwd=ROOT, capture_output=True, text=True, timeout=600,
        env={**os.environ, "NO_MKDOCS_2_WARNING": "1"})
    assert result.returncode == 0, result.stdout + result.stderr
    assert (site / "index.html").is_file()
    assert (site / "tutorial" / "index.html").is_file()
    # the command-line reference shows each option's real default: no click sentinel (an option
    # without a default reads "None"), and the defaults the options declare
    cli = (site / "reference" / "cli" / "index.html").read_text(encoding="utf-8")
    assert "Sentinel" not in cli and "UNSET" not in cli
    assert "<td><code>spco-demo</code></td>" in cli  # spco demo --out
    assert "<td>None</td>" in cli


def _griffe_spco():
    _require_mkdocs()
    spec = importlib.util.spec_from_file_location("griffe_spco", ROOT / "tools" / "griffe_spco.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_docstrings_are_rewritten_for_the_numpy_parser() -> None:
    rewrite = _griffe_spco().rewrite
    text = ("Fit it.\n\nParameters\n----------\ncorpus: the homes (a :class:`~spco.data.Corpus`), or a\n"
            "    folder.\nrng, seed: a generator; progress: show a bar.\n\nConventions: NaN is left out.\n\n"
            "Returns\n-------\nThe :func:`spco.knowledge.fit_knowledge` result.\n")
    assert rewrite(text, "Knowledge", {"corpus", "rng", "seed", "progress"}).split("\n") == [
        "Fit it.", "", "Parameters", "----------",
        "corpus", "    the homes (a `Corpus`), or a", "    folder.",
        "rng", "    a generator", "seed", "    a generator", "progress", "    show a bar.", "",
        "Notes", "-----", "Conventions: NaN is left out.", "",
        "Returns", "-------", "Knowledge", "    The `spco.knowledge.fit_knowledge` result.", ""]


def _run_doc_blocks():
    spec = importlib.util.spec_from_file_location("run_doc_blocks", ROOT / "tools" / "run_doc_blocks.py")
    module = importlib.util.module_from_spec(spec)
    sys.modules["run_doc_blocks"] = module  # dataclasses look their module up by name
    spec.loader.exec_module(module)
    return module


def test_doc_blocks_run_in_order_with_a_server_in_the_background(tmp_path: Path,
                                                                 capsys: pytest.CaptureFixture[str]) -> None:
    tool = _run_doc_blocks()
    with socket.socket() as probe:
        probe.bind(("127.0.0.1", 0))
        port = probe.getsockname()[1]
    url = f"http://127.0.0.1:{port}/"
    page = tmp_path / "page.md"
    page.write_text(
        "<!-- blocks: not run (needs a robot) -->\n```bash\nexit 1\n```\n\n"
        "```bash\necho served > index.html\n```\n\n"
        f"<!-- blocks: in the background (wait for {url}) -->\n```bash\n"
        f"{sys.executable} -m http.server {port} --bind 127.0.0.1\n```\n\n"
        f"```python\nimport urllib.request\n"
        f"assert urllib.request.urlopen('{url}').read() == b'served\\n'\n```\n\n"
        "```python\nraise SystemExit(3)\n```\n", encoding="utf-8")
    work = tmp_path / "work"
    work.mkdir()
    assert not tool.run_page(page, None, False, keep=True, folder=work)
    out = capsys.readouterr().out
    assert "not run: needs a robot" in out
    assert f"in the background, up at {url}" in out
    assert re.search(r"line 1\d \(python\): ok", out)  # the block after the server reached it
    assert "stopped (exit" in out
    assert "FAILED (exit 3)" in out
    with socket.socket() as probe:  # the server is gone: nothing listens on its port
        probe.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)  # the client's TIME_WAIT is fine
        probe.bind(("127.0.0.1", port))


def test_a_marker_mentioned_in_the_text_is_not_a_marker(tmp_path: Path) -> None:
    """Only a line of its own marks the next block: prose that shows the syntax does not."""
    tool = _run_doc_blocks()
    page = tmp_path / "page.md"
    page.write_text("Write `<!-- blocks: not run (reason) -->` before a block to skip it:\n\n"
                    "<!-- blocks: run in the repository -->\n```bash\ntrue\n```\n\n"
                    "<!-- blocks: not run (needs a robot) -->\n```bash\nexit 1\n```\n", encoding="utf-8")
    first, second = tool.blocks(page)
    assert first.not_run is None and first.in_repo
    assert second.not_run == "needs a robot"
