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

The processes a sweep starts on this machine — the figure renderer, joblib's workers,
submitit's local job processes — end with their launcher, kill -9 included
(:func:`exit_with`): a worker left behind held 260-390 MB for minutes (the renderer)
or more than 25 minutes (a joblib worker).
"""

from __future__ import annotations

import logging
import os
import signal
import socket
import sys
import threading
import time
from collections.abc import Iterator
from contextlib import contextmanager

LAUNCHER_ENV = "MAGLEV_LAUNCHER_PID"  # the pid of the process that launched the sweep, for its workers
_forward = False
_watched: int | None = None  # the launcher whose end ends this process (exit_with)
received: int | None = None  # the signal that is ending this process, once one has arrived
reported = False  # whether the sweep's (or the single run's) line has said what the signal ended
_held = 0  # how many deferred() blocks the main thread is in
_pending: int | None = None  # a signal that arrived in one, raised when the outermost ends
_status: int | None = None  # the status this process exits with, once its main code has ended (:func:`ending`)
_jobs = 0  # jobs this process is running (:func:`job`): their runs are marked before exit_with ends it
_ran = False  # whether this process has started a job (:func:`job`), for :func:`final_line`
_between = False  # Hydra's code runs between this process's jobs: signals held (:func:`between_jobs`)


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


def raise_if_received() -> None:
    """Raise the exit of a signal that has arrived, at a safe point (a job's start, a sweep's end): the
    handler's exception is lost when it lands in a garbage-collector callback or a ``__del__`` (Python
    prints "Exception ignored" and goes on) — seen with SIGTERM to a sweep's process group, which then
    ran its remaining jobs and exited 0.  Ends the hold of :func:`between_jobs`."""
    _release()
    if received is not None and not _held:
        _raise(received)


def between_jobs() -> None:
    """In a process that runs a sweep's jobs itself (Hydra's basic launcher), once a job's config is composed
    (:mod:`maglev.study.compose`), a job ends, or the sweep's start: hold the signals' exits, as :func:`deferred`
    does, until the next composition or job starts or the sweep ends (:func:`raise_if_received`).  Hydra's
    code in between edits OmegaConf configs, which an exception landing inside leaves broken: SIGTERM while
    Hydra set the next job's overrides surfaced as OmegaConf's ``AttributeError`` — a traceback and exit 1
    instead of the sweep's one line and 143.  Hydra's own checks of a large sweep's configs stay
    interruptible: each composition ends the hold before the next."""
    global _held, _between
    if threading.current_thread() is threading.main_thread() and not _between:
        _between = True
        _held += 1


def _release() -> None:
    """End :func:`between_jobs`'s hold (a signal that arrived in it is still ``received``)."""
    global _held, _between, _pending
    if _between:
        _between = False
        _held -= 1
        if not _held:
            _pending = None


def _on_sigint(signum, frame) -> None:
    global _pending, received
    received = received or signum
    if _held:
        _pending = _pending or signum
        return
    _raise(signum)


def _lost(unraisable) -> None:
    """``sys.unraisablehook``: the exit a signal handler raised inside a garbage-collector or weakref callback
    (SQLAlchemy's, seen with SIGTERM to a sweep's process group) is dropped there with an "Exception
    ignored" traceback; deliver the signal again a moment later, outside that callback, without the print."""
    ours = isinstance(unraisable.exc_value, KeyboardInterrupt) or (
        isinstance(unraisable.exc_value, SystemExit) and received and unraisable.exc_value.code == 128 + received)
    if not ours or received is None:
        _previous_hook(unraisable)
        return
    signal.signal(received, _on_sigint if received == signal.SIGINT else _on_sigterm)
    threading.Timer(0.05, os.kill, (os.getpid(), received)).start()


_previous_hook = sys.unraisablehook


def install(forward: bool = False) -> bool:
    """Install the SIGTERM handler, and Ctrl-C's where Python's default is in place (possible in the
    main thread only); True if installed.

    ``forward``: pass SIGTERM on to every descendant first (the launching process).
    """
    global _forward
    if threading.current_thread() is not threading.main_thread():
        return False
    _forward = _forward or forward
    sys.unraisablehook = _lost
    if received != signal.SIGTERM:  # after one, SIGTERM stays ignored: a second must not break the cleanup
        signal.signal(signal.SIGTERM, _on_sigterm)
    if signal.getsignal(signal.SIGINT) is signal.default_int_handler:
        signal.signal(signal.SIGINT, _on_sigint)
    return True


