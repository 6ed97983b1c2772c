"""The sweep's Hydra callbacks: the parent MLflow run (:class:`SweepCallback`) and the ranking (:class:`RankingCallback`).

``SweepCallback.on_multirun_start`` runs once in the launching process before any job:
it checks every job's config (:func:`check_sweep`: an impossible config stops the sweep
before any run exists, naming the key), creates the store and experiment (so parallel
workers never race to create the SQLite database), takes the sweep's lock — a second
launch of the same sweep waits until the first has ended, then finds every config done
— reaps runs left RUNNING by dead processes, finds or creates the parent run
(``kind=sweep``; a relaunch of the same sweep reuses its parent), writes its id to
``<sweep dir>/parent_run_id`` (read by every job, also on a cluster) and
``$MAGLEV_PARENT_RUN_ID``, and logs the lab-level steps once per sweep.
``on_multirun_end`` finishes the parent with a summary.  If the sweep dies (a job
config error, Ctrl-C, SIGTERM) an ``atexit`` hook marks the parent KILLED, or deletes it
when no job ever started a run, and marks KILLED what its jobs left RUNNING.
``RankingCallback.on_multirun_end`` then ranks the sweep and writes its report
(:func:`maglev.study.report.rank_and_report`).
"""

from __future__ import annotations

import atexit
import hashlib
import json
import logging
import os
import signal
import socket
import time
from pathlib import Path
from typing import Any

from hydra.core.hydra_config import HydraConfig
from hydra.experimental.callback import Callback
from omegaconf import DictConfig, OmegaConf

from maglev.study import credentials, heap, shutdown
from maglev.study.config import (StudyConfigError, check, check_lab, config_hash, report_file_name, runs_jobs_here,
                                 task_config)
from maglev.study.lazy import lazy_module, loaded

# imported on first use: a relaunch with nothing to do (maglev.study.resume) ends before MLflow is imported
claims = lazy_module("maglev.study.claims")
datasets = lazy_module("maglev.study.datasets")
environment = lazy_module("maglev.study.environment")
progress = lazy_module("maglev.study.progress")
render = lazy_module("maglev.study.render")
tracking = lazy_module("maglev.study.tracking")

log = logging.getLogger("maglev.study")


def sweep_id(config: DictConfig, task: dict) -> str:
    """Identity of a sweep: its name, sweeper params and command-line overrides (not tracking/hydra)."""
    raw, grids = config.hydra.sweeper.get("params"), config.hydra.sweeper.get("orders")
    params = OmegaConf.to_container(raw, resolve=False) if raw is not None else {}
    overrides = sorted(o for o in config.hydra.overrides.task
                       if not o.lstrip("+~").startswith(("tracking", "hydra")))
    identity = {"name": task["study"]["name"], "params": params, "overrides": overrides}
    if grids:  # a sweep without order grids keeps the identity it had before they existed
        identity["orders"] = OmegaConf.to_container(grids, resolve=False)
    text = json.dumps(identity, sort_keys=True, default=str)
    return hashlib.sha1(text.encode()).hexdigest()


def sweep_size(config: DictConfig) -> int | None:
    """How many jobs the sweep launches (None if unknown): its jobs (:func:`sweep_jobs`) counted, else the
    product of its sweep sizes — the cartesian product of the sweeper params and the command-line sweeps
    (the command line wins for a key given twice).
    """
    from hydra.core.override_parser.overrides_parser import OverridesParser

    try:
        jobs = sweep_jobs(config)
    except StudyConfigError:
        return None  # check_sweep refuses the sweep, naming the key
    if jobs is not None:
        return len(jobs)
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


class SweepRefused(SystemExit):
    """A job's config cannot describe a run: the sweep stops before any run exists (one line, exit status 1).

    A ``SystemExit``: Hydra turns an ``Exception`` raised by a callback into a warning and goes on.
    """


class SweepNotStarted(SystemExit):
    """The sweep's parent could not be set up (the store refused a write, ...): stop before any job (exit
    status 1).  Hydra turns an ``Exception`` from a callback into a warning and runs the jobs anyway —
    without the sweep's lock and with whatever parent id an earlier sweep left in the sweep dir."""


