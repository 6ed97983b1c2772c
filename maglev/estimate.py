"""Estimate ARX, ARMAX, OE, BJ and general polynomial models (MATLAB's arx/armax/oe/bj/pem).

* ``arx`` is linear least squares.  With the default ``initial_condition="auto"`` it
  reproduces MATLAB's default: regression rows t = na+1 … N, inputs before the first
  sample taken as zero (the na pre-sample outputs are simply not predicted).
  ``"zero"`` uses every row with all pre-sample data zero; ``"estimate"`` (and
  ``"backcast"``) drops every row that needs pre-sample data.
* ``armax``, ``oe``, ``bj`` and ``pem`` minimise the one-step prediction error with
  Levenberg–Marquardt (:mod:`maglev.prediction_error`) from sound starting points
  (:mod:`maglev.starts`: pseudo-linear regression for ARMAX, refined instrumental
  variables for the input path of OE and BJ with a Hannan–Rissanen noise model, plain
  ARX, and an optional warm start ``init``).  The strongest start is minimised first;
  the others are tried only when its prediction errors still show structure.
  ``initial_condition``: ``"zero"`` (filters start at rest), ``"estimate"`` (the
  initial filter state is fitted by least squares and counted in d), ``"backcast"``
  (fitted the same way but treated as a nuisance, not counted in d — our stand-in
  for MATLAB's backward filtering), ``"auto"`` (``"estimate"`` when fitting the state
  lowers the loss at the start point by more than 0.1 %, else ``"zero"``).

All functions return a `PolyModel` with covariance λ̂ (JᵀJ)⁻¹, noise variance
λ̂ = N·V/(N−d) and a `FitReport` with MATLAB's loss and information criteria.
"""

from __future__ import annotations

import numpy as np

from .data import IOData
from .initial_state import INITIAL_CONDITIONS
from .models import FitReport, PolyModel
from .prediction_error import evaluate, project, triangular_factor
from .starts import best_minimum, more_starts, nested_theta, starts
from .structure import PolySpec
from .threads import single_threaded_blas

AUTO_STATE_GAIN = 1e-3


# ---------------------------------------------------------------------------- public API
@single_threaded_blas
def arx(data: IOData, na: int, nb: int, nk: int, initial_condition: str = "auto") -> PolyModel:
    """ARX  A(q) y = B(q) u + e  by least squares (see the module docstring for the rows used)."""
    spec = PolySpec("arx", na=na, nb=nb, nk=nk)
    y, u = _checked(data, spec, initial_condition)
    first = {"auto": spec.na, "zero": 0}.get(initial_condition, spec.max_lag)
    phi, target = _regression(y, u, spec, first)
    r, qty = triangular_factor(phi, target)
    theta = _solve_triangular(r, qty, data)
    e = target - phi @ theta
    A, B, *_ = spec.polys(theta)
    report = FitReport.from_residuals(
        e, target, spec.n_params, 0,
        method="least squares", iterations=0, termination="exact solution",
        initial_condition=initial_condition,
    )
    return _model(spec, A, B, None, None, None, data, e, r, report)


def armax(
    data: IOData, na: int, nb: int, nc: int, nk: int, initial_condition: str = "auto", init=None, **options
) -> PolyModel:
    """ARMAX  A(q) y = B(q) u + C(q) e  by prediction-error minimisation (``init``: see `estimate`)."""
    return _pem(data, PolySpec("armax", na=na, nb=nb, nc=nc, nk=nk), initial_condition, init=init, **options)


def oe(data: IOData, nb: int, nf: int, nk: int, initial_condition: str = "auto", init=None, **options) -> PolyModel:
    """Output error  y = B(q)/F(q) u + e  by prediction-error minimisation (``init``: see `estimate`)."""
    return _pem(data, PolySpec("oe", nb=nb, nf=nf, nk=nk), initial_condition, init=init, **options)


def bj(
    data: IOData, nb: int, nc: int, nd: int, nf: int, nk: int, initial_condition: str = "auto", init=None,
    **options,
) -> PolyModel:
    """Box–Jenkins  y = B(q)/F(q) u + C(q)/D(q) e  by prediction-error minimisation (``init``: see `estimate`)."""
    return _pem(data, PolySpec("bj", nb=nb, nc=nc, nd=nd, nf=nf, nk=nk), initial_condition, init=init, **options)


