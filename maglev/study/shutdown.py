"""SIGTERM ends a sweep the way Ctrl-C does: runs in flight KILLED, the parent KILLED, nothing left RUNNING.

SIGTERM is what Slurm sends on ``scancel`` and at a time limit, and what ``kill`` sends;
Python's default action ends the process on the spot, with no ``finally`` and no
``atexit``, so the run in flight and the sweep's parent stayed RUNNING.  The handler
turns the signal into ``SystemExit(143)`` in the main thread, wherever it is:
``job.run`` marks its run KILLED and re-raises; Hydra's launchers and callbacks catch
only ``Exception``, so the sweep ends; at exit the sweep callback marks the parent
KILLED, abandons queued figure renders and marks KILLED the runs of its workers that
are gone (:meth:`maglev.study.callbacks.SweepCallback._abort`).  A second SIGTERM
during that cleanup is ignored (Slurm follows with SIGKILL).

The launching process (``study.py``) first passes the signal on to every process below
it: submitit's local job processes outlive their launcher, and their own handler (set
by ``job.run`` in every process that runs jobs, replacing submitit's "bypass") marks
their runs KILLED.

A signal that lands inside a tracking-store transaction waits for its end
(:func:`deferred`, around every SQLite session of :func:`maglev.study.tracking.new_client`):
an exception raised in SQLite's commit leaves the process holding the database's write
lock, and every later write of the cleanup then waits SQLite's 20 s busy timeout and fails
(measured: the parent and the run in flight left RUNNING, exit 1 after 100 s instead of
143 at once).  Ctrl-C's ``KeyboardInterrupt`` waits the same way.
"""

from __future__ import annotations

import os
import signal
import threading
from collections.abc import Iterator
from contextlib import contextmanager

_forward = False
received: int | None = None  # the signal that is ending this process, once one has arrived
_held = 0  # how many deferred() blocks the main thread is in
_pending: int | None = None  # a signal that arrived in one, raised when the outermost ends


def descendants(pid: int | None = None) -> list[int]:
    """Pids of every process below ``pid`` (default: this one), read from /proc ([] where there is none)."""
    pid = os.getpid() if pid is None else pid
    try:
        entries = os.listdir("/proc")
    except OSError:
        return []
    children: dict[int, list[int]] = {}
    for entry in entries:
        if not entry.isdigit():
            continue
        try:
            with open(f"/proc/{entry}/stat") as fh:
                ppid = int(fh.read().rsplit(")", 1)[1].split()[1])
        except (OSError, IndexError, ValueError):
            continue
        children.setdefault(ppid, []).append(int(entry))
    out, todo = [], [pid]
    while todo:
        for child in children.get(todo.pop(), []):
            out.append(child)
            todo.append(child)
    return out


def _raise(signum: int) -> None:
    if signum == signal.SIGINT:
        raise KeyboardInterrupt
    raise SystemExit(128 + signum)


@contextmanager
def deferred() -> Iterator[None]:
    """Hold SIGTERM's ``SystemExit`` and Ctrl-C's ``KeyboardInterrupt`` until the block ends (in the
    main thread, where Python runs signal handlers; elsewhere a no-op)."""
    global _held, _pending
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    _held += 1
    try:
        yield
    finally:
        _held -= 1
        if not _held and _pending is not None:
            signum, _pending = _pending, None
            _raise(signum)


def _on_sigterm(signum, frame) -> None:
    global received, _pending
    signal.signal(signum, signal.SIG_IGN)  # let the cleanup finish; SIGKILL still works
    received = signum
    if _forward:
        for pid in descendants():
            try:
                os.kill(pid, signum)
            except (ProcessLookupError, PermissionError):
                pass
    if _held:
        _pending = signum
        return
    _raise(signum)


def _on_sigint(signum, frame) -> None:
    global _pending
    if _held:
        _pending = _pending or signum
        return
    _raise(signum)


def install(forward: bool = False) -> bool:
    """Install the SIGTERM handler, and Ctrl-C's where Python's default is in place (possible in the
    main thread only); True if installed.

    ``forward``: pass SIGTERM on to every descendant first (the launching process).
    """
    global _forward
    if threading.current_thread() is not threading.main_thread():
        return False
    _forward = _forward or forward
    signal.signal(signal.SIGTERM, _on_sigterm)
    if signal.getsignal(signal.SIGINT) is signal.default_int_handler:
        signal.signal(signal.SIGINT, _on_sigint)
    return True
