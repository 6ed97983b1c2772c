"""Parallel mode: joblib workers sharing one SQLite store (a tracking server: test_server.py)."""

from __future__ import annotations

import os

import pytest

from .harness import LEAN, TINY, all_runs, launch

pytestmark = pytest.mark.filterwarnings("ignore:The .*noload.* loader strategy is deprecated")


@pytest.mark.slow
def test_joblib_two_workers_lose_no_run(migrated_store):
    pytest.importorskip("hydra_plugins.hydra_joblib_launcher")
    # the launching process is this one (harness.launch); the jobs run in joblib's two worker processes
    launch(migrated_store, "hydra/launcher=parallel", "hydra.launcher.n_jobs=2",
           "dataset=uniform_narrow,binary_a025", "structure=arx,oe", *TINY, *LEAN)
    _, _, runs = all_runs(migrated_store)
    parent = [r for r in runs if r.data.tags.get("kind") == "sweep"]
    kids = [r for r in runs if r.data.tags.get("kind") == "model"]
    assert len(parent) == 1 and len(kids) == 4
    assert all(r.info.status == "FINISHED" and "val_fit" in r.data.metrics for r in kids)
    assert {r.data.tags["mlflow.parentRunId"] for r in kids} == {parent[0].info.run_id}
    assert len({r.data.tags["config_hash"] for r in kids}) == 4
    pids = {r.data.tags["pid"] for r in kids}
    assert str(os.getpid()) not in pids and len(pids) <= 2  # in the workers, not here
