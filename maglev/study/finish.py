"""A model run after its estimation: the rest of its validation, what it logs, its figures, FINISHED.

On the basic launcher a sweep's job estimates, logs the run's params and hands the rest of its run
(:class:`Work`) to the background renderer (:mod:`maglev.study.render`), which calls :func:`complete`:
no later job needs the simulation FIT, the residual tests, the distances to the truth or the uploads,
only the ranking, which reads them after the renderer is drained.  A single run, a joblib worker or
``study.fail_on_error=true`` does the same inline (:func:`log_outputs`, then the figures).  A failure
after the estimation ends the run FAILED with its error, wherever it happens (:func:`record_end`).
"""

from __future__ import annotations

import logging
import traceback
from dataclasses import dataclass
from pathlib import Path

from maglev.study import credentials, tracking
from maglev.study.identify import Estimated, RunOutput, orders_string, validate
from maglev.validation import format_p

log = logging.getLogger("maglev.study")


@dataclass(frozen=True)
class Work:
    """What finishing an estimated run needs: the estimate, the Hydra job's config folder (its YAML files are
    logged as ``config/hydra/``; None outside Hydra) and the run's artifact URI (None: read from the run)."""

    estimated: Estimated
    hydra_dir: str | None
    artifact_uri: str | None


def config_text(cfg: dict) -> str:
    """The resolved config as logged in ``config/config.yaml`` (a password in a URI redacted)."""
    from omegaconf import OmegaConf

    return credentials.redact(OmegaConf.to_yaml(OmegaConf.create(cfg)))


def log_outputs(client, run_id: str, work: Work, out: RunOutput) -> None:
    """The run's artifacts (config, model, residuals, data), its metrics and description (one transaction) and
    its dataset inputs."""
    cfg = work.estimated.cfg
    files = {"config/config.yaml": config_text(cfg),
             "model/model.json": out.model.to_json(), "model/summary.txt": out.model.summary(),
             "resid/resid.json": out.resid, "data/data.json": out.prepared.info()}
    if work.hydra_dir is not None:
        for f in sorted(Path(work.hydra_dir).glob("*.yaml")):
            files[f"config/hydra/{f.name}"] = credentials.redact(f.read_text())
    tracking.log_files(client, run_id, files, work.artifact_uri)
    tracking.log_batch(client, run_id, metrics={**out.metrics, **tracking.key_metrics(out.metrics)},
                       tags={tracking.NOTE: model_description(cfg, out.metrics)})  # one transaction
    log_data_inputs(client, run_id, cfg, out.prepared)


def complete(uri: str, run_id: str, work: Work) -> str | None:
    """In the renderer: validate the estimated run, log it, draw its figures and mark it FINISHED.  A failure
    before the figures marks it FAILED with its error (:func:`record_end`) and returns the line to print;
    a drawing error is tagged and the run still FINISHED (:func:`maglev.study.render.draw_and_finish`)."""
    from mlflow import MlflowClient

    from maglev.study.render import draw_and_finish

    client = MlflowClient(tracking_uri=uri)
    try:
        out = validate(work.estimated)
        log_outputs(client, run_id, work, out)
    except Exception as exc:  # noqa: BLE001 — recorded on the run, said by the launcher
        record_end(client, work.estimated.cfg["tracking"], run_id, exc, "FAILED", config_text(work.estimated.cfg))
        return f"run {run_id} FAILED: {type(exc).__name__}: {exc}"
    draw_and_finish(uri, run_id, out.figure_inputs, client)
    return None


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


def record_end(client, tracking_cfg: dict, run_id: str, exc: BaseException, status: str, config_yaml: str) -> None:
    """End a run that died: the ``error`` tag first (one small call), then ``error.txt`` and the config,
    then the status; each step on its own, so that one failing upload loses nothing else.  A server
    that stopped answering ends the sweep at the first step that fails, saying nothing else
    (:class:`maglev.study.tracking.TrackingUnreachable`)."""
    steps = (lambda: tracking.log_batch(client, run_id, tags={"error": f"{type(exc).__name__}: {exc}"[:4000]}),
             lambda: tracking.log_files(client, run_id, {"error.txt": "".join(traceback.format_exception(exc)),
                                                         "config/config.yaml": config_yaml}))
    for step in steps:
        try:
            step()
        except Exception as err:  # noqa: BLE001 — go on to the status
            tracking.raise_if_unreachable(tracking_cfg["uri"])
            log.warning("run %s: could not record its error: %s: %s", run_id, type(err).__name__, err)
    try:
        client.set_terminated(run_id, status)
    except Exception:
        tracking.raise_if_unreachable(tracking_cfg["uri"])
        raise
