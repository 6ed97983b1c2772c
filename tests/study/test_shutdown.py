"""A signal that lands in a SQLite commit: the store stays writable, so the cleanup can mark runs KILLED.

Without :func:`maglev.study.shutdown.deferred` around the store's sessions, the ``SystemExit`` raised
in the commit left this process holding the database's write lock: the write after it waited SQLite's
20 s busy timeout and failed with "database is locked" (CI saw the SIGTERM test exit 1 after 100 s).
Each case runs in its own process, since it installs signal handlers and signals itself.
"""

from __future__ import annotations

import contextlib
import subprocess
import sys
import time

import pytest

from .harness import default_ctrl_c, process_env

SCRIPT = """
import os, signal, sys, time
from sqlalchemy import event
from maglev.study import shutdown, tracking

client = tracking.new_client("sqlite:///" + sys.argv[1] + "/mlflow.db")
exp = client.create_experiment("x")
armed = []

def signal_in_commit(conn):  # the handler runs at the next bytecode, inside SQLAlchemy's commit
    if armed:
        os.kill(os.getpid(), armed.pop())
        sum(range(1000))

event.listen(client._tracking_client.store.engine, "commit", signal_in_commit)
for name in ("SIGTERM", "SIGINT"):
    run = client.create_run(exp).info.run_id
    shutdown.install()
    armed.append(getattr(signal, name))
    try:
        client.set_tag(run, "written", "yes")
    except BaseException as exc:
        print(name, "raised", type(exc).__name__, getattr(exc, "code", ""))
    tic = time.monotonic()
    client.set_terminated(run, "KILLED")
    r = client.get_run(run)
    print(name, "then wrote in %.1f s:" % (time.monotonic() - tic), r.info.status, r.data.tags.get("written"))
"""


def test_a_signal_in_a_commit_is_raised_after_it_and_the_store_stays_writable(tmp_path):
    out = subprocess.run([sys.executable, "-c", SCRIPT, str(tmp_path)], capture_output=True, text=True,
                         timeout=120, env=process_env(), preexec_fn=default_ctrl_c)
    lines = [line.strip() for line in out.stdout.splitlines()]
    assert out.returncode == 0 and len(lines) == 4, out.stdout + out.stderr[-3000:]
    assert lines[0] == "SIGTERM raised SystemExit 143" and lines[2] == "SIGINT raised KeyboardInterrupt"
    for line in lines[1::2]:
        assert float(line.split()[4]) < 5, lines  # not SQLite's 20 s busy timeout
        assert line.endswith(": KILLED yes"), lines  # the interrupted transaction committed whole


ENDING = """
import atexit, sys
from maglev.study import shutdown

class Held:
    def __del__(self):  # runs in the interpreter's teardown, if there is one
        print("torn down", flush=True)

held = Held()
atexit.register(shutdown.skip_teardown)
atexit.register(print, "atexit ran")  # registered later: runs before skip_teardown
sys.stdout.write("unflushed")
if sys.argv[1] == "outside":
    raise SystemExit(4)
with shutdown.ending():
    exec(sys.argv[1])
"""


def test_study_py_exits_with_pythons_status_and_output_but_without_the_interpreters_teardown():
    """``study.py`` ends through :func:`maglev.study.shutdown.skip_teardown` (a sweep's launcher spent 1.2 s
    freeing modules after its last line, and waited 1.2 s more for its renderer's): the exit status Python
    gives the exception that ends the main code, every atexit handler run and the output flushed."""
    cases = {"pass": 0, "sys.exit()": 0, "raise SystemExit(3)": 3, "raise SystemExit('bad')": 1,
             "raise ValueError('boom')": 1, "outside": 4}
    for body, status in cases.items():
        out = subprocess.run([sys.executable, "-c", ENDING, body], capture_output=True, text=True, timeout=60,
                             env=process_env())
        assert out.returncode == status, (body, out.returncode, out.stderr[-2000:])
        assert out.stdout.startswith("unflushed") and "atexit ran" in out.stdout, (body, out.stdout)
        assert ("torn down" in out.stdout) == (body == "outside"), (body, out.stdout)  # no status: Python's end
        assert ("ValueError: boom" in out.stderr) == ("boom" in body) and ("bad" in out.stderr) == ("bad" in body)


EXIT_WITH = """
import subprocess, sys, threading, time
from maglev.study import shutdown

launcher = subprocess.Popen([sys.executable, "-c", "import time; time.sleep(60)"])
shutdown.install()
shutdown.exit_with(launcher.pid, grace=30, poll=0.05)
threading.Thread(target=time.sleep, args=(3600,)).start()  # what kept joblib's idle workers from exiting
launcher.kill()
if sys.argv[1] == "job":
    with shutdown.job():
        try:
            while True:
                time.sleep(0.01)
        except SystemExit:
            time.sleep(0.5)  # the job marks its run KILLED
            print("marked", flush=True)
            raise
else:
    threading.Event().wait()  # between jobs: waiting for the next one
"""


