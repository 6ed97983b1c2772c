"""Checks of a drawn figure's fixed layout (:func:`maglev.plots.figure_grid`): what a layout engine would have
avoided, found from the drawn texts' extents."""

from __future__ import annotations

import itertools

from matplotlib.backends.backend_agg import FigureCanvasAgg


def _texts(fig) -> dict[str, list]:
    """Window extents (pixels) of the drawn figure's texts and legends: per axes, its tick labels and its
    labels, titles and legend, by name."""
    renderer = FigureCanvasAgg(fig).get_renderer()
    fig.draw(renderer)
    boxes = {}
    for i, ax in enumerate(fig.axes):
        ticks = [label for axis, (low, high) in ((ax.xaxis, sorted(ax.get_xlim())), (ax.yaxis, sorted(ax.get_ylim())))
                 for tick in axis.get_major_ticks() + axis.get_minor_ticks()
                 if low <= tick.get_loc() <= high  # drawn: inside the view
                 for label in (tick.label1,) if label.get_visible() and label.get_text()]
        boxes[f"{i} ticks"] = [t.get_window_extent(renderer) for t in ticks]
        for name, text in (("xlabel", ax.xaxis.label), ("ylabel", ax.yaxis.label), ("title", ax.title)):
            if text.get_text():
                boxes[f"{i} {name}"] = [text.get_window_extent(renderer)]
        if ax.get_legend() is not None:
            boxes[f"{i} legend"] = [ax.get_legend().get_window_extent(renderer)]
    return boxes


def clash(fig) -> list[str]:
    """What lies partly outside the figure, and which two texts of different kinds overlap (a tick label and
    an axis label, a legend and a title, …): the faults a layout engine would have avoided."""
    boxes = _texts(fig)
    bounds = fig.bbox
    faults = [f"{name} outside the figure" for name, group in boxes.items() for b in group
              if b.x0 < bounds.x0 - 0.5 or b.y0 < bounds.y0 - 0.5 or b.x1 > bounds.x1 + 0.5 or b.y1 > bounds.y1 + 0.5]
    for (a, ga), (b, gb) in itertools.combinations(boxes.items(), 2):
        if any(x.overlaps(y) for x in ga for y in gb):
            faults.append(f"{a} overlaps {b}")
    return faults
