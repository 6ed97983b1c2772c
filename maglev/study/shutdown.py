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
"""

from __future__ import annotations

import os
import signal
import threading

_forward = False
received: int | None = None  # the signal that is ending this process, once one has arrived


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


def _on_sigterm(signum, frame) -> None:
    global received
    signal.signal(signum, signal.SIG_IGN)  # let the cleanup finish; SIGKILL still works
    received = signum
    if _forward:
        for pid in descendants():
            try:
                os.kill(pid, signum)
            except (ProcessLookupError, PermissionError):
                pass
    raise SystemExit(128 + signum)


def install(forward: bool = False) -> bool:
    """Install the SIGTERM handler (possible in the main thread only); True if installed.

    ``forward``: pass the signal on to every descendant first (the launching process).
    """
    global _forward
    if threading.current_thread() is not threading.main_thread():
        return False
    _forward = _forward or forward
    signal.signal(signal.SIGTERM, _on_sigterm)
    return True
