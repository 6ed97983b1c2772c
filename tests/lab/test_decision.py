"""The decision record: JSON round-trip, forced flag, HTML-ready rows."""

from __future__ import annotations

import json

import numpy as np
import pytest

from maglev.lab.decision import Decision, read_decisions, write_decisions


def test_round_trip_through_json_keeps_every_field():
    d = Decision("delay", "the largest vote", {"nk": np.int64(3), "Ts": np.float64(0.002)},
                 evidence=[{"source": "step", "nk": 2}, {"source": "delayest", "nk": 3}],
                 reasons=["two of three say 3"], forced=True, cautions=["c"])
    text = json.dumps(write_decisions([d]))
    back = read_decisions(text)["delay"]
    assert back == Decision("delay", "the largest vote", {"nk": 3, "Ts": 0.002},
                            [{"source": "step", "nk": 2}, {"source": "delayest", "nk": 3}], ["two of three say 3"],
                            True, ["c"])
    assert "forced by the config" in back.choice_text()


def test_unknown_name_and_missing_keys_are_refused():
    with pytest.raises(ValueError, match="decision name must be one of"):
        Decision("colour", "r", 1)
    with pytest.raises(ValueError, match="missing \\['rule'\\]"):
        Decision.from_dict({"name": "delay", "choice": 1})


def test_rows_escape_html_and_tables_keep_column_order():
    d = Decision("records", "a < b", ["x"], evidence=[{"record": "<r>", "score": 0.123456, "wins": True}])
    assert ("rule", "a &lt; b") in d.rows()
    header, rows = d.table_rows()
    assert header == ["record", "score", "wins"] and rows == [["&lt;r&gt;", "0.1235", "yes"]]


def test_each_choice_reads_as_a_sentence_with_units_and_no_keys():
    """A decision's choice is printed as words with units, drawn from its numbers: the sentence follows the choice
    (a region, a forced set of records, one length for every record or one each, a delay the config sets)."""
    region = {"u_min": 1.5, "u_max": 3.5, "u_star": 2.5, "slope": 0.6459}
    assert Decision("working_region", "r", region).choice_text() == (
        "working region 1.5–3.5 A, working point u* = 2.5 A, static gain (slope of ȳ against ū) 0.646 cm/A")
    assert Decision("working_region", "r", {**region, "u_max": 3.0, "u_star": 2.25, "u_sat_model": 3.908}).choice_text() == (
        "working region 1.5–3 A, working point u* = 2.25 A, static gain (slope of ȳ against ū) 0.646 cm/A; the "
        "physical model's current regulator saturates at 3.91 A")
    chosen = {"uniform": ["w1", "w2"], "binary": ["b4"]}
    assert Decision("records", "r", chosen).choice_text() == (
        "uniform white-noise records w1 and w2; random binary record b4")
    forced = Decision("records", "r", {"forced": ["b2", "w1", "w4"], "rule": chosen}, forced=True).choice_text()
    assert forced == ("the records the config names, b2, w1 and w4, forced by the config (the rule would choose "
                      "uniform white-noise records w1 and w2; random binary record b4)")
    same = {"trim_s": 2.0, "est_s": 11.0, "val_s": 11.0, "split": 0.5}
    assert Decision("data_length", "r", {"a": same, "b": same}, forced=True).choice_text() == (
        "each record 2.00 s trimmed, 11.00 s estimation + 11.00 s validation (the trim is the config's)")
    assert Decision("data_length", "r", {"a": same, "b": {**same, "val_s": 7.25}}).choice_text() == (
        "a 2.00 s trimmed, 11.00 s estimation + 11.00 s validation; b 2.00 s trimmed, 11.00 s estimation + 7.25 s "
        "validation")
    assert Decision("alpha", "r", {"b4": 0.4969}).choice_text() == (
        "α = 0.497 for b4 (its measured switching probability per recorded sample)")
    assert Decision("delay", "r", {"nk": 2}).choice_text() == "an input delay of nk = 2 samples"
    assert Decision("delay", "r", {"nk": 3, "rule": 2}, forced=True).choice_text() == (
        "an input delay of nk = 3 samples, set by the config (the rule's answer is nk = 2)")
    assert Decision("orders", "r", {"arx": 6, "bj": 4}).choice_text() == "ARX order 6, BJ order 4"
