"""The ``maglev`` command: every operation on the study and the simulator, one subcommand each.

    maglev rank       [--tracking-uri URI] [--experiment NAME] [--parent RUN_ID] [--structure S] [--force]
    maglev report     [--tracking-uri URI] [--experiment NAME] [--parent RUN_ID] [--structure S] [--out FILE|DIR] [--pdf]
    maglev reproduce  RUN_ID [--tracking-uri URI] [--data-dir DIR] [--log]
    maglev reap       [--tracking-uri URI] [--experiment NAME] [--older-than-hours H]
    maglev ui         [--tracking-uri URI] [--port 5000]
    maglev labdata    --out DIR [--seed N]          (the simulator's lab dataset)
    maglev calibrate  [--refdata DIR] [--no-fit] [--plant NAME] [--seed N] [--markdown PATH]
                                                    (refit the simulator to the real records)

``python -m maglev …`` is the same command.  The store defaults to
:func:`maglev.paths.default_store_uri` (``$MLFLOW_TRACKING_URI`` or the project's
``mlruns/mlflow.db``).  User mistakes print one line on stderr and exit 2.
"""

from __future__ import annotations

import argparse
import sys
import warnings
from collections.abc import Callable

warnings.filterwarnings("ignore", message="The .*noload.* loader strategy is deprecated")

def _store_args(p: argparse.ArgumentParser, sweep: bool = True) -> None:
    from maglev.structures import names as structure_names

    p.add_argument("--tracking-uri", default=None,
                   help="default: $MLFLOW_TRACKING_URI or sqlite:///<repo>/mlruns/mlflow.db")
    p.add_argument("--experiment", default="maglev", help="MLflow experiment (default: maglev)")
    if sweep:
        p.add_argument("--parent", default=None, help="the sweep's parent run id (default: the latest sweep)")
        p.add_argument("--structure", default=None, choices=structure_names(),
                       help="structure of the binary vs uniform comparison (default: best with both classes)")


def _uri(a: argparse.Namespace) -> str:
    from maglev.paths import default_store_uri
    from maglev.study.credentials import to_env

    return to_env(a.tracking_uri or default_store_uri())  # a server's user and password: MLflow's variables


def _rank(a: argparse.Namespace) -> int:
    from maglev.study.store import load_sweep

    sweep = load_sweep(_uri(a), a.experiment, a.parent)  # a missing store is answered before the ranking's imports
    from maglev.study.ranking import compute, log_ranking, previous_ranking_run, top_text, ui_hint

    ranking = compute(sweep, a.structure, draw=False)
    run_id = None if a.force else previous_ranking_run(ranking)
    reused = run_id is not None
    if not reused:
        ranking = compute(sweep, a.structure, ranked=ranking)
        run_id = log_ranking(ranking)
    print(top_text(ranking))
    for note in ranking.notes:
        print(f"  note: {note}")
    again = " (reused: it ranked these same runs; --force logs a new one)" if reused else ""
    print(f"ranking run {run_id}{again}\n  {ui_hint(sweep, run_id)}")
    return 0


def _report(a: argparse.Namespace) -> int:
    from maglev.study.report import rank_and_report
    from maglev.study.report.pdf import PdfError, chromium

    if a.pdf and chromium() is None:  # refused before anything is ranked or logged
        raise PdfError("--pdf needs Chromium on PATH (chromium or chromium-browser; e.g. apt-get install chromium)")
    rank_and_report(_uri(a), a.experiment, a.parent, a.structure, a.out, a.pdf)
    return 0


