"""Figures: residual correlations, compare, pole-zero map, Bode and step with bounds (headless, Agg)."""

from __future__ import annotations

import math

import control as ct
import numpy as np
import pytest
from matplotlib.figure import Figure

from maglev.data import IOData
from maglev.estimation import arx
from maglev.model import PolyModel
from maglev.plots import MARGINS, figure_grid, plot_bode, plot_compare, plot_pzmap, plot_resid, plot_step
from maglev.uncertainty import frequency_bounds, root_regions, step_bounds
from maglev.validation import compare, resid

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
    fits, preds = compare(data, _model(-1.5, "good"), _model(-1.4, "bad"), 1)
    fig = plot_compare(data, preds[0], fits[0])
    whole, zoom = fig.axes
    assert len(whole.get_lines()) == 2 and len(zoom.get_lines()) == 2
    fig = plot_compare(data, preds, fits, labels=["good", "bad"])
    whole, zoom = fig.axes
    legend = [t.get_text() for t in whole.get_legend().get_texts()]
    assert legend == ["measured", f"good: FIT {fits[0]:.1f} %", f"bad: FIT {fits[1]:.1f} %"]
    for axis in (whole, zoom):
        *predictions, measured = axis.get_lines()  # measured drawn last, on top, black and thicker
        assert measured.get_color() == "k" and measured.get_zorder() > max(p.get_zorder() for p in predictions)
        assert measured.get_linewidth() > max(p.get_linewidth() for p in predictions)
        assert axis.get_ylabel() == "y (cm)" and axis.get_xlabel() == "time (s)"
    np.testing.assert_allclose(whole.get_lines()[-1].get_ydata(), data.y)
    np.testing.assert_allclose(whole.get_lines()[0].get_ydata(), preds[0])
    with pytest.raises(ValueError, match="fit"):
        plot_compare(data, list(preds), fits[0])


def test_plot_compare_zoom_window_is_shown_below_and_marked_above():
    data = _data()
    fit, yhat = compare(data, _model(-1.5, "m"))
    fig = plot_compare(data, yhat, fit, window=(1.0, 1.5), y_unit="mm")
    whole, zoom = fig.axes
    t = zoom.get_lines()[-1].get_xdata()
    assert t[0] == pytest.approx(1.0) and t[-1] == pytest.approx(1.5)
    np.testing.assert_allclose(zoom.get_lines()[-1].get_ydata(), data.y[100:151])
    assert zoom.get_xlim() == pytest.approx((1.0, 1.5))
    assert whole.get_xlim() == pytest.approx((0.0, data.t[-1]))
    (span,) = whole.patches
    assert (span.get_x(), span.get_x() + span.get_width()) == pytest.approx((1.0, 1.5))
    assert zoom.get_ylabel() == "y (mm)"
    default = plot_compare(data, yhat, fit).axes[1].get_lines()[-1].get_xdata()
    assert default.size == 50 and default[0] == pytest.approx(data.t[225])  # the middle 10 %
    for bad in ((2.0, 1.0), (0.0, 99.0), "soon"):
        with pytest.raises(ValueError, match="window"):
            plot_compare(data, yhat, fit, window=bad)


def test_compare_several_models_in_one_call_as_matlab():
    data = _data()
    m1, m2 = _model(-1.5, "a"), _model(-1.4, "b")
    fits, yhats = compare(data, m1, m2, math.inf, "zero")
    assert fits.shape == (2,) and yhats.shape == (2, data.N)
    for i, m in enumerate((m1, m2)):
        fit, yhat = compare(data, m, horizon=math.inf, initial_condition="zero")
        assert isinstance(fit, float) and fits[i] == fit
        np.testing.assert_array_equal(yhats[i], yhat)
    assert compare(data, m1, m2)[0].tolist() == [compare(data, m1, 1)[0], compare(data, m2, 1)[0]]
    with pytest.raises(TypeError, match="models must come first"):
        compare(data, m1, 1, m2)
    with pytest.raises(TypeError, match="both positionally and by keyword"):
        compare(data, m1, 1, horizon=2)
    with pytest.raises(TypeError, match="one or more PolyModels"):
        compare(data, 1)


def _estimated(seed: int = 0, N: int = 400) -> PolyModel:
    """An ARX model of the plant above, estimated from short noisy data (so its bounds are visible)."""
    rng = np.random.default_rng(seed)
    u = rng.standard_normal(N)
    y = _model(-1.5, "true").simulate(u, 0.5 * rng.standard_normal(N))
    return arx(IOData(u, y, TS, name="short"), 2, 2, 1)


def _has_points(collection, x: np.ndarray, y: np.ndarray) -> bool:
    """Every (x_i, y_i) is a vertex of the collection's (first) polygon."""
    v = collection.get_paths()[0].vertices
    hit = np.isclose(v[None, :, 0], np.asarray(x)[:, None], rtol=1e-12) & \
        np.isclose(v[None, :, 1], np.asarray(y)[:, None], rtol=1e-9, atol=1e-12)
    return bool(np.all(hit.any(axis=1)))


