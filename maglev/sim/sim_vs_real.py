"""The simulated-vs-real comparison: the lab's numbers on the real records and on the simulator.

Why: every claim about the simulator's realism must be a number anyone can
recompute.  :func:`compare` replays the real records' inputs through a
:class:`~maglev.sim.plant.Levitator` and computes, on both, what the lab computes: the
static curve, the sensor noise, rise time and overshoot of the stair steps, α*, the
output std per record (the rig's amplitude dependence) and the lightly damped modes of
models identified with the same settings from real and simulated records.  The
settings here are also the targets ``maglev.sim.calibrate`` fits.

Two identifications, because the rig has two lightly damped modes and no one model
order shows both on every record:

* the dominant mode (≈ 90 rad/s) of OE(2,2,3) models of the binary records, trimmed and
  detrended (``OE_ORDERS``);
* both modes (≈ 80-90 and ≈ 215 rad/s) of OE(4,4,5) models of the same records and of
  ``white_noise_4`` (U(1.5, 4) A), decimated by 2 (``FOURTH_ORDERS``; nk = 5 is
  ``delayest`` on the decimated real ``white_noise_4``).  On white noise the 90 rad/s
  mode is not excited enough to be identified (the friction holds small motions
  back), so its least-damped mode (pairs slower than 30 rad/s are drift or stick
  plateaus, pairs faster than 1000 rad/s sit at the decimated records' Nyquist frequency;
  both are skipped) is the 215 rad/s one.

The ARMAX and frequency-response measurements (``ARMAX_ORDERS``, ``FRF_CLASSES``):

* ARMAX [4 4 4 1] on ``binary_signal_2`` at the labelled 1 ms, as the 2022 group
  identified it (whole record mean removed, first half): the rig shows two lightly
  damped modes (≈ 74 and ≈ 218 rad/s).  The fit is repeated on the simulated record
  without measurement noise: ARMAX's A polynomial also carries the noise's poles, so
  a sharp sensor-noise line can take two of its four poles (docs/simulator.md);
* the real records' Welch frequency-response estimate (:func:`maglev.spectral.frequency_response`,
  with its coherence-based error) against the simulator's best linear approximation
  for the same input class (:func:`maglev.sim.bla.bla`), both trimmed and detrended at 1 ms,
  compared in dB where the real estimate's coherence is at least ``FRF_COHERENCE``: the
  largest difference, its rms, and its mean per band of ``FRF_BANDS`` (a level offset
  shows in every band, a misplaced mode in one).  Beside the largest difference stands what
  an exact simulator would read from the real estimate's own error alone
  (:meth:`FrfComparison.exact_max_db`, ≈ 2.2 dB on the rig's records).

Beside the output stds, :func:`hops` gives each record's share of readings above
``HOP_LEVEL`` and its largest reading: on the rig only ``binary_signal_2`` hops (the upper
magnet thrown up to readings of 15.6 cm), which its std alone does not show.

The output of each of ``SPLIT_RECORDS``, real and simulated, is split per band
(``SPLIT_BANDS``) into the rms the input explains linearly (coherent) and the rest
(:func:`output_split`): equal output stds can rest on different parts.  On
``white_noise_2`` the rig's output is mostly incoherent (0-30 rad/s: 0.0017 cm coherent
vs 0.0134 cm), the simulator's replay mostly coherent (0.0100 vs 0.0026 cm).  The coherent
part per A of input (:func:`coherent_gain`, 30-150 rad/s) compared across the records of one
input class (``RANGE_CLASSES``) measures the response's range dependence: a linear plant
passes the same share at every range, the rig's share grows with the range in every class
(uniform ×5.0 from 0.75 to 2.5 A, binary α .5 ×1.5 and α .25 ×1.2 from 1.5 to 2.5 A).
:func:`stair_steps` reads the staircase's 0.5 A steps from 1.5 to 4 A one by one (overshoot, and gain over
the same band), so the working point can be told apart from the range: on the rig the gain falls with the
working point as the simulator's does, and the damping grows (the first step after lift-off overshoots 51 %,
the steps above 3 A 2-4 %).

Which of these numbers are checks, with which tolerances and why, is declared once in
:mod:`maglev.sim.checks`; :meth:`Comparison.verdicts` and the table's verdicts read it.

Frequencies are in rad/s of the 1 ms label the records carry.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from maglev.lab.input_design import choose_alpha, output_spectrum
from maglev.lab.measures import (ARMAX_ORDERS, FAST_BAND, FOURTH_DECIMATION, FOURTH_ORDERS, HOP_LEVEL, OE_ORDERS,
                                 SLOW_BAND, STD_PARTS, TRANSIENT_FRACTION, StairStep, armax_modes_of, dominant_mode_of,
                                 fourth_order_modes_of, hops, least_damped, noise_psd, output_level, output_std,
                                 output_std_parts, quantisation_step, stair_averages, stair_step, stair_steps,
                                 two_modes)
from maglev.sim import bla as bla_mod, checks
from maglev.sim.checks import (ARMAX_RECORD, ARMAX_WN_TOLERANCE, ARMAX_ZETA_TOLERANCE, FRF_TOLERANCE_DB,
                               MODE_TOLERANCE, POLE_RECORDS, RATIO_TOLERANCE, STATIC_NOISE_MULTIPLE,
                               STD_TOLERANCE, WHITE_RECORD, Mode)
from maglev.data import IOData
from maglev.sim.labdata import ExperimentSpec
from maglev.sim.plant import Levitator
from maglev.refdata import load_record
from maglev.spectral import FrequencyResponse, Preprocess, frequency_response

__all__ = ["Comparison", "FrfComparison", "compare", "compare_frf", "armax_errors", "output_split", "coherent_gain",
           "record_frf", "record_halves", "halves_frf", "halves_db"]

# records whose output std shows the rig's amplitude dependence (notes §4.6)
RECORD_INPUTS = {"binary_signal_1": "bin α.25 1.5-3 A", "binary_signal_2": "bin α.25 1.5-4 A",
                 "binary_signal_3": "bin α.5 1.5-4 A", "binary_signal_4": "bin α.5 1.5-3 A",
                 "white_noise_1": "U(1.5, 3) A", "white_noise_2": "U(1.75, 2.5) A",
                 "white_noise_4": "U(1.5, 4) A"}
STD_RECORDS = checks.STD_RECORDS
# the 2022 group's ARMAX on the α .25 1.5-4 A record, and the frequency-domain comparison
FRF_CLASSES = {  # real record -> its input class (the simulator's BLA is estimated for this class)
    "binary_signal_2": ExperimentSpec("binary", 1.5, 4.0, alpha=0.25, duration_s=20.0),
    "binary_signal_3": ExperimentSpec("binary", 1.5, 4.0, alpha=0.5, duration_s=20.0),
    "white_noise_4": ExperimentSpec("uniform", 1.5, 4.0, duration_s=20.0),
}
FRF_PREPROCESS = Preprocess(trim=2000, detrend=True, decimate=1)
FRF_SEGMENT_S = 1.0  # s per Welch segment: 17+ averages on a 20 s record, 6.3 rad/s resolution
FRF_COHERENCE = 0.5  # the real estimate's coherence above which the magnitudes are compared
FRF_REALISATIONS = 8
EXACT_DRAWS = 2000  # Monte Carlo draws of FrfComparison.exact_max_db
# rad/s of the 1 ms label, for the FRF gap by band: below the slow mode (≈ 75-90 rad/s), around it, between the
# modes, up to and around the fast one (≈ 218 rad/s), and above both (lo <= w < hi)
FRF_BANDS = ((0.0, 50.0), (50.0, 100.0), (100.0, 150.0), (150.0, 215.0), (215.0, 300.0), (300.0, 600.0))
# coherent / incoherent output per band (output_split): the records of RECORD_INPUTS
SPLIT_RECORDS = ("binary_signal_1", "binary_signal_2", "binary_signal_3", "binary_signal_4", "white_noise_1",
                 "white_noise_2", "white_noise_4")
# rad/s of the 1 ms label: below, at and above the two lightly damped modes, and the rest up to the Nyquist
# frequency (whose own bin, half a bin wide, is left out: lo <= w < hi)
SPLIT_BANDS = ((0.0, 30.0), (30.0, 150.0), (150.0, 400.0), (400.0, math.pi / 1e-3))

# input class -> its records of SPLIT_RECORDS, smallest range first: the response's range dependence (coherent_gain)
RANGE_CLASSES = {"uniform": ("white_noise_2", "white_noise_1", "white_noise_4"),
                 "bin α.5": ("binary_signal_4", "binary_signal_3"),
                 "bin α.25": ("binary_signal_1", "binary_signal_2")}
GAIN_BAND = SPLIT_BANDS[1]  # rad/s: around the slow mode (≈ 75-90 rad/s), below the fast one
# constant-input records that start from rest (0 A): how far a large step throws the upper magnet
STARTUP_RECORDS = ("binary_signal_9", "binary_signal_10")  # 3 A, 4 A (the regulator saturated)
STARTUP_SAMPLES = 1000  # the throw's peak is sought in the first ones



# ---------------------------------------------------------------------- the lab's numbers
def record_frf(data: IOData) -> FrequencyResponse:
    """A record's Welch frequency-response estimate with the comparison's settings (``FRF_PREPROCESS``,
    ``FRF_SEGMENT_S``): the same for a real record and a simulated replay."""
    return frequency_response(FRF_PREPROCESS.apply(data), FRF_SEGMENT_S)


def record_halves(data: IOData) -> tuple[IOData, IOData]:
    """The part of a record that :func:`record_frf` keeps, cut into two equal halves.  Each half comes
    with the ``FRF_PREPROCESS.trim`` samples before it, which :func:`record_frf` drops again, so both
    halves are estimated exactly as the whole record is."""
    trim = FRF_PREPROCESS.trim
    half = (len(data) - trim) // 2
    return data.segment(0, trim + half), data.segment(half, trim + 2 * half)


def halves_frf(data: IOData) -> tuple[FrequencyResponse, FrequencyResponse]:
    """:func:`record_frf` of each of a record's :func:`record_halves`, first half first."""
    first, second = record_halves(data)
    return record_frf(first), record_frf(second)


