"""The study's figures: each model run's four, the ranking's (best vs worst, binary vs uniform), orders.

Drawn on ``Figure`` objects made without pyplot (safe headless), with the library's
plot helpers (:mod:`maglev.plots`), and rendered to PNG bytes so the ranking run logs
exactly the images the HTML report embeds.
"""

from __future__ import annotations

import math

import numpy as np
import pandas as pd
from matplotlib.figure import Figure
from matplotlib.transforms import ScaledTranslation

from maglev import raster
from maglev.plots import (LABEL_OFFSETS, clear, figure_grid, place_labels, plot_bode, plot_compare,
                          plot_pzmap, plot_resid, plot_step, text_size)

DPI = 150  # the report's figures: at least 150 dpi, sharp in print
RUN_DPI = 110  # each run's figures, browsed in the MLflow UI (≈ 800 px wide)
LEVEL = 0.99  # confidence level of every band the study draws
# the figures' fixed layouts (maglev.plots.figure_grid; inches): room for two-line titles, for the titles of a
# second row of panels below the first one's x labels, for the y labels of a second column and their wide ticks
RESID_MARGINS = {"top": 0.6, "hgap": 0.85, "wgap": 0.95}
ORDERS_MARGINS = {"left": 1.15, "hgap": 0.85, "wgap": 1.15}
# tick labels wider than the default leaves room for: a long record's AIC (−110000), a loss's 6 × 10⁻⁵
ORDERS_LABEL_OFFSETS = {"y": 0.9}
TICK_SPACE = 0.1  # from the axes to a tick label: the tick's length and its pad (3.5 + 3.5 pt)
LABEL_HEIGHT = 0.2  # an axis label's line at the default font size
LEGEND_ROW = 0.19  # a legend row at fontsize "small", and the legend's frame and padding:
LEGEND_FRAME = 0.15


def png(fig: Figure, dpi: int = DPI) -> bytes:
    """The figure as PNG bytes (:func:`maglev.raster.png`: texts from a cache of rasterised strings)."""
    return raster.png(fig, dpi)


def pngs(make, *args) -> bytes | dict[str, bytes]:
    """``make(*args)`` (a figure, or a dict of them) as PNG bytes: a module-level function, so that the renderer
    can draw a ranking's figures while the launcher goes on (:func:`maglev.study.render.offload`)."""
    made = make(*args)
    return {k: png(f) for k, f in made.items()} if isinstance(made, dict) else png(made)


def best_worst_figures(best, worst, resid_best, resid_worst, fit_best: float, fit_worst: float) -> dict:
    """``bode``: both overlaid; ``pzmap``: both maps together (99 % bounds and regions); ``resid``: their
    correlations side by side."""
    bode = plot_bode([best, worst], level=LEVEL)
    pz = plot_pzmap([best, worst], level=LEVEL)
    axes = figure_grid((13.0, 6.0), 2, 2, margins=RESID_MARGINS)
    fig = axes[0, 0].figure
    for col, (result, model, fit) in enumerate(((resid_best, best, fit_best), (resid_worst, worst, fit_worst))):
        plot_resid(result, ax=(axes[0, col], axes[1, col]))
        axes[0, col].set_title(f"{model.name} (val FIT {fit:.2f} %)\n{axes[0, col].get_title()}",
                               fontsize="medium")
    return {"bode": bode, "pzmap": pz, "resid": fig}


