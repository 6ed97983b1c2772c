"""One Hydra job = one MLflow run: check the config, claim it, identify, log, finish.

A config error (impossible orders, missing data file, ...) raises before any run is
created.  A job then claims its config (:func:`maglev.study.claims.claim`): when a
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

from maglev.study import credentials
from maglev.study import progress as progress_
from maglev.study.config import StudyConfigError, check, config_hash, flatten, plain_config
from maglev.study.identify import identify, orders_string, run_label
from maglev.study.lazy import lazy_module
from maglev.validation import format_p

# MLflow (1-2 s of imports) on first use: a run refused by its config ends before it
claims = lazy_module("maglev.study.claims")
render = lazy_module("maglev.study.render")
tracking = lazy_module("maglev.study.tracking")

log = logging.getLogger("maglev.study")
ENTRY = "study.py"  # the runs' source in the MLflow UI


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
    return progress_.time_left(ctx.get("job_num"), sweep_size(), ctx.get("launcher", "").endswith("BasicLauncher"))


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


def log_data_inputs(client, run_id: str, cfg: dict, prepared) -> None:
    """The run's estimation and validation data as MLflow dataset inputs (file records by their path)."""
    source = prepared.raw.meta.get("source") if cfg["dataset"]["source"] == "file" else None
    spec = prepared.raw.meta.get("spec") if source is None else None
    tracking.log_dataset_inputs(client, run_id, prepared.est, prepared.val, source, spec)


def _pct(x: float) -> str:
    return f"{x:.2f} %"


