"""The study as users run it: two launches at once, SIGTERM and kill -9 in the middle of a sweep, a cluster launcher.

Real processes (``python study.py``), tiny datasets; every assertion is about the store
afterwards: each config FINISHED exactly once, nothing left RUNNING, one ranking per sweep.
"""

from __future__ import annotations

import contextlib
import io
import os
import signal
import subprocess
import sys
import time
from collections import Counter
from pathlib import Path

import pytest

from .harness import LEAN, REPO, TINY, launch, model_statuses, process_env, store_overrides, study_log

pytestmark = [pytest.mark.slow, pytest.mark.filterwarnings("ignore:The .*noload.* loader strategy is deprecated")]
SMALL = ["dataset=binary_a025", *TINY, *LEAN]


def start(store: Path, *args: str, log: str = "study", rank: bool = False) -> subprocess.Popen:
    """``python study.py -m ARGS`` in its own process group, its output in ``store/<log>.log``; the
    end-of-sweep ranking only with ``rank=True`` (its report then goes to ``store/reports``)."""
    env = process_env()
    out = open(store / f"{log}.log", "w")
    cmd = [sys.executable, str(REPO / "study.py"), "-m", *args, *store_overrides(store),
           f"hydra.callbacks.maglev_rank.report_dir={store}/reports" if rank else "~hydra.callbacks.maglev_rank"]
    return subprocess.Popen(cmd, stdout=out, stderr=subprocess.STDOUT, cwd=store, env=env, start_new_session=True)


def runs(store: Path, kind: str | None = None) -> list:
    from maglev.study.tracking import new_client

    client = new_client(f"sqlite:///{store}/mlflow.db")  # under the store lock: never races a migration
    exp = client.get_experiment_by_name("maglev")
    if exp is None:
        return []
    found = client.search_runs([exp.experiment_id], max_results=1000)
    return [r for r in found if kind is None or r.data.tags.get("kind") == kind]


def wait_for_model_runs(store: Path, proc: subprocess.Popen, *statuses: str, timeout: float = 240) -> None:
    """Until the sweep has a model run in each of ``statuses`` at once (e.g. one FINISHED and one in flight)."""
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline and proc.poll() is None:
        if set(statuses) <= model_statuses(store):
            return
        time.sleep(0.1)
    pytest.fail(f"no model runs {statuses} (exit {proc.poll()}): {(store / 'study.log').read_text()[-3000:]}")


def finished_once(models: list) -> Counter:
    """FINISHED runs per config hash."""
    return Counter(r.data.tags["config_hash"] for r in models if r.info.status == "FINISHED")


def test_two_launches_at_once_run_every_config_once_into_a_fresh_then_an_existing_store(tmp_path, capsys):
    """The second launch of a sweep waits for the first, then finds every config done: one ranking.
    Then an overlapping sweep (one structure more), twice at once, into the existing store: it runs only
    the new config, ranks all three, and its report does not overwrite the first sweep's."""
    from maglev.study.callbacks import NothingToDo
    from maglev.study.cli import main

    first = [*SMALL, "structure=arx,oe", "study.name=twin"]
    procs = [start(tmp_path, *first, log=f"a{i}", rank=True) for i in range(2)]
    assert [p.wait(timeout=600) for p in procs] == [0, 0], (tmp_path / "a1.log").read_text()[-3000:]
    logs = "".join((tmp_path / f"a{i}.log").read_text() for i in range(2))
    # each config identified once in all (the second launch waits for the first, or skips what it claimed)
    # (or, when it starts after the first has ranked, stops at once: nothing to do)
    assert logs.count("val_fit") == 2 and (logs.count("skip ") == 2 or logs.count("nothing to do") == 1), logs
    assert "Callback" not in logs and "Traceback" not in logs, logs  # no callback error swallowed by Hydra
    models = runs(tmp_path, "model")
    assert len(models) == 2 and finished_once(models) == Counter({h: 1 for h in finished_once(models)})
    [parent] = runs(tmp_path, "sweep")
    assert parent.info.status == "FINISHED"
    assert len(runs(tmp_path, "ranking")) == 1

    # the second pair: a process, and once it holds the sweep (its parent RUNNING) the same launch in this
    # process (a process start less; the store exists, so the race left is the sweep's, not the migration's)
    second = [*SMALL, "structure=arx,oe,armax", "study.name=twin"]
    proc = start(tmp_path, *second, log="b0", rank=True)
    deadline = time.monotonic() + 240
    while "parent run" not in (tmp_path / "b0.log").read_text() and proc.poll() is None and time.monotonic() < deadline:
        time.sleep(0.05)
    with study_log() as lines, contextlib.redirect_stdout(io.StringIO()):
        try:
            launch(tmp_path, *second, rank=True)
        except NothingToDo as stop:  # on a busy machine the process ran, ranked and reported it all first
            assert stop.code == 0 and any(line.startswith("sweep 'twin': nothing to do: ") for line in lines), lines
    assert proc.wait(timeout=600) == 0, (tmp_path / "b0.log").read_text()[-3000:]
    logs = (tmp_path / "b0.log").read_text() + "\n".join(lines)
    assert logs.count("val_fit") == 1 and "Callback" not in logs and "Traceback" not in logs, logs
    models = runs(tmp_path, "model")
    assert len(models) == 3 and set(finished_once(models).values()) == {1}
    parents = runs(tmp_path, "sweep")
    assert len(parents) == 2 and {p.info.status for p in parents} == {"FINISHED"}
    new = next(p for p in parents if p.info.run_id != parent.info.run_id)
    rankings = [r for r in runs(tmp_path, "ranking") if r.data.tags["sweep_parent"] == new.info.run_id]
    assert len(rankings) == 1 and rankings[0].data.metrics["n_ranked"] == 3  # incl. the 2 of the first sweep
    assert new.data.metrics["runs_finished"] == 1 and new.data.metrics["runs_referenced"] == 2
    assert ", and 2 run(s) of other sweeps with the same configs." in new.data.tags["mlflow.note.content"]
    reports = sorted(p.name for p in (tmp_path / "reports").glob("*.html"))
    assert reports == sorted(f"twin-{p.data.tags['sweep_id'][:8]}.html" for p in parents)
    assert main(["rank", "--tracking-uri", f"sqlite:///{tmp_path}/mlflow.db"]) == 0
    assert "Top 3 of 3 FINISHED runs of sweep 'twin'" in capsys.readouterr().out


