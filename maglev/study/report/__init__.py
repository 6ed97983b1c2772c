"""The lab report of a sweep as one self-contained HTML page (figures embedded as base64 PNG), and its PDF.

It is the lab's answer, written from the run data in the order of EL2820 Lab 3 §5's list
(:mod:`.sections`): the preparation tasks derived (:mod:`.preparation`), the working region
and its plot, why these three input signals, the amount of data, the structures and the
motivation of each one's order, the top four, binary vs uniform input for one structure on
common validation data, best vs worst and why one is better (:mod:`.verdicts`), a conclusion,
and the grading template filled in (:mod:`.template`); then, after the ``Appendices``
heading, the attached code, the cautions, every run and further figures.  Its print
stylesheet fits the main report on six A4 pages and prints only the attached code and the cautions after it
(:mod:`.pdf` prints it with Chromium).
Written to ``reports/<sweep>-<id>.html`` (default; ``<id>``: the first 8 characters of the
sweep's ``sweep_id``, so two sweeps of one name never overwrite each other's report, and a
relaunch of the same sweep updates its own) and logged under the same name to the sweep's
ranking run — the latest FINISHED one that ranked the same runs, else a new one.
``maglev report`` (``--pdf`` for the PDF too) and the end-of-sweep callback call it.
"""

from __future__ import annotations

import datetime as dt
import html
from pathlib import Path

from maglev.paths import reports_dir
from maglev.study.ranking import Ranking, compute, log_ranking, previous_ranking_run, report_name, top_text, ui_hint
from maglev.study.report import sections as sec
from maglev.study.store import SweepError, load_sweep
from maglev.study.tracking import log_files

LAB_FIGURES = ("working_region.png", "rise_time.png", "output_spectrum.png", "alpha.png", "orders.png")
DECISIONS = "lab/decisions.json"  # the parent run's lab decisions (maglev.lab.decision: one JSON artifact)
CSS = """
body{font-family:system-ui,sans-serif;max-width:1100px;margin:2em auto;padding:0 1em;color:#222;line-height:1.4}
h1{font-size:1.5em} h2{border-bottom:2px solid #ccc;padding-bottom:.2em;margin-top:1.6em} h3{margin:.6em 0 .1em}
table.t{border-collapse:collapse;font-size:.85em;margin:.5em 0} table.t td,table.t th{border:1px solid #ccc;
padding:2px 6px;text-align:right} table.t th{background:#f2f2f2} figure{margin:.4em 0}
img{max-width:100%} .row{display:flex;flex-wrap:wrap;gap:1em} figure.half{flex:1 1 45%;margin:.3em 0}
figure.side{float:right;width:45%;margin:0 0 .5em 1em} .clear{clear:both}
figcaption{font-size:.85em;color:#444} .missing{color:#a00} nav a{margin-right:1em} .meta{color:#555;font-size:.9em}
pre{font-size:.8em;background:#f7f7f7;padding:.4em;overflow-x:auto} #appendix{margin-top:3em} .print{display:none}
@page{size:A4;margin:11mm 11mm 12mm 11mm}
@media print{
 body{font-size:8.2pt;line-height:1.22;max-width:none;margin:0;padding:0}
 nav,.screen,#all-runs,#extra-figures,#decisions-evidence{display:none} .print{display:block} h1{font-size:12pt;margin:0 0 .2em} .meta{font-size:7pt}
 h2{font-size:10.2pt;margin:.7em 0 .25em;break-after:avoid} h3{font-size:8.9pt;break-after:avoid}
 p{margin:.25em 0} ul{margin:.2em 0;padding-left:1.3em} li{margin:.05em 0}
 table.t{font-size:7pt;margin:.25em 0;break-inside:avoid} table.t td,table.t th{padding:0 3px}
 figure{break-inside:avoid;margin:.2em 0} figcaption{font-size:7pt} .row{gap:.6em}
 figure img{max-height:58mm;width:auto;max-width:100%;display:block;margin:0 auto}
 figure.wide img{max-height:60mm} figure.full img{max-height:50mm} figure.side{width:42%}
 #appendix{break-before:page;margin-top:0} pre{font-size:6.6pt;white-space:pre-wrap}
}
"""
# the lab allows six pages plus the attached code: the printed report stops after Appendix B and says where the rest is
PRINT_NOTE = ("<p class='print'>Appendices C–E (every run, further figures, the evidence of the lab decisions) are in "
              "the HTML version of this report and on its MLflow ranking run; they are not printed, so that the "
              "report keeps to the lab's six pages plus the attached code.</p>")
SECTIONS = [("preparation", "Preparation"), ("working-region", "Working region"), ("inputs", "Inputs"),
            ("data", "Data"), ("structures", "Structures and orders"), ("top4", "Top four"),
            ("binary-vs-uniform", "Binary vs uniform"), ("best-vs-worst", "Best vs worst"),
            ("conclusion", "Conclusion"), ("grading-template", "Grading template"), ("appendix", "Appendices")]


