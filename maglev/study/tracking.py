"""Everything MLflow on the writing side: the store, the experiment, logging a run, queries.

Written against MLflow 3.x (see ../shared/notes/hydra-mlflow.md): the local store is
SQLite with an absolute URI, created under a file lock — constructing the first
``MlflowClient`` of a process creates and migrates the database, and two processes
migrating a fresh database at once destroy it.  A tracking server is checked once
(``GET /health``) before anything else, and MLflow's HTTP retries are bounded
(``tracking.max_retries``, ``tracking.timeout_s``): MLflow's defaults retry a dead server
for about 4 minutes per call.  An unreachable server ends the sweep at once with one line
naming the URI (:class:`TrackingUnreachable`).  Which launch runs a sweep and which job runs a
config is decided in :mod:`maglev.study.claims`.  Runs are created with ``MlflowClient`` rather than the
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
from collections.abc import Callable
from functools import lru_cache
from pathlib import Path

warnings.filterwarnings("ignore", message="The .*noload.* loader strategy is deprecated")

import mlflow  # noqa: E402
from mlflow import MlflowClient  # noqa: E402
from mlflow.entities import Metric, Param, RunTag  # noqa: E402

from maglev.locks import exclusive  # noqa: E402
from maglev.study.credentials import public, to_env  # noqa: E402
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


def store_lock(uri: str) -> contextlib.AbstractContextManager:
    """An exclusive lock beside a SQLite database (no-op for servers and without fcntl)."""
    db = sqlite_path(uri)
    if db is None:
        return contextlib.nullcontext()
    return exclusive(db.with_name(db.name + ".lock"))


class TrackingUnreachable(SystemExit):
    """The tracking store cannot be reached: the sweep stops with this one line (exit status 1).

    A ``SystemExit``, not an ``Exception``: Hydra's launchers and callbacks catch every
    ``Exception`` and go on with the next job, and each job would then wait out its own
    retries against the dead server before failing in turn.
    """

    def __init__(self, uri: str, why: str) -> None:
        global unreachable
        unreachable = uri = public(uri)
        self.uri, self.why = uri, why
        super().__init__(f"maglev: the MLflow tracking server {uri} cannot be reached ({why}); start it, "
                         "or fix tracking.uri")

    def __reduce__(self):
        """Rebuilt from its URI and reason: raised in the figure renderer's process, it reaches the launcher
        as itself (and marks the server unreachable there too), not as a pool that cannot read its answer."""
        return type(self), (self.uri, self.why)


# the URI of a server this process found unreachable (the cleanup at exit then writes nothing: every call
# would wait out its retries against a dead server)
unreachable: str | None = None


# bounded HTTP retries when the config says nothing (CLI commands): ≈ 2 s on a refused port
HTTP_DEFAULTS = {"max_retries": 2, "timeout_s": 10}


def is_http(uri: str) -> bool:
    return uri.startswith(("http://", "https://"))


def http_env(max_retries: int, timeout_s: int) -> dict[str, str]:
    """MLflow's variables bounding its HTTP retries: ``max_retries`` retries (urllib3 waits 0, 2, 4 … s between
    attempts) and ``timeout_s`` per attempt (MLflow takes whole seconds, at most 10 retries)."""
    return {"MLFLOW_HTTP_REQUEST_MAX_RETRIES": str(int(max_retries)), "MLFLOW_HTTP_REQUEST_BACKOFF_FACTOR": "1",
            "MLFLOW_HTTP_REQUEST_TIMEOUT": str(int(timeout_s)),
            "MLFLOW_SUPPRESS_PRINTING_URL_TO_STDOUT": "true"}  # else every run's end prints two URLs


def tracking_env(tracking: dict) -> dict[str, str]:
    """The HTTP bounds of a ``tracking`` config, for a process the study starts (the figure renderer): it
    must have them before its first MLflow call, or it retries a dead server with MLflow's defaults (7
    retries of 120 s each: a sweep whose server died exited after 998 s, waiting for its renderer)."""
    return http_env(tracking.get("max_retries", HTTP_DEFAULTS["max_retries"]),
                    tracking.get("timeout_s", HTTP_DEFAULTS["timeout_s"]))


def http_settings(max_retries: int, timeout_s: int, override: bool = True) -> None:
    """Bound MLflow's HTTP retries in this process (it reads these variables on every request; processes
    started later inherit them).  ``override=False`` keeps values the user set."""
    for key, value in http_env(max_retries, timeout_s).items():
        if override:
            os.environ[key] = value
        else:
            os.environ.setdefault(key, value)


def check_reachable(uri: str, timeout_s: float, retries: int = 0) -> None:
    """``GET <uri>/health`` until it answers 200, at most ``1 + retries`` times, waiting 0, 2, 4 … s between
    as MLflow's own retries do (so a job that starts while the server restarts waits for it, within the
    same bound as every other call); :class:`TrackingUnreachable` after the last."""
    import requests

    for attempt in range(retries + 1):
        if attempt > 1:
            time.sleep(2 ** (attempt - 1))
        try:
            answer = requests.get(uri.rstrip("/") + "/health", timeout=timeout_s)
        except requests.RequestException as exc:
            reason = exc.__context__ or exc.__cause__ or exc
            why = f"{type(exc).__name__}: {_short(reason)}"
            continue
        if answer.status_code == 200:
            return
        why = f"/health answered HTTP {answer.status_code}"
    raise TrackingUnreachable(uri, why)


def raise_if_unreachable(uri: str) -> None:
    """After a store call failed: :class:`TrackingUnreachable` when ``uri`` is a server that does not answer
    ``/health`` (one try, within this process's MLflow HTTP timeout), so that a server that died in the middle
    of a sweep ends it with its one line wherever a call first failed; nothing otherwise (the caller raises
    its own error)."""
    if is_http(uri):
        check_reachable(uri, float(os.environ.get("MLFLOW_HTTP_REQUEST_TIMEOUT", HTTP_DEFAULTS["timeout_s"])))


def _short(exc: BaseException) -> str:
    """The last clause of a connection error (urllib3 nests the reason several levels deep)."""
    text = str(exc).replace("\n", " ")
    return text.rsplit(": ", 1)[-1].strip(" )\"'")[:200] or type(exc).__name__


class StoreProblem(RuntimeError):
    """A SQLite store that cannot be used — damaged, read-only, or not creatable — in one line saying what to do."""


_checked: set[Path] = set()  # stores this process has checked (PRAGMA quick_check reads the whole file)


def check_store(db: Path, write: bool = True) -> None:
    """An existing SQLite store must pass ``PRAGMA quick_check`` (a truncated or overwritten file fails it;
    MLflow itself noticed 8 KB of garbage inside nowhere) and, for ``write``, be writable with its folder
    (SQLite writes a journal beside it).  Once per process and file; :class:`StoreProblem` otherwise."""
    import sqlite3

    if not db.is_file() or db in _checked:
        return
    aside = f"move it aside (mv {db} {db}.damaged) and restore a backup, or pass another tracking.uri"
    try:
        con = sqlite3.connect(f"file:{db}?mode=ro", uri=True)
        try:
            found = [row[0] for row in con.execute("PRAGMA quick_check(3)")]
            tables = {row[0] for row in con.execute("SELECT name FROM sqlite_master WHERE type = 'table'")}
        finally:
            con.close()
    except sqlite3.DatabaseError as exc:
        raise StoreProblem(f"the MLflow store {db} is damaged ({exc}); {aside}") from None
    if found != ["ok"]:
        said = "; ".join(line.strip() for text in found for line in text.splitlines() if not line.startswith("***"))
        raise StoreProblem(f"the MLflow store {db} is damaged (PRAGMA quick_check: {said[:160]}); {aside}")
    if tables and "runs" not in tables and not any(t.startswith("_alembic_tmp_") for t in tables):
        raise StoreProblem(f"{db} is an SQLite file but not an MLflow store (no runs table); pass another "
                           "tracking.uri")
    if write and not (os.access(db, os.W_OK) and os.access(db.parent, os.W_OK)):
        raise StoreProblem(f"the MLflow store {db} is read-only (the file or its folder {db.parent}); make both "
                           "writable, or copy the store elsewhere and pass its tracking.uri")
    _checked.add(db)


def _first_line(exc: BaseException) -> str:
    return f"{type(exc).__name__}: {(str(exc).splitlines() or [''])[0][:200]}"


def _forget_engine(uri: str) -> None:
    """Drop MLflow's cached SQLAlchemy engine of ``uri`` (``SqlAlchemyStore._engine_map``, MLflow 3.x): its
    pooled connections would go on reading a file that was replaced or moved aside."""
    from mlflow.store.tracking.sqlalchemy_store import SqlAlchemyStore

    engine = getattr(SqlAlchemyStore, "_engine_map", {}).pop(uri, None)
    if engine is not None:
        engine.dispose()


def _create_store(db: Path) -> None:
    """Create a new SQLite store atomically: in a file beside it, renamed into place once complete.  A
    creation that fails (a full disk) leaves nothing; before, it left a half-migrated file that every later
    launch failed on (``table _alembic_tmp_experiments already exists``).  The file is a copy of this MLflow
    version's empty store (:func:`_empty_store`), opened once by MLflow to add its default experiment:
    migrating a new file costs 1.5-2 s of CPU in a fresh process, the copy 0.03 s."""
    import shutil
    import uuid

    part = db.with_name(f"{db.name}.creating-{uuid.uuid4().hex[:12]}")  # MLflow caches a store per URI
    try:
        db.parent.mkdir(parents=True, exist_ok=True)
        empty = _empty_store()
        if empty is None:
            _migrate(part)
        else:
            shutil.copyfile(empty, part)
        MlflowClient(tracking_uri=f"sqlite:///{part}")._tracking_client.store  # noqa: B018 — default experiment
        _forget_engine(f"sqlite:///{part}")
        os.replace(part, db)
    except Exception as exc:
        _forget_engine(f"sqlite:///{part}")
        part.unlink(missing_ok=True)
        raise StoreProblem(f"the MLflow store {db} could not be created ({_first_line(exc)}); nothing was left "
                           "behind: free space or fix the folder's permissions, then launch again") from None


def _migrate(db: Path) -> None:
    """Let MLflow create and migrate the SQLite store ``db`` (a new file)."""
    MlflowClient(tracking_uri=f"sqlite:///{db}")._tracking_client.store  # noqa: B018 — creates, migrates
    _forget_engine(f"sqlite:///{db}")


def _empty_store() -> Path | None:
    """This MLflow version's store as its migrations leave it, less the default experiment (MLflow adds it,
    with this store's artifact root and time, when it first opens a copy), made once in
    ``<cache>/mlflow`` (:func:`maglev.paths.cache_root`); None if that folder cannot hold it."""
    import sqlite3
    import uuid

    from maglev.paths import cache_root

    path = cache_root() / "mlflow" / f"empty-store-{mlflow.__version__}.db"
    if path.is_file():
        return path
    part = path.with_name(f"{path.name}.creating-{uuid.uuid4().hex[:12]}")
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        _migrate(part)
        con = sqlite3.connect(part)
        try:
            with con:
                con.execute("DELETE FROM experiments WHERE experiment_id = 0")
        finally:
            con.close()
        os.replace(part, path)  # another process making it at the same time replaces an equal file
    except Exception:  # noqa: BLE001 — a read-only or full cache: the store is migrated in place
        _forget_engine(f"sqlite:///{part}")
        with contextlib.suppress(OSError):
            part.unlink(missing_ok=True)
        return None
    return path


def _half_made(db: Path) -> bool:
    """A store whose creation was interrupted: MLflow's migration left an ``_alembic_tmp_*`` table and the
    store has no runs (a store with runs is never moved aside)."""
    import sqlite3

    con = sqlite3.connect(f"file:{db}?mode=ro", uri=True)
    try:
        tables = {row[0] for row in con.execute("SELECT name FROM sqlite_master WHERE type = 'table'")}
        runs = con.execute("SELECT count(*) FROM runs").fetchone()[0] if "runs" in tables else 0
    finally:
        con.close()
    return runs == 0 and any(t.startswith("_alembic_tmp_") for t in tables)


def _sqlite_client(db: Path, uri: str, write: bool) -> MlflowClient:
    """A client of a SQLite store (under the store lock): created atomically when missing, checked when it
    exists, repaired when an interrupted creation left it half-made (and said so)."""
    import logging

    if not db.exists():
        _create_store(db)
    check_store(db, write)
    try:
        client = MlflowClient(tracking_uri=uri)
        client._tracking_client.store  # noqa: B018 — opening the store migrates it: fail here, not later
        return client
    except Exception as exc:
        if not _half_made(db):
            raise StoreProblem(f"the MLflow store {db} cannot be opened ({_first_line(exc)}); move it aside "
                               f"(mv {db} {db}.damaged) and restore a backup, or pass another tracking.uri") from None
        aside = db.with_name(f"{db.name}.half-made-{time.strftime('%Y%m%d-%H%M%S')}")
        _forget_engine(uri)
        os.replace(db, aside)
        logging.getLogger("maglev.study").warning(
            "the MLflow store %s was left half-made by an interrupted creation (%s) and had no runs; moved it "
            "to %s and created it anew", db, _first_line(exc), aside.name)
        _create_store(db)
        return MlflowClient(tracking_uri=uri)


def new_client(uri: str, max_retries: int | None = None, timeout_s: int | None = None,
               write: bool = True) -> MlflowClient:
    """A client of the store at ``uri``: a server is checked first, with bounded retries; a SQLite
    store is created (migrated) under :func:`store_lock`, the only safe moment for it, atomically, and an
    existing one is checked first (``write``: it must be writable; :class:`StoreProblem`).  A user and password
    in a server's URI go to MLflow's variables (:mod:`maglev.study.credentials`)."""
    uri = to_env(uri)
    if is_http(uri):
        given = max_retries is not None
        http_settings(max_retries if given else HTTP_DEFAULTS["max_retries"],
                      timeout_s if timeout_s is not None else HTTP_DEFAULTS["timeout_s"], override=given)
        check_reachable(uri, float(os.environ["MLFLOW_HTTP_REQUEST_TIMEOUT"]),
                        int(os.environ["MLFLOW_HTTP_REQUEST_MAX_RETRIES"]))
        return MlflowClient(tracking_uri=uri)
    db = sqlite_path(uri)
    if db is not None:
        check_store(db, write)  # before the lock: a read-only folder cannot hold the lock file either
    with store_lock(uri) if db is None or os.access(db.parent, os.W_OK) else contextlib.nullcontext():
        client = MlflowClient(tracking_uri=uri) if db is None else _sqlite_client(db, uri, write)
    _defer_signals_in_sessions(client)
    return client


def _defer_signals_in_sessions(client: MlflowClient) -> None:
    """Make SIGTERM and Ctrl-C wait for the end of each SQLite session of ``client``'s store (one store
    per URI and process, shared by every client): see :mod:`maglev.study.shutdown` for why.  Reaches
    into MLflow's ``SqlAlchemyStore.ManagedSessionMaker`` (3.x); a test fails if that moves."""
    from maglev.study.shutdown import deferred

    store = getattr(getattr(client, "_tracking_client", None), "store", None)
    sessions = getattr(store, "ManagedSessionMaker", None)
    if sessions is None or getattr(sessions, "defers_signals", False):
        return

    @contextlib.contextmanager
    def deferring(*args, **kwargs):
        with deferred(), sessions(*args, **kwargs) as session:
            yield session

    deferring.defers_signals = True
    store.ManagedSessionMaker = deferring


