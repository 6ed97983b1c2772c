"""The background renderer: a run is FINISHED only once its figures are up, and never left RUNNING."""

from __future__ import annotations

import gc
import os
import signal
import subprocess
import sys
import time
from concurrent.futures.process import EXTRA_QUEUED_CALLS

import pytest

from maglev.study import render, tracking

pytestmark = pytest.mark.filterwarnings("ignore:The .*noload.* loader strategy is deprecated")


@pytest.fixture
def store(migrated_store):
    uri = f"sqlite:///{migrated_store}/mlflow.db"
    client, exp = tracking.connect({"uri": uri, "experiment": "maglev", "artifact_location": str(migrated_store / "a")})
    return uri, client, exp


def test_a_drawing_error_is_tagged_and_the_run_still_finishes(store):
    uri, client, exp = store
    run = client.create_run(exp).info.run_id
    render.submit(uri, run, inputs=None)  # nothing to draw: run_figures fails in the renderer
    assert render.drain() == {}
    got = client.get_run(run)
    assert got.info.status == "FINISHED" and got.data.tags["figures_error"].startswith("AttributeError")


def test_a_dead_renderer_fails_its_runs_and_abandon_kills_the_queued_ones(store):
    uri, client, exp = store
    first, second = (client.create_run(exp).info.run_id for _ in range(2))
    render.submit(uri, first, inputs=None)
    render.drain()
    pid = next(iter(render._pool._processes))  # the renderer process, started by the first submit
    os.kill(pid, signal.SIGSTOP)  # it cannot draw the second run before it dies (it would in a few ms)
    render.submit(uri, second, inputs=None)
    deadline = time.monotonic() + 10
    while not render._pending[second][1].running() and time.monotonic() < deadline:  # handed to the renderer
        time.sleep(0.01)  # (queued runs it has not taken, drain draws itself)
    os.kill(pid, signal.SIGKILL)
    failed = render.drain()
    assert list(failed) == [second] and "BrokenProcessPool" in failed[second]
    got = client.get_run(second)
    assert got.info.status == "FAILED" and got.data.tags["error"].startswith("figures: BrokenProcessPool")
    third = client.create_run(exp).info.run_id
    render.submit(uri, third, inputs=None)  # the broken renderer is replaced
    time.sleep(0.1)
    assert render.abandon() in ([third], [])  # queued and not yet drawn: KILLED; or already done
    assert client.get_run(third).info.status in ("KILLED", "FINISHED")


def test_a_renderer_ended_by_the_sweeps_signal_leaves_its_run_killed_not_failed(store, monkeypatch, caplog):
    """Ctrl-C reaches the renderer too (it ends at once): a run it was drawing while the launcher waited for it
    is KILLED, as abandon marks the runs a signal leaves, with no error line — not FAILED."""
    from maglev.study import shutdown

    uri, client, exp = store
    render.abandon()
    render.submit(uri, client.create_run(exp).info.run_id, inputs=None)
    render.drain()
    pid = next(iter(render._pool._processes))  # the renderer process, started by the first submit
    os.kill(pid, signal.SIGSTOP)
    render.submit(uri, second := client.create_run(exp).info.run_id, inputs=None)
    deadline = time.monotonic() + 10
    while not render._pending[second][1].running() and time.monotonic() < deadline:
        time.sleep(0.01)
    monkeypatch.setattr(shutdown, "received", signal.SIGINT)
    os.kill(pid, signal.SIGKILL)
    with caplog.at_level("DEBUG", logger="maglev.study"):
        render.drain()
    got = client.get_run(second)
    assert got.info.status == "KILLED" and got.data.tags["error"] == f"figures: {render.STOPPED}"
    assert not [r for r in caplog.records if r.levelname == "ERROR"], caplog.text


def test_start_spawns_the_renderer_before_any_run_and_it_draws_afterwards(store):
    uri, client, exp = store
    render.abandon()  # no renderer left from an earlier test
    assert render.submit_lab(uri, "no-parent", {}, []) is False  # none: the sweep callback makes the lab steps
    assert render.start() and not render.start()  # one renderer: a second start finds it running
    assert len(render._pool._processes) == render.WORKERS  # spawned now, importing while the sweep starts
    pid = next(iter(render._pool._processes))
    run = client.create_run(exp).info.run_id
    render.submit(uri, run, inputs=None)
    assert render.drain() == {} and client.get_run(run).info.status == "FINISHED"
    assert next(iter(render._pool._processes)) == pid  # the same process drew it
    # it imported with full garbage collections held off, then froze its libraries (maglev.study.heap)
    fresh = subprocess.run([sys.executable, "-c", "import gc; print(*gc.get_threshold())"], capture_output=True,
                           text=True, check=True).stdout.split()  # Python's own thresholds
    assert render._pool.submit(gc.get_threshold).result(timeout=60) == tuple(map(int, fresh))
    assert render._pool.submit(gc.get_freeze_count).result(timeout=60) > 100_000


