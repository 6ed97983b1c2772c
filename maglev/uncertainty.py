"""Confidence bounds of an identified model from its parameter covariance (MATLAB's ``showConfidence``).

An estimated `PolyModel` carries the covariance P of its parameters θ (asymptotically
θ̂ ~ N(θ₀, P)).  Every response the lab looks at — the frequency response G(e^{jωTs}),
the poles and zeros of G, the step response — is a smooth function h(θ), so to first
order h(θ̂) ~ N(h(θ₀), J P Jᵀ) with J = ∂h/∂θ at θ̂.  This is the Gauss approximation
formula MATLAB documents for ``translatecov`` and uses for the standard deviations that
``bode`` (``sdmag``, ``sdphase``), ``step`` (``ysd``) and ``iopzplot`` + ``showConfidence``
display.  All derivatives here are analytic (the tests check them against finite
differences); only the transfer function G = B/(A F) is covered, so the C and D
columns of J are zero.

How wide a bound is: MATLAB's ``showConfidence(h, sd)`` draws ``sd`` standard deviations
(default 1) and its documentation equates 99 % with 2.58 SD.  Here every function takes
either ``sd`` (MATLAB's number, default 1 when neither is given) or ``level``; a level
is turned into the multiplier with the χ² quantile of the bound's dimension
(:func:`multiplier`): k = √χ²₁(level) = the two-sided normal quantile (2.576 at 99 %)
for the pointwise magnitude, phase and step bounds and for real poles/zeros (a
segment on the real axis), and k = √χ²₂(level) (3.035 at 99 %) for the ellipse of a
complex pole or zero, whose location is two-dimensional.  MATLAB's 2.58 SD ellipse
therefore covers a complex root with 96.4 %, not 99 %.

The step response is propagated the same way (first order), not by Monte-Carlo draws
from N(θ̂, P): the rig's poles sit within a few 1e-3 of z = 1, so a fair share of such
draws is unstable and their diverging step responses would make the band describe
models the data rule out; a first-order band is also deterministic and costs three
filters instead of hundreds of simulations.

Functions compute response objects (frozen dataclasses, python-control's split) that
:mod:`maglev.plots` draws; nothing here imports matplotlib.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.stats import chi2

from .model import PolyModel
from .polynomials import filt, polymul

MAX_STEP_SAMPLES = 20_000
SETTLING_TIME_CONSTANTS = 6  # default step horizon: the slowest pole decays to e⁻⁶ ≈ 0.25 %


def multiplier(level: float | None = None, sd: float | None = None, dims: int = 1) -> tuple[float, float]:
    """(k, coverage): the number of standard deviations k and the probability it covers in ``dims`` dimensions.

    Give ``level`` (e.g. 0.99 → k = √χ²_dims(0.99)) or ``sd`` (k = sd, MATLAB's
    ``showConfidence`` argument; its coverage is χ²_dims(sd²)); neither means MATLAB's
    default of 1 SD.
    """
    if dims not in (1, 2):
        raise ValueError(f"multiplier: dims must be 1 or 2, got {dims!r}")
    if level is not None and sd is not None:
        raise ValueError(f"give either level or sd, not both (got level={level!r}, sd={sd!r})")
    if level is not None:
        if not (isinstance(level, (int, float, np.floating)) and 0.0 < level < 1.0):
            raise ValueError(f"level must be a probability strictly between 0 and 1, got {level!r}")
        return math.sqrt(float(chi2.ppf(level, dims))), float(level)
    sd = 1.0 if sd is None else sd
    if not (isinstance(sd, (int, float, np.floating)) and math.isfinite(sd) and sd > 0):
        raise ValueError(f"sd must be a positive number of standard deviations, got {sd!r}")
    return float(sd), float(chi2.cdf(float(sd) ** 2, dims))


# ---------------------------------------------------------------------------- frequency response
@dataclass(frozen=True)
class FrequencyBounds:
    """G(e^{jωTs}) with pointwise bounds: MATLAB's ``[mag, phase, w, sdmag, sdphase] = bode(sys, w)``.

    ``sd_magnitude`` is the standard deviation of |G| (absolute units, as MATLAB's
    ``sdmag``), ``sd_phase`` that of the phase in degrees (``sdphase``).  The bounds are
    ``k`` standard deviations either side; ``level`` is the pointwise two-sided coverage
    of each of them.  A lower magnitude bound that would go below 0 is 0.
    """

    w: np.ndarray
    response: np.ndarray
    sd_magnitude: np.ndarray
    sd_phase: np.ndarray
    k: float
    level: float
    name: str | None = None

    @property
    def magnitude(self) -> np.ndarray:
        return np.abs(self.response)

    @property
    def phase(self) -> np.ndarray:
        """Unwrapped phase in degrees."""
        return np.degrees(np.unwrap(np.angle(self.response)))

    @property
    def magnitude_lower(self) -> np.ndarray:
        return np.clip(self.magnitude - self.k * self.sd_magnitude, 0.0, None)

    @property
    def magnitude_upper(self) -> np.ndarray:
        return self.magnitude + self.k * self.sd_magnitude

    @property
    def phase_lower(self) -> np.ndarray:
        return self.phase - self.k * self.sd_phase

    @property
    def phase_upper(self) -> np.ndarray:
        return self.phase + self.k * self.sd_phase


def freqresp_jacobian(model: PolyModel, w: np.ndarray) -> np.ndarray:
    """∂G(e^{jωTs})/∂θ, complex, shape (len(w), n_params), θ in ``model.parameters`` order.

    With x = e^{-jωTs}: ∂G/∂a_k = −x^k G/A, ∂G/∂b_k = x^k/(A F), ∂G/∂f_k = −x^k G/F.
    """
    _check_model(model, "freqresp_jacobian")
    w = _frequencies(w, "freqresp_jacobian")
    x = np.exp(-1j * w * model.Ts)
    A, B, F = (np.polyval(p[::-1], x) for p in (model.A, model.B, model.F))
    G = B / (A * F)
    powers = x[:, None] ** np.arange(max(model.na, model.nk + model.nb, model.nf) + 1)
    jac = np.zeros((w.size, model.n_params), dtype=complex)
    a, b, _, _, f = _offsets(model)
    jac[:, a : a + model.na] = -powers[:, 1 : model.na + 1] * (G / A)[:, None]
    jac[:, b : b + model.nb] = powers[:, model.nk : model.nk + model.nb] / (A * F)[:, None]
    jac[:, f : f + model.nf] = -powers[:, 1 : model.nf + 1] * (G / F)[:, None]
    return jac


def frequency_bounds(
    model: PolyModel, w: np.ndarray, level: float | None = None, sd: float | None = None
) -> FrequencyBounds:
    """Magnitude and phase of G at ``w`` (rad/s) with first-order bounds (see the module docstring).

    d|G| = Re(Ḡ dG)/|G| and d∠G = Im(dG/G), each propagated through P; ``level`` or
    ``sd`` as in :func:`multiplier` with one dimension (MATLAB: 99 % ↔ 2.58 SD).
    """
    k, coverage = multiplier(level, sd, dims=1)
    P = _covariance(model, "frequency_bounds")
    w = _frequencies(w, "frequency_bounds")
    jac = freqresp_jacobian(model, w)
    G = model.freqresp(w)
    d_mag = np.real(np.conj(G)[:, None] * jac) / np.abs(G)[:, None]
    d_phase = np.imag(jac / G[:, None])
    return FrequencyBounds(
        w=w, response=G,
        sd_magnitude=np.sqrt(_quadratic(d_mag, P)),
        sd_phase=np.degrees(np.sqrt(_quadratic(d_phase, P))),
        k=k, level=coverage, name=model.name or model.label,
    )


# ---------------------------------------------------------------------------- poles and zeros
@dataclass(frozen=True)
class RootRegions:
    """Poles or zeros of G with the first-order covariance of each location.

    ``covariance[i]`` is the 2×2 covariance of (Re r_i, Im r_i).  A complex root's
    region is the ellipse δᵀ C⁻¹ δ ≤ k², with k = ``k_complex``; a real root stays real
    under small perturbations (its Im variance is 0), so its region is the segment
    |δ| ≤ ``k_real``·σ_Re on the real axis.  ``level_complex``/``level_real`` are their
    coverages.  At a multiple root ∂r/∂θ is infinite: first-order theory does not
    apply, and the region is reported as infinite.
    """

    kind: str
    roots: np.ndarray
    covariance: np.ndarray
    k_complex: float
    k_real: float
    level_complex: float
    level_real: float
    name: str | None = None

    @property
    def is_real(self) -> np.ndarray:
        return self.roots.imag == 0.0

    def scale(self, i: int) -> float:
        """The multiplier k that applies to root ``i``."""
        return self.k_real if self.is_real[i] else self.k_complex

    def contains(self, i: int, point: complex) -> bool:
        """Is ``point`` inside the region of root ``i``?"""
        delta = complex(point) - complex(self.roots[i])
        C = self.covariance[i]
        if not np.all(np.isfinite(C)):
            return True
        if self.is_real[i]:
            return delta.imag == 0.0 and abs(delta.real) <= self.k_real * math.sqrt(max(C[0, 0], 0.0))
        d = np.array([delta.real, delta.imag])
        return float(d @ np.linalg.solve(C, d)) <= self.k_complex**2

    def outline(self, i: int, n_points: int = 60) -> np.ndarray:
        """Boundary of root ``i``'s region as complex points (closed ellipse, or the segment's two ends)."""
        C = self.covariance[i]
        if not np.all(np.isfinite(C)):
            return np.array([], dtype=complex)
        r = complex(self.roots[i])
        if self.is_real[i]:
            half = self.k_real * math.sqrt(max(C[0, 0], 0.0))  # a variance rounded below 0: a point
            return np.array([r - half, r + half])
        vals, vecs = np.linalg.eigh(C)
        t = np.linspace(0.0, 2.0 * np.pi, n_points)
        unit = np.stack([np.cos(t), np.sin(t)])
        pts = vecs @ (np.sqrt(np.clip(vals, 0.0, None))[:, None] * unit) * self.k_complex
        return r + pts[0] + 1j * pts[1]


def root_regions(
    model: PolyModel, kind: str = "poles", level: float | None = None, sd: float | None = None
) -> RootRegions:
    """Confidence regions of G's poles (roots of A·F) or zeros (roots of B without its nk delays).

    For a root r of p(z) = Σ c_j z^{n−j}, ∂r/∂θ = −Σ_j (∂c_j/∂θ) r^{n−j} / p′(r); the
    2×2 covariance of (Re r, Im r) follows from P.  ``level``: χ²₂ quantile for complex
    roots, χ²₁ for real ones; ``sd``: MATLAB's number of standard deviations for both.
    """
    if kind not in ("poles", "zeros"):
        raise ValueError(f"root_regions: kind must be 'poles' or 'zeros', got {kind!r}")
    P = _covariance(model, "root_regions")
    k_complex, level_complex = multiplier(level, sd, dims=2)
    k_real, level_real = multiplier(level, sd, dims=1)
    coeffs, d_coeffs = _root_polynomial(model, kind)
    roots = model.poles() if kind == "poles" else model.zeros()
    roots = np.asarray(roots, dtype=complex)
    n = coeffs.size - 1
    if roots.size:
        vander = roots[:, None] ** np.arange(n, -1, -1)
        slope = np.polyval(np.polyder(coeffs), roots)
        with np.errstate(divide="ignore", invalid="ignore"):
            jac = -(vander @ d_coeffs) / slope[:, None]
        stacked = np.concatenate([jac.real, jac.imag])  # (2m, p): Re rows, then Im rows
        full = stacked @ P @ stacked.T
        m = roots.size
        cov = np.empty((m, 2, 2))
        cov[:, 0, 0] = np.diag(full)[:m]
        cov[:, 1, 1] = np.diag(full)[m:]
        cov[:, 0, 1] = cov[:, 1, 0] = np.diag(full[:m, m:])
        cov[~np.isfinite(cov).all(axis=(1, 2))] = np.inf
    else:
        cov = np.zeros((0, 2, 2))
    return RootRegions(kind=kind, roots=roots, covariance=cov, k_complex=k_complex, k_real=k_real,
                       level_complex=level_complex, level_real=level_real, name=model.name or model.label)


def _root_polynomial(model: PolyModel, kind: str) -> tuple[np.ndarray, np.ndarray]:
    """Coefficients c (highest power of z first) whose roots are the poles/zeros, and ∂c/∂θ."""
    a, b, _, _, f = _offsets(model)
    if kind == "poles":
        coeffs = polymul(model.A, model.F)
        d = np.zeros((coeffs.size, model.n_params))
        for k in range(1, model.na + 1):  # ∂(A F)/∂a_k = q^-k F
            d[k : k + model.F.size, a + k - 1] = model.F
        for k in range(1, model.nf + 1):
            d[k : k + model.A.size, f + k - 1] = model.A
        return coeffs, d
    lead = model.nk + int(np.argmax(model.B[model.nk :] != 0)) if np.any(model.B) else model.B.size
    coeffs = model.B[lead:]  # the same coefficients model.zeros() takes the roots of
    d = np.zeros((coeffs.size, model.n_params))
    for j in range(coeffs.size):
        d[j, b + lead - model.nk + j] = 1.0
    return coeffs, d


# ---------------------------------------------------------------------------- step response
@dataclass(frozen=True)
class StepBounds:
    """Unit-step response of G from rest (MATLAB's ``[y, t, ~, ysd] = step(sys)``) with pointwise bounds."""

    t: np.ndarray
    y: np.ndarray
    sd: np.ndarray
    k: float
    level: float
    name: str | None = None

    @property
    def lower(self) -> np.ndarray:
        return self.y - self.k * self.sd

    @property
    def upper(self) -> np.ndarray:
        return self.y + self.k * self.sd


def step_jacobian(model: PolyModel, n: int) -> tuple[np.ndarray, np.ndarray]:
    """(s, ∂s/∂θ): the first ``n`` samples of the unit-step response and its Jacobian (n × n_params).

    With s = B/(A F)·1: ∂s/∂a_k = −q^-k s/A, ∂s/∂b_k = q^-k 1/(A F), ∂s/∂f_k = −q^-k s/F.
    """
    _check_model(model, "step_jacobian")
    step = np.ones(n)
    s = model.simulate(step)
    jac = np.zeros((n, model.n_params))
    a, b, _, _, f = _offsets(model)
    one = np.ones(1)
    s_over_a = filt(one, model.A, s)
    s_over_f = filt(one, model.F, s)
    step_over_af = filt(one, polymul(model.A, model.F), step)
    for k in range(1, model.na + 1):
        jac[k:, a + k - 1] = -s_over_a[: n - k]
    for j in range(model.nb):
        lag = model.nk + j
        jac[lag:, b + j] = step_over_af[: n - lag]
    for k in range(1, model.nf + 1):
        jac[k:, f + k - 1] = -s_over_f[: n - k]
    return s, jac


def step_bounds(
    model: PolyModel, n: int | None = None, level: float | None = None, sd: float | None = None
) -> StepBounds:
    """Unit-step response over ``n`` samples (t = 0 … (n−1)Ts) with first-order pointwise bounds.

    ``n`` defaults to ``SETTLING_TIME_CONSTANTS`` time constants of the slowest pole
    (at most ``MAX_STEP_SAMPLES``); an unstable model needs an explicit ``n``.
    """
    k, coverage = multiplier(level, sd, dims=1)
    P = _covariance(model, "step_bounds")
    n = step_length(model) if n is None else n
    if isinstance(n, (bool, np.bool_)) or not isinstance(n, (int, np.integer)) or n < 2:
        raise ValueError(f"step_bounds: n must be an integer number of samples >= 2, got {n!r}")
    s, jac = step_jacobian(model, int(n))
    return StepBounds(t=np.arange(n) * model.Ts, y=s, sd=np.sqrt(_quadratic(jac, P)), k=k, level=coverage,
                      name=model.name or model.label)


def step_length(model: PolyModel) -> int:
    """Default step horizon: ``SETTLING_TIME_CONSTANTS`` time constants of the slowest pole (20 … ``MAX_STEP_SAMPLES``)."""
    _check_model(model, "step_length")
    poles = model.poles()
    radius = float(np.max(np.abs(poles))) if poles.size else 0.0
    if radius >= 1.0:
        raise ValueError(
            f"step_bounds: {model.name or model.label} has a pole with |z| = {radius:.4g} >= 1; "
            "its step response does not settle, so pass the number of samples n"
        )
    settle = SETTLING_TIME_CONSTANTS / -math.log(radius) if radius > 0 else 0.0
    return int(min(MAX_STEP_SAMPLES, max(math.ceil(settle) + model.nk + model.nb, 20)))


# ---------------------------------------------------------------------------- helpers
def _check_model(model, caller: str) -> None:
    if not isinstance(model, PolyModel):
        raise TypeError(f"{caller}: model must be a PolyModel, got {type(model).__name__}")


def _covariance(model: PolyModel, caller: str) -> np.ndarray:
    _check_model(model, caller)
    P = model.covariance
    name = model.name or model.label
    if P is None:
        raise ValueError(f"{caller}: {name} has no parameter covariance (estimate it from data for bounds)")
    if P.shape != (model.n_params, model.n_params):
        raise ValueError(f"{caller}: {name} has a covariance of shape {P.shape}, expected "
                         f"({model.n_params}, {model.n_params}) for its parameters {model.parameter_names}")
    if not np.all(np.isfinite(P)):
        raise ValueError(f"{caller}: {name}'s parameter covariance is not finite (singular estimation problem)")
    return P


def _frequencies(w, caller: str) -> np.ndarray:
    w = np.atleast_1d(np.asarray(w, dtype=float))
    if w.ndim != 1 or w.size == 0 or not np.all(np.isfinite(w)) or np.any(w < 0):
        raise ValueError(f"{caller}: w must be a non-empty 1-D array of frequencies >= 0 in rad/s")
    return w


def _offsets(model: PolyModel) -> tuple[int, int, int, int, int]:
    """Start of the a, b, c, d, f blocks in ``model.parameters``."""
    a = 0
    b = a + model.na
    c = b + model.nb
    d = c + model.nc
    f = d + model.nd
    return a, b, c, d, f


def _quadratic(jac: np.ndarray, P: np.ndarray) -> np.ndarray:
    """diag(J P Jᵀ) for real J (rows), clipped at 0 against rounding."""
    return np.clip(np.einsum("ip,pq,iq->i", jac, P, jac), 0.0, None)