_CONNECTED: dict[str, tuple[MlflowClient, str]] = {}  # connect's answers in this process, by tracking config


def connect(tracking: dict, reuse: bool = False) -> tuple[MlflowClient, str]:
    """Client and experiment id for the ``tracking`` config; creates the store/experiment if needed.
    ``reuse``: the answer of an earlier call with the same config in this process, if any (a sweep's jobs:
    the sweep callback checked the store, created the experiment and tagged it already; ≈ 7 ms a job)."""
    key = json.dumps(tracking, sort_keys=True, default=str)
    if reuse and key in _CONNECTED:
        return _CONNECTED[key]
    uri = tracking["uri"]
    db = sqlite_path(uri)
    if db is not None and not db.is_absolute():
        raise ValueError(f"tracking.uri must be an absolute sqlite path (sqlite:////abs/path.db), got {uri!r}")
    mlflow.set_tracking_uri(uri)  # does not touch the store
    client = new_client(uri, tracking.get("max_retries", HTTP_DEFAULTS["max_retries"]),
                        tracking.get("timeout_s", HTTP_DEFAULTS["timeout_s"]))
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
        tag_experiment(client, exp_id)  # check-then-write: two processes at once would both insert
    _CONNECTED[key] = client, exp_id
    return client, exp_id


