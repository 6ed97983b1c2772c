"""End to end: the default lab sweep with the ranking callback into a tmp store, then the report;
and the default sweep's own promises (issue 12, done-when).

The sweep runs once, in-process (tests/study/harness.py), as ``python study.py -m +sweep=lab``
runs it (full-length records, four structures, the default orders, the BLA, the lab steps)
but without the run figures (the report draws its own), with conf/config.yaml's ranking
callback writing the report under the store.  Expected numbers are read from the store, not
copied from output.  Its checks stay in this one file so that the suite's workers
(``--dist loadfile``) run the sweep once.
"""

from __future__ import annotations

import collections
import contextlib
import html
import io
import json
import math
import re
import shutil
import subprocess

import numpy as np
import pytest
from scipy.stats import spearmanr

from .harness import all_runs, launch, rule_orders

pytestmark = [pytest.mark.slow, pytest.mark.filterwarnings("ignore:The .*noload.* loader strategy is deprecated")]
SECTION_IDS = ("preparation", "working-region", "inputs", "data", "structures", "top4", "binary-vs-uniform",
               "best-vs-worst", "conclusion", "grading-template", "code", "cautions", "all-runs", "extra-figures")


@pytest.fixture(scope="module")
def lab_sweep(tmp_path_factory, migrated_db):
    """The default sweep (30 full-length runs, no run figures), ranked and reported by the callback;
    (store, report dir, stdout)."""
    store = tmp_path_factory.mktemp("report")
    shutil.copyfile(migrated_db, store / "mlflow.db")
    out = io.StringIO()
    with contextlib.redirect_stdout(out):
        launch(store, "+sweep=lab", "tracking.log_figures=false", rank=True)
    return store, store / "reports", out.getvalue()


def report_file(reports):
    """The sweep's one report, ``<sweep>-<sweep_id[:8]>.html``."""
    [page] = reports.glob("lab-*.html")
    assert len(page.stem) == len("lab-") + 8
    return page


def ranked(runs) -> list:
    """FINISHED model runs by val_fit, ties to fewer parameters (the lab's ranking, done independently)."""
    kids = [r for r in runs if r.data.tags.get("kind") == "model" and r.info.status == "FINISHED"]
    return sorted(kids, key=lambda r: (-r.data.metrics["val_fit"], r.data.metrics["n_params"], r.info.run_name))


def test_sweep_ends_with_ranking_run_and_prints_where_things_are(lab_sweep):
    store, reports, out = lab_sweep
    assert "ranking run:" in out and f"report:      {report_file(reports)}" in out
    assert f"maglev ui --tracking-uri sqlite:///{store}/mlflow.db" in out
    client, _, runs = all_runs(store)
    parent = next(r for r in runs if r.data.tags.get("kind") == "sweep")
    [ranking] = [r for r in runs if r.data.tags.get("kind") == "ranking"]
    assert ranking.data.tags["sweep_parent"] == parent.info.run_id
    order = ranked(runs)
    assert ranking.data.tags["best_run"] == order[0].info.run_id
    assert ranking.data.tags["worst_run"] == order[-1].info.run_id
    best = order[0]
    # the sweep's end describes the parent with its ranking (the callbacks' real order), the ranking run too
    assert parent.data.tags["mlflow.note.content"].startswith(f"Sweep lab: {len(order)} model runs ({len(order)} "
                                                              "FINISHED) of 3 dataset(s) ")
    assert (f"Best {best.info.run_name} with one-step validation FIT {best.data.metrics['val_fit']:.2f} % "
            f"(ranking run [ranking · lab](#/experiments/") in parent.data.tags["mlflow.note.content"]
    assert ranking.data.tags["mlflow.note.content"].startswith(f"Ranking of sweep lab: {len(order)} FINISHED model runs")
    top_lines = [ln for ln in out.splitlines() if re.match(r"\s+[1-4]\.\s", ln)]
    assert [next(r.info.run_name for r in order if r.info.run_name in ln) for ln in top_lines] == \
        [r.info.run_name for r in order[:4]]
    paths = {a.path for d in ("ranking", "best_vs_worst", "binary_vs_uniform", "report")
             for a in client.list_artifacts(ranking.info.run_id, d)}
    assert {"ranking/table.csv", "ranking/top4.md", "best_vs_worst/bode.png", "best_vs_worst/pzmap.png",
            "best_vs_worst/resid.png", "binary_vs_uniform/fit.png", "binary_vs_uniform/common_validation.csv",
            f"report/{report_file(reports).name}"} <= paths


