"""The write lock of knowledge and home files: :mod:`spco.knowledge.locking` (this module keeps the
path ``spco.locking`` working)."""

from spco.knowledge.locking import (
    DEFAULT_TIMEOUT,
    HeldLock,
    HomeServedError,
    LockTimeoutError,
    adopt,
    hold,
    lock_path,
    locked,
    served_by,
)

__all__ = ["DEFAULT_TIMEOUT", "HeldLock", "HomeServedError", "LockTimeoutError", "adopt", "hold", "lock_path",
           "locked", "served_by"]