def pem(
    data: IOData, na: int, nb: int, nc: int, nd: int, nf: int, nk: int,
    initial_condition: str = "auto", init=None, **options,
) -> PolyModel:
    """General  A(q) y = B(q)/F(q) u + C(q)/D(q) e  by prediction-error minimisation (``init``: see `estimate`)."""
    spec = PolySpec("pem", na=na, nb=nb, nc=nc, nd=nd, nf=nf, nk=nk)
    return _pem(data, spec, initial_condition, init=init, **options)


def estimate(data: IOData, structure: str, orders, initial_condition: str = "auto", init=None, **options) -> PolyModel:
    """Estimate by structure name and MATLAB order vector, e.g. ``estimate(d, "bj", [2, 2, 2, 2, 1])``.

    ``init`` warm-starts the search (not for ``arx``, which is solved exactly): a
    `PolyModel` whose polynomials fit inside the requested orders — typically the
    model one order lower, padded with zeros — or a parameter vector [a b c d f] of
    the requested orders.  The search then minimises from it and from the principal
    starting point only (strongest first), so the result's loss is never above the
    warm start's: in a sweep over nested orders with zero initial conditions, passing
    each model's best lower neighbour makes the loss fall (or stay) with every added
    coefficient, at about one minimisation per model.  Without ``init`` the search
    tries more starts when the first minimum leaves structure in the residuals,
    among them the nested lower-order models it fits itself (:mod:`maglev.starts`).
    """
    spec = PolySpec.from_orders(structure, orders)
    if structure == "arx":
        if init is not None:
            raise ValueError("arx is solved exactly by least squares; init applies to armax, oe, bj and pem")
        return arx(data, spec.na, spec.nb, spec.nk, initial_condition)
    return _pem(data, spec, initial_condition, init=init, **options)


# ---------------------------------------------------------------------------- checks
def _checked(data: IOData, spec: PolySpec, initial_condition: str) -> tuple[np.ndarray, np.ndarray]:
    """Refuse data that cannot support the requested model, with a message that says why."""
    if not isinstance(data, IOData):
        raise TypeError(f"{spec.structure}: data must be an IOData, got {type(data).__name__}")
    if initial_condition not in INITIAL_CONDITIONS:
        raise ValueError(
            f"{spec.structure}: initial_condition must be one of {INITIAL_CONDITIONS}, got {initial_condition!r}"
        )
    src = data.name or "data"
    need = spec.max_lag + 2 * spec.n_params + 1
    if data.N < need:
        raise ValueError(
            f"{src}: {spec.label} has {spec.n_params} parameters and lags up to {spec.max_lag}; "
            f"it needs at least {need} samples, the data has {data.N} (orders too large for the data)"
        )
    if np.ptp(data.y) == 0:
        raise ValueError(f"{src}: output y is constant; there is nothing to identify")
    if spec.nb:
        if np.ptp(data.u) == 0:
            raise ValueError(
                f"{src}: input u is constant (= {data.u[0]:g}); it does not excite the system, "
                "so no input-output model can be identified"
            )
        order = spec.nb + spec.nf
        level = _excitation_level(data.u, order)
        if level < 1e-9:
            raise ValueError(
                f"{src}: input u is not persistently exciting of order {order} (needed by {spec.label}); "
                f"its lag covariance is singular (relative eigenvalue {level:.1e})"
            )
    return data.y, data.u


def _excitation_level(u: np.ndarray, order: int) -> float:
    """Smallest over largest eigenvalue of the Gram matrix of ``order`` lagged copies of u."""
    x = u - u.mean()
    n = x.size - order + 1
    lags = np.column_stack([x[order - 1 - k : order - 1 - k + n] for k in range(order)])
    eig = np.linalg.eigvalsh(lags.T @ lags)
    if eig[-1] <= 0:
        return 0.0
    return float(max(eig[0], 0.0) / eig[-1])


