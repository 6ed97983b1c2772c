"""Least-squares fit of a predictor's initial state (MATLAB's InitialCondition options).

Predictions and prediction errors are sums of IIR filters run from an unknown
initial state.  Their output is the zero-state response plus a linear combination of
free responses, so the state that best explains the first samples is a small linear
least-squares problem over the transient window only (free responses of stable
filters die out; we stop once they are below 1e-10).
"""

from __future__ import annotations

import numpy as np

from .polynomials import free_response_window, free_responses, n_states

INITIAL_CONDITIONS = ("zero", "estimate", "backcast", "auto")


def free_response_matrix(filters: list[tuple[np.ndarray, np.ndarray]], n: int) -> np.ndarray:
    """Free responses of all ``(num, den)`` filters, truncated to their common transient window.

    Returns an ``M × k`` matrix with ``M ≤ n`` rows and one column per filter state.
    The window covers every state of every filter: the numerator's delays plus the
    decay of the denominator (an ARX predictor's filters B and 1 − A are FIR, and all
    max(na, nb+nk−1) of their states must be fitted, not just the first two).
    """
    filters = [(np.asarray(b, float), np.asarray(a, float)) for b, a in filters]
    active = [(b, a) for b, a in filters if np.any(b != 0)]
    if not active:
        return np.zeros((0, 0))
    m = max(free_response_window(n_states(b, a), a, n) for b, a in active)
    blocks = [free_responses(b, a, m) for b, a in active]
    return np.hstack(blocks) if blocks else np.zeros((m, 0))


def fit_initial_state(
    residual: np.ndarray,
    filters: list[tuple[np.ndarray, np.ndarray]],
    mode: str = "estimate",
) -> tuple[np.ndarray, int]:
    """The correction to add to a zero-state prediction and the number of fitted states.

    ``residual`` is target minus zero-state prediction; the correction is the
    combination of free responses that minimises its squared norm.  "estimate",
    "backcast" and "auto" all fit the state here (they differ only in how
    :mod:`maglev.estimation` counts and uses it); "zero" returns no correction.
    A 2-D ``residual`` holds one record per row, each with its own state (one
    least-squares solve for all of them).
    """
    correction = np.zeros_like(residual)
    if mode == "zero":
        return correction, 0
    phi = free_response_matrix(filters, residual.shape[-1])
    if phi.size == 0:
        return correction, 0
    m = phi.shape[0]
    x, _, rank, _ = np.linalg.lstsq(phi, residual[..., :m].T, rcond=1e-10)
    correction[..., :m] = (phi @ x).T
    return correction, int(rank)


def fit_shifted_response(residual: np.ndarray, response: np.ndarray, n: int) -> np.ndarray:
    """The combination of ``response`` delayed by 0 … n−1 samples closest to ``residual`` (least squares).

    The errors of a k-step predictor depend on the model's n pre-sample values through one
    response delayed by the value's index, so fitting the initial state is this problem,
    whose size (N × n) does not depend on the horizon.
    """
    N = residual.size
    n = min(n, N)
    if n == 0:
        return np.zeros_like(residual)
    phi = np.zeros((N, n))
    for i in range(n):
        phi[i:, i] = response[: N - i]
    x, *_ = np.linalg.lstsq(phi, residual, rcond=1e-10)
    return phi @ x
