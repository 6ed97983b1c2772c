"""The sweep's Hydra callbacks: the parent MLflow run (:class:`SweepCallback`) and the ranking (:class:`RankingCallback`).

``SweepCallback.on_multirun_start`` runs once in the launching process before any job:
it creates the store and experiment (so parallel workers never race to create the
SQLite database), reaps runs left RUNNING by dead processes, finds or creates the
parent run (``kind=sweep``; a relaunch of the same sweep reuses its parent), writes
its id to ``<sweep dir>/parent_run_id`` (read by every job, also on a cluster) and
``$MAGLEV_PARENT_RUN_ID``, and logs the lab-level steps once per sweep.
``on_multirun_end`` finishes the parent with a summary.  If the sweep dies (a job
config error, Ctrl-C) an ``atexit`` hook marks the parent KILLED, or deletes it when
no job ever started a run.  ``RankingCallback.on_multirun_end`` then ranks the sweep
and writes its report (:func:`maglev.study.report.rank_and_report`).
"""

from __future__ import annotations

import atexit
import hashlib
import json
import logging
import os
from pathlib import Path
from typing import Any

from hydra.core.hydra_config import HydraConfig
from hydra.experimental.callback import Callback
from omegaconf import DictConfig, OmegaConf

from maglev.study import render, tracking
from maglev.study.config import task_config

log = logging.getLogger("maglev.study")


def sweep_id(config: DictConfig, task: dict) -> str:
    """Identity of a sweep: its name, sweeper params and command-line overrides (not tracking/hydra)."""
    raw = config.hydra.sweeper.get("params")
    params = OmegaConf.to_container(raw, resolve=False) if raw is not None else {}
    overrides = sorted(o for o in config.hydra.overrides.task
                       if not o.lstrip("+~").startswith(("tracking", "hydra")))
    text = json.dumps({"name": task["study"]["name"], "params": params, "overrides": overrides},
                      sort_keys=True, default=str)
    return hashlib.sha1(text.encode()).hexdigest()


def sweep_size(config: DictConfig) -> int | None:
    """How many jobs the sweep launches: the product of its sweep sizes (None if unknown).

    The basic and joblib sweepers take the cartesian product of the sweeper params and
    the command-line sweeps (the command line wins for a key given twice).
    """
    from hydra.core.override_parser.overrides_parser import OverridesParser

    raw = config.hydra.sweeper.get("params") or {}
    specs = {str(k): f"{k}={v}" for k, v in raw.items()}
    parser = OverridesParser.create()
    for text in config.hydra.overrides.task:
        specs[parser.parse_override(text).key_or_group] = text
    size = 1
    for override in parser.parse_overrides(list(specs.values())):
        if override.is_sweep_override():
            try:
                size *= len(list(override.sweep_string_iterator()))
            except Exception:  # noqa: BLE001 — e.g. glob sweeps need the config to expand
                return None
    return size


