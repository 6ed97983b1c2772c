"""The cluster path for real: sweeps submitted to a single-node Slurm cluster (``hydra/launcher=slurm``)
into an MLflow server on PostgreSQL with basic auth (``tracking=cluster``), then the faults a cluster
brings: a job cancelled, a job at its time limit, the server restarted mid-sweep, two users at once.

Run with ``MAGLEV_CLUSTER=1 python -m pytest -q -p no:cacheprovider tests/cluster`` (``.ci/run``'s
cluster stage); the services are in ``services.py``, the fixture in ``conftest.py``.
"""

from __future__ import annotations

import time
from collections import Counter

from tests.cluster.conftest import TINY, dump, finish, metrics, tags

FIGURES = {"figures/bode.png", "figures/compare.png", "figures/pzmap.png", "figures/resid.png"}
LEAN = ["study.true_plant=false", "lab.enabled=false"]
FAULT = [*LEAN, "tracking.log_figures=false"]  # the fault tests are about runs' states, not their figures


def finished_once(cluster, experiment: str, n: int) -> dict[str, dict]:
    """Every config of ``experiment`` FINISHED exactly once (``n`` configs), none left RUNNING; by hash."""
    models = cluster.runs(experiment, "tags.kind = 'model'")
    assert not [r for r in models if r["info"]["status"] == "RUNNING"], "a run was left RUNNING"
    done = [r for r in models if r["info"]["status"] == "FINISHED"]
    per_config = Counter(tags(r)["config_hash"] for r in done)
    assert len(per_config) == n and set(per_config.values()) == {1}, per_config
    return {tags(r)["config_hash"]: r for r in done}


def test_a_sweep_of_8_slurm_jobs_into_the_postgres_server(cluster, tmp_path):
    # a stray MLFLOW_RUN_ID (left by another tool in the user's shell) must not become the parent or a job's run
    decoy_exp = cluster.rest("experiments/create", {"name": "decoy"})["experiment_id"]
    decoy = cluster.rest("runs/create", {"experiment_id": decoy_exp})["run"]["info"]["run_id"]
    proc = cluster.sweep("alice", tmp_path, "c8", "dataset=binary_a025,uniform_narrow", "structure=arx,oe",
                         "structure.order=2,3", "tracking.experiment=c8", *TINY, *LEAN,
                         env={"MLFLOW_RUN_ID": decoy})
    assert proc.returncode == 0, dump(proc)

    [parent] = cluster.runs("c8", "tags.kind = 'sweep'")
    assert parent["info"]["status"] == "FINISHED"
    runs = finished_once(cluster, "c8", 8)
    assert {tags(r)["mlflow.parentRunId"] for r in runs.values()} == {parent["info"]["run_id"]}
    assert len({tags(r)["slurm_job"] for r in runs.values()}) == 8  # one Slurm array task each
    assert metrics(parent)["runs_finished"] == 8
    for run in runs.values():
        contexts = sorted(t["value"] for i in run["inputs"]["dataset_inputs"] for t in i["tags"]
                          if t["key"] == "mlflow.data.context")
        assert contexts == ["estimation", "validation"], run["inputs"]
        listing = cluster.rest(f"artifacts/list?run_id={run['info']['run_id']}&path=figures")
        assert FIGURES <= {f["path"] for f in listing["files"]}, listing  # uploaded through the server
    [ranking] = cluster.runs("c8", "tags.kind = 'ranking'")
    assert tags(ranking)["sweep_parent"] == parent["info"]["run_id"] and metrics(ranking)["n_ranked"] == 8
    sid = tags(parent)["sweep_id"]
    assert [p.name for p in (tmp_path / "reports").glob("*.html")] == [f"c8-{sid[:8]}.html"]
    listing = cluster.rest(f"artifacts/list?run_id={ranking['info']['run_id']}&path=report")
    assert [f["path"] for f in listing["files"]] == [f"report/c8-{sid[:8]}.html"]
    secrets = [pw for _, pw in cluster.users.values()]  # credentials stay in MLflow's variables, never logged
    assert not [kv for r in runs.values() for kv in r["data"]["params"] + r["data"]["tags"]
                if any(pw in kv["value"] for pw in secrets)]
    decoy_run = cluster.rest(f"runs/get?run_id={decoy}")["run"]
    assert decoy_run["info"]["status"] == "RUNNING" and not decoy_run["data"].get("metrics")
    assert not cluster.runs("decoy", f"tags.`mlflow.parentRunId` = '{decoy}'")


