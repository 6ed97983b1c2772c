"""Hostile configs and stores: names that would become paths outside the project, values the config alone decides
are wrong — each refused or neutralised before any run exists (credentials in the tracking URI: test_server.py).

The table of what the user sees is docs/faults.md.
"""

from __future__ import annotations

import pytest

from .harness import LEAN, TINY, all_runs, launch, study_log

pytestmark = pytest.mark.filterwarnings("ignore:The .*noload.* loader strategy is deprecated")
SMALL = ["dataset=binary_a025", *TINY, *LEAN]


def written(root) -> set[str]:
    return {str(p.relative_to(root)) for p in root.rglob("*")}


# ---------------------------------------------------------------------------- names that become paths
@pytest.mark.parametrize("override, needle", [
    ("study.name=../../../escape", "study.name='../../../escape': a name must be"),
    ("study.name=/tmp/maglev-escape", "study.name='/tmp/maglev-escape': a name must be"),
    ("study.name=" + "n" * 300, "(300 characters)': a name must be"),
    ("dataset.name=a/../../b", "dataset.name='a/../../b': a name must be"),
    ("data_dir=../../../elsewhere", "data_dir=../../../elsewhere: the job's folder"),
])
def test_a_name_that_would_write_outside_the_sweep_dir_is_refused_before_anything_is_written(tmp_path, override,
                                                                                          needle):
    """Before: ../../../escape wrote the report at the filesystem root and the sweep dir outside the
    project; dataset.name=a/../../b put Hydra's job dir outside the sweep dir."""
    root = tmp_path / "project"
    root.mkdir()
    with pytest.raises(SystemExit) as refused:
        launch(root, *SMALL, override)
    message = str(refused.value.code)
    assert message.startswith("maglev: sweep refused before any run: job ") and needle in message, message
    assert "\n" not in message
    assert written(tmp_path) == {"project"} and not (tmp_path.parent / "escape").exists()


def test_a_single_run_with_a_path_for_a_name_is_refused_in_one_line(tmp_path):
    with pytest.raises(SystemExit) as refused:
        launch(tmp_path, *SMALL, "study.name=../up", multirun=False)
    assert str(refused.value.code).startswith("maglev: run refused before it started: study.name='../up'")
    assert not (tmp_path / "mlflow.db").exists()


def test_a_sweep_tag_read_back_from_the_store_cannot_move_the_report(tmp_path, migrated_store, capsys):
    """Anyone may tag a run in a shared, login-free store: the report's name is made a plain file name, so
    ``maglev report --out DIR`` writes in DIR whatever the tag says."""
    from maglev.study.cli import main

    launch(migrated_store, *SMALL, "structure=arx,oe", "study.name=victim")
    client, _, runs = all_runs(migrated_store)
    [parent] = [r for r in runs if r.data.tags.get("kind") == "sweep"]
    client.set_tag(parent.info.run_id, "sweep", "../../../../evil")
    out = tmp_path / "mine"
    before = written(migrated_store)
    assert main(["report", "--tracking-uri", f"sqlite:///{migrated_store}/mlflow.db", "--out", str(out)]) == 0
    sid = parent.data.tags["sweep_id"][:8]
    assert written(out) == {f"_.._.._.._evil-{sid}.html"}, written(out)
    outside = written(migrated_store) - before
    assert {p for p in outside if not p.startswith(("artifacts/", "mine"))} == set(), outside
    assert not (tmp_path.parent / "evil").exists()
    capsys.readouterr()


def test_an_artifact_path_that_leaves_the_artifact_folder_is_refused(migrated_store):
    from maglev.study import tracking

    client, exp = tracking.connect({"uri": f"sqlite:///{migrated_store}/mlflow.db", "experiment": "maglev",
                                    "artifact_location": str(migrated_store / "a")})
    run = client.create_run(exp).info.run_id
    for bad in ("/etc/escape.txt", "report/../../escape.txt"):
        with pytest.raises(ValueError, match="leaves the run's artifact folder"):
            tracking.log_files(client, run, {bad: "x"})


# ---------------------------------------------------------------------------- credentials in the URI
# a password in the tracking URI: tests/study/test_server.py (its launch against a server carries one)


