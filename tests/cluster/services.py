"""The daemons of a one-machine cluster, each started in a throw-away directory on 127.0.0.1 and always
stopped: munge and Slurm (slurmctld + slurmd, one partition of 2 CPUs), PostgreSQL (initdb + pg_ctl) and an
MLflow tracking server on it with basic auth.

Each ``start_*`` returns a handle whose ``stop()`` ends what it started (by pid or process group, never by
name); a start that cannot succeed raises :class:`Unavailable` with a one-line reason the tests skip with.
"""

from __future__ import annotations

import os
import pwd
import secrets
import shutil
import signal
import socket
import subprocess
import sys
import tempfile
import time
import urllib.error
import urllib.request
from base64 import b64encode
from dataclasses import dataclass, field
from pathlib import Path


class Unavailable(RuntimeError):
    """A service cannot be installed or started here (the reason is one line)."""


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def wait_for(what: str, ready, timeout: float, log: Path | None = None, proc: subprocess.Popen | None = None) -> None:
    """Poll ``ready()`` until true; :class:`Unavailable` naming ``what`` (and the log's tail) after ``timeout``."""
    end = time.monotonic() + timeout
    while not ready():
        if (proc is not None and proc.poll() is not None) or time.monotonic() > end:
            lines = log.read_text(errors="replace").strip().splitlines() if log and log.exists() else []
            errors = [line for line in lines if "Error" in line or "Exception" in line] or lines
            how = "exited" if proc is not None and proc.poll() is not None else f"not up within {timeout:.0f} s"
            raise Unavailable(f"{what} {how}: {errors[-1] if errors else 'no log'}")
        time.sleep(0.3)


def _run(cmd: list[str], what: str, **kw) -> subprocess.CompletedProcess:
    proc = subprocess.run(cmd, capture_output=True, text=True, timeout=120, **kw)
    if proc.returncode:
        raise Unavailable(f"{what} failed ({proc.returncode}): {(proc.stderr or proc.stdout).strip()[-300:]}")
    return proc


def _stop_group(proc: subprocess.Popen, grace: float = 20) -> None:
    """SIGTERM to the process group ``proc`` leads (started with ``start_new_session``), then SIGKILL."""
    if proc.poll() is not None:
        return
    try:
        os.killpg(proc.pid, signal.SIGTERM)
        proc.wait(timeout=grace)
    except ProcessLookupError:
        pass
    except subprocess.TimeoutExpired:
        os.killpg(proc.pid, signal.SIGKILL)
        proc.wait(timeout=10)


# ---------------------------------------------------------------------------- munge + Slurm
@dataclass
class Slurm:
    """A single-node Slurm cluster: ``env`` holds ``SLURM_CONF`` for sbatch/squeue/scancel and submitit."""

    home: Path
    env: dict[str, str]
    partition: str
    procs: list[subprocess.Popen] = field(default_factory=list)

    def run(self, *cmd: str) -> str:
        return _run(list(cmd), cmd[0], env={**os.environ, **self.env}).stdout

    def queue(self) -> list[str]:
        """Job ids (``<array>_<task>`` for array tasks) Slurm still lists, pending or running."""
        return self.run("squeue", "-h", "-o", "%i").split()

    def wait_empty(self, timeout: float) -> None:
        wait_for("an empty Slurm queue", lambda: not self.queue(), timeout)

    def stop(self) -> None:
        for proc in reversed(self.procs):
            _stop_group(proc)
        shutil.rmtree(self.home, ignore_errors=True)


