"""The report's verdicts on constructed numbers: binary vs uniform, best vs worst, the conclusion change their
verdict when the numbers change, and a residual test on a record the input does not explain is reported as
without power (maglev.study.report.verdicts, and the sections that print them)."""

from __future__ import annotations

import html as html_module
import math
from types import SimpleNamespace

import numpy as np
import pandas as pd
import pytest

from maglev.study.report import verdicts as v

DATASETS = {"bin": "binary", "uni_w": "uniform", "uni_n": "uniform"}


def comparison(own: dict[str, float], u0: dict[str, float] | None = None) -> pd.DataFrame:
    """One structure's runs: two orders per dataset, the higher order ``own[ds]`` FIT on its own data."""
    rows = []
    for ds, cls in DATASETS.items():
        for order, fit in ((4, own[ds] - 2.0), (5, own[ds])):
            rows.append({"name": f"bj{order} {ds}", "dataset": ds, "input_class": cls, "val_fit": fit,
                         "val_fit_naive": {"bin": 82.0, "uni_w": 83.0, "uni_n": 86.0}[ds],
                         "u0": (u0 or {}).get(ds, 2.75), "orders": f"[{order}]"})
    return pd.DataFrame(rows)


def common(matrix: dict[str, dict[str, float]]) -> pd.DataFrame:
    """FIT of every run on every validation set; ``matrix[est][val]`` for the higher orders, 1 point less for the
    lower ones."""
    out = {}
    for est in DATASETS:
        for order, drop in ((4, 1.0), (5, 0.0)):
            out[f"bj{order} {est}"] = {f"{val}[val]": matrix[est][val] - drop for val in DATASETS}
    return pd.DataFrame(out).T


OWN_CLASS = {"bin": {"bin": 99.0, "uni_w": 87.0, "uni_n": 82.0},
             "uni_w": {"bin": 93.0, "uni_w": 93.0, "uni_n": 90.0},
             "uni_n": {"bin": 80.0, "uni_w": 86.0, "uni_n": 92.0}}
BINARY_EVERYWHERE = {"bin": {"bin": 99.0, "uni_w": 95.0, "uni_n": 94.0},
                     "uni_w": {"bin": 90.0, "uni_w": 93.0, "uni_n": 90.0},
                     "uni_n": {"bin": 80.0, "uni_w": 86.0, "uni_n": 92.0}}


def test_binary_vs_uniform_each_class_wins_on_its_own_and_the_wide_uniform_model_transfers_best():
    cc = v.class_comparison(comparison({d: OWN_CLASS[d][d] for d in DATASETS}), common(OWN_CLASS), 2.75, 2.5)
    assert cc.higher == "split" and cc.own_class_wins
    assert cc.models == {"bin": "bj5 bin", "uni_w": "bj5 uni_w", "uni_n": "bj5 uni_n"}  # each dataset's best order
    # transfer: mean FIT on the other records' validation sets, by hand
    assert cc.transfer["uni_w"] == pytest.approx((93.0 + 90.0) / 2) and cc.transfer.idxmax() == "uni_w"
    text = " ".join(cc.sentences)
    assert "Neither class is higher everywhere: the binary-input model is higher on 1 and the uniform-input model " \
           "on 2 of the 3 common validation sets." in text
    assert "Each validation set is won by a model estimated on its own input class." in text
    assert "the model from uni_w (uniform) transfers best: mean FIT 91.50 %" in text
    # y(t−1)'s FIT is the baseline: 99 % on the binary record is 17 points above y(t−1)'s 82 %
    assert "y(t−1) alone scores 82.00 % there, so they add +17.00 and +11.00 points to it" in text
    assert "so the comparison is one of input classes, not of operating points" in text


