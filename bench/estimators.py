"""Benchmark maglev's ARX/ARMAX/OE/BJ estimators for speed and accuracy, with peers side by side.

Run ``python bench/estimators.py`` (about 3–5 minutes) or ``--quick`` (under a
minute, no N = 1e5 and no N = 1e6 line).  For each true system (second-order ARX/ARMAX/OE/BJ with poles 0.7 ± 0.3j,
and a lightly damped 4th-order levitator-like plant with poles 0.95 ± 0.2j,
0.98 ± 0.07j at Ts = 1 ms) and each record length N, every repeat draws fresh data
(random binary ±1 input, noise scaled so that std(H e) = 0.1 std(G u)) and reports
medians over the repeats of: wall and CPU time of the estimator call (CPU time is
the steadier one on a shared machine; both are single-threaded), for maglev the number
of minimisations it ran ("starts") and their Levenberg–Marquardt iterations in all
(counted by wrapping ``maglev.estimation.starts.minimise``; statsmodels reports its own
iterations), the relative parameter error ‖θ̂ − θ‖/‖θ‖, the largest pole error of G
(poles matched one to one), and the one-step FIT on fresh validation data minus the
true model's ("-" when the estimated G is unstable, so that its predictor diverges).
The target lines check maglev's median CPU times.  A line times ARMAX [4 4 4 1] on
N = 10⁶ samples of a levitator-like plant (CPU and wall time, then the peak of traced
memory in a second, traced run), and the last lines give the estimator speed targets
as CPU times and ratios measured in the same run (medians of at least 5, threadpoolctl
holding BLAS to one thread): BJ [4 2 2 4 1] on the first half of the 2022
binary_signal_2 record (skipped without the reference data), BJ [2 2 2 2 1] at
N = 10⁴ over the floor of one Gauss–Newton iteration (6 lfilter passes and one QR of
the Jacobian, timed alongside), and ARMAX [4 4 4 1]'s CPU time per sample at N = 10⁶
over that at 10⁵.  ``--markdown PATH`` also writes the table and these lines as
markdown, so that docs quote numbers the command wrote, headed by the command and the fingerprint of what it
measured (``bench/fingerprints.py``: docs/benchmarks.md is checked against it by a test).

Peers run in the same process where installed (the ``bench`` extra):
statsmodels ``SARIMAX`` as an exact ARMAX (lagged y and u as regressors, MA(nc)
errors) and SIPPY's ARX (least squares), ARMAX (ILLS), OE and BJ (casadi/IPOPT).
"ratio" is peer time / maglev time on the same cell.  A peer gets fewer repeats when
slow (it stops repeating once it has spent ``PEER_CELL_BUDGET`` seconds in a cell)
and is skipped at the next N when its time extrapolated linearly in N exceeds
``PEER_SKIP_SECONDS``; a peer raising on a record has that repeat counted as failed.
SIPPY's noise numerator C is reflected into the unit circle before prediction (same
noise spectrum; the minimum-phase C gives the one-step predictor).  SIPPY has no
separate "PEM" method: its OE and BJ are its prediction-error (IPOPT) estimators.
BLAS is single-threaded so that timings are comparable.
"""

import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ[_var] = "1"

import argparse  # noqa: E402
import contextlib  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402
import tracemalloc  # noqa: E402
import warnings  # noqa: E402
from collections.abc import Callable, Iterator  # noqa: E402
from dataclasses import dataclass  # noqa: E402

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import fingerprints  # noqa: E402
import numpy as np  # noqa: E402
import pandas as pd  # noqa: E402
from scipy.optimize import linear_sum_assignment  # noqa: E402

import maglev.estimation.starts as starts_module  # noqa: E402
from maglev import IOData, PolyModel, PolySpec  # noqa: E402
from maglev.estimation import estimate  # noqa: E402
from maglev.polynomials import polymul, stabilize  # noqa: E402
from maglev.validation import compare  # noqa: E402

SNR_RATIO = 0.1  # std(H e) / std(G u)
N_VALIDATION = 5000
PEER_CELL_BUDGET = 5.0  # seconds a peer may spend repeating in one cell
PEER_SKIP_SECONDS = 25.0  # skip a peer at the next N if its extrapolated time exceeds this
# the targets, milliseconds: (N = 1e4, N = 1e5) for second-order and levitator-like cases
TARGETS_MS = {"second": (15.0, 130.0), "lev": (40.0, 350.0), "arx_1e5": 20.0}
BIG_N, BIG_TARGET_S, BIG_TARGET_GB = 1_000_000, 1.0, 0.4


