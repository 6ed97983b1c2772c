"""The cluster harness's fixture: Slurm, PostgreSQL and the MLflow server, started once for the module and
always stopped.  Collected only with ``MAGLEV_CLUSTER=1`` (tests/conftest.py); skips with one line where
a service cannot be installed or started."""

from __future__ import annotations

import json
import os
import subprocess
import sys
import time
from dataclasses import dataclass
from pathlib import Path

import pytest

from tests.cluster import services

REPO = Path(__file__).resolve().parents[2]
TINY = ["dataset.duration_s=4", "dataset.preprocess.trim=500"]  # 3500 samples: a job of a few seconds


@dataclass
class Cluster:
    slurm: services.Slurm
    pg: services.Postgres
    server: services.Server
    users: dict[str, tuple[str, str]]

    def env(self, user: str) -> dict[str, str]:
        """A user's shell on the login node: Slurm's config, the server's address and the user's
        credentials in MLflow's variables, this checkout importable by the jobs."""
        env = {k: v for k, v in os.environ.items() if not k.startswith(("MLFLOW_", "MAGLEV_"))}
        name, password = self.users[user]
        env.update(self.slurm.env, MLFLOW_TRACKING_URI=self.server.url, MLFLOW_TRACKING_USERNAME=name,
                   MLFLOW_TRACKING_PASSWORD=password,
                   PYTHONPATH=os.pathsep.join(p for p in (str(REPO), os.environ.get("PYTHONPATH", "")) if p))
        return env

    def command(self, work: Path, name: str, *overrides: str, rank: bool = True) -> list[str]:
        """``python study.py -m hydra/launcher=slurm tracking=cluster …``: the documented command, its
        outputs under ``work``."""
        return [sys.executable, str(REPO / "study.py"), "-m", "hydra/launcher=slurm", "tracking=cluster",
                f"hydra.launcher.partition={self.slurm.partition}", f"study.name={name}", *overrides,
                f"hydra.sweep.dir={work}/multirun",
                f"hydra.callbacks.maglev_rank.report_dir={work}/reports" if rank else "~hydra.callbacks.maglev_rank"]

    def start(self, user: str, work: Path, name: str, *overrides: str, rank: bool = True,
              env: dict | None = None) -> subprocess.Popen:
        work.mkdir(parents=True, exist_ok=True)
        return subprocess.Popen(self.command(work, name, *overrides, rank=rank), cwd=work, text=True,
                                stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                                env={**self.env(user), **(env or {})}, start_new_session=True)

    def sweep(self, user: str, work: Path, name: str, *overrides: str, rank: bool = True,
              timeout: float = 900, env: dict | None = None) -> subprocess.CompletedProcess:
        proc = self.start(user, work, name, *overrides, rank=rank, env=env)
        return finish(proc, timeout)

    # ---------------------------------------------------------------- reading the server as the UI does
    def rest(self, endpoint: str, body: dict | None = None) -> dict:
        return self.server.rest(endpoint, body)

    def experiment(self, name: str) -> str:
        return self.rest(f"experiments/get-by-name?experiment_name={name}")["experiment"]["experiment_id"]

    def runs(self, experiment: str, filter: str = "") -> list[dict]:
        out, token = [], None
        while True:
            body = {"experiment_ids": [self.experiment(experiment)], "filter": filter, "max_results": 1000}
            page = self.rest("runs/search", {**body, **({"page_token": token} if token else {})})
            out += page.get("runs", [])
            token = page.get("next_page_token")
            if not token:
                return out

    def wait_running(self, experiment: str, timeout: float = 300) -> dict:
        """The first model run seen RUNNING in ``experiment`` (polled every 0.3 s)."""
        end = time.monotonic() + timeout
        while time.monotonic() < end:
            try:
                running = self.runs(experiment, "tags.kind = 'model' and attributes.status = 'RUNNING'")
            except Exception:  # noqa: BLE001 — the experiment does not exist yet
                running = []
            if running:
                return running[0]
            time.sleep(0.3)
        raise AssertionError(f"no run of {experiment} RUNNING within {timeout} s")


def finish(proc: subprocess.Popen, timeout: float) -> subprocess.CompletedProcess:
    try:
        out, err = proc.communicate(timeout=timeout)
    except subprocess.TimeoutExpired:
        os.killpg(proc.pid, 15)
        out, err = proc.communicate(timeout=60)
        raise AssertionError(f"the sweep did not end within {timeout} s: {err[-3000:]}") from None
    return subprocess.CompletedProcess(proc.args, proc.returncode, out, err)


def tags(run: dict) -> dict[str, str]:
    return {t["key"]: t["value"] for t in run["data"].get("tags", [])}


def metrics(run: dict) -> dict[str, float]:
    return {m["key"]: m["value"] for m in run["data"].get("metrics", [])}


@pytest.fixture(scope="session")
def cluster():
    pytest.importorskip("hydra_plugins.hydra_submitit_launcher",
                        reason="hydra-submitit-launcher is not installed (pip install -e .[cluster])")
    pytest.importorskip("psycopg", reason="psycopg is not installed (pip install -e .[cluster])")
    pytest.importorskip("flask_wtf", reason="MLflow's basic auth needs Flask-WTF (pip install -e .[cluster])")
    started: list = []
    try:
        started.append(services.start_slurm())
        started.append(services.start_postgres())
        started.append(services.start_server(started[1]))
    except services.Unavailable as exc:
        for service in reversed(started):
            service.stop()  # the server's start failed: start_server removed its own
        pytest.skip(f"cluster harness: {exc}")
    slurm, pg, server = started
    try:
        users = {u: server.add_user(u) for u in ("alice", "bob")}
        yield Cluster(slurm, pg, server, users)
    finally:
        try:
            subprocess.run(["scancel", "--partition", slurm.partition], env={**os.environ, **slurm.env},
                           capture_output=True, timeout=60)
        finally:
            server.close()
            pg.stop()
            slurm.stop()
        alive = [p.pid for p in slurm.procs if p.poll() is None]
        assert not alive, f"daemons still running: {alive}"


def dump(proc: subprocess.CompletedProcess) -> str:
    return json.dumps({"rc": proc.returncode, "stderr": proc.stderr[-4000:]}, indent=1)