# ---------------------------------------------------------------------------- how the UI shows the study
EXPERIMENT_KIND = "custom_model_development"  # MLflow 3: "model training", not GenAI (mlflow.experimentKind)
NOTE = "mlflow.note.content"  # a run's or experiment's description (Markdown; the table shows its start raw)
SHARE_KEY = "maglev"  # the runs table's shared view: experiment tag mlflow.sharedViewState.<key>
def _decimals(n: int) -> Callable[[float], float]:
    return lambda x: round(x, n)


def _significant(n: int) -> Callable[[float], float]:
    return lambda x: float(f"{x:.{n}g}")


def _minus_log10(x: float) -> float:
    """−log10 p rounded to 0.01 (p = 0 shows as 300): the residual tests pass at p ≥ 0.01, i.e. at ≤ 2."""
    return round(-math.log10(max(x, 1e-300)), 2) + 0.0


# the metrics a user compares first, also logged under a common prefix so that they sort and filter together,
# rounded to what the table can show (``key.<name>``: (the schema's metric, its rounding); the schema's names
# and full values stay the contract).  p-values keep 3 significant digits (rounded to 1e-4 they showed 0
# below 5e-5) and are also given as −log10 p.
KEY_METRICS = {"key.val_fit": ("val_fit", _decimals(2)), "key.sim_fit": ("val_fit_sim", _decimals(2)),
               "key.naive_fit": ("val_fit_naive", _decimals(2)),
               "key.white_p": ("whiteness_pvalue", _significant(3)),
               "key.indep_p": ("independence_pvalue", _significant(3)),
               "key.white_log10p": ("whiteness_pvalue", _minus_log10),
               "key.indep_log10p": ("independence_pvalue", _minus_log10), "key.n_params": ("n_params", _decimals(0))}