def comparison_figure(comp: pd.DataFrame, common: pd.DataFrame | None, structure: str) -> Figure:
    """Validation FIT of the structure's runs by orders and dataset; and, if given, FIT on common data."""
    datasets = list(dict.fromkeys(comp.sort_values(["input_class", "dataset"])["dataset"]))
    ncols = min(len(datasets), 2)
    # the legend hangs below the bar panel's x label: the margin grows with its rows
    legend_drop = LABEL_OFFSETS["x"] + LABEL_HEIGHT + 0.05
    margins = {"bottom": legend_drop + LEGEND_ROW * math.ceil(len(datasets) / max(ncols, 1)) + LEGEND_FRAME}
    if common is not None:
        heat_margins, heat_labels = _heatmap_layout(common)
        margins = {**heat_margins, "bottom": max(margins["bottom"], heat_margins["bottom"])}
    axes = figure_grid((12.0 if common is not None else 7.0, 4.5), 1, 2 if common is not None else 1,
                       margins=margins)[0]
    fig = axes[0].figure
    ax = axes[0]
    orders = list(dict.fromkeys(comp["orders"]))
    width = 0.8 / max(len(datasets), 1)
    for j, ds in enumerate(datasets):
        # several runs of one dataset and orders (records of other seeds): one bar, their mean
        rows = comp[comp["dataset"] == ds].groupby("orders", sort=False).agg(
            val_fit=("val_fit", "mean"), runs=("val_fit", "size"), input_class=("input_class", "first"))
        cls = rows["input_class"].iloc[0]
        x = [i + (j - (len(datasets) - 1) / 2) * width for i, o in enumerate(orders) if o in rows.index]
        y = [rows.loc[o, "val_fit"] for o in orders if o in rows.index]
        runs = int(rows["runs"].max())
        label = f"{ds} ({cls})" + (f", mean of up to {runs} runs" if runs > 1 else "")
        bars = ax.bar(x, y, width, label=label, hatch="//" if cls == "binary" else None,
                      edgecolor="k", linewidth=0.5)
        ax.bar_label(bars, fmt="%.1f", fontsize="x-small")
    low = float(np.nanmin(comp["val_fit"]))
    # from 0 (below it only when a FIT is negative): bar lengths compare; to 105: the values over bars near 100 %
    ax.set_ylim(min(0.0, low - 5.0), 105.0)
    # the order vectors under the bars, the structure once below them: long labels ran into each other
    ax.set_xticks(range(len(orders)), [str(o) for o in orders])
    ax.set_ylabel("one-step FIT on own validation data (%)")
    ax.set_xlabel(f"orders of {structure}")
    ax.set_title(f"{structure}: binary (hatched) vs uniform input", fontsize="medium")
    ax.legend(loc="upper center", bbox_to_anchor=(0.5, 0.0), ncols=ncols, fontsize="small",
              bbox_transform=ax.transAxes + ScaledTranslation(0.0, -legend_drop, fig.dpi_scale_trans))
    # below the axes: inside, it covered the bars of FITs near 100 %
    if common is not None:
        ax2 = axes[1]
        values = common.to_numpy(dtype=float)
        image = ax2.imshow(values, cmap="viridis", aspect="auto")
        for (i, k), v in np.ndenumerate(values):
            ax2.text(k, i, "" if np.isnan(v) else f"{v:.1f}", ha="center", va="center", color="w",
                     fontsize="small")
        ax2.set_xticks(range(values.shape[1]), list(common.columns), rotation=30, ha="right",
                       rotation_mode="anchor")  # anchored at the tick: long record names do not run into each other
        ax2.set_yticks(range(values.shape[0]), list(common.index), fontsize="small")
        ax2.set_title("FIT % of each model on each validation set", fontsize="medium")
        ax2.set_xlabel("validation data")
        ax2.set_ylabel("model")
        place_labels(ax2, **heat_labels)
        fig.colorbar(image, ax=ax2, label="one-step FIT (%)")
    return fig


def _heatmap_layout(common: pd.DataFrame) -> tuple[dict[str, float], dict[str, float]]:
    """The comparison figure's margins and the heatmap's label offsets (inches; :func:`maglev.plots.figure_grid`,
    :func:`maglev.plots.place_labels`) for its tick labels, measured: the model names left of it (fontsize
    small), the validation sets' names below it, turned by 30°."""
    ywidth = max(text_size(str(name), "small")[0] for name in common.index)
    xwidth, xheight = max(text_size(str(name)) for name in common.columns)
    turned = TICK_SPACE + xwidth * math.sin(math.radians(30)) + xheight * math.cos(math.radians(30))
    labels = {"x": turned + 0.05, "y": TICK_SPACE + ywidth + 0.05}
    margins = {"bottom": labels["x"] + LABEL_HEIGHT + 0.1, "wgap": labels["y"] + LABEL_HEIGHT + 0.15, "right": 0.3}
    return margins, labels


