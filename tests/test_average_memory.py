"""The posterior average's low-memory paths give the same parameters as the plain ones: each
home's θ^v read from its own state (no joined copy) and the result built in the sums' memory."""

from __future__ import annotations

import numpy as np

from spco.data.synthetic import SyntheticConfig, generate_homes
from spco.model.driver import start_run
from spco.model.posterior import ParameterAverage
from spco.model.state import PreparedData
from spco.model.transfer import SpCoTransfer


def test_per_home_visual_rows_and_release_give_the_same_average() -> None:
    corpus = generate_homes(4, seed=5, config=SyntheticConfig(n_features=64, n_train=30, n_test=5),
                            new_homes=1, specific_rooms=False)
    model = SpCoTransfer(n_iterations=1, random_state=5, progress=False)
    data = PreparedData.from_corpus(corpus, model.position_scale)
    run = start_run(None, data, len(corpus.vocabulary), model.checked_hyperparameters(),
                    model.sampler_settings(), np.random.default_rng(5))
    plain = ParameterAverage(data.homes, data.position_scale)
    rows = ParameterAverage(data.homes, data.position_scale)
    for iteration in range(4):  # several samples: label matching and log sums across sweeps
        run.sweep(iteration)
        plain.add(run.state())
        partial = run.state(visual=False)
        assert partial.log_theta_v is None
        rows.add(partial, visual=run.home_visual())
    state = run.state()
    expected = plain.result(state)
    again = plain.result(state)  # without release the average can be read again
    got = rows.result(state, release=True)
    for name in ("visual_probabilities", "word_probabilities", "concept_weights", "region_weights",
                 "region_means", "region_covariances"):
        assert np.array_equal(getattr(expected, name), getattr(got, name)), name
        assert np.array_equal(getattr(expected, name), getattr(again, name)), name


def test_a_fit_averages_each_thinned_sweep_once_the_last_after_its_workers_are_dropped(monkeypatch) -> None:
    """The fit's peak memory: the last sweep's joined state enters the average (whose (E, L, D) sums
    it may allocate) only after the workers (their states, data views and caches) are dropped; the
    earlier averaged sweeps are read per home, without a joined θ^v."""
    from spco.model import driver, transfer
    from spco.model.posterior import thinned_sweeps

    events: list[tuple[str, object]] = []
    add, close = ParameterAverage.add, driver.LocalRun.close

    def recording_add(self, state, visual=None):
        events.append(("add", state.log_theta_v is None))
        return add(self, state, visual)

    def recording_close(self):
        events.append(("close", None))
        return close(self)

    monkeypatch.setattr(ParameterAverage, "add", recording_add)
    monkeypatch.setattr(driver.LocalRun, "close", recording_close)
    corpus = generate_homes(3, seed=2, config=SyntheticConfig(n_features=32, n_train=12, n_test=3),
                            new_homes=1, specific_rooms=False)
    n = 12
    model = transfer.SpCoTransfer(n_iterations=n, random_state=2, progress=False).fit(corpus)
    averaged = thinned_sweeps(n)
    assert len(averaged) == 3
    # every averaged sweep but the last per home (no joined θ^v), then the workers dropped, then the last
    assert events == [("add", True)] * (len(averaged) - 1) + [("close", None), ("add", False)]
    assert np.isfinite(model.log_joint_).all() and model.log_joint_.shape == (n,)
