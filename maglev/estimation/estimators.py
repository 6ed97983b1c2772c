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
  Levenberg–Marquardt (:mod:`maglev.estimation.prediction_error`) from sound starting points
  (:mod:`maglev.estimation.starts`: pseudo-linear regression for ARMAX, refined instrumental
  variables for the input path of OE and BJ with a Hannan–Rissanen noise model, plain
  ARX, and an optional warm start ``init``).  The strongest start is minimised first;
  the others are tried only when its prediction errors still show structure.
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

import math
import warnings
from dataclasses import dataclass

import numpy as np

from ..data import IOData
from ..initial_state import INITIAL_CONDITIONS
from ..model import FitReport, PolyModel
from .least_squares import regression, solve_regression
from .prediction_error import evaluate, project, r_factor, triangular_factor, with_fitted_states
from .starts import best_minimum, nested_theta, starts
from ..structures import PolySpec
from ..structures import get as get_structure
from ..threads import single_threaded_blas

AUTO_NORM_RATIO = 1.05  # MATLAB's AutoInitialState threshold: ‖e_zero‖ / ‖e_fitted‖ at the start
ARX_AUTO = "auto→na initial outputs"  # how arx reports MATLAB's default convention


# ---------------------------------------------------------------------------- public API
def arx(data: IOData, na: int, nb: int, nk: int, initial_condition: str = "auto") -> PolyModel:
    """ARX  A(q) y = B(q) u + e  by least squares (see the module docstring for the rows used)."""
    return _least_squares(data, PolySpec("arx", na=na, nb=nb, nk=nk), initial_condition)