def test_report_has_every_section_with_numbers_from_the_runs(lab_sweep):
    store, reports, _ = lab_sweep
    page = report_file(reports).read_text()
    for anchor in SECTION_IDS:
        assert f"<section id='{anchor}'>" in page, anchor
    client, _, runs = all_runs(store)
    parent = next(r for r in runs if r.data.tags.get("kind") == "sweep").data.metrics
    order = ranked(runs)
    sections = dict(re.findall(r"<section id='([^']+)'>(.*?)</section>", page, flags=re.S))
    wr = sections["working-region"]
    assert f"[{parent['lab.u_min']:.2f}, {parent['lab.u_max']:.2f}] A" in wr
    assert f"<b>u* = (u_min + u_max)/2 = {parent['lab.u_star']:.2f} A</b>" in wr
    assert f"α* = {parent['lab.alpha_star']:.2f}" in sections["inputs"]
    for ds in ("uniform_narrow", "uniform_wide", "binary_a025"):
        assert ds in sections["inputs"] and ds in sections["data"]
    m = order[0].data.metrics
    assert f"{int(m['n_est'])} samples = {m['n_est'] * m['Ts']:.2f} s" in sections["data"]
    for st in ("ARX", "ARMAX", "OE", "BJ"):
        assert f"<li><b>{st}</b>" in sections["structures"]
    aic = order[0].data.metrics["aic"]
    assert f"{aic:.2f}" in sections["all-runs"]  # every run's AIC, in the appendix
    top = sections["top4"]
    positions = [top.index(f"<b>{r.info.run_name}</b>: FIT {r.data.metrics['val_fit']:.2f} %") for r in order[:4]]
    assert positions == sorted(positions)
    assert "binary" in sections["binary-vs-uniform"] and "uniform" in sections["binary-vs-uniform"]
    prep = sections["preparation"]
    from maglev.sim.plant import rig
    from maglev.study.report.preparation import first_principles

    lin = first_principles(rig(), parent["lab.u_star"], m["Ts"])  # the sweep's datasets name the default plant
    assert f"static gain {lin.dc_gain:.3f} cm/A" in prep and f"At the working point u* = {parent['lab.u_star']:.2f} A" in prep
    assert "def get_average(" in sections["code"] and "def get_stationary_averages(" in sections["code"]
    from maglev.study.datasets import dataset_bla
    from maglev.study.report.sections import resonance_rise
    from maglev.study.store import run_config

    # best vs worst states each validation record's BLA resonance exactly when |G| rises above its low-frequency
    # value by more than two standard errors, at the frequency of its peak
    bw_text = html.unescape(sections["best-vs-worst"])
    for r in (order[0], order[-1]):
        b = dataset_bla(run_config(client, r.info.run_id)["dataset"])
        keep = b.w > 0
        peak = f"the BLA peaks at {b.w[keep][np.argmax(np.abs(b.G[keep]))]:.1f} rad/s"
        assert (peak in bw_text) == resonance_rise(b), (r.info.run_name, peak)
    [ranking] = [r for r in runs if r.data.tags.get("kind") == "ranking"]
    assert sections["cautions"].count("<li>") == int(ranking.data.metrics["n_cautions"])
    bw = sections["best-vs-worst"]
    assert f"Best <b>{order[0].info.run_name}</b>" in bw and f"worst <b>{order[-1].info.run_name}</b>" in bw
    assert f"rank {len(order)}, FIT {order[-1].data.metrics['val_fit']:.2f} %" in bw


def test_report_is_self_contained(lab_sweep):
    _, reports, _ = lab_sweep
    page = report_file(reports).read_text()
    srcs = re.findall(r"<img [^>]*src='([^']*)'", page)
    assert len(srcs) == 11  # main: working region, spectrum, α, binary vs uniform, 3 best vs worst; appendix: rise
    # time, order selection, orders, preparation (the first-principles |G| beside the BLAs)
    assert all(s.startswith("data:image/png;base64,") for s in srcs)
    assert "<link" not in page and "<script" not in page and "(figure" not in page  # no missing figures