def test_binary_vs_uniform_verdict_changes_with_the_numbers():
    cc = v.class_comparison(comparison({d: BINARY_EVERYWHERE[d][d] for d in DATASETS}, {"uni_n": 2.1}),
                            common(BINARY_EVERYWHERE), 2.75, 2.5)
    assert cc.higher == "binary" and not cc.own_class_wins
    assert cc.sentences[0].startswith("The binary-input model is higher on all 3 common validation sets.")
    assert "The model estimated on the other class wins on uni_n, uni_w" in cc.sentences[0]
    assert cc.transfer.idxmax() == "bin"
    assert any("uni_n is centred at 2.10 A, not at u* = 2.75 A" in s for s in cc.sentences)


def test_binary_vs_uniform_compares_the_models_at_the_structures_final_order():
    """With the orders decision settling at order 4, each record is represented by its order-4 model, although its
    order-5 model scores higher on its own data; a record with no run at the final order keeps its best run."""
    comp = comparison({d: OWN_CLASS[d][d] for d in DATASETS})
    final = comp.assign(final_order=comp["orders"] == "[4]")
    cc = v.class_comparison(final, common(OWN_CLASS), 2.75, 2.5)
    assert cc.models == {"bin": "bj4 bin", "uni_w": "bj4 uni_w", "uni_n": "bj4 uni_n"}
    assert cc.matrix.loc["uni_w", "bin"] == OWN_CLASS["uni_w"]["bin"] - 1.0  # the order-4 row of the common FITs
    partial = comp.assign(final_order=(comp["orders"] == "[4]") & (comp["dataset"] != "bin"))
    assert v.class_comparison(partial, common(OWN_CLASS)).models["bin"] == "bj5 bin"


def facts(name: str, **kw) -> v.ModelFacts:
    base = dict(name=name, rank=1, val_fit=99.0, val_fit_sim=20.0, val_dataset="d[val]", explained=0.4, white=False,
                whiteness_p=1e-9, independent=False, independence_p=1e-9, unit_poles=0, cancellations=0,
                nmp_zeros=0, dominant=(100.0, 0.1), dcgain=0.62)
    return v.ModelFacts(**{**base, **kw})


def test_best_vs_worst_explains_which_is_better_and_flips_with_the_numbers():
    best = facts("B")
    worst = facts("W", rank=24, val_fit=9.0, val_fit_sim=9.0, unit_poles=1, cancellations=3, dcgain=0.93)
    bw = v.best_vs_worst(best, worst, slope=0.62)
    assert bw.better == "best" and bw.tally == {"best": 4, "worst": 0}  # simulation, gain, unit circle, cancellations
    # now the best by one-step FIT simulates badly, its gain is off and it has a pole on the unit circle
    best2 = facts("B", val_fit_sim=6.9, dcgain=0.81, unit_poles=1)
    worst2 = facts("W", rank=21, val_fit=16.0, val_fit_sim=23.9, dcgain=0.61, white=True, whiteness_p=0.3)
    bw2 = v.best_vs_worst(best2, worst2, slope=0.62)
    assert bw2.better == "worst" and bw2.tally == {"best": 0, "worst": 4}
    said = {check: side for check, side, _ in bw2.checks}
    assert said["simulation"] == "worst" and said["static gain"] == "worst" and said["whiteness"] == "worst"
    assert said["unit-circle poles"] == "worst"
    gain = next(s for c, _, s in bw2.checks if c == "static gain")
    assert "B 0.810 cm/A (+31 %), W 0.610 cm/A (-2 %)" in gain and "(within 20%)" in gain


