"""The report of the real-data sweep (``+sweep=lab_real``, the 2022 KTH records): every §5 item answered, printed
on at most six A4 pages before the appendix, and the residual tests of a record the input does not explain
reported as without power.  The sweep runs once, in-process, as ``python study.py -m +sweep=lab_real`` runs it,
without the run figures (the report draws its own) and on orders 2 and 3 of every structure (24 runs instead of the
sweep's 63: what is tested here is the report's form and its verdicts' wording, which the grid's size does not
change, and the suite keeps its time)."""

from __future__ import annotations

import contextlib
import html
import io
import re
import shutil

import pytest

from .harness import all_runs, launch, rule_orders

pytestmark = [pytest.mark.slow, pytest.mark.realdata,
              pytest.mark.filterwarnings("ignore:The .*noload.* loader strategy is deprecated")]


@pytest.fixture(scope="module")
def real_report(tmp_path_factory, migrated_db):
    from maglev.paths import refdata_dir

    path = refdata_dir()
    if path is None or not (path / "el2820_maglev_2022").is_dir():
        pytest.skip("real lab data not found (set MAGLEV_REFDATA or place ../shared/refdata)")
    store = tmp_path_factory.mktemp("real_report")
    shutil.copyfile(migrated_db, store / "mlflow.db")
    with contextlib.redirect_stdout(io.StringIO()):
        launch(store, "+sweep=lab_real", f"data_dir={path}", "tracking.log_figures=false", "structure.order=2,3",
               rank=True)
    [page] = (store / "reports").glob("lab_real-*.html")
    return store, page


def test_real_report_answers_every_template_item(real_report):
    from maglev.study.report.template import GRADING, REQUIRED, answered

    _, page = real_report
    text = page.read_text()
    for item, anchors in REQUIRED + GRADING:
        assert answered(text, anchors), item


def test_real_report_calls_an_unexplained_records_independence_test_without_power(real_report):
    """Wherever the worst model's validation record is one no model simulates above FIT 2.5 % (the input explains
    under 5 % of its output), its independence test is reported as without power, never as a pass."""
    from maglev.study.report.verdicts import EXPLAINED_MIN, explained_share

    store, page = real_report
    _, _, runs = all_runs(store)
    models = [r for r in runs if r.data.tags.get("kind") == "model" and r.info.status == "FINISHED"]
    worst = min(models, key=lambda r: (r.data.metrics["val_fit"], -r.data.metrics["n_params"]))
    same = [r for r in models if r.data.tags["dataset"] == worst.data.tags["dataset"]]
    share = explained_share(max(r.data.metrics["val_fit_sim"] for r in same))
    section = html.unescape(re.search(r"<section id='best-vs-worst'>(.*?)</section>", page.read_text(), re.S).group(1))
    unpowered = f"the independence test of {worst.info.run_name} (p = "
    assert (unpowered in section and "is without power" in section) == (share < EXPLAINED_MIN), share


def test_real_report_prints_to_at_most_six_a4_pages_before_the_appendix(real_report, tmp_path):
    from maglev.study.report.pdf import PAGE_LIMIT, chromium, page_texts, pages_before_appendix, print_pdf

    if chromium() is None:
        pytest.skip("chromium not installed (apt-get install -y chromium): the report is not printed")
    _, page = real_report
    texts = page_texts(print_pdf(page, tmp_path / "real.pdf"))
    pages = pages_before_appendix(texts)
    assert 0 < pages <= PAGE_LIMIT and len(texts) == pages + 1  # the attached code and cautions on one


def test_real_sweeps_orders_decision_and_conclusion_follow_the_orders_rule(real_report):
    """The orders decision the real sweep logged is the rule recomputed from its runs (harness.rule_orders: near
    cancellations count here, there is no BLA), and the conclusion's model for simulation is the best-simulating
    run at those orders."""
    import json

    from maglev.lab.decision import read_decisions
    from maglev.study.cautions import ORDER_MARGIN
    from maglev.study.ranking import model_order

    store, page = real_report
    client, _, runs = all_runs(store)
    models = [r for r in runs if r.data.tags.get("kind") == "model" and r.info.status == "FINISHED"]
    parent = next(r for r in runs if r.data.tags.get("kind") == "sweep")
    with open(client.download_artifacts(parent.info.run_id, "lab/decisions.json")) as fh:
        orders = read_decisions(json.load(fh))["orders"]
    final = {st: o for st, (o, _) in rule_orders(models, ORDER_MARGIN).items()}
    assert orders.choice == final
    at_final = [r for r in models if int(model_order(r.data.tags["orders"])) == final[r.data.tags["structure"]]]
    sim = max(at_final, key=lambda r: r.data.metrics["val_fit_sim"])
    conclusion = html.unescape(re.search(r"<section id='conclusion'>(.*?)</section>", page.read_text(), re.S).group(1))
    assert f"For simulation (the output from the input alone) use {sim.info.run_name}: " in conclusion
