"""Tests of maglev.plant: statics against the force balance, stops, linearisation, noise, speed."""

import re
import time

import control as ct
import numpy as np
import pytest
from scipy import signal

from maglev.estimate import arx
from maglev.plant import Levitator, LevitatorParams
from maglev.signals import random_binary


def _forces(p: LevitatorParams, current: float, z: float, h: float) -> tuple[float, float]:
    """Net static force on the lower and upper magnet, written out from the force laws."""
    fm = p.c / (h - z + p.d) ** 4
    lower = current / (p.a * (z + p.b) ** p.n_coil) - fm - p.m * p.g
    upper = fm - p.kappa * current / (p.a * (h + p.b) ** p.n_coil) - p.m * p.g
    return lower, upper


@pytest.mark.parametrize("u0", [0.0, 1.0, 2.0, 2.75, 3.5])
def test_equilibrium_balances_forces_and_is_where_the_simulation_settles(u0):
    lev = Levitator()
    eq = lev.equilibrium(u0)
    lower, upper = _forces(lev.params, eq.current, eq.z, eq.h)
    assert abs(upper) < 1e-9
    if eq.lower_seated:
        assert eq.z == 0.0 and lower <= 0.0  # the seat carries the rest
    else:
        assert abs(lower) < 1e-9
    data = lev.simulate(np.full(3000, u0), noise=False)
    assert data.meta["h"][-1] == pytest.approx(eq.h, abs=1e-6)
    assert data.meta["z"][-1] == pytest.approx(eq.z, abs=1e-6)
    assert data.y[-1] == pytest.approx(eq.y, abs=1e-6)


def test_dead_zone_and_saturation_of_the_static_curve():
    lev = Levitator()
    y = lev.static_curve(np.array([0.0, 0.5, 1.0, 2.0, 3.0, 5.0, 9.5]))
    assert np.ptp(y[:3]) < 0.1  # dead zone: lower magnet seated
    assert y[4] - y[3] > 0.2  # sensitive once levitated
    assert y[5] == pytest.approx(y[6], abs=1e-12)  # regulator saturation
    assert lev.equilibrium(0.5).lower_seated and not lev.equilibrium(2.0).lower_seated


def test_seat_and_top_stop_hold():
    lev = Levitator()
    low = lev.simulate(random_binary(3000, 0.1, 0.0, 1.0, seed=1), noise=False)
    assert np.all(low.meta["z"] == 0.0)  # below lift-off the lower magnet never leaves its seat
    wild = lev.simulate(random_binary(5000, 0.02, 0.0, 4.0, seed=2), noise=False)
    assert wild.meta["z"].min() == 0.0 and wild.meta["z"].max() > 1.0
    capped = lev.with_params(h_top=8.6)
    data = capped.simulate(np.full(2000, 3.5), noise=False)
    assert data.meta["h"].max() <= 8.6
    assert data.meta["h"][-1] == 8.6 and capped.equilibrium(3.5).upper_at_top


def test_logging_quirk_zero_at_10():
    quirky = Levitator(zero_at_10=True)
    assert quirky.equilibrium(10.0).y == pytest.approx(quirky.equilibrium(0.0).y)
    assert Levitator().equilibrium(10.0).y == pytest.approx(Levitator().equilibrium(5.0).y)


def _dominant(poles, Ts):
    s = np.log(np.asarray(poles, dtype=complex)) / Ts
    s = s[np.isfinite(s) & (s.imag > 1e-9)]
    p = s[np.argmin(np.abs(s))]
    return abs(p), -p.real / abs(p)


