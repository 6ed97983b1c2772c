"""Every simulated-vs-real check, declared once: what is measured, on which record, its tolerance, and why.

Why one list: the printed comparison's verdicts (``maglev calibrate``), its verdict count, the
calibration's cost (:func:`maglev.sim.calibrate.friction_errors`), the generated validation page
(``maglev calibrate --markdown``) and the acceptance test all read :data:`CHECKS`, so a check cannot
mean one thing in the table and another in the fit.

A check reads its numbers from a *measured* object: the printed comparison
(:class:`maglev.sim.sim_vs_real.Comparison`) or the calibration's cheaper replay of the same records.
Both carry the attributes of :class:`Measured`. Each check returns its error in units of its
tolerance, one per component (ωn and ζ of a mode, say): 1.0 is at the tolerance, nan means the
simulated record does not show what is measured. A check is within when every component is at most 1.
A check whose record the measured object does not hold is left out ("as far as it holds them").

Frequencies are in rad/s of the 1 ms label the records carry.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import Any, Protocol

from maglev.lab.measures import Mode

__all__ = ["Check", "CHECKS", "Measured", "errors", "verdicts", "verdict_line", "STATIC_NOISE_MULTIPLE",
           "RISE_TOLERANCE", "MODE_TOLERANCE", "STD_TOLERANCE", "RATIO_TOLERANCE", "ARMAX_WN_TOLERANCE",
           "ARMAX_ZETA_TOLERANCE", "FRF_TOLERANCE_DB", "POLE_RECORDS", "STD_RECORDS", "FRF_RECORDS",
           "WHITE_RECORD", "ARMAX_RECORD", "STAIR_RECORD", "RATIO_RECORDS"]

# tolerances
STATIC_NOISE_MULTIPLE = 5.0  # static curve: rms over the staircase's levels <= this many sensor-noise stds
RISE_TOLERANCE = 0.25  # relative error of the stair steps' rise time (the same decimation advice)
MODE_TOLERANCE = 0.2  # relative error of an identified mode's ωn and ζ
STD_TOLERANCE = 1.25  # output std within [1/1.25, 1.25] of the real one
RATIO_TOLERANCE = 0.25  # relative error of the binary α .25 / white-noise output-std ratio
ARMAX_WN_TOLERANCE, ARMAX_ZETA_TOLERANCE = 0.15, 0.30  # relative errors of ARMAX's two modes
FRF_TOLERANCE_DB = 3.0  # largest |dB| gap of the frequency response where the real estimate is coherent

# the records the checks are made on (KTH EL2820 2022, maglev.refdata)
STAIR_RECORD = "working_region"  # the 21-level staircase
WHITE_RECORD = "white_noise_4"  # white noise over the working region 1.5-4 A
ARMAX_RECORD = "binary_signal_2"  # binary α .25 over 1.5-4 A: the 2022 group's ARMAX record
POLE_RECORDS = ("binary_signal_3", "binary_signal_4", "binary_signal_2", "binary_signal_1")
STD_RECORDS = ("binary_signal_1", "binary_signal_2", "binary_signal_3", "binary_signal_4", "white_noise_1",
               "white_noise_2", "white_noise_4")
RATIO_RECORDS = (ARMAX_RECORD, WHITE_RECORD)  # binary α .25 and white noise, both over 1.5-4 A
FRF_RECORDS = ("binary_signal_2", "binary_signal_3", "white_noise_4")  # one per input class


class Measured(Protocol):
    """What a check reads: real and simulated numbers of the same records (each dict: record -> (real, sim))."""

    static_rms: float  # cm, rms of the simulated staircase's stationary averages minus the real ones
    static_tolerance: float  # cm, STATIC_NOISE_MULTIPLE x the sensor noise std at constant current
    rise_real: float  # samples, 10-90 % rise time of the mean stair step
    rise_sim: float
    alpha_real: float  # α* from white noise's output spectrum
    alpha_sim: float
    modes: Mapping[str, tuple[Mode, Mode]]  # dominant OE(2,2,3) mode per binary record
    white_noise_mode: tuple[Mode, Mode] | None  # least-damped OE(4,4,5) mode of WHITE_RECORD
    stds: Mapping[str, tuple[float, float]] | None  # output std per record [cm]
    armax_pairs: tuple[tuple[Mode | None, Mode | None], tuple[Mode | None, Mode | None]] | None  # (slow, fast)
    frf: Mapping[str, Any] | None  # record -> FrfComparison (its max_db)


@dataclass(frozen=True)
class Check:
    """One sim-vs-real check: its ``name`` (the key of verdicts), ``what`` is measured, on which ``record``,
    its ``tolerance`` (in words), ``why`` the lab or the study needs it, ``measure``: the measured object ->
    {component: error / tolerance}, or None when the object does not hold the record; ``shown``: the measured
    object -> (the rig's number, the simulator's) as text, for the validation page; and whether the
    calibration's cost scores it (``scored``)."""

    name: str
    what: str
    record: str
    tolerance: str
    why: str
    measure: Callable[[Any], dict[str, float] | None]
    shown: Callable[[Any], tuple[str, str]]
    scored: bool = True