@dataclass(frozen=True)
class Case:
    """A true system and the structure/orders to estimate it with."""

    name: str
    structure: str
    orders: tuple[int, ...]
    true: PolyModel
    noise_std: float


def _poly(*roots: complex) -> np.ndarray:
    return np.real(np.poly(roots))


def _cases() -> list[Case]:
    """Second-order systems with poles 0.7 ± 0.3j and a 4th-order levitator-like plant (Ts = 1 ms)."""
    one = np.ones(1)
    a2 = _poly(0.7 + 0.3j, 0.7 - 0.3j)
    b2 = np.array([0.0, 1.0, 0.5])
    c2 = np.array([1.0, -0.5, 0.2])
    d2 = _poly(0.5 + 0.2j, 0.5 - 0.2j)
    f4 = _poly(0.95 + 0.2j, 0.95 - 0.2j, 0.98 + 0.07j, 0.98 - 0.07j)
    b4 = np.array([0.0, 1.0, 0.5, -0.3, 0.1]) * 1e-4
    d4 = _poly(0.8 + 0.2j, 0.8 - 0.2j)
    specs = [
        ("ARX 2", "arx", (2, 2, 1), dict(A=a2, B=b2), 1.0),
        ("ARMAX 2", "armax", (2, 2, 2, 1), dict(A=a2, B=b2, C=c2), 1.0),
        ("OE 2", "oe", (2, 2, 1), dict(B=b2, F=a2), 1.0),
        ("BJ 2", "bj", (2, 2, 2, 2, 1), dict(B=b2, C=c2, D=d2, F=a2), 1.0),
        ("ARX 4 lev", "arx", (4, 4, 1), dict(A=f4, B=b4), 1e-3),
        ("ARMAX 4 lev", "armax", (4, 4, 2, 1), dict(A=f4, B=b4, C=c2), 1e-3),
        ("OE 4 lev", "oe", (4, 4, 1), dict(B=b4, F=f4), 1e-3),
        ("BJ 4 lev", "bj", (4, 2, 2, 4, 1), dict(B=b4, C=c2, D=d4, F=f4), 1e-3),
    ]
    cases = []
    rng = np.random.default_rng(12345)
    u, e = _binary(rng, 100_000), rng.standard_normal(100_000)
    for name, structure, orders, polys, Ts in specs:
        full = {"A": one, "C": one, "D": one, "F": one, **polys}
        true = PolyModel(nk=1, Ts=Ts, structure=structure, name="true", **full)
        noise_std = SNR_RATIO * np.std(true.simulate(u)) / np.std(true.simulate(np.zeros_like(u), e))
        cases.append(Case(name, structure, orders, true, float(noise_std)))
    return cases


def _binary(rng: np.random.Generator, n: int) -> np.ndarray:
    return np.where(rng.random(n) < 0.5, -1.0, 1.0)


def _record(case: Case, n: int, seed: int) -> IOData:
    rng = np.random.default_rng(seed)
    u = _binary(rng, n)
    e = case.noise_std * rng.standard_normal(n)
    return IOData(u, case.true.simulate(u, e), case.true.Ts, name=f"{case.name} N={n}")


# ---------------------------------------------------------------------------- estimators
@dataclass(frozen=True)
class Fit:
    """What one estimator call returned: the model (as a PolyModel) and its iteration count."""

    model: PolyModel
    iterations: int | None
    starts: int | None = None


def _maglev(case: Case, data: IOData) -> Fit:
    with _counted_minimisations() as runs:
        model = estimate(data, case.structure, case.orders)
    return Fit(model, sum(runs), len(runs))


@contextlib.contextmanager
def _counted_minimisations() -> Iterator[list[int]]:
    """Record the iteration count of every minimisation ``maglev.estimation.starts`` runs inside the block."""
    runs: list[int] = []
    original = starts_module.minimise

    def counted(*args, **kwargs):
        result = original(*args, **kwargs)
        runs.append(result.iterations)
        return result

    starts_module.minimise = counted
    try:
        yield runs
    finally:
        starts_module.minimise = original


