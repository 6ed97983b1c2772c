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