UI_PARAMS = "workflowType=machine_learning"  # the UI's query parameter for model-training mode


def key_metrics(metrics: dict) -> dict:
    """The ``key.*`` copies of a run's metrics (those it has), rounded."""
    return {k: rounded(float(metrics[m])) for k, (m, rounded) in KEY_METRICS.items() if m in metrics}


def shared_view(search_filter: str | None = None) -> dict:
    """The runs table as the UI restores it from ``?viewStateShareKey=``: the key metrics first, sorted by
    ``val_fit`` (unrounded, so in the ranking's order), the run name wide enough for
    ``armax 3-3-3-2 · real_binary_signal_2``."""
    metrics = [f"metrics.`{k}`" for k in KEY_METRICS]
    attrs = ["attributes.`Dataset`", "attributes.`Description`", "attributes.`Source`"]
    view = {"selectedColumns": metrics + attrs,
            "columnOrder": ["attributes.`Run Name`", *metrics, *attrs],
            "columnWidths": {"attributes.`Run Name`": 290, "attributes.`Dataset`": 240,
                             "attributes.`Description`": 400},
            "orderByKey": "metrics.`val_fit`", "orderByAsc": False}
    if search_filter:
        view["searchFilter"] = search_filter
    return view


def experiment_url(base: str, exp_id: str, share_key: str = SHARE_KEY) -> str:
    """The experiment's runs table in model-training mode with a shared view (``base``: the UI's address)."""
    return f"{base.rstrip('/')}/#/experiments/{exp_id}/runs?{UI_PARAMS}&viewStateShareKey={share_key}"


