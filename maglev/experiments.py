"""The lab's analysis steps before identification, as functions returning small result objects.

EL2820 Lab 3 asks the students to (§3.1) average the stationary part of every level of
a staircase response and pick the working region where ȳ vs ū is nearly a straight
line, (§3.2) measure the 10 %→90 % rise time to choose the sampling period, and
(§3.4) find the band holding most of the output's spectral energy and pick the random
binary signal's α whose spectrum puts most power there.  Each step here returns numbers
in a frozen dataclass with a ``plot()`` method that draws the lab's figure on a
matplotlib ``Figure`` (created without pyplot, so it is safe headless and never shows).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from matplotlib.axes import Axes
from matplotlib.figure import Figure

from maglev.data import IOData
from maglev.signals import rbs_spectrum

__all__ = [
    "get_average",
    "get_stationary_averages",
    "WorkingRegion",
    "working_region",
    "RiseTime",
    "rise_time",
    "OutputSpectrum",
    "output_spectrum",
    "AlphaChoice",
    "choose_alpha",
    "LAB_ALPHAS",
]

LAB_ALPHAS: tuple[float, ...] = (0.0, 0.25, 0.5, 0.75, 1.0)


def _axes(ax: Axes | None) -> Axes:
    return Figure(figsize=(6, 4), layout="constrained").add_subplot() if ax is None else ax


def _check_tail(tail: float) -> float:
    tail_f = float(tail)
    if not 0.0 < tail_f <= 100.0:
        raise ValueError(f"tail must be a percentage in (0, 100], got {tail!r}")
    return tail_f


# ---------------------------------------------------------------------- §4 preparation tasks 2-3
def get_average(v: Sequence[float] | np.ndarray, tail: float) -> float:
    """Mean of the last ``tail`` percent of ``v`` (at least one sample), the lab's ``getAverage``."""
    tail = _check_tail(tail)
    arr = np.asarray(v, dtype=float).reshape(-1)
    if arr.size == 0:
        raise ValueError("v must hold at least one sample, got an empty vector")
    n = max(1, int(round(arr.size * tail / 100.0)))
    return float(arr[-n:].mean())


def get_stationary_averages(y_step: Sequence[float] | np.ndarray, nwr: int, tail: float) -> np.ndarray:
    """``get_average`` of each of the ``nwr`` equal-length levels of a staircase response."""
    y = np.asarray(y_step, dtype=float).reshape(-1)
    if isinstance(nwr, (bool, np.bool_)) or not isinstance(nwr, (int, np.integer)) or nwr < 1:
        raise ValueError(f"nwr must be a positive integer number of levels, got {nwr!r}")
    if y.size == 0 or y.size % nwr:
        raise ValueError(
            f"y_step has {y.size} samples, which is not a multiple of nwr={nwr}; "
            "expected len(y_step) = nwr * samples per level"
        )
    _check_tail(tail)
    return np.array([get_average(seg, tail) for seg in y.reshape(nwr, -1)])


# ---------------------------------------------------------------------- §3.1 working region
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

    def plot(self, ax: Axes | None = None) -> Figure:
        """ȳ vs ū with the fitted line and the region's bounds and centre (the lab's Fig. 3)."""
        ax = _axes(ax)
        inside = slice(self.lo, self.hi + 1)
        ax.plot(self.u_bar, self.y_bar, "s", mfc="none", color="tab:red", label="stationary averages")
        uu = np.array([self.u_min, self.u_max])
        ax.plot(uu, self.slope * uu + self.intercept, "k-", label=f"LS line, slope {self.slope:.3g}")
        ax.plot(self.u_bar[inside], self.y_bar[inside], "s", color="tab:red")
        for edge in uu:
            ax.axvline(edge, color="k", lw=0.8)
        ax.axvline(self.u_star, color="k", ls=":", label=f"working point {self.u_star:.3g}")
        ax.set_xlabel("step level ū")
        ax.set_ylabel("stationary output ȳ")
        ax.set_title(f"Working region [{self.u_min:.3g}, {self.u_max:.3g}]")
        ax.legend(loc="best", fontsize="small")
        return ax.figure


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