def test_an_independence_test_on_an_unexplained_record_is_without_power_not_a_pass():
    """The worst passes the independence test (p = 0.996), but on its record every model simulates at FIT −1.3 %:
    the input explains nothing, so the pass is reported as without power and counted for neither model."""
    table = pd.DataFrame({"val_dataset": ["a[val]", "a[val]", "b[val]"], "val_fit_sim": [-1.3, -1.6, 30.0]})
    explained = v.explained_by_dataset(table)
    assert explained["a[val]"] == 0.0 and explained["b[val]"] == pytest.approx(1 - 0.7 ** 2)
    worst = facts("W", explained=explained["a[val]"], independent=True, independence_p=0.996, val_dataset="a[val]")
    best = facts("B", explained=explained["b[val]"], independent=False, independence_p=1e-5, val_dataset="b[val]")
    assert not worst.power and best.power
    bw = v.best_vs_worst(best, worst)
    check, side, sentence = next(c for c in bw.checks if c[0] == "independence")
    assert side is None  # a pass without power is no evidence for the worst
    assert ("the independence test of W (p = 0.996) is without power: on a's validation data the input explains "
            "nothing of the output (less than 5%") in sentence and "not a pass in its favour" in sentence
    assert "B fails the independence test (p = 1e-05; the input explains 51.0 % of the output on b's validation " \
           "data, so the test has power)" in sentence
    # the same pass where the input explains 6 % of the output counts for the worst
    worst6 = facts("W", explained=0.06, independent=True, independence_p=0.996)
    assert next(c for c in v.best_vs_worst(best, worst6).checks if c[0] == "independence")[1] == "worst"


def test_the_best_vs_worst_section_reports_the_unpowered_test_from_the_models():
    """The section itself, on two fitted models: the worst is validated on a record whose output is noise
    independent of its input, so its independence test passes without power."""
    from maglev import IOData, arx
    from maglev.study.report.sections import best_vs_worst
    from maglev.validation import compare, resid

    rng = np.random.default_rng(3)
    u = rng.standard_normal(4000)
    y = np.convolve(u, [0, 0.5, 0.3], mode="full")[:4000] + 0.05 * rng.standard_normal(4000)
    good, noise = IOData(u, y, 0.002, name="good"), IOData(u, rng.standard_normal(4000), 0.002, name="noise")
    rows, models, resids = [], {}, {}
    for rank, (name, data) in enumerate((("good", good), ("noise", noise)), start=1):
        est, val = data.split(0.5)
        m = arx(est, 2, 2, 1)
        rid = f"run-{name}"
        models[rid], resids[rid] = m, resid(val, m)
        rows.append({"rank": rank, "name": f"arx {name}", "run_id": rid, "val_dataset": f"{name}[val]",
                     "val_fit": compare(val, m, 1)[0], "val_fit_sim": compare(val, m, math.inf)[0],
                     "val_fit_naive": 0.0, "dcgain": m.dcgain()})
    table = pd.DataFrame(rows)
    ranking = SimpleNamespace(best=table.iloc[0], worst=table.iloc[1], table=table, resids=resids, files={},
                              orders=None)
    html = best_vs_worst(ranking, models, {"lab.slope": 0.8})
    assert resids["run-noise"].independent  # it passes ...
    assert "the independence test of arx noise" in html and "is without power" in html  # ... without power
    assert "arx good passes the independence test" in html and "so the test has power" in html
    assert "better model of the plant" in html
    assert ("The lab's best and worst model in terms of FIT (§3.7) are the #1 and the #2 of the one-step ranking "
            "(§6). The #1 is also the model the conclusion recommends for simulation and one-step prediction (§9).") \
        in html_module.unescape(html)


def test_conclusion_names_the_model_for_simulation_and_for_prediction_and_changes_with_the_numbers():
    # one order per structure: no orders decision, every model is a candidate
    table = pd.DataFrame([
        {"rank": 1, "name": "bj bin", "structure": "bj", "order": 4, "val_fit": 98.6, "val_fit_naive": 81.8,
         "val_fit_sim": 6.9, "dcgain": 0.81, "val_dataset": "bin[val]"},
        {"rank": 2, "name": "bj wide", "structure": "bj", "order": 4, "val_fit": 91.3, "val_fit_naive": 83.9,
         "val_fit_sim": 27.1, "dcgain": 0.41, "val_dataset": "wide[val]"},
        {"rank": 3, "name": "oe bin", "structure": "oe", "order": 4, "val_fit": 23.9, "val_fit_naive": 81.8,
         "val_fit_sim": 23.9, "dcgain": 0.61, "val_dataset": "bin[val]"}])
    c = v.conclusion(table, slope=0.62)
    assert (c.simulation, c.prediction) == ("bj wide", "bj bin")
    assert c.sentences[0] == ("No orders decision: each structure was swept at one order, so the model to use is "
                              "chosen among all 3 models.")
    text = " ".join(c.sentences)
    assert "Where the static response matters, oe bin is the better choice" in text
    assert "on the same validation data oe bin (#3) simulates at 23.90 %" in text
    # a #1 no better than y(t−1) one step ahead, and the best simulator with the right gain: one verdict changes
    table2 = table.assign(val_fit_naive=[98.2, 90.0, 98.2], dcgain=[0.81, 0.60, 0.61])
    c2 = v.conclusion(table2, slope=0.62)
    assert (c2.simulation, c2.prediction) == ("bj wide", None)
    assert "For one-step prediction no model is needed" in " ".join(c2.sentences)
    assert "Where the static response matters" not in " ".join(c2.sentences)


