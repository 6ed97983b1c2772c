"""Mark runs left RUNNING by killed processes as KILLED (before resuming or ranking).

A run is stale when its ``host`` tag is this machine and its ``pid`` is no longer
alive, or (any host) when it started more than ``older_than_hours`` ago.  Runs of
live processes — e.g. another sweep writing to the same store — are left alone.

    maglev reap [--tracking-uri URI] [--experiment NAME] [--older-than-hours H]
"""

from __future__ import annotations

import os
import socket
import time


def _alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True
    return True


def stale(run, older_than_hours: float | None = None, host: str | None = None) -> bool:
    host = host or socket.gethostname()
    tags = run.data.tags
    if older_than_hours is not None:
        age_h = (time.time() * 1000 - run.info.start_time) / 3.6e6
        if age_h > older_than_hours:
            return True
    if tags.get("host") != host or not tags.get("pid", "").isdigit():
        return False
    pid = int(tags["pid"])
    return pid != os.getpid() and not _alive(pid)


def reap(client, experiment_ids: list[str], older_than_hours: float | None = None) -> list[str]:
    """Set every stale RUNNING run of the experiments to KILLED; return their ids."""
    runs = client.search_runs(experiment_ids, filter_string="attributes.status = 'RUNNING'",
                              max_results=50000)
    killed = []
    for run in runs:
        if stale(run, older_than_hours):
            client.set_tag(run.info.run_id, "reaped", "process gone; marked KILLED")
            client.set_terminated(run.info.run_id, "KILLED")
            killed.append(run.info.run_id)
    return killed
