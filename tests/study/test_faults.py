"""Faults and impossible configs, in-process: refused before any run, one line naming the key or the URI.

The table of every fault tried and what the user sees is docs/faults.md; the process-level
faults (concurrent launches, SIGTERM, kill -9, a cluster launcher) are in test_concurrency.py.
"""

from __future__ import annotations

import os
import socket
import subprocess
import sys
import time
from types import SimpleNamespace

import pytest

from .harness import REPO, TINY, all_runs, artifact_paths, launch, process_env

pytestmark = pytest.mark.filterwarnings("ignore:The .*noload.* loader strategy is deprecated")


def closed_port() -> int:
    """A 127.0.0.1 port nobody listens on (bound, then released)."""
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def no_runs(store) -> bool:
    return not (store / "mlflow.db").exists() or all_runs(store)[2] == []


# ---------------------------------------------------------------------------- impossible configs
@pytest.mark.parametrize("overrides, needle", [
    (["dataset.preprocess.split=0.5,0.9999"], "dataset.preprocess.split=0.9999: dataset 'binary_a025'"),
    (["structure=bj", "structure.order=2,400"], "structure.order (bj[400 400 400 400 2])"),
    (["dataset.preprocess.trim=500,3950"], "dataset.preprocess.trim=3950: dataset 'binary_a025' (4000 samples"),
    (["study.resid_lags=25,1000"], "study.resid_lags=1000"),
    (["structure=oe", "structure.max_iterations=200,-3"], "structure.max_iterations must be >= 0, got -3"),
    (["dataset.alpha=null"], "dataset.alpha (switching probability in [0, 1]) is needed"),
])
def test_a_sweep_with_an_impossible_config_is_refused_before_any_run(tmp_path, overrides, needle):
    """The good first job would have run before the bad second one: the whole sweep is checked first."""
    with pytest.raises(SystemExit) as refused:
        launch(tmp_path, "dataset=binary_a025", "structure.order=2", *TINY, "lab.enabled=false", *overrides)
    message = str(refused.value.code)
    assert message.startswith("maglev: sweep refused before any run: job ") and needle in message, message
    assert "\n" not in message and "tracking.uri" not in message
    assert no_runs(tmp_path)


def test_a_single_impossible_run_is_refused_before_its_run(tmp_path):
    """One line (a SystemExit: Hydra prints an Exception of the task with its traceback), no store."""
    with pytest.raises(SystemExit, match=r"^maglev: run refused before it started: study\.resid_lags=900: .* "
                                         r"leaves 875 estimation and 875 valid") as refused:
        launch(tmp_path, "dataset=binary_a025", *TINY, "study.resid_lags=900", multirun=False)
    assert "\n" not in str(refused.value.code)
    assert no_runs(tmp_path)


def test_a_sweep_whose_parent_cannot_be_set_up_stops_before_any_job(tmp_path, monkeypatch):
    """Hydra turns a callback's Exception into a warning and would run the jobs without lock or parent."""
    from maglev.study import tracking

    def refuse(cfg):
        raise RuntimeError("UNIQUE constraint failed: experiment_tags.key\n[SQL: INSERT ...]")

    monkeypatch.setattr(tracking, "connect", refuse)
    # no figures: the renderer's process (≈ 1.8 s of CPU to import) would start before the store, for nothing; what is
    # asserted here (one line, no run) does not involve it
    with pytest.raises(SystemExit) as stopped:
        launch(tmp_path, "dataset=binary_a025", "structure=arx,oe", *TINY, "lab.enabled=false",
               "tracking.log_figures=false")
    assert stopped.value.code == ("maglev: the sweep could not start: RuntimeError: "
                                  "UNIQUE constraint failed: experiment_tags.key")
    assert no_runs(tmp_path)


# ---------------------------------------------------------------------------- an unreachable server
def test_a_closed_port_fails_at_once_in_one_line_naming_the_uri(tmp_path):
    """MLflow alone retried each call for ≈ 4 minutes and printed a 100-line traceback."""
    uri = f"http://127.0.0.1:{closed_port()}"
    cmd = [sys.executable, str(REPO / "study.py"), "-m", "tracking=server", f"tracking.uri={uri}",
           "dataset=binary_a025", "structure=arx,oe", *TINY, f"hydra.sweep.dir={tmp_path}/multirun"]
    env = process_env("MLFLOW_")
    tic = time.monotonic()
    proc = subprocess.run(cmd, capture_output=True, text=True, cwd=tmp_path, timeout=120, env=env)
    elapsed = time.monotonic() - tic
    assert proc.returncode == 1 and elapsed < 60, (elapsed, proc.stderr[-2000:])
    lines = proc.stderr.strip().splitlines()
    assert lines[-1].startswith(f"maglev: the MLflow tracking server {uri} cannot be reached (ConnectionError"), lines
    assert "Traceback" not in proc.stderr and len(lines) <= 3, proc.stderr


