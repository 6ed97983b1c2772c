"""The ranking's binary-vs-uniform figure (:func:`maglev.study.figures.comparison_figure`), the report's orders
figure, and their fixed layouts: no layout engine, and still nothing clipped or overlapping."""

from __future__ import annotations

import numpy as np
import pandas as pd

from maglev.study.figures import comparison_figure, orders_figure

from ..layout import clash


def _bars(fig):
    ax = fig.axes[0]
    return {c.get_label(): [round(p.get_height(), 9) for p in c.patches] for c in ax.containers}


def test_one_bar_per_dataset_and_orders():
    comp = pd.DataFrame({"dataset": ["uni", "uni", "bin", "bin"], "input_class": ["uniform"] * 2 + ["binary"] * 2,
                         "orders": ["2-2-1", "3-3-1"] * 2, "val_fit": [80.0, 85.0, 90.0, 95.0]})
    assert _bars(comparison_figure(comp, None, "oe")) == {"bin (binary)": [90.0, 95.0], "uni (uniform)": [80.0, 85.0]}


def test_several_runs_of_a_dataset_and_orders_draw_their_mean():
    """A sweep over seeds of one record has several runs per dataset and orders: one bar, their mean, and the
    legend says so (the figure stopped the ranking with a shape mismatch)."""
    comp = pd.DataFrame({"dataset": ["uni"] * 4 + ["bin"] * 2, "input_class": ["uniform"] * 4 + ["binary"] * 2,
                         "orders": ["2-2-1", "2-2-1", "3-3-1", "3-3-1", "2-2-1", "3-3-1"],
                         "val_fit": [80.0, 70.0, 85.0, 86.0, 90.0, 95.0]})
    bars = _bars(comparison_figure(comp, None, "oe"))
    assert bars == {"bin (binary)": [90.0, 95.0], "uni (uniform), mean of up to 2 runs": [75.0, 85.5]}


def test_the_comparison_figure_leaves_its_long_names_room_without_a_layout_engine():
    """Models and records with long names (the real records'), three datasets (a two-row legend below the bars):
    the margins measured from the names keep every tick label, axis label, title and legend inside the figure
    and apart."""
    names = ["real_binary_signal_10", "real_white_noise_1", "real_white_noise_2"]
    comp = pd.DataFrame({"dataset": names * 2, "input_class": ["binary", "uniform", "uniform"] * 2,
                         "orders": ["[2 2 2 2 2]"] * 3 + ["[7 7 7 7 2]"] * 3,
                         "val_fit": [91.8, 72.4, 70.9, 99.1, -3.2, 75.0]})
    common = pd.DataFrame(np.arange(9.0).reshape(3, 3) * 10, columns=[f"{n}[val]" for n in names],
                          index=[f"armax 7-7-7-2 · {n}" for n in names])
    for fig in (comparison_figure(comp, common, "armax"), comparison_figure(comp, None, "armax")):
        assert fig.get_layout_engine() is None
        assert clash(fig) == []


def test_the_orders_figure_leaves_wide_tick_labels_room_without_a_layout_engine():
    """Four structures, log-scale losses (tick labels such as 6 × 10⁻⁵) and six-digit AICs of long records."""
    rows = [{"structure": st, "dataset": ds, "n_params": n, "loss": 10.0 ** (-5 + k / 3 - n / 8),
             "aic": -115000.0 + 900 * n * (k + 1), "val_fit": 90.0 - n - 40 * k}
            for st in ("arx", "armax", "oe", "bj") for k, ds in enumerate(("uniform_narrow", "binary_a025"))
            for n in range(4, 15, 2)]
    fig = orders_figure(pd.DataFrame(rows))
    assert fig.get_layout_engine() is None
    assert clash(fig) == []


def _run_inputs(*overrides: str):
    """A short simulated run's figure inputs (identified as a sweep's job is)."""
    from hydra import compose, initialize_config_dir

    import maglev.study.schema  # noqa: F401  (schemas and ${maglev.root:})
    from maglev.study.config import task_config
    from maglev.study.identify import identify

    from .harness import CONF, TINY

    with initialize_config_dir(version_base="1.3", config_dir=str(CONF)):
        cfg = task_config(compose("config", overrides=[*TINY, "study.true_plant=false", *overrides]))
    return identify(cfg).figure_inputs


def _pixels(fig):
    import io

    import numpy as np
    from PIL import Image

    from maglev.study.figures import RUN_DPI, png

    return np.asarray(Image.open(io.BytesIO(png(fig, RUN_DPI))))


def test_a_runs_figures_drawn_on_another_runs_are_the_images_new_figures_give():
    """The renderer draws every run on the figures of the run before (maglev.plots.clear): nothing of that run
    may show — another structure, dataset, horizon and number of systems (the small-signal Jacobian in one)."""
    import dataclasses

    from maglev.study.figures import run_figures
    from maglev.study.identify import true_plant

    first = _run_inputs("structure=bj", "structure.order=3", "dataset=binary_a025")
    true_sys = true_plant(first.prepared, "stuck_stretched")
    first = dataclasses.replace(first, jacobian=(true_sys.A, true_sys.B, true_sys.C, true_sys.D, true_sys.dt))
    second = _run_inputs("structure=arx", "structure.order=2", "dataset=uniform_narrow", "study.val_horizon=5")
    kept: dict = {}
    for fig in run_figures(first, reuse=kept).values():
        _pixels(fig)  # drawn, as the renderer does
    again = run_figures(second, reuse=kept)
    assert set(again) == set(kept) == {"compare.png", "resid.png", "pzmap.png", "step.png", "bode.png"}
    new = run_figures(second)
    for name in new:
        a, b = _pixels(new[name]), _pixels(again[name])
        assert a.shape == b.shape and (a == b).all(), f"{name}: {(a != b).any(axis=-1).sum()} pixels differ"
        assert again[name] is kept[name] and len(new[name].axes) == len(kept[name].axes)
