"""Validation tools: FIT %, compare (k-step prediction, initial state) and resid (residual tests)."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from maglev.data import IOData
from maglev.estimation import arx
from maglev.model import PolyModel
from maglev.validation import compare, fit_percent, resid

A2 = np.array([1.0, -1.5, 0.7])
B2 = np.array([0.0, 1.0, 0.5])
C2 = np.array([1.0, -0.3, 0.2])
ONE = np.ones(1)


def _armax_model() -> PolyModel:
    return PolyModel(A=A2, B=B2, C=C2, D=ONE, F=ONE, nk=1, Ts=1.0, structure="armax")


def _loop_armax(u: np.ndarray, e: np.ndarray) -> np.ndarray:
    """y(t) = 1.5 y(t-1) - 0.7 y(t-2) + u(t-1) + 0.5 u(t-2) + e(t) - 0.3 e(t-1) + 0.2 e(t-2)."""
    y = np.zeros(u.size)
    for t in range(u.size):
        def at(x, k):
            return x[t - k] if t - k >= 0 else 0.0
        y[t] = (1.5 * at(y, 1) - 0.7 * at(y, 2) + at(u, 1) + 0.5 * at(u, 2)
                + e[t] - 0.3 * at(e, 1) + 0.2 * at(e, 2))
    return y


def _armax_data(seed: int, N: int = 2000, coloured: bool = True) -> IOData:
    rng = np.random.default_rng(seed)
    w = rng.standard_normal(N)
    u = w.copy()
    if coloured:  # u(t) = 0.7 u(t-1) + w(t)
        for t in range(1, N):
            u[t] = 0.7 * u[t - 1] + w[t]
    e = 0.5 * rng.standard_normal(N)
    return IOData(u, _loop_armax(u, e), 1.0, name=f"armax-{seed}")


# ---------------------------------------------------------------------------- fit_percent
def test_fit_percent_hand_computed():
    y = np.array([1.0, 2.0, 3.0, 4.0])  # ‖y − ȳ‖ = √5
    assert fit_percent(y, np.array([1.0, 2.0, 3.0, 5.0])) == pytest.approx(100 * (1 - 1 / math.sqrt(5)))
    assert fit_percent(y, y) == pytest.approx(100.0)
    assert fit_percent(y, np.full(4, 2.5)) == pytest.approx(0.0)
    assert fit_percent(y, -y) < 0


def test_fit_percent_rejects_bad_input():
    with pytest.raises(ValueError, match="shape"):
        fit_percent(np.ones(3), np.ones(4))
    with pytest.raises(ValueError, match="constant"):
        fit_percent(np.ones(3), np.zeros(3))


# ---------------------------------------------------------------------------- compare
def test_compare_k_step_arx_matches_independent_recursion():
    rng = np.random.default_rng(1)
    N, k = 300, 3
    u = rng.standard_normal(N)
    y = _loop_armax(u, 0.3 * rng.standard_normal(N))
    data = IOData(u, y, 1.0)
    model = PolyModel(A=A2, B=B2, C=ONE, D=ONE, F=ONE, nk=1, Ts=1.0, structure="arx")
    # independent k-step predictor: iterate the one-step ARX predictor from measured y up to t-k
    expected = np.zeros(N)
    for t in range(N):
        known = {s: (y[s] if s >= 0 else 0.0) for s in range(t - k - 2, t - k + 1)}
        for s in range(t - k + 1, t + 1):
            us = lambda j: u[s - j] if s - j >= 0 else 0.0  # noqa: E731
            known[s] = 1.5 * known[s - 1] - 0.7 * known[s - 2] + us(1) + 0.5 * us(2)
        expected[t] = known[t]
    fit, yhat = compare(data, model, horizon=k, initial_condition="zero")
    np.testing.assert_allclose(yhat, expected, atol=1e-10)
    assert fit == pytest.approx(fit_percent(y, expected))


def test_compare_one_step_armax_and_simulation_match_loops():
    data = _armax_data(2, N=400, coloured=False)
    model = _armax_model()
    # one step: e(t) = y(t) - ŷ(t) from C e = A y - B u, run as a loop
    e = np.zeros(data.N)
    y, u = data.y, data.u
    for t in range(data.N):
        def at(x, j):
            return x[t - j] if t - j >= 0 else 0.0
        e[t] = y[t] - 1.5 * at(y, 1) + 0.7 * at(y, 2) - at(u, 1) - 0.5 * at(u, 2) + 0.3 * at(e, 1) - 0.2 * at(e, 2)
    _, yhat = compare(data, model, 1, initial_condition="zero")
    np.testing.assert_allclose(yhat, y - e, atol=1e-9)
    _, ysim = compare(data, model, math.inf, initial_condition="zero")
    np.testing.assert_allclose(ysim, _loop_armax(u, np.zeros(data.N)), atol=1e-9)


def test_compare_estimate_recovers_nonzero_initial_state():
    rng = np.random.default_rng(3)
    N = 400
    u = rng.standard_normal(N)
    w = np.zeros(N + 2)
    w[0], w[1] = 6.0, 8.0  # w(-2), w(-1): the system starts far from rest
    u_ext = np.r_[0.0, 0.0, u]
    for i in range(2, N + 2):
        w[i] = 1.5 * w[i - 1] - 0.7 * w[i - 2] + u_ext[i - 1] + 0.5 * u_ext[i - 2]
    w = w[2:]
    y = w + 0.05 * rng.standard_normal(N)
    data = IOData(u, y, 1.0)
    model = PolyModel(A=ONE, B=B2, C=ONE, D=ONE, F=A2, nk=1, Ts=1.0, structure="oe")
    fit_zero, yhat_zero = compare(data, model, math.inf, initial_condition="zero")
    fit_est, yhat_est = compare(data, model, math.inf, initial_condition="estimate")
    assert fit_est > fit_zero + 5.0
    # the fitted start leaves only the measurement noise over the first samples
    assert np.sqrt(np.mean((y[:30] - yhat_est[:30]) ** 2)) < 0.1
    assert np.sqrt(np.mean((y[:30] - yhat_zero[:30]) ** 2)) > 1.0


def test_compare_rejects_mismatched_sampling_period():
    data = _armax_data(0, N=100)
    with pytest.raises(ValueError, match="Ts"):
        compare(IOData(data.u, data.y, 0.5), _armax_model())


# ---------------------------------------------------------------------------- resid
def test_resid_true_model_passes_at_about_the_nominal_rate():
    model = _armax_model()
    results = [resid(_armax_data(seed), model) for seed in range(20)]
    white = sum(r.white for r in results)
    independent = sum(r.independent for r in results)
    # nominal pass rate 99 %: three or more failures in 20 would have probability ~1e-3
    assert white >= 18
    assert independent >= 18
    # the per-lag bands are 99 % bands: about 1 % of lags outside on average
    assert np.mean([r.auto_outside for r in results]) < 0.05
    assert np.mean([r.cross_outside for r in results]) < 0.05


def test_resid_wrong_model_fails_both_tests():
    for seed in range(3):
        data = _armax_data(seed)
        result = resid(data, arx(data, 1, 1, 1))
        assert not result.white
        assert not result.independent
        assert result.whiteness_pvalue < 1e-6
        assert result.auto_outside > 0.1


def test_resid_bands_statistics_and_lags():
    data = _armax_data(5, N=1500)
    result = resid(data, _armax_model(), lags=10)
    N = data.N
    assert result.auto_band == pytest.approx(2.58 / math.sqrt(N))
    np.testing.assert_array_equal(result.auto_lags, np.arange(11))
    np.testing.assert_array_equal(result.cross_lags, np.arange(-10, 11))
    assert result.auto_corr[0] == pytest.approx(1.0)
    # independent correlation estimates (means removed, biased normalisation)
    e = result.e - result.e.mean()
    u = data.u - data.u.mean()
    full_e = np.correlate(e, e, "full")[N - 1 :] / (e @ e)
    full_u = np.correlate(u, u, "full")[N - 1 :] / (u @ u)
    np.testing.assert_allclose(result.auto_corr, full_e[:11], atol=1e-12)
    assert result.whiteness_stat == pytest.approx(N * np.sum(full_e[1:11] ** 2))
    assert result.whiteness_dof == 10 and result.independence_dof == 21
    P = 1.0 + 2.0 * np.sum(full_e[1:11] * full_u[1:11])
    assert result.cross_band == pytest.approx(2.58 * math.sqrt(P / N))
    assert 0 <= result.whiteness_pvalue <= 1 and 0 <= result.independence_pvalue <= 1


def test_resid_cross_correlation_sign_convention():
    """y(t) = u(t-3): a model that predicts nothing leaves e = y, so r_eu peaks at τ = +3."""
    rng = np.random.default_rng(7)
    u = rng.standard_normal(2000)
    y = np.r_[np.zeros(3), u[:-3]]
    silent = PolyModel(A=ONE, B=np.zeros(1), C=ONE, D=ONE, F=ONE, nk=0, Ts=1.0)
    result = resid(IOData(u, y, 1.0), silent, lags=5, initial_condition="zero")
    peak = result.cross_lags[np.argmax(np.abs(result.cross_corr))]
    assert peak == 3
    assert result.cross_corr[result.cross_lags == 3][0] == pytest.approx(1.0, abs=0.01)
    assert not result.independent


def test_resid_rejects_bad_arguments():
    data = _armax_data(0, N=200)
    with pytest.raises(ValueError, match="lags"):
        resid(data, _armax_model(), lags=0)
    with pytest.raises(ValueError, match="lags"):
        resid(data, _armax_model(), lags=150)
    with pytest.raises(ValueError, match="Ts"):
        resid(IOData(data.u, data.y, 0.1), _armax_model())
    with pytest.raises(TypeError, match="model"):
        resid(data, "not a model")


def test_resid_result_dict_round_trip():
    from maglev.validation import ResidResult

    r = resid(_armax_data(seed=3), _armax_model(), lags=10)
    back = ResidResult.from_dict(json.loads(json.dumps(r.to_dict())))
    for key in ("auto_lags", "auto_corr", "cross_lags", "cross_corr"):
        np.testing.assert_array_equal(getattr(back, key), getattr(r, key))
    assert back.whiteness_pvalue == r.whiteness_pvalue and back.independent == r.independent
    assert back.e.size == 0


def test_p_values_read_alike_everywhere_with_three_significant_digits():
    from maglev.validation import format_p

    assert [format_p(p) for p in (0.993, 0.0123, 1e-6, 5.8e-185, 1.0)] == ["0.993", "0.0123", "1e-06", "5.8e-185", "1"]