def halves_db(data: IOData, bands: tuple[tuple[float, float], ...] = FRF_BANDS) -> list[float]:
    """Mean dB of a record's second half over its first (:func:`halves_frf`) within each band (rad/s,
    lo <= w < hi), over the bins where both halves' coherence is at least ``FRF_COHERENCE``; nan where
    no bin is.

    Why: the halves of a record differ for two reasons.  Their inputs are two realisations, which a
    nonlinear plant answers differently, and the rig itself may drift.  The simulator's replay of the
    same input shows the first reason alone; what the rig shows beyond it is its own drift.  On
    binary_signal_2 the rig's second half passes 1.9-2.5 dB less than its first from 150 to 300 rad/s,
    stick_slip's replay 0.6 dB less to 0.2 dB more.
    """
    first, second = halves_frf(data)
    both = (first.coherence >= FRF_COHERENCE) & (second.coherence >= FRF_COHERENCE) & (first.w > 0)
    return _band_means(first.w[both], 20 * np.log10(np.abs(second.G[both]) / np.abs(first.G[both])), bands)


def output_split(data: IOData, bands: tuple[tuple[float, float], ...] = SPLIT_BANDS) -> list[tuple[float, float]]:
    """(coherent, incoherent) output rms [cm] per band of a record (:meth:`~maglev.spectral.FrequencyResponse.band_rms`)
    of its :func:`record_frf`.  Why: the output std alone cannot tell an output the input drives
    from one it does not.
    """
    frf = record_frf(data)
    return [frf.band_rms(lo, hi) for lo, hi in bands]