@pytest.fixture(scope="module")
def cli_report(lab_sweep, tmp_path_factory):
    """``maglev report --out r.html [--pdf]`` on the sweep's store, once for the file (Chromium prints the PDF the
    page-count test reads): (page, what it printed, whether a PDF was printed)."""
    from maglev.study.cli import main
    from maglev.study.report.pdf import chromium

    store, _, _ = lab_sweep
    out = tmp_path_factory.mktemp("cli_report") / "r.html"
    printed = chromium() is not None  # with Chromium, --pdf prints it beside the page and logs it too
    said = io.StringIO()
    with contextlib.redirect_stdout(said):
        code = main(["report", "--tracking-uri", f"sqlite:///{store}/mlflow.db", "--out", str(out)]
                    + (["--pdf"] if printed else []))
    assert code == 0, said.getvalue()
    return out, said.getvalue(), printed


def test_report_cli_reuses_the_ranking_run_of_the_same_runs(lab_sweep, cli_report):
    store, reports, _ = lab_sweep
    out, said, printed = cli_report
    assert f"report:      {out}" in said and (f"pdf:         {out.with_suffix('.pdf')}" in said) == printed
    assert out.is_file() and "<section id='best-vs-worst'>" in out.read_text()
    assert out.with_suffix(".pdf").is_file() == printed
    client, _, runs = all_runs(store)
    rankings = [r for r in runs if r.data.tags.get("kind") == "ranking"]
    assert len(rankings) == 1
    if printed:
        logged = {a.path for a in client.list_artifacts(rankings[0].info.run_id, "report")}
        assert f"report/{report_file(reports).stem}.pdf" in logged  # named as the logged page, not the --out file


def test_report_renders_in_headless_chromium_without_broken_images(lab_sweep, tmp_path):
    chromium = shutil.which("chromium") or shutil.which("chromium-browser")
    if chromium is None:
        pytest.skip("chromium not installed (apt-get install -y chromium)")
    _, reports, _ = lab_sweep
    probe = ("<script>window.addEventListener('load', () => { const im = [...document.images]; "
             "document.title = 'broken=' + im.filter(i => !i.complete || i.naturalWidth === 0).length "
             "+ ' total=' + im.length; });</script>")
    page = tmp_path / "probe.html"
    page.write_text(report_file(reports).read_text().replace("</body>", probe + "</body>"))
    proc = subprocess.run(
        [chromium, "--headless=new", "--no-sandbox", "--disable-gpu", "--disable-background-networking",
         "--disable-component-update", "--disable-sync", "--no-first-run", f"--user-data-dir={tmp_path / 'profile'}",
         "--virtual-time-budget=10000", "--dump-dom", page.as_uri()],
        capture_output=True, text=True, timeout=120)
    title = re.search(r"<title>(.*?)</title>", proc.stdout)
    assert title, proc.stderr[-2000:]
    broken, total = map(int, re.fullmatch(r"broken=(\d+) total=(\d+)", title.group(1)).groups())
    assert broken == 0 and total == 11


# ---------------------------------------------------------------------------- the default sweep's promises
DATASETS = ("uniform_narrow", "uniform_wide", "binary_a025")
MIN_RANK_CORRELATION = 0.6  # issue 12: Spearman(g_bla_err, val_fit_sim) <= -0.6 within each dataset
# the datasets whose validation output the input explains enough for the FIT to rank G; on uniform_narrow, the
# smaller uniform range, more of the default plant's output is its wander (test below)
RANKED_DATASETS = ("uniform_wide", "binary_a025")
WANDER_CEILING = 25.0  # %, the BLA's own simulation FIT below which the wander owns the validation output


def model_runs(store) -> dict[str, list]:
    """FINISHED model runs by dataset."""
    _, _, runs = all_runs(store)
    out = collections.defaultdict(list)
    for r in runs:
        if r.data.tags.get("kind") == "model" and r.info.status == "FINISHED":
            out[r.data.tags["dataset"]].append(r)
    return out


