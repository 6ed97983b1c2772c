"""Read a sweep back from the MLflow store: its parent run, its FINISHED model runs, their artifacts.

The ranking and the report only read what the study logged (schema in docs/tracking.md),
so they work on any store — the local SQLite file or a tracking server — long after the
sweep.  User mistakes (no store, unknown experiment, no sweep, a sweep without finished
runs) raise :class:`SweepError` with a message saying what to do; the CLIs print it and
exit non-zero instead of showing a traceback.
"""

from __future__ import annotations

import json
import tempfile
import warnings
from dataclasses import dataclass, field
from pathlib import Path

import pandas as pd

warnings.filterwarnings("ignore", message="The .*noload.* loader strategy is deprecated")

TAG_COLUMNS = ("dataset", "input_class", "data_source", "structure", "orders", "val_dataset", "sweep")


class SweepError(RuntimeError):
    """A user-facing problem with the store or the sweep (printed without a traceback)."""


@dataclass(frozen=True)
class Sweep:
    """A sweep's parent run, its FINISHED model runs (one row each) and the children ignored by status."""

    client: object  # mlflow.MlflowClient
    uri: str
    experiment_id: str
    experiment: str
    parent: object  # mlflow.entities.Run
    runs: pd.DataFrame
    ignored: dict[str, int]  # status -> number of model runs not FINISHED
    # the artifact URIs of the parent and model runs: a local store's artifacts are then read as files, not
    # downloaded (MLflow reads the whole run back for each download: ≈ 20 ms of the ≈ 50 a sweep's end reads)
    artifact_uris: dict[str, str] = field(default_factory=dict)

    @property
    def parent_id(self) -> str:
        return self.parent.info.run_id

    def artifact(self, run_id: str, path: str) -> bytes | None:
        """The content of one artifact of a run of this store (:func:`artifact_bytes`)."""
        return artifact_bytes(self.client, run_id, path, self.artifact_uris.get(run_id))

    def artifact_json(self, run_id: str, path: str) -> dict | None:
        return artifact_json(self.client, run_id, path, self.artifact_uris.get(run_id))

    def model(self, run_id: str):
        """The run's fitted ``PolyModel`` (:func:`load_model`)."""
        return load_model(self.client, run_id, self.artifact_uris.get(run_id))

    def config(self, run_id: str) -> dict:
        """The resolved config the run logged (:func:`run_config`)."""
        return run_config(self.client, run_id, self.artifact_uris.get(run_id))

    @property
    def name(self) -> str:
        return self.parent.data.tags.get("sweep") or self.parent.info.run_name or self.parent_id[:8]


def open_store(uri: str, experiment: str):
    """(client, experiment id) of an existing store and experiment; never creates either.

    A server is checked first (one line naming the URI when it does not answer, within
    seconds: MLflow's HTTP retries are bounded unless ``$MLFLOW_HTTP_REQUEST_*`` say
    otherwise); a SQLite file is opened under the store lock, so a store another process
    is still creating is waited for, not migrated twice.
    """
    from maglev.study.credentials import public
    from maglev.study.tracking import StoreProblem, TrackingUnreachable, new_client, sqlite_path

    db = sqlite_path(uri)
    if db is not None and not db.is_file():
        raise SweepError(f"no MLflow store at {db}; run a sweep first (python study.py -m +sweep=lab) "
                         "or pass --tracking-uri")
    from mlflow.exceptions import MlflowException

    try:
        client = new_client(uri)
    except TrackingUnreachable as exc:
        raise SweepError(str(exc.code).removeprefix("maglev: ")) from None
    except StoreProblem as exc:
        raise SweepError(str(exc)) from None
    try:
        exp = client.get_experiment_by_name(experiment)
        known = [e.name for e in client.search_experiments()] if exp is None else []
    except MlflowException as exc:
        raise SweepError(f"cannot read the MLflow store {public(uri)}: {exc.message}") from None
    if exp is None:
        raise SweepError(f"no experiment {experiment!r} in {public(uri)} (experiments: {', '.join(known) or 'none'})")
    return client, exp.experiment_id


def find_parent(client, experiment_id: str, parent_id: str | None = None):
    """The sweep's parent run: ``parent_id`` if given (must be a ``kind=sweep`` run), else the latest sweep."""
    from mlflow.exceptions import MlflowException

    if parent_id:
        try:
            run = client.get_run(parent_id)
        except MlflowException:
            raise SweepError(f"no run {parent_id!r} in the store") from None
        if run.info.experiment_id != experiment_id or run.data.tags.get("kind") != "sweep":
            raise SweepError(f"run {parent_id} is not a sweep parent run (kind=sweep) of this experiment")
        return run
    runs = client.search_runs([experiment_id], filter_string="tags.kind = 'sweep'",
                              order_by=["attributes.start_time DESC"], max_results=1)
    if not runs:
        raise SweepError("the experiment has no sweep yet; run one with python study.py -m +sweep=lab")
    return runs[0]


def model_rows(runs: list) -> pd.DataFrame:
    """One row per model run: run_id, name, status, the schema's tags and every metric."""
    rows = []
    for r in runs:
        row = {"run_id": r.info.run_id, "name": r.info.run_name, "status": r.info.status}
        row.update({k: r.data.tags.get(k, "") for k in TAG_COLUMNS})
        row.update(r.data.metrics)
        rows.append(row)
    return pd.DataFrame(rows)


