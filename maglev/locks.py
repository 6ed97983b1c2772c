"""An exclusive lock on a file, for the places where several processes share one file.

Why one helper: the study's SQLite store (parallel jobs creating runs) and the simulator's
BLA cache (a sweep's background estimating the entry a job is about to need) both hold a
lock file beside the shared one while they work on it.  ``fcntl.flock`` is POSIX; where it
is missing nothing is locked.
"""

from __future__ import annotations

import contextlib
from collections.abc import Iterator
from pathlib import Path

__all__ = ["exclusive"]


@contextlib.contextmanager
def exclusive(path: Path, *, best_effort: bool = False) -> Iterator[None]:
    """Hold an exclusive ``flock`` on ``path`` (created, with its directory) for the ``with`` block.

    Without ``fcntl`` the block runs unlocked.  A lock file that cannot be created (an
    unwritable directory) raises ``OSError``, or with ``best_effort=True`` leaves the block
    unlocked: for a cache, where locking only saves work.  Closing the file releases the lock.
    """
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        import fcntl

        fh = open(path, "a")
    except ImportError:
        fh = None
    except OSError:
        if not best_effort:
            raise
        fh = None
    if fh is None:
        yield
        return
    with fh:
        fcntl.flock(fh, fcntl.LOCK_EX)
        yield
