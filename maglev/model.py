"""The fitted polynomial model, MATLAB's ``idpoly``:  A(q) y = B(q)/F(q) u + C(q)/D(q) e.

A `PolyModel` carries its polynomials (arrays in q⁻¹; A, C, D, F monic, B with nk
leading zeros), the estimated parameter covariance and noise variance, and a
`FitReport` with the estimation diagnostics.  It predicts k steps ahead, simulates,
computes residuals, and converts to python-control transfer functions for Bode and
pole-zero work.  Estimation lives in :mod:`maglev.estimation`; this module only
evaluates a given model.
"""

from __future__ import annotations

import json
import math
from dataclasses import asdict, dataclass, field
from dataclasses import fields as dataclass_fields

import numpy as np
from scipy.signal import fftconvolve

from .data import IOData
from .fit import fit_percent
from .initial_state import INITIAL_CONDITIONS, fit_initial_state, fit_shifted_response
from .polynomials import filt, is_stable, polymul
from .structures import PolySpec
from .structures import get as get_structure



@dataclass(frozen=True)
class FitReport:
    """Estimation diagnostics, with MATLAB's definitions (see ``maglev.estimation``)."""

    method: str
    n_samples: int
    n_params: int
    n_initial: int
    loss: float
    fpe: float
    aic: float
    aicc: float
    bic: float
    naic: float
    fit_percent: float
    iterations: int
    termination: str
    initial_condition: str

    @classmethod
    def from_residuals(
        cls,
        e: np.ndarray,
        y: np.ndarray,
        n_params: int,
        n_initial: int,
        **info,
    ) -> "FitReport":
        """Compute loss and information criteria from estimation residuals.

        MATLAB's definitions: N = all samples of the record (``e`` has one entry per
        sample; residuals freed by estimated initial conditions are zero),
        V = Σe²/N, d = parameters + estimated initial values,
        FPE = V(1+d/N)/(1-d/N), AIC = N ln V + 2d + N(ln 2π + 1),
        AICc = AIC + 2d(d+1)/(N-d-1), BIC = N ln V + d ln N + N(ln 2π + 1),
        nAIC = ln V + 2d/N.
        """
        N = int(e.size)
        V = float(e @ e) / N
        d = n_params + n_initial
        logV = math.log(V) if V > 0 else -math.inf
        const = N * (math.log(2 * math.pi) + 1)
        aic = N * logV + 2 * d + const
        return cls(
            n_samples=N,
            n_params=n_params,
            n_initial=n_initial,
            loss=V,
            fpe=V * (1 + d / N) / (1 - d / N) if d < N else math.inf,
            aic=aic,
            aicc=aic + 2 * d * (d + 1) / (N - d - 1) if N - d - 1 > 0 else math.inf,
            bic=N * logV + d * math.log(N) + const,
            naic=logV + 2 * d / N,
            fit_percent=fit_percent(y, y - e),
            **info,
        )


CANCEL_TOL = 0.05  # |pole − zero| in the z-plane below which a pair counts as a near cancellation
MODEL_KEYS = {"structure", "orders", "Ts", "nk", "A", "B", "C", "D", "F", "noise_variance", "covariance",
              "report", "name"}