# ---------------------------------------------------------------------- §3.2 rise time
@dataclass(frozen=True)
class RiseTime:
    """10 %→90 % rise time of the averaged, normalised step response and the advised sampling.

    ``response`` is the average of the steps used, each scaled to go from 0 (level
    before the step) to 1 (stationary level after it).  ``ts_range`` is the sampling
    period giving 4 to 10 samples per rise time; ``decimation`` the recommended integer
    factor on the record's ``Ts`` (about 7 samples per rise time, inside that range
    when one exists) and ``decimation_range`` all factors inside it.
    """

    samples: float
    Ts: float
    n_steps: int
    response: np.ndarray
    t10: float
    t90: float

    @property
    def seconds(self) -> float:
        return self.samples * self.Ts

    @property
    def ts_range(self) -> tuple[float, float]:
        return (self.seconds / 10.0, self.seconds / 4.0)

    @property
    def decimation_range(self) -> tuple[int, int]:
        return (max(1, math.ceil(self.samples / 10.0)), max(1, math.floor(self.samples / 4.0)))

    @property
    def decimation(self) -> int:
        k_lo, k_hi = self.decimation_range
        return int(min(max(round(self.samples / 7.0), k_lo), k_hi))

    def plot(self, ax: Axes | None = None) -> Figure:
        """The averaged normalised step response with the 10 % and 90 % crossings (the lab's Fig. 4)."""
        ax = _axes(ax)
        ax.plot(np.arange(self.response.size), self.response, color="tab:blue",
                label=f"mean of {self.n_steps} normalised steps")
        for level, t in ((0.1, self.t10), (0.9, self.t90)):
            ax.axhline(level, color="k", lw=0.6, ls=":")
            ax.axvline(t, color="tab:red", lw=0.8)
        ax.set_xlabel("samples after the step")
        ax.set_ylabel("normalised output")
        ax.set_title(f"Rise time {self.samples:.1f} samples = {self.seconds * 1e3:.3g} ms; "
                     f"decimate by {self.decimation}")
        ax.legend(loc="lower right", fontsize="small")
        return ax.figure


def _first_crossing(r: np.ndarray, level: float) -> float:
    """First (linearly interpolated) index where ``r`` reaches ``level``."""
    idx = np.flatnonzero(r >= level)
    if idx.size == 0:
        raise ValueError(f"the averaged step response never reaches {level:.0%} of its final value")
    k = int(idx[0])
    if k == 0:
        return 0.0
    return k - 1 + (level - r[k - 1]) / (r[k] - r[k - 1])


def rise_time(
    data: IOData,
    *,
    u_range: tuple[float, float] | None = None,
    min_len: int = 60,
    tail: float = 50.0,
) -> RiseTime:
    """Rise time from every step of ``data.u`` whose two levels lie in ``u_range``.

    A step is any change of the input held for at least ``min_len`` samples on both
    sides.  Each step's response over the shortest such holding length is normalised
    by the stationary levels before and after it (means of the last ``tail`` % of the
    two holding periods), so up and down steps of any size average together; noise
    shrinks by the square root of the number of steps.
    """
    u, y = data.u, data.y
    lo, hi = u_range if u_range is not None else (-np.inf, np.inf)
    if not isinstance(min_len, int) or min_len < 4:
        raise ValueError(f"min_len must be an integer >= 4 samples, got {min_len!r}")
    _check_tail(tail)
    edges = np.concatenate([[0], np.flatnonzero(np.diff(u) != 0) + 1, [u.size]])
    steps = []
    for a, k, b in zip(edges[:-2], edges[1:-1], edges[2:]):
        if k - a < min_len or b - k < min_len:
            continue
        if not (lo <= u[a] <= hi and lo <= u[k] <= hi):
            continue
        y0, y1 = get_average(y[a:k], tail), get_average(y[k:b], tail)
        if abs(y1 - y0) > 0:
            steps.append((k, b - k, y0, y1))
    if not steps:
        raise ValueError(
            f"{data.name or 'data'}: no input step with both levels in u_range={u_range} held for "
            f">= min_len={min_len} samples; expected a staircase or step record"
        )
    length = min(s[1] for s in steps)
    response = np.mean([(y[k:k + length] - y0) / (y1 - y0) for k, _, y0, y1 in steps], axis=0)
    t10, t90 = _first_crossing(response, 0.1), _first_crossing(response, 0.9)
    return RiseTime(samples=float(t90 - t10), Ts=data.Ts, n_steps=len(steps), response=response,
                    t10=float(t10), t90=float(t90))


# ---------------------------------------------------------------------- §3.4 output spectrum
@dataclass(frozen=True)
class OutputSpectrum:
    """|FFT(y - ȳ)| at ω_n = 2πn/N, n = 1..N/2, and the narrowest band holding ``fraction`` of its energy."""

    w: np.ndarray  # rad/sample
    magnitude: np.ndarray
    band: tuple[float, float]  # rad/sample
    fraction: float

    def plot(self, ax: Axes | None = None) -> Figure:
        """|Y| against normalised frequency with the energy band shaded."""
        ax = _axes(ax)
        ax.semilogy(self.w / np.pi, self.magnitude, lw=0.6, color="tab:blue", label="|FFT(y - mean y)|")
        ax.axvspan(self.band[0] / np.pi, self.band[1] / np.pi, color="tab:orange", alpha=0.3,
                   label=f"{self.fraction:.0%} of the energy")
        ax.set_xlabel("ω / π  (1 = Nyquist)")
        ax.set_ylabel("|Y|")
        ax.legend(loc="best", fontsize="small")
        return ax.figure