def ranked_orders(rows: list[tuple], bla: dict[str, dict[int, float]]):
    """A ranked table of (name, structure, order, dataset, val_fit, val_fit_naive, val_fit_sim) rows with its
    orders decision (mean FIT by order over the datasets; ``bla``: mean distance to the BLA by order) and
    ``final_order`` marked, as maglev.study.ranking.compute does."""
    from maglev.lab.orders import orders_decision
    from maglev.study.ranking import mark_final_orders

    t = pd.DataFrame(rows, columns=["name", "structure", "order", "dataset", "val_fit", "val_fit_naive", "val_fit_sim"])
    t = t.sort_values("val_fit", ascending=False, kind="mergesort").reset_index(drop=True)
    t.insert(0, "rank", range(1, len(t) + 1))
    t["val_dataset"] = t["dataset"] + "[val]"
    fit = {st: g.groupby("order")["val_fit_sim"].mean().to_dict() for st, g in t.groupby("structure")}
    orders = orders_decision(fit, bla=bla)
    return mark_final_orders(t, orders), orders


def test_a_higher_scoring_model_of_an_order_the_rule_does_not_choose_is_named_but_not_recommended():
    rows = [("bj4 bin", "bj", 4, "bin", 98.5, 80.0, 41.2), ("bj5 bin", "bj", 5, "bin", 98.6, 80.0, 41.3),
            ("bj4 uni", "bj", 4, "uni", 92.0, 84.0, 26.0), ("bj5 uni", "bj", 5, "uni", 92.1, 84.0, 25.5),
            ("oe4 bin", "oe", 4, "bin", 41.3, 80.0, 41.3), ("oe5 bin", "oe", 5, "bin", 41.4, 80.0, 41.4),
            ("oe4 uni", "oe", 4, "uni", 17.0, 84.0, 17.0), ("oe5 uni", "oe", 5, "uni", 19.5, 84.0, 19.5)]
    away = {"bj": {4: 0.13, 5: 0.20}, "oe": {4: 0.40, 5: 0.50}}  # order 5 moves away from the BLA in both
    table, orders = ranked_orders(rows, away)
    assert orders.choice == {"bj": 4, "oe": 4}
    c = v.conclusion(table, orders=orders)
    assert (c.simulation, c.prediction) == ("oe4 bin", "bj4 bin")
    assert c.sentences[0] == ("The model to use is chosen among the orders the orders rule chose, where each "
                              "structure's FIT levels off (§5: BJ 4, OE 4): 4 of the 8 models.")
    text = " ".join(c.sentences)
    assert ("oe5 bin simulates higher, at 41.40 % (+0.10 points), but is not recommended: its order 5 is not the order "
            "4 the orders rule chose for OE (its models move away from the best linear approximation; §5).") in text
    assert ("The #1 by one-step FIT, bj5 bin (98.60 %, +0.10 points over bj4 bin), is not recommended: its order 5 is "
            "not the order 4 the orders rule chose for BJ (its models move away from the best linear approximation; "
            "§5)") in text
    assert "final order" not in text and "settled" not in text
    # the numbers flip: OE's order 5 comes closer to the BLA and gains more than 1 point, so the rule settles OE at
    # 5 (not settled: the largest swept) and its model is recommended, with no sentence against it
    closer = {"bj": away["bj"], "oe": {4: 0.40, 5: 0.30}}
    table, orders = ranked_orders(rows, closer)
    assert orders.choice == {"bj": 4, "oe": 5}
    c = v.conclusion(table, orders=orders)
    assert c.simulation == "oe5 bin" and "simulates higher" not in " ".join(c.sentences)
    assert "OE 5 (the largest swept, its FIT still rising)" in c.sentences[0]
    assert c.sentences[0].startswith("The model to use is chosen among the orders the orders rule chose, not all of "
                                     "them where the FIT levels off")


