"""A home read with the sentences of every teaching rate it can give: what the loaders read
(:func:`spco.data.loading.read_records`) and the cache stores (:mod:`spco.data.cache`)."""

from __future__ import annotations

from dataclasses import dataclass

from spco.data.environment import Environment
from spco.data.sigverse import RatesMap, select_rate

__all__ = ["HomeRecord"]


@dataclass(frozen=True)
class HomeRecord:
    """A home with the sentences of every teaching rate it can give (used by loaders and the cache).

    ``rates`` maps a teaching rate to the sentences taught at that rate (SIGVerse homes; empty when
    nothing was taught at all); ``None`` means the home has one set of sentences, ``environment``'s,
    of which :meth:`at_rate` keeps a seeded random subset.
    """

    environment: Environment
    rates: RatesMap | None
    where: str

    def at_rate(self, teaching_rate: int) -> Environment:
        """The home as taught at ``teaching_rate`` percent."""
        if self.rates is None:
            env = self.environment
            return env if teaching_rate == 100 else env.with_teaching_rate(teaching_rate, seed=0)
        return select_rate(self.environment, self.rates, teaching_rate, self.where)
