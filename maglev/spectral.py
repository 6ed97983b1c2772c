"""Nonparametric frequency responses of records (Welch, MATLAB's ``spa``-style) and the study's preprocessing.

Why here, in the identification layer: estimating a record's frequency response and its standard error
needs nothing of the simulator; the simulator's best linear approximation (:mod:`maglev.sim.bla`) averages
the same spectra over many simulated realisations, and the sim-vs-real comparison and the study's figures
estimate real records with it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
from scipy import signal

from maglev.data import IOData

if TYPE_CHECKING:
    from maglev.uncertainty import FrequencyBounds

__all__ = ["Preprocess", "FrequencyResponse", "frequency_response", "spectra", "segment_length", "RECORD_SEGMENT_S"]

RECORD_SEGMENT_S = 2.0  # s per segment of one record's estimate (frequency_response): ≥ 10 averages on 22 s
_HANN_OVERLAP_RHO = 0.1667  # correlation of Hann segments overlapping by 50 % (Welch 1967)


@dataclass(frozen=True)
class Preprocess:
    """The study's preprocessing, applied in this order: trim, detrend, decimate."""

    trim: int = 2000  # samples dropped at the start (the start-up transient)
    detrend: bool = True  # remove the means of u and y
    decimate: int = 1  # keep every k-th sample after the anti-aliasing filter

    def __post_init__(self) -> None:
        if not isinstance(self.trim, (int, np.integer)) or self.trim < 0:
            raise ValueError(f"Preprocess.trim must be an integer >= 0, got {self.trim!r}")
        if not isinstance(self.decimate, (int, np.integer)) or self.decimate < 1:
            raise ValueError(f"Preprocess.decimate must be an integer >= 1, got {self.decimate!r}")

    def apply(self, data: IOData) -> IOData:
        data = data.trim(int(self.trim)) if self.trim else data
        data = data.detrend() if self.detrend else data
        return data.decimate(int(self.decimate))