def test_plot_pzmap_overlays_models_and_unit_circle():
    m1, m2 = _model(-1.5, "first"), _model(-1.2, "second")
    fig = plot_pzmap([m1, m2])
    context, zoom = fig.axes
    for axis in (context, zoom):
        markers = [ln for ln in axis.get_lines() if ln.get_marker() in ("x", "o")]
        assert len(markers) == 4
        poles = [ln for ln in markers if ln.get_marker() == "x"]
        np.testing.assert_allclose(np.sort_complex(poles[0].get_xdata() + 1j * poles[0].get_ydata()),
                                   np.sort_complex(m1.poles()))
    circle = max(context.get_lines(), key=lambda ln: len(ln.get_xdata()))
    np.testing.assert_allclose(np.hypot(circle.get_xdata(), circle.get_ydata()), 1.0)
    assert [t.get_text() for t in zoom.get_legend().get_texts()] == ["first", "second"]


def test_plot_pzmap_zooms_on_the_poles_with_the_unit_circle_as_context():
    slow = PolyModel(A=np.real(np.poly([0.995 + 0.01j, 0.995 - 0.01j, 0.98])), B=[0, 1.0, -3.0], C=ONE, D=ONE,
                     F=ONE, nk=1, Ts=TS, structure="arx", name="slow")  # zero at z = 3, poles near z = 1
    fig = plot_pzmap(slow)
    context, zoom = fig.axes
    poles = slow.poles()
    x0, x1 = zoom.get_xlim()
    y0, y1 = zoom.get_ylim()
    assert np.all((poles.real > x0) & (poles.real < x1) & (poles.imag > y0) & (poles.imag < y1))
    assert x1 - x0 < 0.05 and x1 - x0 == pytest.approx(y1 - y0)  # a square zoom, not the whole disc
    arc = zoom.get_lines()[-1]
    np.testing.assert_allclose(np.hypot(arc.get_xdata(), arc.get_ydata()), 1.0)
    ax_, ay_ = arc.get_xdata(), arc.get_ydata()
    assert np.sum((ax_ >= x0) & (ax_ <= x1) & (ay_ >= y0) & (ay_ <= y1)) > 100  # the arc, finely, in the window
    assert context.get_xlim()[1] >= 3.0 and context.get_ylim()[0] <= -1.0  # the zero at 3 and the circle
    assert context.get_xlim()[0] > -1.5  # nothing on the left but the circle: no empty half
    box, fig = context.get_position(original=True), context.figure
    (c0, c1), (d0, d1) = context.get_xlim(), context.get_ylim()  # equal scales that fill the panel: no shrunk box
    assert (c1 - c0) / (d1 - d0) == pytest.approx(box.width * fig.get_figwidth() / (box.height * fig.get_figheight()))
    (frame,) = context.patches
    assert frame.get_x() == pytest.approx(x0) and frame.get_width() == pytest.approx(x1 - x0)


def test_plot_pzmap_draws_the_confidence_regions_of_poles_and_zeros():
    m = _estimated()
    fig = plot_pzmap(m, level=0.99)
    context, zoom = fig.axes
    poles, zeros = root_regions(m, "poles", 0.99), root_regions(m, "zeros", 0.99)
    for axis, regions in ((context, (poles, zeros)), (zoom, (poles,))):  # zero regions on the context only
        outlines = [ln for ln in axis.get_lines() if ln.get_marker() in ("None", "") and ln.get_linestyle() == "-"]
        expected = [r.outline(i) for r in regions for i in range(r.roots.size)]
        assert len(outlines) == len(expected)
        for line, edge in zip(outlines, expected):
            np.testing.assert_allclose(line.get_xdata() + 1j * line.get_ydata(), edge)
    assert "99 % regions" in context.get_title()
    assert len([ln for ln in plot_pzmap(m).axes[1].get_lines() if ln.get_linestyle() == "-"]) == 0


def test_plot_pzmap_context_stops_at_three_and_says_what_it_leaves_out():
    far = PolyModel(A=[1.0, -0.5], B=[0, 1.0, -9.0], C=ONE, D=ONE, F=ONE, nk=1, Ts=TS, structure="arx")
    context, _ = plot_pzmap(far).axes
    x0, x1 = context.get_xlim()
    y0, y1 = context.get_ylim()
    assert x0 < -1.0 and 1.0 < x1 < 3.0 and y0 < -1.0 < 1.0 < y1 < 3.0  # the circle and the pole, not the zero at 9
    assert context.get_title().endswith("(1 beyond |z| = 3)")
    assert "beyond" not in plot_pzmap(_model(-1.5, "m")).axes[0].get_title()


def test_plot_pzmap_accepts_a_single_control_system():
    sys = ct.tf([1.0, 0.5], [1.0, -1.5, 0.7], TS, name="plant")
    fig = plot_pzmap(sys, level=0.99)  # no covariance: no regions, no error
    assert [t.get_text() for t in fig.axes[1].get_legend().get_texts()] == ["plant"]


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


