"""Shared test fixtures: where the real lab recordings are, a non-interactive matplotlib, and an empty
MLflow store made once per session and copied."""

from __future__ import annotations

import os
import shutil
from pathlib import Path

import matplotlib
import pytest

matplotlib.use("Agg")  # before anything imports pyplot (python-control does)

from maglev.paths import refdata_dir  # noqa: E402

REPO = Path(__file__).resolve().parents[1]
TESTS = Path(__file__).resolve().parent

# The cluster harness (tests/cluster: Slurm, PostgreSQL, an MLflow server with auth) installs system packages
# and runs minutes: its own CI stage runs it with MAGLEV_CLUSTER=1; the suite's default run leaves it out.
collect_ignore_glob = [] if os.environ.get("MAGLEV_CLUSTER") == "1" else ["cluster/*"]

# The README's command runs the suite in two pytest-xdist workers, whole files at a time (--dist loadfile),
# handing a worker its next file once it has at most 2 tests left.  xdist's default order (files with the
# most tests first) leaves the end-to-end files, a few tests of 5–35 s each, for last, and one worker
# idle while the other finishes them.  Longest first instead (durations summed per file, a full run on a 2-core
# machine, 2026-11-27, in s):
LONGEST_FIRST = (
    "study/test_concurrency.py",  # 75: two launches at once (twice), SIGTERM, kill -9
    "study/test_report.py",       # 69: the default sweep, its BLAs estimated, ranked and reported
    "study/test_sweep.py",        # 42: a sweep, maglev ui
    "study/test_server.py",       # 34: a tracking server, submitit's job processes
    "study/test_report_real.py",  # 25 s of CPU: the real sweep, ranked, reported and printed (loaded machine)
    "sim/test_calibrate.py",      # 30
    "study/test_config.py",       # 25
    "estimation/test_nested_orders.py",  # 19
    "estimation/test_estimate_real.py",  # 18
    "study/test_parallel.py",     # 17: joblib's worker processes
    "study/test_faults.py",       # 16
)


def pytest_configure(config: pytest.Config) -> None:
    if hasattr(config.option, "loadscopereorder"):  # pytest-xdist: keep the collection order below
        config.option.loadscopereorder = False


def pytest_collection_modifyitems(items: list[pytest.Item]) -> None:
    """Files of ``LONGEST_FIRST`` first, in that order; the rest after them, as collected."""
    rank = {name: i for i, name in enumerate(LONGEST_FIRST)}

    def key(item: pytest.Item) -> int:
        try:
            return rank.get(item.path.relative_to(TESTS).as_posix(), len(rank))
        except ValueError:
            return len(rank)

    items.sort(key=key)


@pytest.fixture
def refdata() -> Path:
    """The real recordings (``$MAGLEV_REFDATA`` or ``../shared/refdata``), or skip with the reason."""
    path = refdata_dir()
    if path is None or not (path / "el2820_maglev_2022").is_dir():
        searched = os.environ.get("MAGLEV_REFDATA") or REPO.parent / "shared" / "refdata"
        pytest.skip(f"real lab data not found at {searched} (set MAGLEV_REFDATA or place ../shared/refdata)")
    return path


@pytest.fixture(scope="session")
def migrated_db(tmp_path_factory) -> Path:
    """An empty MLflow SQLite store (tables only), created once per worker: MLflow's migrations of a fresh
    file take 0.6 s in a process that has run them before, 1.5–2 s in a new one (idle 2-core machine),
    which a test that is not about creating the store need not pay again."""
    from maglev.study.tracking import new_client

    path = tmp_path_factory.mktemp("migrated") / "mlflow.db"
    new_client(f"sqlite:///{path}")
    return path


@pytest.fixture
def migrated_store(tmp_path, migrated_db) -> Path:
    """``tmp_path`` holding a copy of the empty store as ``mlflow.db`` (what the harness's overrides use)."""
    shutil.copyfile(migrated_db, tmp_path / "mlflow.db")
    return tmp_path