def test_scancel_of_a_job_mid_run_ends_its_run_killed_and_the_same_command_finishes_it(cluster, tmp_path):
    args = ("alice", tmp_path, "cancel", "dataset=binary_a025,uniform_narrow", "structure=oe",
            "dataset.duration_s=30", "tracking.experiment=cancel", *FAULT)
    proc = cluster.start(*args, rank=False)
    victim = cluster.wait_running("cancel")
    cluster.slurm.run("scancel", tags(victim)["slurm_job"])
    first = finish(proc, 900)
    assert first.returncode == 1, dump(first)
    assert f"Slurm job {tags(victim)['slurm_job']} (" in first.stderr and "CANCELLED" in first.stderr, dump(first)
    assert "Traceback" not in first.stderr, dump(first)
    run = cluster.rest(f"runs/get?run_id={victim['info']['run_id']}")["run"]
    assert run["info"]["status"] == "KILLED", run["info"]
    assert not cluster.runs("cancel", "attributes.status = 'RUNNING'")

    again = cluster.sweep(*args, rank=False)
    assert again.returncode == 0, dump(again)
    finished_once(cluster, "cancel", 2)
    [parent] = cluster.runs("cancel", "tags.kind = 'sweep'")
    assert parent["info"]["status"] == "FINISHED" and tags(parent)["resumed"] == "true"


def test_a_job_at_its_time_limit_ends_its_run_killed_in_one_line(cluster, tmp_path):
    # a BJ of a 50-minute record takes minutes (a 10-minute one took 40 s on an idle machine): Slurm stops it
    # at its 1-minute limit, its run long created
    # (a job's process takes up to 30 s to start under load): submitit's SIGUSR2 asked for 5 s before the
    # end, or the SIGTERM at the limit itself when slurmctld's 30-s checks pass that window
    tic = time.monotonic()
    proc = cluster.sweep("alice", tmp_path, "limit", "dataset=uniform_wide", "structure=bj", "structure.order=6",
                         "dataset.duration_s=3000", "tracking.experiment=limit", "hydra.launcher.timeout_min=1",
                         "hydra.launcher.signal_delay_s=5", *FAULT, rank=False)
    runs = cluster.runs("limit", "tags.kind = 'model'")
    assert len(runs) == 1, dump(proc)
    run = runs[0]
    assert run["info"]["status"] != "FINISHED", f"the job finished in {time.monotonic() - tic:.0f} s, within its limit"
    assert proc.returncode == 1, dump(proc)
    assert run["info"]["status"] == "KILLED", run["info"]
    assert "UncompletedJobError" in tags(run)["error"] or "SystemExit: 143" in tags(run)["error"], tags(run)
    lines = [line for line in proc.stderr.splitlines() if line.startswith("maglev: Slurm job")]
    assert len(lines) == 1 and "Traceback" not in proc.stderr, dump(proc)
    [parent] = cluster.runs("limit", "tags.kind = 'sweep'")
    assert parent["info"]["status"] == "KILLED"


def test_the_server_restarted_mid_sweep_loses_and_duplicates_no_run(cluster, tmp_path):
    proc = cluster.start("bob", tmp_path, "restart", "dataset=binary_a025,uniform_narrow,uniform_wide",
                         "structure=oe", "dataset.duration_s=20", "tracking.experiment=restart", *FAULT, rank=False)
    cluster.wait_running("restart")
    cluster.server.stop()
    time.sleep(3)  # jobs meet a closed port, then a server starting up
    cluster.server.start()
    done = finish(proc, 900)
    assert done.returncode == 0, dump(done)
    finished_once(cluster, "restart", 3)
    assert not [r for r in cluster.runs("restart", "tags.kind = 'model'") if r["info"]["status"] != "FINISHED"]
    [parent] = cluster.runs("restart", "tags.kind = 'sweep'")
    assert parent["info"]["status"] == "FINISHED"


def test_two_users_sweeping_into_one_server_at_once_run_each_config_once(cluster, tmp_path):
    common = ("structure=arx", "structure.order=2,3", "tracking.experiment=shared", *TINY, *FAULT)
    procs = {"alice": cluster.start("alice", tmp_path / "alice", "alab", "dataset=binary_a025,uniform_narrow", *common),
             "bob": cluster.start("bob", tmp_path / "bob", "blab", "dataset=uniform_narrow,uniform_wide", *common)}
    results = {user: finish(proc, 900) for user, proc in procs.items()}
    for result in results.values():
        assert result.returncode == 0, dump(result)
    finished_once(cluster, "shared", 6)  # 2 configs (uniform_narrow × orders 2, 3) are both users'
    parents = {tags(p)["sweep"]: p for p in cluster.runs("shared", "tags.kind = 'sweep'")}
    assert set(parents) == {"alab", "blab"}
    for user, name in (("alice", "alab"), ("bob", "blab")):
        pid = parents[name]["info"]["run_id"]
        [ranking] = cluster.runs("shared", f"tags.kind = 'ranking' and tags.sweep_parent = '{pid}'")
        assert metrics(ranking)["n_ranked"] == 4  # its own 4 configs, whoever ran them
        sid = tags(parents[name])["sweep_id"]
        assert [p.name for p in (tmp_path / user / "reports").glob("*.html")] == [f"{name}-{sid[:8]}.html"]
