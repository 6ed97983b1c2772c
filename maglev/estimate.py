"""Estimate ARX, ARMAX, OE, BJ and general polynomial models (MATLAB's arx/armax/oe/bj/pem).

* ``arx`` is linear least squares.  With the default ``initial_condition="auto"`` it
  reproduces MATLAB's (time-domain) arx: regression rows t = na+1 … N, inputs before
  the first sample taken as zero; the first na outputs serve as initial conditions, so
  their residuals are zero and the na initial outputs count in d (d = 2 na + nb), as in
  MATLAB's report.  ``"zero"`` uses every row with all pre-sample data zero (d = na + nb);
  ``"estimate"`` (and ``"backcast"``, which MATLAB turns into "estimate" when C·F = 1)
  frees the pre-sample outputs and inputs: rows t ≥ max(na, nb+nk−1) + 1, the
  max(na, nb+nk−1) initial values counted in d.
* ``armax``, ``oe``, ``bj`` and ``pem`` minimise the one-step prediction error with
  Levenberg–Marquardt (:mod:`maglev.prediction_error`) from several sound starting points
  (pseudo-linear regression for ARMAX, Steiglitz–McBride for OE, OE plus a
  Hannan–Rissanen noise model for BJ, plain ARX) and keep the best minimum, so that
  lightly damped plants do not end in a poor local minimum.
  ``initial_condition``: ``"zero"`` (filters start at rest), ``"estimate"`` (the
  initial state of the prediction-error filter — all its states, numerator included —
  is fitted by least squares at every evaluation), ``"backcast"`` (fitted the same way:
  our stand-in for MATLAB's backward filtering, which approximates the same
  least-squares state), ``"auto"`` (MATLAB's rule, decided at the best starting point:
  ``"backcast"`` when ‖e‖ with zero states exceeds ‖e‖ with fitted states by more than
  ``AUTO_NORM_RATIO`` = 1.05 — MATLAB's AutoInitialState threshold — else ``"zero"``;
  the report says ``auto→backcast`` or ``auto→zero``).  Fitted states count in d for
  "estimate", "backcast" and "auto→backcast" alike, as MATLAB counts them.  On the lab
  records the ratio is ≈ 2–3 on binary_signal_2 and the 2017 records (lift-off
  transient: backcast) and ≈ 1.002 on white_noise_2 with its start dropped (zero), as
  MATLAB chose; AIC would not separate them (the states would win by ≈ 11 on
  white_noise_2), BIC would.

All functions return a `PolyModel` and a `FitReport` with MATLAB's N, V and d: N = all
samples, V = Σe²/N (residuals freed by initial conditions are zero), d = parameters +
initial values; FPE, AIC, AICc, BIC and nAIC follow from them by MATLAB's formulas, the
noise variance is λ̂ = N·V/(N−d) and the covariance λ̂ (JᵀJ)⁻¹.
"""

from __future__ import annotations

import numpy as np

from .data import IOData
from .initial_state import INITIAL_CONDITIONS
from .models import FitReport, PolyModel
from .prediction_error import CONVERGED, evaluate, minimise, project, triangular_factor
from .polynomials import filt, stabilize
from .structures import PolySpec
from .structures import get as get_structure
from .threads import single_threaded_blas

AUTO_NORM_RATIO = 1.05  # MATLAB's AutoInitialState threshold: ‖e_zero‖ / ‖e_fitted‖ at the start
ARX_AUTO = "auto→na initial outputs"  # how arx reports MATLAB's default convention
START_RATIO = 10.0
ABANDON_MARGIN = 0.01  # a secondary start must be within 1 % of the best minimum by then


# ---------------------------------------------------------------------------- public API
def arx(data: IOData, na: int, nb: int, nk: int, initial_condition: str = "auto") -> PolyModel:
    """ARX  A(q) y = B(q) u + e  by least squares (see the module docstring for the rows used)."""
    return _least_squares(data, PolySpec("arx", na=na, nb=nb, nk=nk), initial_condition)