def test_drain_draws_the_runs_the_busy_renderer_has_not_started(store):
    uri, client, exp = store
    render.start()
    render._pool.submit(time.sleep, 3)  # the renderer is busy
    runs = [client.create_run(exp).info.run_id for _ in range(5)]
    for run in runs:
        render.submit(uri, run, inputs=None)
    time.sleep(0.5)
    futures = {run: render._pending[run][1] for run in runs}
    assert render.drain() == {}
    drawn_here = [run for run, fut in futures.items() if fut.cancelled()]  # the renderer never ran these
    handed_ahead = render.WORKERS + EXTRA_QUEUED_CALLS  # the pool's call queue: runs taken before they start
    assert len(drawn_here) >= len(runs) - handed_ahead
    for run in runs:  # each finished, with its drawing error tagged (inputs=None), none lost
        got = client.get_run(run)
        assert got.info.status == "FINISHED" and got.data.tags["figures_error"].startswith("AttributeError")


def test_drain_takes_runs_from_the_back_of_the_queue_while_the_renderer_goes_on_from_the_front(store):
    """At a sweep's end the renderer lags some runs behind: this process draws from the last one back, the
    renderer from the first one on, each run once.  (Taking every run the renderer had not started left it idle
    while this process drew them one by one: 9 runs, 2.4 s, at the default sweep's end.)"""
    from .harness import drawn_slowly

    uri, client, exp = store
    render.start()
    render._pool.submit(int).result(timeout=60)  # the renderer has imported and waits for work
    runs = [client.create_run(exp).info.run_id for _ in range(10)]
    for run in runs:
        render.submit(uri, run, 0.3, task=drawn_slowly)
    assert render.drain() == {}
    by = [client.get_run(run).data.tags["drawn_by"] for run in runs]
    there = [run for run, pid in zip(runs, by) if pid != str(os.getpid())]
    assert there == runs[:len(there)]  # the renderer drew the first runs, this process the others
    handed_ahead = render.WORKERS + EXTRA_QUEUED_CALLS  # what the renderer holds before it starts them
    assert handed_ahead < len(there) < len(runs), by  # the renderer went on drawing while this process drew
    assert {client.get_run(run).info.status for run in runs} == {"FINISHED"}


def test_offload_runs_on_the_renderer_when_there_is_one_else_here(store):
    """The ranking's figures are drawn on the sweep's renderer, idle once drained, while the report is written
    here; arguments that do not pickle, or no renderer, and they are made here."""
    from .harness import pid_of

    render.start()
    assert render.offload(pid_of, 1)() not in (os.getpid(), None)
    assert render.offload(pid_of, lambda: 1)() == os.getpid()  # a python-control system's lambda does not pickle
    pool, render._pool = render._pool, None
    try:
        assert render.offload(pid_of, 1)() == os.getpid()
    finally:
        render._pool = pool


def test_lab_steps_queued_on_the_renderer_are_made_by_the_time_drain_returns_a_failure_a_warning(store):
    """The sweep's lab steps go to the renderer first (the runs estimate meanwhile); the ranking reads them after
    drain.  (Without a renderer nothing is queued: the test of start.)"""
    from .harness import study_log

    uri, client, exp = store
    render.start()
    parent = client.create_run(exp).info.run_id
    assert render.submit_lab(uri, parent, {}, [])  # a task without a lab section: lab_steps raises
    with study_log() as lines:
        assert render.drain() == {}
    assert client.get_run(parent).data.tags["lab_error"] == "KeyError: 'lab'"
    assert lines == ["lab steps failed: KeyError: 'lab'"]



