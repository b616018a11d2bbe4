"""Where the benchmarks find the shared data sets by default: ``$SPCO_SIGVERSE`` for the SIGVerse data
(as the tests read it), else ``../shared/datasets/sigverse`` beside the project (not the working
directory), so a script gives the same default wherever it is run from."""

from __future__ import annotations

import os
from pathlib import Path

#: The project's folder (the parent of ``benchmarks/``).
ROOT = Path(__file__).resolve().parents[1]
#: The SIGVerse data set: ``$SPCO_SIGVERSE``, else ``../shared/datasets/sigverse`` beside the project.
SIGVERSE = Path(os.environ.get("SPCO_SIGVERSE") or ROOT.parent / "shared" / "datasets" / "sigverse")
#: The folder of the shared data sets (``sigverse``, ``sigverse_images``, ``sigverse_subject``, …).
DATASETS = SIGVERSE.parent
