"""What a sweep leaves behind when its tracking server or its launcher dies: no process, no run RUNNING
that could have been marked, one line.

Real processes (``python study.py``), tiny datasets.  Before: a sweep whose server was killed exited
998 s later (its figure renderer retried with MLflow's defaults); after kill -9 of the launcher its
renderer, a resource tracker and a joblib worker lived on for minutes.
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from maglev.study.shutdown import descendants

from .conftest import start_server, stop_server
from .harness import LEAN, REPO, TINY, model_statuses, process_env, store_overrides

pytestmark = [pytest.mark.slow, pytest.mark.filterwarnings("ignore:The .*noload.* loader strategy is deprecated")]


def alive(pids: list[int]) -> list[int]:
    """Those of ``pids`` still running (zombies count as ended)."""
    out = []
    for pid in pids:
        try:
            with open(f"/proc/{pid}/stat") as fh:
                if fh.read().rsplit(")", 1)[1].split()[0] != "Z":
                    out.append(pid)
        except (OSError, IndexError):
            pass
    return out


def wait_for(predicate, timeout: float, what: str, log: Path) -> None:
    deadline = time.monotonic() + timeout
    while not predicate():
        if time.monotonic() > deadline:
            pytest.fail(f"{what} not within {timeout:g} s: {log.read_text()[-3000:]}")
        time.sleep(0.2)


def test_a_server_killed_in_the_middle_of_a_sweep_ends_it_within_a_minute_leaving_no_process(tmp_path):
    """Figures on (the renderer runs), basic launcher, 6 jobs; the server is killed after the first run."""
    server, base = start_server(tmp_path)
    log = tmp_path / "study.log"
    cmd = [sys.executable, str(REPO / "study.py"), "-m", "tracking=server", f"tracking.uri={base}",
           "dataset=binary_a025", "structure=arx,oe,armax", "structure.order=2,3", *TINY,
           "study.true_plant=false", "lab.enabled=false", f"hydra.sweep.dir={tmp_path}/multirun",
           "~hydra.callbacks.maglev_rank"]
    with open(log, "w") as out:
        sweep = subprocess.Popen(cmd, stdout=out, stderr=subprocess.STDOUT, cwd=tmp_path,
                                 env=process_env("MLFLOW_"), start_new_session=True)
    try:
        wait_for(lambda: "val_fit" in log.read_text() or sweep.poll() is not None, 240, "a first run", log)
        below = descendants(sweep.pid)
        assert sweep.poll() is None and below, log.read_text()[-3000:]  # the renderer is running
        stop_server(server, signal.SIGKILL)
        tic = time.monotonic()
        sweep.wait(timeout=120)
        elapsed = time.monotonic() - tic
        print(f"the sweep exited {elapsed:.1f} s after its server was killed")
    finally:
        stop_server(server, signal.SIGKILL)
        if sweep.poll() is None:
            os.killpg(sweep.pid, signal.SIGKILL)
    text = log.read_text()
    lines = text.strip().splitlines()
    assert sweep.returncode == 1 and elapsed < 60, (elapsed, text[-3000:])
    assert lines[-1].startswith(f"maglev: the MLflow tracking server {base} cannot be reached"), lines[-5:]
    assert "Traceback" not in text, text[-3000:]
    wait_for(lambda: not alive(below), 10, f"the sweep's processes {alive(below)} ending", log)


def test_kill_9_of_a_parallel_launcher_ends_its_workers_and_their_runs(migrated_store):
    """joblib's workers lived on for more than 25 minutes after their launcher was killed; now each
    notices within a second, marks its run in flight KILLED and exits."""
    pytest.importorskip("hydra_plugins.hydra_joblib_launcher", reason="hydra-joblib-launcher is not installed")
    from .test_concurrency import runs

    store = migrated_store  # the empty store's tables made once per worker: the test is about processes
    log = store / "study.log"
    cmd = [sys.executable, str(REPO / "study.py"), "-m", "hydra/launcher=parallel", "hydra.launcher.n_jobs=2",
           "dataset=binary_a025", "structure=oe,armax,bj", "structure.order=2,3", *TINY, *LEAN,
           *store_overrides(store), "~hydra.callbacks.maglev_rank"]
    with open(log, "w") as out:
        sweep = subprocess.Popen(cmd, stdout=out, stderr=subprocess.STDOUT, cwd=store,
                                 env=process_env(), start_new_session=True)
    try:
        wait_for(lambda: sweep.poll() is not None or "RUNNING" in model_statuses(store),
                 240, "a run in flight", log)
        below = descendants(sweep.pid)
        assert sweep.poll() is None and below, log.read_text()[-3000:]
        sweep.kill()
        sweep.wait(timeout=10)
        wait_for(lambda: not alive(below), 60, f"the workers {alive(below)} ending", log)
    finally:
        if alive(descendants(sweep.pid)):
            os.killpg(sweep.pid, signal.SIGKILL)
    models = runs(store, "model")
    assert models and [r.info.status for r in models if r.info.status == "RUNNING"] == [], \
        [(r.info.status, r.data.tags.get("pid")) for r in models]
    assert {r.info.status for r in models} <= {"FINISHED", "KILLED"}


@pytest.mark.parametrize("sig, code", [(signal.SIGINT, 130), (signal.SIGTERM, 143)])
def test_ctrl_c_or_sigterm_to_the_process_group_prints_one_line_and_leaves_nothing_running(
        migrated_store, sig, code):
    """A terminal's Ctrl-C and a whole-group SIGTERM reach the launcher and its figure renderer at once.
    Before: Ctrl-C printed 40-132 lines (tracebacks of both processes); SIGTERM's exception was dropped in
    a SQLAlchemy weakref callback ("Exception ignored"), and the sweep ran on to exit 0."""
    from .harness import default_ctrl_c
    from .test_concurrency import runs

    store = migrated_store  # the empty store's tables made once per worker: the test is about processes
    log = store / "study.log"
    cmd = [sys.executable, str(REPO / "study.py"), "-m", "dataset=binary_a025", "structure=arx,oe,armax",
           "structure.order=2,3", *TINY, "study.true_plant=false", "lab.enabled=false", *store_overrides(store),
           "~hydra.callbacks.maglev_rank"]
    with open(log, "w") as out:
        sweep = subprocess.Popen(cmd, stdout=out, stderr=subprocess.STDOUT, cwd=store, env=process_env(),
                                 start_new_session=True, preexec_fn=default_ctrl_c)
    try:
        wait_for(lambda: "val_fit" in log.read_text() or sweep.poll() is not None, 240, "a first run", log)
        before = len(log.read_text().splitlines())
        below = descendants(sweep.pid)
        os.killpg(sweep.pid, sig)
        sweep.wait(timeout=60)
    finally:
        if sweep.poll() is None:
            os.killpg(sweep.pid, signal.SIGKILL)
    after = [line for line in log.read_text().splitlines()[before:]  # but a job that ended before the signal
             if "] \t#" not in line and "val_fit" not in line]
    assert sweep.returncode == code, log.read_text()[-3000:]
    assert len(after) == 1 and f"sweep stopped ({sig.name}): parent run " in after[0], after
    models = runs(store, "model")
    assert not [r for r in runs(store) if r.info.status == "RUNNING"]
    assert {r.info.status for r in models} <= {"FINISHED", "KILLED"}
    wait_for(lambda: not alive(below), 10, f"the sweep's processes {alive(below)} ending", log)
