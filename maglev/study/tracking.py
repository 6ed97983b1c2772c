"""Everything MLflow on the writing side: the store, the experiment, logging a run, queries.

Written against MLflow 3.x (see ../shared/notes/hydra-mlflow.md): the local store is
SQLite with an absolute URI, created once under a file lock (two processes migrating a
fresh database at once crash); runs are created with ``MlflowClient`` rather than the
fluent API, so no "active run" leaks between jobs of a reused worker process; params,
metrics and tags go in one ``log_batch``; artifacts are written to a temporary folder
and uploaded in one ``log_artifacts``.  The run schema is documented in docs/tracking.md.
"""

from __future__ import annotations

import contextlib
import json
import math
import os
import socket
import subprocess
import tempfile
import time
import warnings
from functools import lru_cache
from pathlib import Path

warnings.filterwarnings("ignore", message="The .*noload.* loader strategy is deprecated")

import mlflow  # noqa: E402
from mlflow import MlflowClient  # noqa: E402
from mlflow.entities import Metric, Param, RunTag  # noqa: E402

from maglev.paths import project_root  # noqa: E402

PARENT_FILE = "parent_run_id"
PARENT_ENV = "MAGLEV_PARENT_RUN_ID"
SIZE_ENV = "MAGLEV_SWEEP_SIZE"  # number of jobs in the running sweep, for progress


# ---------------------------------------------------------------------------- store and experiment
def sqlite_path(uri: str) -> Path | None:
    """The database file of a ``sqlite:///`` URI (None for other stores)."""
    if not uri.startswith("sqlite:///"):
        return None
    return Path(uri[len("sqlite:///"):])


@contextlib.contextmanager
def store_lock(uri: str):
    """An exclusive lock beside a SQLite database (no-op for servers and without fcntl)."""
    db = sqlite_path(uri)
    if db is None:
        yield
        return
    db.parent.mkdir(parents=True, exist_ok=True)
    try:
        import fcntl
    except ImportError:  # Windows: rely on creating the store before workers start
        yield
        return
    with open(db.with_name(db.name + ".lock"), "w") as fh:
        fcntl.flock(fh, fcntl.LOCK_EX)
        try:
            yield
        finally:
            fcntl.flock(fh, fcntl.LOCK_UN)


def connect(tracking: dict) -> tuple[MlflowClient, str]:
    """Client and experiment id for the ``tracking`` config; creates the store/experiment if needed."""
    uri = tracking["uri"]
    db = sqlite_path(uri)
    if db is not None and not db.is_absolute():
        raise ValueError(f"tracking.uri must be an absolute sqlite path (sqlite:////abs/path.db), got {uri!r}")
    mlflow.set_tracking_uri(uri)
    client = MlflowClient(tracking_uri=uri)
    name = tracking["experiment"]
    with store_lock(uri):
        exp = client.get_experiment_by_name(name)
        if exp is None:
            location = None
            if tracking.get("artifact_location"):
                location = (Path(tracking["artifact_location"]) / name).resolve().as_uri()
            try:
                exp_id = client.create_experiment(name, artifact_location=location)
            except mlflow.exceptions.MlflowException:  # created meanwhile by another host
                exp_id = client.get_experiment_by_name(name).experiment_id
        else:
            exp_id = exp.experiment_id
    return client, exp_id


# ---------------------------------------------------------------------------- provenance
@lru_cache(maxsize=1)
def git_info() -> dict[str, str]:
    """Commit of the project checkout and whether tracked files are modified."""
    root = project_root()

    def git(*args: str) -> str:
        return subprocess.run(["git", "-C", root, *args], capture_output=True, text=True,
                              timeout=10).stdout.strip()

    try:
        commit = git("rev-parse", "HEAD") or "unknown"
        dirty = bool(git("status", "--porcelain", "--untracked-files=no"))
    except (OSError, subprocess.SubprocessError):
        commit, dirty = "unknown", False
    return {"git_commit": commit, "git_dirty": str(dirty).lower()}


def process_tags() -> dict[str, str]:
    return {"host": socket.gethostname(), "pid": str(os.getpid()), **git_info()}


# ---------------------------------------------------------------------------- queries
def finished_run(client: MlflowClient, exp_id: str, chash: str) -> str | None:
    """Id of a FINISHED run with this config hash, if any."""
    runs = client.search_runs(
        [exp_id], filter_string=f"tags.config_hash = '{chash}' and attributes.status = 'FINISHED'",
        max_results=1,
    )
    return runs[0].info.run_id if runs else None


def sweep_parent(sweep_dir: str | None) -> str | None:
    """The running sweep's parent run: from ``<sweep dir>/parent_run_id`` (written by the sweep
    callback, readable on a cluster), else ``$MAGLEV_PARENT_RUN_ID``; None outside a sweep."""
    if not sweep_dir:
        return None
    f = Path(sweep_dir) / PARENT_FILE
    text = f.read_text().strip() if f.is_file() else ""
    return text or os.environ.get(PARENT_ENV) or None


def children(client: MlflowClient, exp_id: str, parent_id: str) -> list:
    return client.search_runs([exp_id], filter_string=f"tags.`mlflow.parentRunId` = '{parent_id}'",
                              max_results=50000)


# ---------------------------------------------------------------------------- logging
def _finite(x: float) -> float:
    return x if math.isfinite(x) else (math.nan if math.isnan(x) else math.copysign(1e308, x))


def log_batch(client: MlflowClient, run_id: str, params: dict | None = None,
              metrics: dict | None = None, tags: dict | None = None) -> None:
    now = int(time.time() * 1000)
    client.log_batch(
        run_id,
        metrics=[Metric(k, _finite(float(v)), now, 0) for k, v in (metrics or {}).items()],
        params=[Param(k, str(v)) for k, v in (params or {}).items()],
        tags=[RunTag(k, str(v)) for k, v in (tags or {}).items()],
    )


def log_files(client: MlflowClient, run_id: str, files: dict) -> None:
    """Upload ``{artifact path: content}`` in one call; content is str, bytes (e.g. a PNG), dict (JSON) or a Path."""
    with tempfile.TemporaryDirectory(prefix="maglev-artifacts-") as tmp:
        for rel, content in files.items():
            path = Path(tmp) / rel
            path.parent.mkdir(parents=True, exist_ok=True)
            if isinstance(content, str):
                path.write_text(content)
            elif isinstance(content, bytes):
                path.write_bytes(content)
            elif isinstance(content, dict):
                path.write_text(json.dumps(content, indent=1, default=str))
            elif isinstance(content, Path):
                path.write_bytes(content.read_bytes())
            else:
                raise TypeError(f"log_files: {rel}: expected str, bytes, dict or Path, got {type(content).__name__}")
        client.log_artifacts(run_id, tmp)


def download_text(client: MlflowClient, run_id: str, path: str) -> str:
    with tempfile.TemporaryDirectory() as tmp:
        local = client.download_artifacts(run_id, path, tmp)
        return Path(local).read_text()
