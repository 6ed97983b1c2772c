"""The working region (EL2820 Lab 3 §3.1): where the staircase's stationary averages lie on a line.

The students average the stationary part of every level of a staircase response and
pick the widest range of levels where ȳ vs ū is nearly a straight line; its centre is
the working point every identification experiment is designed around.  The range must
exclude the resting zone (the magnet seated: ȳ flat or falling) and the saturation
plateau (the current regulator saturated: ȳ flat at its highest level), which a loose
straight-line test lets in at the range's end; :func:`region_decision` states the rule
with the numbers of every level and checks it against the physical model's saturation
current.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from maglev.lab.averages import get_stationary_averages

__all__ = ["WorkingRegion", "working_region", "saturation_plateau", "region_decision"]


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
    plateau_level: float = float("nan")  # ȳ of the saturation plateau (nan: none found)
    plateau_first: int = -1  # index of the first level on the plateau (-1: none)
    plateau_margin: float = 0.05  # a level is on the plateau within this share of ȳ's range below it
    slope_ratio: tuple[float, float] = (0.75, 4 / 3)
    dev_limit: float = 0.05  # the max_dev a linear range may have

    def on_plateau(self) -> np.ndarray:
        """Per level: ȳ within ``plateau_margin`` × (range of ȳ) of the plateau's level."""
        if self.plateau_first < 0:
            return np.zeros(self.y_bar.size, dtype=bool)
        span = float(self.y_bar.max() - self.y_bar.min())
        return self.plateau_level - self.y_bar < self.plateau_margin * span

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
    slope_ratio: tuple[float, float] = (0.75, 4 / 3),
    min_levels: int = 3,
    plateau_margin: float = 0.05,
) -> WorkingRegion:
    """The largest range of staircase levels over which ȳ vs ū stays close to a straight line.

    A contiguous range of at least ``min_levels`` levels counts as linear when
    (1) every point lies within ``max_dev`` × (range of ȳ over the levels) of the
    least-squares line through them, (2) every slope between neighbouring levels
    is within ``slope_ratio`` times the line's slope (this rejects flat, noise-only
    stretches and kinks that the first test alone would tolerate), and (3) no level is on
    the saturation plateau (:func:`saturation_plateau`; ȳ within ``plateau_margin`` × the
    staircase's range of ȳ below the plateau's level), which rejects the level where the
    curve bends onto the plateau even when its slope still passes (2).  Among linear
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
    if not 0 <= plateau_margin < 1:
        raise ValueError(f"plateau_margin must be a fraction in [0, 1), got {plateau_margin!r}")
    plateau_level, plateau_first = saturation_plateau(u_bar, y_bar)
    probe = WorkingRegion(u_bar, y_bar, 0, 0, 0.0, 0.0, 0.0, plateau_level, plateau_first, plateau_margin)
    saturated = probe.on_plateau()
    best: tuple[float, float, int, int, float, float] | None = None
    for lo in range(nwr):
        for hi in range(lo + min_levels - 1, nwr):
            if saturated[lo:hi + 1].any():
                break
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
    return WorkingRegion(u_bar=u_bar, y_bar=y_bar, lo=lo, hi=hi, slope=slope, intercept=intercept,
                         max_dev=-neg_dev, plateau_level=plateau_level, plateau_first=plateau_first,
                         plateau_margin=plateau_margin, slope_ratio=(float(r_lo), float(r_hi)),
                         dev_limit=float(max_dev))


def saturation_plateau(u_bar: np.ndarray, y_bar: np.ndarray, flat: float = 0.05,
                       min_segments: int = 2) -> tuple[float, int]:
    """(ȳ level, index of its first level) of the saturation plateau, or (nan, -1) when there is none.

    The plateau is the highest run of at least ``min_segments`` consecutive level-to-level
    slopes whose size is below ``flat`` × the largest slope of the staircase (the output
    stops following the input), whose level is the staircase's highest (within the same
    ``flat`` share of ȳ's range): a flat stretch at the bottom is the resting zone, not a
    saturation.  Its level is the median ȳ over the run.
    """
    du = np.diff(u_bar)
    if u_bar.size < min_segments + 1 or np.any(du == 0):
        return float("nan"), -1
    slopes = np.diff(y_bar) / du
    steepest = float(np.max(np.abs(slopes)))
    if steepest == 0:
        return float("nan"), -1
    is_flat = np.abs(slopes) < flat * steepest
    span = float(y_bar.max() - y_bar.min())
    best: tuple[float, int] = (float("nan"), -1)
    i = 0
    while i < slopes.size:
        if not is_flat[i]:
            i += 1
            continue
        j = i
        while j < slopes.size and is_flat[j]:
            j += 1
        if j - i >= min_segments:  # levels i..j are flat
            level = float(np.median(y_bar[i:j + 1]))
            if y_bar.max() - level < flat * span and (best[1] < 0 or level > best[0]):
                best = (level, i)
        i = j
    return best


def region_decision(wr: WorkingRegion, u_sat: float | None = None, source: str = "staircase"):
    """The working region as a :class:`~maglev.lab.decision.Decision`: each level's ū, ȳ, slope to the next
    level against the region's slope, whether it is on the plateau and whether it is inside, and the reasons
    each bound stops where it does.  ``u_sat``, the physical model's regulator saturation current, is checked
    against the staircase: it should lie between the region's upper bound and the first plateau level (one
    story); a caution says so when it does not."""
    from maglev.lab.decision import Decision

    lo_r, hi_r = wr.slope_ratio
    sat = wr.on_plateau()
    slopes = np.diff(wr.y_bar) / np.diff(wr.u_bar)
    rows = []
    for i, (u, y) in enumerate(zip(wr.u_bar, wr.y_bar)):
        s = float(slopes[i]) if i < slopes.size else float("nan")
        rows.append({"u (A)": float(u), "y (cm)": float(y), "slope to next (cm/A)": s,
                     "slope / region slope": s / wr.slope, "on plateau": bool(sat[i]),
                     "in region": wr.lo <= i <= wr.hi})
    rule = (f"the widest range of >= 3 staircase levels where every level-to-level slope is within "
            f"{lo_r:.3g}–{hi_r:.3g} times the range's least-squares slope, every level lies within "
            f"{wr.dev_limit:g} of ȳ's range from that line, and no level is on the saturation "
            f"plateau (ȳ within {wr.plateau_margin:g} of the staircase's ȳ range below the plateau level)")
    reasons = [f"ū ∈ [{wr.u_min:.3g}, {wr.u_max:.3g}] A: {wr.hi - wr.lo + 1} levels, slope {wr.slope:.3g} cm/A, "
               f"largest deviation from the line {100 * wr.max_dev:.2g} % of their ȳ range."]
    if wr.lo > 0:
        r = float(slopes[wr.lo - 1] / wr.slope)
        reasons.append(f"Lower bound: the slope from {wr.u_bar[wr.lo - 1]:.3g} to {wr.u_min:.3g} A is "
                       f"{slopes[wr.lo - 1]:.3g} cm/A, {r:.2f} times the region's "
                       + ("(outside the band: the resting zone)." if not lo_r <= r <= hi_r else
                          "(inside the band, but the wider range fails another test)."))
    if wr.hi + 1 < wr.u_bar.size:
        nxt = wr.hi + 1
        r = float(slopes[wr.hi] / wr.slope)
        why = []
        if sat[nxt]:
            why.append(f"ȳ({wr.u_bar[nxt]:.3g} A) = {wr.y_bar[nxt]:.4g} cm is on the plateau at "
                       f"{wr.plateau_level:.4g} cm")
        if not lo_r <= r <= hi_r:
            why.append(f"the slope from {wr.u_max:.3g} to {wr.u_bar[nxt]:.3g} A is {slopes[wr.hi]:.3g} cm/A, "
                       f"{r:.2f} times the region's (band {lo_r:.3g}–{hi_r:.3g})")
        reasons.append(f"Upper bound {wr.u_max:.3g} A: the next level is excluded because "
                       + (" and ".join(why) if why else "the wider range deviates from a line") + ".")
    cautions = []
    choice = {"u_min": wr.u_min, "u_max": wr.u_max, "u_star": wr.u_star, "slope": wr.slope}
    if u_sat is not None and sat.any():
        first = float(wr.u_bar[int(np.argmax(sat))])
        choice["u_sat_model"] = float(u_sat)
        if wr.u_max <= u_sat <= first:
            reasons.append(f"The physical model's regulator saturation, {u_sat:.4g} A, lies between the region's "
                           f"upper bound {wr.u_max:.3g} A and the first level on the plateau, {first:.3g} A: the "
                           "plateau is the regulator saturating, and the region ends below it.")
        else:
            cautions.append(f"The physical model's regulator saturation, {u_sat:.4g} A, lies outside "
                            f"[{wr.u_max:.3g}, {first:.3g}] A, between the region's upper bound and the first "
                            f"plateau level of the {source}: the model and the staircase disagree.")
    return Decision("working_region", rule, choice, rows, reasons, cautions=cautions)
