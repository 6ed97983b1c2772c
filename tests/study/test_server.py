"""The cluster path on one machine: a sweep whose jobs are each their own process (submitit's local
executor), tracked on an `mlflow server` on 127.0.0.1 (the ``mlflow_server`` fixture, conftest.py), and
read back as MLflow's UI reads it, through the server's REST API.

One launch covers both the server mode and the cluster launcher: each costs a process start and a
server, and a cluster sweep is what a server is for (docs/study.md, "Parallel and cluster runs").
"""

from __future__ import annotations

import json
import subprocess
import sys
import urllib.request

import pytest

from .harness import REPO, TINY, process_env

pytestmark = [pytest.mark.slow, pytest.mark.filterwarnings("ignore:The .*noload.* loader strategy is deprecated")]


def rest(base: str, endpoint: str, body: dict | None = None) -> dict:
    """One call of MLflow's REST API (``/api/2.0/mlflow/<endpoint>``), GET or, with ``body``, POST."""
    data = None if body is None else json.dumps(body).encode()
    req = urllib.request.Request(f"{base}/api/2.0/mlflow/{endpoint}", data=data,
                                 headers={"Content-Type": "application/json"})
    with urllib.request.urlopen(req, timeout=30) as resp:
        return json.loads(resp.read())


def tags(run: dict) -> dict[str, str]:
    return {t["key"]: t["value"] for t in run["data"].get("tags", [])}


def test_a_submitit_sweep_against_a_tracking_server_is_listed_by_its_rest_api(tmp_path, mlflow_server):
    pytest.importorskip("hydra_plugins.hydra_submitit_launcher",
                        reason="hydra-submitit-launcher is not installed (pip install -e .[cluster])")
    store = tmp_path / "client"
    store.mkdir()
    cmd = [sys.executable, str(REPO / "study.py"), "-m", "hydra/launcher=local", "tracking=server",
           f"tracking.uri={mlflow_server}", "dataset=binary_a025,uniform_narrow", "structure=arx", *TINY,
           "study.true_plant=false", "lab.enabled=false", "study.name=sub2", "tracking.experiment=cluster",
           f"hydra.sweep.dir={store}/multirun", f"hydra.callbacks.maglev_rank.report_dir={store}/reports"]
    proc = subprocess.run(cmd, capture_output=True, text=True, cwd=store, timeout=600, env=process_env())
    assert proc.returncode == 0, proc.stderr[-3000:]

    exp = rest(mlflow_server, "experiments/get-by-name?experiment_name=cluster")["experiment"]["experiment_id"]
    everything = rest(mlflow_server, "runs/search", {"experiment_ids": [exp], "max_results": 100})["runs"]
    [parent] = [r for r in everything if tags(r).get("kind") == "sweep"]
    models = [r for r in everything if tags(r).get("kind") == "model"]
    assert parent["info"]["status"] == "FINISHED" and len(models) == 2
    assert {r["info"]["status"] for r in models} == {"FINISHED"}
    assert len({tags(r)["config_hash"] for r in models}) == 2
    assert {tags(r)["mlflow.parentRunId"] for r in models} == {parent["info"]["run_id"]}
    assert len({tags(r)["pid"] for r in models}) == 2  # one process per job: submitit's, not the launcher
    for run in models:  # each job uploaded its figures through the server
        listing = rest(mlflow_server, f"artifacts/list?run_id={run['info']['run_id']}&path=figures")
        assert {"figures/bode.png", "figures/compare.png"} <= {f["path"] for f in listing["files"]}
    [ranking] = [r for r in everything if tags(r).get("kind") == "ranking"]
    n_ranked = {m["key"]: m["value"] for m in ranking["data"]["metrics"]}["n_ranked"]
    assert tags(ranking)["sweep_parent"] == parent["info"]["run_id"] and n_ranked == 2
    sweep_id = tags(parent)["sweep_id"]
    assert [p.name for p in (store / "reports").glob("*.html")] == [f"sub2-{sweep_id[:8]}.html"]
    assert (store / "multirun" / ".submitit").is_dir() and not (store / "mlruns").exists()
