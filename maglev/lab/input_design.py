"""Input design (EL2820 Lab 3 §3.4): the output's energy band and the binary signal's α*.

The band holding most of the output's spectral energy is where the input must put its
power; the random binary signal's switching probability α shapes its spectrum, and α*
is the lab's α with the largest share of power in that band.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

__all__ = ["LAB_ALPHAS", "OutputSpectrum", "output_spectrum", "AlphaChoice", "choose_alpha"]

LAB_ALPHAS: tuple[float, ...] = (0.0, 0.25, 0.5, 0.75, 1.0)


@dataclass(frozen=True)
class OutputSpectrum:
    """|FFT(y - ȳ)| at ω_n = 2πn/N, n = 1..N/2, and the narrowest band holding ``fraction`` of its energy."""

    w: np.ndarray  # rad/sample
    magnitude: np.ndarray
    band: tuple[float, float]  # rad/sample
    fraction: float


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
