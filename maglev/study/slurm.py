"""Waiting for a sweep's Slurm jobs however they end (used by ``hydra/launcher=slurm``).

submitit's launcher waits for each job's result file, and learns that a job ended without one
(``scancel``, a time limit, a node lost, out of memory) from ``sacct`` only.  Without Slurm's
accounting (``AccountingStorageType=accounting_storage/none``, common on small clusters) ``sacct``
fails, every such job stays "UNKNOWN", and the sweep waits forever; with it, the launcher raises at
the first such job in submission order while later jobs still run.  Here a job is over when its
result file exists or ``squeue`` no longer lists it; the sweep waits for every job, then ends with
one line per job that left no result, its Slurm state (``scontrol``) and its log.
"""

from __future__ import annotations

import logging
import subprocess
import time
from collections.abc import Sequence
from pathlib import Path

log = logging.getLogger("maglev.study")


class SlurmJobsEnded(SystemExit):
    """Jobs of the sweep ended without a result: the sweep stops (exit status 1) with one line each.

    A ``SystemExit``: Hydra would print an ``Exception``'s traceback.  The sweep's parent ends KILLED
    and the same command again runs every config that is not FINISHED (:mod:`maglev.study.callbacks`).
    """


def queued() -> set[str] | None:
    """Ids of the jobs Slurm still lists (pending, running, completing; one per array task:
    ``<array>_<task>``), or None when ``squeue`` cannot answer."""
    try:
        out = subprocess.run(["squeue", "-h", "-r", "-o", "%i"], capture_output=True, text=True, timeout=60)
    except (OSError, subprocess.SubprocessError):
        return None
    return set(out.stdout.split()) if out.returncode == 0 else None


def job_state(job_id: str) -> str:
    """Slurm's state of a finished job (``CANCELLED``, ``TIMEOUT``, ``OUT_OF_MEMORY`` ...), from
    ``scontrol`` while Slurm remembers it (``MinJobAge``), else ``unknown``."""
    try:
        out = subprocess.run(["scontrol", "-o", "show", "job", job_id], capture_output=True, text=True, timeout=60)
    except (OSError, subprocess.SubprocessError):
        return "unknown"
    for field in out.stdout.split():
        if field.startswith("JobState="):
            reason = next((f.split("=", 1)[1] for f in out.stdout.split() if f.startswith("Reason=")), "None")
            state = field.split("=", 1)[1]
            return state if reason in ("None", "") else f"{state} ({reason})"
    return "unknown"


def wait(jobs: Sequence, poll_s: float = 2.0, settle_s: float = 10.0) -> None:
    """Return once every submitit job has written its result or left Slurm's queue (then give a
    shared filesystem ``settle_s`` to show a result written just before).  ``squeue`` failing only
    means waiting for the result files, as submitit does."""
    pending = list(jobs)
    gone_since: dict[str, float] = {}
    while pending:
        listed = queued()
        now = time.monotonic()
        still = []
        for job in pending:
            if Path(job.paths.result_pickle).exists():
                continue
            if listed is not None and job.job_id not in listed:
                if now - gone_since.setdefault(job.job_id, now) >= settle_s:
                    continue
            still.append(job)
        pending = still
        if pending:
            time.sleep(poll_s)


def outcome(job, overrides: Sequence[str]):
    """The job's ``JobReturn``, or the line saying why it has none: it left no result (signalled,
    killed), or its run was stopped at the time limit (submitit's ``UncompletedJobError``, which the
    job re-raises after marking its run KILLED)."""
    try:
        if not Path(job.paths.result_pickle).exists():  # gone from the queue without one (:func:`wait`)
            raise ProcessLookupError("the job's process ended without writing its result")
        ret = job.results()[0]
    except Exception as exc:  # noqa: BLE001 — submitit re-raises what ended the job, or UncompletedJobError
        ret, why = None, exc
    else:
        why = getattr(ret, "_return_value", None) if getattr(ret.status, "name", "") == "FAILED" else None
        if type(why).__name__ != "UncompletedJobError":
            return ret, None
    shown = " ".join(o for o in overrides if not o.lstrip("+~").startswith(("tracking", "hydra")))
    text = str(why).strip().splitlines()[-1] if str(why).strip() else ""
    return None, (f"Slurm job {job.job_id} ({shown}) ended without a result: {job_state(job.job_id)}; "
                  f"{type(why).__name__}: {text[:300]}; its log: {job.paths.stderr}")


def collect(jobs: Sequence, job_overrides: Sequence[Sequence[str]]) -> list:
    """Wait for every job (:func:`wait`), then their ``JobReturn``s; :class:`SlurmJobsEnded` naming each
    job that left none."""
    wait(jobs)
    returns, lines = [], []
    for job, overrides in zip(jobs, job_overrides):
        ret, line = outcome(job, overrides)
        if line:
            log.error("%s", line)
            lines.append(line)
        else:
            returns.append(ret)
    if lines:
        raise SlurmJobsEnded("maglev: " + "\nmaglev: ".join(lines) + "\nmaglev: the same command again runs "
                             "every config that is not FINISHED")
    return returns