@single_threaded_blas
def _least_squares(data: IOData, spec: PolySpec, initial_condition: str) -> PolyModel:
    """A structure with only A and B free (ARX and its special cases) by linear least squares."""
    y, u = _checked(data, spec, initial_condition)
    first = {"auto": spec.na, "zero": 0}.get(initial_condition, spec.max_lag)
    phi, target = _regression(y, u, spec, first)
    r, qty = triangular_factor(phi, target)
    theta = _solve_triangular(r, qty, data)
    e = np.zeros(y.size)  # the first residuals vanish: their pre-sample data are free
    e[first:] = target - phi @ theta
    A, B, *_ = spec.polys(theta)
    report = FitReport.from_residuals(
        e, y, spec.n_params, first,
        method="least squares", iterations=0, termination="exact solution",
        initial_condition=ARX_AUTO if initial_condition == "auto" else initial_condition,
    )
    return _model(spec, A, B, None, None, None, data, e, r, report)


def armax(data: IOData, na: int, nb: int, nc: int, nk: int, initial_condition: str = "auto", **options) -> PolyModel:
    """ARMAX  A(q) y = B(q) u + C(q) e  by prediction-error minimisation."""
    return _pem(data, PolySpec("armax", na=na, nb=nb, nc=nc, nk=nk), initial_condition, **options)


def oe(data: IOData, nb: int, nf: int, nk: int, initial_condition: str = "auto", **options) -> PolyModel:
    """Output error  y = B(q)/F(q) u + e  by prediction-error minimisation."""
    return _pem(data, PolySpec("oe", nb=nb, nf=nf, nk=nk), initial_condition, **options)


def bj(data: IOData, nb: int, nc: int, nd: int, nf: int, nk: int, initial_condition: str = "auto", **options) -> PolyModel:
    """Box–Jenkins  y = B(q)/F(q) u + C(q)/D(q) e  by prediction-error minimisation."""
    return _pem(data, PolySpec("bj", nb=nb, nc=nc, nd=nd, nf=nf, nk=nk), initial_condition, **options)


def pem(
    data: IOData, na: int, nb: int, nc: int, nd: int, nf: int, nk: int,
    initial_condition: str = "auto", **options,
) -> PolyModel:
    """General  A(q) y = B(q)/F(q) u + C(q)/D(q) e  by prediction-error minimisation."""
    return _pem(data, PolySpec("pem", na=na, nb=nb, nc=nc, nd=nd, nf=nf, nk=nk), initial_condition, **options)


def estimate(data: IOData, structure: str, orders, initial_condition: str = "auto", **options) -> PolyModel:
    """Estimate by structure name and MATLAB order vector, e.g. ``estimate(d, "bj", [2, 2, 2, 2, 1])``.

    Any registered structure (:mod:`maglev.structures`) works: least squares when only A
    and B are free, prediction-error minimisation otherwise.
    """
    spec = PolySpec.from_orders(structure, orders)
    _check_scale(data)
    if get_structure(structure).least_squares:
        if options:
            raise ValueError(f"{structure} is estimated by least squares and takes no options, got {sorted(options)}")
        return _least_squares(data, spec, initial_condition)
    return _pem(data, spec, initial_condition, **options)


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


MAX_RMS = 1e100  # the data's squares and their sums over N samples stay far inside float64 (1e±308)


def _check_options(max_iterations, tolerance) -> None:
    """``max_iterations`` an integer >= 0 (0: the best starting point), ``tolerance`` None or a number > 0."""
    if isinstance(max_iterations, (bool, np.bool_)) or not isinstance(max_iterations, (int, np.integer)) \
            or max_iterations < 0:
        raise ValueError(f"max_iterations must be an integer >= 0, got {max_iterations!r}")
    if tolerance is not None and (isinstance(tolerance, (bool, np.bool_)) or not isinstance(tolerance, (int, float))
                                  or not np.isfinite(tolerance) or tolerance <= 0):
        raise ValueError(f"tolerance must be None or a finite number > 0, got {tolerance!r}")


