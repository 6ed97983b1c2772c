"""One launch per sweep, one run per config, whichever launches share the store.

A sweep's launch holds a file lock for the sweep (:func:`acquire_sweep`): a second launch of the
same sweep waits for it, then finds its configs done.  A job claims its config before it creates
its run (:func:`claim`): a FINISHED run of the config, or the first-started RUNNING one of a live
process, holds it, and the job then only references that run from its sweep (:func:`reference`),
which the sweep counts as its own (:func:`referenced`).
"""

from __future__ import annotations

import os
import socket
import time
from pathlib import Path

from mlflow import MlflowClient

from maglev.study.tracking import sqlite_path, store_lock

# ---------------------------------------------------------------------------- one launch per sweep
_held: dict[str, object] = {}  # lock path -> open file holding the lock (this process)


def sweep_lock_path(uri: str, sweep_dir: str | Path, sid: str) -> Path:
    """The lock of one sweep: beside a SQLite store, else (a server) in the sweep dir."""
    db = sqlite_path(uri)
    return db.with_name(f"{db.name}.sweep-{sid[:16]}.lock") if db else Path(sweep_dir) / f".sweep-{sid[:16]}.lock"


def acquire_sweep(path: Path, waiting) -> None:
    """Hold an exclusive lock on ``path`` until :func:`release_sweep` or the end of the process (kill -9
    included).  While another process holds it, call ``waiting(holder)`` once and wait."""
    if str(path) in _held:  # an earlier launch in this process died without releasing it
        return
    try:
        import fcntl
    except ImportError:  # Windows: launches of one sweep are not serialised
        return
    path.parent.mkdir(parents=True, exist_ok=True)
    fh = open(path, "a+")
    try:
        fcntl.flock(fh, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except BlockingIOError:
        fh.seek(0)
        waiting(fh.read().strip() or "another process")
        fcntl.flock(fh, fcntl.LOCK_EX)
    fh.seek(0)
    fh.truncate()
    fh.write(f"process {os.getpid()} on {socket.gethostname()}")
    fh.flush()
    _held[str(path)] = fh


def release_sweep(path: Path) -> None:
    fh = _held.pop(str(path), None)
    if fh is not None:
        fh.close()  # releases the lock


# ---------------------------------------------------------------------------- claiming a config
REF_PREFIX = "sweep_ref."  # tag on a run that also belongs to another sweep: sweep_ref.<parent id> = sweep name


def holder(client: MlflowClient, exp_id: str, chash: str, mine: str | None = None):
    """The run that holds a config: a FINISHED model run with this hash, else the first-started RUNNING
    one of a live process (``mine`` included); None when ``mine`` is that one or nothing holds it."""
    from maglev.study.reap import stale

    runs = client.search_runs([exp_id], filter_string=f"tags.config_hash = '{chash}' and tags.kind = 'model'",
                              max_results=1000)
    first = sorted((r for r in runs if r.info.status == "FINISHED" and r.info.run_id != mine),
                   key=lambda r: (r.info.start_time, r.info.run_id))
    if not first:
        first = sorted((r for r in runs if r.info.status == "RUNNING" and not stale(r)),
                       key=lambda r: (r.info.start_time, r.info.run_id))
    if not first or first[0].info.run_id == mine:
        return None
    return first[0]


def claim(client: MlflowClient, exp_id: str, uri: str, chash: str, create) -> tuple[str | None, object]:
    """Create this config's run with ``create()`` unless another run holds the config: ``(run id, None)``,
    or ``(None, the holding run)``.

    On a SQLite store the look-up and the creation happen under :func:`store_lock`, so two
    processes never both create a run of one config.  A server offers no lock: the run is
    created, then the config looked up again, and the run deleted when an earlier one of a
    live process holds it — two jobs starting within the same few milliseconds on clocks
    that disagree may still both run; the ranking keeps one run per config.
    """
    with store_lock(uri):
        found = holder(client, exp_id, chash)
        if found is not None:
            return None, found
        run_id = create()
    if sqlite_path(uri) is None:
        found = holder(client, exp_id, chash, mine=run_id)
        if found is not None:
            client.delete_run(run_id)
            return None, found
    return run_id, None


def reference(client: MlflowClient, run, parent: str | None, sweep: str) -> None:
    """Make ``run`` (of another sweep, or none) part of the sweep ``parent`` as well (``sweep_ref.<parent>``)."""
    if parent and run.data.tags.get("mlflow.parentRunId") != parent:
        client.set_tag(run.info.run_id, f"{REF_PREFIX}{parent}", sweep or "sweep")


def referenced(client: MlflowClient, exp_id: str, parent_id: str) -> list:
    """Model runs of other sweeps that the sweep ``parent_id`` counts as its own (:func:`reference`)."""
    return client.search_runs([exp_id], filter_string=f"tags.`{REF_PREFIX}{parent_id}` != '' and tags.kind = 'model'",
                              max_results=50000)


def wait_for_references(client: MlflowClient, exp_id: str, parent_id: str, timeout_s: float,
                        poll_s: float = 2.0) -> list:
    """Wait, at most ``timeout_s``, until no run the sweep ``parent_id`` references is RUNNING in a live
    process (another user's launch or an overlapping sweep holds some of its configs), so that its ranking
    includes them; returns those still RUNNING at the end (left out of the ranking, as ``ignored_running``)."""
    from maglev.study.reap import stale

    end = time.monotonic() + timeout_s
    while True:
        running = [r for r in referenced(client, exp_id, parent_id) if r.info.status == "RUNNING" and not stale(r)]
        if not running or time.monotonic() >= end:
            return running
        time.sleep(poll_s)
