"""One Hydra job = one MLflow run: check the config, claim it, identify, log, finish.

A config error (impossible orders, missing data file, ...) raises before any run is
created.  A job then claims its config (:func:`maglev.study.tracking.claim`): when a
FINISHED run of the same config exists, or a live process is running it — another
launch, or an overlapping sweep — the job creates no run, links that run to its own
sweep (``sweep_ref.<parent>`` tag, so the sweep ranks it) and returns.  An error while
identifying marks the run FAILED: the ``error`` tag first, then the traceback
(``error.txt``) and the config (``config/config.yaml``, so it can be reproduced); the job
then returns normally so the rest of the sweep goes on (``study.fail_on_error=true``
re-raises instead).  SIGTERM, Ctrl-C and a submitit job out of requeues mark the run
KILLED and end the job (:mod:`maglev.study.shutdown`).
"""

from __future__ import annotations

import logging
import os
import traceback
from pathlib import Path

from omegaconf import DictConfig, OmegaConf

from maglev.study import render, tracking
from maglev.study.config import check, config_hash, flatten, plain_config
from maglev.study.identify import identify, orders_string, run_label

log = logging.getLogger("maglev.study")


def hydra_context() -> dict:
    """Output dir, overrides and sweep dir of the running Hydra job ({} outside Hydra)."""
    try:
        from hydra.core.hydra_config import HydraConfig
        from hydra.types import RunMode

        hc = HydraConfig.get()
    except (ImportError, ValueError):
        return {}
    multirun = hc.mode == RunMode.MULTIRUN
    return {"output_dir": hc.runtime.output_dir, "overrides": list(hc.overrides.task),
            "sweep_dir": hc.sweep.dir if multirun else None, "job_num": hc.job.num if multirun else None,
            "launcher": str(hc.launcher.get("_target_", ""))}


def progress(ctx: dict) -> str:
    """``[k/total] `` for the k-th job of a sweep of known size (``[k] `` if unknown), else ''."""
    if ctx.get("job_num") is None:
        return ""
    total = os.environ.get(tracking.SIZE_ENV)
    return f"[{ctx['job_num'] + 1}/{total}] " if total else f"[{ctx['job_num'] + 1}] "


def run_tags(cfg: dict, chash: str, ctx: dict, parent: str | None) -> dict:
    ds, st = cfg["dataset"], cfg["structure"]
    tags = {
        "kind": "model", "dataset": ds["name"], "input_class": ds["input_class"],
        "data_source": ds["source"], "structure": st["name"], "orders": orders_string(st),
        "val_dataset": f"{ds['name']}[val]", "config_hash": chash, "sweep": cfg["study"]["name"],
        **tracking.process_tags(),
    }
    if ctx:
        tags["hydra.output_dir"] = ctx["output_dir"]
        tags["hydra.overrides"] = " ".join(ctx["overrides"])[:5000]
    if parent:
        tags["mlflow.parentRunId"] = parent
    return tags


def run(cfg: DictConfig) -> float | None:
    """The task of ``study.py``: returns the run's ``val_fit`` (None if it failed or was skipped)."""
    from maglev.study import shutdown

    shutdown.install()  # joblib and submitit workers never run study.py's own installation
    plain = plain_config(cfg)
    check(plain)
    chash = config_hash(plain)
    ctx = hydra_context()
    label = progress(ctx) + run_label(plain)
    client, exp_id = tracking.connect(plain["tracking"])
    parent = tracking.sweep_parent(ctx.get("sweep_dir"))

    def create() -> str:
        return client.create_run(exp_id, run_name=run_label(plain), tags=run_tags(plain, chash, ctx, parent)).info.run_id

    if plain["study"]["skip_finished"]:
        run_id, holder = tracking.claim(client, exp_id, plain["tracking"]["uri"], chash, create)
        if holder is not None:
            tracking.reference(client, holder, parent, plain["study"]["name"])
            log.info("skip %s: run %s with config hash %s is %s", label, holder.info.run_id, chash[:10],
                     holder.info.status if holder.info.status == "FINISHED"
                     else f"RUNNING (process {holder.data.tags.get('pid', '?')} on {holder.data.tags.get('host', '?')})")
            return None
    else:
        run_id = create()
    config_yaml = OmegaConf.to_yaml(OmegaConf.create(plain))
    try:
        tracking.log_batch(client, run_id, params=flatten(plain))
        out = identify(plain)
        files = {"config/config.yaml": config_yaml,
                 "model/model.json": out.model.to_json(), "model/summary.txt": out.model.summary(),
                 "resid/resid.json": out.resid, "data/data.json": out.prepared.info()}
        if ctx:
            hydra_dir = Path(ctx["output_dir"]) / ".hydra"
            for f in sorted(hydra_dir.glob("*.yaml")):
                files[f"config/hydra/{f.name}"] = f
        tracking.log_files(client, run_id, files)
        tracking.log_batch(client, run_id, metrics=out.metrics)
        if not plain["tracking"]["log_figures"]:
            client.set_terminated(run_id, "FINISHED")
        elif ctx.get("job_num") is not None and ctx["launcher"].endswith("BasicLauncher"):
            render.submit(plain["tracking"]["uri"], run_id, out.figure_inputs)  # FINISHED once drawn
        else:
            render.draw_and_finish(plain["tracking"]["uri"], run_id, out.figure_inputs)
        log.info("%s: val_fit %.2f %%  (run %s)", label, out.metrics["val_fit"], run_id)
        return out.metrics["val_fit"]
    except BaseException as exc:  # noqa: BLE001 — record every way of dying
        # submitit raises UncompletedJobError (an Exception) when a job ran out of requeues: killed, not failed
        killed = not isinstance(exc, Exception) or type(exc).__name__ == "UncompletedJobError"
        status = "KILLED" if killed else "FAILED"
        record_end(client, plain["tracking"], run_id, exc, status, config_yaml)
        log.error("%s: run %s %s: %s: %s", label, run_id, status, type(exc).__name__, exc)
        if killed or plain["study"]["fail_on_error"]:
            raise
        return None


def record_end(client, tracking_cfg: dict, run_id: str, exc: BaseException, status: str, config_yaml: str) -> None:
    """End a run that died: the ``error`` tag first (one small call), then ``error.txt`` and the config,
    then the status; each step on its own, so that one failing upload loses nothing else.  A server
    that stopped answering ends the sweep (:class:`maglev.study.tracking.TrackingUnreachable`)."""
    steps = (lambda: tracking.log_batch(client, run_id, tags={"error": f"{type(exc).__name__}: {exc}"[:4000]}),
             lambda: tracking.log_files(client, run_id, {"error.txt": "".join(traceback.format_exception(exc)),
                                                         "config/config.yaml": config_yaml}))
    for step in steps:
        try:
            step()
        except Exception as err:  # noqa: BLE001 — go on to the status
            log.warning("run %s: could not record its error: %s: %s", run_id, type(err).__name__, err)
    try:
        client.set_terminated(run_id, status)
    except Exception:
        if tracking.is_http(tracking_cfg["uri"]):
            tracking.check_reachable(tracking_cfg["uri"], float(tracking_cfg.get("timeout_s", 10)))
        raise