def test_linearisation_matches_small_signal_identification():
    lev = Levitator()
    lin = lev.linearize(2.75)
    u = 2.75 + 0.01 * (random_binary(8000, 0.5, -1.0, 1.0, seed=4))
    data = lev.simulate(u, noise=False, start=2.75, substeps=16)
    data = data.trim(500).detrend()
    nd = lin.delay_samples
    model = arx(data, 4, 4, nd + 1)  # ZOH: one sample of lag plus the pure delay
    wn_id, z_id = _dominant(model.poles(), data.Ts)
    wn_true, z_true = _dominant(ct.poles(lin.sys_d), lin.Ts)
    assert wn_id == pytest.approx(wn_true, rel=0.03)
    assert z_id == pytest.approx(z_true, rel=0.05)
    # the continuous model's poles map onto the discrete ones
    pc = np.sort_complex(np.exp(ct.poles(lin.sys_c) * lin.Ts))
    pd = np.sort_complex(ct.poles(lin.sys_d)[np.abs(ct.poles(lin.sys_d)) > 1e-9])
    assert np.allclose(pc, pd, atol=1e-9)


def test_linear_gain_equals_static_slope():
    lev = Levitator()
    for u0 in (2.0, 3.0):
        slope = (lev.equilibrium(u0 + 1e-4).y - lev.equilibrium(u0 - 1e-4).y) / 2e-4
        lin = lev.linearize(u0)
        assert lin.dc_gain == pytest.approx(slope, rel=1e-4)
        assert float(np.real(ct.dcgain(lin.sys_d))) == pytest.approx(slope, rel=1e-4)
    assert lev.linearize(6.0).dc_gain == 0.0  # saturated regulator: no small-signal gain


def test_time_base_flag_stretches_transients():
    labelled, physical = Levitator(), Levitator(physical_time=True)
    scale = labelled.params.t_phys / 1e-3
    assert labelled.time_scale() == pytest.approx(scale) and physical.time_scale() == 1.0
    wn_l = max(abs(p) for p in ct.poles(labelled.linearize(2.75).sys_c))
    wn_p = max(abs(p) for p in ct.poles(physical.linearize(2.75).sys_c))
    assert wn_l / wn_p == pytest.approx(scale)
    u = np.r_[np.full(1000, 2.5), np.full(3000, 3.0)]
    t_l = np.argmax(labelled.simulate(u, start=2.5, noise=False).y > labelled.equilibrium(2.75).y)
    t_p = np.argmax(physical.simulate(u, start=2.5, noise=False).y > physical.equilibrium(2.75).y)
    assert (t_p - 1000) / (t_l - 1000) == pytest.approx(scale, rel=0.25)


def test_noise_level_spectrum_quantisation_and_seed():
    lev = Levitator()
    d1 = lev.simulate(np.full(20000, 3.0), seed=7)
    d2 = lev.simulate(np.full(20000, 3.0), seed=7)
    d3 = lev.simulate(np.full(20000, 3.0), seed=8)
    assert np.array_equal(d1.y, d2.y) and not np.array_equal(d1.y, d3.y)
    y = d1.y[5000:]
    p = lev.params
    assert np.std(y) == pytest.approx(p.noise_std, rel=0.15)
    grid = y / p.quant
    assert np.allclose(grid, np.round(grid), atol=1e-6)
    f, psd = signal.welch(y - y.mean(), nperseg=512)
    assert 0.30 <= f[np.argmax(psd)] <= 0.34  # mains ripple aliased as in the real records


def test_sixty_seconds_simulate_fast():
    lev = Levitator()
    u = random_binary(60_000, 0.25, 1.5, 4.0, seed=0)
    best = np.inf
    for _ in range(2):
        t0 = time.perf_counter()
        lev.simulate(u, Ts=0.001, seed=0)
        best = min(best, time.perf_counter() - t0)
    assert best < 1.0


@pytest.mark.parametrize("bad", [-0.5, 10.5])
def test_current_outside_range_is_refused(bad):
    u = np.full(100, 2.0)
    u[10] = bad
    with pytest.raises(ValueError, match=r"u must stay within .*\[0, 10\] A.*" + re.escape(repr(bad))):
        Levitator().simulate(u)
    with pytest.raises(ValueError, match="u must stay within"):
        Levitator().linearize(bad)


def test_bad_parameters_are_named():
    with pytest.raises(ValueError, match="LevitatorParams.m must be a positive number, got -1"):
        LevitatorParams(m=-1.0)
    with pytest.raises(ValueError, match="Ts must be"):
        Levitator().simulate(np.full(100, 2.0), Ts=0.0)