def _reproduce(a: argparse.Namespace) -> int:
    from maglev.study.reproduce import reproduce, same, within_rounding

    ok, rows = reproduce(a.run_id, _uri(a), a.data_dir, a.log)
    width = max((len(k) for k, *_ in rows), default=6)
    print(f"{'metric':{width}s}  {'logged':>22s}  {'recomputed':>22s}")
    for key, old, new in rows:
        mark = "" if same(old, new) else "ROUNDING" if within_rounding(old, new) else "DIFFERENT"
        print(f"{key:{width}s}  {old:22.15g}  {new:22.15g}  {mark}")
    n_diff = sum(not within_rounding(o, n) for _, o, n in rows)
    n_rounded = sum(not same(o, n) for _, o, n in rows) - n_diff
    verdict = ("metrics identical" if ok else f"{n_diff} metric(s) differ" if n_diff
               else f"metrics equal to rounding ({n_rounded} differ in their last digits only)")
    print(f"run {a.run_id}: {verdict} ({len(rows)} compared, timings excluded)")
    return 0 if n_diff == 0 and rows else 1


def _reap(a: argparse.Namespace) -> int:
    from maglev.study.reap import reap
    from maglev.study.store import open_store

    client, exp_id = open_store(_uri(a), a.experiment)
    killed = reap(client, [exp_id], a.older_than_hours)
    print(f"{len(killed)} stale run(s) marked KILLED" + (": " + " ".join(killed) if killed else ""))
    return 0


def _ui(a: argparse.Namespace) -> int:
    from maglev.study.ui import serve

    return serve(_uri(a), a.experiment, a.host, a.port)


def _forward(module: str) -> Callable[[list[str]], int]:
    def run(argv: list[str]) -> int:
        import importlib

        return importlib.import_module(module).main(argv)

    return run


# the simulator's commands keep their own options (they live below the study layer)
FORWARDED = {"labdata": ("maglev.sim.labdata", "write the simulated lab dataset (.mat and .csv)"),
             "calibrate": ("maglev.sim.calibrate", "refit the simulator to the real records and print sim vs real")}


def parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="maglev", description=__doc__.split("\n\n")[0])
    sub = p.add_subparsers(dest="command", required=True, metavar="COMMAND")
    rank = sub.add_parser("rank", help="rank a sweep's runs and log a ranking run")
    _store_args(rank)
    rank.add_argument("--force", action="store_true",
                      help="log a new ranking run even if one ranked exactly these runs")
    rank.set_defaults(func=_rank)
    report = sub.add_parser("report", help="write a sweep's lab report (HTML) and log it")
    _store_args(report)
    report.add_argument("--out", default=None, help="output file or directory (default: reports/<sweep>-<id>.html)")
    report.add_argument("--pdf", action="store_true", help="also print it to an A4 PDF beside it (needs Chromium)")
    report.set_defaults(func=_report)
    repro = sub.add_parser("reproduce", help="recompute a run from its logged config; exit 0 if identical")
    repro.add_argument("run_id")
    repro.add_argument("--tracking-uri", default=None, help="default: $MLFLOW_TRACKING_URI or the local store")
    repro.add_argument("--data-dir", default=None, help="where the real records are, if not where they were")
    repro.add_argument("--log", action="store_true", help="log the reproduction as a new run")
    repro.set_defaults(func=_reproduce)
    reap = sub.add_parser("reap", help="mark runs left RUNNING by dead processes KILLED")
    _store_args(reap, sweep=False)
    reap.add_argument("--older-than-hours", type=float, default=None,
                      help="also runs of any host started longer ago than this")
    reap.set_defaults(func=_reap)
    ui = sub.add_parser("ui", help="start the MLflow UI on the store (one worker, 127.0.0.1)")
    _store_args(ui, sweep=False)
    ui.add_argument("--host", default="127.0.0.1")
    ui.add_argument("--port", type=int, default=5000)
    ui.set_defaults(func=_ui)
    for name, (_, text) in FORWARDED.items():
        sub.add_parser(name, help=text, add_help=False)
    return p


def main(argv: list[str] | None = None) -> int:
    from maglev.study.store import SweepError

    argv = list(sys.argv[1:] if argv is None else argv)
    if argv and argv[0] in FORWARDED:
        return _forward(FORWARDED[argv[0]][0])(argv[1:])
    a = parser().parse_args(argv)
    try:
        return a.func(a)
    except SweepError as exc:
        print(f"maglev {a.command}: {exc}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    raise SystemExit(main())
