"""Cautions appear exactly when the numbers call for them, and the report's prose follows the numbers."""

from __future__ import annotations

import html

import os
import shutil

import numpy as np
import pandas as pd
import pytest

from maglev.model import PolyModel
from maglev.study.cautions import cautions

pytestmark = pytest.mark.filterwarnings("ignore:The .*noload.* loader strategy is deprecated")

# a sweep where nothing is wrong: every model beats y(t−1), simulates about as it predicts, passes its tests,
# BJ's order supported by the simulation FIT (3: order 4 adds 0.5 point, order 2 loses 3) is inside the grid
# 2..4 (ARMAX has one order: no grid), every dataset at the working point
GOOD = [  # name, structure, order, dataset, val_fit, val_fit_sim, aic
    ("armax[3 3 3 2] · b", "armax", 3, "b", 96.0, 91.0, -950.0),
    ("bj[3 3 3 3 2] · b", "bj", 3, "b", 95.0, 90.0, -900.0), ("bj[2 2 2 2 2] · b", "bj", 2, "b", 94.0, 87.0, -800.0),
    ("bj[4 4 4 4 2] · b", "bj", 4, "b", 94.5, 90.5, -850.0), ("bj[3 3 3 3 2] · u", "bj", 3, "u", 93.0, 88.0, -700.0),
    ("bj[2 2 2 2 2] · u", "bj", 2, "u", 92.0, 85.0, -600.0), ("bj[4 4 4 4 2] · u", "bj", 4, "u", 92.5, 88.5, -650.0),
]


def ranked(rows=GOOD, **changes) -> pd.DataFrame:
    """``rows`` (default GOOD) ranked (best first), with ``changes``: column -> {row index: value}.
    GOOD ranked: 0 armax3·b, 1 bj3·b, 2 bj4·b, 3 bj2·b, 4 bj3·u, 5 bj4·u, 6 bj2·u."""
    rows = [{"name": n, "structure": s, "order": o, "dataset": d, "val_fit": f, "aic": a, "val_fit_naive": 85.0,
             "val_fit_sim": sim, "whiteness_pvalue": 0.5, "independence_pvalue": 0.5, "max_pole_radius": 0.9,
             "near_cancellations": 0, "u0": 2.75, "g_bla_err": 0.1} for n, s, o, d, f, sim, a in rows]
    t = pd.DataFrame(rows).sort_values("val_fit", ascending=False).reset_index(drop=True)
    for col, values in changes.items():
        for i, v in values.items():
            t.loc[i, col] = v
    return t


def keys(table: pd.DataFrame, u0: dict | None = None) -> set[str]:
    return {c.key for c in cautions(table, u0 or {"b": 2.75, "u": 2.75}, 2.75, 2.5)}


def test_no_caution_when_nothing_is_wrong():
    assert keys(ranked()) == set()


@pytest.mark.parametrize("changes, expected", [
    ({"whiteness_pvalue": {0: 0.001}}, {"top_fails_whiteness", "runs_fail_whiteness"}),
    ({"whiteness_pvalue": {3: 0.001}}, {"runs_fail_whiteness"}),  # not the top one
    ({"independence_pvalue": {0: 1e-9}}, {"top_fails_independence", "runs_fail_independence"}),
    ({"val_fit_naive": {0: 95.5}}, {"top_no_better_than_naive", "runs_no_better_than_naive"}),
    ({"val_fit_naive": {5: 92.0}}, {"runs_no_better_than_naive"}),
    ({"val_fit_sim": {0: 40.0}}, {"top_simulates_poorly"}),
    ({"val_fit_sim": {0: 76.5}}, set()),  # 19.5 points: below the threshold
    ({"g_bla_err": {0: 0.5}}, {"top_far_from_bla"}),
    ({"val_fit_sim": {2: 91.6, 5: 89.6}}, {"order_at_edge_bj"}),  # BJ 4 now 1.1 above 3: still rising at the top
    ({"val_fit_sim": {2: 91.0, 5: 89.0}}, set()),  # BJ 4 exactly 1 point above 3: not more than the margin
    ({"val_fit_sim": {3: 91.8, 6: 89.8}}, {"order_at_edge_bj"}),  # BJ 2 now 1.3 above all: falling from the bottom
    ({"val_fit_sim": {3: 90.5, 6: 88.5}}, set()),  # BJ 2 level with 3 and 4: flat, no edge
    ({"aic": {2: -2000.0, 5: -2000.0}}, set()),  # AIC alone falling to the top of the grid is no edge
    ({"max_pole_radius": {4: 1.01}}, {"unstable_models"}),
    ({"near_cancellations": {1: 2}}, {"top_cancellations"}),
    ({"near_cancellations": {5: 2}}, set()),  # rank 6: not in the top four
])
def test_each_caution_appears_exactly_when_its_condition_holds(changes, expected):
    assert keys(ranked(**changes)) == expected


