"""Estimators on known true systems: consistency, covariance, validation FIT, errors."""

from __future__ import annotations

import numpy as np
import pytest

from maglev import estimation as E
from maglev.data import IOData
from maglev.estimation.prediction_error import evaluate
from maglev.estimation.starts import nested_theta
from maglev.structures import PolySpec
from maglev.validation import fit_percent

from ..systems import TRUE, simulate, true_model

STRUCTURE = {"arx": "arx", "armax": "armax", "oe": "oe", "bj": "bj", "pem": "pem", "lev": "oe"}


def fitted(name: str, data: IOData, **kw):
    return E.estimate(data, STRUCTURE[name], TRUE[name]["orders"], **kw)


def param_error(name: str, model) -> float:
    """Largest absolute parameter error against the truth."""
    return float(np.max(np.abs(model.parameters - true_model(name).parameters)))


@pytest.mark.parametrize("name", list(TRUE))
def test_converges_to_truth_as_N_grows(name):
    errors = {}
    truth = true_model(name).parameters
    for N, seeds in ((2_000, 10), (100_000, 3)):
        deviations = [fitted(name, simulate(name, N, seed)).parameters - truth for seed in range(seeds)]
        errors[N] = float(np.sqrt(np.mean(np.square(deviations))))
    # root-mean-square error should shrink like 1/sqrt(N): a factor 7 here; require 3
    assert errors[100_000] < errors[2_000] / 3, errors
    # and the large-sample estimate sits within 4 reported standard errors of the truth
    m = fitted(name, simulate(name, 100_000, 7))
    z = (m.parameters - true_model(name).parameters) / m.std_errors
    assert np.all(np.abs(z) < 4.5), dict(zip(m.parameter_names, z.round(2)))


@pytest.mark.parametrize("name", list(TRUE))
def test_monte_carlo_spread_matches_reported_covariance(name):
    runs = 60
    estimates, reported = [], []
    for seed in range(runs):
        m = fitted(name, simulate(name, 2_000, 100 + seed))
        estimates.append(m.parameters)
        reported.append(m.std_errors)
    empirical = np.std(estimates, axis=0, ddof=1)
    predicted = np.mean(reported, axis=0)
    ratio = empirical / predicted
    # 60 runs give the std to about ±10 % (1 sigma); allow ±35 %
    assert np.all((ratio > 0.65) & (ratio < 1.35)), dict(zip(m.parameter_names, ratio.round(2)))


@pytest.mark.parametrize("name", list(TRUE))
@pytest.mark.parametrize("N", [2_000, 20_000])
def test_validation_fit_close_to_true_model(name, N):
    est = simulate(name, N, seed=1)
    val = simulate(name, 20_000, seed=2)
    m = fitted(name, est)
    truth = true_model(name)
    fit_model = fit_percent(val.y, m.predict(val, 1))
    fit_truth = fit_percent(val.y, truth.predict(val, 1))
    assert fit_model > fit_truth - 0.2, (fit_model, fit_truth)


def test_lightly_damped_plant_poles_found_from_binary_input():
    """The levitator-like plant: all four poles within 1e-3 of the truth, none unstable."""
    m = fitted("lev", simulate("lev", 20_000, seed=3, binary=True))
    true_poles = np.sort_complex(true_model("lev").poles())
    got = np.sort_complex(m.poles())
    assert np.max(np.abs(got - true_poles)) < 1e-3
    assert np.all(np.abs(got) < 1)


def test_information_criteria_follow_matlab_formulas():
    m = fitted("armax", simulate("armax", 3_000, seed=4))
    r = m.report
    N, d, V = r.n_samples, r.n_params + r.n_initial, r.loss
    e = m.residuals(simulate("armax", 3_000, seed=4), "estimate" if r.n_initial else "zero")
    assert V == pytest.approx(np.mean(e**2), rel=1e-6)
    assert r.fpe == pytest.approx(V * (1 + d / N) / (1 - d / N))
    assert r.aic == pytest.approx(N * np.log(V) + 2 * d + N * (np.log(2 * np.pi) + 1))
    assert r.aicc == pytest.approx(r.aic + 2 * d * (d + 1) / (N - d - 1))
    assert r.bic == pytest.approx(N * np.log(V) + d * np.log(N) + N * (np.log(2 * np.pi) + 1))
    assert r.naic == pytest.approx(np.log(V) + 2 * d / N)
    assert m.noise_variance == pytest.approx(N * V / (N - d))


def test_arx_matches_explicit_least_squares_with_matlab_rows():
    """Rows t = na+1..N, pre-sample inputs zero, solved by the normal equations in a loop."""
    data = simulate("armax", 500, seed=5)
    na, nb, nk = 3, 2, 3
    rows, targets = [], []
    for t in range(na, data.N):
        phi = [-data.y[t - i] for i in range(1, na + 1)]
        phi += [data.u[t - nk - j] if t - nk - j >= 0 else 0.0 for j in range(nb)]
        rows.append(phi)
        targets.append(data.y[t])
    P, Y = np.array(rows), np.array(targets)
    theta = np.linalg.solve(P.T @ P, P.T @ Y)
    m = E.arx(data, na, nb, nk)
    np.testing.assert_allclose(m.parameters, theta, rtol=1e-9, atol=1e-12)
    # MATLAB's report: all N samples, the first na residuals zero, the na initial outputs in d
    assert (m.report.n_samples, m.report.n_initial) == (data.N, na)
    assert m.report.loss == pytest.approx(np.sum((Y - P @ theta) ** 2) / data.N, rel=1e-9)
    assert m.B[:nk].tolist() == [0.0] * nk


