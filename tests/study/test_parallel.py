"""Parallel and server modes: joblib workers sharing one SQLite store; an `mlflow server` on 127.0.0.1
(the ``mlflow_server`` fixture, conftest.py)."""

from __future__ import annotations

import json
import os
import subprocess
import sys
import urllib.request
from pathlib import Path

import pytest

from .harness import LEAN, REPO, TINY, all_runs, study_process

pytestmark = pytest.mark.filterwarnings("ignore:The .*noload.* loader strategy is deprecated")


@pytest.mark.slow
def test_joblib_two_workers_lose_no_run(tmp_path):
    pytest.importorskip("hydra_plugins.hydra_joblib_launcher")
    study_process(tmp_path, "-m", "~hydra.callbacks.maglev_rank", "hydra/launcher=parallel", "hydra.launcher.n_jobs=2",
                  "dataset=uniform_narrow,binary_a025", "structure=arx,oe", *TINY, *LEAN)
    _, _, runs = all_runs(tmp_path)
    parent = [r for r in runs if r.data.tags.get("kind") == "sweep"]
    kids = [r for r in runs if r.data.tags.get("kind") == "model"]
    assert len(parent) == 1 and len(kids) == 4
    assert all(r.info.status == "FINISHED" and "val_fit" in r.data.metrics for r in kids)
    assert {r.data.tags["mlflow.parentRunId"] for r in kids} == {parent[0].info.run_id}
    assert len({r.data.tags["config_hash"] for r in kids}) == 4


def _api(base: str, endpoint: str, body: dict | None = None) -> dict:
    data = None if body is None else json.dumps(body).encode()
    req = urllib.request.Request(f"{base}/api/2.0/mlflow/{endpoint}", data=data,
                                 headers={"Content-Type": "application/json"})
    with urllib.request.urlopen(req, timeout=30) as resp:
        return json.loads(resp.read())


@pytest.mark.slow
def test_server_mode_runs_are_listed_by_the_rest_api(tmp_path, mlflow_server):
    store = tmp_path / "client"
    store.mkdir()
    cmd = [sys.executable, str(REPO / "study.py"), "-m", "tracking=server", f"tracking.uri={mlflow_server}",
           "dataset=uniform_narrow", "structure=arx,oe", *TINY, "study.true_plant=false", "lab.enabled=false",
           f"hydra.sweep.dir={store}/multirun", f"hydra.run.dir={store}/outputs",
           f"hydra.callbacks.maglev_rank.report_dir={store}/reports"]  # ranking via the server too
    env = {k: v for k, v in os.environ.items() if k != "MLFLOW_TRACKING_URI"}
    proc = subprocess.run(cmd, capture_output=True, text=True, cwd=store, timeout=300, env=env)
    assert proc.returncode == 0, proc.stderr[-3000:]
    exp = _api(mlflow_server, "experiments/get-by-name?experiment_name=maglev")["experiment"]
    found = _api(mlflow_server, "runs/search", {"experiment_ids": [exp["experiment_id"]],
                                                "filter": "tags.kind = 'model'", "max_results": 100})
    runs = found["runs"]
    assert len(runs) == 2 and all(r["info"]["status"] == "FINISHED" for r in runs)
    tags = [{t["key"]: t["value"] for t in r["data"]["tags"]} for r in runs]
    parents = {t["mlflow.parentRunId"] for t in tags}
    assert len(parents) == 1
    parent = _api(mlflow_server, f"runs/get?run_id={parents.pop()}")["run"]
    assert parent["info"]["status"] == "FINISHED"
    run_id = runs[0]["info"]["run_id"]
    listing = _api(mlflow_server, f"artifacts/list?run_id={run_id}&path=figures")
    assert {"figures/bode.png", "figures/compare.png"} <= {f["path"] for f in listing["files"]}
    assert not (Path(store) / "mlruns").exists()
    # the end-of-sweep ranking also works against the server
    ranking = _api(mlflow_server, "runs/search", {"experiment_ids": [exp["experiment_id"]],
                                                  "filter": "tags.kind = 'ranking'", "max_results": 10})
    assert len(ranking["runs"]) == 1 and (Path(store) / "reports").is_dir()