def _statsmodels_armax(case: Case, data: IOData) -> Fit:
    """ARMAX as SARIMAX: regressors -y(t-i), u(t-nk-j), MA(nc) errors; exact Gaussian likelihood."""
    from statsmodels.tsa.statespace.sarimax import SARIMAX

    na, nb, nc, nk = case.orders
    lag = max(na, nb + nk - 1)
    N = data.N
    cols = [data.y[lag - i : N - i] for i in range(1, na + 1)]
    cols += [data.u[lag - nk - j : N - nk - j] for j in range(nb)]
    result = SARIMAX(data.y[lag:], exog=np.column_stack(cols), order=(0, 0, nc), trend="n").fit(
        disp=False, maxiter=200
    )
    p = np.asarray(result.params)
    A = np.r_[1.0, -p[:na]]
    B = np.r_[np.zeros(nk), p[na : na + nb]]
    C = np.r_[1.0, p[na + nb : na + nb + nc]]
    model = PolyModel(A=A, B=B, C=C, D=[1.0], F=[1.0], nk=nk, Ts=data.Ts, structure="armax")
    return Fit(model, int(result.mle_retvals.get("iterations", -1)))


def _sippy(method: str) -> Callable[[Case, IOData], Fit]:
    def run(case: Case, data: IOData) -> Fit:
        from sippy_unipi import system_identification

        *orders, nk = case.orders
        key = {"ARX": "ARX_orders", "ARMAX": "ARMAX_orders", "OE": "OE_orders", "BJ": "BJ_orders"}[method]
        model = system_identification(data.y, data.u, method, tsample=data.Ts, **{key: [*orders, nk - 1]})
        return Fit(_from_control(model.G, model.H, data.Ts), None)

    return run


def _from_control(G, H, Ts: float) -> PolyModel:
    """A PolyModel y = B/F u + C/D e from SISO transfer functions in z."""
    B, F = _q_inverse(G)
    C, D = _q_inverse(H)
    # the one-step predictor of the noise spectrum C C*/(D D*): C monic and minimum phase
    C = stabilize(C / C[0])
    nk = int(np.argmax(np.abs(B) > 0))
    return PolyModel(A=[1.0], B=B, C=C, D=D, F=F, nk=nk, Ts=Ts, structure="pem")


def _q_inverse(system) -> tuple[np.ndarray, np.ndarray]:
    num = np.trim_zeros(np.atleast_1d(np.squeeze(system.num[0][0])).astype(float), "f")
    den = np.trim_zeros(np.atleast_1d(np.squeeze(system.den[0][0])).astype(float), "f")
    n = max(num.size, den.size)
    num = np.r_[np.zeros(n - num.size), num]
    den = np.r_[den, np.zeros(n - den.size)]
    return num / den[0], den / den[0]


def _peers(structure: str) -> dict[str, Callable[[Case, IOData], Fit] | str]:
    """Peer estimators for a structure; a string says why a peer cannot run."""
    out: dict[str, Callable[[Case, IOData], Fit] | str] = {}
    if structure == "armax":
        out["statsmodels SARIMAX"] = _statsmodels_armax if _installed("statsmodels") else "skipped: not installed"
    method = {"arx": "ARX", "armax": "ARMAX", "oe": "OE", "bj": "BJ"}[structure]
    out[f"SIPPY {method}"] = _sippy(method) if _installed("sippy_unipi") else "skipped: not installed"
    return out


def _installed(module: str) -> bool:
    import importlib.util

    return importlib.util.find_spec(module) is not None


@contextlib.contextmanager
def _silenced() -> Iterator[None]:
    """Hide peers' prints (IPOPT writes to the C-level stdout) and warnings."""
    sys.stdout.flush()
    saved = os.dup(1)
    with open(os.devnull, "w") as null, warnings.catch_warnings():
        warnings.simplefilter("ignore")
        os.dup2(null.fileno(), 1)
        try:
            yield
        finally:
            sys.stdout.flush()
            os.dup2(saved, 1)
            os.close(saved)