def test_order_edge_suggests_the_next_order_and_working_points_name_the_offset_dataset():
    [edge] = cautions(ranked(val_fit_sim={2: 91.6, 5: 89.6}))  # rows 2 and 5 are the BJ order-4 models
    assert edge.numbers == {"chosen": 4, "grid": [2, 3, 4], "suggest": 5, "edge": "upper",
                            "fit": {2: 86.0, 3: 89.0, 4: 90.6}, "margin": 1.0}
    assert edge.text == ("bj: the mean simulation FIT over 2 dataset(s) (order 2: 86.00 %, order 3: 89.00 %, "
                         "order 4: 90.60 %) still rises by more than 1 point at the largest swept order 4: the "
                         "smallest order within 1 point of the best is 4, the edge of the swept orders [2, 3, 4]; "
                         "add order 5 (++hydra.sweeper.orders.bj=[2,3,4,5]) before concluding.")
    [low] = cautions(ranked(val_fit_sim={3: 91.8, 6: 89.8}))
    assert low.numbers["suggest"] == 1 and low.numbers["edge"] == "lower"
    assert "is highest at the smallest swept order 2, more than 1 point above every other" in low.text
    [wp] = cautions(ranked(), {"b": 2.75, "u": 2.12}, 2.75, 2.5)
    assert wp.key == "working_points_differ" and "u is centred at 2.12 A" in wp.text and "2.75 A" in wp.text
    assert cautions(ranked(), {"b": 2.75, "u": 2.55}, 2.75, 2.5) == []  # 0.2 A: within 10 % of 2.5 A


# two orders, as the default sweep has (name, structure, order, dataset, val_fit, val_fit_sim, aic)
TWO = [("arx[4 4 2] · b", "arx", 4, "b", 97.0, 38.0, -5e4), ("arx[5 5 2] · b", "arx", 5, "b", 97.1, 38.3, -5.1e4),
       ("arx[4 4 2] · u", "arx", 4, "u", 96.0, 37.0, -4e4), ("arx[5 5 2] · u", "arx", 5, "u", 96.1, 37.5, -4.1e4)]


@pytest.mark.parametrize("sim5, expected", [
    ((38.3, 37.5), None),  # +0.4 on average: 5 adds nothing, 4 is chosen
    ((37.3, 36.8), None),  # 5 slightly worse: 4 is chosen, the FIT does not fall by more than the margin
    ((39.3, 38.3), "upper"),  # +1.3: still rising at 5, add 6
    ((36.0, 35.8), "lower"),  # -1.6: falling from 4, add 3
    ((39.0, 38.0), None),  # +1.0 exactly: not more than the margin
])
def test_two_order_grid_is_at_its_edge_only_when_the_fit_still_moves_by_more_than_the_margin(sim5, expected):
    rows = [r if r[2] == 4 else (*r[:5], sim5[0] if r[3] == "b" else sim5[1], r[6]) for r in TWO]
    found = [c for c in cautions(ranked(rows)) if c.key.startswith("order_at_edge")]
    assert [c.numbers["edge"] for c in found] == ([expected] if expected else [])
    if expected:
        assert found[0].numbers["suggest"] == {"upper": 6, "lower": 3}[expected]


@pytest.mark.parametrize("bla5, grows", [(0.3, True), (0.05, False), (0.1, False)])
def test_an_order_whose_models_move_away_from_the_bla_is_no_edge(bla5, grows):
    # ARX's simulation FIT rises by 1.3 points from order 4 to 5; its distance to the BLA is 0.1 at order 4 and
    # bla5 at order 5: a distance that grows means the gain is not G's, so order 5 does not count (the orders
    # decision's rule, maglev.lab.orders) and order 4 is settled; otherwise 5 is the upper edge
    t = ranked([r if r[2] == 4 else (*r[:5], r[5] + 1.3, r[6]) for r in TWO])
    t.loc[t["order"] == 5, "g_bla_err"] = bla5
    edges = [c for c in cautions(t) if c.key == "order_at_edge_arx"]
    assert (edges == []) == grows
    if not grows:
        assert edges[0].numbers["edge"] == "upper" and edges[0].text.endswith("before concluding.")
        assert "bla" not in edges[0].numbers
    t["g_bla_err"] = np.nan  # real datasets have no BLA: no such sentence
    [edge] = [c for c in cautions(t) if c.key == "order_at_edge_arx"]
    assert edge.text.endswith("before concluding.") and "bla" not in edge.numbers


