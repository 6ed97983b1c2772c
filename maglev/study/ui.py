"""``maglev ui``: the MLflow UI on the project's store, started lightly, opened on the latest sweep's runs.

``mlflow ui`` as documented starts four web workers and seven job processes (≈ 3 GB,
≈ 80 s to answer on two cores); the job runner only serves MLflow's GenAI features.
Here the server runs with one worker, without job execution, bound to 127.0.0.1 (no
authentication: never bind a shared address without protection, see docs/study.md, "Server security").

The URL printed opens the runs table in "model training" mode (the query parameter
``workflowType=machine_learning``: MLflow 3.17 ignores the experiment's
``mlflow.experimentKind`` tag) with a shared view (``viewStateShareKey``, an experiment
tag ``mlflow.sharedViewState.<key>``): the latest sweep's runs, the ``key.*`` metrics as
the first columns, sorted by ``val_fit``.
"""

from __future__ import annotations

import os
import re
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


def sweep_share_key(name: str) -> str:
    """The shared-view key of a sweep's runs (URL- and tag-safe)."""
    return "sweep-" + re.sub(r"[^A-Za-z0-9_-]", "_", name)


def landing_url(base: str, uri: str, experiment: str) -> str:
    """The experiment's runs table in model-training mode, showing the latest sweep's runs when there is one
    (its shared view is written to the experiment here)."""
    from maglev.study.store import SweepError, find_parent, open_store
    from maglev.study.tracking import SHARE_KEY, UI_PARAMS, experiment_url, shared_view, tag_experiment

    try:
        client, exp_id = open_store(uri, experiment)
    except SweepError:
        return f"{base}/#/?{UI_PARAMS}"
    views = {SHARE_KEY: shared_view()}
    try:
        parent = find_parent(client, exp_id)
    except SweepError:
        parent = None
    key = SHARE_KEY
    if parent is not None:
        name = parent.data.tags.get("sweep") or parent.info.run_name
        key = sweep_share_key(name)
        views[key] = shared_view("tags.sweep = '{}'".format(name.replace("'", "\\'")))
    tag_experiment(client, exp_id, share=views)
    return experiment_url(base, exp_id, key)


def serve(uri: str, experiment: str, host: str = "127.0.0.1", port: int = 5000) -> int:
    """Print the UI's URL for a tracking server; start one (and wait for Ctrl-C) for a local store."""
    if uri.startswith(("http://", "https://")):
        print(f"MLflow UI: {landing_url(uri.rstrip('/'), uri, experiment)}")
        return 0
    from maglev.study.tracking import sqlite_path

    db = sqlite_path(uri)
    if db is not None and not db.is_file():  # the server would create (and migrate) it unlocked
        print(f"maglev ui: no MLflow store at {db}; run a sweep first (python study.py -m +sweep=lab) "
              "or pass --tracking-uri", file=sys.stderr)
        return 2
    base = f"http://{host}:{port}"
    env = {**os.environ, "MLFLOW_SERVER_ENABLE_JOB_EXECUTION": "false"}
    proc = subprocess.Popen(server_command(uri, host, port), env=env, stdout=2)  # stdout: only the URL
    try:
        url = landing_url(base, uri, experiment)  # while the server starts
        if not wait_healthy(base, proc):
            why = (f"exited with status {proc.poll()}" if proc.poll() is not None
                   else f"did not answer within {HEALTH_TIMEOUT_S:g} s")
            print(f"maglev ui: the MLflow server on {base} {why}", file=sys.stderr)
            return 2
        print(f"MLflow UI: {url}   (Ctrl-C stops it)", flush=True)
        while proc.poll() is None:  # not proc.wait(): a Ctrl-C the kernel hands to another thread (MLflow's
            time.sleep(0.2)         # telemetry) leaves a blocking waitpid in the main thread uninterrupted
        return proc.returncode
    except KeyboardInterrupt:
        return 0
    finally:
        if proc.poll() is None:
            proc.terminate()
            proc.wait(timeout=20)