# ---------------------------------------------------------------------------- accuracy
def _accuracy(case: Case, model: PolyModel, val: IOData, true_fit: float) -> tuple[float, float, float]:
    """(relative parameter error or NaN if not comparable, max pole error of G, ΔFIT on val)."""
    spec = PolySpec.from_orders(case.structure, case.orders)
    t = case.true
    if model.structure == case.structure and model.orders == case.orders:
        theta = spec.theta(t.A, t.B, t.C, t.D, t.F)
        rel = float(np.linalg.norm(model.parameters - theta) / np.linalg.norm(theta))
    else:
        rel = float("nan")
    p_true, p_hat = t.poles(), model.poles()
    if p_hat.size == p_true.size:
        dist = np.abs(p_true[:, None] - p_hat[None, :])
        rows, cols = linear_sum_assignment(dist)
        pole = float(dist[rows, cols].max())
    else:
        pole = float("nan")
    stable = p_hat.size == 0 or np.abs(p_hat).max() < 1.0
    fit = compare(val, model, 1)[0] if stable else float("nan")  # unstable G: the predictor diverges
    return rel, pole, fit - true_fit


# ---------------------------------------------------------------------------- driver
def _cell(
    case: Case,
    n: int,
    estimator: Callable[[Case, IOData], Fit],
    reps: int,
    budget: float,
    warm_up: bool,
    true_fits: list[float],
    vals: list[IOData],
) -> dict:
    """Run one estimator up to ``reps`` times on fresh records (stopping after ``budget`` s); medians.

    A peer that raises on a record has that repeat counted as failed; maglev raising stops the run.
    """
    if warm_up:  # imports, JIT and caches are not what we time
        try:
            estimator(case, _record(case, min(n, 1000), seed=999))
        except (Exception, SystemExit):
            if estimator is _maglev:
                raise
    times, cpu, iters, n_starts, rels, poles, dfits = [], [], [], [], [], [], []
    spent, failures = 0.0, []
    for rep in range(reps):
        data = _record(case, n, seed=rep)
        start, start_cpu = time.perf_counter(), time.process_time()
        try:
            fit = estimator(case, data)
        except (Exception, SystemExit) as exc:  # a peer failing on one record must not stop the benchmark
            if estimator is _maglev:
                raise
            failures.append(f"{type(exc).__name__}: {str(exc)[:40]}")
            continue
        elapsed = time.perf_counter() - start
        cpu.append(time.process_time() - start_cpu)
        spent += elapsed
        times.append(elapsed)
        if fit.iterations is not None:
            iters.append(fit.iterations)
        if fit.starts is not None:
            n_starts.append(fit.starts)
        rel, pole, dfit = _accuracy(case, fit.model, vals[rep % len(vals)], true_fits[rep % len(vals)])
        rels.append(rel)
        poles.append(pole)
        dfits.append(dfit)
        if spent > budget:
            break
    if not times:
        raise RuntimeError(f"all {len(failures)} repeats failed, e.g. {failures[0]}")
    return {
        "reps": len(times),
        "time_ms": 1e3 * float(np.median(times)),
        "cpu_ms": 1e3 * float(np.median(cpu)),
        "starts": float(np.median(n_starts)) if n_starts else float("nan"),
        "iters": float(np.median(iters)) if iters else float("nan"),
        "rel_theta_err": float(np.median(rels)),
        "pole_err": float(np.median(poles)),
        "dFIT_%": float(np.median(dfits)),
        "note": f"{len(failures)} of {len(failures) + len(times)} repeats failed ({failures[0]})" if failures else "",
    }


