"""The write lock of knowledge and home files: :mod:`spco.knowledge.locking` (this module keeps the
path ``spco.locking`` working)."""

from spco.knowledge.locking import LockTimeoutError, lock_path, locked

__all__ = ["LockTimeoutError", "lock_path", "locked"]
