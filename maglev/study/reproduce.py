"""Re-run a tracked run from its logged config and check that the metrics are identical.

``maglev reproduce RUN_ID`` downloads ``config/config.yaml`` (the resolved config) of
the run, re-applies the schema, recomputes the identification without MLflow and
compares every metric except timings (``fit_seconds``) exactly.  ``--log`` also logs
the reproduction as a new run tagged ``reproduces=RUN_ID`` (``kind=reproduction``).
The run's ``git_commit`` tag says which code produced it, its ``lib.*`` tags which
numpy, scipy and control, and its sweep's ``environment/requirements.txt`` every installed
package (:mod:`maglev.study.environment`); a different checkout or package version is reported, and
metrics that differ only by rounding (:func:`within_rounding`) are told apart from
real differences.  A wrong id, a run that is not a model run (a sweep parent, a ranking) or one
that did not finish raises :class:`~maglev.study.store.SweepError` with one line saying
what the run is (the command prints it and exits 2).
"""

from __future__ import annotations

import math
import sys


# Other builds of numpy / scipy round differently: measured on runs logged before 2026-11-26 and recomputed
# with numpy 2.4.6 and scipy 1.17.1, OE's metrics moved by <= 1.2e-13 relative, ARMAX's (through its
# optimiser's iterations) by <= 1.4e-8, and p-values of 1e-90 to 1e-165 by <= 6e-6 relative.
ROUNDING_RELATIVE = 1e-7
ROUNDING_ABSOLUTE = 1e-12  # for the vanishing p-values


def same(a: float, b: float) -> bool:
    return a == b or (math.isnan(a) and math.isnan(b))


def within_rounding(a: float, b: float) -> bool:
    """Equal but for the last digits another build of the numeric libraries may change."""
    return same(a, b) or abs(a - b) <= max(ROUNDING_RELATIVE * max(abs(a), abs(b)), ROUNDING_ABSOLUTE)


def open_client(uri: str):
    """A client on an existing store (a missing SQLite file is an error, never created)."""
    from mlflow import MlflowClient

    from maglev.study.store import SweepError
    from maglev.study.tracking import sqlite_path

    db = sqlite_path(uri)
    if db is not None and not db.is_file():
        raise SweepError(f"no MLflow store at {db}; pass --tracking-uri")
    return MlflowClient(tracking_uri=uri)


def model_run(client, run_id: str, uri: str):
    """The run ``run_id`` if it is a FINISHED model run; else a one-line :class:`SweepError` saying what it is."""
    from mlflow.exceptions import MlflowException

    from maglev.study.store import SweepError

    try:
        run = client.get_run(run_id)
    except MlflowException as exc:
        if exc.error_code in ("RESOURCE_DOES_NOT_EXIST", "INVALID_PARAMETER_VALUE"):
            raise SweepError(f"no run {run_id!r} in {uri}") from None
        raise SweepError(f"cannot read run {run_id!r} from {uri}: {exc.message.splitlines()[0]}") from None
    kind, name = run.data.tags.get("kind"), run.info.run_name
    if kind != "model":
        what = {"sweep": "a sweep's parent run", "ranking": "a ranking run",
                "reproduction": "a reproduction"}.get(kind, "not a run of the study")
        raise SweepError(f"run {run_id} ({name}) is {what}, not a model run; give the id of one of "
                         "its model runs (tags.kind = 'model')")
    if run.info.status != "FINISHED":
        why = run.data.tags.get("error", "")
        raise SweepError(f"run {run_id} ({name}) is {run.info.status}, not FINISHED: nothing to reproduce"
                         + (f" ({why.splitlines()[0][:200]})" if why else ""))
    return run


def recompute(cfg: dict, logged: dict[str, float]):
    """(identical?, rows of (metric, logged, recomputed), run output): ``cfg``'s run again
    without MLflow, every logged metric but the timings compared exactly."""
    from maglev.study import tracking
    from maglev.study.identify import TIMING_METRICS, identify

    out = identify(cfg)
    recomputed = {**out.metrics, **tracking.key_metrics(out.metrics)}
    rows = [(key, logged[key], tracking._finite(recomputed.get(key, math.nan)))
            for key in sorted(logged) if key not in TIMING_METRICS]
    return all(same(a, b) for _, a, b in rows) and bool(rows), rows, out


def _compare_environment(client, run) -> None:
    """Warn, naming each package, when this environment differs from the one the run's sweep recorded."""
    from maglev.study import environment
    from maglev.study.store import artifact_bytes

    parent = run.data.tags.get("mlflow.parentRunId")
    raw = artifact_bytes(client, parent, environment.ARTIFACT) if parent else None
    if raw is None:
        print(f"note: the run's sweep recorded no environment ({environment.ARTIFACT}); package versions "
              "are not compared", file=sys.stderr)
        return
    diff = environment.differences(environment.parse(raw.decode()), environment.current())
    if diff:
        print(f"warning: {len(diff)} package(s) differ from the sweep's environment: {', '.join(diff)}; "
              f"`pip install -r {environment.ARTIFACT}` (an artifact of parent run {parent}) rebuilds it",
              file=sys.stderr)


def reproduce(run_id: str, uri: str, data_dir: str | None = None, log_run: bool = False) -> tuple[bool, list]:
    """(identical?, rows of (metric, logged, recomputed)) for the run ``run_id``."""
    from maglev.study import tracking
    from maglev.study.config import config_hash
    from maglev.study.store import run_config

    client = open_client(uri)
    run = model_run(client, run_id, uri)
    cfg = run_config(client, run_id)
    if data_dir:
        cfg["data_dir"] = data_dir
    logged_hash = run.data.tags.get("config_hash")
    if logged_hash and config_hash(cfg) != logged_hash:
        print(f"warning: the config hash differs from the logged one ({logged_hash[:10]})", file=sys.stderr)
    commit = run.data.tags.get("git_commit")
    now = tracking.git_info()["git_commit"]
    if commit and commit != now:
        print(f"note: run made at commit {commit[:10]}, this checkout is {now[:10]}", file=sys.stderr)
    libs = {k: (v, run.data.tags[k]) for k, v in tracking.library_versions().items()
            if run.data.tags.get(k, v) != v}
    if libs:
        print("note: run made with " + ", ".join(f"{k[len(tracking.LIBRARY_TAG):]} {was} (now {current})"
                                                 for k, (current, was) in libs.items())
              + ": metrics may differ in their last digits", file=sys.stderr)
    _compare_environment(client, run)
    ok, rows, out = recompute(cfg, run.data.metrics)
    if log_run:
        client2, exp_id = tracking.connect(cfg["tracking"] | {"uri": uri})
        rid = client2.create_run(exp_id, run_name=f"reproduce {run.info.run_name}",
                                 tags={"kind": "reproduction", "reproduces": run_id,
                                       "identical": str(ok).lower(), **tracking.process_tags()}).info.run_id
        tracking.log_batch(client2, rid, metrics=out.metrics)
        client2.set_terminated(rid, "FINISHED")
    return ok, rows