def run(ns: list[int], reps: int, with_peers: bool) -> pd.DataFrame:
    rows = []
    for case in _cases():
        vals = [_record(case, N_VALIDATION, seed=10_000 + k) for k in range(3)]
        true_fits = [compare(v, case.true, 1)[0] for v in vals]
        peers = _peers(case.structure) if with_peers else {}
        peer_time: dict[str, tuple[int, float]] = {}
        for i, n in enumerate(ns):
            base = dict(case=case.name, N=n)
            mine = _cell(case, n, _maglev, reps, float("inf"), i == 0, true_fits, vals)
            rows.append({**base, "method": "maglev", **mine, "ratio": 1.0})
            print(f"  {case.name:12s} N={n:<6d} maglev {mine['time_ms']:9.1f} ms", file=sys.stderr)
            for name, peer in peers.items():
                row = {**base, "method": name}
                if isinstance(peer, str):
                    rows.append({**row, "note": peer})
                    continue
                if name in peer_time:
                    prev_n, prev_s = peer_time[name]
                    if prev_s * n / prev_n > PEER_SKIP_SECONDS:
                        rows.append({**row, "note": f"skipped: ~{prev_s * n / prev_n:.0f} s expected"})
                        continue
                try:
                    with _silenced():
                        res = _cell(case, n, peer, reps, PEER_CELL_BUDGET, i == 0, true_fits, vals)
                except RuntimeError as exc:
                    rows.append({**row, "note": f"failed: {exc}"})
                    continue
                peer_time[name] = (n, res["time_ms"] / 1e3)
                rows.append({**row, **res, "ratio": res["time_ms"] / mine["time_ms"]})
                print(f"  {case.name:12s} N={n:<6d} {name} {res['time_ms']:9.1f} ms", file=sys.stderr)
    columns = ["case", "N", "method", "reps", "time_ms", "cpu_ms", "starts", "iters", "rel_theta_err", "pole_err",
               "dFIT_%", "ratio", "note"]
    return pd.DataFrame(rows, columns=columns)


def _targets(table: pd.DataFrame) -> list[str]:
    """The issue's speed targets, checked on maglev's median CPU times (wall time follows the machine's load)."""
    mine = table[table["method"] == "maglev"].set_index(["case", "N"])["cpu_ms"]
    lines = []
    if ("ARX 2", 100_000) in mine.index:
        t = mine[("ARX 2", 100_000)]
        lines.append(f"ARX on N=1e5: CPU {t:.1f} ms (target < {TARGETS_MS['arx_1e5']:.0f} ms) "
                     f"{'OK' if t < TARGETS_MS['arx_1e5'] else 'MISSED'}")
    for case, n in mine.index:
        if case.startswith("ARX") or n not in (10_000, 100_000):
            continue
        limit = TARGETS_MS["lev" if case.endswith("lev") else "second"][n == 100_000]
        t = mine[(case, n)]
        verdict = "OK" if t <= limit else "MISSED"
        lines.append(f"{case} on N={n:.0e}: CPU {t:.1f} ms (target <= {limit:.0f} ms) {verdict}")
    for case in dict.fromkeys(c for c, _ in mine.index):
        if (case, 10_000) in mine.index and (case, 100_000) in mine.index:
            ratio = mine[(case, 100_000)] / mine[(case, 10_000)]
            lines.append(f"{case}: CPU time(1e5)/time(1e4) = {ratio:.1f} (linear in N: ~10)")
    return lines


def _big_armax(reps: int) -> str:
    """ARMAX [4 4 4 1] on N = 1e6 samples of a levitator-like plant: median CPU time, then traced peak memory."""
    c4 = np.convolve([1.0, -0.5, 0.2], [1.0, 0.3, 0.1])
    lev = next(c for c in _cases() if c.name == "ARMAX 4 lev")
    true = PolyModel(A=lev.true.A, B=lev.true.B, C=c4, D=[1.0], F=[1.0], nk=1, Ts=lev.true.Ts, structure="armax")
    case = Case("ARMAX 4441 lev", "armax", (4, 4, 4, 1), true, lev.noise_std)
    _maglev(case, _record(case, 10_000, seed=999))  # warm-up
    data = _record(case, BIG_N, seed=0)
    times, cpu = [], []
    for _ in range(reps):
        start, start_cpu = time.perf_counter(), time.process_time()
        _maglev(case, data)
        times.append(time.perf_counter() - start)
        cpu.append(time.process_time() - start_cpu)
    tracemalloc.start()
    fit = _maglev(case, data)
    peak = tracemalloc.get_traced_memory()[1] / 1e9
    tracemalloc.stop()
    t = float(np.median(cpu))
    return (f"ARMAX [4 4 4 1] on N=1e6: CPU {t:.2f} s (target < {BIG_TARGET_S:.0f} s) "
            f"{'OK' if t < BIG_TARGET_S else 'MISSED'}, wall {float(np.median(times)):.2f} s, peak memory {peak:.2f} GB "
            f"(target < {BIG_TARGET_GB} GB) {'OK' if peak < BIG_TARGET_GB else 'MISSED'}; "
            f"{fit.starts} start(s), {fit.iterations} iterations, median of {reps}")


