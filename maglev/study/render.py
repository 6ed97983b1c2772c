"""Draw a sweep's run figures, and make its lab steps, in a background process, so the runs estimate meanwhile.

A run's five figures cost far more than its estimation (matplotlib's text layout and
rasterising) and no number depends on them.  In a sweep on the basic launcher, a job
estimates, hands the rest of its run (:class:`maglev.study.finish.Work`: the validation no later
job needs, the uploads, the figures) to the renderer (one process, started with the sweep) and
returns; the renderer validates, logs, draws, uploads the PNGs and only then marks the run
FINISHED, so FINISHED still means complete (:func:`maglev.study.finish.complete`; a failure there
ends the run FAILED with its error, and the launcher prints it).  The sweep callback waits
for it (:func:`drain`) before it counts the runs and the ranking reads them.  A single
run, or a job in a joblib worker (already one of several processes), draws inline.

The sweep's lab steps (:func:`log_lab`) go to the renderer too, first: no run needs them, only
the ranking and the report, which read them after :func:`drain`; so the first runs estimate
while they are made instead of after them.
"""

from __future__ import annotations

import contextlib
import logging
import multiprocessing
from concurrent.futures import Future, ProcessPoolExecutor
from concurrent.futures.process import BrokenProcessPool
from typing import Callable

from maglev.study import shutdown

log = logging.getLogger("maglev.study")

# One renderer: a run's five figures take ≈ 0.2 s of CPU (drawn on the figures of the run before), less than
# the time from one run to the next, so one process keeps up on the second core; a second one cost ≈ 3-5 s
# more CPU per sweep (its imports) for no shorter sweep (36-48 s both ways at load 1.5-2.5,
# bench/study_overhead.py --sweep)
WORKERS = 1
STOPPED = "the sweep stopped before the renderer finished this run"  # the error tag of a run a signal left undrawn
_pool: ProcessPoolExecutor | None = None
_pending: dict[str, tuple[str, Future, object, Callable]] = {}  # run id -> (tracking URI, its render, inputs, task)
_figures: dict = {}  # this process's run figures, drawn again for every run (maglev.study.figures.run_figures)
_lab: tuple[Future, tuple] | None = None  # the sweep's lab steps queued on the renderer, and their arguments
_gone: BaseException | None = None  # the store's server was found dead here: every later task says so at once


def _task(task: Callable, uri: str, *args):
    """``task(uri, *args)`` as the renderer runs it: when it fails and ``uri`` is a server that no longer
    answers, :class:`maglev.study.tracking.TrackingUnreachable` instead — printed by nothing here: the launcher
    gets it (drain raises it: the sweep's one line) — and every later task raises it at once rather than wait
    out MLflow's retries against the dead server again."""
    from maglev.study import tracking

    global _gone
    if _gone is not None:
        raise _gone
    try:
        try:
            return task(uri, *args)
        except Exception:
            tracking.raise_if_unreachable(uri)
            raise
    except tracking.TrackingUnreachable as exc:
        _gone = exc
        raise


def draw_and_finish(uri: str, run_id: str, inputs, client=None) -> None:
    """Draw the run's figures, upload them and mark the run FINISHED (a drawing error is tagged, not fatal:
    the run's numbers are complete).  ``client``: the store's, if the caller has one."""
    import matplotlib

    matplotlib.use("Agg")
    from mlflow import MlflowClient

    from maglev.study import tracking
    from maglev.study.figures import RUN_DPI, png, run_figures

    client = MlflowClient(tracking_uri=uri) if client is None else client
    try:
        figures = run_figures(inputs, reuse=_figures)
        tracking.log_files(client, run_id, {f"figures/{name}": png(fig, RUN_DPI) for name, fig in figures.items()})
    except Exception as exc:  # noqa: BLE001 — a plotting bug must not lose a run
        tracking.log_batch(client, run_id, tags={"figures_error": f"{type(exc).__name__}: {exc}"[:4000]})
    client.set_terminated(run_id, "FINISHED")


def log_lab(client, parent: str, task: dict, jobs: list[dict]) -> str | None:
    """The sweep's lab steps (:func:`maglev.study.lab.lab_steps`) logged on its parent run: their figures,
    ``lab/lab.json``, ``lab/decisions.json``, metrics and the tag ``lab_logged``.  They are informative and
    the sweep goes on without them: returns None, or the warning to print when they failed (tagged
    ``lab_error`` on the parent)."""
    from maglev.study import tracking
    from maglev.study.lab import lab_steps

    try:
        metrics, figures, summary = lab_steps(task, jobs)
    except Exception as exc:  # noqa: BLE001
        tracking.log_batch(client, parent, tags={"lab_error": f"{type(exc).__name__}: {exc}"})
        return f"lab steps failed: {type(exc).__name__}: {exc}"
    from maglev.study.figures import png

    files = {f"lab/{k}": png(fig) for k, fig in figures.items()}
    files["lab/decisions.json"] = summary.pop("decisions")  # schema: maglev.lab.decision
    files["lab/lab.json"] = summary
    tracking.log_files(client, parent, files)
    tracking.log_batch(client, parent, metrics=metrics, tags={"lab_logged": "true"})
    return None