def _check_scale(data: IOData) -> None:
    """Refuse data whose scale over- or underflows once squared (loss inf or 0, a "converged" nonsense model)."""
    if not isinstance(data, IOData):
        return  # _checked says so
    for what, x in (("input u", data.u), ("output y", data.y)):
        rms = float(np.sqrt(np.mean(np.square(x / max(np.max(np.abs(x)), 1e-300))))) * float(np.max(np.abs(x)))
        if rms > MAX_RMS or 0 < rms < 1 / MAX_RMS:
            raise ValueError(f"{data.name or 'data'}: {what} has RMS {rms:.1e}; estimation squares the data, which "
                             f"over- or underflows beyond RMS 1e±100 — rescale it (other units)")


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


def _lstsq(phi: np.ndarray, target: np.ndarray) -> np.ndarray:
    """Least squares through one R-only QR of [Φ y]; SVD-based lstsq if Φ is rank deficient."""
    p = phi.shape[1]
    if p == 0:
        return np.zeros(0)
    r, qty = triangular_factor(phi, target)
    diag = np.abs(np.diag(r))
    if diag.min() <= 1e-10 * diag.max():
        return np.linalg.lstsq(phi, target, rcond=None)[0]
    from scipy.linalg import solve_triangular

    return solve_triangular(r, qty)


def _ls_arx(
    y: np.ndarray, u: np.ndarray, na: int, nb: int, nk: int, residuals: bool = True
) -> tuple[np.ndarray, np.ndarray, np.ndarray | None]:
    """Plain ARX by least squares on fully measured rows; returns (A, B, residuals over all N)."""
    spec = PolySpec("pem", na=na, nb=nb, nk=nk)
    phi, target = _regression(y, u, spec, spec.max_lag)
    A, B, *_ = spec.polys(_lstsq(phi, target))
    if not residuals:
        return A, B, None
    e = filt(A, np.ones(1), y) - (filt(B, np.ones(1), u) if nb else 0.0)
    return A, B, e


def _ls_columns(target: np.ndarray, columns: list[np.ndarray], first: int) -> np.ndarray:
    if not columns:
        return np.zeros(0)
    return _lstsq(np.column_stack([c[first:] for c in columns]), target[first:])


def _shift(x: np.ndarray, lag: int) -> np.ndarray:
    out = np.zeros_like(x)
    out[lag:] = x[: x.size - lag]
    return out


