"""Nested orders: one more coefficient never raises the minimum (real records, zero initial conditions).

With zero initial conditions a model one order higher in one polynomial contains the
lower one (its extra coefficient zero), so its minimum loss cannot be higher; an
estimator that ends above it has stopped in a poorer local minimum.  Grids: OE nb, nf 1..4; ARMAX na, nb, nc 1..3; BJ nb, nc, nd, nf 1..3; nk = 1 — on
the first halves (means removed) of DaISy's dryer and the lab's binary_signal_2.

Plain calls, as a user makes them, are checked on the OE and ARMAX grids and on
nested BJ pairs (the whole BJ grids pass too, but take a minute or more).  The BJ
grids are also swept as a study would, each model warm-started (``init``) from its
best nested lower model: a guarantee by construction, which checks that the warm
start lands in the right coefficients and is never lost.
"""

from __future__ import annotations

import functools
import itertools
from pathlib import Path

import numpy as np
import pytest

from maglev.data import IOData
from maglev.estimation import estimate
from maglev.refdata import load_record
from maglev.sim.labdata import ExperimentSpec, experiment
from maglev.sim.plant import rig

GRIDS = {"oe": (2, range(1, 5)), "armax": (3, range(1, 4)), "bj": (4, range(1, 4))}
SLACK = 0.01  # the criterion: no higher model more than 1 % above its nested lower one


def first_half(refdata, record: str) -> IOData:
    if record == "dryer":
        data = IOData.from_csv(refdata / "daisy" / "dryer.csv", Ts=0.08)
    else:
        data = load_record(record, root=refdata)
    return data.detrend().split(0.5)[0]


def loss(data: IOData, structure: str, orders: tuple[int, ...], init=None):
    return estimate(data, structure, [*orders, 1], initial_condition="zero", init=init)


@functools.lru_cache(maxsize=None)
def plain_bj_loss(refdata: Path, record: str, orders: tuple[int, ...]) -> float:
    """The loss of a plain BJ call on the record's first half, fitted once for the file (both white-noise tests
    below fit BJ [2 2 2 2 1]; a plain call's minimum does not depend on what was fitted before it)."""
    return loss(first_half(refdata, record), "bj", orders).report.loss


def lower_neighbours(orders: tuple[int, ...]) -> list[tuple[int, ...]]:
    return [orders[:i] + (orders[i] - 1,) + orders[i + 1 :] for i in range(len(orders)) if orders[i] > 1]


def fit_grid(data: IOData, structure: str, warm: bool) -> dict[tuple[int, ...], float]:
    """Loss of every model on the grid; with ``warm`` each starts from its best lower neighbour."""
    n, orders = GRIDS[structure]
    losses, models = {}, {}
    for o in sorted(itertools.product(orders, repeat=n), key=sum):
        lower = lower_neighbours(o)
        init = models[min(lower, key=losses.get)] if warm and lower else None
        models[o] = loss(data, structure, o, init)
        losses[o] = models[o].report.loss
    return losses


def violations(losses: dict[tuple[int, ...], float], slack: float = SLACK) -> list[tuple]:
    """Nested pairs (lower, higher, relative excess) where the higher model ends above the lower one."""
    return [
        (low, o, float(f"{losses[o] / losses[low] - 1:.3g}"))
        for o in losses
        for low in lower_neighbours(o)
        if losses[o] > losses[low] * (1 + slack)
    ]


@pytest.mark.parametrize("record, structure", [
    ("dryer", "oe"), ("dryer", "armax"), ("binary_signal_2", "oe"), ("binary_signal_2", "armax"),
])
def test_plain_calls_never_end_above_the_nested_lower_model(refdata, record, structure):
    assert violations(fit_grid(first_half(refdata, record), structure, warm=False)) == []


# BJ grids take ≈ 30-80 s a record as plain calls; the suite checks a random sample of
# dryer's pairs and the lab record's pairs that ended 17 % and 12 % above their lower
# model before the nested starts were searched fully (both full grids: no violation).
BJ_PAIRS = {"binary_signal_2": [((1, 1, 2, 3), (1, 1, 3, 3)), ((1, 2, 2, 3), (1, 3, 2, 3))]}


