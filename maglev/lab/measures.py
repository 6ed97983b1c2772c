"""The lab's numbers on one record: the staircase's averages and steps, the output's level, spread and hops,
the sensor's noise, and the modes of models identified from the record.

Why in the lab layer: nothing here knows the simulator; the same function measures a real record and a
simulated one, so the sim-vs-real comparison (:mod:`maglev.sim.sim_vs_real`) and the calibration compare
like with like, with the settings below.

Frequencies are in rad/s of the record's time base (the 1 ms label of the lab's records).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy import signal

from maglev.data import IOData
from maglev.estimation import armax, oe
from maglev.lab.averages import get_stationary_averages
from maglev.lab.sampling import held_steps, rise_time

Mode = tuple[float, float]  # (ωn [rad/s], ζ)

STAIR_LEVELS = 21
STAIR_TAIL = 50.0
STAIR_STEP_RANGE = (1.5, 4.0)  # A: the staircase's levels inside the working region (rise time, overshoot)
STEP_GAIN_BAND = (30.0, 150.0)  # rad/s: around the slow mode (≈ 75-90 rad/s), below the fast one
TRANSIENT_FRACTION = 0.25  # start-up transient dropped from identification records
OE_ORDERS = (2, 2, 3)  # nb, nf, nk of the models whose dominant mode is compared
FOURTH_ORDERS = (4, 4, 5)  # nb, nf, nk of the models that resolve both modes (after decimation)
FOURTH_DECIMATION = 2
ARMAX_ORDERS = (4, 4, 4, 1)  # na, nb, nc, nk, at the labelled 1 ms
SLOWEST_RESONANCE = 30.0  # rad/s: slower identified pairs are drift or stick plateaus, not resonances
# rad/s: faster pairs sit at the Nyquist frequency of the records decimated by FOURTH_DECIMATION (1571 rad/s), the
# noise's sample-to-sample alternation, not a resonance (the rig's modes lie near 75-90 and 215 rad/s)
FASTEST_RESONANCE = 1000.0
SLOW_BAND, FAST_BAND = (40.0, 150.0), (150.0, 400.0)  # rad/s: where the two lightly damped modes lie
LIGHTLY_DAMPED = 0.6  # ζ below which a pair counts as a lightly damped mode


# ---------------------------------------------------------------------- the staircase and the output
def stair_averages(data: IOData) -> tuple[np.ndarray, np.ndarray]:
    """Stationary averages (ū, ȳ) of the 21-level staircase."""
    return (get_stationary_averages(data.u, STAIR_LEVELS, STAIR_TAIL),
            get_stationary_averages(data.y, STAIR_LEVELS, STAIR_TAIL))


def stair_step(data: IOData, u_range: tuple[float, float] = STAIR_STEP_RANGE) -> tuple[float, float]:
    """(rise time [samples], overshoot [fraction]) of the mean normalised stair step in ``u_range``."""
    rt = rise_time(data, u_range=u_range)
    return rt.samples, float(rt.response.max() - 1.0)


@dataclass(frozen=True)
class StairStep:
    """One stair step's numbers: the levels ``u0`` -> ``u1`` [A], its overshoot (fraction of the step) and
    its band gain [cm/A]: the rms of |G| over a band (trapezoids on a 1 rad/s grid), G the DTFT of the
    step's impulse response (the differenced response over the whole hold, per A of the step)."""

    u0: float
    u1: float
    overshoot: float
    band_gain: float


def stair_steps(data: IOData, u_range: tuple[float, float] = STAIR_STEP_RANGE,
                band: tuple[float, float] = STEP_GAIN_BAND) -> list[StairStep]:
    """Overshoot and band gain of each stair step in ``u_range``, one by one.

    Why: the mean normalised step (:func:`stair_step`) averages the working points away.  Step by
    step, with the step size fixed, the numbers say how the dynamics change with the working point
    alone, which the records with a wider input range confound with the range.
    """
    lo, hi = band
    w = np.linspace(lo, hi, int(round(hi - lo)) + 1) * data.Ts  # rad/sample
    out = []
    for step in held_steps(data, u_range=u_range):
        r = step.response(data.y)
        h = np.diff(r, prepend=0.0) * (step.y1 - step.y0) / (step.u1 - step.u0)
        _, g = signal.freqz(h, worN=w)
        power = np.trapezoid(np.abs(g) ** 2, w) / (w[-1] - w[0])
        out.append(StairStep(u0=step.u0, u1=step.u1, overshoot=float(r.max() - 1.0), band_gain=float(np.sqrt(power))))
    return out


