"""Run the command blocks of Markdown pages as a reader would, to check that they work as written.

Every fenced block marked ``bash`` (run with ``bash -euo pipefail``) or ``python`` of each page is
run in order, in one scratch folder per page, so that a block can use the files an earlier block of
the same page wrote. Blocks are run as written, with three substitutions a reader makes too:

- ``pip install -e .`` / ``-e ".[extra]"`` installs this repository (the scratch folder is not a
  clone of it);
- a line ``D=path/to/datasets`` sets ``D`` to ``--datasets`` (a folder holding ``sigverse/`` and
  ``sigverse_regions.json``); without ``--datasets`` such blocks are skipped;
- a block running the test suite (``pytest``) is skipped unless ``--with-tests`` (CI runs it).

A block preceded by ``<!-- blocks: not run (reason) -->`` is listed as not run, with its reason; one
preceded by ``<!-- blocks: run in the repository -->`` runs in this repository's folder, as a
developer in a clone runs it. A block preceded by ``<!-- blocks: in the background (wait for URL)
-->`` is a server a reader leaves running in another terminal: it is started, the next block runs
once ``URL`` answers, and it is stopped (SIGTERM, as Ctrl-C) when that next block has run.
Prints each block's status and time (its output goes to ``block-<line>.log`` in the page's folder;
``--keep`` keeps it), and exits with status 1 at the first block that fails::

    python tools/run_doc_blocks.py README.md docs/tutorial.md --datasets ../shared/datasets
"""

from __future__ import annotations

import argparse
import os
import re
import shutil
import signal
import subprocess
import sys
import tempfile
import time
import urllib.error
import urllib.request
from dataclasses import dataclass
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
_OPEN = re.compile(r"^```(bash|python)\s*$")
# a marker is a line of its own (a page may mention one in its text, as docs/development.md does)
_NOT_RUN = re.compile(r"^\s*<!--\s*blocks:\s*not run\s*\((.*)\)\s*-->\s*$")
_IN_REPO = re.compile(r"^\s*<!--\s*blocks:\s*run in the repository\s*-->\s*$")
_BACKGROUND = re.compile(r"^\s*<!--\s*blocks:\s*in the background\s*\(wait for (\S+)\)\s*-->\s*$")
#: Seconds a background block has to answer at its URL.
BACKGROUND_WAIT = 300.0
_DATASETS = re.compile(r"^D=path/to/datasets\b.*$", re.MULTILINE)
_PIP_EDITABLE = re.compile(r"""pip install (-q )?-e (?:"\.(\[[\w,]+\])"|\.(?=\s|$))""")


@dataclass
class Block:
    """One fenced block of a page: its language, its text, its first line, why it is not run,
    whether it runs in the repository's folder, and the URL to wait for when it runs in the
    background."""

    language: str
    text: str
    line: int
    not_run: str | None = None
    in_repo: bool = False
    wait_for: str | None = None


def blocks(page: Path) -> list[Block]:
    """The ``bash`` and ``python`` blocks of ``page``, in order."""
    found: list[Block] = []
    lines = page.read_text(encoding="utf-8").splitlines()
    i, reason, in_repo, wait_for = 0, None, False, None
    while i < len(lines):
        marker = _NOT_RUN.search(lines[i])
        if marker:
            reason = marker.group(1)
        in_repo = in_repo or bool(_IN_REPO.search(lines[i]))
        background = _BACKGROUND.search(lines[i])
        if background:
            wait_for = background.group(1)
        match = _OPEN.match(lines[i])
        if match:
            start, body = i + 1, []
            i += 1
            while i < len(lines) and not lines[i].startswith("```"):
                body.append(lines[i])
                i += 1
            found.append(Block(match.group(1), "\n".join(body) + "\n", start, reason, in_repo, wait_for))
            reason, in_repo, wait_for = None, False, None
        elif lines[i].startswith("```"):  # another language: skip to its end
            i += 1
            while i < len(lines) and not lines[i].startswith("```"):
                i += 1
        i += 1
    return found


def prepared(block: Block, datasets: Path | None, with_tests: bool) -> tuple[str | None, str]:
    """The text to run (``None`` when skipped) and what was substituted or why it is skipped."""
    if block.not_run:
        return None, f"not run: {block.not_run}"
    text, notes = block.text, []
    if re.search(r"\bpytest\b", text) and not with_tests:
        return None, "skipped: runs the test suite (--with-tests to run it)"
    if _DATASETS.search(text):
        if datasets is None:
            return None, "skipped: needs --datasets"
        text = _DATASETS.sub(f"D={datasets}", text)
        notes.append(f"D={datasets}")

    def install(match: re.Match[str]) -> str:
        extra = match.group(2) or ""
        return f'pip install -q -e "{ROOT}{extra}"'

    if _PIP_EDITABLE.search(text) and not block.in_repo:
        text = _PIP_EDITABLE.sub(install, text)
        notes.append("pip installs this repository")
    return text, "; ".join(notes)


