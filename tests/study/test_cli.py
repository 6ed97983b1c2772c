"""The entry points as processes: ``python study.py`` and the ``maglev`` command (everything else runs in-process)."""

from __future__ import annotations

import os
import shutil
import subprocess
import sys

import pytest

from .harness import REPO, all_runs, study_process

pytestmark = pytest.mark.filterwarnings("ignore:The .*noload.* loader strategy is deprecated")


def test_study_py_refuses_a_typo_with_the_key_and_creates_no_run(tmp_path):
    proc = study_process(tmp_path, "-m", "structure=arx,oe", "structure.na=abc", check=False)
    assert proc.returncode != 0 and "structure.na" in proc.stderr, proc.stderr[-2000:]
    assert not (tmp_path / "mlflow.db").exists() or all_runs(tmp_path)[2] == []


@pytest.mark.parametrize("command", [["maglev"], [sys.executable, "-m", "maglev"]])
def test_maglev_command_answers_a_missing_store_in_one_line(tmp_path, command):
    if command == ["maglev"] and shutil.which("maglev") is None:
        pytest.skip("the maglev console script is not installed (pip install -e .)")
    env = {k: v for k, v in os.environ.items() if k != "MLFLOW_TRACKING_URI"}
    missing = tmp_path / "none.db"
    proc = subprocess.run([*command, "rank", "--tracking-uri", f"sqlite:///{missing}"], capture_output=True,
                          text=True, cwd=REPO, env=env, timeout=120)
    assert proc.returncode == 2
    assert proc.stderr.strip().splitlines() == [f"maglev rank: no MLflow store at {missing}; run a sweep first "
                                                "(python study.py -m +sweep=lab) or pass --tracking-uri"]
    assert not missing.exists()
