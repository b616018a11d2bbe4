"""The write lock of knowledge and home files: :mod:`spco.knowledge.locking` (this module keeps the
path ``spco.locking`` working)."""

from spco.knowledge.locking import (
    HeldLock,
    HomeServedError,
    LockTimeoutError,
    adopt,
    hold,
    lock_path,
    locked,
    served_by,
)

__all__ = ["HeldLock", "HomeServedError", "LockTimeoutError", "adopt", "hold", "lock_path", "locked",
           "served_by"]