# ---------------------------------------------------------------------------- least squares
def _regression(y: np.ndarray, u: np.ndarray, spec: PolySpec, first: int) -> tuple[np.ndarray, np.ndarray]:
    """ARX regressors [-y(t-1) … -y(t-na), u(t-nk) … u(t-nk-nb+1)] for rows t ≥ first (pre-sample zero)."""
    N = y.size
    rows = N - first
    phi = np.empty((rows, spec.na + spec.nb), order="F")
    for i in range(1, spec.na + 1):
        phi[:, i - 1] = -_lagged(y, i, first)
    for j in range(spec.nb):
        phi[:, spec.na + j] = _lagged(u, spec.nk + j, first)
    return phi, y[first:]


def _lagged(x: np.ndarray, lag: int, first: int) -> np.ndarray:
    """x(t - lag) for t = first … N-1, zero before the record starts."""
    N = x.size
    out = np.zeros(N - first)
    start = max(first - lag, 0)
    offset = max(lag - first, 0)
    out[offset:] = x[start : N - lag]
    return out


def _solve_triangular(r: np.ndarray, rhs: np.ndarray, data: IOData) -> np.ndarray:
    diag = np.abs(np.diag(r))
    if diag.size and (diag.min() <= 1e-12 * max(diag.max(), 1e-300)):
        raise ValueError(
            f"{data.name or 'data'}: the regression is singular — the data do not determine all "
            "parameters (input not exciting enough, or orders too high)"
        )
    from scipy.linalg import solve_triangular

    return solve_triangular(r, rhs)


# ---------------------------------------------------------------------------- PEM driver
@single_threaded_blas
def _pem(
    data: IOData,
    spec: PolySpec,
    initial_condition: str,
    max_iterations: int = 200,
    tolerance: float | None = None,
    init=None,
) -> PolyModel:
    y, u = _checked(data, spec, initial_condition)
    candidates = [nested_theta(spec, init)] if init is not None else []
    candidates += starts(spec, y, u)
    fit_states = _wants_states(spec, candidates, y, u, initial_condition)
    more = None if init is not None else lambda: more_starts(spec, y, u, fit_states, max_iterations, tolerance)
    best = best_minimum(spec, candidates, y, u, fit_states, max_iterations, tolerance, more=more)
    ev = best.evaluation
    n_initial = ev.n_initial if initial_condition != "backcast" else 0
    mode = initial_condition
    if initial_condition == "auto":
        mode = "auto→estimate" if fit_states else "auto→zero"
    report = FitReport.from_residuals(
        ev.e, y, spec.n_params, n_initial,
        method="prediction-error minimisation (Levenberg-Marquardt)",
        iterations=best.iterations, termination=best.termination, initial_condition=mode,
    )
    A, B, C, D, F = spec.polys(ev.theta)
    return _model(spec, A, B, C, D, F, data, ev.e, best.r_factor, report)


def _wants_states(spec: PolySpec, starts: list[np.ndarray], y, u, initial_condition: str) -> bool:
    """Whether to fit initial states; "auto" decides at the best starting point."""
    if initial_condition in ("estimate", "backcast"):
        return True
    if initial_condition == "zero":
        return False
    candidates = [project(spec, t) for t in starts]
    losses = [evaluate(spec, t, y, u, False, False).loss for t in candidates]
    theta0 = candidates[int(np.argmin(losses))]
    zero = min(losses)
    fitted = evaluate(spec, theta0, y, u, True, False).loss
    return zero > 0 and (zero - fitted) / zero > AUTO_STATE_GAIN


def _model(spec, A, B, C, D, F, data: IOData, e: np.ndarray, r: np.ndarray, report: FitReport) -> PolyModel:
    """Wrap estimates in a PolyModel with λ̂ = N V/(N-d) and covariance λ̂ (RᵀR)⁻¹."""
    N = e.size
    d = report.n_params + report.n_initial
    noise_variance = float(e @ e) / max(N - d, 1)
    try:
        r_inv = np.linalg.inv(r)
        covariance = noise_variance * (r_inv @ r_inv.T)
    except np.linalg.LinAlgError:
        covariance = np.full((spec.n_params, spec.n_params), np.inf)
    one = np.ones(1)
    return PolyModel(
        A=A, B=B,
        C=one if C is None else C,
        D=one if D is None else D,
        F=one if F is None else F,
        nk=spec.nk, Ts=data.Ts, structure=spec.structure,
        noise_variance=noise_variance, covariance=covariance, report=report,
        name=f"{spec.label} · {data.name}" if data.name else spec.label,
    )