def test_order_choice_uses_only_the_datasets_swept_at_every_order():
    from maglev.study.cautions import order_choice

    rows = [r for r in GOOD if r[1] == "bj" and not (r[2] == 4 and r[3] == "u")]  # dataset u lacks order 4
    c = order_choice(ranked(rows))
    assert c["datasets"] == 1 and c["fit"] == {2: 87.0, 3: 90.0, 4: 90.5} and c["chosen"] == 3 and c["edge"] is None


def test_caution_sentences_state_their_numbers():
    t = ranked(whiteness_pvalue={0: 5.8e-185}, val_fit_sim={0: 40.7}, val_fit_naive={0: 95.9})
    text = {c.key: c.text for c in cautions(t)}
    assert "(p = 5.8e-185 < 0.01)" in text["top_fails_whiteness"]
    assert "FIT 40.70 % against 96.00 % one step ahead (55.3 points lower)" in text["top_simulates_poorly"]
    assert "y(t−1) alone scores 95.90 %" in text["top_no_better_than_naive"] and "+0.10 points" in text[
        "top_no_better_than_naive"]
    assert text["runs_fail_whiteness"].startswith("1 of 7 ranked models fail the whiteness test")


# ---------------------------------------------------------------------------- through a store
def _store(tmp_path, empty_db, best_white: float, best_indep: float, worst_white: float, worst_indep: float):
    """A sweep of two runs whose logged residual tests are given, in a copy of ``empty_db`` under
    ``tmp_path``; returns the computed Ranking."""
    from maglev.study import tracking
    from maglev.study.ranking import compute
    from maglev.study.store import load_sweep
    from tests.study.test_ranking import model, resid_json

    tmp_path.mkdir(exist_ok=True)
    shutil.copyfile(empty_db, tmp_path / "mlflow.db")
    uri = f"sqlite:///{tmp_path}/mlflow.db"
    client, exp = tracking.connect({"uri": uri, "experiment": "maglev", "artifact_location": str(tmp_path / "a")})
    parent = client.create_run(exp, run_name="s", tags={"kind": "sweep", "sweep": "s"}).info.run_id
    tracking.log_batch(client, parent, metrics={"lab.u_star": 2.75, "lab.u_min": 1.5, "lab.u_max": 4.0})
    for name, fit, white, indep in (("arx[2 2 2] · b", 97.0, best_white, best_indep),
                                    ("oe[2 2 2] · u", 90.0, worst_white, worst_indep)):
        st, ds = name.split("[")[0], name.split(" · ")[1]
        res = {**resid_json(0.1), "whiteness_pvalue": white, "white": white >= 0.01,
               "independence_pvalue": indep, "independent": indep >= 0.01}
        rid = client.create_run(exp, run_name=name, tags={
            "kind": "model", "structure": st, "orders": "[2 2 2]", "dataset": ds, "val_dataset": f"{ds}[val]",
            "input_class": "binary" if ds == "b" else "uniform", "mlflow.parentRunId": parent,
            "host": "test", "pid": str(os.getpid())}).info.run_id
        tracking.log_batch(client, rid, metrics={"val_fit": fit, "val_fit_naive": 80.0, "val_fit_sim": fit - 2,
                                                 "n_params": 4, "whiteness_pvalue": white,
                                                 "independence_pvalue": indep, "u0": 2.75})
        tracking.log_files(client, rid, {"model/model.json": model(st, fit).to_json(), "resid/resid.json": res})
        client.set_terminated(rid, "FINISHED")
    client.set_terminated(parent, "FINISHED")
    return compute(load_sweep(uri, "maglev"))


