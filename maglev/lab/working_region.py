"""The working region (EL2820 Lab 3 §3.1): where the staircase's stationary averages lie on a line.

The students average the stationary part of every level of a staircase response and
pick the widest range of levels where ȳ vs ū is nearly a straight line; its centre is
the working point every identification experiment is designed around.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from maglev.lab.averages import get_stationary_averages

__all__ = ["WorkingRegion", "working_region"]


@dataclass(frozen=True)
class WorkingRegion:
    """Stationary averages of a staircase and the largest nearly linear range of levels.

    ``lo``/``hi`` index the first/last level inside the region; ``u_min``/``u_max`` are
    its bounds and ``u_star`` their mean (the working point); ``slope``/``intercept`` the
    least-squares line through the region's points; ``max_dev`` the largest distance of
    a region point from that line relative to the region's range of ȳ.
    """

    u_bar: np.ndarray
    y_bar: np.ndarray
    lo: int
    hi: int
    slope: float
    intercept: float
    max_dev: float

    @property
    def u_min(self) -> float:
        return float(self.u_bar[self.lo])

    @property
    def u_max(self) -> float:
        return float(self.u_bar[self.hi])

    @property
    def u_star(self) -> float:
        return 0.5 * (self.u_min + self.u_max)


def working_region(
    u_step: Sequence[float] | np.ndarray,
    y_step: Sequence[float] | np.ndarray,
    nwr: int,
    tail: float = 50.0,
    *,
    max_dev: float = 0.05,
    slope_ratio: tuple[float, float] = (0.5, 1.5),
    min_levels: int = 3,
) -> WorkingRegion:
    """The largest range of staircase levels over which ȳ vs ū stays close to a straight line.

    A contiguous range of at least ``min_levels`` levels counts as linear when both
    (1) every point lies within ``max_dev`` × (range of ȳ over the levels) of the
    least-squares line through them, and (2) every slope between neighbouring levels
    is within ``slope_ratio`` times the line's slope (this rejects flat, noise-only
    stretches and kinks that the first test alone would tolerate).  Among linear
    ranges the widest in ū wins (ties: the one with the smaller deviation).
    """
    u_bar = get_stationary_averages(u_step, nwr, tail)
    y_bar = get_stationary_averages(y_step, nwr, tail)
    if not 0 < max_dev < 1:
        raise ValueError(f"max_dev must be a fraction in (0, 1), got {max_dev!r}")
    r_lo, r_hi = slope_ratio
    if not 0 <= r_lo < 1 < r_hi:
        raise ValueError(f"slope_ratio must be (low, high) with 0 <= low < 1 < high, got {slope_ratio!r}")
    if not isinstance(min_levels, int) or not 2 < min_levels <= nwr:
        raise ValueError(f"min_levels must be an integer in [3, nwr={nwr}], got {min_levels!r}")
    best: tuple[float, float, int, int, float, float] | None = None
    for lo in range(nwr):
        for hi in range(lo + min_levels - 1, nwr):
            uu, yy = u_bar[lo:hi + 1], y_bar[lo:hi + 1]
            span_u = uu.max() - uu.min()
            span_y = yy.max() - yy.min()
            if span_u <= 0 or span_y <= 0:
                continue
            slope, intercept = np.polyfit(uu, yy, 1)
            dev = float(np.max(np.abs(yy - (slope * uu + intercept))) / span_y)
            du = np.diff(uu)
            if np.any(du == 0) or slope == 0:
                continue
            ratios = np.diff(yy) / du / slope
            if dev > max_dev or ratios.min() < r_lo or ratios.max() > r_hi:
                continue
            key = (span_u, -dev)
            if best is None or key > best[:2]:
                best = (span_u, -dev, lo, hi, float(slope), float(intercept))
    if best is None:
        raise ValueError(
            f"no range of >= {min_levels} levels is linear within max_dev={max_dev} and "
            f"slope_ratio={slope_ratio}; loosen the criterion or check the staircase"
        )
    _, neg_dev, lo, hi, slope, intercept = best
    return WorkingRegion(u_bar=u_bar, y_bar=y_bar, lo=lo, hi=hi, slope=slope,
                         intercept=intercept, max_dev=-neg_dev)