def _relative(sim: float, real: float) -> float:
    return abs(sim / real - 1)


def _mode_errors(pair: tuple[Mode, Mode] | None, tolerance: float) -> dict[str, float] | None:
    if pair is None:
        return None
    (wr, zr), (ws, zs) = pair
    return {"wn": _relative(ws, wr) / tolerance, "zeta": _relative(zs, zr) / tolerance}


def _armax_errors(m: Any, which: int) -> dict[str, float] | None:
    if m.armax_pairs is None:
        return None
    real, sim = (pair[which] for pair in m.armax_pairs)
    if real is None or sim is None:
        return {"wn": math.nan, "zeta": math.nan}
    return {"wn": _relative(sim[0], real[0]) / ARMAX_WN_TOLERANCE,
            "zeta": _relative(sim[1], real[1]) / ARMAX_ZETA_TOLERANCE}


def _std_error(m: Any, record: str) -> dict[str, float] | None:
    if not m.stds or record not in m.stds:
        return None
    real, sim = m.stds[record]
    return {"": abs(math.log(max(sim, 1e-6) / real)) / math.log(STD_TOLERANCE)}


def _ratio_error(m: Any) -> dict[str, float] | None:
    if not m.stds or not all(r in m.stds for r in RATIO_RECORDS):
        return None
    (b_r, b_s), (w_r, w_s) = (m.stds[r] for r in RATIO_RECORDS)
    return {"": _relative(b_s / max(w_s, 1e-9), b_r / w_r) / RATIO_TOLERANCE}


def _ratio_text(m: Any) -> tuple[str, str]:
    if not m.stds or not all(r in m.stds for r in RATIO_RECORDS):
        return "", ""
    (b_r, b_s), (w_r, w_s) = (m.stds[r] for r in RATIO_RECORDS)
    return f"{b_r / w_r:.1f}x", f"{b_s / w_s:.1f}x"


def _frf_text(m: Any, record: str) -> tuple[str, str]:
    if not m.frf or record not in m.frf:
        return "", ""
    c = m.frf[record]
    return f"{int(c.band.sum())} coherent bins", f"largest gap {c.max_db:.1f} dB"


def _frf_error(m: Any, record: str) -> dict[str, float] | None:
    if not m.frf or record not in m.frf:
        return None
    return {"": m.frf[record].max_db / FRF_TOLERANCE_DB}  # nan: no coherent bin


def _mode_text(mode: Mode | None) -> str:
    return "none" if mode is None or not all(map(math.isfinite, mode)) else f"{mode[0]:.0f} rad/s, ζ {mode[1]:.2f}"


def _pair_text(pair: tuple[Any, Any] | None, text: Callable[[Any], str]) -> tuple[str, str]:
    return ("", "") if pair is None else (text(pair[0]), text(pair[1]))