def output_spectrum(y: Sequence[float] | np.ndarray, fraction: float = 0.8) -> OutputSpectrum:
    """The output spectrum of the lab's §3.4 and its energy band (narrowest contiguous band)."""
    if not 0 < fraction < 1:
        raise ValueError(f"fraction must be in (0, 1), got {fraction!r}")
    y = np.asarray(y, dtype=float).reshape(-1)
    if y.size < 8:
        raise ValueError(f"y must have at least 8 samples, got {y.size}")
    n = y.size
    Y = np.fft.fft(y - y.mean())[1:n // 2 + 1]
    w = 2 * np.pi * np.arange(1, n // 2 + 1) / n
    mag = np.abs(Y)
    cum = np.concatenate([[0.0], np.cumsum(mag ** 2)])
    need = fraction * cum[-1]
    # for each start bin i, the first end bin j with energy(i..j) >= need
    ends = np.searchsorted(cum, cum[:-1] + need, side="left") - 1
    ok = ends < w.size
    starts = np.flatnonzero(ok)
    widths = w[ends[ok]] - w[starts]
    best = int(np.argmin(widths))
    i, j = int(starts[best]), int(ends[ok][best])
    return OutputSpectrum(w=w, magnitude=mag, band=(float(w[i]), float(w[j])), fraction=float(fraction))


# ---------------------------------------------------------------------- §3.4 choice of alpha
def _rbs_power_share(alpha: float, w1: float, w2: float) -> float:
    """Share of the ±1 binary signal's power (over 0 < ω <= π) lying in [w1, w2].

    The lab's spectrum is the Poisson kernel with ρ = 1 - 2α, whose integral is
    2 arctan(((1+ρ)/(1-ρ)) tan(ω/2)); α = 0 is a constant (no power at ω > 0) and
    α = 1 alternates (all power at ω = π).
    """
    if alpha == 0.0:
        return 0.0
    if alpha == 1.0:
        return 1.0 if w2 >= np.pi else 0.0
    ratio = (1.0 - alpha) / alpha  # (1 + ρ) / (1 - ρ)

    def prim(w: float) -> float:
        return math.pi if w >= math.pi else 2.0 * math.atan(ratio * math.tan(w / 2.0))

    return (prim(w2) - prim(w1)) / math.pi


@dataclass(frozen=True)
class AlphaChoice:
    """Share of the random binary signal's power inside ``band`` for each α, and the best α."""

    alphas: tuple[float, ...]
    shares: tuple[float, ...]
    band: tuple[float, float]  # rad/sample

    @property
    def alpha_star(self) -> float:
        return self.alphas[int(np.argmax(self.shares))]

    def plot(self, ax: Axes | None = None) -> Figure:
        """Binary-signal spectra for each α with the output's energy band shaded (the lab's Fig. 5)."""
        ax = _axes(ax)
        w = np.linspace(1e-3, np.pi - 1e-3, 600)
        for alpha, share in zip(self.alphas, self.shares):
            style = "-" if alpha == self.alpha_star else "--"
            if 0 < alpha < 1:
                ax.plot(w / np.pi, rbs_spectrum(alpha, w), style, label=f"α = {alpha:g} ({share:.0%} in band)")
            else:
                where = 0.0 if alpha == 0 else 1.0
                ax.axvline(where, ls=style, color="gray", label=f"α = {alpha:g}: line at ω = {where:g}π")
        ax.axvspan(self.band[0] / np.pi, self.band[1] / np.pi, color="tab:orange", alpha=0.3,
                   label="output energy band")
        ax.set_yscale("log")
        ax.set_xlabel("ω / π")
        ax.set_ylabel("Φ_s(ω)")
        ax.set_title(f"α* = {self.alpha_star:g}")
        ax.legend(loc="best", fontsize="small")
        return ax.figure


def choose_alpha(band: tuple[float, float], alphas: Sequence[float] = LAB_ALPHAS) -> AlphaChoice:
    """The α whose binary spectrum puts the largest share of its power in ``band`` (rad/sample)."""
    w1, w2 = float(band[0]), float(band[1])
    if not 0 <= w1 < w2 <= np.pi + 1e-12:
        raise ValueError(f"band must be (w1, w2) in rad/sample with 0 <= w1 < w2 <= pi, got {band!r}")
    alist = tuple(float(a) for a in alphas)
    for a in alist:
        if not 0 <= a <= 1:
            raise ValueError(f"alpha must be a probability in [0, 1], got {a!r}")
    shares = tuple(_rbs_power_share(a, w1, w2) for a in alist)
    return AlphaChoice(alphas=alist, shares=shares, band=(w1, w2))
