"""PolyModel: predictions against independent computations, conversions and round-trips."""

from __future__ import annotations

import json
import math

import control as ct
import numpy as np
import pytest
from scipy import signal

from maglev.data import IOData
from maglev.model import PolyModel

from .systems import simulate, true_model


@pytest.mark.filterwarnings("ignore:Badly conditioned filter coefficients")  # scipy strips B's nk leading zeros
def test_simulation_matches_scipy_dlsim():
    m = true_model("bj")
    u = np.random.default_rng(0).standard_normal(300)
    num, den = m.G_polys
    n = max(num.size, den.size)
    _, y = signal.dlsim((np.pad(num, (0, n - num.size)), np.pad(den, (0, n - den.size)), 1.0), u)
    np.testing.assert_allclose(m.simulate(u), y[:, 0], atol=1e-10)


def test_one_step_predictor_of_armax_equals_direct_recursion():
    """ŷ(t) = -a1 y(t-1) - a2 y(t-2) + b u(t-1..) + c1 e(t-1) + c2 e(t-2), e = y - ŷ."""
    m = true_model("armax")
    d = simulate("armax", 400, seed=1)
    a, b, c = m.A, m.B, m.C
    yhat = np.zeros(d.N)
    e = np.zeros(d.N)
    for t in range(d.N):
        acc = 0.0
        for i in range(1, a.size):
            acc -= a[i] * (d.y[t - i] if t - i >= 0 else 0.0)
        for j in range(b.size):
            acc += b[j] * (d.u[t - j] if t - j >= 0 else 0.0)
        for i in range(1, c.size):
            acc += c[i] * (e[t - i] if t - i >= 0 else 0.0)
        yhat[t] = acc
        e[t] = d.y[t] - yhat[t]
    np.testing.assert_allclose(m.predict(d, 1), yhat, atol=1e-10)
    np.testing.assert_allclose(m.residuals(d), e, atol=1e-10)


def test_k_step_prediction_error_is_a_moving_average_of_the_innovations():
    """With the true model, y - ŷ(t|t-k) = Σ_{i<k} h_i e(t-i) exactly (zero initial state)."""
    m = true_model("bj")
    rng = np.random.default_rng(3)
    u = rng.standard_normal(2000)
    e = 0.5 * rng.standard_normal(2000)
    d = IOData(u, m.simulate(u, e), 1e-3)
    k = 4
    h = signal.lfilter(m.C, np.convolve(m.A, m.D), np.r_[1.0, np.zeros(k - 1)])
    expected = signal.lfilter(h, [1.0], e)
    np.testing.assert_allclose(d.y - m.predict(d, k), expected, atol=1e-9)
    np.testing.assert_allclose(m.predict(d, math.inf), m.simulate(u), atol=1e-12)


def test_estimated_initial_state_removes_the_start_transient():
    m = true_model("oe")
    u = np.random.default_rng(4).standard_normal(3000)
    y = m.simulate(u)
    d = IOData(u[1000:], y[1000:], 1e-3)  # starts mid-experiment, state far from zero
    assert np.max(np.abs(d.y - m.predict(d, math.inf, "zero"))) > 0.1
    np.testing.assert_allclose(m.predict(d, math.inf, "estimate"), d.y, atol=1e-8)


def test_control_conversion_agrees_with_freqresp_poles_and_zeros():
    m = true_model("lev")
    G, H = m.to_control()
    assert G.dt == m.Ts and H.dt == m.Ts
    w = np.logspace(0, np.log10(np.pi / m.Ts), 20)
    np.testing.assert_allclose(G(np.exp(1j * w * m.Ts)), m.freqresp(w), rtol=1e-9)
    np.testing.assert_allclose(np.sort_complex(ct.poles(G)), np.sort_complex(m.poles()), atol=1e-9)
    np.testing.assert_allclose(np.sort_complex(m.zeros()), [-0.5])
    assert m.dcgain() == pytest.approx(0.015 / np.polyval(m.F[::-1], 1.0))


def test_json_round_trip_is_exact():
    from maglev.estimation import bj

    m = bj(simulate("bj", 2000, seed=5), 2, 1, 1, 2, 1)
    back = PolyModel.from_json(json.dumps(m.to_dict()))
    for key in "ABCDF":
        np.testing.assert_array_equal(getattr(back, key), getattr(m, key))
    np.testing.assert_array_equal(back.covariance, m.covariance)
    assert back.report == m.report and back.orders == m.orders == (2, 1, 1, 2, 1)
    assert "bj[2 1 1 2 1]" in m.summary() and "±" in m.summary()


