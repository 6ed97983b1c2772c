"""A relaunch with nothing to do, decided from one read of the store before any job is launched.

Relaunching a finished sweep used to compose and launch every job only for each to find its
config FINISHED, then rank the unchanged runs and rebuild the report (17–21 s on the 2-core
machine).  :func:`survey` answers from one SQL query on a local SQLite store — read-only,
without importing MLflow — whether the launch can stop at once: the sweep's latest parent run
(``tags.sweep_id``) is FINISHED with its lab steps logged, every job's config hash is held by a
FINISHED model run of that sweep (its child, or another sweep's run it references), and, when
the sweep is ranked, its ranking run is FINISHED, ranked exactly the runs the ranking would rank
now (``tags.ranked_hash``, :meth:`maglev.study.ranking.Ranking.ranked_hash`) and its report
file exists, and no RUNNING run of the experiment was left by a dead process of this host (the usual
path marks those KILLED).  Anything else — a server store, an unknown schema, a config to run or to
reference, a missing report — answers None, and the sweep takes its usual path, which decides
the same things with MLflow's API.
"""

from __future__ import annotations

import hashlib
import os
import socket
import sqlite3
from dataclasses import dataclass
from pathlib import Path

# the tags the decision reads, of the parent, its ranking run and the model runs
TAGS = ("kind", "config_hash", "mlflow.parentRunId", "lab_logged", "ranking_run", "ranked_hash",
        "compared_structure", "sweep_parent", "host", "pid")
REF_PREFIX = "sweep_ref."  # maglev.study.claims.REF_PREFIX (a test checks they agree)
SQLITE = "sqlite:///"  # maglev.study.tracking.sqlite_path's prefix: that module imports MLflow

QUERY = """
WITH exp AS (SELECT experiment_id FROM experiments WHERE name = ? AND lifecycle_stage = 'active'),
parent AS (
  SELECT r.run_uuid FROM runs r
  JOIN tags s ON s.run_uuid = r.run_uuid AND s.key = 'sweep_id' AND s.value = ?
  JOIN tags k ON k.run_uuid = r.run_uuid AND k.key = 'kind' AND k.value = 'sweep'
  WHERE r.experiment_id IN (SELECT experiment_id FROM exp) AND r.lifecycle_stage = 'active'
  ORDER BY r.start_time DESC LIMIT 1),
ranking AS (SELECT t.value AS run_uuid FROM tags t WHERE t.key = 'ranking_run' AND t.run_uuid IN parent),
models AS (
  SELECT r.run_uuid FROM runs r
  JOIN tags k ON k.run_uuid = r.run_uuid AND k.key = 'kind' AND k.value = 'model'
  WHERE r.experiment_id IN (SELECT experiment_id FROM exp) AND r.lifecycle_stage = 'active'
    AND r.status = 'FINISHED' AND (
      EXISTS (SELECT 1 FROM tags h WHERE h.run_uuid = r.run_uuid AND h.key = 'config_hash' AND h.value IN ({hashes}))
      OR EXISTS (SELECT 1 FROM tags p WHERE p.run_uuid = r.run_uuid AND p.key = 'mlflow.parentRunId'
                 AND p.value IN parent)
      OR EXISTS (SELECT 1 FROM tags f, parent WHERE f.run_uuid = r.run_uuid AND f.key = ? || parent.run_uuid))),
running AS (SELECT run_uuid FROM runs WHERE experiment_id IN (SELECT experiment_id FROM exp)
            AND lifecycle_stage = 'active' AND status = 'RUNNING')
SELECT r.run_uuid, r.status, r.start_time, r.experiment_id, t.key, t.value,
       CASE WHEN r.run_uuid IN parent THEN 'parent' WHEN r.run_uuid IN ranking THEN 'ranking'
            WHEN r.run_uuid IN models THEN 'model' ELSE 'running' END
FROM runs r JOIN tags t ON t.run_uuid = r.run_uuid
WHERE r.lifecycle_stage = 'active'
  AND (r.run_uuid IN parent OR r.run_uuid IN ranking OR r.run_uuid IN models OR r.run_uuid IN running)
  AND (t.key IN ({tags}) OR substr(t.key, 1, {ref_len}) = ?)
"""


PARENT = """
SELECT 1 FROM runs r
JOIN experiments e ON e.experiment_id = r.experiment_id AND e.name = ? AND e.lifecycle_stage = 'active'
JOIN tags s ON s.run_uuid = r.run_uuid AND s.key = 'sweep_id' AND s.value = ?
JOIN tags k ON k.run_uuid = r.run_uuid AND k.key = 'kind' AND k.value = 'sweep'
WHERE r.lifecycle_stage = 'active' LIMIT 1
"""


@dataclass(frozen=True)
class Done:
    """A sweep whose relaunch has nothing to do: its parent run, how many configs, its ranking run and report."""

    parent: str
    experiment_id: str
    configs: int
    ranked: int
    ranking_run: str | None
    report: Path | None


@dataclass
class _Run:
    run_id: str
    status: str
    start_time: int
    experiment_id: str
    role: str
    tags: dict


def read(db: Path, experiment: str, sid: str, hashes: list[str]) -> list[_Run] | None:
    """The sweep's parent, its ranking run and the FINISHED model runs that matter to it, in one query
    (none when there is no store yet; None when it cannot be read that way: locked, another schema)."""
    if not db.exists():
        return []
    query = QUERY.format(hashes=",".join("?" * len(hashes)), tags=",".join("?" * len(TAGS)),
                         ref_len=len(REF_PREFIX))
    args = [experiment, sid, *hashes, REF_PREFIX, *TAGS, REF_PREFIX]
    try:
        con = sqlite3.connect(f"{db.resolve().as_uri()}?mode=ro", uri=True, timeout=5)
        try:
            rows = con.execute(query, args).fetchall()
        finally:
            con.close()
    except sqlite3.Error:
        return None
    runs: dict[str, _Run] = {}
    for run_id, status, start, exp_id, key, value, role in rows:
        run = runs.setdefault(run_id, _Run(run_id, status, int(start or 0), str(exp_id), role, {}))
        run.tags[key] = value
    return list(runs.values())


