"""Run the study in-process through Hydra's own API, into a temporary MLflow store.

``launch`` composes ``conf/`` exactly as ``python study.py`` does (same config, same
callbacks, same task function) but in the test process, so a sweep costs its runs and
not ~2 s of imports per subprocess.  Tests that are about the command line itself
(``study.py`` as a process, joblib workers, a tracking server) start subprocesses.
"""

from __future__ import annotations

import contextlib
import logging
import subprocess
import sys
import warnings
from pathlib import Path

warnings.filterwarnings("ignore", message="The .*noload.* loader strategy is deprecated")

REPO = Path(__file__).resolve().parents[2]
CONF = REPO / "conf"
TINY = ["dataset.duration_s=4", "dataset.preprocess.trim=500"]  # 3500 samples → 875 + 875 after decimation
# what a test that is not about them can leave out: run figures, the BLA and Jacobian, the sweep's lab steps
LEAN = ["tracking.log_figures=false", "study.true_plant=false", "lab.enabled=false"]


def store_overrides(store: Path) -> list[str]:
    """Everything a launch writes goes under ``store`` (never the repository's mlruns/, multirun/, reports/)."""
    return [f"tracking.uri=sqlite:///{store}/mlflow.db", f"tracking.artifact_location={store}/artifacts",
            f"hydra.run.dir={store}/outputs", f"hydra.sweep.dir={store}/multirun"]


def launch(store: Path, *overrides: str, multirun: bool = True, rank: bool = False):
    """``python study.py [-m] OVERRIDES`` in-process; the ranking callback only with ``rank=True``
    (then the report goes to ``store/reports``).  Returns Hydra's job returns."""
    from hydra._internal.hydra import Hydra
    from hydra._internal.utils import create_config_search_path
    from hydra.core.global_hydra import GlobalHydra

    import maglev.study.schema  # noqa: F401  (schemas and ${maglev.root:})
    from maglev.study.job import run

    args = [*overrides, *store_overrides(store), f"hydra.mode={'MULTIRUN' if multirun else 'RUN'}"]
    args.append(f"hydra.callbacks.maglev_rank.report_dir={store}/reports" if rank else "~hydra.callbacks.maglev_rank")
    GlobalHydra.instance().clear()
    hydra = Hydra.create_main_hydra2(task_name="study", config_search_path=create_config_search_path(f"file://{CONF}"))
    try:
        go = hydra.multirun if multirun else hydra.run
        return go(config_name="config", task_function=run, overrides=args, with_log_configuration=False)
    finally:
        GlobalHydra.instance().clear()


@contextlib.contextmanager
def study_log():
    """Collect the messages of the study's logger (``maglev.study``) at INFO while the block runs."""
    lines: list[str] = []

    class Collect(logging.Handler):
        def emit(self, record: logging.LogRecord) -> None:
            lines.append(record.getMessage())

    logger, handler = logging.getLogger("maglev.study"), Collect(logging.INFO)
    level = logger.level
    logger.addHandler(handler)
    logger.setLevel(logging.INFO)
    try:
        yield lines
    finally:
        logger.removeHandler(handler)
        logger.setLevel(level)


def process_env(drop: str = "MLFLOW_TRACKING_URI") -> dict[str, str]:
    """The environment of a study process: without variables starting with ``drop``, and with this
    checkout first on ``PYTHONPATH`` — submitit's job processes start in the launch directory, where
    ``import maglev`` would otherwise find whichever checkout is pip-installed."""
    import os

    env = {k: v for k, v in os.environ.items() if not k.startswith(drop)}
    env["PYTHONPATH"] = os.pathsep.join(p for p in (str(REPO), env.get("PYTHONPATH", "")) if p)
    return env


def default_ctrl_c() -> None:
    """``preexec_fn`` of a process a test sends Ctrl-C to: Python's own SIGINT handling in it, however the suite
    was started.  A shell starts a background command (``cmd &``, ``nohup``) with SIGINT ignored, its children
    inherit that, and a Python started so never raises KeyboardInterrupt: the ui and shutdown tests then
    failed in every full run started that way (and passed when run in the foreground)."""
    import signal

    signal.signal(signal.SIGINT, signal.SIG_DFL)