def sweep_jobs(config: DictConfig) -> list[list[str]] | None:
    """Every job's overrides, as the study's sweeper (:mod:`maglev.study.sweeper`: the basic sweeper with an
    order grid per structure) or Hydra's basic sweeper will launch them (None for another sweeper).  A mistake
    in the order grids raises :class:`StudyConfigError` naming the key."""
    from hydra.core.global_hydra import GlobalHydra

    from maglev.study.sweeper import sweep_jobs as jobs

    if not str(config.hydra.sweeper.get("_target_", "")).endswith(("BasicSweeper", "StudySweeper")):
        return None
    grids = config.hydra.sweeper.get("orders")
    grids = OmegaConf.to_container(grids) if grids is not None else None
    hydra_ = GlobalHydra.instance()
    structures = hydra_.config_loader().get_group_options("structure") if grids and hydra_.is_initialized() else None
    choices = config.hydra.get("runtime", {}).get("choices", {})
    return jobs(config.hydra.sweeper.get("params"), list(config.hydra.overrides.task), grids,
                choices.get("structure"), structures)


def check_job_dir(config: DictConfig, overrides: list) -> None:
    """A job's output dir, ``<sweep dir>/<its overrides>`` (Hydra's ``override_dirname``), must stay inside
    the sweep dir: an override value with ``..`` (``dataset.name=a/../../b``) would put it elsewhere."""
    from hydra._internal.config_loader_impl import get_overrides_dirname

    if OmegaConf.to_container(config.hydra.sweep, resolve=False).get("subdir") != "${hydra.job.override_dirname}":
        return  # a subdir of the user's own making
    how = config.hydra.job.config.override_dirname
    sub = get_overrides_dirname(overrides, list(how.exclude_keys), how.item_sep, how.kv_sep)
    top = Path(str(config.hydra.sweep.dir)).resolve()
    if sub and top not in (top / sub).resolve().parents:
        bad = [o.input_line for o in overrides if ".." in Path(o.input_line).parts or o.input_line.endswith("/..")]
        raise StudyConfigError(f"{' '.join(bad) or sub}: the job's folder {sub!r} would lie outside the sweep dir "
                               f"{top} (no '..' in values that name the job's folder)")


def check_sweep(config: DictConfig) -> list[dict]:
    """Compose and :func:`~maglev.study.config.check` every job of the sweep; the first impossible one
    raises :class:`SweepRefused` naming the job and the key.  Returns the jobs' configs (plain, resolved).

    Composing a job costs Hydra ≈ 0.1 s of CPU, so each distinct choice of config groups
    (``dataset=…``, ``structure=…``) is composed once and plain value overrides
    (``structure.order=3``) are applied to a copy, as composition would apply them: a relaunch with
    nothing to do stops after these.  On the basic launcher these compositions are also the ones the
    sweeper's validation and the launcher use (:func:`maglev.study.compose.memoise`).
    """
    from hydra.core.global_hydra import GlobalHydra
    from hydra.core.override_parser.overrides_parser import OverridesParser

    from maglev.study.compose import memoise, split_overrides

    try:
        jobs = sweep_jobs(config)
    except StudyConfigError as exc:
        raise SweepRefused(f"maglev: sweep refused before any run: {exc}") from None
    if not jobs or not GlobalHydra.instance().is_initialized():
        return []
    loader = GlobalHydra.instance().config_loader()
    if runs_jobs_here(config.hydra.launcher):
        memoise(loader)  # the sweeper's validation and the launcher reuse these compositions
    parser = OverridesParser.create()
    composed: dict[tuple[str, ...], DictConfig] = {}
    checked: list[dict] = []
    try:
        for overrides in jobs:
            parsed = parser.parse_overrides(list(overrides))
            plain, base = split_overrides(parsed, loader.repository)
            try:
                if base not in composed:
                    full = loader.load_sweep_config(config, list(base))
                    composed[base] = OmegaConf.masked_copy(full, [k for k in full if k != "hydra"])
                cfg = composed[base].copy()
                for o in plain:
                    OmegaConf.update(cfg, o.key_or_group, o.value(), merge=False)
                job = OmegaConf.to_container(cfg, resolve=True, enum_to_str=True, throw_on_missing=True)
                check(job)
                check_job_dir(config, parsed)
                checked.append(job)
            except StudyConfigError as exc:
                shown = " ".join(o if len(o) <= 80 else f"{o[:60]}…" for o in overrides
                                 if not o.lstrip("+~").startswith(("tracking", "hydra")))
                raise SweepRefused(f"maglev: sweep refused before any run: job {shown}: {exc}") from None
    finally:  # the compositions hold a signal for the job they would start: raised here, refused or not
        shutdown.raise_if_received()
    return checked