def sweep_runs(client, experiment_id: str, parent_id: str) -> tuple[list, int]:
    """The sweep's model runs — its children and the runs of other sweeps it skipped because they held
    its configs (tag ``sweep_ref.<parent>``) — with one FINISHED run per config hash (its own child
    first, then the earliest), and how many FINISHED duplicates were dropped."""
    from maglev.study.claims import referenced

    kids = client.search_runs([experiment_id], max_results=50000,
                              filter_string=f"tags.`mlflow.parentRunId` = '{parent_id}' and tags.kind = 'model'")
    refs = referenced(client, experiment_id, parent_id)
    runs = {r.info.run_id: r for r in [*kids, *refs]}.values()

    def preference(r) -> tuple:
        return (r.data.tags.get("mlflow.parentRunId") != parent_id, r.info.start_time, r.info.run_id)

    kept, seen, duplicates = [], set(), 0
    for r in sorted(runs, key=preference):
        key = r.data.tags.get("config_hash") or r.info.run_id
        if r.info.status == "FINISHED":
            if key in seen:
                duplicates += 1
                continue
            seen.add(key)
        kept.append(r)
    return kept, duplicates


def load_sweep(uri: str, experiment: str, parent_id: str | None = None, reap: bool = True) -> Sweep:
    """The sweep ``parent_id`` (default: the latest) with its FINISHED model runs, after reaping stale runs."""
    client, exp_id = open_store(uri, experiment)
    if reap:
        from maglev.study.reap import reap as reap_runs

        reap_runs(client, [exp_id])
    parent = find_parent(client, exp_id, parent_id)
    kids, duplicates = sweep_runs(client, exp_id, parent.info.run_id)
    finished = [r for r in kids if r.info.status == "FINISHED"]
    ignored: dict[str, int] = {"duplicate": duplicates} if duplicates else {}
    for r in kids:
        if r.info.status != "FINISHED":
            ignored[r.info.status] = ignored.get(r.info.status, 0) + 1
    name = parent.data.tags.get("sweep") or parent.info.run_name
    if not finished:
        detail = ", ".join(f"{n} {s}" for s, n in sorted(ignored.items())) or "no model runs at all"
        raise SweepError(f"sweep {name!r} (parent run {parent.info.run_id}) has no FINISHED model runs "
                         f"({detail})")
    from maglev.study.credentials import public

    return Sweep(client=client, uri=public(uri), experiment_id=exp_id, experiment=experiment, parent=parent,
                 runs=model_rows(finished), ignored=ignored,
                 artifact_uris={r.info.run_id: r.info.artifact_uri for r in [parent, *kids]})


def local_artifact(artifact_uri: str | None, path: str) -> Path | None:
    """Where a run whose artifacts are at ``artifact_uri`` keeps the artifact ``path``, if that is a local
    folder (``file://``); None for artifacts elsewhere (a server) or an unknown URI."""
    from urllib.parse import unquote, urlparse

    uri = urlparse(artifact_uri or "")
    if uri.scheme != "file" or uri.netloc not in ("", "localhost"):
        return None
    root = Path(unquote(uri.path))
    local = root / path
    return local if root.resolve() in local.resolve().parents else None


def artifact_bytes(client, run_id: str, path: str, artifact_uri: str | None = None) -> bytes | None:
    """The content of one artifact, or None when the run has no such artifact; read as a file when the run's
    ``artifact_uri`` is a local folder, else downloaded."""
    from mlflow.exceptions import MlflowException

    local = local_artifact(artifact_uri, path)
    if local is not None:
        return local.read_bytes() if local.is_file() else None
    with tempfile.TemporaryDirectory(prefix="maglev-rank-") as tmp:
        try:
            local = client.download_artifacts(run_id, path, tmp)
        except (MlflowException, OSError):
            return None
        return Path(local).read_bytes() if Path(local).is_file() else None


def artifact_json(client, run_id: str, path: str, artifact_uri: str | None = None) -> dict | None:
    raw = artifact_bytes(client, run_id, path, artifact_uri)
    return None if raw is None else json.loads(raw)


def run_config(client, run_id: str, artifact_uri: str | None = None) -> dict:
    """The resolved config a run logged (``config/config.yaml``), with the study's schema re-applied (a
    simulated dataset logged before ``dataset.plant`` existed keeps the simulator of that time)."""
    from omegaconf import OmegaConf

    from maglev.study.config import plain_config
    from maglev.study.datasets import UNNAMED_PLANT

    raw = artifact_bytes(client, run_id, "config/config.yaml", artifact_uri)
    if raw is None:
        raise SweepError(f"run {run_id} has no config/config.yaml artifact")
    cfg = OmegaConf.create(raw.decode())
    ds = cfg.get("dataset")
    if ds is not None and ds.get("source") == "sim" and "plant" not in ds:  # logged before dataset.plant existed
        ds.plant = UNNAMED_PLANT
    return plain_config(cfg)


def load_model(client, run_id: str, artifact_uri: str | None = None):
    """The run's fitted ``PolyModel`` (``model/model.json``)."""
    from maglev.model import PolyModel

    raw = artifact_bytes(client, run_id, "model/model.json", artifact_uri)
    if raw is None:
        raise SweepError(f"run {run_id} has no model/model.json artifact")
    return PolyModel.from_json(raw.decode())


def dataset_configs(sweep: Sweep) -> dict[str, dict]:
    """One logged run config per dataset of the sweep (enough to rebuild that dataset)."""
    out: dict[str, dict] = {}
    for name, group in sweep.runs.groupby("dataset", sort=True):
        out[str(name)] = sweep.config(group["run_id"].iloc[0])
    return out