def lab_steps(ranking: Ranking) -> tuple[dict, dict]:
    """The parent run's lab-level numbers (metrics and ``lab/lab.json``) and figures (name -> PNG)."""
    sweep = ranking.sweep
    lab = {k: v for k, v in sweep.parent.data.metrics.items() if k.startswith("lab.")}
    lab.update(sweep.artifact_json(sweep.parent_id, "lab/lab.json") or {})
    figures = {name: sweep.artifact(sweep.parent_id, f"lab/{name}") for name in LAB_FIGURES}
    return lab, figures


def lab_decisions(ranking: Ranking) -> dict:
    """The sweep's lab decisions by name (:class:`maglev.lab.decision.Decision`, from the parent run's
    ``lab/decisions.json``); {} when the sweep logged none."""
    from maglev.lab.decision import read_decisions

    return read_decisions(ranking.sweep.artifact_json(ranking.sweep.parent_id, DECISIONS))


def physics(ranking: Ranking, lab: dict, ts_used: list[float]):
    """(the rig's parameters, the first-principles linearisation at u* or None, the staircase's noise or None)."""
    from maglev.sim.plant import DEFAULT_PLANT, rig
    from maglev.study.datasets import plant_name
    from maglev.study.report.preparation import first_principles, noise_from_staircase

    plants = sorted({plant_name(c["dataset"]) for c in ranking.configs.values() if c["dataset"]["source"] == "sim"})
    lev = rig(plants[0] if plants else DEFAULT_PLANT)
    if "lab.u_star" not in lab:
        return lev.params, None, None
    lin = first_principles(lev, lab["lab.u_star"], ts_used[0] if ts_used else 0.001)
    noise = noise_from_staircase(next(iter(ranking.configs.values())), lab) if ranking.configs else None
    return lev.params, lin, noise


def build(ranking: Ranking, ranking_run: str) -> str:
    """The report page for ``ranking`` (logged as run ``ranking_run``): §5's items in its order, then the
    appendix (attached code, cautions, every run, further figures)."""
    from maglev.study.datasets import load
    from maglev.study import render
    from maglev.study.figures import orders_figure, pngs, preparation_figure
    from maglev.study.report.template import grading_template

    sweep = ranking.sweep
    lab, lab_png = lab_steps(ranking)
    decisions = lab_decisions(ranking)
    datasets = {n: load(c["dataset"], c["data_dir"]) for n, c in sorted(ranking.configs.items())}
    if not datasets:
        raise SweepError("cannot rebuild the sweep's datasets for the report: " + "; ".join(ranking.notes))
    models = {**{rid: sweep.model(rid) for rid in ranking.table["run_id"]
                 if rid not in ranking.models}, **ranking.models}
    ts_used = sorted(set(float(t) for t in ranking.table["Ts"].dropna())) if "Ts" in ranking.table else []
    params, lin, noise = physics(ranking, lab, ts_used)
    references = {}
    for name, prep in datasets.items():
        references[prep.val_name] = sec.reference_response(ranking.configs[name], prep)
    blas = {n: r for n, r in references.items() if hasattr(r, "fit_ceiling")}
    orders_png = render.offload(pngs, orders_figure, ranking.table)  # on the sweep's renderer, if it has one
    tags = sweep.parent.data.tags
    head = (f"<h1>Modelling of a magnetic levitator (EL2820 Lab 3): sweep {html.escape(sweep.name)}</h1>"
            f"<p class='meta'>Generated by maglev from MLflow parent run {sweep.parent_id} (ranking run "
            f"{ranking_run}), git {tags.get('git_commit', '?')[:10]}"
            f"{' (dirty)' if tags.get('git_dirty') == 'true' else ''}, "
            f"{dt.datetime.now().isoformat(timespec='seconds')}.<span class='screen'><br>MLflow UI: "
            f"<code>{html.escape(ui_hint(sweep, ranking_run))}</code></span></p>"
            "<nav>" + "".join(f"<a href='#{a}'>{t}</a>" for a, t in SECTIONS) + "</nav>")
    main = [
        sec.preparation(params, lin, noise, lab, ranking.table),
        sec.working_region(lab, lab_png, ts_used, decisions),
        sec.input_signals(datasets, ranking.configs, lab, lab_png, decisions),
        sec.data_amounts(ranking.table, datasets, ranking.configs, decisions),
        sec.structures(ranking.table, models, lab, decisions),
        sec.top_four(ranking),
        sec.binary_vs_uniform(ranking, lab),
        sec.best_vs_worst(ranking, models, lab, lin.modes() if lin is not None else None, references),
        sec.conclusion(ranking, lab),
    ]
    extra = [(lab_png.get("rise_time.png"), "Averaged step response inside the working region and its 10–90 % "
              "rise time (samples; output normalised to the step)."),
             (lab_png.get("orders.png"), "ARX order selection (arxstruc/selstruc): validation loss (cm²) against "
              "the number of parameters, AIC's and MDL's choices marked."),
             (orders_png(), "Estimation loss (cm²), AIC and validation FIT (%) against the "
              "number of parameters, per structure and dataset.")]
    if lin is not None:
        extra.append((pngs(preparation_figure, lin, blas), "|G| of the first-principles linearisation at u* "
                      + ("beside the best linear approximation of each simulated dataset's input class (shaded: its "
                         "99 % band)." if blas else "(this sweep has no simulated dataset, so no simulator BLA).")))
    appendix = ["<h1 id='appendix'>Appendices</h1>", sec.attached_code(), sec.cautions(ranking.cautions),
                PRINT_NOTE, sec.all_runs(ranking, models), sec.extra_figures(extra), sec.decisions_evidence(decisions)]
    body = "".join(main)
    body += grading_template(body + "".join(appendix))
    page = (f"<!DOCTYPE html><html lang='en'><head><meta charset='utf-8'><title>maglev report: "
            f"{html.escape(sweep.name)}</title><style>{CSS}</style></head><body>{head}{body}{''.join(appendix)}"
            "</body></html>\n")
    return sec.number_figures(page)