def run_link(exp_id: str, run_id: str) -> str:
    """A link to a run's page that works inside a description (relative to the UI's address)."""
    return f"#/experiments/{exp_id}/runs/{run_id}?{UI_PARAMS}"


EXPERIMENT_NOTE = """maglev study: identified models of the magnetic levitator (u: coil current in A, y: upper \
magnet height in cm), one run per dataset × structure × orders.

- `kind=model` runs: one model each; its description says how it fits and whether its residuals pass.
- `kind=sweep` runs: a sweep's parent, with the lab-level steps and the top four.
- `kind=ranking` runs: a sweep's ranking, its comparisons and the lab report.

Columns `key.*` (rounded copies of the run's metrics): one-step validation FIT %, simulation FIT %, the naive \
y(t-1) FIT %, the whiteness and independence p-values (pass at p ≥ 0.01) and the number of parameters. \
`maglev ui` opens this table with them.
"""


def tag_experiment(client: MlflowClient, exp_id: str, share: dict[str, dict] | None = None) -> None:
    """Tag the experiment for the UI: model-training kind, the shared view(s) (``share``: key -> view;
    default the whole experiment's) and a description unless it has one; writes only what differs."""
    tags = client.get_experiment(exp_id).tags
    wanted = {"mlflow.experimentKind": EXPERIMENT_KIND}
    for key, view in (share or {SHARE_KEY: shared_view()}).items():
        wanted[f"mlflow.sharedViewState.{key}"] = json.dumps(view, sort_keys=True)
    if NOTE not in tags:
        wanted[NOTE] = EXPERIMENT_NOTE
    for key, value in wanted.items():
        if tags.get(key) != value:
            try:
                client.set_experiment_tag(exp_id, key, value)
            except mlflow.exceptions.MlflowException:  # a server store has no lock: another process wrote it
                if key not in client.get_experiment(exp_id).tags:
                    raise


