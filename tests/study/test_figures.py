"""The ranking's binary-vs-uniform figure (:func:`maglev.study.figures.comparison_figure`)."""

from __future__ import annotations

import pandas as pd

from maglev.study.figures import comparison_figure


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
