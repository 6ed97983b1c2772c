"""One Hydra job = one MLflow run: check the config, claim it, estimate, validate, log, finish.

A config error (impossible orders, missing data file, ...) raises before any run is
created.  A job then claims its config (:func:`maglev.study.claims.claim`): when a
FINISHED run of the same config exists, or a live process is running it — another
launch, or an overlapping sweep — the job creates no run, links that run to its own
sweep (``sweep_ref.<parent>`` tag, so the sweep ranks it) and returns.  An error while
identifying marks the run FAILED: the ``error`` tag first, then the traceback
(``error.txt``) and the config (``config/config.yaml``, so it can be reproduced); the job
then returns normally so the rest of the sweep goes on (``study.fail_on_error=true``
re-raises instead).  In a sweep on the basic launcher the job only estimates: the rest of
the run is made by the background renderer (:mod:`maglev.study.finish`).  SIGTERM, Ctrl-C and a submitit job out of requeues mark the run
KILLED and end the job (:mod:`maglev.study.shutdown`).
"""

from __future__ import annotations

import logging
import os
from pathlib import Path

from omegaconf import DictConfig

from maglev.study import credentials, heap
from maglev.study import progress as progress_
from maglev.study.config import StudyConfigError, check, config_hash, flatten, plain_config, runs_jobs_here
from maglev.study.identify import estimate_run, orders_string, run_label, validate
from maglev.study.lazy import lazy_module

# MLflow (1-2 s of imports) on first use: a run refused by its config ends before it
claims = lazy_module("maglev.study.claims")
finish = lazy_module("maglev.study.finish")
render = lazy_module("maglev.study.render")
tracking = lazy_module("maglev.study.tracking")

log = logging.getLogger("maglev.study")
ENTRY = "study.py"  # the runs' source in the MLflow UI


def hydra_context() -> dict:
    """Output dir, overrides and sweep dir of the running Hydra job, and whether it is one of a sweep's jobs run
    one after another in this process ({} outside Hydra)."""
    try:
        from hydra.core.hydra_config import HydraConfig
        from hydra.types import RunMode

        hc = HydraConfig.get()
    except (ImportError, ValueError):
        return {}
    multirun = hc.mode == RunMode.MULTIRUN
    return {"output_dir": hc.runtime.output_dir, "overrides": list(hc.overrides.task),
            "sweep_dir": hc.sweep.dir if multirun else None, "job_num": hc.job.num if multirun else None,
            "sequential": multirun and runs_jobs_here(hc.launcher)}


def sweep_size() -> int | None:
    """The running sweep's number of jobs (set by the sweep callback), None if unknown."""
    total = os.environ.get(tracking.SIZE_ENV, "")
    return int(total) if total.isdigit() else None


def progress(ctx: dict) -> str:
    """``[k/total] `` for the k-th job of a sweep of known size (``[k] `` if unknown), else ''."""
    if ctx.get("job_num") is None:
        return ""
    total = sweep_size()
    return f"[{ctx['job_num'] + 1}/{total}] " if total else f"[{ctx['job_num'] + 1}] "


def time_left(ctx: dict) -> str:
    """What is left of the sweep after this job (:func:`maglev.study.progress.time_left`)."""
    return progress_.time_left(ctx.get("job_num"), sweep_size(), ctx.get("sequential", False))


def wait_for_bla(plain: dict, label: str) -> None:
    """Say so when this job's run will wait for a best linear approximation still being estimated."""
    from maglev.study.datasets import missing_blas

    if plain["dataset"]["source"] == "sim" and plain["study"]["true_plant"] and missing_blas([plain]):
        log.info("%s: waiting for the best linear approximation of %s (being estimated in the background)",
                 label, plain["dataset"]["name"])


def run_tags(cfg: dict, chash: str, ctx: dict, parent: str | None) -> dict:
    ds, st = cfg["dataset"], cfg["structure"]
    tags = {
        "kind": "model", "dataset": ds["name"], "input_class": ds["input_class"],
        "data_source": ds["source"], "structure": st["name"], "orders": orders_string(st),
        "val_dataset": f"{ds['name']}[val]", "config_hash": chash, "sweep": cfg["study"]["name"],
        **tracking.process_tags(), **tracking.source_tags(ENTRY),
    }
    if ctx:
        tags["hydra.output_dir"] = ctx["output_dir"]
        tags["hydra.overrides"] = credentials.redact(" ".join(ctx["overrides"]))[:5000]
    if parent:
        tags["mlflow.parentRunId"] = parent
    return tags


def skip_message(label: str, done, chash: str) -> str:
    """Why a job logs nothing: which run holds its config (FINISHED, or RUNNING in a live process: another
    launch or an overlapping sweep), and how to run it again."""
    status = done.info.status
    if status == "RUNNING":
        status += f" in process {done.data.tags.get('pid', '?')} on {done.data.tags.get('host', '?')}"
    return (f"skip {label}: run {done.info.run_name!r} ({done.info.run_id}) already holds this config "
            f"(hash {chash[:10]}, {status}); to run it again add study.skip_finished=false")


class RunRefused(SystemExit):
    """A single run's config cannot describe a run: one line, exit status 1, no run (a ``SystemExit``:
    Hydra prints any ``Exception`` of the task with its traceback)."""