def test_a_closed_port_ends_the_sweep_before_its_renderer_and_bla_process_start(tmp_path, monkeypatch):
    """Before: both started first, while the store was connected to, and ended unused (the renderer imports for
    ≈ 1.8 s of CPU; a BLA process simulates hundreds of records of each class)."""
    from maglev.study import datasets, render

    from . import harness

    started = []
    monkeypatch.setattr(render, "start", lambda *args, **kwargs: started.append("renderer"))
    monkeypatch.setattr(datasets, "prepare_blas", lambda *args, **kwargs: started.append("bla"))
    monkeypatch.setenv("MAGLEV_CACHE", str(tmp_path / "cache"))  # nothing cached: the sweep needs a BLA
    monkeypatch.setattr(harness, "store_overrides", lambda store: [f"hydra.sweep.dir={store}/multirun"])
    uri = f"http://127.0.0.1:{closed_port()}"
    with pytest.raises(SystemExit) as stopped:
        launch(tmp_path, "tracking=server", f"tracking.uri={uri}", "tracking.max_retries=0", "dataset=binary_a025",
               "structure=arx,oe", *TINY, "lab.enabled=false")
    assert str(stopped.value.code).startswith(f"maglev: the MLflow tracking server {uri} cannot be reached"), \
        stopped.value.code
    assert started == []


def test_a_server_gone_when_a_job_claims_its_config_ends_the_sweep_in_one_line_and_its_end_writes_nothing(
        migrated_store, monkeypatch):
    """A server killed in the middle of a sweep: with a run's validation and uploads on the renderer, the next
    job's first call to it is often its claim (a search).  Before, that error went to Hydra, which went on to
    the next job (each waiting out its retries), printed the first one's traceback at the end, and the sweep's
    end at exit called the dead server again.  Here the store is a local one standing in for the server until
    the claim, whose call fails as a dead server's does; the URI is a closed port, as the server's would be."""
    import atexit

    from mlflow.exceptions import MlflowException

    from maglev.study import claims, tracking

    from . import harness
    from .harness import study_log

    uri = f"http://127.0.0.1:{closed_port()}"
    local = tracking.connect({"uri": f"sqlite:///{migrated_store}/mlflow.db", "experiment": "maglev",
                              "artifact_location": str(migrated_store / "artifacts")})
    monkeypatch.setattr(tracking, "connect", lambda cfg, reuse=False: local)  # the server, until it died
    monkeypatch.setattr(tracking, "unreachable", None)
    claimed = []

    def dead(*args):
        claimed.append(args[3])
        raise MlflowException(f"API request to {uri}/api/2.0/mlflow/runs/search failed with exception "
                              "HTTPConnectionPool: Max retries exceeded")

    monkeypatch.setattr(claims, "claim", dead)
    at_exit = []
    monkeypatch.setattr(atexit, "register", at_exit.append)  # the sweep's end at exit, called below
    monkeypatch.setattr(harness, "store_overrides", lambda store: [f"hydra.sweep.dir={store}/multirun"])
    with pytest.raises(SystemExit) as stopped:
        launch(migrated_store, "tracking=server", f"tracking.uri={uri}", "dataset=binary_a025", "structure=arx,oe",
               *TINY, "lab.enabled=false", "tracking.log_figures=false", "study.true_plant=false")
    assert str(stopped.value.code).startswith(f"maglev: the MLflow tracking server {uri} cannot be reached"), \
        stopped.value.code
    assert len(claimed) == 1  # the first job to find the server gone ends the sweep
    ends = [f for f in at_exit if getattr(f, "__name__", "") == "_abort"]  # SweepCallback._abort
    assert len(ends) == 1
    with study_log() as lines:
        ends[0]()
    assert lines == []


def test_rank_against_a_closed_port_says_so_in_one_line(capsys, monkeypatch):
    from maglev.study.cli import main

    for key in [k for k in os.environ if k.startswith("MLFLOW_HTTP")]:
        monkeypatch.delenv(key)
    uri = f"http://127.0.0.1:{closed_port()}"
    tic = time.monotonic()
    assert main(["rank", "--tracking-uri", uri]) == 2
    assert time.monotonic() - tic < 10
    err = capsys.readouterr().err.strip()
    assert err.startswith(f"maglev rank: the MLflow tracking server {uri} cannot be reached") and "\n" not in err


