"""One identification run of the study: estimate, validate, compare with the truth, draw.

No Hydra and no MLflow here.  :func:`identify` takes the resolved config as a plain
dict (sections ``dataset``, ``structure``, ``study``, ``data_dir``) and returns the
model, the scalar metrics, the residual analysis as JSON and what the figures show; the
tracking layer logs them and :mod:`maglev.study.reproduce` recomputes them.  Everything but
``fit_seconds`` is a deterministic function of the config.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass

import numpy as np

from maglev.estimation import estimate
from maglev.model import PolyModel
from maglev.structures import get as structure
from maglev.study.config import orders_of
from maglev.study.datasets import Prepared, dataset_bla, load, plant_name
from maglev.threads import single_threaded_blas
from maglev.validation import ResidResult, compare, naive_fit, resid

TIMING_METRICS = ("fit_seconds",)  # not reproducible; every other metric is


@dataclass(frozen=True)
class FigureInputs:
    """Everything a run's figures show (:func:`maglev.study.figures.run_figures`); picklable, so that a
    background process can draw them (:mod:`maglev.study.render`)."""

    prepared: Prepared
    model: PolyModel
    resid: ResidResult
    yhat: np.ndarray
    ysim: np.ndarray
    val_fit: float
    val_fit_sim: float
    horizon: int
    jacobian: tuple | None = None  # (A, B, C, D, dt) of the small-signal Jacobian, simulated data only
    bla: object = None  # maglev.sim.bla.BLA of the dataset's input class, simulated data only

    def true_system(self):
        """The small-signal Jacobian as a python-control system (None for recorded data)."""
        if self.jacobian is None:
            return None
        import control as ct

        return ct.ss(*self.jacobian, name="small-signal Jacobian")


@dataclass
class RunOutput:
    model: PolyModel
    metrics: dict[str, float]
    resid: dict
    prepared: Prepared
    figure_inputs: FigureInputs


def orders_string(structure: dict) -> str:
    return "[" + " ".join(str(o) for o in orders_of(structure)) + "]"


def run_label(cfg: dict) -> str:
    """Run name short enough for the UI's run-name column, e.g. ``bj 3-3-3-3-2 · binary_a025``: the
    structure, its MATLAB order vector joined by ``-`` (``bj [3 3 3 3 2]``) and the dataset."""
    orders = "-".join(str(o) for o in orders_of(cfg["structure"]))
    return f"{cfg['structure']['name']} {orders} · {cfg['dataset']['name']}"


@dataclass
class Estimated:
    """A run's model and what its console line says (its one-step validation FIT), before the rest of its
    validation (:func:`validate`); picklable, so that a background process can finish the run
    (:mod:`maglev.study.render`)."""

    cfg: dict
    prepared: Prepared
    model: PolyModel
    fit_seconds: float
    val_fit: float
    yhat: np.ndarray


@single_threaded_blas  # same numbers, bit for bit, whichever launcher or process runs it
def estimate_run(cfg: dict) -> Estimated:
    """Estimate the configured structure on the dataset's estimation part; its ``val_horizon``-step FIT on the
    validation part."""
    st = cfg["structure"]
    prep = load(cfg["dataset"], cfg["data_dir"])
    options = {} if structure(st["name"]).least_squares else {"max_iterations": int(st["max_iterations"])}
    tic = time.perf_counter()
    model = estimate(prep.est, st["name"], orders_of(st), st["initial_condition"], **options)
    fit_seconds = time.perf_counter() - tic
    val_fit, yhat = compare(prep.val, model, int(cfg["study"]["val_horizon"]))
    return Estimated(cfg, prep, model, fit_seconds, val_fit, yhat)


@single_threaded_blas
def validate(run: Estimated) -> RunOutput:
    """Everything else a run logs about its model: simulation FIT, residual tests, criteria, poles, and for
    simulated data the distances to the small-signal Jacobian and to the best linear approximation."""
    cfg, prep, model, val_fit, yhat = run.cfg, run.prepared, run.model, run.val_fit, run.yhat
    study = cfg["study"]
    horizon = int(study["val_horizon"])
    val_fit_sim, ysim = compare(prep.val, model, math.inf)
    rr = resid(prep.val, model, lags=int(study["resid_lags"]))
    rep = model.report
    poles = model.poles()
    metrics = {
        "val_fit": val_fit, "val_fit_sim": val_fit_sim, "val_fit_naive": naive_fit(prep.val, horizon),
        "est_fit": rep.fit_percent,
        "loss": rep.loss, "fpe": rep.fpe, "aic": rep.aic, "aicc": rep.aicc, "bic": rep.bic,
        "n_params": rep.n_params, "iterations": rep.iterations, "fit_seconds": run.fit_seconds,
        "whiteness_stat": rr.whiteness_stat, "whiteness_pvalue": rr.whiteness_pvalue,
        "whiteness_pass": float(rr.white),
        "independence_stat": rr.independence_stat, "independence_pvalue": rr.independence_pvalue,
        "independence_pass": float(rr.independent),
        "resid_auto_outside": rr.auto_outside, "resid_cross_outside": rr.cross_outside,
        "max_pole_radius": float(np.max(np.abs(poles))) if poles.size else 0.0,
        "near_cancellations": len(model.near_cancellations()),
        "dcgain": model.dcgain(),
        "n_est": prep.est.N, "n_val": prep.val.N, "Ts": prep.data.Ts, "u0": prep.u0,
    }
    true_sys = ref = None
    if cfg["dataset"]["source"] == "sim" and study["true_plant"]:
        true_sys = true_plant(prep, plant_name(cfg["dataset"]))
        metrics.update(true_distance(model, true_sys))
        ref = dataset_bla(cfg["dataset"])
        metrics.update(bla_distance(model, ref, prep.val.N))
    jacobian = None if true_sys is None else (true_sys.A, true_sys.B, true_sys.C, true_sys.D, true_sys.dt)
    inputs = FigureInputs(prep, model, rr, yhat, ysim, val_fit, val_fit_sim, horizon, jacobian, ref)
    return RunOutput(model=model, metrics={k: float(v) for k, v in metrics.items()}, resid=rr.to_dict(),
                     prepared=prep, figure_inputs=inputs)


def identify(cfg: dict) -> RunOutput:
    """Estimate the configured structure on the dataset's estimation part and validate it."""
    return validate(estimate_run(cfg))


