"""The benchmark scripts still run (smallest settings); their numbers are not checked here."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

BENCH = Path(__file__).resolve().parents[1] / "bench"


@pytest.mark.parametrize("script, args, expect", [
    ("estimators.py", ["--quick", "--no-peers", "--reps", "1"], "target"),
    ("study_overhead.py", ["--repeats", "1", "--structures", "arx"], "beyond estimation: at most"),
    ("simulator.py", ["--repeats", "1"], "Levitator.simulate"),
])
def test_benchmark_script_runs(tmp_path, script, args, expect):
    proc = subprocess.run([sys.executable, str(BENCH / script), *args], capture_output=True, text=True,
                          cwd=tmp_path, timeout=300)
    assert proc.returncode == 0, proc.stderr[-3000:]
    assert expect in proc.stdout
