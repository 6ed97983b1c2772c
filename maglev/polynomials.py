"""Polynomials in the delay operator q⁻¹ and the filtering built on them.

Every model in maglev is a ratio of polynomials in q⁻¹ stored as coefficient arrays
(``[1, a1, a2, ...]`` for monic ones).  This module holds the few operations the
estimators and predictors need: products, stability projection by root reflection,
IIR filtering with optional initial states, and the free responses of a filter
(used to fit initial states by least squares).
"""

from __future__ import annotations

import numpy as np
from scipy.signal import lfilter


def polymul(*polys: np.ndarray) -> np.ndarray:
    """Product of polynomials in q⁻¹ (coefficient convolution)."""
    out = np.array([1.0])
    for p in polys:
        out = np.convolve(out, np.asarray(p, dtype=float))
    return out


def n_states(num: np.ndarray, den: np.ndarray) -> int:
    """Number of direct-form-II-transposed states of ``num/den``."""
    return max(len(num), len(den)) - 1


def filt(num: np.ndarray, den: np.ndarray, x: np.ndarray, zi: np.ndarray | None = None) -> np.ndarray:
    """Filter ``x`` (along its last axis) through ``num(q⁻¹)/den(q⁻¹)``; ``zi`` are the filter's initial states."""
    n = n_states(num, den)
    if n == 0:
        return (num[0] / den[0]) * x
    if zi is None and len(den) == 1 and np.ndim(x) == 1:  # FIR: a direct convolution is several times faster
        return np.convolve(x, np.asarray(num, dtype=float) / den[0])[: len(x)]
    num, den = _pad(num, n + 1), _pad(den, n + 1)
    if zi is None:
        return lfilter(num, den, x)
    y, _ = lfilter(num, den, x, zi=zi)
    return y


def free_responses(num: np.ndarray, den: np.ndarray, n: int) -> np.ndarray:
    """Columns: the first ``n`` output samples of ``num/den`` started from each unit state.

    The output of the filter from initial state ``zi`` is ``filt(x) + free @ zi``; a
    least-squares fit of ``zi`` therefore only needs these columns.  In direct form II
    transposed the zero-input response from ``zi`` is the impulse response of
    ``(zi[0] + zi[1] q⁻¹ + …)/den``, so column i is that of ``1/den`` delayed by i.
    """
    k = n_states(num, den)
    if k == 0:
        return np.zeros((n, 0))
    impulse = np.zeros(n)
    impulse[0] = 1.0
    h = lfilter([1.0], np.asarray(den, dtype=float), impulse)
    cols = np.zeros((n, k))
    for i in range(min(k, n)):
        cols[i:, i] = h[: n - i]
    return cols


def transient_length(den: np.ndarray, n_max: int, tol: float = 1e-10) -> int:
    """Samples after which a free response of ``1/den`` has decayed below ``tol`` (at most ``n_max``)."""
    roots = np.roots(den) if len(den) > 1 else np.array([])
    radius = float(np.max(np.abs(roots))) if roots.size else 0.0
    order = max(len(den) - 1, 1)
    if radius >= 1.0:
        return n_max
    if radius <= 0.0:
        return min(n_max, order + 1)
    # r^n * n^order bound: be generous with repeated/clustered roots.
    n = int(np.ceil(np.log(tol) / np.log(radius))) * 2 + 10 * order
    return int(min(n_max, max(n, order + 1)))


def free_response_window(n_delays: int, den: np.ndarray, n_max: int, tol: float = 1e-10) -> int:
    """Samples that hold the free responses z(q⁻¹)/den · δ with deg z < ``n_delays`` (at most ``n_max``).

    A free response is 1/den's impulse response delayed by up to ``n_delays`` − 1 samples,
    so the window is those delays plus the decay of 1/den.  For an FIR filter (den = 1)
    that is every state; sizing by the denominator alone would miss the numerator's.
    """
    return int(min(n_max, n_delays + transient_length(den, n_max, tol)))


def is_stable(p: np.ndarray, margin: float = 0.0) -> bool:
    """True if all roots of ``p(q⁻¹)`` (as a polynomial in z) lie strictly inside the unit circle."""
    if len(p) <= 1:
        return True
    return bool(np.all(np.abs(np.roots(p)) < 1.0 - margin))


MAX_RADIUS = 1.0 - 1e-5  # roots kept this far inside the unit circle (rounding-safe)


def stabilize(p: np.ndarray) -> np.ndarray:
    """Reflect roots outside the unit circle to 1/conj(r) and pull any left on or near
    the circle in to ``MAX_RADIUS`` (monic kept).

    Reflection keeps the magnitude response's shape (up to a constant) while making
    the polynomial minimum-phase, as MATLAB does for C, D and F during estimation.
    The margin matters for noise models of band-limited (e.g. decimated) data, whose
    best C has a zero at z = -1: a root left at 1 - 1e-6 comes back from ``np.roots``
    of the rounded coefficients at or beyond 1.
    """
    p = np.asarray(p, dtype=float)
    if len(p) <= 1 or roots_within(p, MAX_RADIUS):
        return p.copy()
    roots = np.roots(p)
    outside = np.abs(roots) > 1.0
    roots[outside] = 1.0 / np.conj(roots[outside])
    radius = np.abs(roots)
    near = radius > MAX_RADIUS
    roots[near] *= MAX_RADIUS / radius[near]
    q = np.real(np.poly(roots))
    return q * (p[0] / q[0])


def roots_within(p: np.ndarray, radius: float) -> bool:
    """All roots of monic ``p`` within ``radius``: Jury's conditions up to degree 2, else the
    Schur–Cohn step-down recursion (reflection coefficients of magnitude below 1), which
    needs no eigenvalues."""
    if p[0] != 1.0:
        return bool(np.all(np.abs(np.roots(p)) <= radius))
    if len(p) == 2:
        return abs(p[1]) <= radius
    if len(p) == 3:
        a1, a2 = p[1] / radius, p[2] / radius**2  # roots of z² + a1 z + a2 scaled by 1/radius
        return abs(a2) <= 1.0 and abs(a1) <= 1.0 + a2
    a = np.asarray(p, dtype=float) / radius ** np.arange(len(p))
    for m in range(len(a) - 1, 0, -1):
        k = a[m]
        if abs(k) >= 1.0:
            return False
        a = (a[:m] - k * a[m:0:-1]) / (1.0 - k * k)
    return True


def _pad(p: np.ndarray, n: int) -> np.ndarray:
    p = np.asarray(p, dtype=float)
    if len(p) >= n:
        return p
    return np.concatenate([p, np.zeros(n - len(p))])