# ---------------------------------------------------------------------------- starting points
def _high_order(n_params: int, N: int) -> int:
    return int(min(max(3 * n_params, 10), 40, max(N // 50, 2)))


def _steiglitz_mcbride(y, u, nb, nf, nk, F0=None, iterations: int = 30):
    """OE start: refit B, F by least squares on data prefiltered by 1/F until F settles."""
    if nf == 0:
        _, B, _ = _ls_arx(y, u, 0, nb, nk, residuals=False)
        return B, np.ones(1)
    F = F0 if F0 is not None else _ls_arx(y, u, nf, nb, nk, residuals=False)[0]
    F = stabilize(F)
    B = np.zeros(nb + nk)
    for _ in range(iterations):
        yf, uf = filt(np.ones(1), F, y), filt(np.ones(1), F, u)
        Fn, Bn, _ = _ls_arx(yf, uf, nf, nb, nk, residuals=False)
        Fn = stabilize(Fn)
        change = np.linalg.norm(Fn - F) / (np.linalg.norm(F) + 1e-12)
        F, B = Fn, Bn
        if change < 1e-6:  # a starting point only: the minimiser polishes it
            break
    return B, F


def _g_starts(y, u, nb, nf, nk) -> list[tuple[np.ndarray, np.ndarray]]:
    """Starting (B, F) pairs for the input path of OE/BJ: Steiglitz–McBride and plain ARX."""
    B, F = _steiglitz_mcbride(y, u, nb, nf, nk)
    Aarx, Barx, _ = _ls_arx(y, u, nf, nb, nk, residuals=False)
    return [(B, F), (Barx, stabilize(Aarx))]


def _hannan_rissanen(v: np.ndarray, nc: int, nd: int) -> tuple[np.ndarray, np.ndarray]:
    """ARMA start D v = C e: long AR for the innovations, then least squares for C and D."""
    if nc == 0 and nd == 0:
        return np.ones(1), np.ones(1)
    n_ar = _high_order(nc + nd, v.size)
    Dar, _, e = _ls_arx(v, np.zeros_like(v), n_ar, 0, 1)
    cols = [-_shift(v, i) for i in range(1, nd + 1)] + [_shift(e, i) for i in range(1, nc + 1)]
    theta = _ls_columns(v, cols, n_ar + max(nc, nd))
    D = np.concatenate([[1.0], theta[:nd]])
    C = np.concatenate([[1.0], theta[nd:]])
    return stabilize(C), stabilize(D)


def _starts(spec: PolySpec, y: np.ndarray, u: np.ndarray, g_starts=None) -> list[np.ndarray]:
    """Candidate starting parameter vectors for the structure (``g_starts``: precomputed
    :func:`_g_starts` for OE/BJ, shared with the OE-first BJ start)."""
    na, nb, nc, nd, nf, nk = spec.na, spec.nb, spec.nc, spec.nd, spec.nf, spec.nk
    starts = []
    if nf == 0 and nd == 0:  # ARMAX (or ARX-like pem): pseudo-linear regression and plain ARX
        A, B, _ = _ls_arx(y, u, na, nb, nk)
        starts.append(spec.theta(A, B))
        if nc:
            nh = _high_order(na + nb + nc, y.size)
            _, _, ehat = _ls_arx(y, u, nh, max(nb, nh), nk)
            cols = [-_shift(y, i) for i in range(1, na + 1)]
            cols += [_shift(u, nk + j) for j in range(nb)]
            cols += [_shift(ehat, i) for i in range(1, nc + 1)]
            theta = _ls_columns(y, cols, nh + max(na, nb + nk, nc))
            A, B, C, *_ = PolySpec("pem", na=na, nb=nb, nc=nc, nk=nk).polys(theta)
            starts.append(spec.theta(A, B, stabilize(C)))
        return starts
    if na == 0:  # OE / BJ: Steiglitz–McBride or ARX for G, Hannan–Rissanen for the noise
        for B, F in g_starts if g_starts is not None else _g_starts(y, u, nb, nf, nk):
            C, D = _hannan_rissanen(y - filt(B, F, u), nc, nd)
            starts.append(spec.theta(None, B, C, D, F))
        if nd:  # BJ holding an ARX model: F = D = A_arx, C = 1 (its loss is the ARX loss)
            n = min(nf, nd)
            Aarx, Barx, _ = _ls_arx(y, u, n, nb, nk)
            Aarx = stabilize(Aarx)
            starts.append(spec.theta(None, Barx, None, Aarx, Aarx))
        return starts
    # general: A from ARX, F starts at 1, noise from the ARX residual
    A, B, e = _ls_arx(y, u, na, nb, nk)
    C, D = _hannan_rissanen(e, nc, nd)
    starts.append(spec.theta(A, B, C, D, None))
    return starts


# ---------------------------------------------------------------------------- PEM driver
@single_threaded_blas
def _pem(
    data: IOData,
    spec: PolySpec,
    initial_condition: str,
    max_iterations: int = 200,
    tolerance: float | None = None,
) -> PolyModel:
    _check_options(max_iterations, tolerance)
    _check_scale(data)
    y, u = _checked(data, spec, initial_condition)
    g_starts = _g_starts(y, u, spec.nb, spec.nf, spec.nk) if spec.na == 0 and spec.nb else None
    starts = _starts(spec, y, u, g_starts)
    if spec.structure == "bj" or (spec.structure == "pem" and spec.na == 0 and spec.nf > 0):
        starts.append(_bj_from_oe(spec, y, u, g_starts, max_iterations, tolerance))
    if spec.na and (spec.nf or spec.nd):
        starts.append(_general_from_bj(spec, y, u, max_iterations, tolerance))
    fit_states = _wants_states(spec, starts, y, u, initial_condition)
    best = _best_minimum(spec, starts, y, u, fit_states, max_iterations, tolerance)
    ev = best.evaluation
    mode = initial_condition
    if initial_condition == "auto":
        mode = "auto→backcast" if fit_states else "auto→zero"
    report = FitReport.from_residuals(  # fitted states count in d, backcast too (as in MATLAB)
        ev.e, y, spec.n_params, ev.n_initial,
        method="prediction-error minimisation (Levenberg-Marquardt)",
        iterations=best.iterations, termination=best.termination, initial_condition=mode,
    )
    A, B, C, D, F = spec.polys(ev.theta)
    return _model(spec, A, B, C, D, F, data, ev.e, best.r_factor, report)


def _best_minimum(spec, starts, y, u, fit_states, max_iterations, tolerance):
    """Minimise from every start, best starting loss first; keep the lowest minimum.

    Starts more than START_RATIO worse than the best start are skipped once a run has
    converged.  Later runs are abandoned after a few iterations if they are still
    above the best minimum, so a start heading for a better basin is followed to the
    end while one heading for the same or a worse minimum costs little.
    """
    losses = [evaluate(spec, project(spec, t), y, u, fit_states, False).loss for t in starts]
    order = np.argsort(losses)
    best = None
    for rank, i in enumerate(order):
        converged = best is not None and best.termination.startswith(CONVERGED)
        if rank and converged and losses[i] > START_RATIO * losses[order[0]]:
            break
        result = minimise(
            spec, starts[i], y, u, fit_states, max_iterations, tolerance,
            abandon_above=None if best is None else best.evaluation.loss * (1 + ABANDON_MARGIN),
            known_minimum=best.evaluation.theta if converged else None,
        )
        if best is None or result.evaluation.loss < best.evaluation.loss * (1 - 1e-9):
            best = result
    return best


def _bj_from_oe(spec: PolySpec, y, u, g_starts, max_iterations, tolerance) -> np.ndarray:
    """BJ start: minimise the OE part first (from Steiglitz–McBride; the ARX input path is
    already among BJ's own starts), then model its residual as ARMA."""
    oe_spec = PolySpec("oe", nb=spec.nb, nf=spec.nf, nk=spec.nk)
    oe_starts = _starts(oe_spec, y, u, g_starts[:1])
    oe_best = _best_minimum(oe_spec, oe_starts, y, u, False, max_iterations, tolerance)
    _, B, _, _, F = oe_spec.polys(oe_best.evaluation.theta)
    C, D = _hannan_rissanen(oe_best.evaluation.e, spec.nc, spec.nd)
    return spec.theta(None, B, C, D, F)


def _general_from_bj(spec: PolySpec, y, u, max_iterations, tolerance) -> np.ndarray:
    """Start for A y = B/F u + C/D e with A, F or D free: fit the BJ model with
    F' = A F and D' = A D, then give A the na poles that F' and D' share most closely."""
    wide = PolySpec("pem", nb=spec.nb, nc=spec.nc, nd=spec.nd + spec.na, nf=spec.nf + spec.na, nk=spec.nk)
    fitted = _best_minimum(wide, _starts(wide, y, u), y, u, False, max_iterations, tolerance)
    _, B, C, Dw, Fw = wide.polys(fitted.evaluation.theta)
    rf, rd = list(np.roots(Fw)), list(np.roots(Dw))
    common = []
    for _ in range(spec.na):
        i, j = min(((i, j) for i in range(len(rf)) for j in range(len(rd))),
                   key=lambda ij: abs(rf[ij[0]] - rd[ij[1]]))
        common.append((rf.pop(i) + rd.pop(j)) / 2)
    A, F, D = (np.real(np.poly(r)) if len(r) else np.ones(1) for r in (common, rf, rd))
    return spec.theta(A, B, C, D, F)


def _wants_states(spec: PolySpec, starts: list[np.ndarray], y, u, initial_condition: str) -> bool:
    """Whether to fit initial states; "auto" decides at the best starting point by
    MATLAB's rule: fit them ("backcast") when the prediction-error norm with zero
    states exceeds the norm with fitted states by more than AUTO_NORM_RATIO."""
    if initial_condition in ("estimate", "backcast"):
        return True
    if initial_condition == "zero":
        return False
    candidates = [project(spec, t) for t in starts]
    losses = [evaluate(spec, t, y, u, False, False).loss for t in candidates]
    theta0 = candidates[int(np.argmin(losses))]
    zero = min(losses)
    fitted = evaluate(spec, theta0, y, u, True, False).loss
    return zero > AUTO_NORM_RATIO**2 * fitted


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
