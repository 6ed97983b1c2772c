"""The delay rule on a system with a known delay, and its decision's sentences."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.signal import lfilter

from maglev.data import IOData
from maglev.lab.delay import dead_time, delay_decision, residual_rejects


def _system(nk: int, n: int = 6000, seed: int = 0) -> tuple[IOData, IOData]:
    """y = q^-nk (0.5 + 0.3 q^-1) / (1 - 1.2 q^-1 + 0.5 q^-2) u + small white noise: a true delay of nk samples
    and a smooth response whose visible dead time is later."""
    rng = np.random.default_rng(seed)
    u = rng.standard_normal(n)
    b = np.r_[np.zeros(nk), 0.5, 0.3]
    y = lfilter(b, [1.0, -1.2, 0.5], u) + 0.05 * rng.standard_normal(n)
    return IOData(u[: n // 2], y[: n // 2], 1.0), IOData(u[n // 2:], y[n // 2:], 1.0)


@pytest.mark.parametrize("true_nk", [1, 3])
def test_the_rule_finds_a_known_delay_under_loose_upper_bounds(true_nk):
    est, val = _system(true_nk)
    d = delay_decision([("sys", est, val)], step_dead_samples=6.4, delayest_nk={"sys": 5}, order=4)
    assert d.choice == {"nk": true_nk} and not d.forced
    assert residual_rejects(est, val, true_nk + 1, 4) > 1 >= residual_rejects(est, val, true_nk, 4)
    assert d.reasons[-1].startswith(f"nk = {true_nk}: the largest delay")


def test_the_bounds_cap_the_delay_and_a_config_that_differs_is_forced():
    est, val = _system(3)
    capped = delay_decision([("sys", est, val)], step_dead_samples=2.7, delayest_nk={"sys": 5}, order=4)
    assert capped.choice == {"nk": 2} and "upper bound is nk = 2" in capped.reasons[1]
    forced = delay_decision([("sys", est, val)], 6.4, {"sys": 5}, order=4, configured=5)
    assert forced.forced and forced.choice == {"nk": 5, "rule": 3}
    assert forced.cautions == ["The sweep's config sets structure.nk = 5, not the rule's nk = 3."]
    agrees = delay_decision([("sys", est, val)], 6.4, {"sys": 5}, order=4, configured=3)
    assert not agrees.forced and agrees.cautions == []


def test_dead_time_is_where_the_response_first_reaches_five_percent():
    assert dead_time(np.r_[np.zeros(4), 0.01, 0.049, 0.05, 0.5, 1.0]) == 6
    with pytest.raises(ValueError, match="never reaches 5%"):
        dead_time(np.zeros(5))