def coherent_gain(data: IOData, band: tuple[float, float] = GAIN_BAND) -> float:
    """Coherent output rms [cm] in ``band`` (as :func:`output_split`) per A of input std, both after
    ``FRF_PREPROCESS``.

    Why: within one input class (same distribution shape and switching, another range) a linear
    plant passes the same share at every range, so the ratio across a class's records
    (``RANGE_CLASSES``) says how far the response depends on the range.  On the rig it grows
    with the range in every class.
    """
    coherent, _ = record_frf(data).band_rms(*band)
    return coherent / float(np.std(FRF_PREPROCESS.apply(data).u))


def _noise_numbers(data: IOData) -> tuple[float, float, float]:
    y = data.trim(TRANSIENT_FRACTION).y
    f, psd = noise_psd(y)
    return output_std(data), float(f[np.argmax(psd)]), quantisation_step(y)


def _modes_text(modes: list[Mode]) -> str:
    return ", ".join(f"{w:.0f}/{z:.2f}" for w, z in modes) or "none"


# ---------------------------------------------------------------------- frequency domain
@dataclass(frozen=True)
class FrfComparison:
    """A real record's Welch FRF against the simulator's BLA for the same input class (or, in the
    calibration's cost, against the Welch FRF of the simulator's replay of the record)."""

    record: str
    real: FrequencyResponse
    sim: FrequencyResponse

    @property
    def band(self) -> np.ndarray:
        """Frequencies (mask) where the real estimate's coherence is at least ``FRF_COHERENCE``."""
        return (self.real.coherence >= FRF_COHERENCE) & (self.real.w > 0)

    @property
    def difference_db(self) -> np.ndarray:
        """|G_BLA| / |G_real| in dB over :attr:`band`."""
        b = self.band
        return 20 * np.log10(np.abs(self.sim.G[b]) / np.abs(self.real.G[b]))

    @property
    def max_db(self) -> float:
        d = self.difference_db
        return float(np.max(np.abs(d))) if d.size else math.nan

    @property
    def rms_db(self) -> float:
        d = self.difference_db
        return float(np.sqrt(np.mean(d ** 2))) if d.size else math.nan

    def band_means_db(self, bands: tuple[tuple[float, float], ...] = FRF_BANDS) -> list[float]:
        """Mean of :attr:`difference_db` within each band (rad/s, lo <= w < hi); nan where no bin is coherent.

        Why: the largest difference alone cannot tell a level offset (every band off the same way,
        as on binary_signal_2 and white_noise_4) from a misplaced mode (one band off, its
        neighbours the other way)."""
        return _band_means(self.real.w[self.band], self.difference_db, bands)

    @property
    def real_error_db(self) -> float:
        """Median 1-σ magnitude error of the real estimate over the band [dB]."""
        b = self.band
        rel = self.real.std[b] / np.sqrt(2) / np.abs(self.real.G[b])
        return float(np.median(20 * np.log10(1 + rel))) if b.any() else math.nan

    def exact_max_db(self, draws: int = EXACT_DRAWS, seed: int = 0) -> float:
        """Median largest |dB| difference a simulator would show whose BLA were the rig's true response [dB].

        Monte Carlo over the real estimate's own error alone: each coherent bin's estimate is the true
        response plus a complex Gaussian error of rms ``real.std`` (:class:`~maglev.spectral.FrequencyResponse`).
        Why: :attr:`max_db` is a maximum over tens of bins, each off by its own error (:attr:`real_error_db`,
        ≈ 0.8 dB), so even an exact simulator does not read 0; this is what it would read.
        """
        b = self.band
        if not b.any():
            return math.nan
        rng = np.random.default_rng(seed)
        G, sd = self.real.G[b], self.real.std[b]
        error = (rng.standard_normal((draws, G.size)) + 1j * rng.standard_normal((draws, G.size))) * sd / math.sqrt(2)
        largest = np.max(np.abs(20 * np.log10(np.abs(G + error) / np.abs(G))), axis=1)
        return float(np.median(largest))

    def text(self, within: bool) -> str:
        """The table's row; ``within``: the check's verdict (:data:`maglev.sim.checks.CHECKS`)."""
        w = self.real.w[self.band]
        span = f"{w.min():5.0f}-{w.max():4.0f}" if w.size else "    none"
        ok = "yes" if within else "no"
        return (f"{self.record:>16} {span} {w.size:5d} {self.max_db:7.1f} {self.rms_db:7.1f} "
                f"{self.real_error_db:9.1f} {self.exact_max_db():12.1f}   within {FRF_TOLERANCE_DB:g} dB: {ok}")


