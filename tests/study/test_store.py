"""Store health: a store whose creation fails leaves nothing (or is repaired, saying so), and a damaged or
read-only store is answered in one line saying what to do, exit status 2, by every command and a sweep.

A full disk is a tiny tmpfs mounted by the test (skipped where the test cannot mount one: not root, or no
CAP_SYS_ADMIN in a container).
"""

from __future__ import annotations

import contextlib
import os
import shutil
import subprocess
from pathlib import Path

import pytest

from .harness import LEAN, TINY, all_runs, launch, study_log

pytestmark = pytest.mark.filterwarnings("ignore:The .*noload.* loader strategy is deprecated")
SMALL = ["dataset=binary_a025", "structure=arx,oe", *TINY, *LEAN]
COMMANDS = [["rank"], ["report"], ["reap"], ["ui", "--port", "9"]]


@contextlib.contextmanager
def tmpfs(where: Path, size: str):
    """A tmpfs of ``size`` at ``where`` while the block runs (remount it with :func:`resize`)."""
    where.mkdir()
    made = subprocess.run(["mount", "-t", "tmpfs", "-o", f"size={size}", "tmpfs", str(where)], capture_output=True)
    if made.returncode != 0:
        pytest.skip(f"cannot mount a tmpfs here ({made.stderr.decode().strip() or 'not root'}): "
                    "no full disk to fill")
    try:
        yield where
    finally:
        subprocess.run(["umount", "-l", str(where)], check=False)


def remount(where: Path, options: str) -> None:
    subprocess.run(["mount", "-o", f"remount,{options}", str(where)], check=True)


@pytest.fixture(scope="module")
def finished(tmp_path_factory, migrated_db) -> tuple[Path, str]:
    """A store with a FINISHED sweep of two runs, made once for the file; (its folder, one model run's id).
    Tests damage or remount copies of its database; the artifacts stay here, where the runs name them."""
    store = tmp_path_factory.mktemp("finished")
    shutil.copyfile(migrated_db, store / "mlflow.db")
    launch(store, *SMALL)
    _, _, runs = all_runs(store)
    return store, next(r.info.run_id for r in runs if r.data.tags.get("kind") == "model")


def a_store_with_runs(store: Path, finished: tuple[Path, str]) -> str:
    """``store/mlflow.db``: a copy of the finished sweep's store; returns the id of one model run."""
    shutil.copyfile(finished[0] / "mlflow.db", store / "mlflow.db")
    return finished[1]


def every_command_says(store: Path, run_id: str, needle: str, capsys) -> None:
    from maglev.study.cli import main

    uri = f"sqlite:///{store}/mlflow.db"
    capsys.readouterr()  # what the sweep printed
    for argv in [*COMMANDS, ["reproduce", run_id]]:
        assert main([argv[0], *argv[1:], "--tracking-uri", uri]) == 2, argv
        out = capsys.readouterr()
        assert out.out == "" and out.err.startswith(f"maglev {argv[0]}: ") and needle in out.err, (argv, out)
        assert out.err.count("\n") == 1, out.err


