"""Figures: residual correlations, compare, pole-zero map and Bode diagram (headless, Agg)."""

from __future__ import annotations

import math

import control as ct
import numpy as np
import pytest
from matplotlib.figure import Figure

from maglev.data import IOData
from maglev.models import PolyModel
from maglev.plots import plot_bode, plot_compare, plot_pzmap, plot_resid
from maglev.validate import compare, resid

ONE = np.ones(1)
TS = 0.01


def _model(a1: float, name: str) -> PolyModel:
    return PolyModel(A=[1.0, a1, 0.7], B=[0.0, 1.0, 0.5], C=ONE, D=ONE, F=ONE, nk=1, Ts=TS,
                     structure="arx", name=name)


def _data() -> IOData:
    rng = np.random.default_rng(0)
    u = rng.standard_normal(500)
    y = _model(-1.5, "true").simulate(u, 0.1 * rng.standard_normal(500))
    return IOData(u, y, TS)


def test_plot_resid_draws_both_correlations_with_bands():
    data = _data()
    result = resid(data, _model(-1.5, "true"), lags=15)
    fig = plot_resid(result)
    assert isinstance(fig, Figure)
    auto, cross = fig.axes
    np.testing.assert_allclose(auto.get_lines()[0].get_ydata(), result.auto_corr)
    np.testing.assert_allclose(cross.get_lines()[0].get_xdata(), np.arange(-15, 16))
    for ax, band in ((auto, result.auto_band), (cross, result.cross_band)):
        (shade,) = ax.collections  # the band
        vertices = shade.get_paths()[0].vertices
        assert vertices[:, 1].max() == pytest.approx(band)
        assert vertices[:, 1].min() == pytest.approx(-band)


def test_plot_resid_on_given_axes():
    fig = Figure()
    axes = fig.subplots(1, 2)
    result = resid(_data(), _model(-1.5, "true"), lags=5)
    assert plot_resid(result, ax=axes) is fig
    with pytest.raises(ValueError, match="pair"):
        plot_resid(result, ax=[axes[0]])


def test_plot_compare_one_and_several_predictions():
    data = _data()
    fits, preds = zip(*(compare(data, _model(a, f"m{a}"), 1) for a in (-1.5, -1.4)))
    fig = plot_compare(data, preds[0], fits[0])
    (ax,) = fig.axes
    assert len(ax.get_lines()) == 2
    fig = plot_compare(data, list(preds), list(fits), labels=["good", "bad"])
    (ax,) = fig.axes
    assert len(ax.get_lines()) == 3
    legend = [t.get_text() for t in ax.get_legend().get_texts()]
    assert legend[1] == f"good: FIT {fits[0]:.1f} %"
    np.testing.assert_allclose(ax.get_lines()[0].get_ydata(), data.y)
    with pytest.raises(ValueError, match="fit"):
        plot_compare(data, list(preds), fits[0])


def test_plot_pzmap_overlays_models_and_unit_circle():
    m1, m2 = _model(-1.5, "first"), _model(-1.2, "second")
    fig = plot_pzmap([m1, m2])
    (ax,) = fig.axes
    markers = [ln for ln in ax.get_lines() if ln.get_marker() in ("x", "o")]
    assert len(markers) == 4
    poles = [ln for ln in markers if ln.get_marker() == "x"]
    np.testing.assert_allclose(np.sort_complex(poles[0].get_xdata() + 1j * poles[0].get_ydata()),
                               np.sort_complex(m1.poles()))
    circle = max(ax.get_lines(), key=lambda ln: len(ln.get_xdata()))
    radius = np.hypot(circle.get_xdata(), circle.get_ydata())
    np.testing.assert_allclose(radius, 1.0)
    labels = [t.get_text() for t in ax.get_legend().get_texts()]
    assert labels == ["first poles", "first zeros", "second poles", "second zeros"]


def test_plot_pzmap_accepts_a_single_control_system():
    sys = ct.tf([1.0, 0.5], [1.0, -1.5, 0.7], TS, name="plant")
    fig = plot_pzmap(sys)
    labels = [t.get_text() for t in fig.axes[0].get_legend().get_texts()]
    assert labels == ["plant poles", "plant zeros"]


def test_plot_bode_overlays_models_and_true_system():
    m1, m2 = _model(-1.5, "first"), _model(-1.2, "second")
    true = ct.tf([1.0, 0.5], [1.0, -1.5, 0.7], TS, name="true")
    fig = plot_bode([m1, m2], true_system=true)
    mag, phase = fig.axes
    assert len(mag.get_lines()) == 3 and len(phase.get_lines()) == 3
    w = mag.get_lines()[0].get_xdata()
    assert w[-1] == pytest.approx(math.pi / TS)
    np.testing.assert_allclose(mag.get_lines()[0].get_ydata(), 20 * np.log10(np.abs(m1.freqresp(w))))
    # the control system drawn for "true" is the same G as m1: B/A with the delay in q^-1
    np.testing.assert_allclose(mag.get_lines()[2].get_ydata(), mag.get_lines()[0].get_ydata(), rtol=1e-9)
    np.testing.assert_allclose(np.cos(np.radians(phase.get_lines()[2].get_ydata())),
                               np.cos(np.angle(m1.freqresp(w))), atol=1e-9)
    assert mag.get_xscale() == "log"


def test_plot_bode_custom_frequencies_and_errors():
    w = np.logspace(-1, 2, 50)
    fig = plot_bode(_model(-1.5, "m"), w=w)
    np.testing.assert_allclose(fig.axes[0].get_lines()[0].get_xdata(), w)
    with pytest.raises(ValueError, match="w"):
        plot_bode(_model(-1.5, "m"), w=np.array([-1.0, 1.0]))
    with pytest.raises(ValueError, match="models"):
        plot_bode([])
    with pytest.raises(ValueError, match="pass w"):
        plot_bode(ct.tf([1.0], [1.0, 1.0]))
