"""The lab report of a sweep as one self-contained HTML page (figures embedded as base64 PNG).

Holds what EL2820 Lab 3 §5 asks for, each section with its numbers (:mod:`.sections`):
the working region and its motivation, the three input signals and why (ranges vs the
working region, α* from the spectra), the data used for estimation and validation, the
structures and the motivation of their orders (loss/FPE/AIC vs order, near pole-zero
cancellations), the top-four ranking, binary vs uniform input for one structure, and
best vs worst.  Written to ``reports/<sweep>-<id>.html`` (default; ``<id>``: the first 8
characters of the sweep's ``sweep_id``, so two sweeps of one name never overwrite each
other's report, and a relaunch of the same sweep updates its own) and logged under the
same name to the sweep's ranking run — the latest FINISHED one that ranked the same
runs, else a new one.  ``maglev report`` and the end-of-sweep callback call it.
"""

from __future__ import annotations

import datetime as dt
import html
from pathlib import Path

from maglev.paths import reports_dir
from maglev.study.ranking import Ranking, compute, log_ranking, previous_ranking_run, report_name, top_text, ui_hint
from maglev.study.report import sections as sec
from maglev.study.store import SweepError, artifact_bytes, artifact_json, load_model, load_sweep
from maglev.study.tracking import log_files

LAB_FIGURES = ("working_region.png", "rise_time.png", "output_spectrum.png", "alpha.png", "orders.png")
CSS = """
body{font-family:system-ui,sans-serif;max-width:1250px;margin:2em auto;padding:0 1em;color:#222;line-height:1.4}
h1{font-size:1.6em} h2{border-bottom:2px solid #ccc;padding-bottom:.2em;margin-top:2em} h3{margin-bottom:.2em}
table.t{border-collapse:collapse;font-size:.85em;margin:.6em 0} table.t td,table.t th{border:1px solid #ccc;
padding:2px 6px;text-align:right} table.t th{background:#f2f2f2} figure{margin:.5em 0;display:inline-block}
img{max-width:100%} .row{display:flex;flex-wrap:wrap;gap:1em} .row figure{flex:1 1 45%}
figcaption{font-size:.85em;color:#555} .missing{color:#a00} nav a{margin-right:1em} .meta{color:#555;font-size:.9em}
"""
SECTIONS = [("cautions", "Cautions"), ("preparation", "Preparation tasks"), ("working-region", "Working region"), ("inputs", "Input signals"), ("data", "Data"),
            ("structures", "Structures and orders"), ("top4", "Top four"),
            ("binary-vs-uniform", "Binary vs uniform"), ("best-vs-worst", "Best vs worst")]


def lab_steps(ranking: Ranking) -> tuple[dict, dict]:
    """The parent run's lab-level numbers (metrics and ``lab/lab.json``) and figures (name -> PNG)."""
    sweep = ranking.sweep
    lab = {k: v for k, v in sweep.parent.data.metrics.items() if k.startswith("lab.")}
    lab.update(artifact_json(sweep.client, sweep.parent_id, "lab/lab.json") or {})
    figures = {name: artifact_bytes(sweep.client, sweep.parent_id, f"lab/{name}") for name in LAB_FIGURES}
    return lab, figures


