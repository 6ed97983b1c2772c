"""The cluster path on one machine: a sweep whose jobs are each their own process (submitit's local
executor), tracked on an `mlflow server` on 127.0.0.1 (the ``mlflow_server`` fixture, conftest.py), and
read back as MLflow's UI reads it, through the server's REST API.

One launch covers the server mode, the cluster launcher and a password in the tracking URI: each costs a
process start and a server, a cluster sweep is what a server is for (docs/study.md, "Parallel and cluster runs"),
and a server is where a URI carries a password (docs/faults.md).
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


SECRET = "s3cr3t-pw"


def test_a_submitit_sweep_against_a_tracking_server_is_listed_by_its_rest_api_without_the_uris_password(
        tmp_path, mlflow_server):
    pytest.importorskip("hydra_plugins.hydra_submitit_launcher",
                        reason="hydra-submitit-launcher is not installed (pip install -e .[cluster])")
    store = tmp_path / "client"
    store.mkdir()
    uri = mlflow_server.replace("http://", f"http://alice:{SECRET}@")  # the password test below
    cmd = [sys.executable, str(REPO / "study.py"), "-m", "hydra/launcher=local", "tracking=server",
           f"tracking.uri={uri}", "dataset=binary_a025,uniform_narrow", "structure=arx", *TINY,
           "study.true_plant=false", "lab.enabled=false", "study.name=sub2", "tracking.experiment=cluster",
           f"hydra.sweep.dir={store}/multirun", f"hydra.callbacks.maglev_rank.report_dir={store}/reports"]
    proc = subprocess.run(cmd, capture_output=True, text=True, cwd=store, timeout=600, env=process_env("MLFLOW_"))
    assert proc.returncode == 0, proc.stderr[-3000:]
    assert SECRET not in proc.stdout + proc.stderr and "alice" not in proc.stdout + proc.stderr

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
    assert_no_password(mlflow_server, "cluster", store / "reports", tmp_path / "dl")


def assert_no_password(server: str, experiment: str, reports, downloads) -> None:
    """A password in the tracking URI is nowhere in the store or the report.  Before: stored in a param, two
    tags, the run description, the report and four config artifacts, and printed.  Every param, tag, metric
    name, description and text artifact of every run is searched."""
    from mlflow import MlflowClient

    from .harness import artifact_paths

    client = MlflowClient(tracking_uri=server)
    runs = client.search_runs([client.get_experiment_by_name(experiment).experiment_id], max_results=100)
    assert {r.data.tags.get("kind") for r in runs} == {"sweep", "model", "ranking"}
    for r in runs:
        for text in [*r.data.params.values(), *r.data.tags.values(), *r.data.tags, *r.data.params, *r.data.metrics]:
            assert SECRET not in text and "alice" not in text, (r.info.run_id, text[:300])
        for path in artifact_paths(client, r.info.run_id):
            if path.endswith((".yaml", ".json", ".txt", ".html")):
                local = client.download_artifacts(r.info.run_id, path, str(downloads / r.info.run_id))
                body = open(local, encoding="utf-8").read()
                assert SECRET not in body and "alice" not in body, (r.info.run_id, path)
    [report] = list(reports.glob("*.html"))
    assert SECRET not in report.read_text() and "alice" not in report.read_text()
    params = next(r for r in runs if r.data.tags.get("kind") == "model").data.params
    assert params["tracking.uri"] == server  # the URI, without its userinfo