def checked_config(cfg: DictConfig, single: bool) -> dict:
    """The job's plain config, checked (:func:`maglev.study.config.check`); for a ``single`` run a config
    error is :class:`RunRefused` (a sweep checked every job before its start)."""
    from omegaconf.errors import OmegaConfBaseException

    try:
        plain = plain_config(cfg)
        check(plain)
    except (StudyConfigError, OmegaConfBaseException, ValueError) as exc:
        if not single:
            raise
        text = str(exc).strip().splitlines()[0] if str(exc).strip() else type(exc).__name__
        raise RunRefused(f"maglev: run refused before it started: {text}") from None
    return plain


def run(cfg: DictConfig) -> float | None:
    """The task of ``study.py``: returns the run's ``val_fit`` (None if it failed or was skipped)."""
    from maglev.study import shutdown

    with shutdown.job():
        try:
            return _run(cfg)
        finally:
            if hydra_context().get("sequential"):
                shutdown.between_jobs()  # Hydra goes on in OmegaConf: a signal is raised at the next config or job


def _run(cfg: DictConfig) -> float | None:
    from maglev.study import shutdown

    shutdown.raise_if_received()  # a signal held since the last job, before install() could arm its handler again
    shutdown.install()  # joblib and submitit workers never run study.py's own installation
    if shutdown.launcher() not in (None, os.getpid()):  # a worker of this machine's launcher: end with it
        shutdown.exit_with(shutdown.launcher())
    ctx = hydra_context()
    plain = checked_config(cfg, single=ctx.get("sweep_dir") is None)
    plain["tracking"]["uri"] = credentials.to_env(plain["tracking"]["uri"])  # a server's user and password
    chash = config_hash(plain)
    label = progress(ctx) + run_label(plain)
    try:
        client, exp_id = tracking.connect(plain["tracking"], reuse=ctx.get("sweep_dir") is not None)
    except tracking.StoreProblem as exc:
        raise RunRefused(f"maglev: {exc}") from None
    heap.settle()  # a single run's or a joblib worker's first job's libraries are in (a sweep settles at its start)
    parent = tracking.sweep_parent(ctx.get("sweep_dir"))

    artifact_uris: dict[str, str] = {}  # the created run's: its uploads need not read the run back

    def create() -> str:
        tags = run_tags(plain, chash, ctx, parent)
        info = client.create_run(exp_id, run_name=run_label(plain), tags=tags).info
        artifact_uris[info.run_id] = info.artifact_uri
        return info.run_id

    run_id, holder = None, None
    try:
        with shutdown.deferred():  # a signal while the run is created is raised once this job holds its id
            if plain["study"]["skip_finished"]:
                run_id, holder = claims.claim(client, exp_id, plain["tracking"]["uri"], chash, create)
            else:
                run_id = create()
        if holder is not None:
            claims.reference(client, holder, parent, plain["study"]["name"])
    except BaseException as exc:
        if run_id is not None:  # seen under load: a worker's run left RUNNING when its launcher was killed
            finish.record_end(client, plain["tracking"], run_id, exc, "KILLED", finish.config_text(plain))
        elif isinstance(exc, Exception):  # a server that died: the sweep's one line, not this job's traceback
            tracking.raise_if_unreachable(plain["tracking"]["uri"])
        raise
    if holder is not None:
        log.info("%s", skip_message(label, holder, chash))
        return None
    # the rest of the run on the background renderer: a sweep on the basic launcher that goes on after a failure
    background = plain["tracking"]["log_figures"] and not plain["study"]["fail_on_error"] and ctx.get("sequential")
    try:
        tracking.log_batch(client, run_id, params={k: credentials.redact(v) for k, v in flatten(plain).items()})
        if ctx.get("job_num") is not None and not background:
            wait_for_bla(plain, label)
        estimated = estimate_run(plain)
        work = finish.Work(estimated, str(Path(ctx["output_dir"]) / ".hydra") if ctx else None,
                           artifact_uris.get(run_id))
        if background:
            render.submit(plain["tracking"]["uri"], run_id, work, finish.complete)  # FINISHED once complete
        else:
            out = validate(estimated)
            finish.log_outputs(client, run_id, work, out)
            if plain["tracking"]["log_figures"]:
                render.draw_and_finish(plain["tracking"]["uri"], run_id, out.figure_inputs, client)
            else:
                client.set_terminated(run_id, "FINISHED")
        progress_.run_done()
        log.info("%s: val_fit %.2f %%  (run %s)%s", label, estimated.val_fit, run_id, time_left(ctx))
        return estimated.val_fit
    except BaseException as exc:  # noqa: BLE001 — record every way of dying
        # submitit raises UncompletedJobError (an Exception) when a job ran out of requeues: killed, not failed;
        # an error once a signal has arrived is what its exit broke on the way (OmegaConf's, in a list half-made)
        killed = (not isinstance(exc, Exception) or shutdown.received is not None
                  or type(exc).__name__ == "UncompletedJobError")
        status = "KILLED" if killed else "FAILED"
        finish.record_end(client, plain["tracking"], run_id, exc, status, finish.config_text(plain))
        # a signal's KILLED runs are counted in the sweep's one line (callbacks.SweepCallback._abort)
        level = logging.DEBUG if shutdown.received and ctx.get("sweep_dir") else logging.ERROR
        log.log(level, "%s: run %s %s: %s: %s", label, run_id, status, type(exc).__name__, exc)
        shutdown.reported = shutdown.reported or level == logging.ERROR
        if killed or plain["study"]["fail_on_error"]:
            shutdown.raise_if_received()  # the signal's exit, not the error it caused
            raise
        return None