def build(ranking: Ranking, ranking_run: str) -> str:
    """The report page for ``ranking`` (logged as run ``ranking_run``)."""
    from maglev.study.datasets import load

    sweep = ranking.sweep
    lab, lab_png = lab_steps(ranking)
    datasets = {n: load(c["dataset"], c["data_dir"]) for n, c in sorted(ranking.configs.items())}
    if not datasets:
        raise SweepError("cannot rebuild the sweep's datasets for the report: " + "; ".join(ranking.notes))
    models = {**{rid: load_model(sweep.client, rid) for rid in ranking.table["run_id"]
                 if rid not in ranking.models}, **ranking.models}
    ts_used = sorted(set(float(t) for t in ranking.table["Ts"].dropna())) if "Ts" in ranking.table else []
    tags = sweep.parent.data.tags
    head = (f"<h1>System identification of the magnetic levitator — sweep {html.escape(sweep.name)}</h1>"
            f"<p class='meta'>Parent run {sweep.parent_id}, ranking run {ranking_run}, experiment "
            f"{html.escape(sweep.experiment)} in {html.escape(sweep.uri)}; git {tags.get('git_commit', '?')[:10]}"
            f"{' (dirty)' if tags.get('git_dirty') == 'true' else ''}; generated "
            f"{dt.datetime.now().isoformat(timespec='seconds')}.<br>MLflow UI: "
            f"<code>{html.escape(ui_hint(sweep, ranking_run))}</code></p>"
            "<nav>" + "".join(f"<a href='#{a}'>{t}</a>" for a, t in SECTIONS) + "</nav>")
    body = [
        sec.cautions(ranking.cautions),
        sec.preparation(lab, ts_used, ranking.configs, ranking.table),
        sec.working_region(lab, lab_png, ts_used),
        sec.input_signals(datasets, ranking.configs, lab, lab_png),
        sec.data_amounts(ranking.table, datasets, ranking.configs),
        sec.structures(ranking.table, models, lab, lab_png),
        sec.top_four(ranking),
        sec.binary_vs_uniform(ranking),
        sec.best_vs_worst(ranking, models),
    ]
    return (f"<!DOCTYPE html><html lang='en'><head><meta charset='utf-8'><title>maglev report: "
            f"{html.escape(sweep.name)}</title><style>{CSS}</style></head><body>{head}{''.join(body)}"
            "</body></html>\n")


def report_path(sweep, out: str | Path | None = None) -> Path:
    """Where the report goes: ``out`` if it names an ``.html`` file, else ``report_name`` in ``out`` (a
    directory; None: ``reports/``)."""
    path = Path(out) if out else reports_dir()
    return path if path.suffix.lower() == ".html" else path / report_name(sweep)


def write_report(ranking: Ranking, ranking_run: str, out: str | Path | None = None) -> Path:
    """Write the page (``out``: a file, a directory, or None for ``reports/``) and log it to the ranking run."""
    name = report_name(ranking.sweep)
    path = report_path(ranking.sweep, out)
    path.parent.mkdir(parents=True, exist_ok=True)
    page = build(ranking, ranking_run)
    path.write_text(page, encoding="utf-8")
    log_files(ranking.sweep.client, ranking_run, {f"report/{name}": page})
    return path.resolve()


def ranking_run_for(ranking: Ranking) -> str:
    """The latest FINISHED ranking run of the sweep that ranked exactly these runs; a new one if there is
    none (a ranking run killed half-way is never reused)."""
    return previous_ranking_run(ranking) or log_ranking(ranking)


def rank_and_report(uri: str, experiment: str, parent: str | None, structure: str | None = None,
                    out: str | Path | None = None, reuse: bool = False) -> tuple[str, Path]:
    """Rank, log the ranking run (reused if one ranked the same runs), write and log the report; print where.

    ``reuse=True`` (the end of a sweep): when a FINISHED ranking run ranked exactly these runs and the
    report file exists, neither is made again — only the table is ranked, to tell (≈ 5 s less on the
    2-core machine, where loading the models, drawing the ranking's figures and rebuilding the report
    took 4.4–6.1 s for an unchanged sweep).
    """
    from maglev.study.decisions import with_orders

    sweep = load_sweep(uri, experiment, parent)
    if reuse:
        quick = compute(sweep, structure, draw=False)
        previous = previous_ranking_run(quick)
        path = report_path(sweep, out)
        if previous is not None and path.is_file():
            print(top_text(quick))
            print(f"ranking run: {previous} (reused: it ranked these same runs)\nreport:      {path.resolve()} "
                  f"(unchanged)\nMLflow UI:   {ui_hint(sweep, previous)}", flush=True)
            return previous, path.resolve()
    ranking = compute(sweep, structure)
    decisions = with_orders(artifact_json(sweep.client, sweep.parent_id, "lab/decisions.json"), ranking.table)
    if decisions:  # the last decision of lab/decisions.json, made from the ranked runs
        log_files(sweep.client, sweep.parent_id, {"lab/decisions.json": decisions})
    run_id = ranking_run_for(ranking)
    path = write_report(ranking, run_id, out)
    print(top_text(ranking))
    for note in ranking.notes:
        print(f"  note: {note}")
    print(f"ranking run: {run_id}\nreport:      {path}\nMLflow UI:   {ui_hint(sweep, run_id)}", flush=True)
    return run_id, path
