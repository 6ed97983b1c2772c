"""Configs logged before the package was reorganised still reproduce, metric for metric.

``fixtures/before_layout/*.json`` hold the resolved config and the logged metrics of
two runs (OE and ARMAX on a short simulated binary record, figures and lab steps off)
made at the commit named in each file, before the core moved into packages
(issue 11).  ``maglev reproduce`` re-runs a logged config the same way; this checks
the config format and the numbers survive the move without needing that store.
"""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from maglev.study.reproduce import recompute

FIXTURES = sorted((Path(__file__).parent / "fixtures" / "before_layout").glob("*.json"))


@pytest.mark.parametrize("path", FIXTURES, ids=[p.stem for p in FIXTURES])
def test_a_config_logged_before_the_move_reproduces_identically(path):
    logged = json.loads(path.read_text())
    ok, rows, _ = recompute(logged["config"], logged["metrics"])
    assert len(rows) >= 30  # every metric but the timing
    assert ok, [row for row in rows if row[1] != row[2]]