def _band_means(w: np.ndarray, d: np.ndarray, bands: tuple[tuple[float, float], ...]) -> list[float]:
    """Mean of ``d`` over the frequencies ``w`` within each band (rad/s, lo <= w < hi); nan for an empty band."""
    inside = [(w >= lo) & (w < hi) for lo, hi in bands]
    return [float(np.mean(d[k])) if k.any() else math.nan for k in inside]


def compare_frf(lev: Levitator, record: str, root: Path | None = None, real: IOData | None = None,
                realisations: int = FRF_REALISATIONS) -> FrfComparison:
    """The real record's FRF and the simulator's BLA for its input class (``FRF_CLASSES``), same settings."""
    real = real if real is not None else load_record(record, root)
    spec = FRF_CLASSES[record]
    sim = bla_mod.bla(spec, lev, preprocess=FRF_PREPROCESS, realisations=realisations, segment_s=FRF_SEGMENT_S)
    return FrfComparison(record=record, real=record_frf(real), sim=sim)


# ---------------------------------------------------------------------- the comparison
@dataclass(frozen=True)
class Comparison:
    """Simulated-vs-real numbers printed by ``python -m maglev.sim.calibrate``."""

    u_bar: np.ndarray
    y_real: np.ndarray
    y_sim: np.ndarray
    noise_real: tuple[float, float, float]  # std [cm], peak [cycles/sample], ADC step [cm]
    noise_sim: tuple[float, float, float]
    rise_real: float  # samples
    rise_sim: float
    alpha_real: float
    alpha_sim: float
    modes: dict[str, tuple[Mode, Mode]]  # record -> (real, sim) dominant OE(2,2,3) mode
    overshoot_real: float = math.nan  # mean normalised stair step 1.5-4 A, fraction
    overshoot_sim: float = math.nan
    stds: dict[str, tuple[float, float]] | None = None  # record -> (real, sim) output std [cm]
    # record -> (real, sim) output_std_parts and output_level of the std records
    std_parts: dict[str, tuple[tuple[float, ...], tuple[float, ...]]] | None = None
    levels: dict[str, tuple[float, float]] | None = None
    hops: dict[str, tuple[tuple[float, float], tuple[float, float]]] | None = None  # record -> (real, sim) hops()
    # record of STARTUP_RECORDS -> (command [A], (real, sim) (peak, final) [cm]) of its start from rest
    startups: dict[str, tuple[float, tuple[tuple[float, float], tuple[float, float]]]] | None = None
    fourth_order: dict[str, tuple[list[Mode], list[Mode]]] | None = None  # record -> (real, sim) OE(4,4,5) modes
    armax: tuple[list[Mode], list[Mode]] | None = None  # (real, sim) ARMAX [4 4 4 1] modes of ARMAX_RECORD
    armax_noise_free: list[Mode] | None = None  # the same on the simulated record without sensor and process noise
    frf: dict[str, FrfComparison] | None = None  # record -> real FRF vs simulated BLA
    halves: dict[str, tuple[list[float], list[float]]] | None = None  # frf record -> (real, sim replay) halves_db
    # record -> (real, sim) (coherent, incoherent) output rms [cm] per band of SPLIT_BANDS
    split: dict[str, tuple[list[tuple[float, float]], list[tuple[float, float]]]] | None = None
    gains: dict[str, tuple[float, float, float]] | None = None  # record -> (input range [A], real, sim) coherent_gain
    steps: tuple[list[StairStep], list[StairStep]] | None = None  # (real, sim) stair_steps of the staircase

    @property
    def std_ratio(self) -> tuple[float, float]:
        """(real, sim) output-std ratio binary α .25 / white noise, both 1.5-4 A."""
        (b_r, b_s), (w_r, w_s) = self.stds["binary_signal_2"], self.stds[WHITE_RECORD]
        return b_r / w_r, b_s / w_s

    @property
    def static_rms(self) -> float:
        return float(np.sqrt(np.mean((self.y_sim - self.y_real) ** 2)))

    @property
    def static_tolerance(self) -> float:
        return STATIC_NOISE_MULTIPLE * self.noise_real[0]

    def verdicts(self) -> dict[str, bool]:
        """Every check of :data:`maglev.sim.checks.CHECKS` this comparison holds the record of -> whether it is
        within its tolerance.  The table's last line counts them, so a refit's verdict is one line."""
        return checks.verdicts(self)

    @property
    def armax_pairs(self) -> tuple[tuple[Mode | None, Mode | None], tuple[Mode | None, Mode | None]] | None:
        """(real, sim) ARMAX modes picked per band (:func:`two_modes`: slow, fast), or None without ARMAX."""
        return tuple(two_modes(m) for m in self.armax) if self.armax else None

    def _mode_rows(self) -> list[tuple[str, tuple[Mode, Mode]]]:
        """The identified modes' rows of the table: each record's dominant mode, then white_noise_4's second."""
        rows = list(self.modes.items())
        if self.white_noise_mode is not None:
            rows.append((f"{WHITE_RECORD}*", self.white_noise_mode))
        return rows

    @property
    def white_noise_mode(self) -> tuple[Mode, Mode] | None:
        """(real, sim) least-damped OE(4,4,5) mode of ``white_noise_4`` (the ≈ 215 rad/s one), None without it."""
        if not self.fourth_order or WHITE_RECORD not in self.fourth_order:
            return None
        real, sim = self.fourth_order[WHITE_RECORD]
        return least_damped(real), least_damped(sim)

    def _startup_lines(self) -> list[str]:
        lines = []
        for u, ((peak_r, final_r), (peak_s, final_s)) in (self.startups or {}).values():
            lines += [f"  {f'start-up 0->{u:g} A peak [cm]':<27} {peak_r:9.2f} {peak_s:9.2f}",
                      f"  {f'start-up 0->{u:g} A final [cm]':<27} {final_r:9.2f} {final_s:9.2f}"]
        return lines

    def _steps_lines(self) -> list[str]:
        if not self.steps:
            return []
        lo, hi = GAIN_BAND
        lines = ["", f"Stair steps one by one: overshoot, and |G| rms over {lo:.0f}-{hi:.0f} rad/s from the step's "
                 "response [cm/A]",
                 f"{'step [A]':>16} {'overshoot real':>15} {'sim':>6} {'gain real':>10} {'sim':>7}"]
        sims = {(step.u0, step.u1): step for step in self.steps[1]}
        for real in self.steps[0]:
            sim = sims.get((real.u0, real.u1))
            sim_text = f"{sim.overshoot:6.0%} " if sim else f"{'.':>6} "
            lines.append(f"{f'{real.u0:.2f}->{real.u1:.2f}':>16} {real.overshoot:15.0%} {sim_text}"
                         f"{real.band_gain:10.3f} " + (f"{sim.band_gain:7.3f}" if sim else f"{'.':>7}"))
        return lines

    def table(self) -> str:
        verdicts = self.verdicts()
        lines = ["Static curve (mean of last 50 % of each 500-sample level) [cm]",
                 f"{'u [A]':>7} {'real':>8} {'sim':>8} {'diff':>8}"]
        for u, yr, ys in zip(self.u_bar, self.y_real, self.y_sim):
            lines.append(f"{u:7.2f} {yr:8.3f} {ys:8.3f} {ys - yr:+8.4f}")
        lines.append(f"rms {self.static_rms:.4f} cm (tolerance {STATIC_NOISE_MULTIPLE:g} x noise std "
                     f"= {self.static_tolerance:.4f} cm)")
        lines += ["", "Sensor noise at constant 3 A      real       sim",
                  f"  std [cm]                    {self.noise_real[0]:9.5f} {self.noise_sim[0]:9.5f}",
                  f"  spectral peak [cyc/sample]  {self.noise_real[1]:9.4f} {self.noise_sim[1]:9.4f}",
                  f"  ADC step [cm]               {self.noise_real[2]:9.3e} {self.noise_sim[2]:9.3e}",
                  "", "Lab analysis                       real       sim",
                  f"  rise time 10-90 % [samples] {self.rise_real:9.1f} {self.rise_sim:9.1f}",
                  f"  overshoot of stair steps    {self.overshoot_real:9.0%} {self.overshoot_sim:9.0%}",
                  *self._startup_lines(),
                  f"  alpha* (white_noise_4)      {self.alpha_real:9.2f} {self.alpha_sim:9.2f}",
                  *self._steps_lines(),
                  "", f"Dominant mode of OE{OE_ORDERS} (nb, nf, nk) models, trimmed {TRANSIENT_FRACTION:.0%}, "
                  "detrended; wn in rad/s of the 1 ms label",
                  f"{'record':>16} {'wn real':>8} {'wn sim':>8} {'err':>6} {'zeta real':>9} {'zeta sim':>9} {'err':>6}"]
        for rec, ((wr, zr), (ws, zs)) in self._mode_rows():
            ok = "yes" if verdicts[f"mode {rec}"] else "no"
            lines.append(f"{rec:>16} {wr:8.1f} {ws:8.1f} {ws / wr - 1:+6.0%} {zr:9.2f} {zs:9.2f} "
                         f"{zs / zr - 1:+6.0%}  within {MODE_TOLERANCE:.0%}: {ok}")
        if self.fourth_order:
            lines += [f"  * least-damped mode of OE{FOURTH_ORDERS} on the record decimated by {FOURTH_DECIMATION}",
                      "", f"Complex modes (wn/zeta) of OE{FOURTH_ORDERS} models, decimated by {FOURTH_DECIMATION}",
                      f"{'record':>16}  {'real':<28} sim"]
            for rec, (real, sim) in self.fourth_order.items():
                lines.append(f"{rec:>16}  {_modes_text(real):<28} {_modes_text(sim)}")
        if self.stds:
            lines += ["", f"Output std after dropping the first {TRANSIENT_FRACTION:.0%} [cm] (amplitude dependence)",
                      f"{'record':>16} {'input':>18} {'real':>7} {'sim':>7} {'sim/real':>8} {'spread real':>11} "
                      f"{'sim':>5} {'level sim-real':>14}"]
            for rec, (sr, ss) in self.stds.items():
                ok = "yes" if verdicts[f"std {rec}"] else "no"
                parts = (self.std_parts or {}).get(rec)
                spread = (" ".join(f"{max(p) / min(p):5.2f}" for p in parts) if parts else f"{'':5} {'':5}")
                level = (self.levels or {}).get(rec)
                level_text = f"{level[1] - level[0]:+8.2f} cm" if level else f"{'':11}"
                lines.append(f"{rec:>16} {RECORD_INPUTS.get(rec, ''):>18} {sr:7.3f} {ss:7.3f} {ss / sr:8.2f} "
                             f"{'':>6}{spread} {level_text:>14}  "
                             f"within [{1 / STD_TOLERANCE:.2f}, {STD_TOLERANCE:.2f}]: {ok}")
            if self.std_parts:
                lines.append(f"  spread: largest / smallest std of {STD_PARTS} consecutive pieces of the kept part (the band "
                             f"spans {STD_TOLERANCE ** 2:.2f}x); level: mean reading, sim minus real")
            if "binary_signal_2" in self.stds and WHITE_RECORD in self.stds:
                real, sim = self.std_ratio
                ok = "yes" if verdicts["std ratio"] else "no"
                lines.append(f"  binary α .25 / white noise, both 1.5-4 A: real {real:.1f}x, sim {sim:.1f}x "
                             f"({sim / real - 1:+.0%}; within {RATIO_TOLERANCE:.0%}: {ok})")
            if self.hops:
                lines.append(f"  hops: share of the kept reading above {HOP_LEVEL:g} cm, real / sim, and its largest "
                             "value [cm], real / sim")
                lines += [f"{rec:>16} {RECORD_INPUTS.get(rec, ''):>18} {hr:7.2%} {hs:7.2%} {mr:7.2f} {ms:7.2f}"
                          for rec, ((hr, mr), (hs, ms)) in self.hops.items()]
        if self.split:
            lines += ["", f"Output explained by the input (coherent) and not (incoherent): rms per band [cm], "
                      f"trim {FRF_PREPROCESS.trim}, detrended, {FRF_SEGMENT_S:g} s Welch segments",
                      f"{'record':>16} {'input':>18}      "
                      + "".join(f"{f'{lo:.0f}-{hi:.0f} rad/s':>15}" for lo, hi in SPLIT_BANDS),
                      f"{'':>41}" + f"{'coh|incoh':>15}" * len(SPLIT_BANDS)]
            for rec, (real, sim) in self.split.items():
                for label, name, parts in (("real", rec, real), ("sim", "", sim)):
                    lines.append(f"{name:>16} {RECORD_INPUTS.get(rec, '') if name else '':>18} {label:>4} "
                                 + "".join(f"  {c:6.4f}|{i:6.4f}" for c, i in parts))
        if self.gains:
            lo, hi = GAIN_BAND
            lines += ["", f"Range dependence: coherent output per A of input std, {lo:.0f}-{hi:.0f} rad/s [cm/A], "
                      "by input class, smallest range first",
                      f"{'class':>16} {'ranges [A]':>18}   {'real':<32}sim"]
            for cls, recs in RANGE_CLASSES.items():
                if all(rec in self.gains for rec in recs):
                    ranges, real, sim = zip(*(self.gains[rec] for rec in recs))
                    lines.append(f"{cls:>16} {' '.join(f'{r:.2f}' for r in ranges):>18}   "
                                 f"{_gains_text(real):<32}{_gains_text(sim)}")
            lines.append("  xN: largest range over smallest; a linear plant shows x1.00 in every class")
        if self.armax:
            lines += ["", f"ARMAX {list(ARMAX_ORDERS)} on {ARMAX_RECORD} at 1 ms (mean removed, first half): "
                      f"lightly damped modes (wn/zeta) in {SLOW_BAND[0]:g}-{SLOW_BAND[1]:g} and "
                      f"{FAST_BAND[0]:g}-{FAST_BAND[1]:g} rad/s"]
            picked = [two_modes(m) for m in self.armax]
            for label, modes, pair in zip(("real", "sim"), self.armax, picked):
                lines.append(f"  {label:>4}: {_modes_text([m for m in pair if m]):<22} (all: {_modes_text(modes)})")
            lines.append("  errors: " + _armax_errors_text(*picked, verdicts))
            if self.armax_noise_free is not None:
                lines.append(f"  sim without measurement noise: {_modes_text(self.armax_noise_free)} "
                             "(what the plant shows; the noisy record's answer depends on the noise's spectrum)")
        if self.frf:
            lines += ["", f"Frequency response, real Welch estimate vs the simulator's BLA for the same input class "
                      f"(trim {FRF_PREPROCESS.trim}, detrended, {FRF_SEGMENT_S:g} s segments); "
                      f"where the real coherence >= {FRF_COHERENCE:g}",
                      f"{'record':>16} {'band rad/s':>10} {'bins':>5} {'max dB':>7} {'rms dB':>7} {'real ±dB':>9} "
                      f"{'max if exact':>12}"]
            lines += [c.text(verdicts[f"FRF {rec}"]) for rec, c in self.frf.items()]
            lines.append("  max if exact: the median max dB a BLA equal to the rig's true response would show, "
                         "from the real estimate's own error (real ±dB, 1σ per bin) alone")
            lines += ["  mean dB, sim BLA over real, by band in rad/s (coherent bins only; '.': none):",
                      f"{'':>16} " + "".join(f"{f'{lo:.0f}-{hi:.0f}':>9}" for lo, hi in FRF_BANDS)]
            lines += [f"{rec:>16} " + _db_row(c.band_means_db()) for rec, c in self.frf.items()]
            if self.halves:
                lines.append("  mean dB, a record's second half over its first, same bands (bins coherent in both "
                             "halves): the rig's record, then the simulator's replay of its input")
                for rec, (real, sim) in self.halves.items():
                    lines += [f"{rec:>16} " + _db_row(real) + "  real", f"{'':>16} " + _db_row(sim) + "  sim"]
        lines += ["", checks.verdict_line(self)]
        return "\n".join(lines)


