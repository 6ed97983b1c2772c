"""Fixtures of the study tests: one ``mlflow server`` on 127.0.0.1 shared by the tests that need a server
(each in its own experiment); the empty store made once per session is in ``tests/conftest.py``."""

from __future__ import annotations

import contextlib
import os
import signal
import socket
import subprocess
import sys
import time
import urllib.request
from pathlib import Path

import pytest


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def start_server(home: Path) -> tuple[subprocess.Popen, str]:
    """`mlflow server` on a free 127.0.0.1 port, one worker, no job runner, in its own process group, its
    store in ``home``; returns the process and its address once it answers ``/health`` (≈ 10 s)."""
    port = free_port()
    env = {**os.environ, "MLFLOW_SERVER_ENABLE_JOB_EXECUTION": "false"}
    cmd = [sys.executable, "-m", "mlflow", "server", "--backend-store-uri", f"sqlite:///{home}/server.db",
           "--artifacts-destination", str(home / "server-artifacts"), "--host", "127.0.0.1",
           "--port", str(port), "--workers", "1"]
    with open(home / "server.log", "w") as log:
        proc = subprocess.Popen(cmd, stdout=log, stderr=subprocess.STDOUT, env=env, cwd=home,
                                start_new_session=True)
    base = f"http://127.0.0.1:{port}"
    deadline = time.monotonic() + 120
    while True:
        try:
            with urllib.request.urlopen(f"{base}/health", timeout=2) as r:
                if r.status == 200:
                    return proc, base
        except OSError:
            pass
        if proc.poll() is not None or time.monotonic() > deadline:
            stop_server(proc)
            pytest.fail(f"mlflow server did not start: {(home / 'server.log').read_text()[-3000:]}")
        time.sleep(0.5)


def stop_server(proc: subprocess.Popen, sig: int = signal.SIGTERM) -> None:
    """End the server's whole process group (uvicorn workers), SIGKILL if SIGTERM is not enough."""
    try:
        os.killpg(proc.pid, sig)
        proc.wait(timeout=20)
    except (ProcessLookupError, subprocess.TimeoutExpired):
        with contextlib.suppress(ProcessLookupError):
            os.killpg(proc.pid, signal.SIGKILL)
        proc.wait(timeout=10)


@pytest.fixture(scope="session")
def mlflow_server(tmp_path_factory):
    """`mlflow server` on a free 127.0.0.1 port, one worker, no job runner, started once (≈ 10 s);
    always killed.  Tests keep apart by experiment name (``tracking.experiment``)."""
    proc, base = start_server(tmp_path_factory.mktemp("server"))
    try:
        yield base
    finally:
        stop_server(proc)