def source_tags(entry: str) -> dict[str, str]:
    """The tags the UI's Source, Version and User columns show (``MlflowClient.create_run`` sets none)."""
    import getpass

    try:
        user = getpass.getuser()
    except (KeyError, OSError):
        user = "unknown"
    return {"mlflow.source.name": entry, "mlflow.source.type": "LOCAL",
            "mlflow.source.git.commit": git_info()["git_commit"], "mlflow.user": user}


# ---------------------------------------------------------------------------- dataset inputs
def data_digest(data) -> str:
    """Eight hex digits identifying a record's samples and sampling period (an ``IOData``)."""
    import hashlib

    h = hashlib.sha1(data.u.tobytes())
    h.update(data.y.tobytes())
    h.update(repr(float(data.Ts)).encode())
    return h.hexdigest()[:8]


def dataset_entity(data, source: str | None, spec: dict | None = None):
    """An MLflow dataset for an ``IOData`` part: name, digest, source (a file path: ``local``; else the
    simulator, as code), schema ``u``, ``y`` and a profile with N, Ts, offsets and the units."""
    from mlflow.entities import Dataset

    from maglev.units import U_UNIT, Y_UNIT

    if source:
        kind, where = "local", json.dumps({"uri": source})
    else:
        kind, where = "code", json.dumps({"tags": {"mlflow.source.name": "maglev.sim.labdata"}})
    schema = {"mlflow_colspec": [{"name": "u", "type": "double"}, {"name": "y", "type": "double"}]}
    profile = {"num_rows": data.N, "Ts_s": data.Ts, "u_unit": U_UNIT, "y_unit": Y_UNIT,
               "u_offset": data.u_offset, "y_offset": data.y_offset, **({"spec": spec} if spec else {})}
    return Dataset(name=data.name, digest=data_digest(data), source_type=kind, source=where,
                   schema=json.dumps(schema), profile=json.dumps(profile, default=str))