def test_bad_polynomials_and_horizons_are_refused():
    with pytest.raises(ValueError, match="A must be a monic"):
        PolyModel(A=[2, 1], B=[0, 1], C=[1], D=[1], F=[1], nk=1, Ts=1.0)
    with pytest.raises(ValueError, match="B must start with nk=2 zeros"):
        PolyModel(A=[1], B=[0, 1], C=[1], D=[1], F=[1], nk=2, Ts=1.0)
    m = true_model("arx")
    with pytest.raises(ValueError, match="horizon must be a positive integer or inf"):
        m.predict(simulate("arx", 100, 0), 0)


def _good() -> dict:
    return PolyModel(A=[1.0], B=[0, 0.3, 0.1], C=[1, 0.2], D=[1, -0.5], F=[1, -0.8], nk=1, Ts=0.01,
                     structure="bj", noise_variance=0.5, covariance=np.eye(5), name="g").to_dict()


@pytest.mark.parametrize("change, message", [
    ({"F": [1.0, float("nan")]}, "F has non-finite coefficients"),
    ({"B": [0.0, float("inf"), 0.1]}, "B has non-finite coefficients"),
    ({"C": None}, "C must be a list of numbers"),
    ({"D": "abc"}, "D must be a list of numbers"),
    ({"A": [1.0, 0.5]}, "a bj model has no A polynomial"),
    ({"structure": "arma"}, "unknown structure 'arma'"),
    ({"orders": [9, 1, 1, 1, 1]}, r"'orders' \[9, 1, 1, 1, 1\] do not match the polynomials \(bj\[2 1 1 1 1\]\)"),
    ({"covariance": np.eye(3).tolist()}, r"covariance must be 5 x 5 .*got shape \(3, 3\)"),
    ({"covariance": [[float("nan")] * 5] * 5}, "covariance has NaN"),
    ({"nk": 1.5}, "'nk' must be an integer"),
    ({"nk": True}, "'nk' must be an integer"),
    ({"Ts": True}, "'Ts' must be a number"),
    ({"Ts": -1.0}, "Ts must be a positive number"),
    ({"noise_variance": float("inf")}, "noise_variance must be finite"),
    ({"C": [1.0, 1.5]}, r"C has a root outside the unit circle \(\|root\| = 1.5\)"),
    ({"F": [1.0, -1.2]}, r"F has a root outside the unit circle"),
    ({"extra": 1}, r"unknown key\(s\) \['extra'\]"),
    ({"report": {"loss": 1.0}}, "'report' must be a dict with keys"),
])
def test_from_dict_refuses_what_cannot_be_a_model_naming_the_key(change, message):
    d = {**_good(), **change}
    with pytest.raises(ValueError, match=message):
        PolyModel.from_dict(d)
    missing = _good()
    del missing["B"]
    with pytest.raises(ValueError, match=r"missing key\(s\) \['B'\]"):
        PolyModel.from_dict(missing)


def test_models_and_records_compare_by_value():
    a, b = PolyModel.from_dict(_good()), PolyModel.from_dict(_good())
    assert a == b and not (a != b)
    assert a != PolyModel.from_dict({**_good(), "B": [0, 0.3, 0.2]})
    assert a != PolyModel.from_dict({**_good(), "covariance": None})
    data = simulate("arx", 100, 0)
    assert data == IOData(data.u.copy(), data.y.copy(), data.Ts, name=data.name)
    assert data != IOData(data.u, data.y + 1e-9, data.Ts, name=data.name)


def test_unstable_predictor_is_refused_not_nan():
    m = PolyModel(A=[1, -0.5], B=[0, 1.0], C=[1, 1.5], D=[1], F=[1], nk=1, Ts=1e-3, name="bad")
    data = simulate("arx", 500, 0)
    with pytest.raises(ValueError, match=r"bad: C\(q\)·F\(q\) has a root outside the unit circle \(\|root\| = 1.5\)"):
        m.predict(data, 1)
    unstable_g = PolyModel(A=[1, -1.2], B=[0, 1.0], C=[1], D=[1], F=[1], nk=1, Ts=1e-3)
    assert np.all(np.isfinite(unstable_g.predict(data, math.inf, "zero")))  # diverging but defined
    with pytest.raises(ValueError, match="simulation is unstable"):
        unstable_g.predict(data, math.inf, "estimate")


def test_near_pole_zero_cancellations_are_flagged():
    # G = (q^-2 - 0.5 q^-3) / (1 - 0.52 q^-1)(1 - 0.9 q^-1): zero 0.5 vs pole 0.52 cancel, 0.9 does not
    F = np.convolve([1, -0.52], [1, -0.9])
    m = PolyModel(A=[1.0], B=[0, 0, 1.0, -0.5], C=[1.0], D=[1.0], F=F, nk=2, Ts=0.01, structure="oe")
    [(which, pole, zero, dist)] = m.near_cancellations(tol=0.05)
    assert which == "G" and abs(pole - 0.52) < 1e-9 and abs(zero - 0.5) < 1e-9 and abs(dist - 0.02) < 1e-9
    assert m.near_cancellations(tol=0.01) == []