def damage(db: Path, how: str) -> None:
    size = db.stat().st_size
    if how == "truncated":
        with open(db, "r+b") as fh:
            fh.truncate(size // 2)
    else:  # 8 KB of garbage in the middle of the file
        with open(db, "r+b") as fh:
            fh.seek(size // 2 // 4096 * 4096)
            fh.write(os.urandom(8192))


@pytest.mark.parametrize("how", ["truncated", "garbage"])
def test_a_damaged_store_is_answered_in_one_line_by_every_command_and_a_sweep(tmp_path, finished, capsys, how):
    """Before: rank, report, reap and reproduce exited 1 with a traceback; 8 KB of garbage went unnoticed by
    every command and by a new sweep, though SQLite's integrity check fails."""
    from maglev.study import tracking

    run_id = a_store_with_runs(tmp_path, finished)
    damage(tmp_path / "mlflow.db", how)
    tracking._checked.clear()  # this process checked the store before damaging it
    every_command_says(tmp_path, run_id, f"the MLflow store {tmp_path}/mlflow.db is damaged (", capsys)
    with pytest.raises(SystemExit) as refused:
        launch(tmp_path, *SMALL, "structure.order=3")
    assert str(refused.value.code).startswith(f"maglev: the MLflow store {tmp_path}/mlflow.db is damaged (")
    assert "mv " in str(refused.value.code) and "\n" not in str(refused.value.code)


def test_a_read_only_store_is_answered_in_one_line_and_reproduce_still_reads_it(tmp_path, finished, capsys):
    from maglev.study import tracking
    from maglev.study.cli import main

    run_id = a_store_with_runs(tmp_path, finished)
    with tmpfs(tmp_path / "ro", "20m") as fs:  # a copy no process has open, so it can be remounted read-only
        shutil.copyfile(tmp_path / "mlflow.db", fs / "mlflow.db")
        shutil.copytree(finished[0] / "artifacts", fs / "artifacts")
        remount(fs, "ro")
        tracking._checked.clear()
        from maglev.study.cli import main as cli

        uri = f"sqlite:///{fs}/mlflow.db"
        capsys.readouterr()
        for argv in COMMANDS:
            assert cli([argv[0], *argv[1:], "--tracking-uri", uri]) == 2, argv
            err = capsys.readouterr().err
            assert err.startswith(f"maglev {argv[0]}: the MLflow store {fs}/mlflow.db is read-only"), err
        assert main(["reproduce", run_id, "--tracking-uri", uri]) == 0  # reading needs no write
        assert "metrics identical" in capsys.readouterr().out


def test_a_full_disk_while_the_store_is_created_leaves_nothing_and_the_next_launch_works(tmp_path):
    """Before: a half-migrated store on which every later launch and `maglev rank` failed with
    `table _alembic_tmp_experiments already exists`."""
    with tmpfs(tmp_path / "full", "150k") as fs:
        with pytest.raises(SystemExit) as stopped:
            launch(fs, *SMALL)
        message = str(stopped.value.code)
        assert message.startswith(f"maglev: the MLflow store {fs}/mlflow.db could not be created (") and \
            "nothing was left behind" in message and "\n" not in message, message
        assert not (fs / "mlflow.db").exists() and not list(fs.glob("mlflow.db.creating-*"))
        remount(fs, "size=30m")
        launch(fs, *SMALL)
        _, _, runs = all_runs(fs)
        models = [r for r in runs if r.data.tags.get("kind") == "model"]
        assert sorted(r.info.status for r in models) == ["FINISHED", "FINISHED"]


def test_a_store_left_half_made_by_an_older_version_is_repaired_and_the_launch_says_so(tmp_path):
    from mlflow import MlflowClient

    with tmpfs(tmp_path / "full", "150k") as fs:
        with pytest.raises(Exception, match="database or disk is full"):  # MLflow alone, as before
            MlflowClient(tracking_uri=f"sqlite:///{fs}/mlflow.db").search_experiments()
        remount(fs, "size=30m")
        with pytest.raises(Exception, match="_alembic_tmp_"):
            MlflowClient(tracking_uri=f"sqlite:///{fs}/mlflow.db").search_experiments()
        with study_log() as lines:
            launch(fs, *SMALL)
        [said] = [line for line in lines if "half-made" in line]
        assert said.startswith(f"the MLflow store {fs}/mlflow.db was left half-made by an interrupted creation")
        assert len(list(fs.glob("mlflow.db.half-made-*"))) == 1
        _, _, runs = all_runs(fs)
        assert sorted(r.info.status for r in runs if r.data.tags.get("kind") == "model") == ["FINISHED"] * 2


def test_reproduce_takes_the_unique_prefix_the_ui_shows(tmp_path, finished, capsys):
    """The UI shows a run id's first 8 characters; before, only the whole id was accepted."""
    from maglev.study.cli import main

    run_id = a_store_with_runs(tmp_path, finished)
    uri = f"sqlite:///{tmp_path}/mlflow.db"
    capsys.readouterr()
    assert main(["reproduce", run_id[:8], "--tracking-uri", uri]) == 0
    assert "metrics identical" in capsys.readouterr().out
    absent = next(p for p in ("0000", "ffff", "abcd") if not run_id.startswith(p))
    for prefix, said in ((absent + "0000", f"no run id starts with '{absent}0000' in {uri}"),
                         ("ab", f"no run 'ab' in {uri}")):
        assert main(["reproduce", prefix, "--tracking-uri", uri]) == 2
        assert capsys.readouterr().err.strip() == f"maglev reproduce: {said}"


def _schema(db: Path) -> list[list[str]]:
    """Every table's and index's definition, its lines sorted: MLflow's migrations write a table's constraints
    in an order that differs from one process to the next."""
    import sqlite3

    con = sqlite3.connect(db)
    try:
        return sorted(sorted(line.strip().rstrip(",") for line in row[0].splitlines())
                      for row in con.execute("SELECT sql FROM sqlite_master WHERE sql IS NOT NULL"))
    finally:
        con.close()


def test_a_new_store_is_mlflows_own_empty_store_copied_from_the_cache(tmp_path, monkeypatch):
    """A new store is a copy of the empty store MLflow's migrations made once in the cache (1.5-2 s of CPU per
    sweep before): the same tables and indexes as MLflow's own, and the default experiment MLflow adds, with
    this store's artifact root; a cache that cannot hold the copy only costs the migration."""
    from mlflow import MlflowClient

    from maglev.study import tracking

    monkeypatch.chdir(tmp_path)
    monkeypatch.setenv("MAGLEV_CACHE", str(tmp_path / "cache"))
    own = tmp_path / "own.db"
    MlflowClient(tracking_uri=f"sqlite:///{own}").search_experiments()
    for name in ("first", "second"):  # the first launch makes the cached copy, the second only copies it
        tracking.new_client(f"sqlite:///{tmp_path}/{name}.db")
        assert _schema(tmp_path / f"{name}.db") == _schema(own)
        [default] = MlflowClient(tracking_uri=f"sqlite:///{tmp_path}/{name}.db").search_experiments()
        assert (default.experiment_id, default.name) == ("0", "Default")
        assert default.artifact_location == str(tmp_path / "mlruns" / "0")
    [empty] = (tmp_path / "cache" / "mlflow").glob("empty-store-*.db")
    assert _schema(empty) == _schema(own) and not list(empty.parent.glob("*.creating-*"))
    (tmp_path / "not-a-folder").write_text("")
    monkeypatch.setenv("MAGLEV_CACHE", str(tmp_path / "not-a-folder"))
    tracking.new_client(f"sqlite:///{tmp_path}/third.db")
    assert _schema(tmp_path / "third.db") == _schema(own)
    assert [e.name for e in MlflowClient(tracking_uri=f"sqlite:///{tmp_path}/third.db").search_experiments()] == \
        ["Default"]


def test_files_uploaded_with_the_runs_artifact_uri_land_where_mlflow_puts_them(migrated_store):
    """A job uploads with the artifact URI create_run answered (MLflow would read the whole run back for it)."""
    from maglev.study import tracking

    client, exp = tracking.connect({"uri": f"sqlite:///{migrated_store}/mlflow.db", "experiment": "maglev",
                                    "artifact_location": str(migrated_store / "a")})
    runs = [client.create_run(exp).info for _ in range(2)]
    tracking.log_files(client, runs[0].run_id, {"a/b.txt": "one"})
    tracking.log_files(client, runs[1].run_id, {"a/b.txt": "two"}, runs[1].artifact_uri)
    for info, text in zip(runs, ("one", "two")):
        assert [f.path for f in client.list_artifacts(info.run_id, "a")] == ["a/b.txt"]
        assert tracking.download_text(client, info.run_id, "a/b.txt") == text


def test_a_sweeps_artifacts_in_a_local_store_are_read_as_files_with_the_bytes_mlflow_downloads(finished, monkeypatch):
    """The ranking and the report read ≈ 50 artifacts at a sweep's end: from a local store as files, where
    MLflow keeps them, with the same answer as its download — None for an artifact the run lacks."""
    from maglev.study import store as store_

    folder, run_id = finished
    sweep = store_.load_sweep(f"sqlite:///{folder}/mlflow.db", "maglev")
    uri = sweep.artifact_uris[run_id]  # the sweep carries the URIs it read with its runs
    local = store_.local_artifact(uri, "model/model.json")
    assert local is not None and local.is_file()
    assert store_.local_artifact(uri, "../../outside.txt") is None  # never a file outside the run's folder
    read = {p: sweep.artifact(run_id, p) for p in ("model/model.json", "no/such.json")}
    monkeypatch.setattr(store_, "local_artifact", lambda uri, path: pytest.fail("read as a file") if uri else None)
    assert read == {p: store_.artifact_bytes(sweep.client, run_id, p) for p in read}  # no URI: MLflow downloads
    assert read["model/model.json"].startswith(b"{") and read["no/such.json"] is None