def noise_psd(y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Welch periodogram of the detrended reading (frequencies in cycles/sample)."""
    return signal.welch(y - y.mean(), nperseg=512)


def quantisation_step(y: np.ndarray) -> float:
    """Smallest nonzero difference between readings (the ADC step)."""
    steps = np.abs(np.diff(np.asarray(y, dtype=float)))
    return float(steps[steps > 1e-9].min())


def output_std(data: IOData) -> float:
    """Std of the reading after dropping the start-up transient (``TRANSIENT_FRACTION``) [cm]."""
    return float(np.std(data.trim(TRANSIENT_FRACTION).y))


STD_PARTS = 3  # pieces of the kept part whose stds show how steady a record's amplitude is


def output_std_parts(data: IOData, parts: int = STD_PARTS) -> tuple[float, ...]:
    """Std of each of ``parts`` equal consecutive pieces of the reading after the start-up transient [cm].

    Why: the check compares one std per record, and the rig's small records are not steady (white_noise_1's
    thirds differ by 1.7x); their spread says how well a single record knows its own std.
    """
    return tuple(float(np.std(piece)) for piece in np.array_split(data.trim(TRANSIENT_FRACTION).y, parts))


HOP_LEVEL = 12.0  # cm: the rig's readings exceed it only in binary_signal_2's hops


def hops(data: IOData, level: float = HOP_LEVEL) -> tuple[float, float]:
    """(share of the reading above ``level``, largest reading [cm]) after the start-up transient.

    Why: on the rig, binary α .25 over 1.5-4 A throws the upper magnet up in hops that read up to
    15.6 cm, and no other record passes 10.5 cm; the output std alone cannot tell such hops from a
    larger steady swing.
    """
    y = data.trim(TRANSIENT_FRACTION).y
    return float(np.mean(y > level)), float(y.max())


def output_level(data: IOData) -> float:
    """Mean reading after the start-up transient [cm]: the working point a record sits at."""
    return float(np.mean(data.trim(TRANSIENT_FRACTION).y))


# ---------------------------------------------------------------------- identified modes
def _continuous(poles: np.ndarray, Ts: float) -> np.ndarray:
    s = np.log(np.asarray(poles, dtype=complex)) / Ts
    return s[np.abs(s) > 0]


def dominant_mode(poles: np.ndarray, Ts: float) -> Mode:
    """(ωn [rad/s], ζ) of the slowest complex pole pair (else slowest pole), via s = log(z)/Ts."""
    s = _continuous(poles, Ts)
    cplx = s[s.imag > 1e-9]
    pick = cplx if cplx.size else s
    p = pick[np.argmin(np.abs(pick))]
    return float(abs(p)), float(-p.real / abs(p))


def complex_modes(poles: np.ndarray, Ts: float) -> list[Mode]:
    """(ωn [rad/s], ζ) of every complex pole pair, slowest first."""
    s = _continuous(poles, Ts)
    return sorted((float(abs(p)), float(-p.real / abs(p))) for p in s[s.imag > 1e-9])


def dominant_mode_of(data: IOData) -> Mode:
    """Dominant mode of the OE(2,2,3) model of a record (trimmed, detrended)."""
    d = data.trim(TRANSIENT_FRACTION).detrend()
    return dominant_mode(oe(d, *OE_ORDERS).poles(), d.Ts)


def fourth_order_modes_of(data: IOData) -> list[Mode]:
    """Complex modes of the OE(4,4,5) model of a record (trimmed, detrended, decimated by 2)."""
    d = data.trim(TRANSIENT_FRACTION).detrend().decimate(FOURTH_DECIMATION)
    return complex_modes(oe(d, *FOURTH_ORDERS).poles(), d.Ts)


def armax_modes_of(data: IOData) -> list[Mode]:
    """Complex modes of ARMAX [4 4 4 1] on the first half of the record with its mean removed (no trim)."""
    est, _ = data.detrend().split(0.5)
    return complex_modes(armax(est, *ARMAX_ORDERS).poles(), data.Ts)


def two_modes(modes: list[Mode]) -> tuple[Mode | None, Mode | None]:
    """The least-damped lightly damped mode in ``SLOW_BAND`` and in ``FAST_BAND`` (None where there is none)."""
    def pick(band: tuple[float, float]) -> Mode | None:
        inside = [m for m in modes if band[0] <= m[0] < band[1] and m[1] < LIGHTLY_DAMPED]
        return min(inside, key=lambda m: m[1]) if inside else None
    return pick(SLOW_BAND), pick(FAST_BAND)


def least_damped(modes: list[Mode], slowest: float = SLOWEST_RESONANCE, fastest: float = FASTEST_RESONANCE) -> Mode:
    """The mode with the smallest ζ among those with ``slowest`` <= ωn <= ``fastest`` (NaNs if there is none)."""
    resonances = [m for m in modes if slowest <= m[0] <= fastest]
    return min(resonances, key=lambda m: m[1]) if resonances else (math.nan, math.nan)