@single_threaded_blas
def _least_squares(data: IOData, spec: PolySpec, initial_condition: str) -> PolyModel:
    """A structure with only A and B free (ARX and its special cases) by linear least squares."""
    _check_scale(data)
    y, u = _checked(data, spec, initial_condition)
    y, u, scale = _normalised(spec, y, u)
    first = {"auto": spec.na, "zero": 0}.get(initial_condition, spec.max_lag)
    phi, target = regression(y, u, spec, first)
    r, qty = triangular_factor(phi, target)
    theta = solve_regression(r, qty, data.name)
    e = np.zeros(y.size)  # the first residuals vanish: their pre-sample data are free
    e[first:] = target - phi @ theta
    theta, e, r = scale.restore(theta, e, r)
    A, B, *_ = spec.polys(theta)
    report = FitReport.from_residuals(
        e, data.y, spec.n_params, first,
        method="least squares", iterations=0, termination="exact solution",
        initial_condition=ARX_AUTO if initial_condition == "auto" else initial_condition,
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

    Any registered structure (:mod:`maglev.structures`) works: least squares when only A
    and B are free, prediction-error minimisation otherwise.

    ``init`` warm-starts the search (not for least-squares structures such as ``arx``,
    which are solved exactly): a `PolyModel` whose polynomials fit inside the requested
    orders — typically the model one order lower, padded with zeros — or a parameter
    vector [a b c d f] of the requested orders.  The search then minimises from it and
    from the principal starting point only (strongest first), so the result's loss is
    never above the warm start's: in a sweep over nested orders with zero initial
    conditions, passing each model's best lower neighbour makes the loss fall (or stay)
    with every added coefficient, at about one minimisation per model.  Without
    ``init`` the search tries more starts when the first minimum leaves structure in
    the residuals, among them the nested lower-order models it fits itself
    (:mod:`maglev.estimation.starts`).
    """
    spec = PolySpec.from_orders(structure, orders)
    if get_structure(structure).least_squares:
        if init is not None:
            raise ValueError(f"{structure} is solved exactly by least squares; init applies to "
                             "structures estimated by prediction-error minimisation")
        if options:
            raise ValueError(f"{structure} is estimated by least squares and takes no options, got {sorted(options)}")
        return _least_squares(data, spec, initial_condition)
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
        _check_excitation(data.u, spec, src)
    return data.y, data.u


def _checked_init(spec: PolySpec, init):
    """A warm start that is a PolyModel or numbers; anything else (a string, a dict) is named as such."""
    if isinstance(init, PolyModel):
        return init
    try:
        if isinstance(init, (str, bytes, dict)):
            raise TypeError
        return np.asarray(init, dtype=float)
    except (TypeError, ValueError):
        raise ValueError(f"{spec.label}: init must be a PolyModel or a vector of its {spec.n_params} parameters "
                         f"[a b c d f], got {init!r}") from None


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
        rms = _rms(x)
        if rms > MAX_RMS or 0 < rms < 1 / MAX_RMS:
            raise ValueError(f"{data.name or 'data'}: {what} has RMS {rms:.1e}; estimation squares the data, which "
                             f"over- or underflows beyond RMS 1e±100 — rescale it (other units)")


@dataclass(frozen=True)
class _Scale:
    """Estimation runs on u/su and y/sy (about their RMS), so its tolerances and rank tests see numbers
    near 1 whatever the units; only B (by sy/su) and the residuals (by sy) carry the scales back."""

    theta: np.ndarray  # parameter k of the data's model = theta[k] × parameter k of the scaled data's
    sy: float

    def scaled(self, theta: np.ndarray) -> np.ndarray:
        return theta / self.theta

    def restore(self, theta: np.ndarray, e: np.ndarray, r: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Parameters, residuals and the triangular factor of ∂e/∂θ of the unscaled data."""
        return theta * self.theta, e * self.sy, r * (self.sy / self.theta)[None, :]


def _normalised(spec: PolySpec, y: np.ndarray, u: np.ndarray) -> tuple[np.ndarray, np.ndarray, _Scale]:
    """y and u divided by the power of two nearest their RMS (1 for an all-zero signal), and how to undo it.

    A power of two changes no digit: estimation on data whose RMS is near 1 gives the same numbers
    as without the scaling, bit for bit, and the scales are carried back exactly."""
    sy, su = (2.0 ** round(math.log2(rms)) if rms > 0 else 1.0 for rms in (_rms(y), _rms(u)))
    theta = np.ones(spec.n_params)
    theta[spec.na : spec.na + spec.nb] = sy / su
    return y / sy, u / su, _Scale(theta, sy)


def _rms(x: np.ndarray) -> float:
    """Root mean square, without squaring overflow: max|x| · RMS(x / max|x|)."""
    peak = float(np.max(np.abs(x)))
    return peak * float(np.sqrt(np.mean(np.square(x / peak)))) if peak > 0 else 0.0


POOR_CONDITIONING = 1e6  # condition number of the input's lag matrix above which the estimate is flagged
CLEARLY_EXCITING = 1e-4  # relative singular values above this, estimated from the Gram matrix, need no SVD


def _check_excitation(u: np.ndarray, spec: PolySpec, src: str) -> None:
    """Refuse an input that is not persistently exciting of order nb + nf; warn when it barely is.

    The test is the numerical rank of the N × (nb + nf) matrix of lagged copies of u (mean removed):
    a singular value below max(N, order) · eps times the largest is rounding, so such an input
    determines fewer than nb + nf coefficients (two sinusoids span 4 lag directions, 5 with a
    mean left over by a non-integer number of periods).  An input that excites more directions
    but nearly collinearly — an oversampled band-limited multisine: rank 8 with condition number
    ≈ 1e7 — is estimated, with a warning, since least squares by QR loses only that condition
    number's digits, not its square.  The SVD is skipped when the eigenvalues of the lag matrix's
    Gram matrix already put every relative singular value above ``CLEARLY_EXCITING``.
    """
    order = spec.nb + spec.nf
    x = u - u.mean()
    n = x.size - order + 1
    lags = np.column_stack([x[order - 1 - k : order - 1 - k + n] for k in range(order)])
    eig = np.linalg.eigvalsh(lags.T @ lags)  # squared singular values, each to within ~eps × the largest
    if eig[0] > CLEARLY_EXCITING**2 * eig[-1]:
        return  # the SVD would find full rank and no poor conditioning: skip it
    sv = np.linalg.svd(lags, compute_uv=False)
    relative = sv / sv[0]
    rank = int(np.sum(relative > max(lags.shape) * np.finfo(float).eps))
    if rank < order:
        raise ValueError(
            f"{src}: input u is not persistently exciting of order {order} (needed by {spec.label}): its "
            f"{order} lagged copies span only {rank} directions (singular values relative to the largest "
            f"down to {relative[-1]:.1e}, rank tolerance {max(lags.shape) * np.finfo(float).eps:.1e}); "
            f"use a richer input or orders with nb + nf <= {rank}"
        )
    if relative[-1] * POOR_CONDITIONING < 1:
        warnings.warn(
            f"{src}: input u is poorly conditioned for order {order} ({spec.label}): its lag matrix has "
            f"condition number {1 / relative[-1]:.1e}, so the coefficients are sensitive to noise "
            "(an oversampled or band-limited input); the estimate may still predict well",
            ExcitationWarning, stacklevel=4,
        )


class ExcitationWarning(UserWarning):
    """The input excites the model's orders only through a poorly conditioned lag matrix."""


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
    _check_options(max_iterations, tolerance)
    _check_scale(data)
    y, u = _checked(data, spec, initial_condition)
    y, u, scale = _normalised(spec, y, u)
    candidates = [scale.scaled(nested_theta(spec, _checked_init(spec, init)))] if init is not None else []
    memo: dict = {}
    candidates += starts(spec, y, u, memo)
    fit_states, evaluated = _wants_states(spec, candidates, y, u, initial_condition)
    best = best_minimum(spec, candidates, y, u, fit_states, max_iterations, tolerance, widen=init is None, memo=memo,
                        evaluated=evaluated)
    ev = best.evaluation
    mode = initial_condition
    if initial_condition == "auto":
        mode = "auto→backcast" if fit_states else "auto→zero"
    theta, e, r = scale.restore(ev.theta, ev.e, r_factor(spec, best, y, u))
    report = FitReport.from_residuals(  # fitted states count in d, backcast too (as in MATLAB)
        e, data.y, spec.n_params, ev.n_initial,
        method="prediction-error minimisation (Levenberg-Marquardt)",
        iterations=best.iterations, termination=best.termination, initial_condition=mode,
    )
    A, B, C, D, F = spec.polys(theta)
    return _model(spec, A, B, C, D, F, data, e, r, report)


def _wants_states(spec: PolySpec, starts: list[np.ndarray], y, u, initial_condition: str) -> tuple[bool, list]:
    """Whether to fit initial states; "auto" decides at the best starting point by
    MATLAB's rule: fit them ("backcast") when the prediction-error norm with zero
    states exceeds the norm with fitted states by more than AUTO_NORM_RATIO.  With the
    evaluations at ``starts`` it made when they hold for the decision (zero states), so
    that the search does not repeat them."""
    if initial_condition in ("estimate", "backcast"):
        return True, []
    if initial_condition == "zero":
        return False, []
    zero = [evaluate(spec, project(spec, t), y, u, False, False) for t in starts]
    best = min(zero, key=lambda ev: ev.loss)
    fitted = with_fitted_states(spec, best).loss
    wanted = best.loss > AUTO_NORM_RATIO**2 * fitted
    return wanted, [] if wanted else zero


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
