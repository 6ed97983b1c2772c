"""The final-order rule on a known second-order system, and its decision's sentences."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.signal import lfilter

from maglev.data import IOData
from maglev.estimation import estimate
from maglev.lab.orders import away_from_bla, cancelling_order, final_order, orders_decision, statuses
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
    assert d.reasons == [f"OE: order 2, the smallest within 1 point of the best that counts; order(s) [3, 4] gain less "
                         "than 1 point over order 2: the FIT has levelled off (the physical model has "
                         "2 states)."]


def test_the_sentence_flips_to_a_caution_when_the_fit_still_rises_at_the_top():
    rising = {4: 39.0, 5: 51.0, 6: 53.5, 7: 56.7}
    assert final_order(rising) == (7, False)
    d = orders_decision({"arx": rising}, {"arx": {4: -5.0, 5: -5.5, 6: -5.6, 7: -5.8}}, physics_order=4)
    assert d.reasons == [] and d.cautions[0].startswith("ARX: order 7 is the largest swept")
    assert "its FIT has not levelled off" in d.cautions[0]
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
    assert d.reasons == ["OE: order 4, the smallest within 1 point of the best that counts; order(s) [5] do not count: "
                         "their models move away from the best linear approximation (mean distance 4: 0.43, 5: 1.16)."]
    closer = orders_decision({"oe": fit}, bla={"oe": {4: 0.43, 5: 0.40}})  # the numbers flip, so does the text
    assert closer.choice == {"oe": 5} and closer.cautions and not closer.reasons


def test_an_unsettled_order_never_moves_away_from_the_bla():
    # the rule's guarantee that let the study drop its "yet the distance to the BLA grows" caution: an order at the
    # top of the grid that is not settled (chosen == the largest swept) has never moved away from the BLA, nor come
    # after an order whose added poles are cancelled, on any grid, FIT, distances and cancellations (random draws,
    # distances missing at some orders)
    rng = np.random.default_rng(7)
    unsettled = 0
    for _ in range(2000):
        grid = sorted(rng.choice(np.arange(1, 9), size=rng.integers(2, 6), replace=False).tolist())
        fit = {o: float(rng.uniform(0, 100)) for o in grid}
        bla = {o: float(rng.uniform(0, 2)) for o in grid if rng.random() < 0.85}
        cancels = {o: float(rng.uniform(0, 1.5)) for o in grid}
        chosen, settled = final_order(fit, bla=bla, cancellations=cancels)
        if not settled:
            unsettled += 1
            assert chosen == grid[-1] and chosen not in away_from_bla(bla, grid)
            assert cancelling_order(cancels, grid) is None  # nor was any order's added pole cancelled
            if chosen in bla:  # so its distance is no larger than the order below's
                assert bla[chosen] == min(bla.values())
    assert unsettled > 100  # the draws reach the case


def test_a_known_second_order_systems_order_three_models_cancel_their_added_pole():
    # three records of a known OE with two poles: every order-3 model spends its added pole on a near pole-zero
    # cancellation (one more per model than at order 2), so the rule stops there; order 2 stays settled
    cancels, fits = {o: [] for o in (1, 2, 3)}, {o: [] for o in (1, 2, 3)}
    for seed in (1, 2, 3):
        rng = np.random.default_rng(seed)
        u = rng.standard_normal(4000)
        y = lfilter([0.0, 0.4, 0.25], [1.0, -1.3, 0.6], u) + 0.03 * rng.standard_normal(4000)
        est, val = IOData(u[:2000], y[:2000], 1.0), IOData(u[2000:], y[2000:], 1.0)
        for o in cancels:
            m = estimate(est, "oe", [o, o, 1], "auto")
            cancels[o].append(len(m.near_cancellations()))
            fits[o].append(compare(val, m, math.inf)[0])
    mean_cancel = {o: float(np.mean(v)) for o, v in cancels.items()}
    assert mean_cancel[2] == 0 and mean_cancel[3] >= mean_cancel[2] + 1
    assert cancelling_order(mean_cancel, [1, 2, 3]) == 3
    assert final_order({o: float(np.mean(v)) for o, v in fits.items()}, cancellations=mean_cancel) == (2, True)


def test_an_order_whose_added_poles_are_cancelled_stops_the_search_and_the_sentence_says_so():
    fit = {2: 11.0, 3: 12.5, 4: 12.7, 5: 13.0, 6: 14.2, 7: 2.0}  # order 6 gains 1.2 points over 5
    assert final_order(fit) == (6, True)
    grows = {2: 0.5, 3: 1.0, 4: 1.0, 5: 1.5, 6: 2.5, 7: 2.5}  # ... with one more near cancellation per model
    assert cancelling_order(grows, sorted(fit)) == 6
    assert final_order(fit, cancellations=grows) == (3, True)  # among 2-5: within 1 point of 13.0
    d = orders_decision({"oe": fit}, cancellations={"oe": grows})
    assert d.choice == {"oe": 3} and d.cautions == []
    assert d.reasons == ["OE: order 3, the smallest within 1 point of the best that counts; order 6 adds poles its "
                         "models cancel with zeros (2.50 near cancellations per model against 1.50 at order 5): order 6 "
                         "and the orders above it ([7]) do not count, whatever FIT they gain; order(s) [4, 5] gain less "
                         "than 1 point over order 3: the FIT has levelled off."]
    status = {r["order"]: r["status"] for r in d.evidence}
    assert status == {2: "2.00 points below the best, more than 1", 3: "final",
                      4: "gains +0.20 points over order 3, less than 1", 5: "gains +0.50 points over order 3, less than 1",
                      6: "its added poles are cancelled by zeros", 7: "above order 6, whose added poles are cancelled by zeros"}
    assert statuses(d)[("oe", 6)] == "its added poles are cancelled by zeros"
    # a little less growth (0.9 per model): order 6's poles are not all cancelled, its FIT gain counts
    fewer = {**grows, 6: 2.4, 7: 2.4}
    assert cancelling_order(fewer, sorted(fit)) is None
    d = orders_decision({"oe": fit}, cancellations={"oe": fewer})
    assert d.choice == {"oe": 6} and not any("cancel with zeros" in r for r in d.reasons)
    # over a gap in the grid the growth is per order added: 4 -> 6 needs two more per model
    assert cancelling_order({4: 0.0, 6: 1.5}, [4, 6]) is None and cancelling_order({4: 0.0, 6: 2.0}, [4, 6]) == 6


def test_a_cancelling_order_at_the_top_of_the_grid_settles_the_order_below():
    # the FIT still rises at the top, but the top order's added poles are cancelled: no order to add
    assert final_order({4: 20.0, 5: 23.0}) == (5, False)
    assert final_order({4: 20.0, 5: 23.0}, cancellations={4: 0.0, 5: 1.0}) == (4, True)
    d = orders_decision({"arx": {4: 20.0, 5: 23.0}}, cancellations={"arx": {4: 0.0, 5: 1.0}})
    assert d.cautions == [] and "order 5 does not count, whatever FIT it gains." in d.reasons[0]