def test_sigterm_in_the_middle_of_a_sweep_leaves_no_run_running(migrated_store):
    """What Slurm sends on scancel or at the time limit (and ``kill``), to the launching process: the run
    in flight and the parent end KILLED at once, with no relaunch needed."""
    store = migrated_store
    # BJ [2 …] takes a fraction of a second, the higher orders on a 20 s record seconds each: the signal
    # lands while one of them is in flight (with runs of milliseconds it could fall between two runs)
    slow = ["dataset=binary_a025", "dataset.duration_s=20", "dataset.preprocess.trim=500", *LEAN]
    proc = start(store, *slow, "structure=bj", "structure.order=2,7,8,9")
    wait_for_model_runs(store, proc, "FINISHED", "RUNNING")  # one done, one in flight
    tic = time.monotonic()
    proc.send_signal(signal.SIGTERM)
    code = proc.wait(timeout=120)
    elapsed = time.monotonic() - tic
    # Slurm sends SIGKILL 30 s (KillWait) after SIGTERM: the cleanup must be over by then
    assert code == 143 and elapsed < 30, (code, elapsed, (store / "study.log").read_text()[-3000:])
    everything = runs(store)
    assert not [r.info.run_name for r in everything if r.info.status == "RUNNING"]
    [parent] = [r for r in everything if r.data.tags.get("kind") == "sweep"]
    assert parent.info.status == "KILLED"
    assert f"sweep stopped (SIGTERM): parent run {parent.info.run_id} KILLED" in (store / "study.log").read_text()
    models = [r for r in everything if r.data.tags.get("kind") == "model"]
    assert 1 <= len(finished_once(models)) < 4 and {r.info.status for r in models} <= {"FINISHED", "KILLED"}
    killed = [r for r in models if r.info.status == "KILLED"]  # the run in flight, by its own handler
    assert killed and all(r.data.tags["error"] == "SystemExit: 143" for r in killed), [r.data.tags for r in killed]


def test_kill_9_in_the_middle_of_a_sweep_then_a_relaunch_finishes_every_config_once(migrated_store):
    store = migrated_store
    args = [*SMALL, "structure=arx,oe", "structure.order=2,3,4,5"]
    proc = start(store, *args)
    wait_for_model_runs(store, proc, "FINISHED")
    os.killpg(proc.pid, signal.SIGKILL)  # the launcher and its figure renderers, as the OOM killer or Slurm would
    proc.wait(timeout=60)
    assert len(finished_once(runs(store, "model"))) < 8  # killed in the middle
    launch(store, *args)  # the same sweep again (in-process)
    models = runs(store, "model")
    assert finished_once(models) == Counter({h: 1 for h in finished_once(models)}) and len(finished_once(models)) == 8
    assert not [r for r in runs(store) if r.info.status == "RUNNING"]
    [parent] = runs(store, "sweep")
    assert parent.info.status == "FINISHED" and parent.data.tags["resumed"] == "true"


# ---------------------------------------------------------------------------- the cluster path, on one machine
def launcher_config(name: str) -> dict:
    from hydra import compose, initialize_config_dir
    from omegaconf import OmegaConf

    import maglev.study.schema  # noqa: F401  (the config's schemas)

    with initialize_config_dir(str(REPO / "conf"), version_base="1.3"):
        cfg = compose("config", overrides=[f"hydra/launcher={name}"], return_hydra_config=True)
    return OmegaConf.to_container(cfg.hydra.launcher)


def test_the_local_submitit_launcher_differs_from_slurm_only_in_the_executor():
    pytest.importorskip("hydra_plugins.hydra_submitit_launcher",
                        reason="hydra-submitit-launcher is not installed (pip install -e .[cluster])")
    local, slurm = launcher_config("local"), launcher_config("slurm")
    assert local.pop("_target_").endswith("LocalLauncher") and slurm.pop("_target_").endswith("SlurmLauncher")
    assert {k: slurm[k] for k in local} == local  # every local setting as on Slurm; Slurm adds its queue's
