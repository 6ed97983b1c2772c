"""The sampling period (EL2820 Lab 3 §3.2): rise time of the steps inside the working region.

The 10 %→90 % rise time of the averaged, normalised step response sets the sampling
period (4 to 10 samples per rise time) and hence the decimation of the 1 ms records.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from maglev.data import IOData
from maglev.lab.averages import check_tail, get_average

__all__ = ["HeldStep", "RiseTime", "held_steps", "rise_time"]


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


def _first_crossing(r: np.ndarray, level: float) -> float:
    """First (linearly interpolated) index where ``r`` reaches ``level``."""
    idx = np.flatnonzero(r >= level)
    if idx.size == 0:
        raise ValueError(f"the averaged step response never reaches {level:.0%} of its final value")
    k = int(idx[0])
    if k == 0:
        return 0.0
    return k - 1 + (level - r[k - 1]) / (r[k] - r[k - 1])


@dataclass(frozen=True)
class HeldStep:
    """One input step between two held levels: the input ``u0`` -> ``u1`` at sample ``k``, held for
    ``length`` samples after it, and the stationary outputs ``y0`` before and ``y1`` after it."""

    k: int
    length: int
    u0: float
    u1: float
    y0: float
    y1: float

    def response(self, y: np.ndarray, length: int | None = None) -> np.ndarray:
        """The step's response in ``y`` normalised to go from 0 (``y0``) to 1 (``y1``), over ``length``
        samples (default: the whole hold)."""
        n = self.length if length is None else length
        return (y[self.k:self.k + n] - self.y0) / (self.y1 - self.y0)


def held_steps(
    data: IOData,
    *,
    u_range: tuple[float, float] | None = None,
    min_len: int = 60,
    tail: float = 50.0,
) -> list[HeldStep]:
    """Every step of ``data.u`` whose two levels lie in ``u_range``, held for at least ``min_len``
    samples on both sides and moving the output; the stationary levels are the means of the last
    ``tail`` % of the two holding periods."""
    u, y = data.u, data.y
    lo, hi = u_range if u_range is not None else (-np.inf, np.inf)
    if not isinstance(min_len, int) or min_len < 4:
        raise ValueError(f"min_len must be an integer >= 4 samples, got {min_len!r}")
    check_tail(tail)
    edges = np.concatenate([[0], np.flatnonzero(np.diff(u) != 0) + 1, [u.size]])
    steps = []
    for a, k, b in zip(edges[:-2], edges[1:-1], edges[2:]):
        if k - a < min_len or b - k < min_len:
            continue
        if not (lo <= u[a] <= hi and lo <= u[k] <= hi):
            continue
        y0, y1 = get_average(y[a:k], tail), get_average(y[k:b], tail)
        if abs(y1 - y0) > 0:
            steps.append(HeldStep(k=int(k), length=int(b - k), u0=float(u[a]), u1=float(u[k]), y0=y0, y1=y1))
    if not steps:
        raise ValueError(
            f"{data.name or 'data'}: no input step with both levels in u_range={u_range} held for "
            f">= min_len={min_len} samples; expected a staircase or step record"
        )
    return steps


def rise_time(
    data: IOData,
    *,
    u_range: tuple[float, float] | None = None,
    min_len: int = 60,
    tail: float = 50.0,
) -> RiseTime:
    """Rise time from every step of ``data.u`` whose two levels lie in ``u_range`` (:func:`held_steps`).

    Each step's response over the shortest holding length is normalised by the
    stationary levels before and after it, so up and down steps of any size average
    together; noise shrinks by the square root of the number of steps.
    """
    steps = held_steps(data, u_range=u_range, min_len=min_len, tail=tail)
    length = min(s.length for s in steps)
    response = np.mean([s.response(data.y, length) for s in steps], axis=0)
    t10, t90 = _first_crossing(response, 0.1), _first_crossing(response, 0.9)
    return RiseTime(samples=float(t90 - t10), Ts=data.Ts, n_steps=len(steps), response=response,
                    t10=float(t10), t90=float(t90))