def test_a_worker_whose_launcher_dies_ends_once_its_job_has_marked_its_run():
    """exit_with: SIGTERM, then os._exit as soon as no job is in flight — not after the whole grace (30 s
    here, 20 s in a sweep: joblib's workers between two jobs outlived a killed launcher by that much)."""
    for case in ("idle", "job"):
        tic = time.monotonic()
        out = subprocess.run([sys.executable, "-c", EXIT_WITH, case], capture_output=True, text=True, timeout=60,
                             env=process_env())
        assert out.returncode == 143, (case, out.stderr[-2000:])
        assert out.stdout == ("marked\n" if case == "job" else ""), (case, out.stdout)
        assert time.monotonic() - tic < 15, case


IN_OMEGACONF = """
import os, runpy, signal, sys
from hydra._internal.config_loader_impl import ConfigLoaderImpl
from omegaconf.listconfig import ListConfig
import maglev.study.job as job

where = sys.argv.pop(1)  # "next job": as Hydra prepares the second job; "checks": in Hydra's checks of the configs
ended, appends, sent = [], [], []
run = job.run

def counted(cfg):
    try:
        return run(cfg)
    finally:
        ended.append(1)

def in_checks() -> bool:
    frame = sys._getframe()
    while frame is not None and frame.f_code.co_name != "validate_batch_is_legal":
        frame = frame.f_back
    return frame is not None

set_item = ListConfig._set_item_impl

def signal_in_append(self, key, value):  # the second item appended to a job's overrides (the list half-made)
    armed = ended if where == "next job" else in_checks()
    if armed and not sent and sys._getframe(1).f_code.co_name == "append":
        appends.append(1)
        if len(appends) == 2:
            sent.append(1)
            print("SIGTERM sent from ListConfig.append", file=sys.stderr, flush=True)
            os.kill(os.getpid(), signal.SIGTERM)
    return set_item(self, key, value)

apply = ConfigLoaderImpl._apply_overrides_to_config

def composing(overrides, cfg):
    if sent:
        print("a config composed after the signal", file=sys.stderr, flush=True)
    return apply(overrides, cfg)

job.run = counted
ListConfig._set_item_impl = signal_in_append
ConfigLoaderImpl._apply_overrides_to_config = staticmethod(composing)
sys.argv = sys.argv[1:]
runpy.run_path(sys.argv[0], run_name="__main__")
"""


@pytest.mark.parametrize("where", ["next job", "checks"])
def test_sigterm_inside_omegaconf_between_jobs_ends_the_sweep_at_once_with_its_one_line(tmp_path, where):
    """SIGTERM that lands in OmegaConf while Hydra's basic launcher sets a job's overrides (between a ``None``
    placeholder appended to a list and its item): OmegaConf's cleanup then failed on the placeholder, and its
    ``AttributeError`` replaced the signal's exit — a traceback and exit 1 (seen in the suite: the process-group
    SIGTERM test failed once in three runs).  Now the signal is raised once that config is made: as Hydra
    prepares the second job, or in Hydra's own checks of the sweep's configs, before the next one is composed."""
    from .harness import LEAN, REPO, TINY, model_statuses, store_overrides

    cmd = [sys.executable, "-c", IN_OMEGACONF, where, str(REPO / "study.py"), "-m", "dataset=binary_a025",
           "structure=arx,oe", "structure.order=2,3", *TINY, *LEAN, *store_overrides(tmp_path),
           "~hydra.callbacks.maglev_rank"]
    out = subprocess.run(cmd, capture_output=True, text=True, timeout=240, cwd=tmp_path, env=process_env())
    text = out.stdout + out.stderr
    assert "SIGTERM sent from ListConfig.append" in text, f"the trap in OmegaConf did not fire: {text[-3000:]}"
    assert out.returncode == 143 and "Traceback" not in text, text[-3000:]
    assert "a config composed after the signal" not in text, text[-3000:]
    stopped = [line for line in text.splitlines() if "sweep stopped (SIGTERM)" in line]  # the sweep's one line
    assert len(stopped) == 1 and "[2/4]" not in text, text[-3000:]
    if where == "next job":  # the first job's run FINISHED; the second never started
        assert "[1/4] arx" in text and model_statuses(tmp_path) == {"FINISHED"}, text[-3000:]
    else:
        assert "[1/4]" not in text and model_statuses(tmp_path) == set(), text[-3000:]