def final_line() -> None:
    """At exit of ``study.py``: the one line of a signal that ended it before a sweep or a run said so."""
    if received is not None and not reported:
        name = signal.Signals(received).name
        when = "once its runs had started" if _ran else "before any run was started"
        print(f"maglev: stopped by {name}{' (Ctrl-C)' if received == signal.SIGINT else ''} {when}", file=sys.stderr,
              flush=True)


@contextmanager
def ending() -> Iterator[None]:
    """Around a process's main code: record the status its exit will have, as Python computes it from the
    exception that ends the block (none: 0; ``SystemExit``: its code, a message 1; any other: 1), for
    :func:`skip_teardown`."""
    global _status
    try:
        yield
    except SystemExit as exc:
        _status = exc.code if isinstance(exc.code, int) else 0 if exc.code is None else 1
        raise
    except BaseException:
        _status = 1
        raise
    else:
        _status = 0
    finally:
        _release()  # a sweep that ended between jobs: a Ctrl-C during the cleanup at exit is not held


def skip_teardown(status: int | None = None) -> None:
    """atexit, registered before every handler but logging's, so it runs last: end the process with
    ``status`` (default: the one :func:`ending` recorded; neither: return, Python ends it) once its output is
    flushed, without the interpreter's teardown.  Freeing every module and object of a process that loaded
    MLflow, SQLAlchemy, SciPy and matplotlib takes 0.7-1.2 s; a sweep's launcher waited for its renderer's,
    then did its own, after its last line."""
    status = _status if status is None else status
    if status is None:
        return
    logging.shutdown()
    for stream in (sys.stdout, sys.stderr):
        try:
            stream.flush()
        except (OSError, ValueError, AttributeError):  # closed, or None (pythonw)
            pass
    os._exit(status)


@contextmanager
def job() -> Iterator[None]:
    """Around a job (one run): while it is in flight, :func:`exit_with` waits for it before ending the process."""
    global _jobs, _ran
    _jobs += 1
    _ran = True
    try:
        yield
    finally:
        _jobs -= 1


def mark_launcher() -> None:
    """Record this process as the sweep's launcher (its workers, started later, inherit the variable)."""
    os.environ[LAUNCHER_ENV] = f"{socket.gethostname()}:{os.getpid()}"


def launcher() -> int | None:
    """The pid of the process that launched the running sweep on this machine (None outside a sweep, or
    when the launcher is on another machine: a Slurm job inherits the variable)."""
    host, _, pid = os.environ.get(LAUNCHER_ENV, "").rpartition(":")
    return int(pid) if pid.isdigit() and host == socket.gethostname() else None


def ended(pid: int) -> bool:
    """True when process ``pid`` is gone or a zombie (killed, not yet reaped by its parent)."""
    try:
        with open(f"/proc/{pid}/stat") as fh:
            return fh.read().rsplit(")", 1)[1].split()[0] in ("Z", "X")
    except FileNotFoundError:
        return True
    except (OSError, IndexError):  # no /proc
        try:
            os.kill(pid, 0)
        except ProcessLookupError:
            return True
        except PermissionError:
            pass
        return False


def exit_with(pid: int, grace: float = 20.0, poll: float = 0.5) -> bool:
    """End this process when process ``pid`` (its launcher, on this machine) ends, kill -9 included — also
    when it ended before this call (a joblib worker that receives its first job from a launcher killed
    meanwhile); True if a watch was started.

    A daemon thread polls every ``poll`` s: the launcher is gone or a zombie, or, when it was this
    process's parent, the parent pid changed (an orphan is handed to init or a subreaper).  This
    process then gets SIGTERM, whose handler marks a job's run KILLED (:func:`install`), and
    ``os._exit`` follows once no job is left in flight (:func:`job`), at most ``grace`` s later.  A worker
    between jobs — its main thread blocked reading its launcher's queue, where the signal's exit does not
    end it — was left for the whole grace (20 s) before.  Polling, not Linux's ``PR_SET_PDEATHSIG``: that
    fires when the *thread* that started the process ends, and joblib starts its workers from a helper thread.
    """
    global _watched
    if _watched is not None:
        return False
    child = os.getppid() == pid

    def watch() -> None:
        while not ((child and os.getppid() != pid) or ended(pid)):
            time.sleep(poll)
        os.kill(os.getpid(), signal.SIGTERM)
        end = time.monotonic() + grace
        while _jobs and time.monotonic() < end:  # the job in flight marks its run KILLED
            time.sleep(0.05)
        os._exit(128 + signal.SIGTERM)

    _watched = pid
    threading.Thread(target=watch, name="maglev-exit-with-launcher", daemon=True).start()
    return True