def test_every_simulated_run_logs_the_bla_distance_the_naive_baseline_and_the_simulation_fit(lab_sweep):
    store, _, _ = lab_sweep
    by_dataset = model_runs(store)
    assert sorted(by_dataset) == sorted(DATASETS)
    for ds, runs in by_dataset.items():
        assert len(runs) == 13, ds  # ARX at orders 4 to 7, ARMAX at 4 to 6, OE and BJ at 3 to 5
        for r in runs:
            m = r.data.metrics
            for key in ("g_bla_err", "g_bla_err_stationary", "g_bla_err_unweighted", "bla_fit_ceiling", "val_fit_naive", "val_fit_sim"):
                assert math.isfinite(m[key]), (r.info.run_name, key)
            assert 0 < m["g_bla_err"] < 5, r.info.run_name
            # where the input explains the output every model is within 1.5 BLA norms and simulates at most 5 points
            # above the BLA; on uniform_narrow the OE models' slow pole-zero pair follows the wander (test below)
            if ds in RANKED_DATASETS:
                assert m["g_bla_err"] < 1.5 and m["val_fit_sim"] < m["bla_fit_ceiling"] + 5, r.info.run_name


@pytest.mark.parametrize("dataset", RANKED_DATASETS)
def test_runs_closer_to_the_bla_simulate_the_validation_data_better(lab_sweep, dataset):
    """g_bla_err is measured as the validation FIT sees G: on records of the validation length, initial state fitted.
    On uniform_narrow the stationary distance (g_bla_err_stationary) ranks the OE models' slow pole-zero pair, an
    error on time scales longer than the 11 s record, as their largest (README, 'Is the best linear approximation
    the truth?')."""
    store, _, _ = lab_sweep
    runs = model_runs(store)[dataset]
    rho = spearmanr([r.data.metrics["g_bla_err"] for r in runs], [r.data.metrics["val_fit_sim"] for r in runs])
    assert rho.statistic <= -MIN_RANK_CORRELATION, (dataset, rho.statistic)


def test_on_the_smaller_uniform_range_the_wander_owns_more_of_the_validation_output(lab_sweep):
    """The default plant's small command steps drive a slow wander (its upper bushing sticks), which no linear model
    of the input explains: on uniform_narrow (U(1.75, 3.25) A) the BLA's own simulation FIT, the ceiling of every
    linear model, is lower than on uniform_wide (U(1.5, 3.5) A, the same class over the whole region), and every
    model simulates the validation data below WANDER_CEILING and below that ceiling.  There one validation record's
    FIT does not rank the models' distance to the BLA (the OE models' slow pole-zero pair, an error on time scales
    longer than the 11 s record, follows some of the wander), so issue 12's rank check is made on the other two
    datasets (README, "Is the best linear approximation the truth?")."""
    store, _, _ = lab_sweep
    runs = model_runs(store)
    ceiling = {ds: runs[ds][0].data.metrics["bla_fit_ceiling"] for ds in ("uniform_narrow", "uniform_wide")}
    assert ceiling["uniform_narrow"] < ceiling["uniform_wide"]
    for r in runs["uniform_narrow"]:
        m = r.data.metrics
        assert m["val_fit_sim"] < min(WANDER_CEILING, m["bla_fit_ceiling"]), r.info.run_name


def final_orders(store) -> dict[str, tuple[int, list[int]]]:
    """Each structure's (final order, grid) by the orders rule, recomputed from the runs (harness.rule_orders)."""
    from maglev.study.cautions import ORDER_MARGIN

    return rule_orders([r for v in model_runs(store).values() for r in v], ORDER_MARGIN)


