"""A home served while the robot runs: :class:`LiveHome` (in-process), ``spco serve`` (HTTP).

- :mod:`spco.service.live` — :class:`LiveHome`: the last committed snapshot for readers, one writer
  for teachings (a process of its own by default), events.
- :mod:`spco.service.journal` — the append-only journal beside the home file (durable teachings).
- :mod:`spco.service.teaching` — teachings as journal records: batched (one call of the home a batch),
  replayed, undone;
  :func:`~spco.service.teaching.load_current` (the file plus its journal, for read-only commands).
- :mod:`spco.service.writer` — the one writer of a served home.
- :mod:`spco.service.answers` — the JSON answers shared with ``spco where|what --json``.
- :mod:`spco.service.app` — the HTTP app of ``spco serve`` (needs ``pip install 'spco[serve]'``).

Nothing here imports the web stack but :mod:`spco.service.app` and :mod:`spco.service.server`.
"""

from __future__ import annotations

from typing import Any

__all__ = ["LiveHome", "Subscription"]


def __getattr__(name: str) -> Any:
    if name in __all__:
        from spco.service import live

        return getattr(live, name)
    raise AttributeError(f"module 'spco.service' has no attribute {name!r}")
