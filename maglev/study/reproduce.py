"""Re-run a tracked run from its logged config and check that the metrics are identical.

``maglev reproduce RUN_ID`` downloads ``config/config.yaml`` (the resolved config) of
the run, re-applies the schema, recomputes the identification without MLflow and
compares every metric except timings (``fit_seconds``) exactly.  ``--log`` also logs
the reproduction as a new run tagged ``reproduces=RUN_ID`` (``kind=reproduction``).
The run's ``git_commit`` tag says which code produced it; a different checkout is
reported.
"""

from __future__ import annotations

import math
import sys


def same(a: float, b: float) -> bool:
    return a == b or (math.isnan(a) and math.isnan(b))


def reproduce(run_id: str, uri: str, data_dir: str | None = None, log_run: bool = False) -> tuple[bool, list]:
    """(identical?, rows of (metric, logged, recomputed)) for the run ``run_id``."""
    from mlflow import MlflowClient
    from omegaconf import OmegaConf

    from maglev.study import tracking
    from maglev.study.config import config_hash, plain_config
    from maglev.study.identify import TIMING_METRICS, identify

    client = MlflowClient(tracking_uri=uri)
    run = client.get_run(run_id)
    cfg = plain_config(OmegaConf.create(tracking.download_text(client, run_id, "config/config.yaml")))
    if data_dir:
        cfg["data_dir"] = data_dir
    logged_hash = run.data.tags.get("config_hash")
    if logged_hash and config_hash(cfg) != logged_hash:
        print(f"warning: the config hash differs from the logged one ({logged_hash[:10]})", file=sys.stderr)
    commit = run.data.tags.get("git_commit")
    now = tracking.git_info()["git_commit"]
    if commit and commit != now:
        print(f"note: run made at commit {commit[:10]}, this checkout is {now[:10]}", file=sys.stderr)
    out = identify(cfg)
    rows = []
    for key in sorted(run.data.metrics):
        if key in TIMING_METRICS:
            continue
        new = out.metrics.get(key, math.nan)
        rows.append((key, run.data.metrics[key], tracking._finite(new)))
    ok = all(same(a, b) for _, a, b in rows) and bool(rows)
    if log_run:
        client2, exp_id = tracking.connect(cfg["tracking"] | {"uri": uri})
        rid = client2.create_run(exp_id, run_name=f"reproduce {run.info.run_name}",
                                 tags={"kind": "reproduction", "reproduces": run_id,
                                       "identical": str(ok).lower(), **tracking.process_tags()}).info.run_id
        tracking.log_batch(client2, rid, metrics=out.metrics)
        client2.set_terminated(rid, "FINISHED")
    return ok, rows