# ---------------------------------------------------------------------------- speed ratios (issue targets)
RECORD_BJ = ("binary_signal_2", (4, 2, 2, 4, 1), 150.0)  # record, BJ orders, CPU target in ms
FLOOR_CASE, FLOOR_N, FLOOR_TARGET = "BJ 2", 10_000, 2.5  # BJ [2 2 2 2 1] within 2.5 Gauss-Newton iterations
GROWTH_NS, GROWTH_TARGET = (100_000, 1_000_000), 1.5  # ARMAX [4 4 4 1]: time per sample, 1e6 over 1e5


def _orders(orders) -> str:
    return " ".join(str(o) for o in orders)


def _cpu_median(call: Callable[[], object], reps: int) -> float:
    """Median CPU seconds of ``reps`` calls (BLAS single-threaded), after one untimed warm-up call."""
    call()
    times = []
    for _ in range(reps):
        start = time.process_time()
        call()
        times.append(time.process_time() - start)
    return float(np.median(times))


def _record_bj(reps: int) -> list[str]:
    """BJ [4 2 2 4 1] on the first half of the 2022 binary_signal_2 record: CPU time against its target."""
    from maglev.paths import refdata_dir
    from maglev.refdata import load_record

    name, orders, target = RECORD_BJ
    root = refdata_dir()
    if root is None:
        return [f"BJ [{_orders(orders)}] on {name}: skipped (no reference data; set MAGLEV_REFDATA)"]
    data = load_record(name, root=root).detrend().split(0.5)[0]
    with _counted_minimisations() as runs:
        model = estimate(data, "bj", list(orders))
    cpu = 1e3 * _cpu_median(lambda: estimate(data, "bj", list(orders)), reps)
    return [f"BJ [{_orders(orders)}] on {name}'s first half (N={data.N}): CPU {cpu:.0f} ms = {cpu / target:.2f} x the "
            f"{target:.0f} ms target {'OK' if cpu <= target else 'MISSED'}; loss {model.report.loss:.6g}, "
            f"{len(runs)} minimisations, {sum(runs)} iterations (median of {reps})"]


def _floor(spec: PolySpec, data: IOData, theta: np.ndarray) -> Callable[[], object]:
    """One Gauss-Newton iteration's unavoidable work: 6 lfilter passes and one QR of the Jacobian."""
    from scipy.signal import lfilter

    from maglev.estimation.prediction_error import evaluate, triangular_factor

    ev = evaluate(spec, theta, data.y, data.u, False, True)
    _, B, C, D, F = spec.polys(theta)
    CF, one = polymul(C, F), np.ones(1)

    def work() -> None:  # w = B/F u, e = D/C v; Jacobian: D/(CF) u, e/C, v/C, D/(CF) w
        w = lfilter(B, F, data.u)
        v = data.y - w
        e = lfilter(D, C, v)
        lfilter(D, CF, data.u), lfilter(one, C, e), lfilter(one, C, v), lfilter(D, CF, w)
        triangular_factor(ev.jac, ev.e)

    return work



def _floor_ratio(reps: int) -> list[str]:
    """BJ [2 2 2 2 1] on N = 1e4 samples of its true system: estimate time over one Gauss-Newton iteration."""
    case = next(c for c in _cases() if c.name == FLOOR_CASE)
    data = _record(case, FLOOR_N, seed=0)
    spec = PolySpec.from_orders(case.structure, case.orders)
    t = case.true
    theta = spec.theta(t.A, t.B, t.C, t.D, t.F)
    floor = _cpu_median(_floor(spec, data, theta), reps)
    mine = _cpu_median(lambda: estimate(data, case.structure, list(case.orders)), reps)
    ratio = mine / floor
    return [f"BJ [{_orders(case.orders)}] on N={FLOOR_N:.0e}: CPU {1e3 * mine:.1f} ms = {ratio:.1f} x the floor of one "
            f"Gauss-Newton iteration ({1e3 * floor:.2f} ms: 6 lfilter passes + QR of the Jacobian), target <= "
            f"{FLOOR_TARGET} {'OK' if ratio <= FLOOR_TARGET else 'MISSED'} (medians of {reps})"]