def report_path(sweep, out: str | Path | None = None) -> Path:
    """Where the report goes: ``out`` if it names an ``.html`` file, else ``report_name`` in ``out`` (a
    directory; None: ``reports/``)."""
    path = Path(out) if out else reports_dir()
    return path if path.suffix.lower() == ".html" else path / report_name(sweep)


def write_report(ranking: Ranking, ranking_run: str, out: str | Path | None = None, pdf: bool = False) -> Path:
    """Write the page (``out``: a file, a directory, or None for ``reports/``) and log it to the ranking run; with
    ``pdf``, print it to A4 beside it (same name, ``.pdf``; headless Chromium) and log that too."""
    name = report_name(ranking.sweep)
    path = report_path(ranking.sweep, out)
    path.parent.mkdir(parents=True, exist_ok=True)
    page = build(ranking, ranking_run)
    path.write_text(page, encoding="utf-8")
    log_files(ranking.sweep.client, ranking_run, {f"report/{name}": page})
    if pdf:
        from maglev.study.report.pdf import print_pdf

        printed = print_pdf(path, path.with_suffix(".pdf"))
        log_files(ranking.sweep.client, ranking_run, {f"report/{Path(name).with_suffix('.pdf')}": printed})
    return path.resolve()


def ranking_run_for(ranking: Ranking) -> str:
    """The latest FINISHED ranking run of the sweep that ranked exactly these runs; a new one if there is
    none (a ranking run killed half-way is never reused)."""
    return previous_ranking_run(ranking) or log_ranking(ranking)


def rank_and_report(uri: str, experiment: str, parent: str | None, structure: str | None = None,
                    out: str | Path | None = None, pdf: bool = False, reuse: bool = False) -> tuple[str, Path]:
    """Rank, log the ranking run (reused if one ranked the same runs), write and log the report; print where.

    ``reuse=True`` (the end of a sweep): when a FINISHED ranking run ranked exactly these runs and the
    report file exists (and its PDF, if one is asked for), neither is made again — only the table is
    ranked, to tell (loading the models, drawing the ranking's figures and rebuilding the report are
    the cost of an unchanged sweep's end).
    """
    from maglev.study.decisions import with_orders

    sweep = load_sweep(uri, experiment, parent)
    quick = None
    if reuse:
        quick = compute(sweep, structure, draw=False)
        previous = previous_ranking_run(quick)
        path = report_path(sweep, out)
        if previous is not None and path.is_file() and (not pdf or path.with_suffix(".pdf").is_file()):
            print(top_text(quick))
            print(f"ranking run: {previous} (reused: it ranked these same runs)\nreport:      {path.resolve()} "
                  f"(unchanged)\nMLflow UI:   {ui_hint(sweep, previous)}", flush=True)
            return previous, path.resolve()
    ranking = compute(sweep, structure, ranked=quick)
    decisions = with_orders(sweep.artifact_json(sweep.parent_id, "lab/decisions.json"), ranking.orders)
    if decisions:  # the last decision of lab/decisions.json, made from the ranked runs
        log_files(sweep.client, sweep.parent_id, {"lab/decisions.json": decisions})
    run_id = ranking_run_for(ranking)
    path = write_report(ranking, run_id, out, pdf)
    print(top_text(ranking))
    for note in ranking.notes:
        print(f"  note: {note}")
    print(f"ranking run: {run_id}\nreport:      {path}" + (f"\npdf:         {path.with_suffix('.pdf')}" if pdf else "")
          + f"\nMLflow UI:   {ui_hint(sweep, run_id)}", flush=True)
    return run_id, path
