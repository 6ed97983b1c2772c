"""What a running sweep says about itself: one line per state change, and how long the rest will take.

The sweep callback logs when the sweep starts (its jobs, before their configs are composed), what
they need (runs to make, configs FINISHED already, best linear approximations to estimate, the lab
steps) and when it ranks; each job logs one line when its run ends or is skipped, ``[k/N]``, and on
the sequential launcher the time left: the mean time from one run's end to the next one's in this
launch (the first run also pays for the imports and the data, so it is left out), times the jobs
left.  Skipped jobs take a fraction of a second, so the estimate is an upper bound while the jobs
left include skips.
"""

from __future__ import annotations

import os
import time

START_ENV = "MAGLEV_SWEEP_START"  # time.time() when the sweep's runs started (set by the sweep callback)
_ran: dict[str, list[float]] = {}  # START_ENV's value -> when each run this process identified since then ended


def run_done() -> None:
    """Count a run identified by this process in the running sweep."""
    start = os.environ.get(START_ENV)
    if start:
        _ran.setdefault(start, []).append(time.time())


def duration(seconds: float) -> str:
    """``45 s``, ``3 min 20 s``, ``1 h 05 min``."""
    s = int(round(seconds))
    if s < 60:
        return f"{s} s"
    if s < 3600:
        return f"{s // 60} min {s % 60:02d} s"
    return f"{s // 3600} h {s % 3600 // 60:02d} min"


def time_left(job_num: int | None, total: int | None, sequential: bool) -> str:
    """``; 21 jobs left, ≈ 1 min 10 s`` for job ``job_num`` (0-based) of ``total`` on the sequential
    launcher once a run has been identified in this launch, ``; 21 jobs left`` without an estimate, else ''."""
    if job_num is None or not total:
        return ""
    left = total - (job_num + 1)
    if left <= 0:
        return "; the last job"
    ends = _ran.get(os.environ.get(START_ENV) or "", [])
    if not sequential or len(ends) < 2:
        return f"; {left} job(s) left"
    per_run = (ends[-1] - ends[0]) / (len(ends) - 1)  # the first run also paid the imports and the data
    return f"; {left} job(s) left, ≈ {duration(per_run * left)}"
