"""Figures of the lab steps (the lab's Figs. 3-5), drawn on ``Figure`` objects made without pyplot.

Each step computes a result (:mod:`maglev.lab.working_region`, :mod:`~maglev.lab.sampling`,
:mod:`~maglev.lab.input_design`) and these functions draw it — python-control's split
of computing a response and plotting it — so computing a step never imports matplotlib.
"""

from __future__ import annotations

import numpy as np
from matplotlib.axes import Axes
from matplotlib.figure import Figure

from maglev.lab.input_design import AlphaChoice, OutputSpectrum
from maglev.lab.sampling import RiseTime
from maglev.lab.signals import rbs_spectrum
from maglev.lab.working_region import WorkingRegion
from maglev.plots import figure_grid
from maglev.units import U_UNIT, Y_UNIT

__all__ = ["plot_working_region", "plot_rise_time", "plot_output_spectrum", "plot_alpha"]


def _axes(ax: Axes | None) -> Axes:
    """``ax``, or the axes of a new figure with :mod:`maglev.plots`' fixed layout (no layout engine)."""
    return figure_grid((6.0, 4.0))[0, 0] if ax is None else ax


def plot_working_region(r: WorkingRegion, ax: Axes | None = None, u_unit: str = U_UNIT,
                        y_unit: str = Y_UNIT) -> Figure:
    """ȳ vs ū with the fitted line and the region's bounds and centre (the lab's Fig. 3)."""
    ax = _axes(ax)
    inside = slice(r.lo, r.hi + 1)
    ax.plot(r.u_bar, r.y_bar, "s", mfc="none", color="tab:red", label="stationary averages")
    uu = np.array([r.u_min, r.u_max])
    ax.plot(uu, r.slope * uu + r.intercept, "k-", label=f"LS line, slope {r.slope:.3g} {y_unit}/{u_unit}")
    ax.plot(r.u_bar[inside], r.y_bar[inside], "s", color="tab:red")
    for edge in uu:
        ax.axvline(edge, color="k", lw=0.8)
    ax.axvline(r.u_star, color="k", ls=":", label=f"working point {r.u_star:.3g} {u_unit}")
    ax.set_xlabel(f"step level ū ({u_unit})")
    ax.set_ylabel(f"stationary output ȳ ({y_unit})")
    ax.set_title(f"Working region [{r.u_min:.3g}, {r.u_max:.3g}] {u_unit}")
    ax.legend(loc="best", fontsize="small")
    return ax.figure


def plot_rise_time(r: RiseTime, ax: Axes | None = None) -> Figure:
    """The averaged normalised step response with the 10 % and 90 % crossings (the lab's Fig. 4)."""
    ax = _axes(ax)
    ax.plot(np.arange(r.response.size), r.response, color="tab:blue",
            label=f"mean of {r.n_steps} normalised steps")
    for level, t in ((0.1, r.t10), (0.9, r.t90)):
        ax.axhline(level, color="k", lw=0.6, ls=":")
        ax.axvline(t, color="tab:red", lw=0.8)
    ax.set_xlabel("time after the step (samples)")
    ax.set_ylabel("normalised output (–)")
    ax.set_title(f"Rise time {r.samples:.1f} samples = {r.seconds * 1e3:.3g} ms; "
                 f"decimate by {r.decimation}")
    ax.legend(loc="lower right", fontsize="small")
    return ax.figure


def plot_output_spectrum(r: OutputSpectrum, ax: Axes | None = None) -> Figure:
    """|Y| against normalised frequency with the energy band shaded, on a logarithmic frequency axis: the band of a
    slow plant is a small fraction of the Nyquist range (under 2 % on the lab's records), invisible on a linear one."""
    ax = _axes(ax)
    keep = r.w > 0
    ax.loglog(r.w[keep] / np.pi, r.magnitude[keep], lw=0.6, color="tab:blue", label="|FFT(y - mean y)|")
    ax.axvspan(r.band[0] / np.pi, r.band[1] / np.pi, color="tab:orange", alpha=0.3,
               label=f"{r.fraction:.0%} of the energy")
    ax.set_xlabel("ω / π (1 = the Nyquist frequency)")
    ax.set_ylabel(f"|Y| ({Y_UNIT})")
    ax.legend(loc="best", fontsize="small")
    return ax.figure


def plot_alpha(r: AlphaChoice, ax: Axes | None = None) -> Figure:
    """Binary-signal spectra for each α with the output's energy band shaded (the lab's Fig. 5), on a logarithmic
    frequency axis from below the band's lower edge (α = 0's line at ω = 0 is drawn at the axis' left edge)."""
    ax = _axes(ax)
    low = min(r.band[0] if r.band[0] > 0 else np.pi * 1e-3, np.pi * 1e-3) / 2
    w = np.geomspace(low, np.pi - 1e-3, 600)
    for alpha, share in zip(r.alphas, r.shares):
        style = "-" if alpha == r.alpha_star else "--"
        if 0 < alpha < 1:
            ax.plot(w / np.pi, rbs_spectrum(alpha, w), style, label=f"α = {alpha:g} ({share:.0%} in band)")
        else:
            where, at = (w[0] / np.pi, "0 (left edge)") if alpha == 0 else (1.0, "π")
            ax.axvline(where, ls=style, color="gray", label=f"α = {alpha:g}: line at ω = {at}")
    ax.axvspan(r.band[0] / np.pi, r.band[1] / np.pi, color="tab:orange", alpha=0.3,
               label="output energy band")
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_xlabel("ω / π (1 = the Nyquist frequency)")
    ax.set_ylabel("Φ_s(ω) (–, unit-variance signal)")
    ax.set_title(f"α* = {r.alpha_star:g}")
    low, high = ax.get_ylim()
    ax.set_ylim(low, high * 12)  # room above the spectra for the legend, which otherwise hides α*'s curve
    ax.legend(loc="upper center", fontsize="small", ncol=2)
    return ax.figure
