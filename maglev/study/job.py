"""One Hydra job = one MLflow run: check the config, skip if done, identify, log, finish.

A config error (impossible orders, missing data file, ...) raises before any run is
created.  An error while identifying marks the run FAILED with the traceback logged
as ``error.txt`` and a short ``error`` tag; the job then returns normally so the rest
of the sweep goes on (``study.fail_on_error=true`` re-raises instead).
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
    """The task of ``study.py``: returns the run's ``val_fit`` (None if it failed)."""
    plain = plain_config(cfg)
    check(plain)
    chash = config_hash(plain)
    ctx = hydra_context()
    label = progress(ctx) + run_label(plain)
    client, exp_id = tracking.connect(plain["tracking"])
    if plain["study"]["skip_finished"]:
        done = tracking.finished_run(client, exp_id, chash)
        if done:
            log.info("skip %s: run %s with config hash %s is FINISHED", label, done, chash[:10])
            return None
    run_info = client.create_run(exp_id, run_name=run_label(plain),
                                 tags=run_tags(plain, chash, ctx, tracking.sweep_parent(ctx.get("sweep_dir")))).info
    run_id = run_info.run_id
    try:
        tracking.log_batch(client, run_id, params=flatten(plain))
        out = identify(plain)
        files = {"config/config.yaml": OmegaConf.to_yaml(OmegaConf.create(plain)),
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
        status = "FAILED" if isinstance(exc, Exception) else "KILLED"
        text = "".join(traceback.format_exception(exc))
        try:
            tracking.log_files(client, run_id, {"error.txt": text})
            tracking.log_batch(client, run_id, tags={"error": f"{type(exc).__name__}: {exc}"[:4000]})
        finally:
            client.set_terminated(run_id, status)
        log.error("%s: run %s %s: %s: %s", label, run_id, status, type(exc).__name__, exc)
        if status == "KILLED" or plain["study"]["fail_on_error"]:
            raise
        return None
