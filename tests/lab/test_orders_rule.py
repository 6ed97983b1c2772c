"""The final-order rule on a known second-order system, and its decision's sentences."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.signal import lfilter

from maglev.data import IOData
from maglev.estimation import estimate
from maglev.lab.orders import away_from_bla, final_order, orders_decision
from maglev.validation import compare


def test_a_known_second_order_system_settles_at_order_two():
    rng = np.random.default_rng(4)
    u = rng.standard_normal(4000)
    y = lfilter([0.0, 0.4, 0.25], [1.0, -1.3, 0.6], u) + 0.1 * rng.standard_normal(4000)  # OE, 2 poles
    est, val = IOData(u[:2000], y[:2000], 1.0), IOData(u[2000:], y[2000:], 1.0)
    fit = {o: compare(val, estimate(est, "oe", [o, o, 1], "auto"), math.inf)[0] for o in (1, 2, 3, 4)}
    assert fit[2] - fit[1] > 1.0  # the order below is missing a pole
    d = orders_decision({"oe": fit}, physics_order=2)
    assert d.choice == {"oe": 2} and d.cautions == []
    assert d.reasons[0].startswith("oe: order 2 — mean simulation FIT") and "levelled off" in d.reasons[0]


def test_the_sentence_flips_to_a_caution_when_the_fit_still_rises_at_the_top():
    rising = {4: 39.0, 5: 51.0, 6: 53.5, 7: 56.7}
    assert final_order(rising) == (7, False)
    d = orders_decision({"arx": rising}, {"arx": {4: -5.0, 5: -5.5, 6: -5.6, 7: -5.8}}, physics_order=4)
    assert d.reasons == [] and d.cautions[0].startswith("arx: order 7 is the largest swept")
    assert "sweep order 8 (++hydra.sweeper.orders.arx=[4,5,6,7,8])" in d.cautions[0]
    assert "AIC is lowest at order 7" in d.cautions[0]
    levelled = {**rising, 8: 57.2, 9: 57.4}
    d = orders_decision({"arx": levelled})
    assert d.choice == {"arx": 7} and d.cautions == [] and "order(s) [8, 9] gain less than 1 point" in d.reasons[0]


def test_no_fit_is_refused():
    with pytest.raises(ValueError, match="no orders"):
        final_order({})


def test_an_order_moving_away_from_the_bla_does_not_count():
    fit = {4: 19.2, 5: 20.6}
    assert final_order(fit) == (5, False)
    assert final_order(fit, bla={4: 0.43, 5: 1.16}) == (4, True)
    d = orders_decision({"oe": fit}, bla={"oe": {4: 0.43, 5: 1.16}})
    assert d.choice == {"oe": 4} and d.cautions == []
    assert d.reasons[0].startswith("oe: order(s) [5] do not count") and "levelled off" in d.reasons[1]
    closer = orders_decision({"oe": fit}, bla={"oe": {4: 0.43, 5: 0.40}})  # the numbers flip, so does the text
    assert closer.choice == {"oe": 5} and closer.cautions and not closer.reasons


def test_an_unsettled_order_never_moves_away_from_the_bla():
    # the rule's guarantee that let the study drop its "yet the distance to the BLA grows" caution: an order at the
    # top of the grid that is not settled (chosen == the largest swept) has never moved away from the BLA, on any
    # grid, FIT and distances (random draws, distances missing at some orders)
    rng = np.random.default_rng(7)
    unsettled = 0
    for _ in range(2000):
        grid = sorted(rng.choice(np.arange(1, 9), size=rng.integers(2, 6), replace=False).tolist())
        fit = {o: float(rng.uniform(0, 100)) for o in grid}
        bla = {o: float(rng.uniform(0, 2)) for o in grid if rng.random() < 0.85}
        chosen, settled = final_order(fit, bla=bla)
        if not settled:
            unsettled += 1
            assert chosen == grid[-1] and chosen not in away_from_bla(bla, grid)
            if chosen in bla:  # so its distance is no larger than the order below's
                assert bla[chosen] == min(bla.values())
    assert unsettled > 100  # the draws reach the case