def start_slurm(cpus: int = 2) -> Slurm:
    """munged, slurmctld and slurmd on 127.0.0.1 in a temporary directory; one partition ``maglev`` of
    ``cpus`` CPUs on this host.  Daemons run in the foreground (``-D``) as our children, so ``stop`` ends
    exactly them."""
    for tool in ("munged", "slurmctld", "slurmd", "sbatch", "squeue", "scancel"):
        if shutil.which(tool) is None:
            raise Unavailable(f"{tool} not found (apt-get install slurm-wlm munge)")
    if os.geteuid() != 0:
        raise Unavailable("a Slurm cluster of one node needs root here (slurmd starts jobs as their user)")
    home = Path(tempfile.mkdtemp(prefix="maglev-slurm-"))
    os.chmod(home, 0o755)  # munged wants the socket's directory searchable by everyone
    slurm = Slurm(home, {}, "maglev")
    try:
        key = home / "munge.key"
        key.write_bytes(secrets.token_bytes(1024))
        key.chmod(0o400)
        sock = home / "munge.sock"
        munged = subprocess.Popen(["munged", "--foreground", "--force", f"--key-file={key}", f"--socket={sock}",
                                   f"--pid-file={home}/munged.pid", f"--log-file={home}/munged.log",
                                   f"--seed-file={home}/munged.seed"],
                                  stdout=subprocess.DEVNULL, stderr=subprocess.STDOUT, start_new_session=True)
        slurm.procs.append(munged)
        wait_for("munged", sock.exists, 30, home / "munged.log", munged)
        host = socket.gethostname().split(".")[0]
        memory_mb = os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES") // 2**20 - 512  # what slurmd finds
        for d in ("state", "spool"):
            (home / d).mkdir()
        conf = home / "slurm.conf"
        conf.write_text("\n".join([
            "ClusterName=maglevtest", f"SlurmctldHost={host}(127.0.0.1)",
            f"SlurmctldPort={free_port()}", f"SlurmdPort={free_port()}", "SlurmUser=root", "SlurmdUser=root",
            "AuthType=auth/munge", "CredType=cred/munge", f"AuthInfo=socket={sock}",
            f"StateSaveLocation={home}/state", f"SlurmdSpoolDir={home}/spool",
            f"SlurmctldPidFile={home}/slurmctld.pid", f"SlurmdPidFile={home}/slurmd.pid",
            f"SlurmctldLogFile={home}/slurmctld.log", f"SlurmdLogFile={home}/slurmd.log",
            "ProctrackType=proctrack/linuxproc", "TaskPlugin=task/none",
            "SelectType=select/cons_tres", "SelectTypeParameters=CR_CPU", "SchedulerType=sched/builtin",
            "JobAcctGatherType=jobacct_gather/none", "AccountingStorageType=accounting_storage/none",
            "JobCompType=jobcomp/none", "MpiDefault=none", "ReturnToService=2",
            "KillWait=30", "InactiveLimit=0", "MinJobAge=600", "OverTimeLimit=0",
            "SchedulerParameters=sched_interval=1",
            f"NodeName={host} NodeAddr=127.0.0.1 CPUs={cpus} RealMemory={memory_mb} State=UNKNOWN",
            f"PartitionName={slurm.partition} Nodes={host} Default=YES MaxTime=INFINITE State=UP", ""]))
        slurm.env = {"SLURM_CONF": str(conf)}
        env = {**os.environ, **slurm.env}
        for daemon in (["slurmctld", "-D", "-i"], ["slurmd", "-D", "-N", host]):
            log = home / f"{daemon[0]}.log"
            slurm.procs.append(subprocess.Popen([*daemon, "-f", str(conf)], env=env, stdout=subprocess.DEVNULL,
                                                stderr=subprocess.STDOUT, start_new_session=True))

            def up(name=daemon[0]) -> bool:
                out = subprocess.run(["sinfo", "-h", "-o", "%t"], env=env, capture_output=True, text=True)
                return out.returncode == 0 and (name == "slurmctld" or out.stdout.strip() == "idle")

            wait_for(daemon[0], up, 60, log, slurm.procs[-1])
        return slurm
    except BaseException:
        slurm.stop()
        raise


# ---------------------------------------------------------------------------- PostgreSQL
@dataclass
class Postgres:
    """A throw-away PostgreSQL cluster on 127.0.0.1:``port``; ``password`` is the role ``mlflow``'s."""

    home: Path
    port: int
    password: str
    user: str | None

    def uri(self, db: str) -> str:
        """SQLAlchemy URI without the password (libpq reads it from ``PGPASSWORD``)."""
        return f"postgresql+psycopg://mlflow@127.0.0.1:{self.port}/{db}"

    def stop(self) -> None:
        subprocess.run(["pg_ctl", "stop", "-D", str(self.home / "data"), "-m", "fast", "-w"],
                       capture_output=True, timeout=60, **self._as_owner())
        shutil.rmtree(self.home, ignore_errors=True)

    def _as_owner(self) -> dict:
        return {"user": self.user} if self.user else {}


def start_postgres(databases: tuple[str, ...] = ("mlflow", "mlflow_auth")) -> Postgres:
    """initdb in a temporary directory, password authentication on 127.0.0.1 only, an unused port; the role
    ``mlflow`` owns ``databases``.  As root, the server runs as the ``postgres`` user (it refuses root)."""
    for tool in ("initdb", "pg_ctl", "createdb"):
        if shutil.which(tool) is None:
            raise Unavailable(f"{tool} not found (PostgreSQL's server binaries)")
    user = None
    if os.geteuid() == 0:
        try:
            user = pwd.getpwnam("postgres").pw_name
        except KeyError:
            raise Unavailable("running as root and there is no 'postgres' user to run PostgreSQL as") from None
    home = Path(tempfile.mkdtemp(prefix="maglev-pg-"))
    pg = Postgres(home, free_port(), secrets.token_hex(12), user)
    owner = pg._as_owner()
    try:
        if user:
            shutil.chown(home, user)
        pwfile = home / "pw"
        pwfile.write_text(pg.password + "\n")
        if user:
            shutil.chown(pwfile, user)
        _run(["initdb", "-D", str(home / "data"), "-U", "mlflow", f"--pwfile={pwfile}", "--auth=scram-sha-256",
              "-E", "UTF8", "--locale=C"], "initdb", **owner)
        pwfile.unlink()
        opts = f"-c listen_addresses=127.0.0.1 -p {pg.port} -k {home}"
        _run(["pg_ctl", "start", "-D", str(home / "data"), "-o", opts, "-l", str(home / "postgres.log"), "-w",
              "-t", "60"], "pg_ctl start", **owner)
        env = {**os.environ, "PGPASSWORD": pg.password}
        for db in databases:
            _run(["createdb", "-h", "127.0.0.1", "-p", str(pg.port), "-U", "mlflow", db], "createdb", env=env)
        return pg
    except BaseException:
        pg.stop()
        raise