# ---------------------------------------------------------------------------- a run that fails
def test_a_failed_run_has_its_error_tag_even_when_its_upload_fails_and_logs_its_config(migrated_store, monkeypatch):
    """The error tag goes first: an artifact store that refuses the upload loses the traceback, not the error."""
    from maglev.study import job, tracking

    def broken(cfg):
        raise RuntimeError("estimation blew up")

    real_log_files = tracking.log_files
    uploads: list[set] = []

    def flaky_upload(client, run_id, files):
        uploads.append(set(files))
        if len(uploads) == 1:  # the first FAILED run: its artifact store is gone
            raise OSError("artifact store unavailable")
        real_log_files(client, run_id, files)

    monkeypatch.setattr(job, "estimate_run", broken)
    monkeypatch.setattr(tracking, "log_files", flaky_upload)
    # no figures: a run that fails in identify has none to draw, and the renderer's process would start for nothing
    launch(migrated_store, "dataset=binary_a025", "structure=arx,oe", *TINY, "lab.enabled=false",
           "tracking.log_figures=false")
    client, _, runs = all_runs(migrated_store)
    kids = sorted((r for r in runs if r.data.tags.get("kind") == "model"), key=lambda r: r.info.start_time)
    assert [r.info.status for r in kids] == ["FAILED", "FAILED"]
    assert all(r.data.tags["error"] == "RuntimeError: estimation blew up" for r in kids)
    assert uploads == [{"error.txt", "config/config.yaml"}] * 2
    assert artifact_paths(client, kids[0].info.run_id) == set()
    assert artifact_paths(client, kids[1].info.run_id) == {"error.txt", "config/config.yaml"}
    logged = tracking.download_text(client, kids[1].info.run_id, "config/config.yaml")
    assert f"name: {kids[1].data.tags['structure']}" in logged  # reproducible: the config is there


# ---------------------------------------------------------------------------- claims, references, duplicates
@pytest.fixture
def store(migrated_store):
    from maglev.study import tracking

    uri = f"sqlite:///{migrated_store}/mlflow.db"
    client, exp = tracking.connect({"uri": uri, "experiment": "maglev", "artifact_location": str(migrated_store / "a")})
    return client, exp, uri


def dead_pid() -> str:
    proc = subprocess.Popen([sys.executable, "-c", "pass"])
    proc.wait()
    return str(proc.pid)


def test_a_config_is_held_by_its_finished_run_else_the_first_live_running_one(store):
    from maglev.study.claims import claim, holder

    client, exp, uri = store
    host = socket.gethostname()

    def run(status, pid=str(os.getpid()), start=None):
        r = client.create_run(exp, start_time=start, tags={"kind": "model", "config_hash": "h", "host": host,
                                                           "pid": pid}).info.run_id
        if status != "RUNNING":
            client.set_terminated(r, status)
        return r

    assert holder(client, exp, "h") is None
    run("RUNNING", pid=dead_pid())  # a killed process's run holds nothing
    run("FAILED")
    assert holder(client, exp, "h") is None
    first, second = run("RUNNING", start=1000), run("RUNNING", start=2000)
    assert holder(client, exp, "h").info.run_id == first
    assert holder(client, exp, "h", mine=first) is None  # the first one goes on
    assert holder(client, exp, "h", mine=second).info.run_id == first  # the second one yields
    done = run("FINISHED")
    assert holder(client, exp, "h", mine=first).info.run_id == done
    created = []
    run_id, held = claim(client, exp, uri, "h", lambda: created.append(1))
    assert run_id is None and held.info.run_id == done and created == []  # nothing created for a held config
    run_id, held = claim(client, exp, uri, "other", lambda: run("RUNNING"))
    assert held is None and client.get_run(run_id).info.status == "RUNNING"


