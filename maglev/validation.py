"""Model validation on fresh data: FIT %, MATLAB-style ``compare``, residual tests.

The lab ranks models by the one-step-ahead FIT on validation data,
FIT = 100 (1 − ‖y − ŷ‖ / ‖y − ȳ‖), and checks residual whiteness and independence
from the input (``resid``).  ``compare`` and ``resid`` follow MATLAB: the model's
initial state is fitted to the data by least squares unless told otherwise (for ARX
the pre-sample outputs and inputs, so the first max(na, nb+nk−1) one-step residuals
vanish); a longer horizon fits the same number of values, so the k-step FIT tends
to the simulation FIT — see ``PolyModel.predict``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.linalg import toeplitz
from scipy.stats import chi2

from .data import IOData
from .fit import fit_percent
from .model import PolyModel

__all__ = ["fit_percent", "compare", "naive_fit", "resid", "ResidResult"]


def compare(
    data: IOData,
    *models_and_options,
    horizon: int | float | None = None,
    initial_condition: str | None = None,
) -> tuple[float, np.ndarray] | tuple[np.ndarray, np.ndarray]:
    """FIT % and ``horizon``-step predictions of one or several models on ``data`` (MATLAB's ``compare``).

    * ``compare(data, m)`` or ``compare(data, m, k)`` → ``(fit, yhat)``: a float and an
      array like ``data.y`` (the single-model form, unchanged).
    * ``compare(data, m1, m2, …)`` or ``compare(data, m1, m2, …, k)`` → ``(fits, yhats)``:
      arrays of shape (n_models,) and (n_models, N), in the order given — as MATLAB's
      ``compare(data, sys1, …, sysN, kstep)``, the horizon may trail the models.

    ``horizon`` (default 1; ``math.inf`` simulates) and ``initial_condition`` (default
    ``"estimate"``: each model's initial state fitted to the data by least squares, as
    MATLAB does) may also be given by keyword; positionally they follow the models in
    that order.
    """
    if not isinstance(data, IOData):
        raise TypeError(f"compare: data must be an IOData, got {type(data).__name__}")
    models, horizon, initial_condition = _compare_arguments(models_and_options, horizon, initial_condition)
    fits, yhats = [], []
    for model in models:
        if not math.isclose(data.Ts, model.Ts, rel_tol=1e-9):
            raise ValueError(
                f"compare: data {data.name or ''} has Ts = {data.Ts:g} s but {model.name or model.label} "
                f"has Ts = {model.Ts:g} s"
            )
        yhat = model.predict(data, horizon, initial_condition)
        fits.append(fit_percent(data.y, yhat))
        yhats.append(yhat)
    if len(models) == 1:
        return fits[0], yhats[0]
    return np.array(fits), np.vstack(yhats)


def naive_fit(data: IOData, horizon: int = 1) -> float:
    """FIT % of the naive predictor ŷ(t) = y(t − k): the baseline every k-step FIT must beat.

    At a short sampling period a slowly varying output is predicted well by its own
    last sample, so a one-step FIT of 90 % can mean a model adds nothing.  The first k
    samples have no past and are predicted by themselves (zero error), as an estimated
    initial state would; the FIT is over all N samples like :func:`compare`'s.
    """
    if not isinstance(data, IOData):
        raise TypeError(f"naive_fit: data must be an IOData, got {type(data).__name__}")
    if isinstance(horizon, (bool, np.bool_)) or not isinstance(horizon, (int, np.integer)) or not 1 <= horizon < data.N:
        raise ValueError(f"naive_fit: horizon must be an integer in [1, {data.N - 1}], got {horizon!r}")
    y = data.y
    return fit_percent(y, np.concatenate([y[:horizon], y[:-horizon]]))


def _compare_arguments(args: tuple, horizon, initial_condition) -> tuple[list[PolyModel], int | float, str]:
    """Split ``compare``'s positional arguments into models, then an optional horizon and initial condition."""
    models = []
    for arg in args:
        if not isinstance(arg, PolyModel):
            break
        models.append(arg)
    rest = list(args[len(models):])
    if not models:
        first = type(args[0]).__name__ if args else "nothing"
        raise TypeError(f"compare: expected one or more PolyModels after the data, got {first}")
    if rest and isinstance(rest[0], (int, float, np.integer, np.floating)) and not isinstance(rest[0], bool):
        if horizon is not None:
            raise TypeError("compare: horizon given both positionally and by keyword")
        horizon = rest.pop(0)
    if rest and isinstance(rest[0], str):
        if initial_condition is not None:
            raise TypeError("compare: initial_condition given both positionally and by keyword")
        initial_condition = rest.pop(0)
    if rest:
        raise TypeError(
            f"compare: after the models expected at most a horizon and an initial condition, got {rest[0]!r} "
            "(models must come first)"
        )
    return models, 1 if horizon is None else horizon, "estimate" if initial_condition is None else initial_condition


# ---------------------------------------------------------------------------- residual analysis
CONFIDENCE_Z = 2.58  # two-sided 99 % quantile of N(0, 1), as in MATLAB's resid
TEST_LEVEL = 0.01  # significance level of the whiteness and independence tests


def format_p(p: float) -> str:
    """A p-value as every maglev text prints it (console, run descriptions, cautions, report): three
    significant digits, so ``0.993`` and ``1e-06`` read alike wherever they appear."""
    return f"{float(p):.3g}"


@dataclass(frozen=True)
class ResidResult:
    """Residual analysis of one model on one data set (MATLAB's ``resid``).

    ``auto_lags`` = 0..M and ``auto_corr`` = r_e(τ) with r_e(0) = 1.
    ``cross_lags`` = −M..M and ``cross_corr`` = r_eu(τ) ≈ E e(t) u(t−τ) / (σ_e σ_u):
    positive lags pair the residual with *past* inputs (input leads residual; a peak
    there means unmodelled dynamics or a wrong delay), negative lags with *future*
    inputs (a peak there points to output feedback in the data).
    ``auto_band``/``cross_band`` are the half-widths of the 99 % bands.
    """

    e: np.ndarray
    auto_lags: np.ndarray
    auto_corr: np.ndarray
    auto_band: float
    cross_lags: np.ndarray
    cross_corr: np.ndarray
    cross_band: float
    whiteness_stat: float
    whiteness_dof: int
    whiteness_pvalue: float
    independence_stat: float
    independence_dof: int
    independence_pvalue: float
    auto_outside: float
    cross_outside: float

    @property
    def white(self) -> bool:
        """The whiteness test passes at the 1 % level."""
        return self.whiteness_pvalue >= TEST_LEVEL

    @property
    def independent(self) -> bool:
        """The residual–input independence test passes at the 1 % level."""
        return self.independence_pvalue >= TEST_LEVEL

    def to_dict(self) -> dict:
        """JSON-ready: correlations, bands and tests, without the residual sequence ``e``."""
        return {
            "auto_lags": self.auto_lags.tolist(), "auto_corr": self.auto_corr.tolist(),
            "auto_band": self.auto_band,
            "cross_lags": self.cross_lags.tolist(), "cross_corr": self.cross_corr.tolist(),
            "cross_band": self.cross_band,
            "whiteness_stat": self.whiteness_stat, "whiteness_dof": self.whiteness_dof,
            "whiteness_pvalue": self.whiteness_pvalue, "white": bool(self.white),
            "independence_stat": self.independence_stat, "independence_dof": self.independence_dof,
            "independence_pvalue": self.independence_pvalue, "independent": bool(self.independent),
            "auto_outside": self.auto_outside, "cross_outside": self.cross_outside,
        }

    @classmethod
    def from_dict(cls, d: dict) -> "ResidResult":
        """Inverse of :meth:`to_dict` (``e`` comes back empty)."""
        return cls(
            e=np.array([]), auto_lags=np.asarray(d["auto_lags"]), auto_corr=np.asarray(d["auto_corr"]),
            auto_band=float(d["auto_band"]), cross_lags=np.asarray(d["cross_lags"]),
            cross_corr=np.asarray(d["cross_corr"]), cross_band=float(d["cross_band"]),
            whiteness_stat=float(d["whiteness_stat"]), whiteness_dof=int(d["whiteness_dof"]),
            whiteness_pvalue=float(d["whiteness_pvalue"]), independence_stat=float(d["independence_stat"]),
            independence_dof=int(d["independence_dof"]), independence_pvalue=float(d["independence_pvalue"]),
            auto_outside=float(d["auto_outside"]), cross_outside=float(d["cross_outside"]))


def resid(
    data: IOData,
    model: PolyModel,
    lags: int = 25,
    initial_condition: str = "estimate",
) -> ResidResult:
    """Correlation tests of the one-step prediction errors of ``model`` on ``data``.

    Both signals have their means removed; covariances are the biased estimates
    R_xz(τ) = (1/N) Σ_t x(t) z(t−τ), normalised by √(R_x(0) R_z(0)).

    * Autocorrelation band (MATLAB): ±2.58/√N.
    * Cross-correlation band (MATLAB's resid): ±2.58·√(P/N) with
      P = Σ_{k=−M..M} r_e(k) r_u(k), the asymptotic variance of √N r_eu(τ) when e
      and u are independent but possibly coloured (Ljung 1999, §16.6).  A truncated
      P that comes out non-positive is replaced by 1 (its value for a white e).
    * Whiteness (Ljung §16.6): N Σ_{τ=1..M} r_e(τ)² ~ χ²(M) under white e.
    * Independence (Ljung's version with the input covariance, §16.6, over
      τ = −M..M): with r = [r_eu(−M) … r_eu(M)] and T the (2M+1)×(2M+1) Toeplitz
      matrix of the input autocorrelation r_u(0..2M), N rᵀ T⁻¹ r ~ χ²(2M+1) for a
      white e independent of u.  Unlike N Σ r_eu² it stays valid for a coloured
      input (the r_eu(τ) of neighbouring lags are then correlated).  A (numerically)
      singular T, e.g. for a sinusoidal input, uses the pseudo-inverse and its rank
      as the degrees of freedom.
    * ``auto_outside`` is the fraction of τ = 1..M with |r_e(τ)| above its band,
      ``cross_outside`` that of τ = −M..M for r_eu.
    """
    if not isinstance(data, IOData):
        raise TypeError(f"resid: data must be an IOData, got {type(data).__name__}")
    if not isinstance(model, PolyModel):
        raise TypeError(f"resid: model must be a PolyModel, got {type(model).__name__}")
    if not math.isclose(data.Ts, model.Ts, rel_tol=1e-9):
        raise ValueError(f"resid: data has Ts = {data.Ts:g} s but the model has Ts = {model.Ts:g} s")
    N = data.N
    if isinstance(lags, (bool, np.bool_)) or not isinstance(lags, (int, np.integer)) or not 1 <= lags < N // 2:
        raise ValueError(f"resid: lags must be an integer in [1, {N // 2 - 1}] for N = {N}, got {lags!r}")
    M = int(lags)
    e = model.residuals(data, initial_condition)
    ec = e - e.mean()
    uc = data.u - data.u.mean()
    if not np.any(ec):
        raise ValueError("resid: the residuals are identically zero; there is nothing to test")
    if not np.any(uc):
        raise ValueError("resid: input u is constant; the residual-input correlation is undefined")

    r_e = _correlation(ec, ec, range(M + 1))
    r_u = _correlation(uc, uc, range(2 * M + 1))
    cross_lags = np.arange(-M, M + 1)
    r_eu = _correlation(ec, uc, cross_lags)

    auto_band = CONFIDENCE_Z / math.sqrt(N)
    P = r_e[0] * r_u[0] + 2.0 * float(r_e[1:] @ r_u[1 : M + 1])
    cross_band = CONFIDENCE_Z * math.sqrt((P if P > 0 else 1.0) / N)

    whiteness = N * float(r_e[1:] @ r_e[1:])
    weights, _, cross_dof, _ = np.linalg.lstsq(toeplitz(r_u), r_eu, rcond=1e-10)
    independence = N * float(r_eu @ weights)
    return ResidResult(
        e=e,
        auto_lags=np.arange(M + 1),
        auto_corr=r_e,
        auto_band=auto_band,
        cross_lags=cross_lags,
        cross_corr=r_eu,
        cross_band=cross_band,
        whiteness_stat=whiteness,
        whiteness_dof=M,
        whiteness_pvalue=float(chi2.sf(whiteness, M)),
        independence_stat=independence,
        independence_dof=int(cross_dof),
        independence_pvalue=float(chi2.sf(independence, cross_dof)),
        auto_outside=float(np.mean(np.abs(r_e[1:]) > auto_band)),
        cross_outside=float(np.mean(np.abs(r_eu) > cross_band)),
    )


def _correlation(x: np.ndarray, z: np.ndarray, lags) -> np.ndarray:
    """r_xz(τ) = Σ_t x(t) z(t−τ) / √(Σ x² Σ z²) for each τ in ``lags`` (sums over valid t)."""
    N = x.size
    scale = math.sqrt(float(x @ x) * float(z @ z))
    out = np.empty(len(lags))
    for i, tau in enumerate(lags):
        out[i] = (x[tau:] @ z[: N - tau]) if tau >= 0 else (x[: N + tau] @ z[-tau:])
    return out / scale
