"""The working-region rule on constructed staircases with a known answer, and its decision's sentences."""

from __future__ import annotations

import numpy as np
import pytest

from maglev.lab.signals import staircase
from maglev.lab.working_region import region_decision, saturation_plateau, working_region

LEVELS = np.arange(0, 10.5, 0.5)


def _stairs(y_levels, dwell=20):
    return staircase(LEVELS, dwell), staircase(y_levels, dwell)


def _rig_like(bend: float) -> np.ndarray:
    """Resting at 8 until 1.5 A, linear 0.65 cm/A up to 3.5 A, then up by ``bend`` × 0.65 × 0.5 to the plateau
    at 4 A and flat to 9.5 A; the 10 A level drops (the rig's quirk)."""
    y = np.where(LEVELS <= 1.5, 8.0, 8.0 + 0.65 * (LEVELS - 1.5))
    top = 8.0 + 0.65 * 2.0 + bend * 0.65 * 0.5
    y = np.where(LEVELS >= 4.0, top, y)
    y[-1] = 8.0
    return y


def test_a_plateau_is_excluded_even_when_its_step_is_nearly_linear():
    # the step onto the plateau keeps 90 % of the slope: the slope band alone would take 4 A in
    u, y = _stairs(_rig_like(0.9))
    wr = working_region(u, y, 21, 50)
    assert (wr.u_min, wr.u_max) == (1.5, 3.5)
    assert wr.plateau_level == pytest.approx(_rig_like(0.9)[8]) and LEVELS[wr.plateau_first] == 4.0
    assert wr.on_plateau()[8] and not wr.on_plateau()[7]


def test_without_a_plateau_the_region_runs_to_the_last_linear_level():
    y = 8.0 + 0.65 * np.clip(LEVELS - 1.5, 0, None)  # no saturation at all
    wr = working_region(*_stairs(y), 21, 50)
    assert (wr.u_min, wr.u_max) == (1.5, 10.0) and wr.plateau_first == -1


def test_the_resting_zone_is_not_a_plateau():
    level, first = saturation_plateau(LEVELS, _rig_like(0.5))
    assert LEVELS[first] == 4.0 and level > 9.0


def test_decision_states_why_each_bound_stops_and_flips_with_the_model_saturation():
    wr = working_region(*_stairs(_rig_like(0.5)), 21, 50)
    inside = region_decision(wr, u_sat=3.8)
    assert inside.choice["u_max"] == 3.5 and inside.cautions == []
    assert any("on the plateau" in r and "Upper bound 3.5 A" in r for r in inside.reasons)
    assert any("lies between the region's upper bound 3.5 A" in r for r in inside.reasons)
    assert any("resting zone" in r for r in inside.reasons)
    outside = region_decision(wr, u_sat=5.2)  # a model saturating on the plateau: two stories
    assert not any("lies between" in r for r in outside.reasons)
    assert outside.cautions and "5.2 A, lies outside [3.5, 4] A" in outside.cautions[0]
    rows = inside.evidence
    assert [r["in region"] for r in rows].count(True) == 5 and rows[8]["on plateau"]