def test_a_sweep_counts_its_references_and_one_finished_run_per_config(store):
    from maglev.study.store import sweep_runs
    from maglev.study.claims import reference

    client, exp, _ = store
    parent = client.create_run(exp, tags={"kind": "sweep"}).info.run_id
    other = client.create_run(exp, tags={"kind": "sweep"}).info.run_id

    def run(chash, status, under, start):
        r = client.create_run(exp, start_time=start, tags={"kind": "model", "config_hash": chash,
                                                           "mlflow.parentRunId": under})
        client.set_terminated(r.info.run_id, status)
        return client.get_run(r.info.run_id)

    a_twice = [run("a", "FINISHED", parent, 3000), run("a", "FINISHED", parent, 1000)]
    b_other = run("b", "FINISHED", other, 500)  # finished earlier by another sweep
    b_mine = run("b", "FINISHED", parent, 4000)  # and again here: the own child is kept
    c_killed = run("c", "KILLED", parent, 2000)
    d_other = run("d", "FINISHED", other, 600)
    run("e", "FINISHED", other, 700)  # not part of this sweep
    for r in (b_other, d_other):
        reference(client, r, parent, "s")
    reference(client, a_twice[0], parent, "s")  # own child: no tag needed
    assert f"sweep_ref.{parent}" not in client.get_run(a_twice[0].info.run_id).data.tags
    kept, duplicates = sweep_runs(client, exp, parent)
    ids = {r.info.run_id for r in kept}
    assert ids == {a_twice[1].info.run_id, b_mine.info.run_id, c_killed.info.run_id, d_other.info.run_id}
    assert duplicates == 2


def test_only_a_finished_ranking_run_is_reused(store, monkeypatch):
    """A ranking killed half-way (KILLED, or RUNNING until reaped) must not stand for the sweep's ranking."""
    from maglev.study import report

    client, exp, _ = store
    parent = client.create_run(exp, tags={"kind": "sweep"}).info.run_id
    ranking = SimpleNamespace(sweep=SimpleNamespace(client=client, experiment_id=exp, parent_id=parent),
                              ranked_hash="r")
    monkeypatch.setattr(report, "log_ranking", lambda r: "new ranking run")
    tags = {"kind": "ranking", "sweep_parent": parent, "ranked_hash": "r"}
    killed = client.create_run(exp, start_time=1000, tags=tags).info.run_id
    client.set_terminated(killed, "KILLED")
    client.create_run(exp, start_time=2000, tags=tags)  # left RUNNING
    assert report.ranking_run_for(ranking) == "new ranking run"
    done = client.create_run(exp, start_time=500, tags=tags).info.run_id
    client.set_terminated(done, "FINISHED")
    assert report.ranking_run_for(ranking) == done


def test_two_runs_logging_the_same_new_dataset_at_once_both_log_it(store):
    """MLflow looks a dataset up, then inserts it: the second of two simultaneous inserts failed
    (UNIQUE constraint failed: datasets...) and its run ended FAILED — joblib workers on a fresh
    experiment, or two launches, log the same dataset at the same moment."""
    import threading

    import numpy as np

    from maglev import IOData
    from maglev.study.tracking import log_dataset_inputs

    client, exp, _ = store
    errors: list[str] = []
    for i in range(8):  # each round a dataset new to the experiment, logged by two threads at once
        data = IOData(np.arange(20.0) + i, np.arange(20.0), 1.0, name=f"round{i}")
        runs = [client.create_run(exp).info.run_id for _ in range(2)]
        gate = threading.Barrier(2)

        def log(run_id):
            gate.wait()
            try:
                log_dataset_inputs(client, run_id, data, data)
            except Exception as exc:  # noqa: BLE001 — collected for the assertion
                errors.append(f"{type(exc).__name__}: {str(exc)[:120]}")

        threads = [threading.Thread(target=log, args=(r,)) for r in runs]
        for t in threads:
            t.start()
        for t in threads:
            t.join()
        assert all(len(client.get_run(r).inputs.dataset_inputs) == 1 for r in runs)  # est = val: one dataset
    assert errors == []


def test_an_error_raised_once_a_signal_has_arrived_kills_the_run_with_the_signals_exit(migrated_store, monkeypatch):
    """A signal's exit that lands inside OmegaConf (or any library whose cleanup it breaks) surfaces as that
    library's own error: the run was stopped, not failed, and the process ends as the signal says."""
    import signal

    from maglev.study import job, shutdown

    def interrupted(cfg):
        monkeypatch.setattr(shutdown, "received", signal.SIGTERM)
        raise AttributeError("'NoneType' object has no attribute '_invalidate_flags_cache'")

    monkeypatch.setattr(job, "estimate_run", interrupted)
    with pytest.raises(SystemExit) as stopped:
        launch(migrated_store, "dataset=binary_a025", "structure=arx", *TINY, "lab.enabled=false",
               "tracking.log_figures=false", multirun=False)
    assert stopped.value.code == 143
    _, _, runs = all_runs(migrated_store)
    assert [(r.info.status, r.data.tags["error"].split(":")[0]) for r in runs] == [("KILLED", "AttributeError")]
