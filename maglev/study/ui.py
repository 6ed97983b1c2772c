"""``maglev ui``: the MLflow UI on the project's store, started lightly, opened on the latest sweep.

``mlflow ui`` as documented starts four web workers and seven job processes (≈ 3 GB,
≈ 80 s to answer on two cores); the job runner only serves MLflow's GenAI features.
Here the server runs with one worker, without job execution, bound to 127.0.0.1 (no
authentication: never bind a shared address without protection, see the README), and
the URL printed opens the experiment's runs on the latest sweep's parent.
"""

from __future__ import annotations

import os
import subprocess
import sys
import time
import urllib.request

HEALTH_TIMEOUT_S = 120.0


def server_command(uri: str, host: str, port: int) -> list[str]:
    return [sys.executable, "-m", "mlflow", "server", "--backend-store-uri", uri, "--host", host,
            "--port", str(port), "--workers", "1"]


def wait_healthy(base: str, proc: subprocess.Popen | None = None, timeout: float = HEALTH_TIMEOUT_S) -> bool:
    """Poll ``base/health`` until it answers 200 (False on timeout or when ``proc`` exits first)."""
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        if proc is not None and proc.poll() is not None:
            return False
        try:
            with urllib.request.urlopen(f"{base}/health", timeout=2) as r:
                if r.status == 200:
                    return True
        except OSError:
            pass
        time.sleep(0.5)
    return False


def landing_url(base: str, uri: str, experiment: str) -> str:
    """The experiment's runs page, on the latest sweep's parent run when there is one."""
    from maglev.study.store import SweepError, find_parent, open_store

    try:
        client, exp_id = open_store(uri, experiment)
    except SweepError:
        return base
    try:
        return f"{base}/#/experiments/{exp_id}/runs/{find_parent(client, exp_id).info.run_id}"
    except SweepError:
        return f"{base}/#/experiments/{exp_id}"


def serve(uri: str, experiment: str, host: str = "127.0.0.1", port: int = 5000) -> int:
    """Print the UI's URL for a tracking server; start one (and wait for Ctrl-C) for a local store."""
    if uri.startswith(("http://", "https://")):
        print(f"MLflow UI: {landing_url(uri.rstrip('/'), uri, experiment)}")
        return 0
    base = f"http://{host}:{port}"
    env = {**os.environ, "MLFLOW_SERVER_ENABLE_JOB_EXECUTION": "false"}
    proc = subprocess.Popen(server_command(uri, host, port), env=env)
    try:
        if not wait_healthy(base, proc):
            proc.terminate()
            print(f"maglev ui: the MLflow server on {base} did not start (exit {proc.poll()})", file=sys.stderr)
            return 2
        print(f"MLflow UI: {landing_url(base, uri, experiment)}   (Ctrl-C stops it)", flush=True)
        return proc.wait()
    except KeyboardInterrupt:
        proc.terminate()
        proc.wait(timeout=20)
        return 0