def model_description(cfg: dict, m: dict) -> str:
    """The model run's description (Markdown): structure, orders, FITs and residual tests, from its metrics."""
    from maglev.structures import get as structure

    st, ds = cfg["structure"], cfg["dataset"]
    names = " ".join(structure(st["name"]).orders)
    white = "white" if m["whiteness_pass"] else "not white"
    indep = "independent of the input" if m["independence_pass"] else "correlated with the input"
    beats = "above" if m["val_fit"] > m["val_fit_naive"] else "not above"
    h = int(cfg["study"]["val_horizon"])
    head = (f"{st['name'].upper()} {orders_string(st)} on {ds['name']}: {h}-step validation FIT "
            f"{_pct(m['val_fit'])}, {beats} the naive y(t-{h}) {_pct(m['val_fit_naive'])}; simulation FIT "
            f"{_pct(m['val_fit_sim'])}. Residuals {white} (p = {format_p(m['whiteness_pvalue'])}) and {indep} "
            f"(p = {format_p(m['independence_pvalue'])}), tests at the 1 % level.")
    stable = "stable" if m["max_pole_radius"] < 1 else "unstable"
    rows = [("structure", f"`{st['name']}` orders [{names}] = {orders_string(st)}, {int(m['n_params'])} parameters, "
                          f"{int(m['iterations'])} iterations"),
            ("data", f"{ds['name']} ({ds['source']}, {ds['input_class']} input): {int(m['n_est'])} estimation + "
                     f"{int(m['n_val'])} validation samples, Ts = {m['Ts']:g} s, working point u0 = {m['u0']:.3g} A; "
                     "u in A, y in cm"),
            ("FIT", f"validation {h}-step {_pct(m['val_fit'])}, simulation {_pct(m['val_fit_sim'])}, naive "
                    f"{_pct(m['val_fit_naive'])}; estimation {_pct(m['est_fit'])}"),
            ("criteria", f"loss {m['loss']:.4g}, FPE {m['fpe']:.4g}, AIC {m['aic']:.4g}, BIC {m['bic']:.4g}"),
            ("residuals", f"whiteness χ² {m['whiteness_stat']:.4g} (p = {format_p(m['whiteness_pvalue'])}), "
                          f"independence χ² {m['independence_stat']:.4g} (p = {format_p(m['independence_pvalue'])}); "
                          f"lags outside the 99 % band: {100 * m['resid_auto_outside']:.1f} % auto, "
                          f"{100 * m['resid_cross_outside']:.1f} % cross"),
            ("G", f"largest pole radius {m['max_pole_radius']:.4f} ({stable}), static gain {m['dcgain']:.4g} cm/A, "
                  f"{int(m['near_cancellations'])} near pole-zero cancellation(s)")]
    if "g_bla_err" in m:
        stationary = (f", {m['g_bla_err_stationary']:.3g} in a stationary simulation (input-spectrum weighted)"
                      if "g_bla_err_stationary" in m else "")
        rows.append(("truth", f"distance to the best linear approximation {m['g_bla_err']:.3g} (relative, on "
                              f"records of the validation length, initial state fitted){stationary}; the BLA's own "
                              f"simulation FIT {_pct(m['bla_fit_ceiling'])}"))
    table = "\n".join(f"| {k} | {v} |" for k, v in rows)
    return (f"{head}\n\n| | |\n|---|---|\n{table}\n\nFigures under `figures/`, the model in `model/model.json`, "
            "the resolved config in `config/config.yaml` (`maglev reproduce` recomputes it).\n")


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

    shutdown.install()  # joblib and submitit workers never run study.py's own installation
    shutdown.raise_if_received()
    if shutdown.launcher() not in (None, os.getpid()):  # a worker of this machine's launcher: end with it
        shutdown.exit_with(shutdown.launcher())
    ctx = hydra_context()
    plain = checked_config(cfg, single=ctx.get("sweep_dir") is None)
    plain["tracking"]["uri"] = credentials.to_env(plain["tracking"]["uri"])  # a server's user and password
    chash = config_hash(plain)
    label = progress(ctx) + run_label(plain)
    try:
        client, exp_id = tracking.connect(plain["tracking"])
    except tracking.StoreProblem as exc:
        raise RunRefused(f"maglev: {exc}") from None
    parent = tracking.sweep_parent(ctx.get("sweep_dir"))

    artifact_uris: dict[str, str] = {}  # the created run's: its uploads need not read the run back

    def create() -> str:
        tags = run_tags(plain, chash, ctx, parent)
        info = client.create_run(exp_id, run_name=run_label(plain), tags=tags).info
        artifact_uris[info.run_id] = info.artifact_uri
        return info.run_id

    config_yaml = credentials.redact(OmegaConf.to_yaml(OmegaConf.create(plain)))
    run_id, holder = None, None
    try:
        with shutdown.deferred():  # a signal while the run is created is raised once this job holds its id
            if plain["study"]["skip_finished"]:
                run_id, holder = claims.claim(client, exp_id, plain["tracking"]["uri"], chash, create)
            else:
                run_id = create()
    except BaseException as exc:
        if run_id is not None:  # seen under load: a worker's run left RUNNING when its launcher was killed
            record_end(client, plain["tracking"], run_id, exc, "KILLED", config_yaml)
        raise
    if holder is not None:
        claims.reference(client, holder, parent, plain["study"]["name"])
        log.info("%s", skip_message(label, holder, chash))
        return None
    try:
        tracking.log_batch(client, run_id, params={k: credentials.redact(v) for k, v in flatten(plain).items()})
        if ctx.get("job_num") is not None:
            wait_for_bla(plain, label)
        out = identify(plain)
        files = {"config/config.yaml": config_yaml,
                 "model/model.json": out.model.to_json(), "model/summary.txt": out.model.summary(),
                 "resid/resid.json": out.resid, "data/data.json": out.prepared.info()}
        if ctx:
            hydra_dir = Path(ctx["output_dir"]) / ".hydra"
            for f in sorted(hydra_dir.glob("*.yaml")):
                files[f"config/hydra/{f.name}"] = credentials.redact(f.read_text())
        tracking.log_files(client, run_id, files, artifact_uris.get(run_id))
        tracking.log_batch(client, run_id, metrics={**out.metrics, **tracking.key_metrics(out.metrics)},
                           tags={tracking.NOTE: model_description(plain, out.metrics)})  # one transaction
        log_data_inputs(client, run_id, plain, out.prepared)
        if not plain["tracking"]["log_figures"]:
            client.set_terminated(run_id, "FINISHED")
        elif ctx.get("job_num") is not None and ctx["launcher"].endswith("BasicLauncher"):
            render.submit(plain["tracking"]["uri"], run_id, out.figure_inputs)  # FINISHED once drawn
        else:
            render.draw_and_finish(plain["tracking"]["uri"], run_id, out.figure_inputs)
        progress_.run_done()
        log.info("%s: val_fit %.2f %%  (run %s)%s", label, out.metrics["val_fit"], run_id, time_left(ctx))
        return out.metrics["val_fit"]
    except BaseException as exc:  # noqa: BLE001 — record every way of dying
        # submitit raises UncompletedJobError (an Exception) when a job ran out of requeues: killed, not failed
        killed = not isinstance(exc, Exception) or type(exc).__name__ == "UncompletedJobError"
        status = "KILLED" if killed else "FAILED"
        record_end(client, plain["tracking"], run_id, exc, status, config_yaml)
        # a signal's KILLED runs are counted in the sweep's one line (callbacks.SweepCallback._abort)
        level = logging.DEBUG if shutdown.received and ctx.get("sweep_dir") else logging.ERROR
        log.log(level, "%s: run %s %s: %s: %s", label, run_id, status, type(exc).__name__, exc)
        shutdown.reported = shutdown.reported or level == logging.ERROR
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