def _growth_ratio(reps: int) -> list[str]:
    """ARMAX [4 4 4 1] on a levitator-like plant: CPU time per sample at N = 1e6 over that at N = 1e5."""
    c4 = np.convolve([1.0, -0.5, 0.2], [1.0, 0.3, 0.1])
    lev = next(c for c in _cases() if c.name == "ARMAX 4 lev")
    true = PolyModel(A=lev.true.A, B=lev.true.B, C=c4, D=[1.0], F=[1.0], nk=1, Ts=lev.true.Ts, structure="armax")
    case = Case("ARMAX 4441 lev", "armax", (4, 4, 4, 1), true, lev.noise_std)
    per_sample = []
    for n in GROWTH_NS:
        data = _record(case, n, seed=0)
        per_sample.append(_cpu_median(lambda: estimate(data, "armax", [4, 4, 4, 1]), reps) / n)
    ratio = per_sample[1] / per_sample[0]
    return [f"ARMAX [4 4 4 1]: CPU per sample {1e9 * per_sample[0]:.0f} ns at N={GROWTH_NS[0]:.0e}, "
            f"{1e9 * per_sample[1]:.0f} ns at N={GROWTH_NS[1]:.0e}: ratio {ratio:.2f}, target <= {GROWTH_TARGET} "
            f"{'OK' if ratio <= GROWTH_TARGET else 'MISSED'} (medians of {reps})"]


def speed_ratios(reps: int, quick: bool) -> list[str]:
    """The estimator speed targets as CPU times and same-run ratios, BLAS single-threaded."""
    from threadpoolctl import threadpool_limits

    with threadpool_limits(limits=1):
        lines = _record_bj(reps) + _floor_ratio(reps)
        lines += ["ARMAX [4 4 4 1] growth: skipped with --quick (N = 1e5 and 1e6)"] if quick else _growth_ratio(reps)
    return lines


def _markdown(table: pd.DataFrame, lines: list[str]) -> str:
    """The table and the target lines as markdown (what ``--markdown`` writes)."""
    cells = table.astype(object).where(table.notna(), "-")
    fmt = [[f"{v:.3g}" if isinstance(v, float) else str(v) for v in row] for row in cells.itertuples(index=False)]
    out = ["| " + " | ".join(table.columns) + " |", "|" + "---|" * len(table.columns)]
    out += ["| " + " | ".join(row) + " |" for row in fmt]
    return "\n".join(out + [""] + [f"- {line}" for line in lines]) + "\n"


def _case_list(ns: list[int]) -> str:
    """The cases the table measured, in words: each true system's structure and orders, and the record lengths."""
    cases = ", ".join(f"{c.name} [{_orders(c.orders)}]" for c in _cases())
    return f"{cases} at N = {', '.join(str(n) for n in ns)}"


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="N = 1e3, 1e4 and 3 repeats (under a minute)")
    parser.add_argument("--no-peers", action="store_true", help="time maglev only")
    parser.add_argument("--reps", type=int, default=None, help="repeats per cell (default 5, quick 3)")
    parser.add_argument("--markdown", metavar="PATH", help="also write the table and target lines as markdown")
    args = parser.parse_args(argv)
    ns = [1_000, 10_000] if args.quick else [1_000, 10_000, 100_000]
    reps = args.reps or (3 if args.quick else 5)
    if reps < 1:
        parser.error(f"--reps must be >= 1, got {reps}")
    started = time.perf_counter()
    table = run(ns, reps, not args.no_peers)
    pd.set_option("display.width", 200)
    print(table.to_string(index=False, float_format=lambda x: f"{x:.3g}", na_rep="-"))
    print()
    lines = _targets(table)
    if not args.quick:
        lines.append(_big_armax(3))
    lines += speed_ratios(reps if args.quick else max(reps, 5), args.quick)
    print("\n".join(lines))
    note = (f"total benchmark time {time.perf_counter() - started:.0f} s (numpy {np.__version__}, single-threaded "
            "BLAS); CPU times depend on the machine's load, the ratios are measured side by side in one run")
    print(f"\n{note}")
    if args.markdown:
        command = " ".join(["python bench/estimators.py", *(argv if argv is not None else sys.argv[1:])])
        with open(args.markdown, "w") as out:
            out.write(f"# Estimator benchmark\n\n{fingerprints.header(fingerprints.TABLES['estimators'], command)} "
                      f"Cases: {_case_list(ns)}; {note}.\n\n")
            out.write(_markdown(table, lines))


if __name__ == "__main__":
    main()
