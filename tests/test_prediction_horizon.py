"""k-step prediction over the whole range of horizons: the number of fitted initial values does not
grow with k, the FIT falls towards the simulation FIT, and any horizon costs O(N).

Before, every extra step of the horizon freed one more pre-sample value, so on 4 s of
binary_signal_2's validation half ARX [4 1 8] scored 98.54 / 88.94 / 12.30 / 22.57 / 100.00 %
at k = 1 / 5 / 50 / 500 / N − 1 (simulation: 13.29 %), and a horizon of 10**5 took 1.7 GB.
"""

from __future__ import annotations

import functools
import math
import time
import tracemalloc
from pathlib import Path

import numpy as np
import pytest

from maglev import estimation as E
from maglev.data import IOData
from maglev.lab.records import length_split, start_transient
from maglev.refdata import load_record
from maglev.validation import compare

from .systems import simulate, true_model

HORIZONS = (1, 5, 50, 500)


def _horizons(N: int) -> tuple[int, ...]:
    return (*HORIZONS, N - 1)


@pytest.mark.parametrize("name", ["arx", "armax", "oe", "bj"])
def test_the_true_models_k_step_fit_falls_with_k_to_its_simulation_fit(name):
    """For the true model the k-step error H̄_k e has variance σ² Σ_{i<k} h_i², which grows with k:
    the FIT is non-increasing (up to the sample's cross terms between innovations, which the
    impulse response's tail beyond k = 50 keeps below 1e-3 points) and reaches the simulation FIT."""
    for seed in range(2):
        data = simulate(name, 4000, seed, binary=True)
        m = true_model(name)
        fits = [compare(data, m, k)[0] for k in _horizons(data.N)]
        assert np.all(np.diff(fits) <= 1e-3), (name, seed, fits)
        assert fits[-1] == pytest.approx(compare(data, m, math.inf)[0], abs=0.05)
        if name != "oe":  # an output-error model's predictions do not depend on the horizon
            assert fits[0] > fits[1] + 5


@functools.cache
def _record(root: Path) -> tuple[IOData, IOData]:
    """binary_signal_2's estimation half, and 4 s of its validation half (the issue's numbers)."""
    est, val = load_record("binary_signal_2", root).detrend().split(0.5)
    return est, val.segment(0, 4000)


@functools.cache
def _model(root: Path, structure: str):
    est, _ = _record(root)
    return {"arx": lambda: E.arx(est, 4, 1, 8), "armax": lambda: E.armax(est, 2, 2, 2, 1),
            "oe": lambda: E.oe(est, 2, 2, 1)}[structure]()


@pytest.mark.parametrize("structure", ["arx", "armax", "oe"])
def test_real_records_k_step_fit_never_climbs_back_and_ends_at_the_simulation_fit(refdata, structure):
    """On the real record: the FIT falls over k = 1, 5, 50, no horizon scores above the one-step FIT,
    k = N − 1 scores the simulation FIT (it scored 100 %).  That as many initial values are fitted
    for every k is rebuilt by hand for ARX in ``estimation/test_matlab_conventions.py``.

    A model that does not fit the plant (simulation FIT 13 % for ARX [4 1 8], 0.3 % for ARMAX
    [2 2 2 1]) predicts 50 steps ahead slightly worse than it simulates, also from a zero initial
    state: restarting from a measured output it cannot explain costs more than never using it.
    So past k = 50 the test asks the FIT to be within 10 points of the simulation FIT, not below it.
    """
    _, val = _record(refdata)
    m = _model(refdata, structure)
    fits = {k: compare(val, m, k)[0] for k in _horizons(val.N)}
    simulation = compare(val, m, math.inf)[0]
    slack = 1e-9  # OE predicts every horizon as it simulates: equal FITs differ by rounding only
    assert fits[1] + slack >= fits[5] and fits[5] + slack >= fits[50], fits
    assert max(fits.values()) <= fits[1] + slack, fits
    assert fits[val.N - 1] == pytest.approx(simulation, abs=1e-6)
    assert abs(fits[500] - simulation) < 10


@functools.cache
def _study_record(root: Path) -> tuple[IOData, IOData]:
    """binary_signal_2 prepared as the study prepares a real record: the start transient trimmed,
    detrended, decimated to Ts = 2 ms, split by the lab's length rule (5000 + 5000 samples)."""
    raw = load_record("binary_signal_2", root)
    trim = start_transient(raw.y, raw.Ts).samples
    data = (raw.trim(trim) if trim else raw).detrend().decimate(2)
    return data.split(length_split(data.N, data.Ts)[0])


@pytest.mark.parametrize("structure, orders", [("arx", (5, 5, 2)), ("armax", (6, 6, 6, 2)), ("oe", (3, 3, 2))])
def test_adequate_models_k_step_fit_is_non_increasing_in_k_on_a_real_record(refdata, structure, orders):
    """The issue's criterion on models of adequate orders for the rig (ARX 5, ARMAX 6, OE 3, nk = 2, inside
    the real sweep's grids; not the poor models of the test above): the FIT at k = 1, 5, 50, 500, N − 1 never rises (to rounding) and ends at the
    simulation FIT.  On this record ARX falls 98.2 → 10.5 and ARMAX 99.1 → 12.8; OE's predictions
    do not depend on k.  (Not every record gives this for every model: on white_noise_2 ARMAX
    [6 6 6 2] scores -1.5 % at k = 500 and its simulation 2.2 %.)"""
    est, val = _study_record(refdata)
    m = E.estimate(est, structure, list(orders))
    fits = [compare(val, m, k)[0] for k in _horizons(val.N)]
    assert np.all(np.diff(fits) <= 1e-6), fits
    assert fits[-1] == pytest.approx(compare(val, m, math.inf)[0], abs=1e-6)
    if structure != "oe":
        assert fits[0] > fits[2] + 50, fits


def test_a_horizon_of_the_record_length_or_more_is_simulation():
    m = true_model("armax")
    data = simulate("armax", 600, seed=4)
    for ic in ("zero", "estimate"):
        sim = m.predict(data, math.inf, ic)
        for k in (data.N, data.N + 1, 10**9):
            np.testing.assert_array_equal(m.predict(data, k, ic), sim)
    # one step short of the record: from zero state only the last sample sees a measured output
    np.testing.assert_allclose(m.predict(data, data.N - 1)[:-1], m.simulate(data.u)[:-1], atol=1e-12)


def test_any_horizon_costs_o_of_n_time_and_memory():
    """A horizon of 10**9 samples on 20 000 samples: well under a second of CPU and a few N-long arrays
    (it asked for 7.45 GiB before); every horizon below N too."""
    m = E.bj(simulate("bj", 2000, seed=5), 2, 1, 1, 2, 1)
    data = simulate("bj", 20_000, seed=6)
    tracemalloc.start()
    try:
        cpu = time.process_time()
        m.predict(data, 10**9, "estimate")
        cpu = time.process_time() - cpu
        _, peak_long = tracemalloc.get_traced_memory()
        tracemalloc.reset_peak()
        m.predict(data, data.N - 1, "estimate")
        _, peak_below = tracemalloc.get_traced_memory()
    finally:
        tracemalloc.stop()
    assert cpu < 1.0
    n_bytes = 8 * data.N
    assert peak_long < 40 * n_bytes and peak_below < 40 * n_bytes, (peak_long / n_bytes, peak_below / n_bytes)