@dataclass(frozen=True, eq=False)
class PolyModel:
    """A(q) y(t) = B(q)/F(q) u(t) + C(q)/D(q) e(t), e white with variance ``noise_variance``.

    Parameters are ordered ``a1..ana, b(nk)..b(nk+nb-1), c1..cnc, d1..dnd, f1..fnf``
    (the order of ``parameters`` and of ``covariance``).
    """

    A: np.ndarray
    B: np.ndarray
    C: np.ndarray
    D: np.ndarray
    F: np.ndarray
    nk: int
    Ts: float
    structure: str = "pem"
    noise_variance: float = 1.0
    covariance: np.ndarray | None = None
    report: FitReport | None = None
    name: str | None = None
    meta: dict = field(default_factory=dict, compare=False)

    def __post_init__(self) -> None:
        for key in "ABCDF":
            p = _coefficients(getattr(self, key), key)
            if key != "B" and p[0] != 1.0:
                raise ValueError(f"PolyModel: {key} must be a monic coefficient array [1, ...], got {p.tolist()}")
            object.__setattr__(self, key, p)
        if not _is_int(self.nk) or self.nk < 0 or self.B.size < self.nk or np.any(self.B[: self.nk] != 0):
            raise ValueError(f"PolyModel: B must start with nk={self.nk!r} zeros (nk an integer >= 0), "
                             f"got B = {self.B.tolist()}")
        try:
            entry = get_structure(self.structure)
        except ValueError as exc:
            raise ValueError(f"PolyModel: {exc}") from None
        for key, letter in (("na", "A"), ("nc", "C"), ("nd", "D"), ("nf", "F")):
            if key not in entry.free and getattr(self, letter).size > 1:
                raise ValueError(f"PolyModel: a {self.structure} model has no {letter} polynomial "
                                 f"(orders {list(entry.orders)}), got {letter} = {getattr(self, letter).tolist()}")
        if isinstance(self.Ts, (bool, np.bool_)) or not isinstance(self.Ts, (int, float, np.number)) \
                or not math.isfinite(self.Ts) or self.Ts <= 0:
            raise ValueError(f"PolyModel: Ts must be a positive number of seconds, got {self.Ts!r}")
        if not math.isfinite(self.noise_variance) or self.noise_variance < 0:
            raise ValueError(f"PolyModel: noise_variance must be finite and >= 0, got {self.noise_variance!r}")
        if self.covariance is not None:
            cov = np.asarray(self.covariance, dtype=float)
            p = self.n_params
            if cov.shape != (p, p):
                raise ValueError(f"PolyModel: covariance must be {p} x {p} (one row per parameter "
                                 f"{self.parameter_names}), got shape {cov.shape}")
            if np.any(np.isnan(cov)):
                raise ValueError("PolyModel: covariance has NaN entries")
            object.__setattr__(self, "covariance", cov)

    def __eq__(self, other: object) -> bool:
        """Same polynomials, delay, Ts, structure, noise variance, covariance, report and name."""
        if not isinstance(other, PolyModel):
            return NotImplemented
        arrays = all(np.array_equal(getattr(self, k), getattr(other, k)) for k in "ABCDF")
        same_cov = (self.covariance is None) == (other.covariance is None) and (
            self.covariance is None or np.array_equal(self.covariance, other.covariance))
        return arrays and same_cov and (self.nk, self.Ts, self.structure, self.noise_variance, self.report,
                                        self.name) == (other.nk, other.Ts, other.structure, other.noise_variance,
                                                       other.report, other.name)

    __hash__ = None  # type: ignore[assignment]  (holds arrays)

    # ------------------------------------------------------------------ orders and parameters
    @property
    def na(self) -> int:
        return self.A.size - 1

    @property
    def nb(self) -> int:
        return self.B.size - self.nk

    @property
    def nc(self) -> int:
        return self.C.size - 1

    @property
    def nd(self) -> int:
        return self.D.size - 1

    @property
    def nf(self) -> int:
        return self.F.size - 1

    @property
    def spec(self) -> PolySpec:
        """The model's structure and orders: its parameter layout."""
        return PolySpec(self.structure, na=self.na, nb=self.nb, nc=self.nc, nd=self.nd, nf=self.nf, nk=self.nk)

    @property
    def orders(self) -> tuple[int, ...]:
        """Orders in MATLAB's order for the structure (e.g. ``[na nb nk]`` for ARX)."""
        return self.spec.orders

    @property
    def label(self) -> str:
        """MATLAB-like label, e.g. ``bj[2 2 2 2 1]``."""
        return self.spec.label

    @property
    def parameters(self) -> np.ndarray:
        """Free parameters in the documented order."""
        return np.concatenate([self.A[1:], self.B[self.nk :], self.C[1:], self.D[1:], self.F[1:]])

    @property
    def parameter_names(self) -> list[str]:
        names = [f"a{i}" for i in range(1, self.na + 1)]
        names += [f"b{self.nk + i}" for i in range(self.nb)]
        names += [f"c{i}" for i in range(1, self.nc + 1)]
        names += [f"d{i}" for i in range(1, self.nd + 1)]
        names += [f"f{i}" for i in range(1, self.nf + 1)]
        return names

    @property
    def n_params(self) -> int:
        return self.parameters.size

    @property
    def std_errors(self) -> np.ndarray | None:
        """One-sigma standard errors of ``parameters`` (from ``covariance``)."""
        if self.covariance is None:
            return None
        return np.sqrt(np.clip(np.diag(self.covariance), 0, None))

    # ------------------------------------------------------------------ transfer functions
    @property
    def G_polys(self) -> tuple[np.ndarray, np.ndarray]:
        """(numerator, denominator) of G = B/(A F) in q⁻¹."""
        return self.B, polymul(self.A, self.F)

    @property
    def H_polys(self) -> tuple[np.ndarray, np.ndarray]:
        """(numerator, denominator) of H = C/(A D) in q⁻¹."""
        return self.C, polymul(self.A, self.D)

    def poles(self) -> np.ndarray:
        """Discrete-time poles of G (roots of A·F in z)."""
        den = polymul(self.A, self.F)
        return np.roots(den) if den.size > 1 else np.array([], dtype=complex)

    def zeros(self) -> np.ndarray:
        """Finite discrete-time zeros of G other than the nk delays at the origin."""
        b = np.trim_zeros(self.B, "f")
        return np.roots(b) if b.size > 1 else np.array([], dtype=complex)

    def noise_zeros(self) -> np.ndarray:
        """Zeros of H (roots of C)."""
        return _roots(self.C)

    def near_cancellations(self, tol: float = CANCEL_TOL) -> list[tuple[str, complex, complex, float]]:
        """Pole-zero pairs closer than ``tol`` in the z-plane, in G (poles of A·F vs zeros of B) and
        H (A·D vs C): ``(which, pole, zero, |p − z|)``, one entry per conjugate pair.  A cancellation
        means an order higher than the data support."""
        out = []
        for which, zeros, poles in (("G", self.zeros(), self.poles()),
                                    ("H", self.noise_zeros(), _roots(polymul(self.A, self.D)))):
            for p in poles:
                for z in zeros:
                    d = abs(p - z)
                    if d < tol and (p.imag >= 0 or z.imag >= 0):
                        out.append((which, complex(p), complex(z), float(d)))
        return out

    def dcgain(self) -> float:
        """Static gain G(1)."""
        num, den = self.G_polys
        return float(num.sum() / den.sum())

    def freqresp(self, w: np.ndarray) -> np.ndarray:
        """G(e^{jωTs}) at angular frequencies ``w`` in rad/s."""
        z_inv = np.exp(-1j * np.asarray(w, dtype=float) * self.Ts)
        num, den = self.G_polys
        return np.polyval(num[::-1], z_inv) / np.polyval(den[::-1], z_inv)

    def to_control(self):
        """(G, H) as ``control.TransferFunction`` in z with ``dt = Ts``."""
        import control as ct

        label = self.name or self.label
        return (
            _tf_z(*self.G_polys, self.Ts, f"G {label}", ct),
            _tf_z(*self.H_polys, self.Ts, f"H {label}", ct),
        )

    # ------------------------------------------------------------------ signals
    def simulate(
        self,
        u: np.ndarray | IOData,
        noise: np.ndarray | None = None,
    ) -> np.ndarray:
        """Output G u (+ H e if ``noise`` e is given), from zero initial state."""
        u = u.u if isinstance(u, IOData) else np.asarray(u, dtype=float)
        y = filt(*self.G_polys, u)
        if noise is not None:
            noise = np.asarray(noise, dtype=float)
            if noise.shape != u.shape:
                raise ValueError(f"simulate: noise has shape {noise.shape}, expected {u.shape}")
            y = y + filt(*self.H_polys, noise)
        return y

    def predict(
        self,
        data: IOData,
        horizon: int | float = 1,
        initial_condition: str = "zero",
    ) -> np.ndarray:
        """k-step-ahead prediction ŷ(t|t−k) of ``data.y``; a horizon of ``data.N`` or more (or ``inf``) simulates.

        The k-step prediction error is H̄_k ε: the one-step errors ε = D/C (A y − B/F u)
        filtered by the first k impulse-response terms of H = C/(A D) (Ljung 1999, §3.2),
        computed in O(N) memory for any k (a horizon of N samples or more is simulation).

        ``initial_condition="estimate"`` (or ``"backcast"``/``"auto"``) fits the model's
        initial state by least squares of the k-step errors, as MATLAB's ``compare`` and
        ``predict`` do: the n = max(deg A·F·D, deg B·D, deg C·F) pre-sample values of the
        difference equation A F D y = B D u + C F e, whatever k (for ARX the pre-sample
        outputs and inputs, n = max(na, nb+nk−1)).  So the first n one-step errors vanish,
        and the k-step errors tend to the simulation errors as k grows: the true model's
        k-step FIT falls with k to its simulation FIT (a model far from the plant may dip
        below its simulation FIT at intermediate horizons).
        Simulation fits the free response of G = B/(A F) to the simulation error (for ARX
        the na pre-sample outputs and nb+nk−1 pre-sample inputs).
        """
        if not isinstance(data, IOData):
            raise TypeError(f"predict: data must be an IOData, got {type(data).__name__}")
        if not math.isclose(data.Ts, self.Ts, rel_tol=1e-9):
            raise ValueError(f"predict: data {data.name or ''} has Ts = {data.Ts:g} s but {self.name or self.label} "
                             f"has Ts = {self.Ts:g} s; expected the same sampling period")
        k = _check_horizon(horizon)
        if initial_condition not in INITIAL_CONDITIONS:
            raise ValueError(f"predict: initial_condition must be one of {INITIAL_CONDITIONS}, "
                             f"got {initial_condition!r}")
        if k >= data.N:
            return self._simulation(data, initial_condition)
        return data.y - self._k_step_errors(data, int(k), initial_condition)

    def _simulation(self, data: IOData, initial_condition: str) -> np.ndarray:
        """G u, plus the free response of G that best explains the data unless ``initial_condition="zero"``."""
        num, den = self.G_polys
        self._check_predictor_stable(math.inf, initial_condition, den)
        ysim = filt(num, den, data.u)
        if initial_condition == "zero":
            return ysim
        correction, _ = fit_initial_state(data.y - ysim, [(num, den)], initial_condition)
        return ysim + correction

    def _k_step_errors(self, data: IOData, k: int, initial_condition: str) -> np.ndarray:
        """y − ŷ(t|t−k) = H̄_k ε, with the n pre-sample values of the model fitted unless ``"zero"``."""
        CF, AD = polymul(self.C, self.F), polymul(self.A, self.D)
        self._check_predictor_stable(k, initial_condition, CF)
        N = data.N
        eps = filt(AD, self.C, data.y) - filt(polymul(self.D, self.B), CF, data.u)
        h = filt(self.C, AD, _impulse(k))  # H̄_k: the first k impulse-response terms of H
        errors = _truncated_convolution(h, eps)
        if initial_condition == "zero":
            return errors
        # A pre-sample value s_i enters C F ε like an impulse at sample i: ε gets −q⁻ⁱ/(C F) δ
        n = max(AD.size + self.F.size - 2, self.D.size + self.B.size - 2, CF.size - 1)
        response = _truncated_convolution(h, filt(np.ones(1), CF, _impulse(N)))
        return errors - fit_shifted_response(errors, response, n)

    def _check_predictor_stable(self, horizon, initial_condition: str, *dens: np.ndarray) -> None:
        """Refuse predictions that would diverge: an unstable C·F (k-step), or an unstable
        simulation whose initial state is to be fitted."""
        simulation = _check_horizon(horizon) == math.inf
        if simulation and initial_condition == "zero":
            return  # simulating an unstable G from rest is well defined (it diverges)
        for den in dens:
            if den.size > 1 and not is_stable(den):
                radius = float(np.max(np.abs(np.roots(den))))
                what = "A(q)·F(q)" if simulation else "C(q)·F(q)"
                raise ValueError(
                    f"{self.name or self.label}: {what} has a root outside the unit circle "
                    f"(|root| = {radius:.4g}), so its {'simulation' if simulation else f'{horizon}-step predictor'} "
                    "is unstable; reflect the roots inside (maglev.polynomials.stabilize) or re-estimate"
                )

    def residuals(self, data: IOData, initial_condition: str = "zero") -> np.ndarray:
        """One-step prediction errors e = D/C (A y - B/F u)."""
        return data.y - self.predict(data, 1, initial_condition)

    # ------------------------------------------------------------------ (de)serialisation
    def to_dict(self) -> dict:
        """JSON-ready dictionary; :meth:`from_dict` restores an identical model."""
        return {
            "structure": self.structure,
            "orders": list(self.orders),
            "Ts": self.Ts,
            "nk": self.nk,
            "A": self.A.tolist(),
            "B": self.B.tolist(),
            "C": self.C.tolist(),
            "D": self.D.tolist(),
            "F": self.F.tolist(),
            "noise_variance": self.noise_variance,
            "covariance": None if self.covariance is None else self.covariance.tolist(),
            "report": None if self.report is None else asdict(self.report),
            "name": self.name,
        }

    @classmethod
    def from_dict(cls, d: dict) -> "PolyModel":
        """The model :meth:`to_dict` wrote; a dictionary that cannot be one is refused naming the key.

        Beyond the checks of the constructor: every key is known and of the right type,
        ``orders`` (if given) matches the polynomials, and C, D and F are stable (an
        estimated model's always are: its predictor filters by them).
        """
        if not isinstance(d, dict):
            raise ValueError(f"PolyModel.from_dict: expected a dict, got {type(d).__name__}")
        unknown = sorted(set(d) - MODEL_KEYS)
        missing = sorted({"A", "B", "C", "D", "F", "nk", "Ts"} - set(d))
        if unknown or missing:
            raise ValueError(f"PolyModel.from_dict: unknown key(s) {unknown}, missing key(s) {missing}; "
                             f"expected {sorted(MODEL_KEYS)}")
        report = d.get("report")
        if report is not None:
            fields = {f.name for f in dataclass_fields(FitReport)}
            if not isinstance(report, dict) or set(report) != fields:
                raise ValueError(f"PolyModel.from_dict: 'report' must be a dict with keys {sorted(fields)}")
        for key in ("nk",):
            if not _is_int(d[key]):
                raise ValueError(f"PolyModel.from_dict: {key!r} must be an integer, got {d[key]!r}")
        for key in ("Ts", "noise_variance"):
            if key in d and (isinstance(d[key], bool) or not isinstance(d[key], (int, float))):
                raise ValueError(f"PolyModel.from_dict: {key!r} must be a number, got {d[key]!r}")
        if d.get("name") is not None and not isinstance(d["name"], str):
            raise ValueError(f"PolyModel.from_dict: 'name' must be a string or null, got {d['name']!r}")
        cov = d.get("covariance")
        model = cls(
            A=_coefficients(d["A"], "A"), B=_coefficients(d["B"], "B"), C=_coefficients(d["C"], "C"),
            D=_coefficients(d["D"], "D"), F=_coefficients(d["F"], "F"),
            nk=int(d["nk"]), Ts=float(d["Ts"]),
            structure=d.get("structure", "pem"),
            noise_variance=float(d.get("noise_variance", 1.0)),
            covariance=None if cov is None else _matrix(cov, "covariance"),
            report=None if report is None else FitReport(**report),
            name=d.get("name"),
        )
        if "orders" in d and list(d["orders"]) != list(model.orders):
            raise ValueError(f"PolyModel.from_dict: 'orders' {d['orders']} do not match the polynomials "
                             f"({model.label})")
        for letter in "CDF":
            p = getattr(model, letter)
            if p.size > 1 and not is_stable(p):
                raise ValueError(f"PolyModel.from_dict: {letter} has a root outside the unit circle "
                                 f"(|root| = {np.max(np.abs(np.roots(p))):.4g}); an estimated model's never does")
        return model

    def to_json(self) -> str:
        return json.dumps(self.to_dict(), indent=1)

    @classmethod
    def from_json(cls, text: str) -> "PolyModel":
        """The model :meth:`to_json` wrote; text that is no JSON, or nested too deep to read, is refused in one line."""
        if not isinstance(text, (str, bytes, bytearray)):
            raise ValueError(f"PolyModel.from_json: expected the JSON text of a model (str), got {type(text).__name__}")
        try:
            content = json.loads(text)
        except json.JSONDecodeError as exc:
            raise ValueError(f"PolyModel.from_json: not JSON ({exc.msg} at line {exc.lineno} column {exc.colno}); "
                             "expected the text PolyModel.to_json writes") from None
        except RecursionError:
            raise ValueError("PolyModel.from_json: the JSON is nested too deeply to be a model; "
                             "expected the text PolyModel.to_json writes") from None
        return cls.from_dict(content)

    # ------------------------------------------------------------------ display
    def summary(self) -> str:
        """Human-readable description: polynomials with standard errors and the fit report."""
        lines = [f"{self.label}  Ts = {self.Ts:g} s" + (f"  ({self.name})" if self.name else "")]
        lines.append("  A(q) y(t) = B(q)/F(q) u(t) + C(q)/D(q) e(t)")
        sd = self.std_errors
        names = self.parameter_names
        for letter in "ABCDF":
            p = getattr(self, letter)
            if letter != "B" and p.size == 1:
                continue
            terms = []
            for i, c in enumerate(p):
                if letter == "B" and i < self.nk:
                    continue
                term = f"{c:+.5g}" + (f" q^-{i}" if i else "")
                key = f"{letter.lower()}{i}"
                if sd is not None and key in names:
                    term += f" (±{sd[names.index(key)]:.2g})"
                terms.append(term)
            lines.append(f"  {letter}(q) = " + " ".join(terms))
        lines.append(f"  noise variance = {self.noise_variance:.4g}")
        if self.report is not None:
            r = self.report
            lines.append(
                f"  fit to estimation data = {r.fit_percent:.2f} %  (one-step), "
                f"MSE = {r.loss:.4g}, FPE = {r.fpe:.4g}, AIC = {r.aic:.6g}, BIC = {r.bic:.6g}"
            )
            lines.append(
                f"  {r.method}: {r.iterations} iterations, {r.termination}; "
                f"N = {r.n_samples}, d = {r.n_params} + {r.n_initial} initial values "
                f"(initial_condition = {r.initial_condition})"
            )
        return "\n".join(lines)

    def __repr__(self) -> str:
        return f"PolyModel({self.label}, Ts={self.Ts:g})"