# ---------------------------------------------------------------------------- configs that decide a failure
CONFIG_CASES = [
    (["dataset.seed=-1"], "dataset.seed must be in [0, 2**32), got -1"),
    (["study.name=" + "s" * 300], "study.name='" + "s" * 40 + "… (300 characters)'"),
    (["tracking.experiment="], "tracking.experiment is empty: name the MLflow experiment"),
    (["+structure.oder=3"], "structure.oder: no such key (known: name, order, na, nb, nk, initial_condition)"),
    (["+dataset.preprocess.detrnd=false"], "dataset.preprocess.detrnd: no such key"),
    (["dataset.preprocess.split=0"], "dataset.preprocess.split must be in (0, 1), got 0.0"),
    (["study.val_horizon=0"], "study.val_horizon must be >= 1, got 0"),
    (["dataset.low=5", "dataset.high=1"], "low/high must satisfy 0 <= low <= high <= 10 A, got low=5.0, high=1.0"),
]


@pytest.mark.parametrize("multirun", [True, False], ids=["sweep", "single"])
@pytest.mark.parametrize("overrides, needle", CONFIG_CASES)
def test_a_config_that_decides_a_failure_is_refused_in_one_line_with_no_run(tmp_path, overrides, needle, multirun):
    """Before: a FAILED run (seed), a RUNNING parent ("File name too long"), an AttributeError after creating
    the store (empty experiment), an order-2 run with an unread key (+structure.oder), and on the single-run
    path Hydra's full traceback."""
    with pytest.raises(SystemExit) as refused:
        launch(tmp_path, *SMALL, *overrides, multirun=multirun)
    message = str(refused.value.code)
    head = "maglev: sweep refused before any run: job " if multirun else "maglev: run refused before it started: "
    assert message.startswith(head) and needle in message and "\n" not in message, message
    assert not (tmp_path / "mlflow.db").exists() and not (tmp_path / "multirun").exists()


def test_a_missing_real_file_is_refused_on_both_paths(tmp_path):
    for multirun in (True, False):
        with pytest.raises(SystemExit) as refused:
            launch(tmp_path, "dataset=real_binary_signal_2", f"data_dir={tmp_path}/nowhere", *LEAN, multirun=multirun)
        assert "dataset 'real_binary_signal_2': " in str(refused.value.code) and "not found" in str(refused.value.code)
        assert "\n" not in str(refused.value.code)
    assert not (tmp_path / "mlflow.db").exists()


def test_a_sweep_whose_lab_staircase_is_missing_is_refused_before_any_run(tmp_path):
    """Before: a warning, and the sweep went on to FINISHED without its lab steps."""
    with pytest.raises(SystemExit) as refused:
        launch(tmp_path, "dataset=binary_a025", *TINY, "tracking.log_figures=false", "study.true_plant=false",
               "lab=real", f"data_dir={tmp_path}")
    message = str(refused.value.code)
    assert message.startswith("maglev: sweep refused before any run: lab.staircase_file: ") and "not found" in message
    assert not (tmp_path / "mlflow.db").exists()


@pytest.mark.parametrize("uri", ["notauri", "sqlite:///relative.db", "mlruns"])
def test_a_tracking_uri_mlflow_cannot_use_is_refused_in_one_line(tmp_path, uri):
    """Before: MLflow's file-store deprecation text (a bare word is a file store to MLflow)."""
    import subprocess
    import sys

    from .harness import REPO, process_env

    cmd = [sys.executable, str(REPO / "study.py"), "-m", *SMALL, f"tracking.uri={uri}",
           f"hydra.sweep.dir={tmp_path}/multirun"]
    proc = subprocess.run(cmd, capture_output=True, text=True, cwd=tmp_path, timeout=120, env=process_env())
    lines = proc.stderr.strip().splitlines()
    assert proc.returncode == 1 and len(lines) == 1, proc.stderr[-3000:]
    assert lines[0].startswith("maglev: sweep refused before any run: job ") and f"tracking.uri='{uri}': expected" \
        in lines[0], lines
    assert written(tmp_path) == set()


def test_a_tiny_p_value_is_readable_in_the_runs_table():
    """Rounded to 1e-4, every p-value below 5e-5 showed as 0."""
    from maglev.study.tracking import key_metrics

    shown = key_metrics({"whiteness_pvalue": 3.24e-7, "independence_pvalue": 0.0})
    assert shown == {"key.white_p": 3.24e-7, "key.white_log10p": 6.49, "key.indep_p": 0.0, "key.indep_log10p": 300.0}
    assert key_metrics({"whiteness_pvalue": 0.01})["key.white_log10p"] == 2.0  # the pass threshold