# ---------------------------------------------------------------------------- MLflow server with basic auth
@dataclass
class Server:
    """``mlflow server`` on PostgreSQL with basic auth; artifacts proxied into ``home/artifacts``."""

    home: Path
    port: int
    cmd: list[str]
    env: dict[str, str]
    admin: tuple[str, str]
    proc: subprocess.Popen | None = None

    @property
    def url(self) -> str:
        return f"http://127.0.0.1:{self.port}"

    def start(self, timeout: float = 180) -> None:
        log = open(self.home / "server.log", "a")
        self.proc = subprocess.Popen(self.cmd, stdout=log, stderr=subprocess.STDOUT, env=self.env, cwd=self.home,
                                     start_new_session=True)
        log.close()
        wait_for("mlflow server", self.healthy, timeout, self.home / "server.log", self.proc)

    def healthy(self) -> bool:
        try:
            with urllib.request.urlopen(f"{self.url}/health", timeout=2) as r:
                return r.status == 200
        except OSError:
            return False

    def stop(self) -> None:
        if self.proc is not None:
            _stop_group(self.proc)
            self.proc = None

    def close(self) -> None:
        self.stop()
        shutil.rmtree(self.home, ignore_errors=True)

    def rest(self, endpoint: str, body: dict | None = None, auth: tuple[str, str] | None = None) -> dict:
        """One call of the REST API (``/api/2.0/mlflow/<endpoint>``) as ``auth`` (default: the admin)."""
        import json

        user, password = auth or self.admin
        data = None if body is None else json.dumps(body).encode()
        token = b64encode(f"{user}:{password}".encode()).decode()
        req = urllib.request.Request(f"{self.url}/api/2.0/mlflow/{endpoint}", data=data,
                                     headers={"Content-Type": "application/json", "Authorization": f"Basic {token}"})
        with urllib.request.urlopen(req, timeout=60) as resp:
            return json.loads(resp.read() or b"{}")

    def add_user(self, name: str) -> tuple[str, str]:
        password = secrets.token_hex(12)
        self.rest("users/create", {"username": name, "password": password})
        return name, password


# How long each server worker trusts a verified user:password (MLflow's ``auth_cache_ttl_seconds``, off
# by default).  Without it every request pays the password hash check, by design tens of milliseconds of
# server CPU, and every run makes tens of requests.  The price: a worker that did not handle a password
# change or a user's deletion accepts the old credential for up to this long (docs/cluster.md).
AUTH_CACHE_TTL_S = 300


def start_server(pg: Postgres, workers: int = 2, auth_cache_ttl_s: int = AUTH_CACHE_TTL_S) -> Server:
    """The recipe of docs/cluster.md: backend store and auth database on PostgreSQL (password from
    ``PGPASSWORD``, not in a URI), artifacts served by the server, basic auth with every user allowed to
    edit (a shared study) and verified credentials cached per worker (``auth_cache_ttl_s``, 0: none), one
    admin whose password is random."""
    home = Path(tempfile.mkdtemp(prefix="maglev-mlflow-"))
    admin = ("maglev-admin", secrets.token_hex(12))
    ini = home / "auth.ini"
    ini.write_text("[mlflow]\ndefault_permission = EDIT\n"
                   f"database_uri = {pg.uri('mlflow_auth')}\n"
                   f"admin_username = {admin[0]}\nadmin_password = {admin[1]}\nauthorization_function = "
                   "mlflow.server.auth:authenticate_request_basic_auth\n"
                   f"auth_cache_ttl_seconds = {auth_cache_ttl_s}\n")
    port = free_port()
    env = {**os.environ, "PGPASSWORD": pg.password, "MLFLOW_AUTH_CONFIG_PATH": str(ini),
           "MLFLOW_FLASK_SERVER_SECRET_KEY": secrets.token_hex(16), "MLFLOW_SERVER_ENABLE_JOB_EXECUTION": "false"}
    cmd = [sys.executable, "-m", "mlflow", "server", "--app-name", "basic-auth",
           "--backend-store-uri", pg.uri("mlflow"), "--artifacts-destination", str(home / "artifacts"),
           "--host", "127.0.0.1", "--port", str(port), "--workers", str(workers)]
    server = Server(home, port, cmd, env, admin)
    try:
        server.start()
        return server
    except BaseException:
        server.close()
        raise


def http_error_text(exc: urllib.error.HTTPError) -> str:
    return f"HTTP {exc.code}: {exc.read()[:300]!r}"
