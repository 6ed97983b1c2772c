"""Prediction-error minimisation for A y = B/F u + C/D e (Gauss–Newton / Levenberg–Marquardt).

The prediction error is e = D/C (A y − B/F u).  Its derivative with respect to each
coefficient is the same few filtered signals shifted in time, so one Jacobian costs
five ``lfilter`` calls regardless of the order:

    ∂e/∂a_i =  q⁻ⁱ D/C y          ∂e/∂b_j = −q^-(nk+j) D/(C F) u
    ∂e/∂c_i = −q⁻ⁱ e / C          ∂e/∂d_i =  q⁻ⁱ v / C   (v = A y − B/F u)
    ∂e/∂f_i =  q⁻ⁱ D/(C F) w      (w = B/F u)

Each iteration takes a QR factorisation of the Jacobian and solves the damped
Gauss–Newton step on the small triangular system, so retries with a larger damping
cost nothing extra.  C, D and F are kept stable by reflecting roots that leave the
unit circle.  With ``initial_condition="estimate"`` the filter states are fitted by
least squares at every evaluation and the Jacobian is projected accordingly
(variable projection, Kaufman's approximation).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .initial_state import free_response_matrix
from .polynomials import filt, polymul, stabilize
from .structure import PolySpec

MAX_RETRIES = 12  # damping grows 10x per retry: 1e-4 ... 1e7 relative to diag(JᵀJ)


@dataclass
class Evaluation:
    """Prediction errors (and optionally their Jacobian) at one parameter vector."""

    theta: np.ndarray
    e: np.ndarray
    loss: float
    jac: np.ndarray | None = None
    n_initial: int = 0


def project(spec: PolySpec, theta: np.ndarray) -> np.ndarray:
    """Reflect unstable roots of C, D and F into the unit circle."""
    A, B, C, D, F = spec.polys(theta)
    return spec.theta(A, B, stabilize(C), stabilize(D), stabilize(F))


def evaluate(
    spec: PolySpec,
    theta: np.ndarray,
    y: np.ndarray,
    u: np.ndarray,
    fit_states: bool,
    jacobian: bool,
) -> Evaluation:
    """Prediction errors at ``theta`` (with fitted initial states if asked) and their Jacobian."""
    A, B, C, D, F = spec.polys(theta)
    w = filt(B, F, u) if spec.nb else np.zeros_like(u)
    v = (filt(A, np.ones(1), y) if spec.na else y) - w
    e = filt(D, C, v)
    phi = None
    if fit_states:
        phi = free_response_matrix([(polymul(D, A), C), (polymul(D, B), polymul(C, F))], y.size)
        m = phi.shape[0]
        if m:
            x, *_ = np.linalg.lstsq(phi, -e[:m], rcond=1e-10)
            e = e.copy()
            e[:m] += phi @ x
    jac = _jacobian(spec, A, B, C, D, F, y, u, w, v, e) if jacobian else None
    n_initial = 0
    if phi is not None and phi.size and jac is not None:
        m = phi.shape[0]
        n_initial = int(np.linalg.matrix_rank(phi))
        coef, *_ = np.linalg.lstsq(phi, jac[:m], rcond=1e-10)
        jac[:m] -= phi @ coef
    return Evaluation(theta, e, float(e @ e) / e.size, jac, n_initial)


def _jacobian(spec, A, B, C, D, F, y, u, w, v, e) -> np.ndarray:
    """∂e/∂θ as an N × p matrix (columns in the parameter order a, b, c, d, f)."""
    N = y.size
    jac = np.empty((N, spec.n_params))
    col = 0

    def shifted(x: np.ndarray, lags) -> None:
        nonlocal col
        for lag in lags:
            jac[:lag, col] = 0.0
            jac[lag:, col] = x[: N - lag]
            col += 1

    CF = polymul(C, F)
    if spec.na:
        shifted(filt(D, C, y), range(1, spec.na + 1))
    if spec.nb:
        shifted(-filt(D, CF, u), range(spec.nk, spec.nk + spec.nb))
    if spec.nc:
        shifted(-filt(np.ones(1), C, e), range(1, spec.nc + 1))
    if spec.nd:
        shifted(filt(np.ones(1), C, v), range(1, spec.nd + 1))
    if spec.nf:
        shifted(filt(D, CF, w), range(1, spec.nf + 1))
    return jac


@dataclass
class Minimum:
    """Result of one minimisation run."""

    evaluation: Evaluation
    iterations: int
    termination: str
    r_factor: np.ndarray


def minimise(
    spec: PolySpec,
    theta0: np.ndarray,
    y: np.ndarray,
    u: np.ndarray,
    fit_states: bool = False,
    max_iterations: int = 100,
    tolerance: float | None = None,
) -> Minimum:
    """Levenberg–Marquardt from ``theta0`` until the expected relative improvement < ``tolerance``.

    The default tolerance is ``1e-3 · d / N``: the loss of a fitted model fluctuates
    by about d/N relative between data sets, so improvements a thousand times
    smaller than that change nothing a user can see.
    """
    if tolerance is None:
        tolerance = max(1e-3 * spec.n_params / y.size, 1e-12)
    current = evaluate(spec, project(spec, theta0), y, u, fit_states, jacobian=True)
    lam = 0.0
    termination = "maximum number of iterations reached"
    iterations = 0
    r = np.eye(spec.n_params)
    for iterations in range(1, max_iterations + 1):
        q, r = np.linalg.qr(current.jac)
        g = q.T @ current.e
        # Gauss-Newton predicts a loss reduction of |Q'e|^2 / N
        expected = float(g @ g) / current.e.size
        if current.loss == 0 or expected <= tolerance * current.loss:
            termination = "expected improvement below tolerance"
            iterations -= 1
            break
        scale = np.sqrt(np.sum(r * r, axis=0)) + 1e-300
        accepted = None
        for _ in range(MAX_RETRIES):
            step = _damped_step(r, g, lam, scale)
            candidate_theta = project(spec, current.theta + step)
            candidate = evaluate(spec, candidate_theta, y, u, fit_states, jacobian=False)
            if np.isfinite(candidate.loss) and candidate.loss < current.loss:
                accepted = candidate
                break
            lam = max(lam * 10.0, 1e-4)
        if accepted is None:
            termination = "no improvement along the search direction"
            break
        relative = (current.loss - accepted.loss) / current.loss
        undamped = lam == 0.0
        lam = lam / 10.0 if lam > 1e-8 else 0.0
        current = evaluate(spec, accepted.theta, y, u, fit_states, jacobian=True)
        if undamped and relative < tolerance:
            termination = "relative improvement below tolerance"
            break
    if current.jac is not None:
        r = np.linalg.qr(current.jac, mode="r")
    return Minimum(current, iterations, termination, r)


def _damped_step(r: np.ndarray, g: np.ndarray, lam: float, scale: np.ndarray) -> np.ndarray:
    """Solve min |R s + g|² + lam |diag(scale) s|² (Marquardt's scaled damping)."""
    if lam == 0.0:
        try:
            return -np.linalg.solve(r, g)
        except np.linalg.LinAlgError:
            lam = 1e-8
    p = r.shape[1]
    stacked = np.vstack([r, np.sqrt(lam) * np.diag(scale)])
    rhs = np.concatenate([g, np.zeros(p)])
    step, *_ = np.linalg.lstsq(stacked, -rhs, rcond=None)
    return step