def test_order_at_edge_cautions_are_the_ones_the_logged_fits_support(lab_sweep):
    """The ranking's cautions (its own artifact) name an order-at-edge caution for exactly the structures whose
    final order, recomputed here from the runs' logged metrics by the orders decision's rule (:func:`final_orders`),
    is the largest of its grid.  The sweep gives each
    structure its grid (hydra.sweeper.orders): ARX's FIT still rises at 5 (its noise model 1/A needs more poles;
    its distance to the BLA falls from 4 to 5), so ARX is swept at 4 to 7; ARMAX's FIT rises from 4 to 5 with its
    distance to the BLA falling, so ARMAX is swept at 6 as well.  An order whose distance to the BLA grows does not
    count, nor does one whose added poles its models cancel.  The orders decision logged on the sweep's parent run
    then settles every structure inside its grid, without a caution."""
    from maglev.lab.decision import read_decisions

    store, reports, _ = lab_sweep
    client, _, runs = all_runs(store)
    [ranking] = [r for r in runs if r.data.tags.get("kind") == "ranking"]
    path = client.download_artifacts(ranking.info.run_id, "cautions/cautions.json")
    with open(path) as fh:
        listed = json.load(fh)
    keys = [c["key"] for c in listed]
    assert len(keys) == int(ranking.data.metrics["n_cautions"])
    chosen = final_orders(store)
    assert {st: grid for st, (_, grid) in chosen.items()} == {
        "arx": [4, 5, 6, 7], "armax": [4, 5, 6], "oe": [3, 4, 5], "bj": [3, 4, 5]}
    final = {st: o for st, (o, _) in chosen.items()}
    at_edge = {st for st, (o, grid) in chosen.items() if o == grid[-1]}
    assert {k.removeprefix("order_at_edge_") for k in keys if k.startswith("order_at_edge")} == at_edge
    parent = next(r for r in runs if r.data.tags.get("kind") == "sweep")
    with open(client.download_artifacts(parent.info.run_id, "lab/decisions.json")) as fh:
        orders = read_decisions(json.load(fh))["orders"]
    assert orders.choice == final and orders.cautions == [] and at_edge == set()
    assert all(f"{st.upper()}: order {o}, the smallest within 1 point of the best" in " ".join(orders.reasons)
               for st, o in final.items())


def test_the_recommended_models_are_at_the_settled_orders(lab_sweep):
    """The conclusion's models for simulation and for one-step prediction are at their structure's settled order
    (recomputed from the runs by :func:`final_orders`): the best simulation FIT and the best one-step FIT among the
    runs at those orders; a run of another order that simulates higher is named with its FIT, not recommended."""
    from maglev.study.ranking import model_order

    store, reports, _ = lab_sweep
    page = report_file(reports).read_text()
    conclusion = html.unescape(re.search(r"<section id='conclusion'>(.*?)</section>", page, re.S).group(1))
    final = {st: o for st, (o, grid) in final_orders(store).items() if o < grid[-1]}  # settled: a higher order swept
    assert set(final) == {"arx", "armax", "oe", "bj"}
    runs = [r for v in model_runs(store).values() for r in v]
    at_final = [r for r in runs if int(model_order(r.data.tags["orders"])) == final[r.data.tags["structure"]]]
    sim = max(at_final, key=lambda r: r.data.metrics["val_fit_sim"])
    pred = max(at_final, key=lambda r: (r.data.metrics["val_fit"], -r.data.metrics["n_params"]))
    assert f"For simulation (the output from the input alone) use {sim.info.run_name}: " in conclusion
    assert f"For one-step prediction use {pred.info.run_name}: " in conclusion
    head = conclusion.split("For simulation")[0]
    assert "The model to use is chosen among the orders the orders rule chose, where each structure's FIT levels off " \
           "(§5: " in head
    assert all(f"{st.upper()} {o}" in head for st, o in final.items())
    higher = max(runs, key=lambda r: r.data.metrics["val_fit_sim"])
    if higher is not sim and higher.data.metrics["val_fit_sim"] > sim.data.metrics["val_fit_sim"]:
        assert (f"{higher.info.run_name} simulates higher, at {higher.data.metrics['val_fit_sim']:.2f} %" in conclusion
                and "but is not recommended" in conclusion)
    else:
        assert "simulates higher" not in conclusion