def run_figures(inputs, reuse: dict[str, Figure] | None = None) -> dict:
    """The five figures of one model run (``inputs``: :class:`maglev.study.identify.FigureInputs`), with
    99 % bounds from the model's covariance: compare (one-step and simulation), resid, pzmap, step and
    Bode.  The Bode diagram overlays the reference G is scored against: the simulator's BLA for the
    dataset's input class with its 99 % band, else this record's own spectral estimate with its band;
    and the small-signal Jacobian dashed where known.

    ``reuse``: a dict in which the figures are kept to draw the next run's on them, emptied
    (:func:`maglev.plots.clear`): the same images for about a third less CPU than new figures (the
    renderer of a sweep draws every run's this way); a figure returned is then valid until the next call."""
    from maglev.spectral import frequency_response

    prep, model, rr, true_sys, ref = inputs.prepared, inputs.model, inputs.resid, inputs.true_system(), inputs.bla
    yhat, ysim, val_fit, val_fit_sim, horizon = (inputs.yhat, inputs.ysim, inputs.val_fit, inputs.val_fit_sim,
                                                 inputs.horizon)
    label = model.label

    def compare(axes):
        fig = plot_compare(prep.val, [yhat, ysim], [val_fit, val_fit_sim], ax=axes,
                           labels=[f"{label} {horizon}-step", f"{label} simulation"])
        fig.axes[0].set_title(f"Validation data {prep.val_name}", fontsize="medium")
        return fig

    systems = [model] + ([true_sys] if true_sys is not None else [])
    reference = (ref.bounds(LEVEL, "BLA of the simulator, this input class") if ref is not None else
                 frequency_response(prep.data).bounds(LEVEL, "spectral estimate of this record"))
    draw = {"compare.png": compare,
            "resid.png": lambda axes: plot_resid(rr, ax=axes),
            "pzmap.png": lambda axes: plot_pzmap(systems, ax=axes, level=LEVEL),
            "step.png": lambda axes: plot_step(systems, ax=None if axes is None else axes[0], level=LEVEL),
            "bode.png": lambda axes: plot_bode([model, reference], true_system=true_sys, axes=axes, level=LEVEL)}
    return {name: _drawn(reuse, name, how) for name, how in draw.items()}


def _drawn(reuse: dict[str, Figure] | None, name: str, draw) -> Figure:
    """``draw(axes)`` on the figure ``reuse`` keeps under ``name``, emptied; on a new one (``axes`` None) the
    first time, or without ``reuse``."""
    fig = None if reuse is None else reuse.pop(name, None)  # popped: a drawing that raises leaves no half figure
    if fig is None:
        fig = draw(None)
        if reuse is not None:
            raster.TextCachingCanvas(fig)  # kept with its renderer, and that one's text-size and mathtext caches
    else:
        fig = draw(clear(fig).axes)
    if reuse is not None:
        reuse[name] = fig
    return fig


def orders_figure(runs: pd.DataFrame) -> Figure:
    """Loss, AIC and validation FIT against the number of parameters, one row per structure."""
    structures = list(dict.fromkeys(runs["structure"]))
    axes = figure_grid((12.0, 2.8 * len(structures)), len(structures), 3, margins=ORDERS_MARGINS,
                       label_offsets=ORDERS_LABEL_OFFSETS)
    fig = axes[0, 0].figure
    for i, st in enumerate(structures):
        part = runs[runs["structure"] == st]
        for ds, g in part.groupby("dataset"):
            g = g.sort_values("n_params")
            for j, (col, log) in enumerate((("loss", True), ("aic", False), ("val_fit", False))):
                axes[i, j].plot(g["n_params"], g[col], "o-", label=str(ds))
                axes[i, j].set_yscale("log" if log else "linear")
        for j, (label, unit) in enumerate((("loss", "estimation MSE, cm²"), ("AIC", "–"),
                                           ("validation FIT", "%"))):
            axes[i, j].set_title(f"{st}: {label}", fontsize="medium")
            axes[i, j].set_ylabel(f"{label} ({unit})")
            axes[i, j].set_xlabel("free parameters (count)")
        axes[i, 0].legend(fontsize="x-small")
    return fig


def preparation_figure(lin, blas: dict) -> Figure:
    """|G| of a linearisation at the working point (``lin``: :class:`maglev.sim.plant.LinearModel`) and of the best
    linear approximation of each input class (``blas``: dataset name → :class:`maglev.sim.bla.BLA`); the title
    promises BLAs only when there are some."""
    curves = [ref.bounds(LEVEL, f"BLA, {name}") for name, ref in blas.items()]
    import control as ct

    jac = ct.ss(lin.sys_d.A, lin.sys_d.B, lin.sys_d.C, lin.sys_d.D, lin.sys_d.dt, name="linearisation at u*")
    fig = plot_bode(curves or [jac], true_system=jac if curves else None)
    fig.axes[0].set_title("Linearisation at the working point" + (" and best linear approximations" if curves else
                                                                  " (no simulated dataset: no BLA)"), fontsize="medium")
    return fig