def log_dataset_inputs(client: MlflowClient, run_id: str, est, val, source: str | None = None,
                       spec: dict | None = None) -> None:
    """Log the estimation and validation data as the run's dataset inputs (context ``estimation`` /
    ``validation``): the UI's Dataset column and dataset views.  ``client.log_inputs``, not
    ``mlflow.log_input``, which would start an implicit run."""
    from mlflow.entities import DatasetInput, InputTag
    from mlflow.utils.mlflow_tags import MLFLOW_DATASET_CONTEXT

    inputs = [DatasetInput(dataset_entity(part, source, spec), tags=[InputTag(MLFLOW_DATASET_CONTEXT, context)])
              for part, context in ((est, "estimation"), (val, "validation"))]
    try:
        client.log_inputs(run_id, datasets=inputs)
    except mlflow.exceptions.MlflowException:
        # MLflow looks a dataset up, then inserts it: two processes logging the same new dataset at once
        # both insert it and one fails (UNIQUE constraint failed: datasets...); again, it finds the other's
        client.log_inputs(run_id, datasets=inputs)


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


# the numeric libraries whose builds set the last digits of every metric (a run's reproduction may differ by
# rounding under other versions: maglev reproduce names them)
NUMERIC_LIBRARIES = ("numpy", "scipy", "control")
LIBRARY_TAG = "lib."


@lru_cache(maxsize=1)
def library_versions() -> dict[str, str]:
    """Tags ``lib.<name>``: the installed version of each of ``NUMERIC_LIBRARIES`` (read once per process:
    they cannot change under it, and every run of a sweep's worker tags them)."""
    from importlib.metadata import version

    return {f"{LIBRARY_TAG}{name}": version(name) for name in NUMERIC_LIBRARIES}


def process_tags() -> dict[str, str]:
    """``host``, ``pid`` (for the reaper), the checkout, the numeric libraries, and in a Slurm job its id
    (``slurm_job``: ``<array>_<task>`` as submitit's ``.submitit/<id>/`` log folders, ``squeue`` and
    ``scancel`` name it)."""
    tags = {"host": socket.gethostname(), "pid": str(os.getpid()), **git_info(), **library_versions()}
    array, task = os.environ.get("SLURM_ARRAY_JOB_ID"), os.environ.get("SLURM_ARRAY_TASK_ID")
    job = f"{array}_{task}" if array and task else os.environ.get("SLURM_JOB_ID")
    if job:
        tags["slurm_job"] = job
    return tags


# ---------------------------------------------------------------------------- queries
def sweep_parent(sweep_dir: str | None) -> str | None:
    """The running sweep's parent run: ``$MAGLEV_PARENT_RUN_ID`` (set by the sweep callback, inherited by
    local workers; exact when two sweeps of one name share the sweep dir), else ``<sweep dir>/parent_run_id``
    (written by the callback, readable on a cluster); None outside a sweep."""
    if not sweep_dir:
        return None
    if os.environ.get(PARENT_ENV):
        return os.environ[PARENT_ENV]
    f = Path(sweep_dir) / PARENT_FILE
    text = f.read_text().strip() if f.is_file() else ""
    return text or None


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


def log_files(client: MlflowClient, run_id: str, files: dict, artifact_uri: str | None = None) -> None:
    """Upload ``{artifact path: content}`` in one call; content is str, bytes (e.g. a PNG), dict (JSON) or a Path.
    ``artifact_uri``: the run's (``create_run``'s answer), which MLflow otherwise reads the whole run for."""
    with tempfile.TemporaryDirectory(prefix="maglev-artifacts-") as tmp:
        for rel, content in files.items():
            path = Path(tmp) / rel
            if Path(tmp).resolve() not in path.resolve().parents:  # an absolute name or '..' would write elsewhere
                raise ValueError(f"log_files: artifact path {rel!r} leaves the run's artifact folder")
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
        if artifact_uri is None:
            client.log_artifacts(run_id, tmp)
        else:
            from mlflow.store.artifact.artifact_repository_registry import get_artifact_repository

            get_artifact_repository(artifact_uri, tracking_uri=client.tracking_uri).log_artifacts(tmp)


def download_text(client: MlflowClient, run_id: str, path: str) -> str:
    with tempfile.TemporaryDirectory() as tmp:
        local = client.download_artifacts(run_id, path, tmp)
        return Path(local).read_text()