def test_a_state_space_true_system_draws_its_own_g():
    """The small-signal Jacobian is a state-space system (its response solved in one batch, its step by its
    transfer function): the curves of the same G as a PolyModel's."""
    m1 = _model(-1.5, "first")
    true = ct.ss(ct.tf([1.0, 0.5], [1.0, -1.5, 0.7], TS), name="true")
    mag, phase = plot_bode(m1, true_system=true).axes
    np.testing.assert_allclose(mag.get_lines()[1].get_ydata(), mag.get_lines()[0].get_ydata(), rtol=1e-9)
    np.testing.assert_allclose(np.cos(np.radians(phase.get_lines()[1].get_ydata())),
                               np.cos(np.angle(m1.freqresp(mag.get_lines()[0].get_xdata()))), atol=1e-9)
    (line,) = plot_step(true, n=80).axes[0].get_lines()
    np.testing.assert_allclose(line.get_ydata(), m1.simulate(np.ones(80)), atol=1e-9)


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


def test_plot_bode_shades_the_confidence_band_of_each_estimated_model():
    m = _estimated()
    w = np.logspace(0, np.log10(math.pi / TS), 40)
    fig = plot_bode([m, _model(-1.5, "no covariance")], w=w, level=0.99)
    mag, phase = fig.axes
    (mag_band,), (phase_band,) = mag.collections, phase.collections  # only the estimated model has one
    b = frequency_bounds(m, w, level=0.99)
    assert b.k == pytest.approx(2.5758, abs=1e-4)
    assert _has_points(mag_band, w, 20 * np.log10(b.magnitude_upper))
    assert _has_points(mag_band, w, 20 * np.log10(np.maximum(b.magnitude_lower, b.magnitude / 100)))
    assert _has_points(phase_band, w, b.phase_lower) and _has_points(phase_band, w, b.phase_upper)
    np.testing.assert_allclose(mag.get_lines()[0].get_ydata(), 20 * np.log10(np.abs(m.freqresp(w))))
    assert mag.get_ylabel() == "|G| (dB re 1 cm/A)" and "99 % bounds" in mag.get_title()
    assert not plot_bode(m, w=w).axes[0].collections  # no level, no sd: no band
    singular = PolyModel(A=m.A, B=m.B, C=ONE, D=ONE, F=ONE, nk=1, Ts=TS, structure="arx",
                         covariance=np.full((4, 4), np.inf))  # as estimate() stores a singular problem's
    assert not plot_bode(singular, w=w, level=0.99).axes[0].collections


def test_plot_bode_draws_precomputed_bounds_on_their_own_frequencies():
    m = _estimated()
    w_own = np.array([1.0, 10.0, 100.0])
    given = frequency_bounds(m, w_own, sd=2)
    fig = plot_bode([m, given])
    mag, _ = fig.axes
    np.testing.assert_allclose(mag.get_lines()[1].get_xdata(), w_own)
    (band,) = mag.collections
    assert _has_points(band, w_own, 20 * np.log10(given.magnitude_upper))


def test_plot_step_with_bounds_and_a_control_system():
    m = _estimated()
    true = ct.tf([1.0, 0.5], [1.0, -1.5, 0.7], TS, name="true")  # B/A of _model(-1.5), in z
    fig = plot_step([m, true], n=80, sd=1)
    (ax,) = fig.axes
    est_line, true_line = ax.get_lines()
    b = step_bounds(m, 80, sd=1)
    np.testing.assert_allclose(est_line.get_ydata(), b.y)
    np.testing.assert_allclose(true_line.get_ydata(), _model(-1.5, "t").simulate(np.ones(80)), atol=1e-9)
    (band,) = ax.collections
    assert _has_points(band, b.t, b.lower) and _has_points(band, b.t, b.upper)
    assert ax.get_ylabel() == "y (cm) for a 1 A step"
    with pytest.raises(ValueError, match="one sampling period"):
        plot_step([m, ct.tf([1.0], [1.0, 1.0])])


def test_figure_grid_places_its_panels_by_the_margins_in_inches():
    """Margins and gaps given in inches are where the panels end up, whatever the figure's size; an unknown key
    is refused with the ones expected."""
    axes = figure_grid((10.0, 5.0), 2, 3, margins={"left": 1.5, "wgap": 1.0, "hgap": 0.5})
    fig = axes[0, 0].figure
    boxes = [[ax.get_position().transformed(fig.transFigure).transformed(fig.dpi_scale_trans.inverted())
              for ax in row] for row in axes]
    assert boxes[0][0].x0 == pytest.approx(1.5) and boxes[1][2].x1 == pytest.approx(10.0 - MARGINS["right"])
    assert boxes[0][1].x0 - boxes[0][0].x1 == pytest.approx(1.0)
    assert boxes[0][0].y0 - boxes[1][0].y1 == pytest.approx(0.5)
    assert boxes[1][0].y0 == pytest.approx(MARGINS["bottom"]) and boxes[0][0].y1 == pytest.approx(5.0 - MARGINS["top"])
    assert fig.get_layout_engine() is None
    with pytest.raises(ValueError, match=r"unknown key\(s\) \['gap'\], expected some of"):
        figure_grid((6.0, 4.0), margins={"gap": 1.0})