@dataclass(frozen=True)
class FrequencyResponse:
    """A nonparametric frequency response Ĝ(e^{jωTs}) = Σ S_yu / Σ S_uu and what it rests on.

    Spectra are one-sided Welch densities per Hz (so Σ S·df is the signal's power,
    ``df = w[1] / 2π``).  ``std`` is the RMS error sqrt(E|Ĝ - G|²) of the complex
    estimate (the magnitude's and the phase's standard errors are ≈ std/√2 and
    std/(√2|G|)); ``coherence`` is |S_yu|² / (S_uu S_yy).
    """

    w: np.ndarray  # rad/s on the time base of the (preprocessed) data, 0 .. π/Ts
    G: np.ndarray  # complex frequency response
    std: np.ndarray  # RMS error of G
    coherence: np.ndarray
    Suu: np.ndarray  # input PSD [u²/Hz]
    Syy: np.ndarray  # output PSD [y²/Hz]
    Ts: float  # s, sampling period of the preprocessed data
    averages: int  # Welch segments averaged (over all records)

    @property
    def df(self) -> float:
        return float(self.w[1] / (2 * math.pi))

    @property
    def magnitude_db(self) -> np.ndarray:
        return 20 * np.log10(np.abs(self.G))

    def band_rms(self, lo: float, hi: float) -> tuple[float, float]:
        """(coherent, incoherent) rms of the output over ``lo <= w < hi`` rad/s.

        sqrt(Σ γ² S_yy df) is the part of y the input explains linearly (|S_yu|² / S_uu: the
        output of the estimated G), sqrt(Σ (1 - γ²) S_yy df) the rest (noise, nonlinear
        distortion); their squares add up to the band's output power.  Why: two records
        with the same output std can differ in how much of it the input drives; on the rig's
        ``white_noise_2`` most of the output is incoherent, while the simulator's replay of
        the same input is mostly coherent.

        Each Welch bin stands for ``df`` around its frequency (the DC bin for half of it),
        so the band is resolved to the bins whose frequency lies in it.  The segments' leakage
        leaves a small incoherent floor even without noise: a few % of the coherent rms for a
        response that decays in ≈ 25 ms, with 1 s segments.  Raises ValueError unless
        0 <= lo < hi and the band holds at least one bin.
        """
        if not 0.0 <= lo < hi:
            raise ValueError(f"band_rms needs 0 <= lo < hi rad/s, got lo={lo!r}, hi={hi!r}")
        inside = (self.w >= lo) & (self.w < hi)
        if not inside.any():
            raise ValueError(f"band {lo!r} <= w < {hi!r} rad/s holds none of the estimate's frequencies "
                             f"(0 .. {self.w[-1]:g} rad/s, {2 * math.pi * self.df:g} apart)")
        coh = np.clip(self.coherence[inside], 0.0, 1.0)
        power = self.Syy[inside] * self.df
        return float(math.sqrt(np.sum(coh * power))), float(math.sqrt(np.sum((1.0 - coh) * power)))

    def bounds(self, level: float = 0.99, name: str | None = None) -> "FrequencyBounds":
        """The estimate with pointwise bounds at ``level`` (ω > 0), for :func:`maglev.plots.plot_bode`.

        The complex error is taken as circular: the magnitude's standard error is std/√2 and
        the phase's std/(√2 |G|) (in degrees).
        """
        from maglev.uncertainty import FrequencyBounds, multiplier

        keep = self.w > 0
        sd_mag = self.std[keep] / math.sqrt(2.0)
        k, coverage = multiplier(level)
        return FrequencyBounds(w=self.w[keep], response=self.G[keep], sd_magnitude=sd_mag,
                               sd_phase=np.degrees(sd_mag / np.abs(self.G[keep])), k=k, level=coverage, name=name)

    def simulate(self, u: np.ndarray) -> np.ndarray:
        """G u as a frequency-domain (two-sided FIR) filter: the inverse FFT of G on the Welch grid.

        The impulse response has one segment's length, centred on lag 0 (the estimate
        leaks a little into negative lags, which are kept so the filter is exactly G on
        the grid); the first and last half segment of the output lack part of their past
        or future input.
        """
        n = 2 * (self.w.size - 1)
        g = np.fft.irfft(self.G, n=n)
        two_sided = np.r_[g[n // 2:], g[: n // 2]]  # lags -n/2 .. n/2 - 1
        full = signal.fftconvolve(np.asarray(u, dtype=float), two_sided)
        return full[n // 2: n // 2 + len(u)]


def spectra(data: IOData, nperseg: int) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, int]:
    """(f [Hz], S_uu, S_yy, S_yu, segments) of one record, Hann windows overlapping by half."""
    if data.N < nperseg:
        raise ValueError(f"{data.name or 'record'}: {data.N} samples are fewer than one Welch segment "
                         f"({nperseg}); use a longer record or a shorter segment")
    kw = dict(fs=1.0 / data.Ts, window="hann", nperseg=nperseg, noverlap=nperseg // 2, detrend=False)
    f, suu = signal.welch(data.u, **kw)
    _, syy = signal.welch(data.y, **kw)
    _, syu = signal.csd(data.u, data.y, **kw)  # conj(U) Y: S_yu in the convention G = S_yu / S_uu
    return f, suu, syy, syu, 1 + (data.N - nperseg) // (nperseg // 2)


def segment_length(Ts: float, segment_s: float) -> int:
    """Samples per Welch segment of ``segment_s`` seconds at ``Ts`` (rounded up to an even number)."""
    n = int(round(segment_s / Ts))
    return n + n % 2


def _effective(segments: int) -> float:
    """Independent averages equivalent to ``segments`` Hann segments overlapping by half."""
    return segments / (1 + 2 * _HANN_OVERLAP_RHO ** 2)


def frequency_response(data: IOData, segment_s: float = RECORD_SEGMENT_S) -> FrequencyResponse:
    """Welch (``spa``-style) frequency-response estimate of one record, as it is (preprocess it first).

    Standard error from the coherence and the number of averaged segments n
    (Bendat & Piersol): sqrt(E|Ĝ - G|²) = |Ĝ| sqrt((1 - γ²) / (γ² n)), with n the
    segments' equivalent number of independent averages.
    """
    f, suu, syy, syu, k = spectra(data, segment_length(data.Ts, segment_s))
    coh = np.abs(syu) ** 2 / np.maximum(suu * syy, np.finfo(float).tiny)
    G = syu / suu
    std = np.abs(G) * np.sqrt((1 - coh) / (np.maximum(coh, 1e-12) * _effective(k)))
    return FrequencyResponse(w=2 * np.pi * f, G=G, std=std, coherence=coh, Suu=suu, Syy=syy, Ts=data.Ts,
                             averages=k)