def _answers(url: str) -> bool:
    """Whether ``url`` answers (any HTTP status counts: the server is up)."""
    try:
        with urllib.request.urlopen(url, timeout=2):
            return True
    except urllib.error.HTTPError:
        return True
    except (urllib.error.URLError, OSError):
        return False


def start_background(command: list[str], cwd: Path, log: Path, url: str,
                     wait: float = BACKGROUND_WAIT) -> tuple[subprocess.Popen[bytes] | None, str]:
    """Start ``command`` in its own process group, its output to ``log``, and wait until ``url``
    answers: the process, or ``None`` with why it is not up (it ended, or ``wait`` seconds passed)."""
    with log.open("wb") as out:
        process = subprocess.Popen(command, cwd=cwd, stdout=out, stderr=subprocess.STDOUT,
                                   start_new_session=True)
    deadline = time.monotonic() + wait
    while time.monotonic() < deadline:
        if _answers(url):
            return process, f"up at {url}"
        if process.poll() is not None:
            return None, f"ended (exit {process.returncode}) before {url} answered"
        time.sleep(0.5)
    stop_background(process)
    return None, f"{url} did not answer within {wait:.0f} s"


def stop_background(process: subprocess.Popen[bytes], grace: float = 60.0) -> int:
    """SIGTERM the process group of ``process`` (a reader's Ctrl-C), SIGKILL after ``grace``
    seconds; its exit status."""
    if process.poll() is None:
        try:
            os.killpg(process.pid, signal.SIGTERM)
            process.wait(grace)
        except subprocess.TimeoutExpired:
            os.killpg(process.pid, signal.SIGKILL)
            process.wait()
        except ProcessLookupError:
            process.wait()
    return process.returncode


def run_page(page: Path, datasets: Path | None, with_tests: bool, keep: bool,
             lines: set[int] | None = None, folder: Path | None = None) -> bool:
    """Run the blocks of ``page`` (those opening at ``lines``, if given) in ``folder`` or a new
    scratch folder; False at the first failure."""
    work = folder or Path(tempfile.mkdtemp(prefix=f"doc-blocks-{page.stem}-"))
    keep = keep or folder is not None
    print(f"== {page} (in {work})")
    ok = True
    background: tuple[Block, subprocess.Popen[bytes]] | None = None
    for block in blocks(page):
        if lines and block.line not in lines:
            continue
        text, note = prepared(block, datasets, with_tests)
        head = f"  line {block.line} ({block.language})"
        if text is None:
            print(f"{head}: {note}")
            continue
        command = (["bash", "-euo", "pipefail", "-c", text] if block.language == "bash"
                   else [sys.executable, "-c", text])
        start = time.perf_counter()
        cwd = ROOT if block.in_repo else work
        log = work / f"block-{block.line}.log"
        if block.wait_for:
            process, status = start_background(command, cwd, log, block.wait_for)
            print(f"{head}: in the background, {status} after {time.perf_counter() - start:.1f} s"
                  + (f" [{note}]" if note else ""))
            if process is None:
                print(log.read_text(encoding="utf-8", errors="replace")[-3000:])
                ok = False
                break
            background = (block, process)
            continue
        result = subprocess.run(command, cwd=cwd, capture_output=True, text=True)
        seconds = time.perf_counter() - start
        log.write_text(result.stdout + result.stderr, encoding="utf-8")
        status = "ok" if result.returncode == 0 else f"FAILED (exit {result.returncode})"
        print(f"{head}: {status} in {seconds:.1f} s" + (f" [{note}]" if note else ""))
        if background is not None:
            server, process = background
            code = stop_background(process)
            print(f"  line {server.line}: stopped (exit {code})")
            background = None
        if result.returncode != 0:
            print(result.stdout[-3000:], result.stderr[-3000:], sep="\n")
            ok = False
            break
    if background is not None:
        server, process = background
        print(f"  line {server.line}: stopped (exit {stop_background(process)})")
    if not keep:
        shutil.rmtree(work, ignore_errors=True)
    return ok


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("pages", nargs="+", type=Path, help="Markdown pages")
    parser.add_argument("--datasets", type=Path, help="folder holding sigverse/ and sigverse_regions.json")
    parser.add_argument("--with-tests", action="store_true", help="also run blocks that run pytest")
    parser.add_argument("--keep", action="store_true", help="keep the scratch folders")
    parser.add_argument("--lines", type=int, nargs="+",
                        help="run only the blocks whose code starts at these lines")
    parser.add_argument("--folder", type=Path, help="run in this folder (kept) instead of a scratch one")
    args = parser.parse_args(argv)
    datasets = args.datasets.resolve() if args.datasets else None
    lines = set(args.lines or ())
    ok = all([run_page(page, datasets, args.with_tests, args.keep, lines, args.folder)
              for page in args.pages])
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
