"""The benchmark scripts still run (smallest settings); their numbers are not checked here.

Each script's ``main(argv)`` is called in this process: what is tested is that the scripts run against
today's package, not how they start (a process start would cost more than their smallest settings)."""

from __future__ import annotations

import importlib.util
from pathlib import Path

import pytest

BENCH = Path(__file__).resolve().parents[1] / "bench"


@pytest.mark.parametrize("script, args, expect", [
    ("estimators.py", ["--quick", "--no-peers", "--reps", "1"], "target"),
    ("study_overhead.py", ["--repeats", "1", "--structures", "arx"], "beyond estimation: at most"),
    ("simulator.py", ["--repeats", "1"], "Levitator.simulate"),
    ("prediction.py", ["--samples", "200", "--repeats", "1"], "worst:"),
])
def test_benchmark_script_runs(tmp_path, monkeypatch, capsys, script, args, expect):
    spec = importlib.util.spec_from_file_location(f"bench_{Path(script).stem}", BENCH / script)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    monkeypatch.chdir(tmp_path)
    assert module.main(args) in (0, None)
    assert expect in capsys.readouterr().out
