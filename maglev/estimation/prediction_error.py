"""Prediction-error minimisation for A y = B/F u + C/D e (Gauss–Newton / Levenberg–Marquardt).

The prediction error is e = D/C (A y − B/F u).  Its derivative with respect to each
coefficient is the same few filtered signals shifted in time, so one Jacobian costs
at most five ``lfilter`` calls regardless of the order (four for BJ: the evaluation
filters v by 1/C and applies D as a short convolution, which leaves v/C at hand):

    ∂e/∂a_i =  q⁻ⁱ D/C y          ∂e/∂b_j = −q^-(nk+j) D/(C F) u
    ∂e/∂c_i = −q⁻ⁱ e / C          ∂e/∂d_i =  q⁻ⁱ v / C   (v = A y − B/F u)
    ∂e/∂f_i =  q⁻ⁱ D/(C F) w      (w = B/F u)

Each iteration takes the triangular factor of the Jacobian (through its Gram matrix,
or a QR factorisation when it is ill-conditioned) and solves the damped Gauss–Newton
step on the small triangular system, so retries with a larger damping cost nothing
extra; the Jacobian is written straight into the buffer that is factored.  C, D and F
are kept stable by reflecting roots that leave the unit circle, and roots on its
boundary that a step would push out are held there while the other coefficients
move.  With ``initial_condition="estimate"`` the initial state (the
polynomial z of the zero-input response z/(C F) δ) is fitted by least squares at
every evaluation and the Jacobian is projected on the complement of the state
responses (variable projection, Kaufman's form), whose derivatives are exact.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from scipy.linalg.lapack import dgeqp3, dgeqrf, dorgqr

from ..polynomials import MAX_RADIUS, filt, free_response_window, polymul, roots_within, stabilize
from ..structures import PolySpec
from ..threads import single_threaded_blas

MAX_RETRIES = 10  # damping grows ×2, ×4, ×8 … per failed try: past 1e5 × diag(JᵀJ) after ten
NEGLIGIBLE = 1e3  # expected improvements below 1e3 × tolerance count as converged at a stall
PATIENCE = 8  # iterations a secondary start gets before it must beat the best minimum
STALL = 5  # iterations that together gain less than the tolerance end the search
SAME_MINIMUM = 1e-3  # relative parameter distance at which two runs share a minimum
GRAM_CONDITION = 1e4  # Jacobians better conditioned than this are factored through their Gram matrix
NEAR_BOUNDARY = 0.999  # roots this close to the unit circle are held there when a step pushes them out
ONE = np.ones(1)


@dataclass
class Evaluation:
    """Prediction errors (and optionally their Jacobian) at one parameter vector.

    ``signals`` keeps what the Jacobian is built from (the polynomials, w = B/F u,
    v = A y − w, v/C, the initial-state response and the state basis), so that an
    accepted trial point needs no second filtering pass.
    """

    theta: np.ndarray
    e: np.ndarray
    loss: float
    jac: np.ndarray | None = None
    n_initial: int = 0
    signals: tuple | None = field(default=None, repr=False)


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
    polys = spec.polys(theta)
    A, B, C, D, F = polys
    w = filt(B, F, u) if spec.nb else np.zeros_like(u)
    v = (filt(A, ONE, y) if spec.na else y) - w
    vc = filt(ONE, C, v)  # v/C, which the Jacobian's d columns are
    e = filt(D, ONE, vc)  # D/C v, the numerator D applied as a short convolution
    ev = Evaluation(theta, e, float(e @ e) / e.size, None, 0, (polys, w, v, vc, None, np.zeros((0, 0))))
    if fit_states:
        ev = with_fitted_states(spec, ev)
    if jacobian:
        ev.jac = np.empty((y.size, spec.n_params), order="F")
        fill_jacobian(spec, ev, y, u, ev.jac)
    return ev


def with_fitted_states(spec: PolySpec, ev: Evaluation) -> Evaluation:
    """``ev`` (evaluated with zero initial states) with the initial states fitted by least
    squares: its prediction errors minus their projection on the state responses, so that
    deciding whether to fit them costs no second filtering pass."""
    polys, w, v, vc, _, _ = ev.signals
    _, _, C, _, F = polys
    basis = orthonormal_basis(state_responses(spec, C, F, ev.e.size))
    m = basis.shape[0]
    if not basis.size:
        return ev
    s = np.zeros_like(ev.e)
    s[:m] = -basis @ (basis.T @ ev.e[:m])  # least-squares initial-state response
    e = ev.e + s
    return Evaluation(ev.theta, e, float(e @ e) / e.size, None, basis.shape[1], (polys, w, v, vc, s, basis))


def orthonormal_basis(phi: np.ndarray, rcond: float = 1e-10) -> np.ndarray:
    """Orthonormal columns spanning the numerical column space of ``phi`` (pivoted QR: LAPACK's dgeqp3
    and dorgqr, as ``scipy.linalg.qr(phi, mode="economic", pivoting=True)`` calls them, without its
    argument checks and workspace queries, a quarter of its time on an evaluation's few columns)."""
    if phi.size == 0:
        return phi
    factored, _, tau, _, info = dgeqp3(np.array(phi, order="F"))
    k = min(phi.shape)
    q, _, info_q = dorgqr(factored[:, :k], tau[:k])
    if info or info_q:
        raise np.linalg.LinAlgError(f"QR factorisation failed (LAPACK dgeqp3/dorgqr info = {info}/{info_q})")
    diag = np.abs(np.diag(factored[:k]))
    rank = int(np.sum(diag > rcond * diag[0])) if diag[0] > 0 else 0
    return q[:, :rank]


def state_responses(spec: PolySpec, C: np.ndarray, F: np.ndarray, n: int) -> np.ndarray:
    """Free responses of the prediction-error filter, over their transient window.

    Multiplying out, C F e = D A F y − D B u: one difference equation whose
    zero-input responses are z(q)/(C F) δ for polynomials z of degree < k.  The
    columns are the impulse response of 1/(C F) delayed by 0 … k−1 samples.
    """
    P = polymul(C, F)
    k = max(P.size, spec.na + spec.nd + spec.nf + 1, spec.nd + spec.nb + spec.nk) - 1
    if k == 0:
        return np.zeros((0, 0))
    m = free_response_window(k, P, n)
    impulse = np.zeros(m)
    impulse[0] = 1.0
    h = filt(np.ones(1), P, impulse)
    phi = np.zeros((m, k))
    for i in range(min(k, m)):
        phi[i:, i] = h[: m - i]
    return phi


def fill_jacobian(spec: PolySpec, ev: Evaluation, y: np.ndarray, u: np.ndarray, out: np.ndarray) -> None:
    """Write ∂e/∂θ at ``ev`` into the N × p array ``out`` (columns in the order a, b, c, d, f).

    ``out`` may be the leading columns of the Fortran-ordered buffer that LAPACK then
    factors in place, so the Jacobian is never copied.  ``ev.e`` includes the
    initial-state response ``s`` = z/(C F) δ when states are fitted; holding z fixed,
    ∂s/∂c_i = −q⁻ⁱ s/C (already in the c columns, which use the total e) and
    ∂s/∂f_i = −q⁻ⁱ s/F.  With fitted states the columns are then projected on the
    complement of the state responses (variable projection).
    """
    (A, B, C, D, F), w, v, vc, s, basis = ev.signals
    N = y.size
    col = 0

    def shifted(x: np.ndarray, lags) -> None:
        nonlocal col
        for lag in lags:
            out[:lag, col] = 0.0
            out[lag:, col] = x[: N - lag]
            col += 1

    CF = polymul(C, F)
    if spec.na:
        shifted(filt(D, C, y), range(1, spec.na + 1))
    if spec.nb:
        shifted(-filt(D, CF, u), range(spec.nk, spec.nk + spec.nb))
    if spec.nc:
        shifted(-filt(ONE, C, ev.e), range(1, spec.nc + 1))
    if spec.nd:
        shifted(vc, range(1, spec.nd + 1))
    if spec.nf:
        df = filt(D, CF, w)
        if s is not None:
            df -= filt(ONE, F, s)
        shifted(df, range(1, spec.nf + 1))
    if basis.size:
        m = basis.shape[0]
        out[:m] -= basis @ (basis.T @ out[:m])


@dataclass
class Minimum:
    """Result of one minimisation run.

    ``r_factor``: the triangular factor of the Jacobian at the minimum when the run
    factored it there, else None (`r_factor` computes it): a search runs many
    minimisations and needs the factor of the one it returns only.
    """

    evaluation: Evaluation
    iterations: int
    termination: str
    r_factor: np.ndarray | None


@single_threaded_blas
def minimise(
    spec: PolySpec,
    theta0: np.ndarray,
    y: np.ndarray,
    u: np.ndarray,
    fit_states: bool = False,
    max_iterations: int = 100,
    tolerance: float | None = None,
    abandon_above: float | None = None,
    known_minimum: np.ndarray | None = None,
    evaluated: Evaluation | None = None,
    patience: int = PATIENCE,
) -> Minimum:
    """Levenberg–Marquardt from ``theta0`` until the expected relative improvement < ``tolerance``.

    The default tolerance is ``1e-3 · d / N``: the loss of a fitted model fluctuates
    by about d/N relative between data sets, so improvements a thousand times
    smaller than that change nothing a user can see.  The search also ends when an
    undamped step gains less than that (converged), or ``STALL`` damped steps together
    do (stalled).  When a step would push a root
    of C, D or F out of the unit circle, the step is taken with those roots held
    where they are (on the stability boundary) and the other parameters free, so the
    search goes on along the boundary instead of stalling against the reflection.
    For secondary starting points: with ``abandon_above`` (a loss another start reached)
    the run stops after ``patience`` iterations if its loss is still above that value and
    no longer falling fast enough to get below it, and with ``known_minimum`` (another
    start's converged minimum) it stops as soon as it reaches that parameter vector (within
    ``SAME_MINIMUM`` relative distance), since it would only repeat that run's work.  Both
    are decided before the next iteration's Jacobian is built, which they would not use.
    ``evaluated``: the evaluation at ``theta0`` (already projected), if the caller has it.
    """
    N, p = y.size, spec.n_params
    if tolerance is None:
        tolerance = max(1e-3 * p / N, 1e-12)
    buffer = np.empty((N, p + 1), order="F")  # [J e], factored in place by LAPACK
    if evaluated is None or not np.array_equal(evaluated.theta, theta0):
        evaluated = evaluate(spec, project(spec, theta0), y, u, fit_states, jacobian=False)
    current = evaluated
    lam, nu = 0.0, 2.0  # Nielsen's damping update; lam = 0 is a plain Gauss-Newton step
    termination = "maximum number of iterations reached"
    previous_loss = np.inf
    history = [current.loss]  # losses of the accepted points
    r = None
    iterations = 0
    for iterations in range(1, max_iterations + 1):
        if abandon_above is not None and iterations > patience and current.loss > abandon_above:
            # still above the best minimum: stop unless the last step gained enough to
            # get below it within as many steps again
            if (previous_loss - current.loss) * patience < current.loss - abandon_above:
                termination = "abandoned: stays above the best minimum from another start"
                iterations, r = iterations - 1, None
                break
        if known_minimum is not None and np.linalg.norm(current.theta - known_minimum) <= SAME_MINIMUM * (
            1.0 + np.linalg.norm(known_minimum)
        ):
            termination = "joined the minimum found from another start"
            iterations, r = iterations - 1, None
            break
        r, g = _factor(spec, current, y, u, buffer)
        basis = _boundary_directions(spec, current.theta, r, g)
        rb, gb = (r, g) if basis is None else _restrict(r, g, basis)
        # Gauss-Newton predicts a loss reduction of |Q'e|^2 / N (within the feasible directions)
        expected = float(gb @ gb) / N
        if current.loss == 0 or expected <= tolerance * current.loss:
            termination = "expected improvement below tolerance"
            if iterations == 1 and current.loss > 0:
                # a start this close still gets its Gauss-Newton step: the loss is flat to
                # within the tolerance there, poorly determined parameters need not be
                step = _damped_step(r, g, 0.0, np.ones(p), basis)
                candidate = evaluate(spec, project(spec, current.theta + step), y, u, fit_states, jacobian=False)
                if candidate.loss < current.loss:
                    current, r = candidate, None
                    break
            iterations -= 1
            break
        scale = np.sqrt(np.sum(r * r, axis=0)) + 1e-300
        accepted = None
        for _ in range(MAX_RETRIES):
            step = _damped_step(r, g, lam, scale, basis)
            predicted = (float(g @ g) - float(np.sum((r @ step + g) ** 2))) / N
            candidate = evaluate(spec, project(spec, current.theta + step), y, u, fit_states, jacobian=False)
            actual = current.loss - candidate.loss
            if np.isfinite(candidate.loss) and actual > 0:
                rho = actual / predicted if predicted > 0 else 0.0
                lam *= max(1.0 / 3.0, 1.0 - (2.0 * rho - 1.0) ** 3)
                lam = 0.0 if lam < 1e-12 else lam
                nu = 2.0
                accepted = candidate
                break
            lam = max(lam, 1e-6) * nu
            nu *= 2.0
        if accepted is None:
            # at a minimum, rounding leaves nothing to gain: converged if little was expected
            termination = (
                "no further improvement possible (converged to rounding)"
                if expected <= NEGLIGIBLE * tolerance * current.loss
                else "no improvement along the search direction"
            )
            iterations -= 1
            break
        relative = (current.loss - accepted.loss) / current.loss
        undamped = lam == 0.0
        previous_loss, current = current.loss, accepted
        history.append(current.loss)
        if undamped and relative < tolerance:
            termination = "relative improvement below tolerance"
            r = None
            break
        if len(history) > STALL and history[-1 - STALL] - current.loss < tolerance * current.loss:
            # damped steps crawling along a flat valley: stop, but not as converged (other
            # starts are then not abandoned against this one)
            termination = f"stalled: relative improvement over the last {STALL} iterations below tolerance"
            r = None
            break
    else:
        r = None
    return Minimum(current, iterations, termination, r)


def r_factor(spec: PolySpec, minimum: Minimum, y: np.ndarray, u: np.ndarray) -> np.ndarray:
    """The triangular factor R of the Jacobian at ``minimum`` (JᵀJ = RᵀR), factored now if the run did not."""
    if minimum.r_factor is None:
        buffer = np.empty((y.size, spec.n_params + 1), order="F")
        minimum.r_factor = _factor(spec, minimum.evaluation, y, u, buffer)[0]
    return minimum.r_factor


def _factor(spec: PolySpec, ev: Evaluation, y, u, buffer: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """R and Qᵀe of [J e] = QR, with J built in ``buffer``.

    The triangular factor of [J e] is that of its Gram matrix, so it comes from a
    Cholesky factorisation of the (p+1)² Gram matrix (columns scaled to unit norm),
    a third of the work of a Householder QR of the N × (p+1) matrix.  Squaring the
    condition number costs accuracy, so when the factor's diagonal spans more than
    ``GRAM_CONDITION`` (J is that ill-conditioned at least) the QR is used instead.
    """
    p = spec.n_params
    fill_jacobian(spec, ev, y, u, buffer[:, :p])
    buffer[:, p] = ev.e
    gram = buffer.T @ buffer
    norms = np.sqrt(np.diag(gram))
    if np.all(norms[:p] > 0) and norms[p] > 0:
        try:
            lower = np.linalg.cholesky(gram / norms[:, None] / norms[None, :])
        except np.linalg.LinAlgError:
            lower = None
        if lower is not None:
            pivots = np.abs(np.diag(lower)[:p])
            if pivots.min() * GRAM_CONDITION > pivots.max():
                full = lower.T * norms[None, :]
                return full[:p, :p], full[:p, p]
    return _factor_in_place(buffer)


def triangular_factor(matrix: np.ndarray, rhs: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """R and Qᵀ·rhs of matrix = QR, from one Householder QR of [matrix rhs] (Q never formed)."""
    n, p = matrix.shape
    a = np.empty((n, p + 1), order="F")
    a[:, :p] = matrix
    a[:, p] = rhs
    return _factor_in_place(a)


def _factor_in_place(a: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """R and Qᵀ·(last column) from LAPACK's dgeqrf on the Fortran-ordered ``a``, overwritten."""
    p = a.shape[1] - 1
    factored, _, _, info = dgeqrf(a, overwrite_a=1)
    if info != 0:
        raise np.linalg.LinAlgError(f"QR factorisation failed (LAPACK dgeqrf info = {info})")
    k = min(a.shape[0], p + 1)
    full = np.triu(factored[:k])
    return full[:p, :p], full[:p, p]


CONVERGED = ("expected", "relative", "no further")


def _boundary_directions(spec: PolySpec, theta: np.ndarray, r: np.ndarray, g: np.ndarray) -> np.ndarray | None:
    """Orthonormal basis of the steps that hold fixed the roots of C, D, F which the
    Gauss–Newton step would push out of the stability region (None if it pushes none).
    Only roots already within ``NEAR_BOUNDARY`` of the circle are held; farther ones
    approach it through damped steps.

    A root ρ of P(q⁻¹) = 1 + p₁q⁻¹ + … stays put when the step δ satisfies
    Σ δᵢ ρ⁻ⁱ = 0 (real and imaginary part for a complex root): linear constraints
    whose null space the step is then restricted to.
    """
    try:
        step = -np.linalg.solve(r, g)
    except np.linalg.LinAlgError:
        return None
    rows = []
    offset = spec.na + spec.nb
    for n in (spec.nc, spec.nd, spec.nf):
        now = np.concatenate((ONE, theta[offset : offset + n]))
        after = now.copy()
        after[1:] += step[offset : offset + n]
        if n and not roots_within(now, NEAR_BOUNDARY) and not roots_within(after, MAX_RADIUS):
            now, after = np.roots(now), np.roots(after)
            held = {int(np.argmin(np.abs(now - root))) for root in after[np.abs(after) > MAX_RADIUS]}
            for rho in now[[i for i in held if abs(now[i]) > NEAR_BOUNDARY]]:
                # a conjugate pair gives the same two rows twice; the SVD drops them
                row = np.zeros(spec.n_params, dtype=complex)
                row[offset : offset + n] = rho ** -np.arange(1, n + 1)
                rows.append(row.real)
                if abs(rho.imag) > 1e-12:
                    rows.append(row.imag)
        offset += n
    if not rows:
        return None
    _, sv, vt = np.linalg.svd(np.array(rows))
    rank = int(np.sum(sv > 1e-10 * sv[0]))
    return vt[rank:].T


def _restrict(r: np.ndarray, g: np.ndarray, basis: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The Gauss–Newton problem min |R Z t + g| in coordinates t of the directions Z:
    its triangular factor and projected right-hand side (for the expected improvement)."""
    q, rz = np.linalg.qr(r @ basis)
    return rz, q.T @ g


def _damped_step(
    r: np.ndarray, g: np.ndarray, lam: float, scale: np.ndarray, basis: np.ndarray | None = None
) -> np.ndarray:
    """Solve min |R s + g|² + lam |diag(scale) s|² (Marquardt's scaled damping), with s
    restricted to the columns of ``basis`` when given (QR of the stacked 2p × p system)."""
    directions = np.eye(r.shape[1]) if basis is None else basis
    if lam == 0.0 and basis is None:
        try:
            return -np.linalg.solve(r, g)
        except np.linalg.LinAlgError:
            lam = 1e-8
    stacked = np.vstack([r @ directions, np.sqrt(lam) * (scale[:, None] * directions)])
    q, rr = np.linalg.qr(stacked)
    try:
        t = np.linalg.solve(rr, -(q[: r.shape[0]].T @ g))
    except np.linalg.LinAlgError:
        t = np.linalg.lstsq(stacked, -np.concatenate([g, np.zeros(r.shape[1])]), rcond=None)[0]
    return directions @ t
