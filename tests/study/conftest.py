"""Fixtures of the study tests: an empty MLflow store made once per session and copied."""

from __future__ import annotations

import shutil
from pathlib import Path

import pytest


@pytest.fixture(scope="session")
def migrated_db(tmp_path_factory) -> Path:
    """An empty MLflow SQLite store (tables only), created once: MLflow's migrations of a fresh
    file take 5–10 s, which a test that is not about creating the store need not pay again."""
    from maglev.study.tracking import new_client

    path = tmp_path_factory.mktemp("migrated") / "mlflow.db"
    new_client(f"sqlite:///{path}")
    return path


@pytest.fixture
def migrated_store(tmp_path, migrated_db) -> Path:
    """``tmp_path`` holding a copy of the empty store as ``mlflow.db`` (what the harness's overrides use)."""
    shutil.copyfile(migrated_db, tmp_path / "mlflow.db")
    return tmp_path
