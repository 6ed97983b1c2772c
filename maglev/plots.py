"""The identification figures: residual correlations, compare, pole-zero map, Bode, step response.

The study logs these figures to MLflow and the report embeds them, so each helper
draws on axes it is given (or on a new ``Figure`` made without pyplot, which is safe
headless and never opens a window) and returns the ``Figure``.  Models may be
`PolyModel`s or python-control systems, so a true plant can be overlaid on estimates.

Confidence bounds (``level`` or ``sd``, as in :mod:`maglev.uncertainty`, which computes
them) are drawn for every `PolyModel` that carries a finite covariance: shaded bands on
Bode and step plots, ellipses (complex roots) or segments (real roots) on pole-zero
maps.  With neither argument no bounds are drawn; models without a (finite) covariance,
such as python-control systems or estimates from singular data, are drawn without.

Figures use a fixed layout (margins in inches) rather than constrained layout, and
few text objects: at 150 dpi the layout engine and tick-label text dominate the cost
of a figure, and a study run draws several per model.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from matplotlib.axes import Axes
from matplotlib.figure import Figure
from matplotlib.font_manager import FontProperties
from matplotlib.patches import Rectangle
from matplotlib.textpath import text_to_path
from matplotlib.ticker import LogLocator, MaxNLocator
from matplotlib.transforms import ScaledTranslation

from .data import IOData
from .model import PolyModel
from .uncertainty import FrequencyBounds, frequency_bounds, root_regions, step_bounds, step_length
from .units import U_UNIT, Y_UNIT
from .validation import ResidResult, format_p

N_FREQUENCIES = 300
MAX_POINTS = 2000  # samples drawn per line over a whole record (≈ 2 per pixel at the figures' size)
DECADES = 3  # default Bode range: 10^-3 … 1 times the Nyquist frequency
COMPARE_WINDOW = 0.1  # default zoom of plot_compare: the middle 10 % of the record
MIN_WINDOW_SAMPLES = 50
FLOOR_DB = 40.0  # a magnitude band whose lower bound reaches 0 is drawn down to 40 dB below the curve
ZOOM_PAD = 0.3  # pole-zero zoom: half-width = (0.5 + ZOOM_PAD) × the poles' spread …
MIN_ZOOM = 1e-3  # … but at least this
CONTEXT_REACH = 3.0  # the context panel shows |z| up to this at most
BAND_ALPHA = 0.2
MINOR_SUBS = (2.0, 5.0)  # minor ticks of the Bode frequency axis
N_TICKS = 5  # at most this many intervals on a linear axis: every tick is a Text to lay out
MEASURED = {"color": "k", "linewidth": 1.4, "zorder": 3}  # measured output: black, thicker, on top


def plot_resid(result: ResidResult, ax: Sequence[Axes] | None = None) -> Figure:
    """Autocorrelation of the residuals and their cross-correlation with the input, with 99 % bands.

    ``ax`` is a pair of axes (autocorrelation, cross-correlation) or None for a new figure.
    """
    if not isinstance(result, ResidResult):
        raise TypeError(f"plot_resid: result must be a ResidResult, got {type(result).__name__}")
    ax_auto, ax_cross = _axes_pair(ax, "plot_resid")
    for axis, lags, corr, band, title in (
        (ax_auto, result.auto_lags, result.auto_corr, result.auto_band,
         f"Residual autocorrelation (whiteness p = {format_p(result.whiteness_pvalue)})"),
        (ax_cross, result.cross_lags, result.cross_corr, result.cross_band,
         f"Residual-input cross-correlation (independence p = {format_p(result.independence_pvalue)})"),
    ):
        axis.fill_between(lags, -band, band, color="tab:blue", alpha=0.15, label="99 % band")
        axis.plot(lags, corr, "o-", color="tab:blue", markersize=3, label="estimate")
        axis.axhline(0.0, color="k", linewidth=0.5)
        axis.set_title(title, fontsize="medium")
        axis.set_ylabel("correlation (–)")
        axis.legend(loc="upper right", fontsize="small")
    _few_ticks(ax_auto, ax_cross)
    ax_auto.set_xlabel("lag τ (samples)")
    ax_cross.set_xlabel("lag τ (samples; τ > 0: input leads residual)")
    return ax_auto.figure


def plot_compare(
    data: IOData,
    yhat: np.ndarray | Sequence[np.ndarray],
    fit: float | Sequence[float],
    ax: Sequence[Axes] | None = None,
    labels: Sequence[str] | None = None,
    window: tuple[float, float] | None = None,
    y_unit: str = Y_UNIT,
) -> Figure:
    """Measured output and one or several predictions: the whole record, and a zoomed window below it.

    ``yhat``/``fit`` are one prediction and its FIT % or sequences of them (as
    :func:`maglev.validation.compare` returns for one or several models).  The measured
    output is drawn last, black and thicker, so it stays visible; ``window`` = (t0, t1)
    in seconds (default: the middle ``COMPARE_WINDOW`` of the record) is shaded on the
    upper panel and shown in the lower one.  ``ax``: a (whole record, zoom) pair or None.
    """
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
    zoom = _window(data, window)
    ax_all, ax_zoom = _axes_pair(ax, "plot_compare", size=(8.0, 6.0))
    t = data.t
    whole = slice(None, None, max(1, -(-data.N // MAX_POINTS)))  # the overview needs no more points than pixels
    for axis, keep in ((ax_all, whole), (ax_zoom, zoom)):
        lines = [axis.plot(t[keep], p[keep], linewidth=1.0, color=f"C{i}", zorder=2)[0]
                 for i, p in enumerate(preds)]
        measured = axis.plot(t[keep], data.y[keep], **MEASURED)[0]
        axis.set_ylabel(f"y ({y_unit})")
        axis.set_xlabel("time (s)")
    _few_ticks(ax_all, ax_zoom)
    ax_all.axvspan(t[zoom.start], t[zoom.stop - 1], color="0.85", zorder=0)
    ax_zoom.set_xlim(t[zoom.start], t[zoom.stop - 1])
    ax_all.set_xlim(t[0], t[-1])
    ax_all.legend([measured, *lines], ["measured", *(f"{n}: FIT {f:.1f} %" for n, f in zip(names, fits))],
                  loc="upper right", fontsize="small")
    return ax_all.figure


def plot_pzmap(
    models,
    ax: Sequence[Axes] | None = None,
    level: float | None = None,
    sd: float | None = None,
) -> Figure:
    """Poles (x) and zeros (o) of G: the unit circle with everything (left) and a zoom on the poles (right).

    ``models``: a `PolyModel` or python-control system, or a sequence of them.  With
    ``level`` or ``sd`` every `PolyModel` with a covariance gets confidence regions
    (:func:`maglev.uncertainty.root_regions`): around its poles on both panels, around
    its zeros on the left one only (an over-parameterised B has zeros whose regions span
    the plane; they would hide the poles).  The zoom is a square around all models'
    poles (``ZOOM_PAD`` margin, at least ``MIN_ZOOM`` half-width), marked by a rectangle
    on the left panel; it shows the unit circle's arc where it crosses the window.  The
    left panel frames the unit circle, the zoom and the roots out to |z| = ``CONTEXT_REACH`` at
    most (widened to the panel's shape) and says how many roots lie beyond.  ``ax``: a (context, zoom) pair or None.
    """
    systems = _as_list(models, "plot_pzmap")
    bounds = level is not None or sd is not None
    ax_all, ax_zoom = _axes_pair(ax, "plot_pzmap", size=(10.0, 5.0), rows=1)
    pole_sets, everything, handles = [], [], []
    for i, system in enumerate(systems):
        style = {"color": f"C{i}", "linestyle": "none"}
        poles, zeros = np.asarray(system.poles(), dtype=complex), np.asarray(system.zeros(), dtype=complex)
        pole_sets.append(poles)
        everything += [poles, zeros]
        regions = {}
        if bounds and _has_covariance(system):
            regions = {kind: root_regions(system, kind, level, sd) for kind in ("poles", "zeros")}
        for axis in (ax_all, ax_zoom):
            handle = axis.plot(poles.real, poles.imag, marker="x", markersize=8, **style)[0]
            axis.plot(zeros.real, zeros.imag, marker="o", markerfacecolor="none", **style)
            for kind, region in regions.items():
                if kind == "zeros" and axis is ax_zoom:
                    continue
                for j in range(region.roots.size):
                    edge = region.outline(j)
                    axis.plot(edge.real, edge.imag, color=f"C{i}", linewidth=0.8)
        handles.append(handle)
    centre, half = _zoom_square(np.concatenate(pole_sets))
    _unit_circle(ax_all, None)
    _unit_circle(ax_zoom, (centre, half))
    ax_zoom.set_xlim(centre.real - half, centre.real + half)
    ax_zoom.set_ylim(centre.imag - half, centre.imag + half)
    radii = np.abs(np.concatenate(everything))
    radii = radii[np.isfinite(radii)]
    reach = max(1.1, abs(centre.real) + half, abs(centre.imag) + half,
                min(1.05 * float(radii.max(initial=0.0)), CONTEXT_REACH))
    beyond = int(np.sum(radii > reach))
    roots = np.concatenate(everything)
    roots = roots[np.isfinite(roots) & (np.abs(roots) <= reach)]
    corners = centre + half * np.array([1 + 1j, -1 - 1j])
    shown = np.concatenate([roots, corners, [1.1, -1.1, 1.1j]])  # the roots, the zoom's frame, the unit circle
    pad = 0.05 * reach
    _fill_panel(ax_all, (shown.real.min() - pad, shown.real.max() + pad),
                (-np.abs(shown.imag).max() - pad, np.abs(shown.imag).max() + pad))  # conjugates: symmetric
    ax_all.add_patch(Rectangle((centre.real - half, centre.imag - half), 2 * half, 2 * half,
                               fill=False, edgecolor="0.3", linewidth=0.8))
    _few_ticks(ax_all, ax_zoom)
    for axis in (ax_all, ax_zoom):
        axis.set_aspect("equal", adjustable="box")
        axis.set_xlabel("Re z (–)")
    ax_all.set_ylabel("Im z (–)")
    what = "" if not bounds else f", {_level_text(level, sd)} regions"
    off = f" ({beyond} beyond |z| = {reach:.3g})" if beyond else ""
    ax_all.set_title(f"Poles (x) and zeros (o) of G{what}{off}", fontsize="medium")
    ax_zoom.set_title("zoom on the poles", fontsize="medium")
    ax_zoom.legend(handles, [_name(s, i) for i, s in enumerate(systems)], loc="upper left", fontsize="small")
    return ax_all.figure


def plot_bode(
    models,
    w: np.ndarray | None = None,
    true_system=None,
    axes: Sequence[Axes] | None = None,
    level: float | None = None,
    sd: float | None = None,
    u_unit: str = U_UNIT,
    y_unit: str = Y_UNIT,
) -> Figure:
    """Bode diagram of G (magnitude in dB re 1 ``y_unit``/``u_unit``, phase in degrees, against ω in rad/s).

    ``models``: one or several `PolyModel`s, python-control systems or precomputed
    `FrequencyBounds` (drawn on their own frequencies with their own band, e.g. a
    nonparametric estimate with its standard error); ``true_system`` (a python-control
    system) is drawn dashed in black.  With ``level`` or ``sd`` each `PolyModel` with a
    covariance gets a shaded band (:func:`maglev.uncertainty.frequency_bounds`).  ``w``
    defaults to ``N_FREQUENCIES`` log-spaced points over ``DECADES`` decades below the
    smallest model's Nyquist frequency π/Ts.  ``axes`` is a (magnitude, phase) pair or None.
    """
    systems = _as_list(models, "plot_bode", FrequencyBounds)
    curves = [(s, _name(s, i), {"color": f"C{i}"}) for i, s in enumerate(systems)]
    if true_system is not None:
        curves.append((true_system, _name(true_system, -1, "true system"), {"color": "k", "linestyle": "--"}))
    if w is None:
        dts = [_sampling_period(s) for s, _, _ in curves if not isinstance(s, FrequencyBounds)]
        dts = [dt for dt in dts if dt]
        if not dts:
            raise ValueError("plot_bode: no discrete-time model to take a frequency range from; pass w (rad/s)")
        nyquist = np.pi / min(dts)
        w = np.logspace(np.log10(nyquist) - DECADES, np.log10(nyquist), N_FREQUENCIES)
    w = np.asarray(w, dtype=float)
    if w.ndim != 1 or w.size == 0 or np.any(~np.isfinite(w)) or np.any(w <= 0):
        raise ValueError("plot_bode: w must be a non-empty 1-D array of positive frequencies in rad/s")
    ax_mag, ax_phase = _axes_pair(axes, "plot_bode", sharex=True)
    for system, name, style in curves:
        band = system if isinstance(system, FrequencyBounds) else None
        if band is None and (level is not None or sd is not None) and _has_covariance(system):
            band = frequency_bounds(system, w, level, sd)
        if band is not None:
            x, response = band.w, band.response
            mag_db = _db(band.magnitude)
            floor = mag_db - FLOOR_DB
            low = np.maximum(_db(band.magnitude_lower), floor)
            ax_mag.fill_between(x, low, _db(band.magnitude_upper), color=style["color"], alpha=BAND_ALPHA,
                                linewidth=0)
            ax_phase.fill_between(x, band.phase_lower, band.phase_upper, color=style["color"], alpha=BAND_ALPHA,
                                  linewidth=0)
        else:
            x, response = w, _frequency_response(system, w)
        ax_mag.semilogx(x, _db(np.abs(response)), label=name, **style)
        ax_phase.semilogx(x, np.degrees(np.unwrap(np.angle(response))), label=name, **style)
    ax_mag.set_ylabel(f"|G| (dB re 1 {y_unit}/{u_unit})")
    ax_phase.set_ylabel("phase (deg)")
    ax_phase.set_xlabel("frequency ω (rad/s)")
    what = "" if level is None and sd is None else f" with {_level_text(level, sd)} bounds"
    ax_mag.set_title(f"Bode diagram of G{what}", fontsize="medium")
    for axis in (ax_mag, ax_phase):
        axis.grid(True, which="major", linewidth=0.3)
    ax_phase.xaxis.set_minor_locator(LogLocator(subs=MINOR_SUBS))  # few minor ticks: each costs a Text
    ax_mag.legend(loc="lower left", fontsize="small")
    return ax_mag.figure


def plot_arxstruc(table, chosen: Sequence[tuple[int, int, str]] = (), ax: Axes | None = None) -> Figure:
    """MATLAB's ``selstruc`` plot: the smallest validation loss for each number of parameters of an
    ``arxstruc`` table, with the chosen (na, nb, label) models marked."""
    axis = _axes(ax)
    best = table.loc[table.groupby("n_params")["loss"].idxmin()]
    axis.semilogy(best["n_params"], best["loss"], "o-", color="C0", markersize=4,
                  label="best ARX per number of parameters")
    for i, (na, nb, label) in enumerate(chosen):
        row = table[(table["na"] == na) & (table["nb"] == nb)].iloc[0]
        axis.semilogy([row["n_params"]], [row["loss"]], "sD^"[i % 3], markersize=9 + 4 * i, markerfacecolor="none",
                      color=f"C{i + 1}", label=f"{label}: na = {na}, nb = {nb}")  # growing: one never hides another
    axis.set_xlabel("parameters na + nb (count)")
    axis.set_ylabel(f"validation loss (mean squared one-step error, {Y_UNIT}²)")
    axis.legend(loc="upper right", fontsize="small")
    return axis.figure


def plot_step(
    models,
    n: int | None = None,
    ax: Axes | None = None,
    level: float | None = None,
    sd: float | None = None,
    u_unit: str = U_UNIT,
    y_unit: str = Y_UNIT,
) -> Figure:
    """Response of G to a unit input step from rest, with shaded bounds for `PolyModel`s with a covariance.

    ``models``: one or several `PolyModel`s or discrete-time python-control systems (all
    with one sampling period).  ``n`` samples; default: the longest
    :func:`maglev.uncertainty.step_length` of the `PolyModel`s (or 200 samples).
    """
    systems = _as_list(models, "plot_step")
    dts = {_sampling_period(s) for s in systems}
    if None in dts or len(dts) != 1:
        raise ValueError("plot_step: all models must be discrete-time with one sampling period, "
                         f"got {sorted(map(str, dts))}")
    (dt,) = dts
    if n is None:
        lengths = [step_length(s) for s in systems if isinstance(s, PolyModel)]
        n = max(lengths) if lengths else 200
    axis = _axes(ax)
    for i, system in enumerate(systems):
        color = f"C{i}"
        if (level is not None or sd is not None) and _has_covariance(system):
            result = step_bounds(system, n, level, sd)
            t, y = result.t, result.y
            axis.fill_between(t, result.lower, result.upper, step="post", color=color, alpha=BAND_ALPHA, linewidth=0)
        else:
            t = np.arange(n) * dt
            y = system.simulate(np.ones(n)) if isinstance(system, PolyModel) else _control_step(system, t)
        axis.plot(t, y, drawstyle="steps-post", color=color, label=_name(system, i))
    _few_ticks(axis)
    axis.set_xlabel("time (s)")
    axis.set_ylabel(f"y ({y_unit}) for a 1 {u_unit} step")
    what = "" if level is None and sd is None else f" with {_level_text(level, sd)} bounds"
    axis.set_title(f"Step response of G{what}", fontsize="medium")
    axis.grid(True, linewidth=0.3)
    axis.legend(loc="lower right", fontsize="small")
    return axis.figure


def clear(fig: Figure) -> Figure:
    """Empty ``fig`` of what the helpers drew (lines, bands, markers, patches, texts, legends, titles, axis
    labels), keeping its axes with their ticks, scales, locators and fixed layout, so that the next figure of
    the same kind is drawn on them (``ax=fig.axes``).  It looks as it would on a new figure; matplotlib then
    builds neither the axes nor their tick texts again, which is most of what a new figure costs beyond its
    drawing (``maglev.study.render`` draws every run's figures this way)."""
    for axis in fig.axes:
        for artist in [*axis.lines, *axis.collections, *axis.patches, *axis.texts, *axis.images,
                       *axis.artists, *axis.tables]:
            artist.remove()
        if axis.legend_ is not None:
            axis.legend_.remove()
        axis.containers.clear()
        axis.set_title("")
        axis.set_xlabel("")
        axis.set_ylabel("")
        axis.relim()  # no data left: the next lines set the limits afresh
        axis.set_autoscale_on(True)
        axis.set_prop_cycle(None)
    return fig


# ---------------------------------------------------------------------------- helpers
MARGINS = {"left": 0.9, "right": 0.25, "bottom": 0.55, "top": 0.35, "hgap": 0.75, "wgap": 0.75}  # inches
# from the axes to the x label's top and to the y label's right edge (inches): below the tick labels, and the
# y label at the figure's left edge, where every tick label that fits the margin leaves room for it
LABEL_OFFSETS = {"x": 0.31, "y": 0.65}


def figure_grid(size: tuple[float, float], rows: int = 1, cols: int = 1, sharex: bool = False,
                margins: dict[str, float] | None = None, label_offsets: dict[str, float] | None = None) -> np.ndarray:
    """A pyplot-free figure with a fixed ``rows`` × ``cols`` grid of axes: margins and the gaps between panels
    in inches (``MARGINS``, updated by ``margins``), titles and axis labels at fixed places (``LABEL_OFFSETS``,
    updated by ``label_offsets``; :func:`place_labels`).  No layout engine: drawing does not measure every
    tick label to place the axes, a large part of a figure's cost.  A figure whose tick labels or titles are
    longer than the defaults allow asks for wider margins (:func:`text_size` measures a string without drawing
    it)."""
    for given, known in ((margins, MARGINS), (label_offsets, LABEL_OFFSETS)):
        unknown = sorted(set(given or {}) - set(known))
        if unknown:
            raise ValueError(f"figure_grid: unknown key(s) {unknown}, expected some of {sorted(known)}")
    m = {**MARGINS, **(margins or {})}
    offsets = {**LABEL_OFFSETS, **(label_offsets or {})}
    fig = Figure(figsize=size)
    width, height = size
    hgap = m["hgap"] / 2 if sharex else m["hgap"]  # no tick labels between shared-x panels
    fig.subplots_adjust(
        left=m["left"] / width, right=1 - m["right"] / width,
        bottom=m["bottom"] / height, top=1 - m["top"] / height,
        hspace=hgap * rows / max(height - m["bottom"] - m["top"] - hgap * (rows - 1), 1e-3),
        wspace=m["wgap"] * cols / max(width - m["left"] - m["right"] - m["wgap"] * (cols - 1), 1e-3),
    )
    axes = fig.subplots(rows, cols, sharex=sharex, squeeze=False)
    for axis in axes.ravel():
        axis.set_title("", y=1.0)  # at the axes' top, not above the tick labels drawing would measure
        place_labels(axis, **offsets)
    return axes


def place_labels(axis: Axes, x: float, y: float) -> None:
    """The x label's top ``x`` inches below the axes, the y label's right edge ``y`` inches left of them."""
    inches = axis.figure.dpi_scale_trans
    axis.xaxis.set_label_coords(0.5, 0.0, axis.transAxes + ScaledTranslation(0.0, -x, inches))
    axis.yaxis.set_label_coords(0.0, 0.5, axis.transAxes + ScaledTranslation(-y, 0.0, inches))


def text_size(text: str, fontsize: str | float = "medium") -> tuple[float, float]:
    """Width and height (inches) of one line of ``text`` in the default font at ``fontsize``, from the font's
    metrics (no renderer, no figure): the room a fixed margin must leave for a label known only at run time."""
    width, height, _ = text_to_path.get_text_width_height_descent(text, FontProperties(size=fontsize), ismath=False)
    return width / 72.0, height / 72.0


def _axes(ax: Axes | None) -> Axes:
    return figure_grid((7.0, 4.5))[0, 0] if ax is None else ax


def _axes_pair(ax: Sequence[Axes] | None, caller: str, size=(7.0, 6.0), rows: int = 2,
               sharex: bool = False) -> tuple[Axes, Axes]:
    if ax is None:
        first, second = figure_grid(size, rows, 3 - rows, sharex).ravel()
        return first, second
    pair = list(ax)
    if len(pair) != 2 or not all(isinstance(a, Axes) for a in pair):
        raise ValueError(f"{caller}: expected a pair of matplotlib Axes or None, got {ax!r}")
    return pair[0], pair[1]


def _few_ticks(*axes: Axes) -> None:
    for axis in axes:
        axis.xaxis.set_major_locator(MaxNLocator(N_TICKS, steps=[1, 2, 5, 10]))
        axis.yaxis.set_major_locator(MaxNLocator(N_TICKS, steps=[1, 2, 5, 10]))


def _window(data: IOData, window: tuple[float, float] | None) -> slice:
    """Sample slice of the zoom window (seconds), default the middle ``COMPARE_WINDOW`` of the record."""
    N = data.N
    if window is None:
        length = min(N, max(MIN_WINDOW_SAMPLES, int(round(COMPARE_WINDOW * N))))
        start = (N - length) // 2
        return slice(start, start + length)
    try:
        t0, t1 = (float(v) for v in window)
    except (TypeError, ValueError):
        raise ValueError(f"plot_compare: window must be a pair (t0, t1) in seconds, got {window!r}") from None
    t = data.t
    if not (t[0] <= t0 < t1 <= t[-1]):
        raise ValueError(f"plot_compare: window {window!r} must satisfy {t[0]:g} <= t0 < t1 <= {t[-1]:g} s")
    start, stop = int(np.searchsorted(t, t0)), int(np.searchsorted(t, t1, side="right"))
    if stop - start < 2:
        raise ValueError(f"plot_compare: window {window!r} holds fewer than 2 samples (Ts = {data.Ts:g} s)")
    return slice(start, stop)


def _zoom_square(poles: np.ndarray) -> tuple[complex, float]:
    """Centre and half-width of a square around ``poles`` (the unit circle's centre if there are none)."""
    poles = poles[np.isfinite(poles)]
    if poles.size == 0:
        return 0j, 1.1
    lo = complex(poles.real.min(), poles.imag.min())
    hi = complex(poles.real.max(), poles.imag.max())
    centre = (lo + hi) / 2
    spread = max(hi.real - lo.real, hi.imag - lo.imag)
    return centre, max((0.5 + ZOOM_PAD) * spread, MIN_ZOOM)


def _fill_panel(axis: Axes, x: tuple[float, float], y: tuple[float, float]) -> None:
    """Limits holding the ranges ``x`` and ``y`` at equal scales, the shorter widened about its centre to the
    shape of the axes' panel, so that an equal-aspect plot fills it."""
    box = axis.get_position(original=True)  # the panel, not the box a previous draw fitted to its aspect
    width, height = box.width * axis.figure.get_figwidth(), box.height * axis.figure.get_figheight()
    scale = max((x[1] - x[0]) / width, (y[1] - y[0]) / height)  # data units per inch
    for setter, (lo, hi), inches in ((axis.set_xlim, x, width), (axis.set_ylim, y, height)):
        centre = (lo + hi) / 2
        setter(centre - scale * inches / 2, centre + scale * inches / 2)


def _unit_circle(axis: Axes, window: tuple[complex, float] | None) -> None:
    """The unit circle (dashed); within a zoom ``window`` only the arc that crosses it, finely sampled."""
    start, stop = 0.0, 2 * np.pi
    if window is not None:
        centre, half = window
        if abs(centre.real) > half or abs(centre.imag) > half:  # the window does not contain z = 0
            corners = centre + half * np.array([1 + 1j, 1 - 1j, -1 + 1j, -1 - 1j])
            offsets = np.angle(corners / centre)
            start = float(np.angle(centre) + offsets.min())
            stop = float(np.angle(centre) + offsets.max())
    theta = np.linspace(start, stop, 400)
    axis.plot(np.cos(theta), np.sin(theta), color="0.6", linewidth=0.8, linestyle="--")


def _level_text(level: float | None, sd: float | None) -> str:
    return f"{100 * level:g} %" if level is not None else f"{sd:g} SD"


def _db(magnitude: np.ndarray) -> np.ndarray:
    with np.errstate(divide="ignore"):
        return 20.0 * np.log10(magnitude)


def _as_list(models, caller: str, *extra: type) -> list:
    def ok(obj) -> bool:
        return isinstance(obj, extra) or _is_system(obj)

    systems = [models] if ok(models) else list(models) if isinstance(models, Sequence) else None
    if not systems or not all(ok(s) for s in systems):
        raise ValueError(
            f"{caller}: models must be a PolyModel or python-control system, or a non-empty sequence of them"
        )
    return systems


def _is_system(obj) -> bool:
    if isinstance(obj, PolyModel):
        return True
    import control as ct

    return isinstance(obj, ct.LTI)


def _has_covariance(system) -> bool:
    """A `PolyModel` whose bounds can be computed (an estimate from singular data carries an infinite covariance)."""
    if not isinstance(system, PolyModel) or system.covariance is None:
        return False
    return bool(np.all(np.isfinite(system.covariance)))


def _name(system, index: int, default: str | None = None) -> str:
    name = system.label if isinstance(system, PolyModel) and not system.name else getattr(system, "name", None)
    return str(name) if name else (default or f"model {index + 1}")


def _sampling_period(system) -> float | None:
    dt = system.Ts if isinstance(system, PolyModel) else system.dt
    return float(dt) if dt not in (None, 0, True) else None


def _frequency_response(system, w: np.ndarray) -> np.ndarray:
    """G at the frequencies ``w`` (rad/s); a state-space system's in one batched solve of (zI − A) x = B
    (python-control solves it point by point)."""
    if isinstance(system, PolyModel):
        return system.freqresp(w)
    import control as ct

    if not system.issiso():
        raise ValueError(f"plot_bode: {system.name} is not single-input single-output")
    if not isinstance(system, ct.StateSpace) or system.nstates == 0:
        return np.asarray(ct.frequency_response(system, w).complex).reshape(-1)
    z = np.exp(1j * w * system.dt) if system.isdtime(strict=True) else 1j * w
    a, b, c, d = (np.asarray(m, dtype=float) for m in (system.A, system.B, system.C, system.D))
    x = np.linalg.solve(z[:, None, None] * np.eye(a.shape[0]) - a, np.broadcast_to(b, (z.size, *b.shape)))
    return (c @ x)[:, 0, 0] + d[0, 0]


def _control_step(system, t: np.ndarray) -> np.ndarray:
    """Response of a discrete-time system to a unit step at the sample times ``t``, from rest; a state-space
    system's by its transfer function in one ``lfilter`` pass (python-control steps its state in Python)."""
    import control as ct

    if not system.issiso():
        raise ValueError(f"plot_step: {system.name} is not single-input single-output")
    if not isinstance(system, ct.StateSpace) or system.nstates == 0:
        return np.asarray(ct.step_response(system, T=t).outputs, dtype=float).reshape(-1)
    from scipy.signal import lfilter, ss2tf

    num, den = ss2tf(system.A, system.B, system.C, system.D)
    return lfilter(num[0], den, np.ones(t.size))
