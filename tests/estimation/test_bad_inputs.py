"""Library inputs that cannot give a meaningful model are refused with a message naming the argument."""

from __future__ import annotations

import re

import numpy as np
import pytest
from scipy.signal import lfilter

from maglev import IOData
from maglev.estimation import estimate


@pytest.fixture(scope="module")
def data() -> IOData:
    """A first-order output-error system, y = 0.5 q⁻¹/(1 − 0.8 q⁻¹) u + e."""
    rng = np.random.default_rng(0)
    u = rng.standard_normal(1000)
    return IOData(u, lfilter([0, 0.5], [1, -0.8], u) + 0.05 * rng.standard_normal(1000), 1.0)


@pytest.mark.parametrize("options, needle", [
    ({"max_iterations": 2.5}, "max_iterations must be an integer >= 0, got 2.5"),
    ({"max_iterations": -3}, "max_iterations must be an integer >= 0, got -3"),
    ({"max_iterations": True}, "max_iterations must be an integer >= 0, got True"),
    ({"tolerance": -1.0}, "tolerance must be None or a finite number > 0, got -1.0"),
    ({"tolerance": "1e-6"}, "tolerance must be None or a finite number > 0"),
    ({"tolerance": float("nan")}, "tolerance must be None or a finite number > 0"),
])
def test_iteration_options_are_checked(data, options, needle):
    with pytest.raises(ValueError, match=re.escape(needle)):
        estimate(data, "oe", [1, 1, 1], **options)


def test_zero_iterations_return_the_best_starting_point(data):
    """max_iterations=0 is allowed: no iteration, the starting point as it is (MATLAB's MaxIterations = 0)."""
    start = estimate(data, "oe", [1, 1, 1], max_iterations=0)
    fitted = estimate(data, "oe", [1, 1, 1])
    assert start.report.iterations == 0 and start.report.loss >= fitted.report.loss


@pytest.mark.parametrize("structure, orders", [("oe", [1, 1, 1]), ("arx", [1, 1, 1])])
@pytest.mark.parametrize("scale", [1e200, 1e-200, 1e120])
def test_data_whose_squares_overflow_is_refused_not_converged(data, structure, orders, scale):
    """Scaled by 1e200 the loss was inf and PEM reported convergence; 1e-200 read as 'not exciting'."""
    scaled = IOData(data.u * scale, data.y * scale, data.Ts, name="scaled")
    with pytest.raises(ValueError, match=r"scaled: input u has RMS .*e[+-]\d+; .* rescale it"):
        estimate(scaled, structure, orders)


def test_a_large_but_safe_scale_gives_the_same_model(data):
    """Scale invariance inside the accepted range: ×1e50 gives the same coefficients."""
    scaled = IOData(data.u * 1e50, data.y * 1e50, data.Ts)
    a, b = estimate(data, "oe", [1, 1, 1]), estimate(scaled, "oe", [1, 1, 1])
    assert np.allclose(a.F, b.F, rtol=1e-6) and np.allclose(a.B, b.B, rtol=1e-6)