def _db_row(values: list[float]) -> str:
    return "".join(f"{m:+9.1f}" if math.isfinite(m) else f"{'.':>9}" for m in values)


def _gains_text(gains: tuple[float, ...]) -> str:
    """A class's coherent gains, smallest range first, and the largest range's over the smallest's."""
    return " ".join(f"{g:.4f}" for g in gains) + f" x{gains[-1] / gains[0]:.2f}"


def compare(lev: Levitator, root: Path | None = None, records: tuple[str, ...] = POLE_RECORDS,
            seed: int = 1, std_records: tuple[str, ...] = STD_RECORDS,
            fourth_order_records: tuple[str, ...] = POLE_RECORDS + (WHITE_RECORD,),
            armax_check: bool = True, frf_records: tuple[str, ...] = tuple(FRF_CLASSES),
            split_records: tuple[str, ...] = SPLIT_RECORDS) -> Comparison:
    """Simulate the real records' inputs with ``lev`` and compare the lab's numbers.

    ``records``: dominant OE(2,2,3) modes; ``std_records``: output std;
    ``fourth_order_records``: OE(4,4,5) modes (empty to skip these slower fits);
    ``armax_check``: ARMAX [4 4 4 1] modes of ``ARMAX_RECORD``, simulated with and
    without the measurement noise (the noise-free fit shows what the plant itself
    offers the estimator); ``frf_records``: real
    FRF vs the simulator's BLA (cached on disk, :mod:`maglev.sim.bla`); ``split_records``:
    coherent and incoherent output per band (:func:`output_split`), and for those of
    ``RANGE_CLASSES`` the coherent output per A (:func:`coherent_gain`).
    """
    stair = load_record("working_region", root)
    sim_stair = lev.simulate(stair.u, Ts=stair.Ts, seed=seed)
    u_bar, y_real = stair_averages(stair)
    _, y_sim = stair_averages(sim_stair)
    pairs = {}  # record -> (real, simulated), each simulated once
    extra = (ARMAX_RECORD,) if armax_check else ()
    for rec in dict.fromkeys(records + std_records + fourth_order_records + split_records + extra + frf_records
                             + (WHITE_RECORD,) + STARTUP_RECORDS):
        real = load_record(rec, root)
        pairs[rec] = (real, lev.simulate(real.u, Ts=real.Ts, seed=seed))
    modes = {rec: tuple(dominant_mode_of(d) for d in pairs[rec]) for rec in records}
    stds = {rec: tuple(output_std(d) for d in pairs[rec]) for rec in std_records}
    std_parts = {rec: tuple(output_std_parts(d) for d in pairs[rec]) for rec in std_records}
    levels = {rec: tuple(output_level(d) for d in pairs[rec]) for rec in std_records}
    hop_numbers = {rec: tuple(hops(d) for d in pairs[rec]) for rec in std_records}
    fourth = {rec: tuple(fourth_order_modes_of(d) for d in pairs[rec]) for rec in fourth_order_records}
    split = {rec: tuple(output_split(d) for d in pairs[rec]) for rec in split_records}
    ranged = {rec for recs in RANGE_CLASSES.values() for rec in recs}
    gains = {rec: (float(np.ptp(pairs[rec][0].u)), *(coherent_gain(d) for d in pairs[rec]))
             for rec in split_records if rec in ranged}
    (rise_r, over_r), (rise_s, over_s) = stair_step(stair), stair_step(sim_stair)

    def alpha(d: IOData) -> float:
        return choose_alpha(output_spectrum(d.trim(TRANSIENT_FRACTION).y).band).alpha_star

    def startup(d: IOData) -> tuple[float, float]:
        return float(d.y[:STARTUP_SAMPLES].max()), output_level(d)

    (const, sim_const), (wn, sim_wn) = pairs["binary_signal_9"], pairs[WHITE_RECORD]
    return Comparison(
        u_bar=u_bar, y_real=y_real, y_sim=y_sim,
        noise_real=_noise_numbers(const),
        noise_sim=_noise_numbers(sim_const),
        startups={rec: (float(pairs[rec][0].u[0]), tuple(startup(d) for d in pairs[rec])) for rec in STARTUP_RECORDS},
        rise_real=rise_r, rise_sim=rise_s,
        alpha_real=alpha(wn), alpha_sim=alpha(sim_wn), modes=modes,
        overshoot_real=over_r, overshoot_sim=over_s, stds=stds, std_parts=std_parts or None,
        levels=levels or None, hops=hop_numbers or None, fourth_order=fourth or None,
        armax=tuple(armax_modes_of(d) for d in pairs[ARMAX_RECORD]) if armax_check else None,
        armax_noise_free=armax_modes_of(lev.simulate(pairs[ARMAX_RECORD][0].u, Ts=pairs[ARMAX_RECORD][0].Ts,
                                                     seed=seed, noise=False)) if armax_check else None,
        frf={rec: compare_frf(lev, rec, root, pairs[rec][0]) for rec in frf_records} or None,
        halves={rec: tuple(halves_db(d) for d in pairs[rec]) for rec in frf_records} or None,
        split=split or None, gains=gains or None,
        steps=(stair_steps(stair, band=GAIN_BAND), stair_steps(sim_stair, band=GAIN_BAND)),
    )