def test_best_vs_worst_says_whether_the_first_is_the_recommended_model_and_why_not():
    """The lab's best and worst are the ends of the FIT ranking; the sentence ties them to the lab's question and
    says, from the numbers, whether the #1 is a model the conclusion recommends, and why not when it is not: its
    order (not the rule's), or a one-step FIT no better than y(t−1)'s at the rule's order."""
    rows = [("bj4 bin", "bj", 4, "bin", 98.5, 80.0, 41.2), ("bj5 bin", "bj", 5, "bin", 98.6, 80.0, 41.3),
            ("bj4 uni", "bj", 4, "uni", 92.0, 84.0, 26.0), ("bj5 uni", "bj", 5, "uni", 92.1, 84.0, 25.5),
            ("oe4 bin", "oe", 4, "bin", 41.3, 80.0, 41.3), ("oe5 bin", "oe", 5, "bin", 41.4, 80.0, 41.4),
            ("oe4 uni", "oe", 4, "uni", 17.0, 84.0, 17.0), ("oe5 uni", "oe", 5, "uni", 19.5, 84.0, 19.5)]
    away = {"bj": {4: 0.13, 5: 0.20}, "oe": {4: 0.40, 5: 0.50}}

    def said(rows_):
        table, orders = ranked_orders(rows_, away)
        return v.extremes_text(table.iloc[0], table.iloc[-1], v.conclusion(table, orders=orders), orders)

    text = said(rows)
    assert text == ("The lab's best and worst model in terms of FIT (§3.7) are the #1 and the #8 of the one-step "
                    "ranking (§6). The #1 is not the model this report recommends (§9: oe4 bin for simulation, bj4 bin "
                    "for one-step prediction): its order 5 is not the order 4 the orders rule chose for BJ (its models "
                    "move away from the best linear approximation; §5). Both are named: the #1 answers the lab's "
                    "question, the recommended model is the one to use.")
    # without BJ's order 5 the #1 is bj4 bin, the model recommended one step ahead
    at_rule = [r for r in rows if r[0] != "bj5 bin"]
    assert said(at_rule).endswith(" The #1 is also the model the conclusion recommends for one-step prediction (§9).")
    # the same #1 whose one-step FIT y(t−1) nearly matches on its record: no model is recommended for prediction
    naive = [(n, s_, o, d, f, 98.0 if d == "bin" else nv, sim) for n, s_, o, d, f, nv, sim in at_rule]
    assert said(naive).endswith("(§9: oe4 bin for simulation, y(t−1) itself for one-step prediction): one step ahead "
                                "it adds +0.50 points to the naive predictor y(t−1), less than 1, and oe4 bin "
                                "simulates better. Both are named: the #1 answers the lab's question, the recommended "
                                "model is the one to use.")


@pytest.mark.parametrize("wn, zeta", [(80.0, 0.13), (220.0, 0.05), (30.0, 0.9)])
def test_dominant_mode_recovers_a_known_continuous_mode(wn, zeta):
    Ts = 0.002
    s = complex(-zeta * wn, wn * math.sqrt(1 - zeta ** 2))
    fast = np.exp(-2000.0 * Ts)
    poles = np.array([np.exp(s * Ts), np.exp(s.conjugate() * Ts), fast])
    got = v.dominant_mode(poles, Ts)
    assert got == pytest.approx((wn, zeta), rel=1e-9)