class SweepCallback(Callback):
    def __init__(self) -> None:
        self.client = None
        self.parent: str | None = None
        self.fresh = False

    # ------------------------------------------------------------------ start
    def on_multirun_start(self, config: DictConfig, **kwargs: Any) -> None:
        HydraConfig.instance().set_config(config)  # hydra#3427: ${hydra:...} in the callback
        task = task_config(config)
        if task["tracking"]["log_figures"] and str(config.hydra.launcher.get("_target_", "")).endswith("BasicLauncher"):
            render.start()  # the renderer's processes import while the store and the lab steps are made
        client, exp_id = tracking.connect(task["tracking"])
        self.client, self.exp_id = client, exp_id
        if task["tracking"]["reap"]:
            from maglev.study.reap import reap

            killed = reap(client, [exp_id])
            if killed:
                log.warning("marked %d stale RUNNING run(s) KILLED", len(killed))
        sid = sweep_id(config, task)
        sweep_dir = Path(config.hydra.sweep.dir).resolve()
        name = task["study"]["name"]
        found = client.search_runs([exp_id], filter_string=f"tags.sweep_id = '{sid}' and tags.kind = 'sweep'",
                                   order_by=["attributes.start_time DESC"], max_results=1)
        tags = {"kind": "sweep", "sweep": name, "sweep_id": sid, "sweep_dir": str(sweep_dir),
                "hydra.overrides": " ".join(config.hydra.overrides.task)[:5000],
                "launcher": str(config.hydra.launcher.get("_target_", "")), **tracking.process_tags()}
        if found:
            self.parent, self.fresh = found[0].info.run_id, False
            client.update_run(self.parent, status="RUNNING")
            tracking.log_batch(client, self.parent, tags={**tags, "resumed": "true"})
        else:
            self.parent = client.create_run(exp_id, run_name=name, tags=tags).info.run_id
            self.fresh = True
        sweep_dir.mkdir(parents=True, exist_ok=True)
        (sweep_dir / tracking.PARENT_FILE).write_text(self.parent)
        os.environ[tracking.PARENT_ENV] = self.parent
        size = sweep_size(config)
        if size:
            os.environ[tracking.SIZE_ENV] = str(size)
        atexit.register(self._abort)
        log.info("sweep %r: parent run %s (%s) in %s", name, self.parent,
                 "new" if self.fresh else "resumed", task["tracking"]["uri"])
        if task["lab"]["enabled"] and (self.fresh or found[0].data.tags.get("lab_logged") != "true"):
            self._log_lab(task)

    def _log_lab(self, task: dict) -> None:
        from maglev.study.lab import lab_steps

        try:
            metrics, figures, summary = lab_steps(task)
        except Exception as exc:  # the lab steps are informative; the sweep goes on
            log.warning("lab steps failed: %s: %s", type(exc).__name__, exc)
            tracking.log_batch(self.client, self.parent, tags={"lab_error": f"{type(exc).__name__}: {exc}"})
            return
        from maglev.study.figures import png

        files = {f"lab/{k}": png(fig) for k, fig in figures.items()}
        files["lab/lab.json"] = summary
        tracking.log_files(self.client, self.parent, files)
        tracking.log_batch(self.client, self.parent, metrics=metrics, tags={"lab_logged": "true"})

    # ------------------------------------------------------------------ end
    def on_multirun_end(self, config: DictConfig, **kwargs: Any) -> None:
        if self.parent is None:
            return
        atexit.unregister(self._abort)
        render.drain()  # the last runs' figures: their runs are FINISHED once drawn
        kids = tracking.children(self.client, self.exp_id, self.parent)
        counts: dict[str, int] = {}
        for r in kids:
            counts[r.info.status] = counts.get(r.info.status, 0) + 1
        tracking.log_batch(self.client, self.parent,
                           metrics={f"runs_{s.lower()}": n for s, n in counts.items()})
        from maglev.study.ranking import describe_sweep

        describe_sweep(self.client, self.parent)  # what was swept, the top four and cautions if ranked
        self.client.set_terminated(self.parent, "FINISHED")
        os.environ.pop(tracking.PARENT_ENV, None)
        os.environ.pop(tracking.SIZE_ENV, None)
        summary = ", ".join(f"{n} {s}" for s, n in sorted(counts.items())) or "no runs"
        log.info("sweep done: %s under parent run %s", summary, self.parent)
        if counts.get("FAILED"):
            log.warning("%d run(s) FAILED; their error.txt artifacts say why", counts["FAILED"])

    def _abort(self) -> None:
        """atexit: the sweep did not reach on_multirun_end."""
        if self.parent is None:
            return
        render.abandon()
        try:
            if self.fresh and not tracking.children(self.client, self.exp_id, self.parent):
                self.client.delete_run(self.parent)
            else:
                self.client.set_terminated(self.parent, "KILLED")
        except Exception:  # noqa: BLE001 — best effort at interpreter exit
            pass


class RankingCallback(Callback):
    """At the end of a multirun: rank the sweep, log the ranking run and write the report.

    Order-independent with :class:`SweepCallback` (it reads the parent id from the sweep
    dir); errors are logged, never raised, so a sweep's exit status is its jobs'.
    """

    def __init__(self, structure: str | None = None, report_dir: str | None = None) -> None:
        self.structure = structure
        self.report_dir = report_dir

    def on_multirun_end(self, config: DictConfig, **kwargs: Any) -> None:
        from maglev.study.report import rank_and_report
        from maglev.study.store import SweepError

        HydraConfig.instance().set_config(config)
        render.drain()  # Hydra ends callbacks in reverse order: this one runs before SweepCallback's end
        task = task_config(config)
        parent = tracking.sweep_parent(str(config.hydra.sweep.dir))
        if parent is None:
            log.warning("ranking skipped: no parent run id in %s", config.hydra.sweep.dir)
            return
        try:
            rank_and_report(task["tracking"]["uri"], task["tracking"]["experiment"], parent,
                            self.structure, self.report_dir)
        except SweepError as exc:
            log.warning("ranking/report not made: %s", exc)
        except Exception as exc:  # noqa: BLE001 — a report bug must not fail a finished sweep
            log.exception("ranking/report failed: %s: %s", type(exc).__name__, exc)
