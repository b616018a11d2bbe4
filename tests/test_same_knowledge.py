"""One start, any shards: `spco fit` gives the same knowledge for a seed whatever the number of
shards and the engine.

Every home draws from its own random stream (seeded from the fit's seed and the home's index) and
the driver sums the homes' statistics exactly, so one process, 2 and 4 local shards and 2 Ray
actors run the same chain and write the same knowledge, array for array."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

from spco.cli import main
from spco.data.plain import write_corpus
from spco.data.synthetic import SyntheticConfig, generate_homes
from spco.knowledge import Knowledge

ITERATIONS = "8"


@pytest.fixture(scope="module")
def fleet(tmp_path_factory) -> Path:
    """Six small synthetic homes (one new, untaught) in the plain format."""
    root = tmp_path_factory.mktemp("fleet")
    write_corpus(generate_homes(6, seed=4, config=SyntheticConfig(n_features=64, n_train=12), new_homes=1),
                 root)
    return root


def fit(fleet: Path, out: Path, *options: str) -> Knowledge:
    result = CliRunner().invoke(main, ["fit", "--data", str(fleet), "--out", str(out), "--iterations",
                                       ITERATIONS, "--seed", "7", *options])
    assert result.exit_code == 0, result.output
    return Knowledge.load(out)


def assert_same_knowledge(a: Knowledge, b: Knowledge) -> None:
    arrays_a, header_a = a._arrays_and_header()
    arrays_b, header_b = b._arrays_and_header()
    assert sorted(arrays_a) == sorted(arrays_b)
    for name in arrays_a:
        np.testing.assert_array_equal(arrays_a[name], arrays_b[name], err_msg=name)
    assert header_a["vocabulary"] == header_b["vocabulary"]
    for key in ("summary", "view_fit", "n_samples", "homes"):
        assert a.provenance[key] == b.provenance[key], key


@pytest.fixture(scope="module")
def one_process(fleet, tmp_path_factory) -> Knowledge:
    return fit(fleet, tmp_path_factory.mktemp("one") / "k.spco")


@pytest.mark.parametrize("shards", ["2", "4"])
def test_local_shards_give_the_one_process_knowledge(fleet, one_process, tmp_path, shards: str) -> None:
    """`spco fit --shards 2` and `--shards 4`: the knowledge of `spco fit`, array for array."""
    assert_same_knowledge(fit(fleet, tmp_path / "k.spco", "--shards", shards), one_process)


def test_ray_gives_the_one_process_knowledge(fleet, one_process, tmp_path, ray_session) -> None:
    """`spco fit --engine ray --shards 2`: the knowledge of `spco fit`, array for array."""
    assert_same_knowledge(fit(fleet, tmp_path / "k.spco", "--engine", "ray", "--shards", "2"), one_process)


def test_another_seed_gives_other_knowledge(fleet, one_process, tmp_path) -> None:
    """The test has teeth: the knowledge does depend on the seed."""
    result = CliRunner().invoke(main, ["fit", "--data", str(fleet), "--out", str(tmp_path / "k.spco"),
                                       "--iterations", ITERATIONS, "--seed", "8"])
    assert result.exit_code == 0, result.output
    assert not np.array_equal(Knowledge.load(tmp_path / "k.spco").log_phi_visual, one_process.log_phi_visual)
