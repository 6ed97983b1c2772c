"""The lab steps' figures draw the numbers of the results they are given."""

from __future__ import annotations

import numpy as np
import pytest
from matplotlib.patches import Polygon, Rectangle

from maglev.data import IOData
from maglev.lab import plots
from maglev.lab.input_design import choose_alpha, output_spectrum
from maglev.lab.sampling import rise_time
from maglev.lab.signals import staircase
from maglev.lab.working_region import working_region

from ..layout import clash


def _vertical_lines(ax) -> list[float]:
    return sorted(float(x[0]) for line in ax.get_lines() for x in [line.get_xdata()]
                  if len(x) == 2 and x[0] == x[1])


def _span(ax) -> tuple[float, float]:
    [patch] = [p for p in ax.patches if isinstance(p, (Polygon, Rectangle))]
    xs = patch.get_xy()[:, 0] if isinstance(patch, Polygon) else [patch.get_x(), patch.get_x() + patch.get_width()]
    return float(min(xs)), float(max(xs))


def test_working_region_figure_marks_the_region_and_the_working_point():
    u_levels = np.arange(0, 11, 1.0)
    y_levels = np.clip(u_levels, 3, 7.5) * 2.0  # the plateau starts between levels 7 and 8
    wr = working_region(staircase(u_levels, 20), staircase(y_levels, 20), 11, 50)
    ax = plots.plot_working_region(wr).axes[0]
    assert _vertical_lines(ax) == [3.0, 5.0, 7.0]  # u_min, u*, u_max
    filled = [ln for ln in ax.get_lines() if ln.get_marker() == "s" and ln.get_markerfacecolor() != "none"]
    assert list(filled[0].get_xdata()) == list(wr.u_bar[wr.lo:wr.hi + 1])
    assert "[3, 7] A" in ax.get_title()
    assert (ax.get_xlabel(), ax.get_ylabel()) == ("step level ū (A)", "stationary output ȳ (cm)")


def test_rise_time_figure_draws_the_averaged_response_and_its_crossings():
    k = np.arange(300)
    resp = 1 - np.exp(-k / 15.0)
    u = np.r_[np.zeros(300), np.ones(300)]
    rt = rise_time(IOData(u, np.r_[np.zeros(300), resp], 0.001))
    ax = plots.plot_rise_time(rt).axes[0]
    curve = ax.get_lines()[0]
    assert np.array_equal(curve.get_ydata(), rt.response)
    assert _vertical_lines(ax) == pytest.approx(sorted([rt.t10, rt.t90]))
    assert f"decimate by {rt.decimation}" in ax.get_title()


def test_spectrum_and_alpha_figures_shade_the_energy_band():
    n = 4096
    y = np.sin(2 * np.pi * 200 / n * np.arange(n))
    spec = output_spectrum(y, fraction=0.8)
    ax = plots.plot_output_spectrum(spec).axes[0]
    assert _span(ax) == pytest.approx((spec.band[0] / np.pi, spec.band[1] / np.pi))
    # a band of a few thousandths of π is visible: the frequency axes are logarithmic and reach below it
    assert ax.get_xscale() == "log" and ax.get_xlim()[0] < spec.band[0] / np.pi
    choice = choose_alpha((0.2, 0.9))
    ax = plots.plot_alpha(choice).axes[0]
    assert _span(ax) == pytest.approx((0.2 / np.pi, 0.9 / np.pi))
    assert ax.get_xscale() == "log" and ax.get_xlim()[0] < 0.2 / np.pi
    solid = [ln.get_label() for ln in ax.get_lines() if ln.get_linestyle() == "-"]
    assert solid == [f"α = {choice.alpha_star:g} ({max(choice.shares):.0%} in band)"]


def test_the_lab_figures_keep_their_texts_apart_without_a_layout_engine():
    """The fixed layout of maglev.plots: every tick label, axis label, title and legend inside the figure and apart."""
    levels = np.arange(0, 11, 1.0)
    wr = working_region(staircase(levels, 20), staircase(np.clip(levels, 3, 7.5) * 2.0 + 7.9, 20), 11, 50)
    k = np.arange(300)
    rt = rise_time(IOData(np.r_[np.zeros(300), np.ones(300)], np.r_[np.zeros(300), 1 - np.exp(-k / 15.0)], 0.001))
    spec = output_spectrum(np.sin(2 * np.pi * 200 / 4096 * np.arange(4096)), fraction=0.8)
    for fig in (plots.plot_working_region(wr), plots.plot_rise_time(rt), plots.plot_output_spectrum(spec),
                plots.plot_alpha(choose_alpha((0.2, 0.9)))):
        assert fig.get_layout_engine() is None
        assert clash(fig) == []