def test_the_default_sweeps_decisions_follow_the_labs_rules(lab_sweep):
    """Issue 35's done-when on the default sweep, read from the decisions it logged: the working region ends below
    the plateau; its datasets are the records rule's choice (not forced), each inside the region, centred at u*,
    its output on the static curve; 10 s / 7 s of data; α within 0.02 of its design; the rig's delay (nk = 2); no
    working-point caution in the ranking."""
    from maglev.lab.decision import read_decisions
    from maglev.lab.records import INPUT_OUTSIDE_MAX, OUTPUT_OUTSIDE_MAX

    store, _, _ = lab_sweep
    client, _, runs = all_runs(store)
    parent = next(r for r in runs if r.data.tags.get("kind") == "sweep")
    with open(client.download_artifacts(parent.info.run_id, "lab/decisions.json")) as fh:
        dec = read_decisions(json.load(fh))
    region = dec["working_region"].choice
    assert region["u_max"] < region["u_sat_model"] and not dec["working_region"].cautions
    records = dec["records"]
    assert not records.forced and sorted(n for v in records.choice.values() for n in v) == sorted(DATASETS)
    rows = {r["record"]: r for r in records.evidence}
    for ds in DATASETS:
        assert rows[ds]["u outside region"] <= INPUT_OUTSIDE_MAX and rows[ds]["y outside curve"] <= OUTPUT_OUTSIDE_MAX
        assert rows[ds]["offset / width"] < 0.05, ds
    assert all(p["est_s"] >= 10 and p["val_s"] >= 7 for p in dec["data_length"].choice.values())
    assert not dec["alpha"].cautions and dec["delay"].choice["nk"] == 2 and not dec["delay"].forced
    [ranking] = [r for r in runs if r.data.tags.get("kind") == "ranking"]
    with open(client.download_artifacts(ranking.info.run_id, "cautions/cautions.json")) as fh:
        assert "working_points_differ" not in {c["key"] for c in json.load(fh)}


# ---------------------------------------------------------------------------- the lab's template, six pages
def test_every_template_item_is_answered_in_a_non_empty_section_in_the_labs_order(lab_sweep):
    """Each item of §5's list maps to a report section that is there and has text; the main sections follow §5's
    order, the conclusion and the filled-in grading template close the main report, the appendix comes after."""
    from maglev.study.report.template import GRADING, REQUIRED, answered, sections_of

    _, reports, _ = lab_sweep
    page = report_file(reports).read_text()
    found = sections_of(page)
    for item, anchors in REQUIRED + GRADING:
        assert answered(page, anchors), (item, anchors, [found.get(a, ("", ""))[1][:80] for a in anchors])
    grading = found["grading-template"][1]
    graded = {a for _, anchors in GRADING for a in anchors}
    listed = len(GRADING) + sum(1 for _, anchors in REQUIRED if not set(anchors) <= graded)
    assert " NO " not in f" {grading} " and grading.count(" yes") == listed
    main = ["preparation", "working-region", "inputs", "data", "structures", "top4", "binary-vs-uniform",
            "best-vs-worst", "conclusion", "grading-template"]
    where = [page.index(f"<section id='{a}'>") for a in main]
    assert where == sorted(where) and max(where) < page.index("<h1 id='appendix'>Appendices</h1>")
    assert all(page.index(f"<section id='{a}'>") > page.index("id='appendix'")
               for a in ("code", "cautions", "all-runs", "extra-figures"))


def test_figures_are_numbered_in_order_with_captions(lab_sweep):
    _, reports, _ = lab_sweep
    page = report_file(reports).read_text()
    numbers = [int(n) for n in re.findall(r"<figcaption><b>Figure (\d+)\.</b> [^<]{20,}</figcaption>", page)]
    assert numbers == list(range(1, len(re.findall(r"<img ", page)) + 1))
    assert "shaded bands: 99 % confidence" in page  # the bands are said what they are


def test_report_prints_to_at_most_six_a4_pages_before_the_appendix(lab_sweep, cli_report):
    from maglev.study.report.pdf import PAGE_LIMIT, page_texts, pages_before_appendix

    out, _, printed = cli_report
    if not printed:
        pytest.skip("chromium not installed (apt-get install -y chromium): the report is not printed")
    _, reports, _ = lab_sweep
    def undated(page) -> str:
        return re.sub(r"\d{4}-\d\d-\d\dT[\d:.]+", "", page.read_text())

    assert undated(out) == undated(report_file(reports))  # the sweep's page (but when it was written), printed
    pdf = out.with_suffix(".pdf")
    texts = page_texts(pdf)
    pages = pages_before_appendix(texts)
    # six pages plus the attached code (and the cautions) on one more: the long appendices stay in the HTML
    assert 0 < pages <= PAGE_LIMIT and len(texts) == pages + 1, (pages, len(texts))
    appendix = "".join(texts[pages:])
    assert "10. Grading template" in "".join(texts[:pages]) and "def get_average(" in appendix
    assert "B. Cautions" in appendix and "C. Every run" not in appendix and "Appendices C–E" in appendix