def test_ranking_and_report_follow_the_residual_tests_both_ways(tmp_path, migrated_db):
    from maglev.study.ranking import top_text
    from maglev.study.report import sections

    r = _store(tmp_path, migrated_db, best_white=0.5, best_indep=1e-6, worst_white=0.5, worst_indep=0.993)
    assert {c.key for c in r.cautions} == {"top_fails_independence", "runs_fail_independence"}
    models = {rid: PolyModel.from_dict(r.models[rid].to_dict()) for rid in r.models}
    page = html.unescape(sections.best_vs_worst(r, models, {}))
    # the worst's record is explained by its input (simulation FIT 88 %): its independence test has power, and its
    # pass counts for it against the best's failure
    assert "arx[2 2 2] · b fails the independence test (p = 1e-06; the input explains" in page
    assert "oe[2 2 2] · u passes the independence test (p = 0.993; the input explains 98.6 % of the output on " \
           "u's validation data, so the test has power)" in page
    assert "Whiteness: arx[2 2 2] · b passes (p = 0.5), oe[2 2 2] · u passes (p = 0.5)." in page
    assert "leaves more structure" not in page
    text = top_text(r)
    assert "Cautions (2):" in text and "fails the independence test (p = 1e-06 < 0.01)" in text
    assert sections.cautions(r.cautions).count("<li>") == 2

    clean = _store(tmp_path / "clean", migrated_db, 0.5, 0.5, 0.5, 0.5)
    assert clean.cautions == [] and "Cautions" not in top_text(clean)
    assert "No caution applies" in sections.cautions(clean.cautions)
    assert np.isclose(clean.table["val_fit_naive"], 80.0).all()


@pytest.mark.parametrize("true_delay, verdict", [
    (2, "in 3 of 3 models (median |b|/σ"),
    (3, "in 0 of 3 models (median |b|/σ"),
])
def test_the_report_judges_the_swept_delay_by_the_models_first_b_coefficient(true_delay, verdict):
    """ARX [1 2 2] fitted to systems whose response starts at lag 2 or 3: the report says whether b2 is there."""
    from scipy import signal

    from maglev.data import IOData
    from maglev.estimation import arx
    from maglev.study.report import sections

    models = []
    for seed in range(3):
        rng = np.random.default_rng(seed)
        u = rng.standard_normal(2000)
        y = signal.lfilter(np.r_[np.zeros(true_delay), 1.0, 0.5], [1.0, -0.7], u) + 0.05 * rng.standard_normal(2000)
        models.append(arx(IOData(u, y, 1.0), na=1, nb=2, nk=2))
    text = sections.delay_evidence(models, delayest_nk=3)
    assert text.startswith("The swept structures use nk = 2; delayest gives 3.") and verdict in text
    if true_delay == 2:
        assert "the response is there at lag 2" in text and "delayest's nk = 3 (from ARX [2 2 nk]) would leave" in text
    else:
        assert ("most models find no response at lag 2, so the swept delay is too small for the data "
                "(delayest: nk = 3)") in text
        # the same models when the delay decision rejected nk = 3 (its residuals keep the input at lag 2)
        kept = sections.delay_evidence(models, delayest_nk=3, rejected=[3])
        assert kept.endswith("most models find no significant response at lag 2, yet the delay decision below "
                             "rejects nk = 3: a longer delay leaves the input at the lags it skips in the residuals, "
                             "so the response at lag 2 is small, not absent (delayest, which fits ARX [2 2 nk] only, "
                             "gives nk = 3).")
        assert sections.delay_evidence(models, delayest_nk=3, rejected=[1]) == text  # a shorter one: no change


@pytest.mark.parametrize("gain, bla5, ending", [
    (1.3, 0.3, " among the orders whose models do not move away from the best linear approximation (order(s) 5 do: "
               "mean distance 4: 0.100, 5: 0.300) is <b>4</b>, the smallest swept (no smaller order was swept)."),
    (1.3, 0.05, " is <b>5</b>, at the upper edge of the swept orders: add order 6."),
    (0.4, 0.1, " is <b>4</b>, the smallest swept: the higher orders add at most 1 point (no smaller order was swept)."),
])
def test_the_reports_order_sentence_says_why_a_higher_order_does_not_count(gain, bla5, ending):
    """ARX's simulation FIT gains ``gain`` points from order 4 to 5 while its distance to the BLA goes from 0.1 to
    ``bla5``: the report's sentence names the order chosen and, when order 5 moves away from the BLA, that it does
    not count — never that it adds at most 1 point when it adds more."""
    from maglev.study.cautions import order_choice
    from maglev.study.report.sections import order_sentence

    t = ranked([r if r[2] == 4 else (*r[:5], r[5] + gain, r[6]) for r in TWO])
    t.loc[t["order"] == 5, "g_bla_err"] = bla5
    sentence = order_sentence(order_choice(t))
    assert sentence.startswith("Mean simulation FIT by order (4: 37.50 %, 5: ") and sentence.endswith(ending)
    assert sentence.split("the best")[0].endswith("within 1 point of ")
