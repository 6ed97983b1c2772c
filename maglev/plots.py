"""The identification figures: residual correlations, compare, pole-zero map, Bode.

The study logs these figures to MLflow and the report embeds them, so each helper
draws on axes it is given (or on a new ``Figure`` made without pyplot, which is safe
headless and never opens a window) and returns the ``Figure``.  Models may be
`PolyModel`s or python-control systems, so a true plant can be overlaid on estimates.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from matplotlib.axes import Axes
from matplotlib.figure import Figure

from .data import IOData
from .models import PolyModel
from .validate import ResidResult

N_FREQUENCIES = 500
DECADES = 3  # default Bode range: 10^-3 … 1 times the Nyquist frequency


def plot_resid(result: ResidResult, ax: Sequence[Axes] | None = None) -> Figure:
    """Autocorrelation of the residuals and their cross-correlation with the input, with 99 % bands.

    ``ax`` is a pair of axes (autocorrelation, cross-correlation) or None for a new figure.
    """
    if not isinstance(result, ResidResult):
        raise TypeError(f"plot_resid: result must be a ResidResult, got {type(result).__name__}")
    ax_auto, ax_cross = _axes_pair(ax, "plot_resid")
    for axis, lags, corr, band, title in (
        (ax_auto, result.auto_lags, result.auto_corr, result.auto_band,
         f"Residual autocorrelation (whiteness p = {result.whiteness_pvalue:.3g})"),
        (ax_cross, result.cross_lags, result.cross_corr, result.cross_band,
         f"Residual-input cross-correlation (independence p = {result.independence_pvalue:.3g})"),
    ):
        axis.fill_between(lags, -band, band, color="tab:blue", alpha=0.15, label="99 % band")
        axis.plot(lags, corr, "o-", color="tab:blue", markersize=3, label="estimate")
        axis.axhline(0.0, color="k", linewidth=0.5)
        axis.set_title(title, fontsize="medium")
        axis.set_ylabel("correlation")
        axis.legend(loc="upper right", fontsize="small")
    ax_auto.set_xlabel("lag τ (samples)")
    ax_cross.set_xlabel("lag τ (samples; τ > 0: input leads residual)")
    return ax_auto.figure


def plot_compare(
    data: IOData,
    yhat: np.ndarray | Sequence[np.ndarray],
    fit: float | Sequence[float],
    ax: Axes | None = None,
    labels: Sequence[str] | None = None,
) -> Figure:
    """Measured output and one or several predictions against time, FIT % in the legend."""
    if not isinstance(data, IOData):
        raise TypeError(f"plot_compare: data must be an IOData, got {type(data).__name__}")
    preds = [np.asarray(yhat, dtype=float)] if np.ndim(yhat) == 1 else [np.asarray(p, dtype=float) for p in yhat]
    fits = [float(fit)] if np.ndim(fit) == 0 else [float(f) for f in fit]
    if len(fits) != len(preds):
        raise ValueError(f"plot_compare: fit has {len(fits)} value(s) but yhat holds {len(preds)} prediction(s)")
    names = [f"model {i + 1}" for i in range(len(preds))] if labels is None else list(labels)
    if len(names) != len(preds):
        raise ValueError(f"plot_compare: labels has {len(names)} entries, expected {len(preds)}")
    for p in preds:
        if p.shape != data.y.shape:
            raise ValueError(f"plot_compare: a prediction has shape {p.shape}, expected {data.y.shape} like data.y")
    axis = _axes(ax)
    axis.plot(data.t, data.y, color="k", linewidth=1.0, label="measured")
    for p, f, name in zip(preds, fits, names):
        axis.plot(data.t, p, linewidth=1.0, label=f"{name}: FIT {f:.1f} %")
    axis.set_xlabel("time (s)")
    axis.set_ylabel("output y")
    axis.legend(loc="best", fontsize="small")
    return axis.figure


def plot_pzmap(models, ax: Axes | None = None) -> Figure:
    """Poles (x) and zeros (o) of G for one or several models, with the unit circle.

    ``models``: a `PolyModel` or python-control system, or a sequence of them.
    """
    systems = _as_list(models, "plot_pzmap")
    axis = _axes(ax)
    theta = np.linspace(0.0, 2.0 * np.pi, 400)
    axis.plot(np.cos(theta), np.sin(theta), color="0.6", linewidth=0.8, linestyle="--")
    for i, system in enumerate(systems):
        color = f"C{i}"
        name = _name(system, i)
        poles, zeros = np.asarray(system.poles()), np.asarray(system.zeros())
        axis.plot(poles.real, poles.imag, "x", color=color, markersize=8, label=f"{name} poles")
        axis.plot(zeros.real, zeros.imag, "o", color=color, markerfacecolor="none", label=f"{name} zeros")
    axis.axhline(0.0, color="k", linewidth=0.5)
    axis.axvline(0.0, color="k", linewidth=0.5)
    axis.set_aspect("equal", adjustable="datalim")
    axis.set_xlabel("real")
    axis.set_ylabel("imaginary")
    axis.set_title("Pole-zero map of G", fontsize="medium")
    axis.legend(loc="upper left", bbox_to_anchor=(1.02, 1.0), fontsize="small")  # outside: keep z = 0 visible
    return axis.figure


def plot_bode(
    models,
    w: np.ndarray | None = None,
    true_system=None,
    axes: Sequence[Axes] | None = None,
) -> Figure:
    """Bode diagram of G (magnitude in dB, phase in degrees, against ω in rad/s).

    ``models``: one or several `PolyModel`s or python-control systems; ``true_system``
    (a python-control system) is drawn dashed in black.  ``w`` defaults to
    ``N_FREQUENCIES`` log-spaced points over ``DECADES`` decades below the smallest
    model's Nyquist frequency π/Ts.  ``axes`` is a (magnitude, phase) pair or None.
    """
    systems = _as_list(models, "plot_bode")
    if w is None:
        dts = [_sampling_period(s) for s in systems + ([true_system] if true_system is not None else [])]
        dts = [dt for dt in dts if dt]
        if not dts:
            raise ValueError("plot_bode: no discrete-time model to take a frequency range from; pass w (rad/s)")
        nyquist = np.pi / min(dts)
        w = np.logspace(np.log10(nyquist) - DECADES, np.log10(nyquist), N_FREQUENCIES)
    w = np.asarray(w, dtype=float)
    if w.ndim != 1 or w.size == 0 or np.any(~np.isfinite(w)) or np.any(w <= 0):
        raise ValueError("plot_bode: w must be a non-empty 1-D array of positive frequencies in rad/s")
    ax_mag, ax_phase = _axes_pair(axes, "plot_bode")
    curves = [(s, _name(s, i), {"color": f"C{i}"}) for i, s in enumerate(systems)]
    if true_system is not None:
        curves.append((true_system, _name(true_system, -1, "true system"), {"color": "k", "linestyle": "--"}))
    for system, name, style in curves:
        response = _frequency_response(system, w)
        ax_mag.semilogx(w, 20.0 * np.log10(np.abs(response)), label=name, **style)
        ax_phase.semilogx(w, np.degrees(np.unwrap(np.angle(response))), label=name, **style)
    ax_mag.set_ylabel("magnitude (dB)")
    ax_phase.set_ylabel("phase (deg)")
    ax_phase.set_xlabel("frequency ω (rad/s)")
    ax_mag.set_title("Bode diagram of G", fontsize="medium")
    for axis in (ax_mag, ax_phase):
        axis.grid(True, which="both", linewidth=0.3)
    ax_mag.legend(loc="best", fontsize="small")
    return ax_mag.figure


# ---------------------------------------------------------------------------- helpers
def _axes(ax: Axes | None) -> Axes:
    return Figure(figsize=(7, 4.5), layout="constrained").add_subplot() if ax is None else ax


def _axes_pair(ax: Sequence[Axes] | None, caller: str) -> tuple[Axes, Axes]:
    if ax is None:
        fig = Figure(figsize=(7, 6), layout="constrained")
        return tuple(fig.subplots(2, 1))
    pair = list(ax)
    if len(pair) != 2 or not all(isinstance(a, Axes) for a in pair):
        raise ValueError(f"{caller}: expected a pair of matplotlib Axes or None, got {ax!r}")
    return pair[0], pair[1]


def _as_list(models, caller: str) -> list:
    systems = [models] if _is_system(models) else list(models) if isinstance(models, Sequence) else None
    if not systems or not all(_is_system(s) for s in systems):
        raise ValueError(
            f"{caller}: models must be a PolyModel or python-control system, or a non-empty sequence of them"
        )
    return systems


def _is_system(obj) -> bool:
    if isinstance(obj, PolyModel):
        return True
    import control as ct

    return isinstance(obj, ct.LTI)


def _name(system, index: int, default: str | None = None) -> str:
    name = system.label if isinstance(system, PolyModel) and not system.name else getattr(system, "name", None)
    return str(name) if name else (default or f"model {index + 1}")


def _sampling_period(system) -> float | None:
    dt = system.Ts if isinstance(system, PolyModel) else system.dt
    return float(dt) if dt not in (None, 0, True) else None


def _frequency_response(system, w: np.ndarray) -> np.ndarray:
    if isinstance(system, PolyModel):
        return system.freqresp(w)
    import control as ct

    if not system.issiso():
        raise ValueError(f"plot_bode: {system.name} is not single-input single-output")
    return np.asarray(ct.frequency_response(system, w).complex).reshape(-1)