def _roots(p: np.ndarray) -> np.ndarray:
    """Roots in z of a polynomial in q⁻¹ (leading zeros dropped; none for a constant)."""
    p = np.trim_zeros(np.asarray(p, dtype=float), "f")
    return np.roots(p) if p.size > 1 else np.array([], dtype=complex)


def _is_int(x) -> bool:
    return isinstance(x, (int, np.integer)) and not isinstance(x, (bool, np.bool_))


def _coefficients(values, key: str) -> np.ndarray:
    """A polynomial as a non-empty, finite 1-D float array, or a ValueError naming it."""
    try:
        if values is None or isinstance(values, (str, bytes)):
            raise TypeError
        p = np.atleast_1d(np.asarray(values, dtype=float))
    except (TypeError, ValueError):
        raise ValueError(f"PolyModel: {key} must be a list of numbers, got {values!r}") from None
    if p.ndim != 1 or p.size == 0:
        raise ValueError(f"PolyModel: {key} must be a non-empty 1-D coefficient array, got shape {p.shape}")
    if not np.all(np.isfinite(p)):
        raise ValueError(f"PolyModel: {key} has non-finite coefficients: {p.tolist()}")
    return p


def _matrix(values, key: str) -> np.ndarray:
    try:
        return np.asarray(values, dtype=float)
    except (TypeError, ValueError):
        raise ValueError(f"PolyModel: {key} must be a matrix of numbers, got {values!r}") from None