def study_process(store: Path, *args: str, timeout: float = 300, env: dict | None = None,
                  check: bool = True) -> subprocess.CompletedProcess:
    """``python study.py ARGS`` as a process (for what only a process shows), logging under ``store``."""
    import os

    cmd = [sys.executable, str(REPO / "study.py"), *args, *store_overrides(store)]
    env = {**os.environ, **(env or {})}
    env.pop("MLFLOW_TRACKING_URI", None)
    proc = subprocess.run(cmd, capture_output=True, text=True, cwd=store, timeout=timeout, env=env)
    if check:
        assert proc.returncode == 0, proc.stderr[-4000:]
    return proc


def client_for(store: Path):
    from mlflow import MlflowClient

    client = MlflowClient(tracking_uri=f"sqlite:///{store}/mlflow.db")
    return client, client.get_experiment_by_name("maglev").experiment_id


def all_runs(store: Path):
    client, exp_id = client_for(store)
    return client, exp_id, client.search_runs([exp_id], max_results=1000)


def model_statuses(store: Path) -> set[str]:
    """The statuses of the model runs in ``store/mlflow.db`` now, read with sqlite3: what a test polls while a
    sweep runs (≈ 0.3 ms a poll, where MLflow's client and a search take ≈ 13 ms); empty while the store is
    missing or being created."""
    import sqlite3

    db = store / "mlflow.db"
    if not db.is_file():
        return set()
    try:
        with contextlib.closing(sqlite3.connect(f"file:{db}?mode=ro", uri=True, timeout=1.0)) as con:
            rows = con.execute("SELECT r.status FROM runs r JOIN tags t ON t.run_uuid = r.run_uuid "
                               "WHERE t.key = 'kind' AND t.value = 'model'").fetchall()
    except sqlite3.OperationalError:  # no tables yet, or locked by the migration
        return set()
    return {status for (status,) in rows}


def artifact_paths(client, run_id: str, path: str | None = None) -> set[str]:
    out = set()
    for a in client.list_artifacts(run_id, path):
        out |= artifact_paths(client, run_id, a.path) if a.is_dir else {a.path}
    return out


def rule_orders(runs: list, margin: float = 1.0) -> dict[str, tuple[int, list[int]]]:
    """Each structure's (final order, swept grid), recomputed from FINISHED model ``runs``' logged metrics by the
    orders decision's rule (maglev.lab.orders), written out here independently: the smallest order within
    ``margin`` of the best mean simulation FIT among the orders that count — below the first order whose models
    carry at least one more near cancellation each, per order added, than the order below's, and whose models'
    mean distance to the BLA (where logged) is not larger than a lower order's.  Means are over the datasets, each
    swept at every order of its structure (asserted)."""
    import collections
    import math

    from maglev.study.ranking import model_order

    by = collections.defaultdict(lambda: collections.defaultdict(list))  # (structure, metric) -> order -> values
    datasets = {r.data.tags["dataset"] for r in runs}
    for r in runs:
        st, order = r.data.tags["structure"], int(model_order(r.data.tags["orders"]))
        for metric in ("val_fit_sim", "g_bla_err", "near_cancellations"):
            if metric in r.data.metrics:
                by[st, metric][order].append(r.data.metrics[metric])
    out = {}
    for st in sorted({st for st, _ in by}):
        assert all(len(v) == len(datasets) for v in by[st, "val_fit_sim"].values())
        fit, d, cancel = ({o: sum(v) / len(v) for o, v in sorted(by[st, m].items())}
                          for m in ("val_fit_sim", "g_bla_err", "near_cancellations"))
        grid = list(fit)
        cut = next((hi for lo, hi in zip(grid, grid[1:]) if cancel[hi] - cancel[lo] >= (hi - lo) - 1e-9), math.inf)
        counted = [o for o in grid if o < cut and not any(o in d and p in d and d[o] > d[p] for p in grid if p < o)]
        best = max(fit[o] for o in counted)
        out[st] = (min(o for o in counted if fit[o] >= best - margin), grid)
    return out


def drawn_slowly(uri: str, run_id: str, seconds: float) -> None:
    """A renderer task (``maglev.study.render.submit``'s ``task``) that takes ``seconds``, tags the pid of the
    process that ran it (``drawn_by``) and ends the run FINISHED, as drawing a run's figures does."""
    import os
    import time

    from mlflow import MlflowClient

    time.sleep(seconds)
    client = MlflowClient(tracking_uri=uri)
    client.set_tag(run_id, "drawn_by", str(os.getpid()))
    client.set_terminated(run_id, "FINISHED")


def pid_of(*args) -> int:
    """The pid of the process that runs it (a task for ``maglev.study.render.offload``)."""
    import os

    return os.getpid()