@pytest.mark.parametrize("mode", ["zero", "estimate", "backcast", "auto"])
def test_initial_condition_modes_all_recover_the_truth(mode):
    data = simulate("bj", 5_000, seed=6)
    m = fitted("bj", data, initial_condition=mode)
    assert param_error("bj", m) < 0.1
    assert m.report.initial_condition.startswith(mode)
    if mode in ("estimate", "backcast"):  # MATLAB counts backcast states in d too
        assert m.report.n_initial > 0
    if mode == "zero":
        assert m.report.n_initial == 0


def test_estimated_initial_state_beats_zero_on_a_record_starting_off_rest():
    """A record cut from the middle of an experiment has a nonzero initial state."""
    full = simulate("oe", 6_000, seed=8)
    data = full.segment(1_000)
    zero = fitted("oe", data, initial_condition="zero")
    est = fitted("oe", data, initial_condition="estimate")
    assert est.report.loss < zero.report.loss


@pytest.mark.parametrize(
    "call, message",
    [
        (lambda d: E.arx(d, -1, 2, 1), "na must be >= 0"),
        (lambda d: E.arx(d, 2, 2, -1), "nk must be >= 0"),
        (lambda d: E.oe(d, 0, 2, 1), "nb must be >= 1"),
        (lambda d: E.arx(d, 2.5, 2, 1), "must be an integer"),
        (lambda d: E.armax(d, 40, 40, 40, 1), "orders too large for the data"),
        (lambda d: E.bj(d, 2, 1, 1, 2, 1, initial_condition="guess"), "initial_condition must be one of"),
        (lambda d: E.estimate(d, "bj", [2, 2, 1]), "bj takes orders [nb nc nd nf nk]"),
        (lambda d: E.estimate(d, "narx", [2, 2, 1]), "unknown structure"),
    ],
)
def test_bad_orders_give_clear_errors(call, message):
    data = simulate("arx", 200, seed=0)
    with pytest.raises(ValueError, match=message.replace("[", r"\[").replace("]", r"\]")):
        call(data)


def test_constant_input_is_refused_as_unexciting():
    data = IOData(np.full(1000, 3.0), np.random.default_rng(0).standard_normal(1000), 1e-3, name="flat")
    with pytest.raises(ValueError, match="flat: input u is constant"):
        E.armax(data, 2, 2, 2, 1)


def test_input_not_persistently_exciting_is_refused():
    u = np.tile([1.0, -1.0], 1000)  # a pure alternating signal excites order 1 only... and 2 at most
    y = np.convolve(u, [0, 1, 0.5])[: u.size] + 0.01 * np.random.default_rng(0).standard_normal(u.size)
    with pytest.raises(ValueError, match="not persistently exciting of order 4"):
        E.oe(IOData(u, y, 1.0, name="alt"), 2, 2, 1)


def test_warm_start_from_the_nested_lower_model_never_ends_above_it():
    """OE [2 1 2] padded into OE [2 2 2] starts at the lower loss (zero initial conditions)."""
    data = simulate("oe", 3_000, seed=11)
    low = E.oe(data, 2, 1, 2, initial_condition="zero")
    spec = PolySpec("oe", nb=2, nf=2, nk=2)
    padded = nested_theta(spec, low)
    np.testing.assert_array_equal(padded, np.r_[low.parameters, 0.0])  # only the new f2 is zero
    assert evaluate(spec, padded, data.y, data.u, False, False).loss == pytest.approx(low.report.loss, rel=1e-12)
    high = E.oe(data, 2, 2, 2, initial_condition="zero", init=low)
    assert high.report.loss <= low.report.loss


def test_warm_start_from_an_arx_model_folds_its_A_into_F_and_D():
    """ARX A y = B u + e is BJ with F = D = A and C = 1: as a warm start it loses nothing."""
    data = simulate("bj", 3_000, seed=12)
    model = E.arx(data, 2, 2, 1, initial_condition="zero")
    spec = PolySpec("bj", nb=2, nc=1, nd=2, nf=2, nk=1)
    _, B, C, D, F = spec.polys(nested_theta(spec, model))
    np.testing.assert_array_equal(F, model.A)
    np.testing.assert_array_equal(D, model.A)
    np.testing.assert_array_equal(B, model.B)
    np.testing.assert_array_equal(C, [1.0, 0.0])
    start_loss = evaluate(spec, nested_theta(spec, model), data.y, data.u, False, False).loss
    assert start_loss == pytest.approx(np.mean(model.residuals(data, "zero") ** 2), rel=1e-9)
    assert E.bj(data, 2, 1, 2, 2, 1, initial_condition="zero", init=model).report.loss <= start_loss


@pytest.mark.parametrize("call, message", [
    (lambda d, m: E.oe(d, 2, 1, 2, init=m), "init oe\\[2 2 2\\].* has F of degree 2; oe\\[2 1 2\\] allows 1"),
    (lambda d, m: E.oe(d, 2, 2, 1, init=m), "B coefficients at delays 2…3, outside oe\\[2 2 1\\]'s 1…2"),
    (lambda d, m: E.oe(d, 2, 2, 2, init=[0.1, 0.2]), "init must be a PolyModel or a vector of its 4 parameters"),
    (lambda d, m: E.estimate(d, "arx", [2, 2, 2], init=m), "arx is solved exactly"),
])
def test_warm_starts_that_do_not_fit_are_refused(call, message):
    data = simulate("oe", 1_000, seed=13)
    model = E.oe(data, 2, 2, 2)
    with pytest.raises(ValueError, match=message):
        call(data, model)
