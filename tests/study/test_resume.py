"""A relaunch with nothing to do stops after one read of the store (maglev.study.resume), and one that only
re-ranks reuses the ranking run and the report of the same runs.

One small ranked sweep (two jobs, lean, tiny records) is launched in-process once per module; each test
then changes one thing the decision depends on and checks which way the relaunch goes.
"""

from __future__ import annotations

import shutil
import socket
import subprocess
import sys

import pytest

from tests.study.harness import LEAN, REPO, TINY, all_runs, launch, store_overrides, study_log

pytestmark = pytest.mark.filterwarnings("ignore:The .*noload.* loader strategy is deprecated")

SWEEP = ["dataset=binary_a025", "structure=arx", "structure.order=2,3", "study.name=resume", *LEAN, *TINY]


@pytest.fixture(scope="module")
def swept(tmp_path_factory, migrated_db):
    """A finished, ranked sweep; tests copy it before they change it."""
    store = tmp_path_factory.mktemp("resume")
    shutil.copyfile(migrated_db, store / "mlflow.db")
    with study_log() as lines:
        launch(store, *SWEEP, rank=True)
    (store / "first-launch.log").write_text("\n".join(lines))
    return store


@pytest.fixture
def store(swept, tmp_path):
    """A copy of the finished sweep's store (database, artifacts, report) under the same paths' names."""
    copy = tmp_path / "store"
    shutil.copytree(swept, copy)
    return copy


def snapshot(store) -> dict:
    """Every run's id, status, end time and tags: what a relaunch with nothing to do must leave as it was."""
    _, _, runs = all_runs(store)
    return {r.info.run_id: (r.info.status, r.info.end_time, dict(r.data.tags)) for r in runs}


def relaunch(store, *extra: str) -> tuple[list[str], BaseException | None]:
    """Launch the sweep again in-process: (the study's log lines, the SystemExit it ended with, if any)."""
    from maglev.study.callbacks import NothingToDo

    with study_log() as lines:
        try:
            launch(store, *SWEEP, *extra, rank=True)
        except NothingToDo as exc:
            return lines, exc
    return lines, None


def test_relaunch_of_a_finished_sweep_stops_before_any_job_and_changes_nothing(store):
    from maglev.study.callbacks import NothingToDo

    before = snapshot(store)
    report = next((store / "reports").glob("resume-*.html"))
    written = report.stat().st_mtime_ns
    lines, stopped = relaunch(store)
    assert isinstance(stopped, NothingToDo) and stopped.code == 0
    (line,) = [m for m in lines if "nothing to do" in m]
    parent = [rid for rid, (_, _, tags) in before.items() if tags.get("kind") == "sweep"]
    ranking = [rid for rid, (_, _, tags) in before.items() if tags.get("kind") == "ranking"]
    assert f"the 2 configs of its 2 jobs all have FINISHED runs under parent run {parent[0]}" in line
    assert f"ranking run {ranking[0]} ranked these 2 runs; report {report}" in line
    assert not [m for m in lines if m.startswith("skip")]  # no job was launched to find its config done
    assert snapshot(store) == before and report.stat().st_mtime_ns == written


def test_a_launch_says_what_it_does_one_line_per_state_change(swept):
    """The first line comes before any config is composed; then what is to run; one line per run with the jobs
    left; the ranking.  Nothing else from the study's logger."""
    lines = (swept / "first-launch.log").read_text().splitlines()
    assert lines[0] == "sweep 'resume': 2 jobs; checking their configs"
    assert lines[1] == "sweep 'resume': 2 configs checked; 2 to run, 0 FINISHED already (skipped)"
    assert lines[2].startswith("sweep 'resume': parent run ") and lines[2].endswith("(new) in " + f"sqlite:///{swept}/mlflow.db")
    assert lines[3].startswith("[1/2] arx 2-2-2 · binary_a025: val_fit ") and lines[3].endswith("; 1 job(s) left")
    assert lines[4].startswith("[2/2] arx 3-3-2 · binary_a025: val_fit ") and lines[4].endswith("; the last job")
    assert lines[5] == "sweep 'resume': ranking its runs and writing the report"
    assert lines[6].startswith("sweep done: 2 FINISHED under parent run ") and len(lines) == 7


def test_the_fast_answer_ranks_the_runs_the_ranking_ranks(store):
    """resume's own query and dedup against MLflow's: the same runs, the same ranked_hash as the ranking run's."""
    from maglev.study import claims, resume
    from maglev.study.ranking import compute
    from maglev.study.store import load_sweep

    sweep = load_sweep(f"sqlite:///{store}/mlflow.db", "maglev", reap=False)
    ranking = compute(sweep, draw=False)
    _, _, every = all_runs(store)
    hashes = sorted({r.data.tags["config_hash"] for r in every if r.data.tags.get("kind") == "model"})
    runs = resume.read(store / "mlflow.db", "maglev", sweep.parent.data.tags["sweep_id"], hashes)
    models = [r for r in runs if r.role == "model"]
    ids = resume.ranked_ids(sweep.parent_id, models)
    assert sorted(ids) == sorted(sweep.runs["run_id"])
    assert resume.ranked_hash(ids, ranking.structure) == ranking.ranked_hash
    assert resume.REF_PREFIX == claims.REF_PREFIX