def _log_lab_here(uri: str, parent: str, task: dict, jobs: list[dict]) -> str | None:
    from mlflow import MlflowClient

    return log_lab(MlflowClient(tracking_uri=uri), parent, task, jobs)


def submit_lab(uri: str, parent: str, task: dict, jobs: list[dict]) -> bool:
    """Queue the sweep's lab steps on the renderer, ahead of the runs' figures; False (nothing queued) when
    no renderer was started: the caller makes them itself."""
    global _lab
    if _pool is None:
        return False
    args = (uri, parent, task, jobs)
    try:
        _lab = (_pool.submit(_task, _log_lab_here, *args), args)
    except BrokenProcessPool:
        return False
    return True


def _drain_lab() -> None:
    """Wait for the lab steps queued on the renderer (made here if it has not started them); a failure is
    a warning, as when the callback makes them, and a dead server the sweep's end (``TrackingUnreachable``)."""
    global _lab
    if _lab is None:
        return
    (fut, args), _lab = _lab, None
    try:
        warning = _task(_log_lab_here, *args) if fut.cancel() else fut.result()
    except Exception as exc:  # noqa: BLE001 — the renderer died, or the store refused the upload
        warning = f"lab steps not logged: {type(exc).__name__}: {exc}"
    if warning:
        log.warning("%s", warning)


def _worker_start(env: dict[str, str], launcher: int) -> None:
    """In each renderer process, before anything else: Ctrl-C's default action, MLflow's HTTP bounds (``env``)
    and an end with the launcher; then import what drawing needs, before the first run's figures arrive."""
    import os
    import signal

    from maglev.study import heap

    heap.hold()  # settled once drawing's libraries are in, below
    # Ctrl-C reaches the whole process group: the renderer ends at once and quietly (the system's default, no
    # traceback), as at the SIGTERM its launcher forwards; the launcher marks the runs it left KILLED (abandon).
    # Ignored, it drew every run queued before the launcher could exit: the executor's exit hook waits for
    # them, and runs before the sweep's atexit cleanup that would have stopped it (≈ 4 s of a test's sweep)
    signal.signal(signal.SIGINT, signal.SIG_DFL)
    os.environ.update(env)
    import atexit

    from maglev.study.shutdown import exit_with, skip_teardown

    # its end: the launcher waits for this process at its own exit (concurrent.futures joins it)
    atexit.register(skip_teardown, 0)
    exit_with(launcher)
    import matplotlib

    matplotlib.use("Agg")
    import mlflow  # noqa: F401

    import control  # noqa: F401  (the runs' small-signal Jacobian)

    import maglev.study.figures  # noqa: F401
    import maglev.study.identify  # noqa: F401  (the runs' validation: maglev.study.finish)
    import maglev.study.tracking  # noqa: F401

    heap.settle()


def start(env: dict[str, str] | None = None) -> bool:
    """Start the renderer now (a sweep's start: its processes import while the configs are checked and the
    store is made), not at the first run's figures; False when one is running already.  ``env``: MLflow's
    HTTP bounds for it (default: this process's ``MLFLOW_HTTP_REQUEST_*`` variables)."""
    import os

    global _pool
    if _pool is not None:
        return False
    if env is None:
        env = {k: v for k, v in os.environ.items() if k.startswith("MLFLOW_HTTP_REQUEST_")}
    _pool = ProcessPoolExecutor(max_workers=WORKERS, mp_context=multiprocessing.get_context("spawn"),
                                initializer=_worker_start, initargs=(env, os.getpid()))
    for _ in range(WORKERS):  # a spawned pool starts its processes on demand
        _pool.submit(int)
    return True


def submit(uri: str, run_id: str, inputs, task: Callable = draw_and_finish) -> None:
    """Queue ``task(uri, run_id, inputs)`` on the background renderer (started on first use): by default the
    run's figures; a task that returns a line (a run it ended FAILED) has it printed here as an error."""
    global _pool
    for _ in range(2):
        if _pool is None:
            start()
        try:
            fut = _pool.submit(_task, task, uri, run_id, inputs)
            _pending[run_id] = (uri, fut, inputs, task)
            fut.add_done_callback(_say)
            return
        except BrokenProcessPool:  # the renderer died earlier: start a new one
            _pool = None
    raise RuntimeError("the figure renderer cannot be started")