class NothingToDo(SystemExit):
    """The relaunch of a finished sweep finds nothing to run, reference, rank or report: exit status 0."""


def ranking_settings(config: DictConfig) -> dict | None:
    """The ranking callback's settings (``structure``, ``report_dir``), None when the sweep is not ranked."""
    for cb in (config.hydra.get("callbacks") or {}).values():
        if str(cb.get("_target_", "")).endswith(".RankingCallback"):
            return {"structure": cb.get("structure"), "report_dir": cb.get("report_dir")}
    return None


def survey(config: DictConfig, task: dict, jobs: list[dict]):
    """Read the store once before any job (:func:`maglev.study.resume.survey`; no MLflow import) and raise
    :class:`NothingToDo` when every job's config is FINISHED in this sweep and its ranking and report are
    those of these runs.  Otherwise returns how many of the jobs' configs have a FINISHED run (None: not
    known)."""
    from maglev.paths import reports_dir
    from maglev.study.resume import survey as read_store

    if not jobs:
        return None
    sid, name = sweep_id(config, task), task["study"]["name"]
    ranking = ranking_settings(config)
    report = None
    if ranking is not None:
        report = Path(ranking["report_dir"]) if ranking["report_dir"] else reports_dir()
        if report.suffix.lower() != ".html":
            report = report / report_file_name(name, sid)
    hashes = [config_hash(j) for j in jobs]
    found = read_store(task["tracking"]["uri"], task["tracking"]["experiment"], sid, hashes,
                       bool(task["lab"]["enabled"]), ranking, report, bool(task["tracking"]["reap"]))
    done = found.done
    if done is None or not all(j["study"]["skip_finished"] for j in jobs):
        return found.finished
    ranked = (f"; ranking run {done.ranking_run} ranked these {done.ranked} runs; report {done.report}"
              if done.ranking_run else "")
    log.info("sweep %r: nothing to do: the %d configs of its %d jobs all have FINISHED runs under parent run "
             "%s%s (study.skip_finished=false runs them again)", name, done.configs, len(jobs), done.parent, ranked)
    raise NothingToDo(0)


