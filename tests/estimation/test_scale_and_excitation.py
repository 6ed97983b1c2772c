"""Estimation does not depend on the data's units, and refuses an input only when it truly does not
excite the orders asked for.

Before: ``arx`` on a record with u × 1e-12 or y × 1e12 said "the regression is singular" (the
unscaled record fits with FIT 98.65 %), BJ's FIT on u × 1e40 moved by 0.03 points, and a
band-limited multisine (60 lines below 12 % of Nyquist, N = 1024) was refused by ``oe(data, 4, 4, 1)``
as "not persistently exciting of order 8" although it excites 120 directions.
"""

from __future__ import annotations

import math
import re
import warnings
from dataclasses import replace

import numpy as np
import pytest
from scipy.signal import lfilter

from maglev import IOData
from maglev import estimation as E
from maglev.estimation import ExcitationWarning
from maglev.refdata import load_record
from maglev.validation import compare

from ..systems import simulate

SCALES = [(1e-12, 1.0), (1.0, 1e12), (1e40, 1e-30)]  # (input factor, output factor)


def _scaled(data: IOData, su: float, sy: float) -> IOData:
    return replace(data, u=data.u * su, y=data.y * sy)


def _same_model_in_other_units(m, ms, su: float, sy: float) -> None:
    """B carries sy/su, the other polynomials nothing; λ scales by sy², the b block of the covariance
    by (sy/su)² — to rounding."""
    for letter in "ACDF":
        np.testing.assert_allclose(getattr(ms, letter), getattr(m, letter), rtol=1e-6, atol=1e-9)
    np.testing.assert_allclose(ms.B, m.B * sy / su, rtol=1e-6, atol=1e-9 * np.max(np.abs(m.B)) * sy / su)
    assert ms.noise_variance == pytest.approx(m.noise_variance * sy**2, rel=1e-6)
    t = np.ones(m.n_params)
    t[m.na : m.na + m.nb] = sy / su
    np.testing.assert_allclose(ms.covariance, m.covariance * np.outer(t, t), rtol=1e-4,
                               atol=1e-9 * np.max(np.abs(m.covariance * np.outer(t, t))))
    assert ms.report.fit_percent == pytest.approx(m.report.fit_percent, abs=1e-6)


@pytest.mark.parametrize("su, sy", SCALES)
@pytest.mark.parametrize("structure, orders", [("arx", (2, 2, 1)), ("armax", (2, 2, 2, 1)), ("oe", (2, 2, 2)),
                                               ("bj", (2, 1, 1, 2, 1))])
def test_a_scaled_copy_gives_the_same_model_in_its_units(structure, orders, su, sy):
    data = simulate(structure, 2000, seed=3)
    val = simulate(structure, 1000, seed=4)
    m = E.estimate(data, structure, orders)
    ms = E.estimate(_scaled(data, su, sy), structure, orders)
    _same_model_in_other_units(m, ms, su, sy)
    assert compare(_scaled(val, su, sy), ms, 1)[0] == pytest.approx(compare(val, m, 1)[0], abs=1e-6)


@pytest.mark.parametrize("su, sy", SCALES[:2])
@pytest.mark.parametrize("structure, orders", [("arx", (4, 1, 8)), ("oe", (2, 2, 1)), ("armax", (2, 2, 2, 1))])
def test_the_real_records_fit_does_not_depend_on_its_units(refdata, structure, orders, su, sy):
    est, val = load_record("binary_signal_2", refdata).detrend().split(0.5)
    m = E.estimate(est, structure, orders)
    ms = E.estimate(_scaled(est, su, sy), structure, orders)
    assert compare(_scaled(val, su, sy), ms, 1)[0] == pytest.approx(compare(val, m, 1)[0], abs=1e-6)
    if structure == "arx":
        assert compare(val, m, 1)[0] == pytest.approx(98.65, abs=0.01)  # MATLAB's published number


@pytest.mark.parametrize("scale", [1e200, 1e-200])
def test_arx_refuses_data_whose_squares_overflow_as_estimate_does(scale):
    data = simulate("arx", 500, seed=1)
    with pytest.raises(ValueError, match=r"^arx-seed1: input u has RMS .*; .* rescale it \(other units\)$"):
        E.arx(_scaled(data, scale, scale), 2, 2, 1)


# ---------------------------------------------------------------------------- persistence of excitation
N = 1024
G = ([0, 0.01, 0.02, -0.005, 0.003], np.real(np.poly([0.95 + 0.2j, 0.95 - 0.2j, 0.9, 0.8])))


def _record(u: np.ndarray, seed: int, name: str) -> IOData:
    noise = 0.01 * np.random.default_rng(seed).standard_normal(u.size)
    return IOData(u, lfilter(*G, u) + noise, 1e-3, name=name)


def _multisine(seed: int) -> IOData:
    """60 cosines on the FFT bins 1 … 60 of 1024 samples (all below 12 % of Nyquist), random phases."""
    t, k = np.arange(N), np.arange(1, 61)
    phases = np.random.default_rng(seed).uniform(0, 2 * math.pi, k.size)
    return _record(np.cos(2 * math.pi * np.outer(t, k) / N + phases).sum(axis=1) / math.sqrt(30), seed + 10,
                   f"multisine{seed}")


@pytest.mark.parametrize("structure, orders", [("oe", (4, 4, 1)), ("arx", (8, 8, 1))])
def test_a_band_limited_multisine_is_estimated_with_a_conditioning_warning(structure, orders):
    est, val = _multisine(1), _multisine(2)
    with pytest.warns(ExcitationWarning, match=r"multisine1: input u is poorly conditioned for order 8 "
                                               r"\(.*\): its lag matrix has condition number 1\.\de\+07"):
        m = E.estimate(est, structure, orders)
    assert compare(val, m, math.inf)[0] > 99  # the 4th-order system behind it, to its 1 % noise


def test_two_sinusoids_are_refused_at_order_6_and_estimated_at_order_4():
    t = np.arange(N)
    data = _record(np.sin(2 * math.pi * 0.013 * t) + 0.5 * np.sin(2 * math.pi * 0.071 * t + 1), 3, "two sines")
    message = ("two sines: input u is not persistently exciting of order 6 (needed by oe[3 3 1]): its 6 lagged "
               "copies span only 5 directions")
    with pytest.raises(ValueError, match="^" + re.escape(message)):
        E.oe(data, 3, 3, 1)
    with warnings.catch_warnings():
        warnings.simplefilter("error", ExcitationWarning)  # 4 lag directions, well apart
        E.oe(data, 2, 2, 1)


@pytest.mark.parametrize("su, sy", SCALES)
def test_order_and_delay_selection_do_not_depend_on_the_units(su, sy):
    """arxstruc's least squares cut columns below eps·N of the largest: with u × 1e-12 the input's
    columns went, and delayest chose nk = 0 for a system with nk = 2."""
    from maglev.estimation.selection import arxstruc, delayest, selstruc

    est, val = simulate("oe", 3000, seed=1), simulate("oe", 3000, seed=2)
    table = arxstruc(est, val, range(1, 5), range(1, 5), range(0, 5))
    scaled = arxstruc(_scaled(est, su, sy), _scaled(val, su, sy), range(1, 5), range(1, 5), range(0, 5))
    np.testing.assert_allclose(scaled["loss"], table["loss"] * sy**2, rtol=1e-8)
    assert selstruc(scaled) == selstruc(table)
    assert delayest(_scaled(est, su, sy)) == delayest(est) == 2