def offload(fn: Callable, *args) -> Callable[[], object]:
    """``fn(*args)`` on the renderer when one is running — idle once the sweep is drained, while the ranking and
    the report are made here — else here when asked; returns the function that waits for its value (made here
    if the renderer died meanwhile, or if the arguments do not pickle)."""
    import pickle

    fut = None
    if _pool is not None:
        try:
            pickle.dumps(args)  # the pool would fail on them in its feeder thread
            fut = _pool.submit(fn, *args)
        except (pickle.PicklingError, AttributeError, TypeError, BrokenProcessPool, RuntimeError):
            fut = None  # not picklable (a python-control system's lambda), or the renderer is broken or shut down

    def value():
        if fut is not None:
            try:
                return fut.result()
            except BrokenProcessPool:
                pass
        return fn(*args)

    return value


def _say(fut: Future) -> None:
    """A task's line, printed as soon as the renderer ends it (in this process's pool thread)."""
    if not fut.cancelled() and fut.exception() is None and fut.result():
        log.error("%s", fut.result())


def pending() -> list[str]:
    """Run ids whose figures are not drawn yet."""
    return [run_id for run_id, (_, fut, _, _) in _pending.items() if not fut.done()]


def drain() -> dict[str, str]:
    """Wait for every queued render, drawing runs the renderer has not started yet here, beside it (the
    caller waits anyway, and the renderer lags a few runs behind at a sweep's end): this process takes them
    from the back of the queue while the renderer goes on from the front, until they meet.  Returns ``{run
    id: error}`` for runs that could not be finished (the renderer's process died, or uploading failed):
    those are marked FAILED with the error, never left RUNNING.  The lab steps queued first are waited for
    before the runs the renderer draws.  A server that stopped answering raises
    :class:`maglev.study.tracking.TrackingUnreachable` (its one line ends the sweep), here or in the renderer."""
    failed = {}
    # the renderer takes its tasks in order: once the last one left cannot be cancelled, it has them all
    while _pending:
        run_id = next(reversed(_pending))
        if not _pending[run_id][1].cancel():
            break
        uri, _, inputs, task = _pending.pop(run_id)
        try:
            said = _task(task, uri, run_id, inputs)
            if said:
                log.error("%s", said)
        except Exception as exc:  # noqa: BLE001 — e.g. the store refused the upload
            failed[run_id] = f"{type(exc).__name__}: {exc}"
            _fail(uri, run_id, failed[run_id])
    _drain_lab()
    for run_id, (uri, fut, _, _) in list(_pending.items()):
        try:
            fut.result()
        except Exception as exc:  # noqa: BLE001 — e.g. BrokenProcessPool: the renderer died
            failed[run_id] = f"{type(exc).__name__}: {exc}"
            if shutdown.received:  # Ctrl-C (or SIGTERM) ended the renderer too: the run was stopped, not failed
                _fail(uri, run_id, STOPPED, "KILLED", quiet=True)
            else:
                _fail(uri, run_id, failed[run_id])
        _pending.pop(run_id, None)
    return failed


def abandon(status: str = "KILLED", write: bool = True) -> list[str]:
    """Stop the renderer without waiting (the sweep is dying; its process is terminated, or the
    interpreter's exit would wait for the figures in flight): runs whose figures were not drawn get
    ``status`` — those still queued, in flight, and those whose renderer died (SIGTERM reaches it too).
    ``write=False``: mark nothing (the store cannot be reached).  Lab steps not made are left for the next
    launch of the sweep (its parent run lacks ``lab_logged``)."""
    global _pool, _lab, _gone
    _lab = _gone = None
    left = [run_id for run_id, (_, fut, _, _) in _pending.items()
            if not (fut.done() and not fut.cancelled() and fut.exception() is None)]
    if _pool is not None:
        processes = list((_pool._processes or {}).values())
        _pool.shutdown(wait=False, cancel_futures=True)
        for process in processes:
            with contextlib.suppress(ProcessLookupError):  # it ended meanwhile (SIGTERM reaches it too)
                process.terminate()
        _pool = None
    for run_id in left if write else []:
        try:
            _fail(_pending[run_id][0], run_id, STOPPED, status, quiet=True)
        except Exception as exc:  # noqa: BLE001 — the store may be gone too; mark the others
            log.error("run %s left RUNNING: %s: %s", run_id, type(exc).__name__, exc)
    _pending.clear()
    return left


def _fail(uri: str, run_id: str, error: str, status: str = "FAILED", quiet: bool = False) -> None:
    from mlflow import MlflowClient

    from maglev.study import tracking

    client = MlflowClient(tracking_uri=uri)
    tracking.log_batch(client, run_id, tags={"error": f"figures: {error}"[:4000]})
    client.set_terminated(run_id, status)
    log.log(logging.DEBUG if quiet else logging.ERROR, "run %s %s: figures not drawn: %s", run_id, status, error)
