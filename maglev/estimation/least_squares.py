"""Linear least squares on lagged signals: ARX's regression and the regressions behind starting points.

``regression``/``solve_regression`` build and solve ARX's regression exactly (the rows
MATLAB's ``arx`` uses; QR of the regressor matrix).  ``lagged_lstsq``/``lagged_iv``
solve the large regressions behind the prediction-error estimators' starting points
through their lag products, without forming the regressor matrix.

The starting points of the prediction-error estimators are regressions whose columns
are delayed copies of two or three signals (y, u, a residual), e.g. the long ARX
model behind an ARMAX start: 72 columns.  Forming that N × p matrix and factoring it
costs O(N p²) time and N p memory (1.1 GB at N = 10⁶).  Its Gram matrix needs far
less: entry (i, j) = Σₜ x(t − a) z(t − b) depends on the lag difference d = b − a up
to the few products at the ends of the row range, so the whole matrix is one
cross-correlation per signal pair plus small corrections — O(N · lags) time and no
extra memory.  The normal equations are then solved with a
factorisation after scaling to unit diagonal (falling back to an SVD when they are
singular); the squared condition number is harmless for a starting point.
"""

from __future__ import annotations

import numpy as np
from scipy.linalg import solve_triangular

from ..structures import PolySpec

Group = tuple[np.ndarray, np.ndarray, float]  # (signal x, lags, sign): columns sign · x(t − lag)


def lagged_lstsq(target: np.ndarray, groups: list[Group], first: int) -> np.ndarray:
    """θ minimising Σ_{t ≥ first} (target(t) − Σ_k θ_k column_k(t))², columns from ``groups`` in order.

    ``first`` must be at least the largest lag, so every row is fully measured.
    """
    groups = _nonempty(groups)
    if not groups:
        return np.zeros(0)
    gram = lagged_gram([*groups, (target, np.zeros(1, dtype=int), 1.0)], first)
    return _solve_normal(gram[:-1, :-1], gram[:-1, -1])


def lagged_iv(target: np.ndarray, regressors: list[Group], instruments: list[Group], first: int) -> np.ndarray:
    """Instrumental-variable estimate: θ solving Zᵀ(target − Φ θ) = 0 over rows t ≥ first,
    Φ from ``regressors`` and Z from ``instruments`` (as many columns as Φ)."""
    regressors = _nonempty(regressors)
    instruments = _nonempty(instruments)
    if not regressors:
        return np.zeros(0)
    p = sum(len(g[1]) for g in regressors)
    gram = lagged_gram([*instruments, *regressors, (target, np.zeros(1, dtype=int), 1.0)], first)
    cross, rhs = gram[:p, p:-1], gram[:p, -1]
    scale = np.sqrt(np.maximum(np.abs(np.diag(cross)), 1e-300))
    theta, *_ = np.linalg.lstsq(cross / scale[None, :], rhs, rcond=1e-12)
    return theta / scale


def _nonempty(groups: list[Group]) -> list[Group]:
    return [(x, np.asarray(lags, dtype=int), float(sign)) for x, lags, sign in groups if len(lags)]


def lagged_gram(groups: list[Group], first: int) -> np.ndarray:
    """Gram matrix Φᵀ Φ over rows t = first … N−1 of the columns of ``groups``, in order.

    Over all rows t = 0 … N−1+L (L the largest lag), with the signals zero outside the
    record, entry (i, j) is the cross-correlation R(b − a) = Σ_τ x(τ) z(τ − b + a): one
    ``np.correlate`` per pair of distinct signals covers every lag difference.  The
    rows before ``first`` and after N−1 are then subtracted as the Gram matrix of their
    few zero-padded lagged rows.  Lags must lie in 0 … first.
    """
    N = groups[0][0].size
    lags = np.concatenate([g[1] for g in groups])
    signs = np.concatenate([np.full(len(g[1]), g[2]) for g in groups])
    signals: list[np.ndarray] = []
    owner = []  # which distinct signal each column delays
    for x, lag, _ in groups:
        k = next((i for i, s in enumerate(signals) if s is x), len(signals))
        if k == len(signals):
            signals.append(x)
        owner += [k] * len(lag)
    owner = np.array(owner)
    L = int(lags.max())
    corr = np.empty((len(signals), len(signals), 2 * L + 1))  # corr[i, j, d + L] = Σ_τ x_i(τ) x_j(τ − d)
    pad = np.zeros(L)
    padded = [np.concatenate([pad, x, pad]) for x in signals]  # x(t) at t + L, zero outside the record
    for i in range(len(signals)):
        for j in range(i, len(signals)):
            corr[i, j] = np.correlate(padded[i], signals[j], "valid")
            corr[j, i] = corr[i, j, ::-1]
    gram = corr[owner[:, None], owner[None, :], lags[None, :] - lags[:, None] + L]
    stacked = np.stack(padded)
    for t0, t1 in ((0, first), (N, N + L)):  # rows outside first … N−1, zero-padded
        edge = stacked[owner[None, :], np.arange(t0, t1)[:, None] - lags[None, :] + L]
        gram -= edge.T @ edge
    return gram * signs[:, None] * signs[None, :]


def _solve_normal(gram: np.ndarray, rhs: np.ndarray) -> np.ndarray:
    """Solve the normal equations, scaled to unit diagonal; minimum-norm SVD solution if singular."""
    scale = np.sqrt(np.maximum(np.diag(gram), 1e-300))
    scaled = gram / scale[:, None] / scale[None, :]
    try:
        return np.linalg.solve(scaled, rhs / scale) / scale
    except np.linalg.LinAlgError:
        return np.linalg.lstsq(scaled, rhs / scale, rcond=1e-12)[0] / scale


def regression(y: np.ndarray, u: np.ndarray, spec: PolySpec, first: int) -> tuple[np.ndarray, np.ndarray]:
    """ARX regressors [-y(t-1) … -y(t-na), u(t-nk) … u(t-nk-nb+1)] for rows t ≥ first (pre-sample zero)."""
    N = y.size
    rows = N - first
    phi = np.empty((rows, spec.na + spec.nb), order="F")
    for i in range(1, spec.na + 1):
        phi[:, i - 1] = -lagged(y, i, first)
    for j in range(spec.nb):
        phi[:, spec.na + j] = lagged(u, spec.nk + j, first)
    return phi, y[first:]


def lagged(x: np.ndarray, lag: int, first: int) -> np.ndarray:
    """x(t - lag) for t = first … N-1, zero before the record starts."""
    N = x.size
    out = np.zeros(N - first)
    start = max(first - lag, 0)
    offset = max(lag - first, 0)
    out[offset:] = x[start : N - lag]
    return out


def solve_regression(r: np.ndarray, rhs: np.ndarray, name: str = "") -> np.ndarray:
    """θ from the triangular factor R and Qᵀy of a regression; a singular R is an error naming the data."""
    diag = np.abs(np.diag(r))
    if diag.size and (diag.min() <= 1e-12 * max(diag.max(), 1e-300)):
        raise ValueError(
            f"{name or 'data'}: the regression is singular — the data do not determine all "
            "parameters (input not exciting enough, or orders too high)"
        )
    return solve_triangular(r, rhs)