# ---------------------------------------------------------------------------- truth and data
def bla_distance(model: PolyModel, ref, n_val: int) -> dict[str, float]:
    """Distances of the model's G to the dataset's best linear approximation (``ref``, a :class:`maglev.sim.bla.BLA`).

    ``g_bla_err``: ‖G_BLA u − Ĝu‖ / ‖G_BLA u‖ over records of the class cut as the validation
    data are (their last ``n_val`` samples), Ĝu simulated with the initial state fitted as
    ``compare`` does (:func:`maglev.sim.bla.record_distance`): the part of the validation
    simulation FIT's error that G's difference to the truth makes, on the record length used;
    ``g_bla_err_stationary``: ‖G − G_BLA‖ weighted by the input class's spectrum, relative to
    ‖G_BLA‖ — by E|y − G u|² = ‖G_BLA − G‖²_Φu + var(y_s) the model's excess error in a
    stationary simulation, over all time; the two differ where G is wrong on time scales longer
    than the record (a slow pole-zero pair), which the fitted initial state takes up;
    ``g_bla_err_unweighted``: the stationary one with uniform weight over 0 … Nyquist;
    ``bla_fit_ceiling``: the BLA's own simulation FIT on the class, which no linear model beats.
    """
    from maglev.sim.bla import record_distance, relative_distance, weighted_distance

    g = model.freqresp  # a function: the norms are integrated finer than the BLA's Welch frequencies
    return {"g_bla_err": record_distance(model.G_polys, ref, n_val),
            "g_bla_err_stationary": weighted_distance(g, ref), "g_bla_err_unweighted": relative_distance(g, ref),
            "bla_fit_ceiling": ref.fit_ceiling}


def true_plant(prep: Prepared, plant: str):
    """The small-signal Jacobian (``Levitator.linearize``) of the simulator's parameter set ``plant`` at the
    record's working point, discrete at the data's Ts: the model of infinitesimal motion about a rest,
    overdamped by the friction's damping at rest — not the truth a model identified from large inputs is
    scored against (that is the BLA, :func:`bla_distance`).

    Compared for G only: the identified model is on detrended data, so offsets do not
    enter; units are the simulator's (A → cm) on both sides.
    """
    import control as ct

    from maglev.sim.plant import rig

    lin = rig(plant).linearize(prep.u0, Ts=prep.data.Ts)
    s = lin.sys_d
    return ct.ss(s.A, s.B, s.C, s.D, s.dt, name="small-signal Jacobian")


_TRUE_RESPONSES: dict[tuple, np.ndarray] = {}  # the Jacobian's response by system and grid: one per dataset


def true_distance(model: PolyModel, true_sys, n: int = 2048) -> dict[str, float]:
    """Distance to the small-signal Jacobian: relative H2 error of G (uniform grid up to Nyquist) and the
    DC-gain error (``g_h2_rel_err``, ``dcgain_true``, ``dcgain_err``, ``dcgain_rel_err``)."""
    import control as ct

    w = np.linspace(0.0, math.pi / model.Ts, n)
    g = model.freqresp(w)
    key = (*(np.asarray(m).tobytes() for m in (true_sys.A, true_sys.B, true_sys.C, true_sys.D)), true_sys.dt,
           w.tobytes())
    if key not in _TRUE_RESPONSES:  # python-control solves one linear system per frequency: ≈ 25 ms
        if len(_TRUE_RESPONSES) >= 64:
            _TRUE_RESPONSES.clear()
        _TRUE_RESPONSES[key] = np.asarray(ct.frequency_response(true_sys, w).complex).reshape(-1)
    g0 = _TRUE_RESPONSES[key]
    h2_rel = float(np.sqrt(np.mean(np.abs(g - g0) ** 2) / np.mean(np.abs(g0) ** 2)))
    dc0 = float(np.real(g0[0]))
    dc = model.dcgain()
    return {"g_h2_rel_err": h2_rel, "dcgain_true": dc0, "dcgain_err": dc - dc0,
            "dcgain_rel_err": abs(dc - dc0) / abs(dc0) if dc0 else math.inf}