AFTER_A_JOB = """
import os, runpy, signal, sys
import hydra.core.utils as hydra_utils
import maglev.study.job as job
from maglev.study import callbacks

case = sys.argv.pop(1)
ended, sent = [], []
run = job.run

def counted(cfg):
    out = run(cfg)
    ended.append(1)
    if case == "no sweep callback" and len(ended) == 2:  # the last job is over; Hydra's code goes on
        print("SIGTERM after the last job", file=sys.stderr, flush=True)
        os.kill(os.getpid(), signal.SIGTERM)
    return out

save = hydra_utils._save_config

def saving(cfg, name, out):  # Hydra writes the next job's .hydra files: the signal is held until that job starts
    if case == "twice" and ended and not sent:
        sent.append(1)
        print("SIGTERM while Hydra prepares the second job", file=sys.stderr, flush=True)
        os.kill(os.getpid(), signal.SIGTERM)
    return save(cfg, name, out)

abort = callbacks.SweepCallback._abort

def aborting(self):  # a second SIGTERM as the sweep's cleanup begins (Slurm and kill send more than one)
    print("SIGTERM again in the cleanup", file=sys.stderr, flush=True)
    os.kill(os.getpid(), signal.SIGTERM)
    return abort(self)

job.run = counted
hydra_utils._save_config = saving
callbacks.SweepCallback._abort = aborting
sys.argv = sys.argv[1:]
runpy.run_path(sys.argv[0], run_name="__main__")
"""


@pytest.mark.parametrize("case", ["twice", "no sweep callback"])
def test_a_sigterm_held_between_jobs_ends_the_sweep_as_one_would_inside_a_job(tmp_path, case):
    """A SIGTERM held after a job is raised at the next job's start: the handler stays off then, so a second
    SIGTERM does not break the cleanup (before: the job's start armed it again, and the second one left the
    parent RUNNING and no sweep line).  Without the sweep callback that raises it at the sweep's end, study.py
    raises it after Hydra returns: exit 143 (before: 0)."""
    import sqlite3

    from .harness import LEAN, REPO, TINY, model_statuses, store_overrides

    drop = ["~hydra.callbacks.maglev_sweep"] if case == "no sweep callback" else []
    cmd = [sys.executable, "-c", AFTER_A_JOB, case, str(REPO / "study.py"), "-m", "dataset=binary_a025",
           "structure=arx,oe", *TINY, *LEAN, *store_overrides(tmp_path), "~hydra.callbacks.maglev_rank", *drop]
    out = subprocess.run(cmd, capture_output=True, text=True, timeout=240, cwd=tmp_path, env=process_env())
    text = out.stdout + out.stderr
    assert out.returncode == 143 and "Traceback" not in text, text[-3000:]
    if case == "twice":
        assert "SIGTERM while Hydra prepares the second job" in text and "SIGTERM again in the cleanup" in text, text
        assert [line for line in text.splitlines() if "sweep stopped (SIGTERM)" in line], text[-3000:]
        with contextlib.closing(sqlite3.connect(tmp_path / "mlflow.db")) as con:
            parents = con.execute("SELECT r.status FROM runs r JOIN tags t ON t.run_uuid = r.run_uuid "
                                  "WHERE t.key = 'kind' AND t.value = 'sweep'").fetchall()
        assert parents == [("KILLED",)] and model_statuses(tmp_path) == {"FINISHED"}, (parents, text[-3000:])
    else:
        assert model_statuses(tmp_path) == {"FINISHED"}, text[-3000:]
        assert text.rstrip().endswith("maglev: stopped by SIGTERM once its runs had started"), text[-3000:]


HELD_IN_PROCESS = """
import os, signal, sys
sys.path.insert(0, sys.argv[1])
from pathlib import Path
from tests.study.harness import LEAN, TINY, launch
import maglev.study.job as job
from maglev.study import shutdown

def failing(cfg):
    raise RuntimeError("estimation failed")

store = Path(sys.argv[2])
for case, overrides in (("refused", ["study.resid_lags=25,1000"]),
                        ("failed", ["study.fail_on_error=true", "structure.order=2,3"])):
    if case == "failed":
        job.estimate_run = failing
    try:
        launch(store / case, "dataset=binary_a025", "structure=arx", *TINY, *LEAN, *overrides)
    except BaseException as exc:
        print(case, "ended by", type(exc).__name__, flush=True)
    shutdown.install()
    try:
        os.kill(os.getpid(), signal.SIGINT)
        for _ in range(1000):
            sum(range(1000))
        print(case, "then Ctrl-C was held", flush=True)
    except KeyboardInterrupt:
        print(case, "then Ctrl-C raised", flush=True)
    shutdown.received = None
"""


def test_a_sweep_ended_by_an_error_leaves_no_signal_held_in_its_process(tmp_path):
    """In-process (a notebook, the tests): a sweep refused by its checks after composing configs, or ended by a
    job's error, leaves signals as it found them (before: Ctrl-C was held for good, the process uninterruptible)."""
    from .harness import REPO

    out = subprocess.run([sys.executable, "-c", HELD_IN_PROCESS, str(REPO), str(tmp_path)], capture_output=True,
                         text=True, timeout=240, env=process_env(), preexec_fn=default_ctrl_c)
    lines = [line for line in out.stdout.splitlines() if line.startswith(("refused ", "failed "))]  # not the log
    assert lines == ["refused ended by SweepRefused", "refused then Ctrl-C raised",
                     "failed ended by RuntimeError", "failed then Ctrl-C raised"], out.stdout + out.stderr[-3000:]