class SweepCallback(Callback):
    def __init__(self) -> None:
        self.client = None
        self.parent: str | None = None
        self.fresh = False
        self.lock: Path | None = None
        self.early_renderer = False  # this sweep started the renderer before its configs were checked

    # ------------------------------------------------------------------ start
    def on_multirun_start(self, config: DictConfig, **kwargs: Any) -> None:
        try:
            try:
                self._start(config)
            except SystemExit:  # NothingToDo, SweepRefused: first, as naming tracking.StoreProblem imports MLflow
                raise
            except tracking.StoreProblem as exc:  # says what to do in its one line
                raise SweepNotStarted(f"maglev: {credentials.redact(str(exc))}") from None
            except Exception as exc:  # Hydra would only warn, then run the jobs without lock or parent
                first = str(exc).splitlines()[0] if str(exc) else ""
                raise SweepNotStarted(f"maglev: the sweep could not start: {type(exc).__name__}: "
                                      f"{credentials.redact(first)}") from exc
        except BaseException:
            if self.early_renderer and self.parent is None:  # started for a sweep that did not start: else the
                render.abandon(write=False)  # exit waits for its imports (once the parent exists, _abort stops it)
            raise

    def _start(self, config: DictConfig) -> None:
        from maglev.study.resume import new_sweep

        HydraConfig.instance().set_config(config)  # hydra#3427: ${hydra:...} in the callback
        credentials.redact_logs()  # Hydra logs every job's overrides, a URI's password included
        task = task_config(config)
        name = task["study"]["name"]
        size = sweep_size(config)
        log.info("sweep %r: %s jobs; checking their configs", name, size or "?")  # the first line, within seconds
        here = runs_jobs_here(config.hydra.launcher)
        drawing = bool(task["tracking"]["log_figures"]) and here
        if drawing and new_sweep(task["tracking"]["uri"], task["tracking"]["experiment"], sweep_id(config, task)):
            # a new sweep in a local store runs jobs: the renderer imports while the configs are checked
            self.early_renderer = render.start({})
        jobs = check_sweep(config)
        try:
            check_lab(task)
        except StudyConfigError as exc:
            raise SweepRefused(f"maglev: sweep refused before any run: {exc}") from None
        task["tracking"]["uri"] = credentials.to_env(task["tracking"]["uri"])
        HydraConfig.instance().set_config(config)  # composing the jobs' configs replaced it
        finished = survey(config, task, jobs)
        if finished is not None:
            configs = len({config_hash(j) for j in jobs})
            skipping = all(j["study"]["skip_finished"] for j in jobs)
            log.info("sweep %r: %d configs checked; %d to run, %d FINISHED already%s", name, configs,
                     configs - finished if skipping else len(jobs), finished, " (skipped)" if skipping else "")
        server = tracking.is_http(task["tracking"]["uri"])
        if server:  # one that does not answer ends the sweep here, before the processes below start for nothing
            client, exp_id = tracking.connect(task["tracking"])
        missing = datasets.missing_blas(jobs)
        if missing:
            log.info("estimating the best linear approximations of %s in the background (once; then cached); "
                     "a run that needs one waits for it", ", ".join(ds["name"] for ds in missing))
            datasets.prepare_blas(jobs, missing)  # while the store and the lab steps are made
        shutdown.mark_launcher()  # the processes started from here end with this one
        if drawing:  # unless started above: its process imports while the store is made; MLflow's HTTP bounds first
            render.start(tracking.tracking_env(task["tracking"]))
        if not server:  # a SQLite store is made while the processes above import
            client, exp_id = tracking.connect(task["tracking"])
        heap.settle()  # MLflow and the configs' checks have imported what the runs need
        self.client, self.exp_id = client, exp_id
        sid = sweep_id(config, task)
        sweep_dir = Path(config.hydra.sweep.dir).resolve()
        self.lock = claims.sweep_lock_path(task["tracking"]["uri"], sweep_dir, sid)
        claims.acquire_sweep(self.lock, lambda holder: log.warning(
            "sweep %r is being run by %s; waiting for it to end (its finished configs are then skipped)",
            name, holder))
        if task["tracking"]["reap"]:
            from maglev.study.reap import reap

            killed = reap(client, [exp_id])
            if killed:
                log.warning("marked %d stale RUNNING run(s) KILLED", len(killed))
        found = client.search_runs([exp_id], filter_string=f"tags.sweep_id = '{sid}' and tags.kind = 'sweep'",
                                   order_by=["attributes.start_time DESC"], max_results=1)
        tags = {"kind": "sweep", "sweep": name, "sweep_id": sid, "sweep_dir": str(sweep_dir),
                "hydra.overrides": credentials.redact(" ".join(config.hydra.overrides.task))[:5000],
                "launcher": str(config.hydra.launcher.get("_target_", "")), **tracking.process_tags()}
        if found:
            self.parent, self.fresh = found[0].info.run_id, False
            client.update_run(self.parent, status="RUNNING")
            tracking.log_batch(client, self.parent, tags={**tags, "resumed": "true"})
        else:
            self.parent = client.create_run(exp_id, run_name=name, tags=tags).info.run_id
            self.fresh = True
            self._log_environment()
        sweep_dir.mkdir(parents=True, exist_ok=True)
        (sweep_dir / tracking.PARENT_FILE).write_text(self.parent)
        os.environ[tracking.PARENT_ENV] = self.parent
        if size:
            os.environ[tracking.SIZE_ENV] = str(size)
        atexit.register(self._abort)
        log.info("sweep %r: parent run %s (%s) in %s", name, self.parent,
                 "new" if self.fresh else "resumed", credentials.public(task["tracking"]["uri"]))
        if task["lab"]["enabled"] and (self.fresh or found[0].data.tags.get("lab_logged") != "true"):
            # queued on the renderer when this sweep started one: made there while the runs estimate, and
            # waited for before the ranking (render.drain); else made here
            queued = render.submit_lab(task["tracking"]["uri"], self.parent, task, jobs)
            log.info("sweep %r: the lab steps (working region, rise time and Ts, output spectrum, alpha*) on its "
                     "parent run%s", name, ", made in the background while the runs go on" if queued else "")
            if not queued:
                self._log_lab(task, jobs)
        os.environ[progress.START_ENV] = str(time.time())  # the runs start: their ETA counts from here
        if here:
            shutdown.between_jobs()  # jobs run here: Hydra composes the first one

    def _log_environment(self) -> None:
        """``environment/requirements.txt``: what `pip install -r` needs to rebuild this environment. Like the
        lab steps it informs, so a store that refuses it is a warning, not the end of the sweep."""
        try:
            self.client.log_text(self.parent, environment.requirements(environment.current()), environment.ARTIFACT)
        except Exception as exc:
            log.warning("environment not recorded: %s: %s", type(exc).__name__, exc)

    def _log_lab(self, task: dict, jobs: list[dict]) -> None:
        warning = render.log_lab(self.client, self.parent, task, jobs)
        if warning:
            log.warning("%s", warning)

    # ------------------------------------------------------------------ end
    def on_multirun_end(self, config: DictConfig, **kwargs: Any) -> None:
        shutdown.raise_if_received()  # a signal held between jobs, or whose exception was lost: the sweep did not end
        if self.parent is None:
            return
        render.drain()  # the last runs' figures: their runs are FINISHED once drawn (a dead server: _abort at exit)
        atexit.unregister(self._abort)
        kids = tracking.children(self.client, self.exp_id, self.parent)
        counts: dict[str, int] = {}
        for r in kids:
            counts[r.info.status] = counts.get(r.info.status, 0) + 1
        refs = len(claims.referenced(self.client, self.exp_id, self.parent))
        tracking.log_batch(self.client, self.parent,
                           metrics={**{f"runs_{s.lower()}": n for s, n in counts.items()}, "runs_referenced": refs})
        from maglev.study.ranking import describe_sweep

        describe_sweep(self.client, self.parent)  # what was swept, the top four and cautions if ranked
        self.client.set_terminated(self.parent, "FINISHED")
        claims.release_sweep(self.lock)
        os.environ.pop(tracking.PARENT_ENV, None)
        os.environ.pop(tracking.SIZE_ENV, None)
        summary = ", ".join(f"{n} {s}" for s, n in sorted(counts.items())) or "no runs"
        log.info("sweep done: %s under parent run %s%s", summary, self.parent,
                 f" (and {refs} run(s) of other sweeps with the same configs)" if refs else "")
        if counts.get("FAILED"):
            log.warning("%d run(s) FAILED; their error.txt artifacts say why", counts["FAILED"])

    def _abort(self) -> None:
        """atexit: the sweep did not reach on_multirun_end (a job raised, Ctrl-C, SIGTERM)."""
        if self.parent is None:
            return
        # the renderer only where this process started it: importing it at exit fails (a Slurm launcher's)
        drawing = render.abandon(write=tracking.unreachable is None) if loaded(render) else []
        why = signal.Signals(shutdown.received).name if shutdown.received else "stopped before its end"
        if tracking.unreachable is not None:  # nothing can be marked; the exit line says why
            claims.release_sweep(self.lock)
            return
        try:
            kids = tracking.children(self.client, self.exp_id, self.parent)
            if self.fresh and not kids:
                self.client.delete_run(self.parent)
                log.warning("sweep stopped (%s) before any run: its parent run %s is deleted", why, self.parent)
            else:
                self.client.set_terminated(self.parent, "KILLED")
                left = self._reap_leftovers()
                after = tracking.children(self.client, self.exp_id, self.parent)
                killed = {r.info.run_id for r in after if r.info.status == "KILLED"}
                finished = sum(r.info.status == "FINISHED" for r in after)
                parts = [f"{len(set(drawing) & killed)} not finished by the renderer" if drawing else "",
                         f"{len(set(left) & killed)} left RUNNING by a process that is gone" if left else ""]
                detail = f"{len(killed)} KILLED" + (f" ({', '.join(p for p in parts if p)})" if any(parts) else "")
                log.warning("sweep stopped (%s): parent run %s KILLED; its runs: %d FINISHED, %s; the same command "
                            "again runs what is not FINISHED", why, self.parent, finished, detail)
        except Exception:  # noqa: BLE001 — best effort at interpreter exit
            pass
        finally:
            shutdown.reported = True
            claims.release_sweep(self.lock)

    def _reap_leftovers(self, timeout: float = 20.0) -> list[str]:
        """Mark KILLED the runs this sweep left RUNNING on this host: this process's own (a ranking run in
        flight) and the parent's children whose process is gone.  Workers that got the signal mark their
        own runs KILLED; wait for them (at most ``timeout`` s: Slurm's SIGKILL follows 30 s after SIGTERM),
        then mark what is left — joblib kills its workers when the main process dies."""
        from maglev.study.reap import _alive

        host, me = socket.gethostname(), os.getpid()

        def pid(run) -> int | None:
            text = run.data.tags.get("pid", "")
            return int(text) if text.isdigit() else None

        def ours(run) -> bool:
            return pid(run) == me or run.data.tags.get("mlflow.parentRunId") == self.parent

        end = time.monotonic() + timeout
        while True:
            running = [r for r in self.client.search_runs(
                [self.exp_id], filter_string=f"attributes.status = 'RUNNING' and tags.host = '{host}'",
                max_results=50000) if ours(r) and r.info.run_id != self.parent]
            alive = [r for r in running if pid(r) not in (None, me) and _alive(pid(r))]
            if not alive or time.monotonic() > end:
                break
            time.sleep(0.5)
        for r in running:
            self.client.set_tag(r.info.run_id, "reaped", "left RUNNING when the sweep was stopped")
            self.client.set_terminated(r.info.run_id, "KILLED")
        return [r.info.run_id for r in running]