def test_explained_share_is_the_variance_a_simulation_fit_accounts_for():
    assert v.explained_share(100.0) == 1.0 and v.explained_share(0.0) == 0.0 and v.explained_share(-1.3) == 0.0
    assert v.explained_share(50.0) == pytest.approx(0.75)
    assert math.isnan(v.explained_share(math.nan))


def test_a_logged_lab_decision_is_printed_in_its_section_with_rule_choice_and_evidence():
    """The decisions the sweep logs (lab/decisions.json, maglev.lab.decision) appear in their §5 sections: the choice
    in words, rule and reasons there; a short evidence table there too, a long one in Appendix E; the records
    decision keeps one row per record with its verdict in its section."""
    from maglev.lab.decision import Decision
    from maglev.study.report.sections import EVIDENCE_ROWS, decision, decisions_evidence

    short = Decision(name="delay", rule="largest nk whose residuals stay white.", choice={"nk": 2, "Ts": 0.002},
                     evidence=[{"nk": k, "outside": 0.5 * k} for k in range(1, 4)], reasons=["nk = 3 fails <x>"])
    long = Decision(name="records", rule="inside the region", choice={"uniform": ["a", "b"], "binary": ["c"]},
                    evidence=[{"record": f"r{i}", "inside": i % 2 == 0} for i in range(EVIDENCE_ROWS + 3)])
    decisions = {"delay": short, "records": long}
    html = decision(decisions, "delay")
    assert ("<b>Decision on the delay: an input delay of nk = 2 samples = 4 ms.</b> Rule: largest nk whose residuals "
            "stay white.") in html
    assert "why: nk = 3 fails &lt;x&gt;" in html and html.count("<tr>") == 4  # header + 3 evidence rows
    html = decision(decisions, "records")
    assert ("<b>Decision on the records: uniform white-noise records a and b; random binary record c.</b>" in html
            and f"evidence: {EVIDENCE_ROWS + 3} rows, Appendix E" in html)
    assert "<tr>" not in html and "uniform:" not in html
    appendix = decisions_evidence(decisions)
    assert "<h3>Decision on the records</h3>" in appendix and appendix.count("<tr>") == EVIDENCE_ROWS + 4
    assert "Decision on the delay" not in appendix
    assert decision(decisions, "orders") == "" and decision({}, "delay") == ""
    # a records decision whose evidence has verdicts: every record's row, cut to the summary columns, stays here
    rows = [{"record": f"r{i}", "class": "uniform", "u range (A)": "1.5–3.5", "mean u (A)": 2.5, "α": None,
             "score": 0.5 - i / 10, "verdict": "chosen (uniform #1)" if i == 0 else f"refused: reason {i}"}
            for i in range(EVIDENCE_ROWS + 3)]
    html = decision({"records": Decision("records", "r", {"uniform": ["r0"]}, rows)}, "records")
    assert html.count("<tr>") == EVIDENCE_ROWS + 4 and "<td>refused: reason 6</td>" in html
    assert "mean u (A)" not in html and "(the table below; all its evidence in Appendix E)" in html


def _input_section(u_wide: np.ndarray, forced: bool) -> str:
    """The report's input-signals section for one uniform record with input ``u_wide`` (region [1.5, 3.5] A)."""
    from maglev.lab.decision import Decision
    from maglev.study.report.sections import input_signals

    prep = SimpleNamespace(raw=SimpleNamespace(u=u_wide), u0=float(u_wide.mean()))
    cfg = {"dataset": {"input_class": "uniform", "preprocess": {"trim": 0}}}
    records = Decision(name="records", rule="the records rule", choice={"uniform": ["wide"]}, forced=forced)
    lab = {"lab.u_min": 1.5, "lab.u_max": 3.5, "lab.u_star": 2.5, "lab.alpha_star": 0.25}
    return input_signals({"wide": prep}, {"wide": cfg}, lab, {}, {"records": records})