def _declare() -> tuple[Check, ...]:
    checks = [
        Check("static curve", "rms of the staircase's stationary averages, simulated minus real", STAIR_RECORD,
              f"<= {STATIC_NOISE_MULTIPLE:g} x the sensor noise std",
              "the lab's working region and working point are read from the static curve",
              lambda m: {"": m.static_rms / m.static_tolerance},
              lambda m: (f"noise std {m.static_tolerance / STATIC_NOISE_MULTIPLE:.5f} cm", f"rms {m.static_rms:.4f} cm"),
              scored=False),
        Check("rise time", "10-90 % rise time of the mean 0.5 A stair step from 1.5 to 4 A", STAIR_RECORD,
              f"within {RISE_TOLERANCE:.0%}", "the lab chooses the sampling period (decimation) from it",
              lambda m: {"": _relative(m.rise_sim, m.rise_real) / RISE_TOLERANCE},
              lambda m: (f"{m.rise_real:.1f} samples", f"{m.rise_sim:.1f} samples")),
        Check("alpha*", "α* from the output spectrum's band (the lab's random-binary design)", WHITE_RECORD,
              "equal", "the lab designs its binary input's switching probability from it",
              lambda m: {"": 0.0 if m.alpha_sim == m.alpha_real else math.inf},
              lambda m: (f"{m.alpha_real:.2f}", f"{m.alpha_sim:.2f}"), scored=False),
    ]
    checks += [Check(f"mode {rec}", "ωn and ζ of the dominant mode of OE(2,2,3), trimmed 25 %, detrended", rec,
                     f"within {MODE_TOLERANCE:.0%} each",
                     "identified models of binary records show the rig's lightly damped ≈ 90 rad/s mode",
                     lambda m, rec=rec: _mode_errors(m.modes.get(rec), MODE_TOLERANCE),
                     lambda m, rec=rec: _pair_text(m.modes.get(rec), _mode_text)) for rec in POLE_RECORDS]
    checks += [
        Check(f"mode {WHITE_RECORD}*", "ωn and ζ of the least-damped mode of OE(4,4,5) after decimation by 2",
              WHITE_RECORD, f"within {MODE_TOLERANCE:.0%} each",
              "white noise shows the rig's second (≈ 215 rad/s) mode",
              lambda m: _mode_errors(m.white_noise_mode, MODE_TOLERANCE),
              lambda m: _pair_text(m.white_noise_mode, _mode_text)),
    ]
    checks += [Check(f"std {rec}", "output std after dropping the first 25 %", rec,
                     f"within [{1 / STD_TOLERANCE:.2f}, {STD_TOLERANCE:.2f}] x the real one",
                     "the rig's response depends on the input's amplitude and class",
                     lambda m, rec=rec: _std_error(m, rec),
                     lambda m, rec=rec: _pair_text((m.stds or {}).get(rec), lambda v: f"{v:.3f} cm"))
               for rec in STD_RECORDS]
    checks += [
        Check("std ratio", "output std of binary α .25 over white noise, both 1.5-4 A", " / ".join(RATIO_RECORDS),
              f"within {RATIO_TOLERANCE:.0%}", "how much more a binary input moves the magnet than white noise",
              _ratio_error, _ratio_text),
        Check("ARMAX slow mode", "ωn and ζ of ARMAX [4 4 4 1]'s lightly damped mode in 40-150 rad/s, first "
              "half, mean removed", ARMAX_RECORD,
              f"ωn within {ARMAX_WN_TOLERANCE:.0%}, ζ within {ARMAX_ZETA_TOLERANCE:.0%}",
              "the model the 2022 lab group identified shows both of the rig's modes",
              lambda m: _armax_errors(m, 0),
              lambda m: _pair_text(m.armax_pairs and tuple(p[0] for p in m.armax_pairs), _mode_text)),
        Check("ARMAX fast mode", "the same in 150-400 rad/s", ARMAX_RECORD,
              f"ωn within {ARMAX_WN_TOLERANCE:.0%}, ζ within {ARMAX_ZETA_TOLERANCE:.0%}",
              "the model the 2022 lab group identified shows both of the rig's modes",
              lambda m: _armax_errors(m, 1),
              lambda m: _pair_text(m.armax_pairs and tuple(p[1] for p in m.armax_pairs), _mode_text)),
    ]
    checks += [Check(f"FRF {rec}", "largest absolute dB gap between the real Welch estimate and the simulator's BLA for "
                     "the record's input class, where the real coherence >= 0.5", rec,
                     f"<= {FRF_TOLERANCE_DB:g} dB",
                     "the study scores identified models against the BLA: it must be the rig's response",
                     lambda m, rec=rec: _frf_error(m, rec), lambda m, rec=rec: _frf_text(m, rec))
               for rec in FRF_RECORDS]
    return tuple(checks)


CHECKS: tuple[Check, ...] = _declare()


def errors(measured: Any, *, scored_only: bool = False) -> dict[str, dict[str, float]]:
    """Check name -> {component: error / tolerance} for every check ``measured`` holds the record of
    (only those the calibration scores with ``scored_only``)."""
    out = {}
    for check in CHECKS:
        if scored_only and not check.scored:
            continue
        value = check.measure(measured)
        if value is not None:
            out[check.name] = value
    return out


def verdicts(measured: Any) -> dict[str, bool]:
    """Check name -> whether every component is within its tolerance (nan: the simulation lacks it, no)."""
    return {name: all(e <= 1.0 for e in parts.values()) for name, parts in errors(measured).items()}


def verdict_line(measured: Any) -> str:
    """One line: how many checks are within their tolerances, and which are not."""
    v = verdicts(measured)
    missed = [name for name, ok in v.items() if not ok]
    return (f"Checks within their tolerances: {len(v) - len(missed)} of {len(v)}"
            + (f"; not within: {', '.join(missed)}" if missed else ""))