REFERENCE_WAIT_S = 600.0  # how long a sweep's ranking waits for its configs' runs in other launches


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

        shutdown.raise_if_received()
        HydraConfig.instance().set_config(config)
        render.drain()  # Hydra ends callbacks in reverse order: this one runs before SweepCallback's end
        task = task_config(config)
        parent = tracking.sweep_parent(str(config.hydra.sweep.dir))
        if parent is None:
            log.warning("ranking skipped: no parent run id in %s", config.hydra.sweep.dir)
            return
        log.info("sweep %r: ranking its runs and writing the report", task["study"]["name"])
        try:
            self._wait_for_references(task["tracking"], parent)
            rank_and_report(task["tracking"]["uri"], task["tracking"]["experiment"], parent,
                            self.structure, self.report_dir, reuse=True)
        except SweepError as exc:
            log.warning("ranking/report not made: %s", exc)
        except Exception as exc:  # noqa: BLE001 — a report bug must not fail a finished sweep
            log.exception("ranking/report failed: %s: %s", type(exc).__name__, exc)

    @staticmethod
    def _wait_for_references(tracking_cfg: dict, parent: str) -> None:
        """Configs of this sweep that another launch is running (a second user's sweep into the same server):
        wait for their runs (at most ``REFERENCE_WAIT_S``), so the ranking has every config of the sweep."""
        client, exp_id = tracking.connect(tracking_cfg)
        running = claims.wait_for_references(client, exp_id, parent, 0)
        if not running:
            return
        log.info("waiting (at most %.0f s) for %d run(s) of other launches that hold configs of this sweep: %s",
                 REFERENCE_WAIT_S, len(running), ", ".join(r.info.run_name for r in running))
        left = claims.wait_for_references(client, exp_id, parent, REFERENCE_WAIT_S)
        if left:
            log.warning("%d run(s) still RUNNING after %.0f s are left out of the ranking: %s", len(left),
                        REFERENCE_WAIT_S, ", ".join(r.info.run_name for r in left))
