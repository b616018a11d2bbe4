"""Same seed, same chain: the log-joint trace and the concepts after 30 sweeps are pinned.

The expected values in ``tests/data/same_chain.json`` come from this file's generator; a refactor
of the sampler or its kernels (moving code, renaming, sharding the homes) must leave them
unchanged bit for bit. A deliberate change of the chain (e.g. a different random stream) must
regenerate them in a commit of its own saying why:

    PYTHONPATH=src python tests/test_same_chain.py --regenerate
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np
import pytest

from spco.data.synthetic import SyntheticConfig, generate_homes
from spco.model.transfer import SpatialConceptModel

FIXTURE = Path(__file__).resolve().parent / "data" / "same_chain.json"
VARIANTS = ("exact", "reference")
N_SWEEPS = 30


def run_chain(variant: str) -> dict:
    """30 sweeps of ``variant`` (pruning on) on 4 small synthetic homes (one new), seed 3."""
    corpus = generate_homes(4, seed=1, new_homes=1, config=SyntheticConfig(n_features=64, n_train=12))
    model = SpatialConceptModel(variant=variant, n_iterations=N_SWEEPS, random_state=3, prune_words=True)
    model.fit(corpus)
    return {"log_joint": [float(v) for v in model.log_joint_],
            "concepts": [int(c) for c in np.concatenate(model.concepts_)],
            "regions": [int(r) for r in np.concatenate(model.regions_)]}


def _expected() -> dict:
    return json.loads(FIXTURE.read_text())


@pytest.mark.parametrize("variant", VARIANTS)
def test_same_seed_same_chain_as_pinned(variant: str) -> None:
    """The chain of today's sampler: identical log joint (to the last bit) and assignments."""
    expected = _expected()[variant]
    got = run_chain(variant)
    assert got["concepts"] == expected["concepts"]
    assert got["regions"] == expected["regions"]
    assert got["log_joint"] == expected["log_joint"]


if __name__ == "__main__":
    if sys.argv[1:] != ["--regenerate"]:
        sys.exit("usage: PYTHONPATH=src python tests/test_same_chain.py --regenerate")
    FIXTURE.write_text(json.dumps({v: run_chain(v) for v in VARIANTS}) + "\n")
    print(f"wrote {FIXTURE}")