def test_the_input_section_says_a_record_leaves_the_region_only_when_its_numbers_do():
    """The section's sentence on each record and on why the records are these follows the share of input samples
    outside the working region and whether the rule chose them: a record the rule chose is never said to leave
    the region (it refuses more than 2 % outside); a forced one that does is named as breaking the rule."""
    rng = np.random.default_rng(0)
    inside = rng.uniform(1.5, 3.5, 20000)
    chosen = _input_section(inside, forced=False)
    assert "inside the working region." in chosen and "<b>leaves the working region</b>" not in chosen
    assert "These records are the records rule's choice: the rule refuses a record whose input leaves" in chosen
    brief = inside.copy()
    brief[::100] = 3.6  # 1 % just above the region: within the rule
    assert "1.0 % of its samples outside the working region (the rule allows 2 %)" in _input_section(brief, False)
    beyond = rng.uniform(1.5, 4.0, 20000)  # white_noise_4's range
    forced = _input_section(beyond, forced=True)
    share = 100 * np.mean(beyond > 3.5)
    assert f"<b>leaves the working region</b> in {share:.1f} % of its samples (the rule refuses more than 2 %)" in forced
    assert "These records are forced by the config, not chosen: wide leaves the working region" in forced
    assert "the records rule's choice" not in forced
    assert "forced by the config, not chosen; each stays inside" in _input_section(inside, forced=True)
    assert v.records_head({"a": 0.3, "b": 0.0}, 0.02, None).endswith(": a leaves the working region.")


def test_a_recommended_model_failing_its_residual_tests_is_said_to_and_passing_ones_are_not():
    """The conclusion's models carry their residual tests: a failed test is stated with its p-value and what it
    means for the model's use; a model passing both gets no caution (p-values against the lab's 1 % level)."""
    table = pd.DataFrame([
        {"rank": 1, "name": "bj bin", "structure": "bj", "order": 4, "val_fit": 98.6, "val_fit_naive": 81.8,
         "val_fit_sim": 6.9, "val_dataset": "bin[val]", "whiteness_pvalue": 1e-13, "independence_pvalue": 0.2},
        {"rank": 2, "name": "oe wide", "structure": "oe", "order": 4, "val_fit": 27.1, "val_fit_naive": 83.9,
         "val_fit_sim": 27.1, "val_dataset": "wide[val]", "whiteness_pvalue": 0.0, "independence_pvalue": 0.003}])
    c = v.conclusion(table)
    assert (c.simulation, c.prediction) == ("oe wide", "bj bin")
    cautions = [s for s in c.sentences if s.startswith("Caution: ")]
    assert cautions == [
        "Caution: oe wide fails the whiteness test (p = 0 < 0.01) and the independence test (p = 0.003 < 0.01): G "
        "misses part of the dynamics; the disturbance is coloured, which a simulation (G alone) does not use.",
        "Caution: bj bin fails the whiteness test (p = 1e-13 < 0.01): its predictions leave structure in the "
        "residuals."]
    # both pass at the 1 % level: no caution; one fails independence only: that one alone
    passing = table.assign(whiteness_pvalue=[0.02, 0.5], independence_pvalue=[0.2, 0.01])
    assert not [s for s in v.conclusion(passing).sentences if s.startswith("Caution: ")]
    one = table.assign(whiteness_pvalue=[0.02, 0.5], independence_pvalue=[0.2, 0.009])
    assert [s for s in v.conclusion(one).sentences if s.startswith("Caution: ")] == [
        "Caution: oe wide fails the independence test (p = 0.009 < 0.01): G misses part of the dynamics."]


