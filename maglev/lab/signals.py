"""Input signals of the levitator lab: staircase, step, uniform white noise, random binary.

The lab (EL2820 Lab 3, §3.1 and §3.3) excites the levitator with a staircase to find
the working region, a step to find the rise time, and two kinds of random signals for
identification.  The random binary signal is generated exactly as the lab text
defines it (w_t = -1 with probability alpha, s_t = s_{t-1} w_t, s_0 = 1,
u_t = A s_t + B) so that its spectrum is the lab's formula (:func:`rbs_spectrum`).
All generators are pure functions of their arguments (random ones of ``seed`` through
``numpy.random.default_rng``) and return 1-D float arrays of samples.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

__all__ = ["staircase", "step", "uniform_noise", "random_binary", "rbs_spectrum"]


def _positive_int(value: int, name: str) -> int:
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, (int, np.integer)) or value < 1:
        raise ValueError(f"{name} must be a positive integer number of samples, got {value!r}")
    return int(value)


def _check_range(low: float, high: float) -> tuple[float, float]:
    low, high = float(low), float(high)
    if not (np.isfinite(low) and np.isfinite(high)) or low > high:
        raise ValueError(f"low/high must be finite with low <= high, got low={low!r}, high={high!r}")
    return low, high


def staircase(levels: Sequence[float] | np.ndarray, dwell: int) -> np.ndarray:
    """Hold each of ``levels`` for ``dwell`` samples, in order (the lab's stair signal).

    ``staircase(np.arange(0, 10.5, 0.5), 500)`` is the lab's 21-level, 10500-sample stair.
    """
    lv = np.asarray(levels, dtype=float).reshape(-1)
    if lv.size == 0 or not np.all(np.isfinite(lv)):
        raise ValueError(f"levels must be a non-empty sequence of finite numbers, got {levels!r}")
    return np.repeat(lv, _positive_int(dwell, "dwell"))


def step(n: int, before: float, after: float, at: int) -> np.ndarray:
    """``n`` samples equal to ``before`` up to index ``at`` (exclusive), ``after`` from then on."""
    n = _positive_int(n, "n")
    if isinstance(at, (bool, np.bool_)) or not isinstance(at, (int, np.integer)) or not 0 <= at <= n:
        raise ValueError(f"at must be an integer sample index in [0, n={n}], got {at!r}")
    u = np.full(n, float(before))
    u[int(at):] = float(after)
    return u


def uniform_noise(n: int, low: float, high: float, seed: int | None = None) -> np.ndarray:
    """``n`` independent samples uniform on [low, high) (MATLAB's ``low + (high-low)*rand(n,1)``)."""
    n = _positive_int(n, "n")
    low, high = _check_range(low, high)
    return np.random.default_rng(seed).uniform(low, high, n)


def random_binary(
    n: int, alpha: float, low: float, high: float, seed: int | None = None
) -> np.ndarray:
    """The lab's random binary signal: switches level with probability ``alpha`` at each sample.

    w_t = -1 with probability alpha (else +1), s_t = s_{t-1} w_t with s_0 = 1, and
    u_t = A s_t + B with A = (high - low)/2, B = (high + low)/2, so s = +1 maps to
    ``high`` and s = -1 to ``low``.  The returned samples are u_1 .. u_n (the first one
    has already had a chance to switch away from s_0 = 1).
    """
    n = _positive_int(n, "n")
    alpha = float(alpha)
    if not 0.0 <= alpha <= 1.0:
        raise ValueError(f"alpha must be a probability in [0, 1], got {alpha!r}")
    low, high = _check_range(low, high)
    w = np.where(np.random.default_rng(seed).random(n) < alpha, -1.0, 1.0)
    s = np.cumprod(w)  # s_t = s_{t-1} w_t with s_0 = 1
    return (high - low) / 2.0 * s + (high + low) / 2.0


def rbs_spectrum(alpha: float, w: float | np.ndarray) -> np.ndarray:
    """Spectrum of the ±1 random binary process: 4α(1-α) / |1 - (1-2α) e^{jω}|² (lab eq. 3).

    ``w`` is the normalised angular frequency in rad/sample.  For α = 0 (constant) and
    α = 1 (alternating) the process has line spectra (all power at ω = 0 resp. ω = π),
    which the formula shows as zero everywhere except a 0/0 at that frequency; those
    points are returned as ``inf``.
    """
    alpha = float(alpha)
    if not 0.0 <= alpha <= 1.0:
        raise ValueError(f"alpha must be a probability in [0, 1], got {alpha!r}")
    w = np.asarray(w, dtype=float)
    den = np.abs(1.0 - (1.0 - 2.0 * alpha) * np.exp(1j * w)) ** 2
    num = 4.0 * alpha * (1.0 - alpha)
    with np.errstate(divide="ignore", invalid="ignore"):
        out = np.where(den > 0, num / np.where(den > 0, den, 1.0), np.inf)
    return out