def test_a_store_without_the_sweeps_parent_run_is_a_new_sweep(store, tmp_path):
    """resume.new_sweep: a launch into it runs jobs whatever its configs (its renderer starts before they are
    checked); a store that holds the parent, a server, or no answer: the usual path decides."""
    from maglev.study.resume import new_sweep

    client, _, runs = all_runs(store)
    parent = next(r for r in runs if r.data.tags.get("kind") == "sweep")
    uri, sid = f"sqlite:///{store}/mlflow.db", parent.data.tags["sweep_id"]
    assert new_sweep(uri, "maglev", sid) is False
    assert new_sweep(uri, "maglev", "0" * 40) is True  # another sweep
    assert new_sweep(uri, "another", sid) is True  # another experiment
    assert new_sweep(f"sqlite:///{tmp_path}/none.db", "maglev", sid) is True  # no store yet
    assert new_sweep("http://127.0.0.1:5000", "maglev", sid) is False
    (tmp_path / "junk.db").write_bytes(b"not a database")
    assert new_sweep(f"sqlite:///{tmp_path}/junk.db", "maglev", sid) is False
    client.delete_run(parent.info.run_id)  # a sweep stopped before any run deletes its parent
    assert new_sweep(uri, "maglev", sid) is True


def decision(store, *, hashes: list[str] | None = None, lab: bool = False, structure: str | None = None,
             uri: str | None = None, reap: bool = True):
    """resume.survey's decision on the sweep in ``store`` (its own hashes unless given)."""
    from maglev.study.resume import survey

    _, _, runs = all_runs(store)
    parent = next(r for r in runs if r.data.tags.get("kind") == "sweep")
    own = [r.data.tags["config_hash"] for r in runs if r.data.tags.get("kind") == "model"]
    report = next((store / "reports").glob("resume-*.html"), store / "reports" / "none.html")
    return survey(uri or f"sqlite:///{store}/mlflow.db", "maglev", parent.data.tags["sweep_id"],
                  own if hashes is None else hashes, lab, {"structure": structure}, report, reap).done


def test_anything_left_to_do_sends_the_relaunch_the_usual_way(store):
    """Each condition of the fast path, broken alone: the answer is then None (the usual path decides)."""
    assert decision(store) is not None
    assert decision(store, hashes=["0" * 40]) is None  # a config no run holds
    assert decision(store, lab=True) is None  # lab steps asked for, never logged (the sweep is lean)
    assert decision(store, structure="oe") is None  # another compared structure than the ranking run's
    assert decision(store, uri="http://127.0.0.1:5000") is None  # a server: MLflow's API decides
    client, _, runs = all_runs(store)
    parent = next(r for r in runs if r.data.tags.get("kind") == "sweep").info.run_id
    client.set_terminated(parent, "KILLED")
    assert decision(store) is None  # a launch that did not end
    client.set_terminated(parent, "FINISHED")
    assert decision(store) is not None
    dead = subprocess.Popen([sys.executable, "-c", "pass"])
    dead.wait()
    _, exp_id, _ = all_runs(store)
    left = client.create_run(exp_id, run_name="left", tags={"host": socket.gethostname(), "pid": str(dead.pid)})
    assert decision(store) is None  # a run left RUNNING by a dead process: the usual path marks it KILLED
    assert decision(store, reap=False) is not None  # unless tracking.reap=false
    client.set_terminated(left.info.run_id, "KILLED")
    next((store / "reports").glob("resume-*.html")).unlink()
    assert decision(store) is None  # no report to reuse


def test_a_relaunch_without_the_report_reuses_the_ranking_run_and_writes_the_report(store):
    from maglev.study.callbacks import NothingToDo

    next((store / "reports").glob("resume-*.html")).unlink()
    lines, stopped = relaunch(store)
    assert not isinstance(stopped, NothingToDo) and not [m for m in lines if "nothing to do" in m]
    assert len([m for m in lines if m.startswith("skip")]) == 2  # each job found its config done
    _, _, runs = all_runs(store)
    assert len([r for r in runs if r.data.tags.get("kind") == "ranking"]) == 1
    assert next((store / "reports").glob("resume-*.html")).is_file()


def test_ranking_an_unchanged_sweep_again_reuses_its_ranking_run_and_report(store, capsys):
    from maglev.study.report import rank_and_report

    report = next((store / "reports").glob("resume-*.html"))
    written = report.stat().st_mtime_ns
    _, _, runs = all_runs(store)
    ranking = next(r.info.run_id for r in runs if r.data.tags.get("kind") == "ranking")
    run_id, path = rank_and_report(f"sqlite:///{store}/mlflow.db", "maglev", None, out=store / "reports", reuse=True)
    assert (run_id, path) == (ranking, report.resolve()) and report.stat().st_mtime_ns == written
    assert "(reused: it ranked these same runs)" in capsys.readouterr().out
    _, _, after = all_runs(store)
    assert len(after) == len(runs)


def test_relaunched_as_a_process_it_never_imports_mlflow(store):
    """The point of the fast path: the command ends before MLflow (≈ 1.5 s of CPU to import) is loaded."""
    args = [sys.executable, "-X", "importtime", str(REPO / "study.py"), "-m", *SWEEP, *store_overrides(store),
            f"hydra.callbacks.maglev_rank.report_dir={store}/reports"]
    proc = subprocess.run(args, capture_output=True, text=True, cwd=store, timeout=120)
    assert proc.returncode == 0, proc.stderr[-3000:]
    assert "nothing to do" in proc.stdout + proc.stderr
    imported = [line.rsplit("|", 1)[-1].strip() for line in proc.stderr.splitlines() if line.startswith("import time")]
    assert imported and not [m for m in imported if m.split(".")[0] in ("mlflow", "sqlalchemy")]