def test_the_top_four_carry_their_residual_tests_and_how_many_fail_each():
    from maglev.study.report.sections import residual_summary, residual_text

    top = pd.DataFrame({"name": ["a", "b", "c", "d"], "whiteness_pvalue": [1e-13, 0.0, 0.2, 0.004],
                        "independence_pvalue": [5.8e-6, 0.5, 0.01, 0.3]})
    assert residual_text(top.iloc[0]) == "; whiteness fails (p = 1e-13); independence fails (p = 5.8e-06)"
    assert "whiteness passes" in residual_text(top.iloc[2]) and "independence passes" in residual_text(top.iloc[2])
    assert residual_summary(top) == ("Residual tests at the 1% level: 3 of the 4 fail the whiteness test and 1 of "
                                     "the 4 fail the independence test: the FIT ranks the predictions, not whether a "
                                     "model has caught the data's structure (§8).")
    assert residual_summary(top.assign(independence_pvalue=0.0)).endswith("and all 4 fail the independence test: "
                                                                          "the FIT ranks the predictions, not whether "
                                                                          "a model has caught the data's structure (§8).")
    assert residual_summary(top.assign(whiteness_pvalue=0.5, independence_pvalue=0.5)) == \
        "All 4 pass the residual tests at the 1% level."
    assert residual_text(pd.Series({"name": "x"})) == "" and residual_summary(top[["name"]]) == ""


@pytest.mark.parametrize("alpha, forced, expected", [
    (0.2511, False, "α = 0.25 = α*, the α whose spectrum puts most power in the output's band"),
    (0.4969, False, "<b>α = 0.50, not α* = 0.25</b>; no binary record with α nearer α* passes the records rule "
                    "(the table below)"),
    (0.4969, True, "<b>α = 0.50, not α* = 0.25</b>; the config forces this record"),
])
def test_the_binary_records_alpha_is_set_against_alpha_star_and_the_report_says_why_it_differs(alpha, forced,
                                                                                               expected):
    from maglev.study.report.sections import alpha_text, binary_alpha

    records = SimpleNamespace(forced=forced, evidence=[])
    assert alpha_text(alpha, 0.25, records).startswith(expected)
    # the records at α* the rule refuses are named, from the verdicts of its evidence rows
    refused = [{"record": f"b{i}", "class": "binary", "α": a, "verdict": v} for i, (a, v) in
               enumerate(((0.251, "refused: 13.2 % of its output outside"), (0.252, "refused: constant input"),
                          (0.27, "refused: 20 % of its input outside"), (0.4969, "chosen (binary #1)")))]
    said = alpha_text(alpha, 0.25, SimpleNamespace(forced=forced, evidence=refused))
    if alpha > 0.3 and not forced:
        assert said.endswith("; the records rule refuses the binary records at α*, b0, b1 (the table below)")
        assert alpha_text(alpha, 0.25, SimpleNamespace(forced=False, evidence=refused[:1])).endswith(
            "refuses the binary record at α*, b0 (the table below)")
    # the α measured by the alpha decision wins over the config's design value; a real record's config has none
    decisions = {"alpha": SimpleNamespace(choice={"real_binary_signal_4": alpha})}
    assert binary_alpha("real_binary_signal_4", {"alpha": None}, decisions) == alpha
    assert binary_alpha("real_binary_signal_4", {"alpha": None}, {}) is None
    assert binary_alpha("binary_a025", {"alpha": 0.25}, None) == 0.25


def test_an_order_chosen_at_the_lower_edge_of_the_swept_orders_says_a_smaller_one_was_not_tried():
    from maglev.study.report.sections import lower_edge_text

    oc = {"grid": [4, 5]}
    assert lower_edge_text(4, oc) == (" It is the smallest order swept: order 3 was not, so whether it would "
                                      "simulate within 1 point as well is untested.")
    assert lower_edge_text(5, oc) == "" and lower_edge_text(1, {"grid": [1, 2]}) == "" and lower_edge_text(4, None) == ""


def test_the_slowest_mode_is_matched_to_a_physical_mode_only_within_a_factor_two():
    physics = [(225.9, 0.07), (80.9, 0.12)]
    near = v.pole_zero_text(facts("m", dominant=(72.3, 0.2)), physics)
    assert "slowest mode ωn = 72.3 rad/s, ζ = 0.20 (nearest mode of the linearised physics: 80.9 rad/s, ζ = 0.12)" in near
    far = v.pole_zero_text(facts("m", dominant=(3.2, 1.0)), physics)
    assert ("slowest mode ωn = 3.2 rad/s, ζ = 1.00, not a mode of the linearised physics (the nearest, 80.9 rad/s, "
            "ζ = 0.12, is more than a factor 2 away)") in far