def test_a_run_the_renderer_cannot_validate_ends_failed_with_its_error_and_the_launcher_says_so(store):
    """A sweep's job hands its estimated run to the renderer (maglev.study.finish.complete): an error there marks
    the run FAILED with its error tag, traceback and config, as an error in the job does, and is printed here."""
    from maglev.study.finish import Work, complete
    from maglev.study.identify import Estimated

    from .harness import artifact_paths, study_log

    uri, client, exp = store
    render.start()
    run = client.create_run(exp).info.run_id
    cfg = {"tracking": {"uri": uri}, "study": {"val_horizon": 1}}
    broken = Estimated(cfg, prepared=None, model=None, fit_seconds=0.0, val_fit=50.0, yhat=None)  # no data
    with study_log() as lines:
        render.submit(uri, run, Work(broken, hydra_dir=None, artifact_uri=None), complete)
        assert render.drain() == {}
        deadline = time.monotonic() + 10
        while not lines and time.monotonic() < deadline:  # said by the pool's thread when the renderer ends it
            time.sleep(0.01)
    got = client.get_run(run)
    assert got.info.status == "FAILED"
    assert got.data.tags["error"] == "AttributeError: 'NoneType' object has no attribute 'val'"
    assert artifact_paths(client, run) == {"error.txt", "config/config.yaml"}
    assert lines == [f"run {run} FAILED: AttributeError: 'NoneType' object has no attribute 'val'"]


def test_a_server_gone_under_the_renderer_ends_the_sweep_with_its_one_line_and_the_renderer_says_nothing(
        monkeypatch, capfd):
    """A server killed in the middle of a sweep: the renderer's first task to fail on it raises TrackingUnreachable,
    which reaches the launcher as itself (drain raises it: the sweep's one line); the task queued after it fails at
    once, and neither process prints anything.  Before: the renderer printed 'could not record its error' twice,
    the launcher could not read its exception back (a broken pool) and went on calling the dead server."""
    from maglev.study.finish import Work, complete
    from maglev.study.identify import Estimated

    from .harness import study_log
    from .test_faults import closed_port

    uri = f"http://127.0.0.1:{closed_port()}"
    bounds = tracking.http_env(max_retries=0, timeout_s=2)  # a refused port fails at once, as a killed server's
    for key, value in bounds.items():
        monkeypatch.setenv(key, value)
    monkeypatch.setattr(tracking, "unreachable", None)  # set in this process when the renderer's exception arrives
    render.abandon()
    render.start(bounds)
    cfg = {"tracking": {"uri": uri}, "study": {"val_horizon": 1}}
    broken = Work(Estimated(cfg, None, None, 0.0, 50.0, None), hydra_dir=None, artifact_uri=None)  # fails, then
    capfd.readouterr()  # its error cannot be recorded: the server is gone
    with study_log() as lines:
        for run in ("first", "second"):
            render.submit(uri, run, broken, complete)
        futures = [render._pending[run][1] for run in ("first", "second")]
        deadline = time.monotonic() + 60
        while not all(fut.done() for fut in futures) and time.monotonic() < deadline:  # both taken by the renderer
            time.sleep(0.05)
        assert [type(fut.exception()) for fut in futures] == [tracking.TrackingUnreachable] * 2
        with pytest.raises(tracking.TrackingUnreachable) as gone:
            render.drain()
    render.abandon(write=False)
    assert str(gone.value).startswith(f"maglev: the MLflow tracking server {uri} cannot be reached (ConnectionError")
    assert tracking.unreachable == uri  # the sweep's end at exit then writes nothing (callbacks._abort)
    assert lines == [] and capfd.readouterr().err == ""


def test_a_new_sweep_starts_its_renderer_before_checking_configs_and_a_refused_one_leaves_none(
        tmp_path, monkeypatch):
    """A sweep new to a local store runs jobs whatever its configs: its renderer imports while they are
    checked.  When the checks refuse the sweep, the renderer is stopped at once: the exit does not wait for
    its imports, and no process is left."""
    from maglev.study import callbacks, shutdown

    from .harness import TINY, launch

    render.abandon()  # no renderer left from an earlier test
    seen = []

    def check_sweep(config):
        seen.append(list(render._pool._processes) if render._pool else [])
        return checked(config)

    checked = callbacks.check_sweep
    monkeypatch.setattr(callbacks, "check_sweep", check_sweep)
    with pytest.raises(SystemExit, match="sweep refused before any run"):
        launch(tmp_path, "dataset=binary_a025", "structure.order=2", *TINY, "lab.enabled=false",
               "dataset.preprocess.split=0.5,0.9999")
    assert len(seen) == 1 and len(seen[0]) == render.WORKERS  # started before the configs were checked
    assert render._pool is None
    deadline = time.monotonic() + 10
    while not shutdown.ended(seen[0][0]) and time.monotonic() < deadline:
        time.sleep(0.05)
    assert shutdown.ended(seen[0][0])