def armax_errors(sim: tuple[Mode | None, Mode | None], real: tuple[Mode | None, Mode | None]) -> dict[str, float]:
    """Relative errors of ωn and ζ of the two ARMAX modes (NaN where either side lacks the mode)."""
    out = {}
    for name, s, r in zip(("slow", "fast"), sim, real):
        out[f"{name} wn"] = s[0] / r[0] - 1 if s and r else math.nan
        out[f"{name} zeta"] = s[1] / r[1] - 1 if s and r else math.nan
    return out


def _armax_errors_text(real: tuple[Mode | None, Mode | None], sim: tuple[Mode | None, Mode | None],
                       verdicts: dict[str, bool]) -> str:
    errs = armax_errors(sim, real)
    parts = []
    for name in ("slow", "fast"):
        wn, z = errs[f"{name} wn"], errs[f"{name} zeta"]
        if math.isnan(wn):
            parts.append(f"{name} mode missing")
        else:
            parts.append(f"{name} wn {wn:+.0%} zeta {z:+.0%} ({'yes' if verdicts[f'ARMAX {name} mode'] else 'no'})")
    return "; ".join(parts) + f" [tolerances {ARMAX_WN_TOLERANCE:.0%} / {ARMAX_ZETA_TOLERANCE:.0%}]"
