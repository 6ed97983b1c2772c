"""Cautions appear exactly when the numbers call for them, and the report's prose follows the numbers."""

from __future__ import annotations

import os

import numpy as np
import pandas as pd
import pytest

from maglev.model import PolyModel
from maglev.study.cautions import cautions

pytestmark = pytest.mark.filterwarnings("ignore:The .*noload.* loader strategy is deprecated")

# a sweep where nothing is wrong: every model beats y(t−1), simulates about as it predicts, passes its tests,
# the best order by AIC (3) is inside the grid 2..4, every dataset at the working point
GOOD = [  # name, structure, order, dataset, val_fit, aic
    ("bj[3 3 3 3 2] · b", "bj", 3, "b", 95.0, -900.0), ("bj[2 2 2 2 2] · b", "bj", 2, "b", 94.0, -800.0),
    ("bj[4 4 4 4 2] · b", "bj", 4, "b", 94.5, -850.0), ("bj[3 3 3 3 2] · u", "bj", 3, "u", 93.0, -700.0),
    ("bj[2 2 2 2 2] · u", "bj", 2, "u", 92.0, -600.0), ("bj[4 4 4 4 2] · u", "bj", 4, "u", 92.5, -650.0),
]


def ranked(**changes) -> pd.DataFrame:
    """The GOOD sweep ranked (best first), with ``changes``: column -> {row index: value}."""
    rows = [{"name": n, "structure": s, "order": o, "dataset": d, "val_fit": f, "aic": a, "val_fit_naive": 85.0,
             "val_fit_sim": f - 5, "whiteness_pvalue": 0.5, "independence_pvalue": 0.5, "max_pole_radius": 0.9,
             "near_cancellations": 0, "u0": 2.75, "g_bla_err": 0.1} for n, s, o, d, f, a in GOOD]
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
    ({"val_fit_naive": {0: 94.5}}, {"top_no_better_than_naive", "runs_no_better_than_naive"}),
    ({"val_fit_naive": {5: 92.0}}, {"runs_no_better_than_naive"}),
    ({"val_fit_sim": {0: 40.0}}, {"top_simulates_poorly"}),
    ({"val_fit_sim": {0: 75.5}}, set()),  # 19.5 points: below the threshold
    ({"g_bla_err": {0: 0.5}}, {"top_far_from_bla"}),
    ({"aic": {1: -2000.0, 4: -2000.0}}, {"order_at_edge_bj"}),  # order 4 now best: the top of the grid
    ({"aic": {2: -2000.0, 5: -2000.0}}, {"order_at_edge_bj"}),  # order 2 now best: the bottom
    ({"max_pole_radius": {4: 1.01}}, {"unstable_models"}),
    ({"near_cancellations": {1: 2}}, {"top_cancellations"}),
    ({"near_cancellations": {5: 2}}, set()),  # rank 6: not in the top four
])
def test_each_caution_appears_exactly_when_its_condition_holds(changes, expected):
    assert keys(ranked(**changes)) == expected


def test_order_edge_suggests_the_next_order_and_working_points_name_the_offset_dataset():
    [edge] = cautions(ranked(aic={1: -2000.0, 4: -2000.0}))  # rows 1 and 4 are the order-4 models
    assert edge.numbers == {"best": 4, "grid": [2, 3, 4], "suggest": 5} and "add order 5" in edge.text
    [low] = cautions(ranked(aic={2: -2000.0, 5: -2000.0}))
    assert low.numbers["suggest"] == 1 and "the lowest of the swept orders [2, 3, 4]" in low.text
    [wp] = cautions(ranked(), {"b": 2.75, "u": 2.12}, 2.75, 2.5)
    assert wp.key == "working_points_differ" and "u is centred at 2.12 A" in wp.text and "2.75 A" in wp.text
    assert cautions(ranked(), {"b": 2.75, "u": 2.55}, 2.75, 2.5) == []  # 0.2 A: within 10 % of 2.5 A


def test_caution_sentences_state_their_numbers():
    t = ranked(whiteness_pvalue={0: 5.8e-185}, val_fit_sim={0: 40.7}, val_fit_naive={0: 94.9})
    text = {c.key: c.text for c in cautions(t)}
    assert "(p = 5.8e-185 < 0.01)" in text["top_fails_whiteness"]
    assert "FIT 40.70 % against 95.00 % one step ahead (54.3 points lower)" in text["top_simulates_poorly"]
    assert "y(t−1) alone scores 94.90 %" in text["top_no_better_than_naive"] and "+0.10 points" in text[
        "top_no_better_than_naive"]
    assert text["runs_fail_whiteness"].startswith("1 of 6 ranked models fail the whiteness test")


# ---------------------------------------------------------------------------- through a store
def _store(tmp_path, best_white: float, best_indep: float, worst_white: float, worst_indep: float):
    """A sweep of two runs whose logged residual tests are given; returns the computed Ranking."""
    from maglev.study import tracking
    from maglev.study.ranking import compute
    from maglev.study.store import load_sweep
    from tests.study.test_ranking import model, resid_json

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


def test_ranking_and_report_follow_the_residual_tests_both_ways(tmp_path):
    from maglev.study.ranking import top_text
    from maglev.study.report import sections

    r = _store(tmp_path, best_white=0.5, best_indep=1e-6, worst_white=0.5, worst_indep=0.993)
    assert {c.key for c in r.cautions} == {"top_fails_independence", "runs_fail_independence"}
    models = {rid: PolyModel.from_dict(r.models[rid].to_dict()) for rid in r.models}
    page = sections.best_vs_worst(r, models)
    assert "The worst passes the independence test and the best fails it (p = 1e-06 for the best, 0.993 for " \
           "the worst)" in page
    assert "Both pass the whiteness test" in page
    assert "leaves more structure" not in page
    text = top_text(r)
    assert "Cautions (2):" in text and "fails the independence test (p = 1e-06 < 0.01)" in text
    assert sections.cautions(r.cautions).count("<li>") == 2

    clean = _store(tmp_path / "clean", 0.5, 0.5, 0.5, 0.5)
    assert clean.cautions == [] and "Cautions" not in top_text(clean)
    assert "No caution applies" in sections.cautions(clean.cautions)
    assert np.isclose(clean.table["val_fit_naive"], 80.0).all()
