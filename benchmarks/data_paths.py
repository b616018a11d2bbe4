"""Where the benchmarks find the shared data sets by default: ``$SPCO_SIGVERSE`` for the SIGVerse data
(as the tests read it), else ``../shared/datasets/sigverse`` beside the project (not the working
directory), so a script gives the same default wherever it is run from."""

from __future__ import annotations

import os
from pathlib import Path

#: The project's folder (the parent of ``benchmarks/``).
ROOT = Path(__file__).resolve().parents[1]
#: The SIGVerse data set where ``$SPCO_SIGVERSE`` does not say: ``../shared/datasets/sigverse`` beside
#: the project.
SIGVERSE_DEFAULT = ROOT.parent / "shared" / "datasets" / "sigverse"


def sigverse_path() -> Path:
    """The SIGVerse data set: ``$SPCO_SIGVERSE`` (read now), else :data:`SIGVERSE_DEFAULT`; the one
    definition for the benchmarks and the tests (``tests/conftest.py``)."""
    return Path(os.environ.get("SPCO_SIGVERSE") or SIGVERSE_DEFAULT)


#: The SIGVerse data set when the script started (:func:`sigverse_path`).
SIGVERSE = sigverse_path()
#: The folder of the shared data sets (``sigverse``, ``sigverse_images``, ``sigverse_subject``, …).
DATASETS = SIGVERSE.parent
