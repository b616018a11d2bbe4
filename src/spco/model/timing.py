"""Wall time per sampler step, for ``spco bench`` (:class:`StepTimer`, re-exported by
:mod:`spco.model.gibbs`)."""

from __future__ import annotations

import time


class StepTimer:
    """Accumulates wall time per sampler step (for ``spco bench``): ``timer.seconds[name]``."""

    def __init__(self) -> None:
        self.seconds: dict[str, float] = {}

    def __call__(self, name: str):
        return _Timed(self, name)


class _Timed:
    def __init__(self, timer: StepTimer | None, name: str) -> None:
        self.timer, self.name = timer, name

    def __enter__(self) -> None:
        self.start = time.perf_counter()

    def __exit__(self, *exc: object) -> None:
        if self.timer is not None:
            elapsed = time.perf_counter() - self.start
            self.timer.seconds[self.name] = self.timer.seconds.get(self.name, 0.0) + elapsed
