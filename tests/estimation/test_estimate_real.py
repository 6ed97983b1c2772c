"""Estimators on the real EL2820 2022 levitator records (skipped without ../shared/refdata)."""

from __future__ import annotations

import numpy as np
import pytest

from maglev import estimation as E
from maglev.data import IOData
from maglev.model import PolyModel
from maglev.estimation.prediction_error import minimise
from maglev.structures import PolySpec
from maglev.validation import compare

RECORDS = {"binary_signal_2": ("u", "y"), "white_noise_2": ("u2", "y2")}


def halves(refdata, name):
    u, y = RECORDS[name]
    data = IOData.from_mat(refdata / "el2820_maglev_2022" / f"{name}.mat", u=u, y=y).detrend()
    return data.split(0.5)


def test_arx_4_1_8_is_matlabs_least_squares(refdata):
    """MATLAB arx default: rows t = na+1..N, pre-sample inputs zero — rebuilt here by hand."""
    est, _ = halves(refdata, "binary_signal_2")
    na, nb, nk = 4, 1, 8
    y, u = est.y, est.u
    rows = np.array([[-y[t - i] for i in range(1, na + 1)] + [u[t - nk] if t >= nk else 0.0]
                     for t in range(na, est.N)])
    theta, *_ = np.linalg.lstsq(rows, y[na:], rcond=None)
    m = E.arx(est, na, nb, nk)
    np.testing.assert_allclose(m.parameters, theta, rtol=1e-8)
    assert m.A.size == 5 and m.B.size == 9 and np.all(m.B[:8] == 0)


@pytest.mark.parametrize("record", list(RECORDS))
@pytest.mark.parametrize("structure, orders", [
    ("armax", (2, 2, 2, 8)), ("armax", (3, 3, 3, 8)), ("armax", (5, 5, 5, 8)),
    ("bj", (2, 2, 2, 2, 8)), ("bj", (3, 3, 3, 3, 8)), ("bj", (5, 5, 5, 5, 8)),
])
def test_armax_and_bj_converge_with_high_stable_validation_fit(refdata, record, structure, orders):
    est, val = halves(refdata, record)
    reference, _ = compare(val, E.arx(est, 4, 4, 8))
    m = E.estimate(est, structure, orders)
    fit, _ = compare(val, m)
    assert m.report.termination != "maximum number of iterations reached"
    assert np.all(np.abs(m.poles()) < 1) and np.all(np.abs(m.noise_zeros()) < 1)
    # at least as good as a plain ARX of similar size, and high in absolute terms
    assert fit > reference - 1.0, (fit, reference)
    assert fit > {"binary_signal_2": 97.0, "white_noise_2": 70.0}[record]
    # Restarts from perturbed parameters: on real (nonlinear) data a low-order BJ has several
    # comparable minima (resonances at slightly different frequencies), so we require that
    # no restart beats our minimum by more than 2 % and that validation FIT is stable.
    spec = PolySpec.from_orders(structure, orders)
    rng = np.random.default_rng(0)
    for _ in range(3):
        theta0 = m.parameters * (1 + 0.02 * rng.standard_normal(m.n_params))
        again = minimise(spec, theta0, est.y, est.u, fit_states=m.report.n_initial > 0)
        A, B, C, D, F = spec.polys(again.evaluation.theta)
        refit = PolyModel(A=A, B=B, C=C, D=D, F=F, nk=m.nk, Ts=m.Ts, structure=structure)
        assert again.evaluation.loss > m.report.loss * (1 - 0.02)
        assert compare(val, refit)[0] == pytest.approx(fit, abs=0.5)


@pytest.mark.parametrize("name", ["binary_signal_9", "binary_signal_10"])
def test_constant_input_records_are_refused(refdata, name):
    data = IOData.from_mat(refdata / "el2820_maglev_2022" / f"{name}.mat").detrend()
    with pytest.raises(ValueError, match=f"{name}: input u is constant"):
        E.armax(data, 2, 2, 2, 8)
    with pytest.raises(ValueError, match="input u is constant"):
        E.arx(data, 4, 1, 8)
