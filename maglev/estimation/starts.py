"""Starting points for the prediction-error estimators, and the search that minimises from them.

Prediction-error losses of OE, BJ and (less often) ARMAX models have local minima, and
on real data the minimum a start leads to depends on the start.  Each structure gets
one principal starting point, cheap and consistent when the structure describes the
data:

* ARMAX: pseudo-linear regression on the innovations of a long ARX model
  (Hannan–Rissanen);
* OE and BJ: the simplified refined instrumental-variable estimate of B/F (SRIV:
  instruments from the noise-free auxiliary model, data prefiltered by 1/F), and for
  BJ a Hannan–Rissanen ARMA model of its residual;
* the general structure: A and B from ARX, a Hannan–Rissanen model of its residual;

plus, when given, the caller's warm start (``init``), e.g. the model one order lower
padded with zeros: the search then ends at or below its loss, so over a sweep of
nested orders the loss never rises.  With a warm start only these two are tried.

The search minimises from the strongest start (lowest loss) to convergence.  If its
prediction errors then look white and uncorrelated with past inputs (Ljung's tests at
99 %), no other linear model predicts markedly better and the search stops: on data the
structure describes, that is one minimisation.

Otherwise further starts are tried, strongest first: plain ARX (for OE/BJ its input
path with a Hannan–Rissanen noise model), BJ holding an ARX model (F = D = A, C = 1),
the refined IV estimate for BJ (prefilter D/(C F), noise model refitted each round),
for the general structure a BJ model whose common poles become A, and for OE and BJ
the nested lower-order models (one order lower in one polynomial, which with zero
initial conditions are this model with one coefficient zero) padded with zeros.  Each
lower model is searched as a plain call searches it, except that its own lower models
are only minimised quickly: from their own starts but the refined-IV one (its two rounds
of refined IV were a tenth of a BJ call's filtering, and leaving them out changed none of
the BJ benchmark's 21 losses, 9 simulated and 12 real), every run cut short once it stays
above the best minimum of the model they are nested in after ``CHECK_PATIENCE``
iterations and is not falling fast enough to get below it; the lower model's own runs
after its first get that shorter patience too (on the BJ grids 1..3 of the nested-order
tests no nested pair then ends further above its lower model; two of binary_signal_2's
81 models end 0.1 % higher, the others where they ended before).  That second level found the
basin BJ [2 2 2 2 1] ends in on white_noise_2's first half, which BJ [2 3 2 2 1] and
[2 2 3 2 1] missed by 0.29 % and 0.25 % when a lower model's search stopped at its own
starts.  Each further run is abandoned once it joins the converged minimum already found,
or when after a few iterations it is still above the best loss reached so far and no
longer falling fast enough to get below it.  That loss counts whether its run converged or
stalled in a flat valley, where it is reached all the same (counting converged runs only,
the default sweep's nine BJ models ended at the same losses, within 2e-8, or higher, and
filtered 13 % more samples; 45 % more on binary_a025's orders 3 and 5).  One call fits
each model, start and run once, however many higher models a lower model is nested in.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass, field, replace

import numpy as np
from scipy.linalg import cho_solve, toeplitz
from scipy.linalg.lapack import dpocon, dpotrf
from scipy.stats import chi2

from .least_squares import lagged_iv, lagged_lstsq
from ..model import PolyModel
from ..polynomials import filt, polymul, stabilize
from .prediction_error import CONVERGED, PATIENCE, Evaluation, Minimum, evaluate, minimise, project
from ..structures import PolySpec

ONE = np.ones(1)
START_RATIO = 10.0  # once a run has converged, starts this much worse than the strongest are skipped
WHITENESS_LEVEL = 0.99  # residual tests at this level decide whether more starts are worth trying
IV_ROUNDS = 20  # refined-IV rounds at most; they stop when F moves less than IV_SETTLED (relative)
IV_SETTLED = 1e-3
CHECK_PATIENCE = 2  # iterations a quickly minimised lower model's run gets before it must near the bound
CUT_SHORT = ("abandoned", "joined")  # runs ended by another run's minimum, not by their own convergence


# ---------------------------------------------------------------------------- search
def best_minimum(
    spec: PolySpec,
    starts: list[np.ndarray],
    y: np.ndarray,
    u: np.ndarray,
    fit_states: bool,
    max_iterations: int,
    tolerance: float | None,
    widen: bool = False,
    memo: dict | None = None,
    evaluated: list[Evaluation] | None = None,
) -> Minimum:
    """The lowest minimum found from ``starts``, and with ``widen`` from the further starts
    the module docstring describes, built only when the evidence asks for them (``memo``:
    the one `starts` filled, so that lower-order models reuse what they share; ``evaluated``:
    the caller's evaluations at ``starts``, projected, with these ``fit_states``)."""
    search = Search(y, u, fit_states, max_iterations, tolerance, built=memo if memo is not None else {})
    for theta, ev in zip(starts, evaluated or []):
        search.remember(spec, theta, ev)
    return search.run(spec, starts, widen)


@dataclass
class Search:
    """One estimator call's search: its data and settings, and the lower-order models it has
    already minimised (quickly, and searched in full), so that each is fitted once however
    many higher models it is nested in."""

    y: np.ndarray
    u: np.ndarray
    fit_states: bool
    max_iterations: int
    tolerance: float | None
    runs: dict[tuple[PolySpec, bytes], Minimum] = field(default_factory=dict)
    evaluations: dict[tuple[PolySpec, bytes], Evaluation] = field(default_factory=dict)
    built: dict[tuple, object] = field(default_factory=dict)  # starting points, and SRIV's (B, F)
    quick: dict[PolySpec, Minimum] = field(default_factory=dict)
    searched: dict[PolySpec, Minimum] = field(default_factory=dict)

    def run(self, spec: PolySpec, starts: list[np.ndarray], widen: bool, bound: float | None = None,
            full_lowers: bool = True, patience: int = PATIENCE) -> Minimum:
        """Minimise from ``starts`` strongest first; with ``widen`` go on as the module docstring says.

        ``bound``: runs still above this loss after ``patience`` iterations, and not falling
        fast enough to get below it, are abandoned (a lower-order model matters only where
        it gets below the best minimum of the model it is nested in).  ``full_lowers``:
        search the lower models as plain calls do; else (a lower model searched for a
        higher one) only minimise them quickly, which bounds the work to two levels.
        """
        best: Minimum | None = None
        best_start = np.inf

        def descend(pending: list[Evaluation]) -> None:
            nonlocal best, best_start
            while pending:
                start = pending.pop(int(np.argmin([ev.loss for ev in pending])))
                converged = best is not None and best.termination.startswith(CONVERGED)
                if converged and start.loss > START_RATIO * best_start:
                    continue
                key = (spec, start.theta.tobytes())
                result = self.runs.get(key)
                if result is None:  # a stalled best's loss is reached too: a run staying above it is not finished
                    limits = [x for x in (best.evaluation.loss if best is not None else None, bound) if x is not None]
                    result = minimise(
                        spec, start.theta, self.y, self.u, self.fit_states, self.max_iterations, self.tolerance,
                        abandon_above=min(limits) if limits else None,
                        known_minimum=best.evaluation.theta if converged else None,
                        evaluated=start, patience=patience,
                    )
                    if not result.termination.startswith(CUT_SHORT):
                        self.runs[key] = result
                if best is None:
                    best_start = start.loss
                if best is None or result.evaluation.loss < best.evaluation.loss * (1 - 1e-9):
                    best = result

        pending = [self._evaluate(spec, t) for t in starts]
        descend([pending.pop(int(np.argmin([ev.loss for ev in pending])))])
        if widen and best.termination.startswith(CONVERGED) and explains(best.evaluation.e, self.u):
            return best
        descend(pending)
        if not widen:
            return best
        # the other starts, and the lower-order models padded with zeros: searched as plain calls
        # search them (at the top), or minimised quickly (for a lower model searched for a higher one)
        pending = [self._evaluate(spec, t) for t in self._others(spec)]
        for lower in lower_neighbours(spec):
            fitted = self._searched(lower) if full_lowers else self._quick(lower, self._limit(bound, best))
            pending.append(self._evaluate(spec, _padded(spec, lower, fitted)))
        descend(pending)
        return best

    @staticmethod
    def _limit(bound: float | None, best: Minimum) -> float:
        return best.evaluation.loss if bound is None else min(bound, best.evaluation.loss)

    def remember(self, spec: PolySpec, theta: np.ndarray, ev: Evaluation) -> None:
        """Keep ``ev``, the caller's evaluation at the projected ``theta``, so that `_evaluate` need not repeat it."""
        self.evaluations[spec, theta.tobytes()] = ev

    def _evaluate(self, spec: PolySpec, theta: np.ndarray) -> Evaluation:
        key = (spec, theta.tobytes())
        if key not in self.evaluations:
            self.remember(spec, theta, evaluate(spec, project(spec, theta), self.y, self.u, self.fit_states, False))
        return self.evaluations[key]

    def _starts(self, spec: PolySpec) -> list[np.ndarray]:
        if (spec, "principal") not in self.built:
            self.built[spec, "principal"] = starts(spec, self.y, self.u, self.built)
        return self.built[spec, "principal"]

    def _others(self, spec: PolySpec, refined: bool = True) -> list[np.ndarray]:
        if (spec, "others", refined) not in self.built:
            self.built[spec, "others", refined] = other_starts(spec, self.y, self.u, self.max_iterations,
                                                               self.tolerance, refined)
        return self.built[spec, "others", refined]

    def _quick(self, spec: PolySpec, bound: float) -> Minimum:
        """``spec`` minimised from its principal and other starts but the refined-IV one, runs that stay above
        ``bound`` cut short."""
        if spec not in self.quick:
            candidates = self._starts(spec) + self._others(spec, refined=False)
            self.quick[spec] = self.run(spec, candidates, False, bound, patience=CHECK_PATIENCE)
        return self.quick[spec]

    def _searched(self, spec: PolySpec) -> Minimum:
        """``spec`` searched as a plain call searches it, but its own lower models only minimised
        quickly and its further runs abandoned after ``CHECK_PATIENCE`` iterations (not ``PATIENCE``)."""
        if spec not in self.searched:
            self.searched[spec] = self.run(spec, self._starts(spec), True, full_lowers=False, patience=CHECK_PATIENCE)
        return self.searched[spec]


def explains(e: np.ndarray, u: np.ndarray, lags: int = 25) -> bool:
    """Whether ``e`` passes Ljung's whiteness and input-independence tests at WHITENESS_LEVEL.

    Whiteness: N Σ_{τ=1..M} r_e(τ)² ~ χ²(M).  Independence of the past inputs, valid
    for a coloured input: with r = [r_eu(0) … r_eu(M)] and T the Toeplitz matrix of
    the input's autocorrelation, N rᵀ T⁻¹ r ~ χ²(M+1).
    """
    N = e.size
    M = int(min(lags, max(N // 20, 1)))
    ec, uc = e - e.mean(), u - u.mean()
    tail = np.zeros(M)
    r_e = np.correlate(np.concatenate((ec, tail)), ec, "valid")  # Σ_t e(t+τ) e(t), τ = 0..M
    r_u = np.correlate(np.concatenate((uc, tail)), uc, "valid")
    r_eu = np.correlate(np.concatenate((ec, tail)), uc, "valid")  # Σ_t e(t+τ) u(t)
    if r_e[0] == 0 or r_u[0] == 0:
        return r_e[0] == 0
    r_eu = r_eu / np.sqrt(r_e[0] * r_u[0])
    r_e, r_u = r_e[1:] / r_e[0], r_u / r_u[0]
    weights = _toeplitz_solve(r_u, r_eu)
    white, independent = _chi2_bounds(M)
    return N * float(r_e @ r_e) <= white and N * float(r_eu @ weights) <= independent


def _toeplitz_solve(r: np.ndarray, b: np.ndarray, rcond: float = 1e-10) -> np.ndarray:
    """x with T x = b for the autocorrelation Toeplitz matrix T of ``r`` (positive semidefinite):
    by Cholesky when LAPACK's estimate of T's reciprocal condition number is well above
    ``rcond`` (no singular value would be cut), else the minimum-norm least-squares solution
    with that ``rcond`` (a periodic input's T is singular)."""
    T = toeplitz(r)
    upper, info = dpotrf(T, lower=0)
    if info == 0 and dpocon(upper, float(np.abs(T).sum(axis=0).max()))[0] > 1e3 * rcond:
        return cho_solve((upper, False), b, check_finite=False)
    return np.linalg.lstsq(T, b, rcond=rcond)[0]


@functools.lru_cache(maxsize=64)
def _chi2_bounds(lags: int) -> tuple[float, float]:
    return float(chi2.ppf(WHITENESS_LEVEL, lags)), float(chi2.ppf(WHITENESS_LEVEL, lags + 1))


# ---------------------------------------------------------------------------- warm start
def nested_theta(spec: PolySpec, init) -> np.ndarray:
    """Parameter vector of ``spec`` from a warm start: a parameter vector of that length, or
    a `PolyModel` whose polynomials fit inside the requested orders (padded with zeros).

    Structures without A take G = B/(A F) and H = C/(A D) into F and D, so an ARX or
    ARMAX model can start an OE or BJ search.
    """
    if not isinstance(init, PolyModel):
        theta = np.asarray(init, dtype=float)
        if theta.ndim != 1 or theta.size != spec.n_params:
            raise ValueError(
                f"{spec.label}: init must be a PolyModel or a vector of its {spec.n_params} parameters "
                f"[a b c d f], got shape {theta.shape}"
            )
        if not np.all(np.isfinite(theta)):
            raise ValueError(f"{spec.label}: init has non-finite parameters")
        return theta
    A, B, C, D, F = init.A, init.B, init.C, init.D, init.F
    if spec.na == 0:
        A, F, D = ONE, polymul(init.A, init.F), polymul(init.A, init.D)
    polys = dict(A=A, B=B, C=C, D=D, F=F)
    for name, p in polys.items():
        order = getattr(spec, f"n{name.lower()}")
        if name == "B":
            delays = np.flatnonzero(np.asarray(p))
            if delays.size and (delays[0] < spec.nk or delays[-1] >= spec.nk + order):
                raise ValueError(
                    f"{spec.label}: init {init.label} has B coefficients at delays {delays[0]}…{delays[-1]}, "
                    f"outside {spec.label}'s {spec.nk}…{spec.nk + order - 1}"
                )
            continue
        terms = np.flatnonzero(np.asarray(p)[1:])
        degree = int(terms[-1]) + 1 if terms.size else 0
        if degree > order:
            raise ValueError(
                f"{spec.label}: init {init.label} has {name} of degree {degree}"
                f"{' (A folded into F and D)' if spec.na == 0 and init.na else ''}; {spec.label} allows {order}"
            )
    return spec.theta(**polys)


# ---------------------------------------------------------------------------- starting points
def starts(spec: PolySpec, y: np.ndarray, u: np.ndarray, memo: dict | None = None) -> list[np.ndarray]:
    """The principal starting parameter vector(s) for ``spec`` (see the module docstring); ``memo``
    keeps the refined-IV input path per (nb, nf, nk), shared by models that differ in C or D only."""
    na, nb, nc, nd, nf, nk = spec.na, spec.nb, spec.nc, spec.nd, spec.nf, spec.nk
    if nf == 0 and nd == 0:  # ARMAX (or ARX-like pem): pseudo-linear regression
        return [_pseudo_linear(spec, y, u) if nc else spec.theta(*ls_arx(y, u, na, nb, nk))]
    if na == 0:  # OE / BJ: refined IV for the input path, Hannan–Rissanen for the noise
        memo = {} if memo is None else memo
        if ("sriv", nb, nf, nk) not in memo:
            memo["sriv", nb, nf, nk] = refined_iv(y, u, nb, nf, nk)
        B, F = memo["sriv", nb, nf, nk]
        return [spec.theta(None, B, *hannan_rissanen(y - filt(B, F, u), nc, nd), F)]
    # general: A from ARX, F starts at 1, noise from the ARX residual
    A, B = ls_arx(y, u, na, nb, nk)
    C, D = hannan_rissanen(filt(A, ONE, y) - filt(B, ONE, u), nc, nd)
    return [spec.theta(A, B, C, D, None)]


def other_starts(spec: PolySpec, y, u, max_iterations: int, tolerance, refined: bool = True) -> list[np.ndarray]:
    """The starting points tried when the strongest one leaves structure in the residuals
    (the nested lower-order models aside, which `Search` fits itself); without the refined-IV
    one unless ``refined``."""
    na, nb, nc, nd, nf, nk = spec.na, spec.nb, spec.nc, spec.nd, spec.nf, spec.nk
    if nf == 0 and nd == 0:  # ARMAX: the plain ARX model
        return [spec.theta(*ls_arx(y, u, na, nb, nk))] if nc else []
    if na:  # general: a BJ model with A's poles in F and D, split afterwards
        return [_general_from_bj(spec, y, u, max_iterations, tolerance)]
    B, F = _arx_input_path(y, u, nb, nf, nk)
    C, D = hannan_rissanen(y - filt(B, F, u), nc, nd)
    out = [spec.theta(None, B, C, D, F)]
    if nd:  # BJ holding an ARX model: F = D = A_arx, C = 1 (its loss is the ARX loss)
        A, B_arx = ls_arx(y, u, min(nf, nd), nb, nk)
        A = stabilize(A)
        out.append(spec.theta(None, B_arx, None, A, A))
    if refined and nf and nc + nd:  # refined IV for BJ (Young's RIV), from the ARX input path and its noise model
        for _ in range(2):
            B, F = refined_iv(y, u, nb, nf, nk, prefilter=(D, C), start=(B, F))
            C, D = hannan_rissanen(y - filt(B, F, u), nc, nd)
        out.append(spec.theta(None, B, C, D, F))
    return out


def lower_neighbours(spec: PolySpec) -> list[PolySpec]:
    """The OE/BJ models one order lower in one polynomial (nb stays >= 1): with zero initial
    conditions each is ``spec`` with one coefficient zero, so ``spec``'s minimum is at or
    below theirs.  None for ARMAX and the general structure."""
    if spec.na or (spec.nf == 0 and spec.nd == 0):
        return []
    return [replace(spec, **{key: getattr(spec, key) - 1}) for key in ("nb", "nc", "nd", "nf")
            if getattr(spec, key) > (key == "nb")]


def _padded(spec: PolySpec, lower: PolySpec, fitted: Minimum) -> np.ndarray:
    """``lower``'s minimum as a parameter vector of ``spec`` (the extra coefficient zero)."""
    return spec.theta(*lower.polys(fitted.evaluation.theta))


def ls_arx(y: np.ndarray, u: np.ndarray, na: int, nb: int, nk: int) -> tuple[np.ndarray, np.ndarray]:
    """Plain ARX A y = B u + e by least squares on the fully measured rows: (A, B)."""
    first = max(na, nb + nk - 1, 0)
    theta = lagged_lstsq(y, [(y, range(1, na + 1), -1.0), (u, range(nk, nk + nb), 1.0)], first)
    return np.concatenate((ONE, theta[:na])), np.concatenate((np.zeros(nk), theta[na:]))


def high_order(n_params: int, N: int) -> int:
    """Order of the long AR/ARX models behind the Hannan–Rissanen starts."""
    return int(min(max(3 * n_params, 10), 40, max(N // 50, 2)))


def _pseudo_linear(spec: PolySpec, y, u) -> np.ndarray:
    """ARMAX start: innovations ê from a long ARX model, then A, B, C by least squares on ê's lags."""
    na, nb, nc, nk = spec.na, spec.nb, spec.nc, spec.nk
    nh = high_order(na + nb + nc, y.size)
    A, B = ls_arx(y, u, nh, max(nb, nh), nk)
    e = filt(A, ONE, y) - filt(B, ONE, u)
    first = nh + max(na, nb + nk, nc)
    theta = lagged_lstsq(y, [(y, range(1, na + 1), -1.0), (u, range(nk, nk + nb), 1.0), (e, range(1, nc + 1), 1.0)],
                         first)
    return spec.theta(np.concatenate((ONE, theta[:na])), np.concatenate((np.zeros(nk), theta[na : na + nb])),
                      stabilize(np.concatenate((ONE, theta[na + nb :]))))


def _arx_input_path(y, u, nb, nf, nk) -> tuple[np.ndarray, np.ndarray]:
    A, B = ls_arx(y, u, nf, nb, nk)
    return B, stabilize(A)


def refined_iv(y, u, nb: int, nf: int, nk: int, prefilter=(ONE, ONE), start=None) -> tuple[np.ndarray, np.ndarray]:
    """B/F by simplified refined instrumental variables (Young's SRIV), from ``start`` = (B, F)
    or the ARX estimate.

    Each round prefilters y and u by L/F (L = ``prefilter`` as (num, den), 1 for SRIV)
    and solves F y_f = B u_f by IV, the instruments being the lagged output of the
    auxiliary model x = B/F u (noise-free, hence uncorrelated with the noise).  The
    estimate is consistent whatever the noise colour, unlike least squares.
    """
    B, F = start if start is not None else _arx_input_path(y, u, nb, nf, nk)
    if nf == 0:
        return B, ONE
    first = max(nf, nb + nk - 1)
    lags_f, lags_b = range(1, nf + 1), range(nk, nk + nb)
    for _ in range(IV_ROUNDS):
        num, den = prefilter[0], polymul(prefilter[1], F)
        yf, uf = filt(num, den, y), filt(num, den, u)
        xf = filt(polymul(num, B), polymul(den, F), u)
        theta = lagged_iv(yf, [(yf, lags_f, -1.0), (uf, lags_b, 1.0)], [(xf, lags_f, -1.0), (uf, lags_b, 1.0)], first)
        F_new = stabilize(np.concatenate((ONE, theta[:nf])))
        B = np.concatenate((np.zeros(nk), theta[nf:]))
        settled = np.linalg.norm(F_new - F) <= IV_SETTLED * np.linalg.norm(F)
        F = F_new
        if settled:
            break
    return B, F


def hannan_rissanen(v: np.ndarray, nc: int, nd: int) -> tuple[np.ndarray, np.ndarray]:
    """ARMA start D v = C e: a long AR model for the innovations, then least squares for C and D."""
    if nc == 0 and nd == 0:
        return ONE, ONE
    n_ar = high_order(nc + nd, v.size)
    Dar, _ = ls_arx(v, v, n_ar, 0, 1)
    e = filt(Dar, ONE, v)
    theta = lagged_lstsq(v, [(v, range(1, nd + 1), -1.0), (e, range(1, nc + 1), 1.0)], n_ar + max(nc, nd))
    return stabilize(np.concatenate((ONE, theta[nd:]))), stabilize(np.concatenate((ONE, theta[:nd])))


def _general_from_bj(spec: PolySpec, y, u, max_iterations, tolerance) -> np.ndarray:
    """Start for A y = B/F u + C/D e with A, F or D free: fit the BJ model with
    F' = A F and D' = A D, then give A the na poles that F' and D' share most closely."""
    wide = PolySpec("pem", nb=spec.nb, nc=spec.nc, nd=spec.nd + spec.na, nf=spec.nf + spec.na, nk=spec.nk)
    fitted = best_minimum(wide, starts(wide, y, u), y, u, False, max_iterations, tolerance)
    _, B, C, Dw, Fw = wide.polys(fitted.evaluation.theta)
    rf, rd = list(np.roots(Fw)), list(np.roots(Dw))
    common = []
    for _ in range(spec.na):
        i, j = min(((i, j) for i in range(len(rf)) for j in range(len(rd))),
                   key=lambda ij: abs(rf[ij[0]] - rd[ij[1]]))
        common.append((rf.pop(i) + rd.pop(j)) / 2)
    A, F, D = (np.real(np.poly(r)) if len(r) else ONE for r in (common, rf, rd))
    return spec.theta(A, B, C, D, F)