def _check_horizon(horizon) -> int | float:
    """A prediction horizon as an int ≥ 1 or ``inf`` (``None`` too is simulation), or a ValueError naming it."""
    if horizon is None:
        return math.inf
    if isinstance(horizon, (bool, np.bool_)) or not isinstance(horizon, (int, float, np.integer, np.floating)) \
            or not (horizon == math.inf or (float(horizon).is_integer() and horizon >= 1)):
        raise ValueError(f"prediction horizon must be a positive integer or inf, got {horizon!r}")
    return math.inf if horizon == math.inf else int(horizon)


def _impulse(n: int) -> np.ndarray:
    """δ: one followed by n − 1 zeros."""
    out = np.zeros(n)
    out[0] = 1.0
    return out


def _truncated_convolution(h: np.ndarray, x: np.ndarray) -> np.ndarray:
    """(h * x)(t) for t < len(x): direct for short ``h``, by FFT for long ones (O(N log N), O(N) memory)."""
    if h.size == 1:
        return h[0] * x
    return fftconvolve(x, h)[: x.size] if h.size > 64 else np.convolve(x, h)[: x.size]


def _tf_z(num: np.ndarray, den: np.ndarray, Ts: float, name: str, ct):
    """Transfer function in z from coefficient arrays in q⁻¹ (pad both to one length)."""
    n = max(num.size, den.size)
    num_z = np.concatenate([num, np.zeros(n - num.size)])
    den_z = np.concatenate([den, np.zeros(n - den.size)])
    return ct.tf(num_z, den_z, Ts, name=name)