def new_sweep(uri: str, experiment: str, sid: str) -> bool:
    """True when the local SQLite store at ``uri`` holds no parent run of sweep ``sid``, or does not exist
    yet: its launch runs jobs whatever its configs turn out to be (only a FINISHED parent can make
    :func:`survey` say there is nothing to do).  False when it holds one, or cannot be read this way (a
    server, another schema, locked)."""
    if not uri.startswith(SQLITE):
        return False
    db = Path(uri[len(SQLITE):])
    if not db.exists():
        return True
    try:
        con = sqlite3.connect(f"{db.resolve().as_uri()}?mode=ro", uri=True, timeout=5)
        try:
            return con.execute(PARENT, (experiment, sid)).fetchone() is None
        finally:
            con.close()
    except sqlite3.Error:
        return False


def ranked_ids(parent: str, models: list[_Run]) -> list[str]:
    """The runs the sweep's ranking ranks (:func:`maglev.study.store.sweep_runs`): one FINISHED run per
    config hash, the parent's own child first, then the earliest started."""
    def preference(r: _Run) -> tuple:
        return (r.tags.get("mlflow.parentRunId") != parent, r.start_time, r.run_id)

    kept, seen = [], set()
    for r in sorted(models, key=preference):
        key = r.tags.get("config_hash") or r.run_id
        if key not in seen:
            seen.add(key)
            kept.append(r.run_id)
    return kept


def ranked_hash(run_ids: list[str], structure: str | None) -> str:
    """:meth:`maglev.study.ranking.Ranking.ranked_hash` of these runs and compared structure."""
    return hashlib.sha1((" ".join(sorted(run_ids)) + f" {structure}").encode()).hexdigest()


def stale(run: _Run) -> bool:
    """A RUNNING run whose process on this host is gone (:func:`maglev.study.reap.stale`, which reads MLflow's
    run objects)."""
    from maglev.study.reap import _alive

    pid = run.tags.get("pid", "")
    return (run.status == "RUNNING" and run.tags.get("host") == socket.gethostname() and pid.isdigit()
            and int(pid) != os.getpid() and not _alive(int(pid)))


@dataclass(frozen=True)
class Survey:
    """What a launch finds before its jobs: :class:`Done` when it has nothing to do, and how many of its
    configs have a FINISHED run already (of any sweep; None when the store was not read)."""

    done: Done | None
    finished: int | None


def survey(uri: str, experiment: str, sid: str, hashes: list[str], lab: bool,
           ranking: dict | None, report: Path | None, reap: bool = True) -> Survey:
    """Read the store once (a local SQLite store; a server is not read here) and decide.

    ``hashes``: every job's config hash; ``lab``: the sweep logs lab steps; ``ranking``: the ranking
    callback's settings (``structure``), None when the sweep is not ranked; ``report``: the file the
    ranking callback writes; ``reap``: stale RUNNING runs of the experiment are to be marked KILLED
    (``tracking.reap``), which is work."""
    if not uri.startswith(SQLITE) or not hashes:
        return Survey(None, None)
    runs = read(Path(uri[len(SQLITE):]), experiment, sid, hashes)
    if runs is None:
        return Survey(None, None)
    finished = {r.tags.get("config_hash") for r in runs if r.role == "model"} & set(hashes)
    return Survey(nothing_to_do(runs, hashes, lab, ranking, report, reap), len(finished))


def nothing_to_do(runs: list[_Run], hashes: list[str], lab: bool, ranking: dict | None, report: Path | None,
                  reap: bool = True) -> Done | None:
    """A :class:`Done` when relaunching the sweep would run, reference, log and rank nothing new (``runs``:
    :func:`read`'s answer; the rest as :func:`survey`'s); else None."""
    if not runs:
        return None
    if reap and any(stale(r) for r in runs if r.role == "running"):
        return None
    parents = [r for r in runs if r.role == "parent"]
    if len(parents) != 1 or parents[0].status != "FINISHED":
        return None
    parent = parents[0]
    if lab and parent.tags.get("lab_logged") != "true":
        return None
    models = [r for r in runs if r.role == "model" and r.tags.get("kind") == "model"]

    def ours(r: _Run) -> bool:
        return r.tags.get("mlflow.parentRunId") == parent.run_id or f"{REF_PREFIX}{parent.run_id}" in r.tags

    held = {r.tags.get("config_hash") for r in models if ours(r)}
    if not set(hashes) <= held:
        return None
    ids = ranked_ids(parent.run_id, [r for r in models if ours(r)])
    ranking_run = None
    if ranking is not None:
        ranked = [r for r in runs if r.role == "ranking" and r.run_id == parent.tags.get("ranking_run")]
        if not ranked or ranked[0].status != "FINISHED" or ranked[0].tags.get("sweep_parent") != parent.run_id:
            return None
        compared = ranked[0].tags.get("compared_structure") or None
        if ranking.get("structure") and ranking["structure"] != compared:
            return None
        if ranked[0].tags.get("ranked_hash") != ranked_hash(ids, compared):
            return None
        if report is None or not report.is_file():
            return None
        ranking_run = ranked[0].run_id
    return Done(parent=parent.run_id, experiment_id=parent.experiment_id, configs=len(set(hashes)),
                ranked=len(ids), ranking_run=ranking_run, report=report if ranking is not None else None)