@pytest.mark.parametrize("record", ["dryer", "binary_signal_2"])
def test_plain_bj_calls_on_nested_pairs(refdata, record):
    data = first_half(refdata, record)
    grid = list(itertools.product(range(1, 4), repeat=4))
    pairs = [(low, o) for o in grid for low in lower_neighbours(o)]
    sample = BJ_PAIRS.get(record) or [pairs[i] for i in np.random.default_rng(10).choice(len(pairs), 8, replace=False)]
    losses = {o: loss(data, "bj", o).report.loss for o in {o for pair in sample for o in pair}}
    excess = {pair: losses[pair[1]] / losses[pair[0]] - 1 for pair in sample}
    assert max(excess.values()) <= SLACK, excess


@pytest.mark.parametrize("record", ["dryer", "binary_signal_2"])
def test_bj_sweep_with_warm_starts_never_raises_the_loss(refdata, record):
    """Each model ends at or below its warm start, the best of its lower neighbours."""
    losses = fit_grid(first_half(refdata, record), "bj", warm=True)
    assert violations(losses) == []
    rises = {o: losses[o] / min(losses[low] for low in lower_neighbours(o)) - 1
             for o in losses if lower_neighbours(o)}
    assert max(rises.values()) <= 1e-9, max(rises.items(), key=lambda kv: kv[1])


# On white_noise_2's first half the BJ losses lie within 0.5 % of each other and the basin
# BJ [2 2 2 2 1] ends in is reached only from a start of its own lower model BJ [2 1 2 2 1]:
# BJ [2 3 2 2 1] and [2 2 3 2 1] ended 0.29 % and 0.25 % above BJ [2 2 2 2 1] while the
# lower models they searched did not search their own lower models.
WHITE_NOISE_PAIRS = [((2, 2, 2, 2), (2, 3, 2, 2)), ((2, 2, 2, 2), (2, 2, 3, 2))]


def test_plain_bj_calls_on_white_noise_never_end_above_the_nested_lower_model(refdata):
    losses = {o: plain_bj_loss(refdata, "white_noise_2", o) for o in {o for pair in WHITE_NOISE_PAIRS for o in pair}}
    excess = {pair: losses[pair[1]] / losses[pair[0]] - 1 for pair in WHITE_NOISE_PAIRS}
    assert max(excess.values()) <= 1e-9, excess


def test_plain_bj_calls_on_white_noise_sweep_of_nested_pairs(refdata):
    """Every nested pair of BJ [nb nc nd nf 1], orders 1..2, on white_noise_2's first half (32 pairs):
    no higher model ends above its lower one, to rounding (pairs ended up to 0.37 % above when
    a converged first minimum was accepted against its lower models' first runs alone)."""
    losses = {o: plain_bj_loss(refdata, "white_noise_2", o) for o in itertools.product(range(1, 3), repeat=4)}
    assert violations(losses, slack=1e-9) == []


def test_bj_on_the_simulated_lab_record_finds_the_minimum_its_lower_models_lead_to():
    """BJ [4 4 4 4 2] on binary_a025's estimation half, as the study fits it (initial conditions
    "auto"): its principal start ends at 1.417e-4; the lower models BJ [4 4 3 4 2] and
    [4 4 4 3 2], searched from their own starts and padded, lead to 1.0928e-4 (a search that
    certified the first minimum against quickly minimised lower models stopped at 1.42e-4)."""
    spec = ExperimentSpec(kind="binary", low=1.5, high=4.0, alpha=0.25, duration_s=24.0, seed=13, Ts=0.001)
    est = experiment(spec, plant=rig("stuck_stretched")).trim(2000).detrend().decimate(2).split(0.5)[0]
    m = estimate(est, "bj", [4, 4, 4, 4, 2])
    assert m.report.loss <= 1.0928e-4, m.report.loss
