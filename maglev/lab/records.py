"""Which records to identify from, and how much of each (EL2820 Lab 3 §3.3–3.4), as rules on the records.

The lab gives a set of recorded experiments and asks for 2 uniform-noise and 1 random-binary
record, with the input's offset at the working point u*, its range as large as possible
inside the working region, and at least 10 s of estimation and 7 s of validation data.
Every number these rules use is measured on the record, on its recorded sample axis:

* :func:`start_transient` — the start-up transient (lift-off, or the magnet settling to another
  level) from the record's output, instead of a fixed trim;
* :func:`length_split` — the estimation/validation split that meets 10 s / 7 s when the record
  allows;
* :func:`switching_rate` — α of a binary record, the share of recorded samples where it switches;
* :func:`assess` and :func:`choose_records` — each record's offset, range, share of input outside
  the working region, share of output outside the static curve, usable length, and the choice: a
  record whose input or output leaves its range in more than 2 % of the samples is refused, however
  much of the region it covers.

Plain numpy; the decisions come back as :class:`~maglev.lab.decision.Decision`.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from maglev.lab.decision import Decision

__all__ = ["Transient", "start_transient", "length_split", "switching_rate", "RecordAssessment", "assess",
           "share_outside", "choose_records", "verdicts", "length_decision", "alpha_decision", "EST_MIN_S", "VAL_MIN_S", "INPUT_OUTSIDE_MAX",
           "OUTPUT_OUTSIDE_MAX"]

EST_MIN_S = 10.0  # lab §3.4: at least 10 s of estimation data
VAL_MIN_S = 7.0  # ... and 7 s of validation data
OUTPUT_OUTSIDE_MAX = 0.02  # a record whose output leaves the static curve's range more often is refused
# ... and one whose input leaves the working region more often (lab §3.1: the input "never exceeds the
# values on the boundary of the working region"; §3.3.2: the amplitude keeps it inside): a linear model
# is only valid there, however wide the record
INPUT_OUTSIDE_MAX = 0.02
CURVE_TOLERANCE = 0.05  # share of the static curve's ȳ range allowed beyond its ends (sensor noise)


# ------------------------------------------------------------------------------------------- the transient
@dataclass(frozen=True)
class Transient:
    """The start-up transient of a record: ``samples`` to drop, with the numbers that decided it."""

    samples: int
    seconds: float
    level: float  # median of the block means over the record's second half
    spread: float  # robust standard deviation of those block means
    block_s: float
    k: float
    outside: tuple[int, ...]  # the leading blocks whose mean lies beyond level ± k·spread


def start_transient(y: Sequence[float] | np.ndarray, Ts: float, block_s: float = 0.25, k: float = 4.0,
                    max_s: float = 5.0) -> Transient:
    """The start-up transient: the leading run of ``block_s`` blocks whose mean output lies more than ``k``
    robust standard deviations from the settled level (median and 1.4826·MAD of the block means over the
    record's second half), a run that ends at two blocks in a row inside the band; at most ``max_s``.

    A lift-off spike makes the first block's mean leave the band; a record that starts at one level and
    settles to another (the magnet moving to another rest) keeps leaving it until it has settled; a block
    that strays later in the record is not a start transient and is not trimmed.
    """
    y = np.asarray(y, dtype=float).reshape(-1)
    b = max(1, int(round(block_s / Ts)))
    nb = y.size // b
    if nb < 4:
        raise ValueError(f"the record has {y.size} samples: at least 4 blocks of {b} samples are needed "
                         "to detect its start transient")
    means = y[:nb * b].reshape(nb, b).mean(axis=1)
    settled = means[nb // 2:]
    level = float(np.median(settled))
    spread = float(1.4826 * np.median(np.abs(settled - level)))
    out = np.abs(means - level) > k * spread if spread > 0 else np.abs(means - level) > 0
    last, inside_run, leading = -1, 0, []
    for i in range(min(nb // 2, int(round(max_s / block_s)))):
        if out[i]:
            last, inside_run = i, 0
            leading.append(i)
        else:
            inside_run += 1
            if inside_run >= 2:
                break
    samples = (last + 1) * b
    return Transient(samples, samples * Ts, level, spread, block_s, k, tuple(leading))


def length_split(n_samples: int, Ts: float, est_min_s: float = EST_MIN_S,
                 val_min_s: float = VAL_MIN_S) -> tuple[float, bool]:
    """(estimation fraction, both minima met) for a record of ``n_samples`` left after the trim.

    An even split when both halves reach their minimum; else ``est_min_s`` of estimation data when
    the rest still holds ``val_min_s`` (an unequal split); else the two shares in the ratio of the
    minima (10 : 7), and ``False``: the record is too short for the lab's minimum.
    """
    total = n_samples * Ts
    if total / 2 >= max(est_min_s, val_min_s):
        return 0.5, True
    if total - est_min_s >= val_min_s:
        return est_min_s / total, True
    return est_min_s / (est_min_s + val_min_s), False


def switching_rate(u: Sequence[float] | np.ndarray) -> float:
    """α of a random binary record: the share of recorded samples where the input changes level
    (the lab's w_t = −1 with probability α, per sample); nan for a record with fewer than 2 samples."""
    u = np.asarray(u, dtype=float).reshape(-1)
    if u.size < 2:
        return float("nan")
    return float(np.mean(np.diff(u) != 0))


# ------------------------------------------------------------------------------------------- the records
@dataclass(frozen=True)
class RecordAssessment:
    """What the choice rule measures on one record (inputs in A, outputs in the record's unit, times in s)."""

    name: str
    input_class: str
    u_low: float
    u_high: float
    u_mean: float
    alpha: float | None  # switching rate on the recorded axis (binary records)
    trim_s: float
    usable_s: float
    coverage: float  # share of the working region's width the input's range covers
    offset: float  # |mean input − u*| / width of the working region
    input_outside: float  # share of input samples outside the working region
    output_outside: float  # share of output samples outside the static curve's range (± CURVE_TOLERANCE)
    shortfall: float  # share of the lab's 17 s the record lacks after its trim
    excited: bool

    @property
    def score(self) -> float:
        return self.coverage - self.offset - self.input_outside - self.shortfall

    @property
    def refusals(self) -> list[str]:
        out = []
        if not self.excited:
            out.append("the input is constant: no excitation")
        if self.input_outside > INPUT_OUTSIDE_MAX:
            out.append(f"{100 * self.input_outside:.1f} % of its input outside the working region "
                       f"(more than {100 * INPUT_OUTSIDE_MAX:g} %)")
        if self.output_outside > OUTPUT_OUTSIDE_MAX:
            out.append(f"{100 * self.output_outside:.1f} % of its output outside the static curve's range "
                       f"(more than {100 * OUTPUT_OUTSIDE_MAX:g} %)")
        return out

    def row(self) -> dict:
        return {"record": self.name, "class": self.input_class, "u range (A)": f"{self.u_low:.3g}–{self.u_high:.3g}",
                "mean u (A)": self.u_mean, "α": self.alpha, "trim (s)": self.trim_s, "usable (s)": self.usable_s,
                "covers region": self.coverage, "offset / width": self.offset, "u outside region": self.input_outside,
                "y outside curve": self.output_outside, "length shortfall": self.shortfall, "score": self.score}


def share_outside(u: np.ndarray, region: tuple[float, float]) -> float:
    """The share of input samples ``u`` outside the working ``region`` (u_min, u_max), to rounding."""
    lo, hi = region
    eps = 1e-9 * max(1.0, abs(hi))
    return float(np.mean((u < lo - eps) | (u > hi + eps)))


def assess(name: str, input_class: str, u: np.ndarray, y: np.ndarray, Ts: float, region: tuple[float, float],
           curve: tuple[float, float]) -> RecordAssessment:
    """Measure one record against the working ``region`` (u_min, u_max) and the static ``curve``'s ȳ range
    (its lowest and highest stationary average), after its start transient."""
    u = np.asarray(u, dtype=float).reshape(-1)
    y = np.asarray(y, dtype=float).reshape(-1)
    tr = start_transient(y, Ts)
    u, y = u[tr.samples:], y[tr.samples:]
    lo, hi = region
    width = hi - lo
    u_low, u_high = float(u.min()), float(u.max())
    coverage = max(0.0, min(u_high, hi) - max(u_low, lo)) / width
    input_outside = share_outside(u, region)
    c_lo, c_hi = curve
    tol = CURVE_TOLERANCE * (c_hi - c_lo)
    output_outside = float(np.mean((y < c_lo - tol) | (y > c_hi + tol)))
    usable = u.size * Ts
    need = EST_MIN_S + VAL_MIN_S
    return RecordAssessment(
        name=name, input_class=input_class, u_low=u_low, u_high=u_high, u_mean=float(u.mean()),
        alpha=switching_rate(u) if input_class == "binary" else None, trim_s=tr.seconds, usable_s=usable,
        coverage=coverage, offset=abs(float(u.mean()) - 0.5 * (lo + hi)) / width, input_outside=input_outside,
        output_outside=output_outside, shortfall=max(0.0, need - usable) / need, excited=bool(np.ptp(u) > 0))


RECORDS_RULE = (
    "Refuse a record whose input is constant, whose input lies outside the working region in more than "
    f"{100 * INPUT_OUTSIDE_MAX:g} % of its samples (lab §3.1, §3.3.2: a linear model is valid inside it only), "
    "or whose output lies outside the static curve's range "
    f"(its lowest to highest stationary average, ± {100 * CURVE_TOLERANCE:g} % of that range) in more than "
    f"{100 * OUTPUT_OUTSIDE_MAX:g} % of its samples, after the start transient. Rank the others by "
    "score = coverage of the working region by the input's range − |mean input − u*| / region width − share of "
    f"input samples outside the region − share of the lab's {EST_MIN_S + VAL_MIN_S:g} s the record lacks; for the "
    "binary class, first keep the records whose α is nearest α*. Take the best 2 uniform and 1 binary record.")


def choose_records(assessed: Sequence[RecordAssessment], alpha_star: float | None = None,
                   wanted: dict[str, int] | None = None, forced: Sequence[str] | None = None) -> Decision:
    """The records decision: per class, the ``wanted`` count (default 2 uniform, 1 binary) of best-scoring
    records that pass the refusals; binary records nearest ``alpha_star`` first.  Each record's verdict (chosen,
    refused and why, or what it loses on) is its evidence row's ``verdict``, so the report prints one table row per
    record; the reasons count them.  ``forced`` (the names the config forces) replaces the choice, and the evidence
    still shows where the forced records rank."""
    wanted = wanted or {"uniform": 2, "binary": 1}
    choice: dict[str, list[str]] = {}
    verdicts: dict[str, str] = {}
    cautions: list[str] = []
    for cls, n in wanted.items():
        members = [a for a in assessed if a.input_class == cls]
        ok = [a for a in members if not a.refusals]
        for a in members:
            if a.refusals:
                verdicts[a.name] = "refused: " + "; ".join(a.refusals)
        pool = ok
        if cls == "binary" and alpha_star is not None and ok:
            nearest = min(abs((a.alpha or 0.0) - alpha_star) for a in ok)
            pool = [a for a in ok if abs((a.alpha or 0.0) - alpha_star) <= nearest + 0.02]
            for a in ok:
                if a not in pool:
                    verdicts[a.name] = (f"not chosen: its α is {abs(a.alpha - alpha_star):.3f} from α* = "
                                        f"{alpha_star:g}, the nearest passing record's {nearest:.3f}")
        ranked = sorted(pool, key=lambda a: -a.score)
        chosen = ranked[:n]
        choice[cls] = [a.name for a in chosen]
        for i, a in enumerate(chosen):
            verdicts[a.name] = f"chosen ({cls} #{i + 1})"
        for a in ranked[n:]:
            verdicts[a.name] = f"not chosen: score below {chosen[-1].name}'s {chosen[-1].score:.3f}"
        if len(chosen) < n:
            cautions.append(f"only {len(chosen)} {cls} record(s) pass the rule, {n} wanted.")
        kept = (f" It is chosen all the same: only {len(ranked)} {cls} record(s) pass the rule, {n} wanted." if
                len(ranked) <= n else f" It is chosen all the same: its score, the shortfall counted, is above "
                f"{ranked[n].name}'s {ranked[n].score:.3f}.")
        cautions += [f"{a.name}: {a.usable_s:.2f} s after its {a.trim_s:.2f} s start transient, less than the lab's "
                     f"{EST_MIN_S:g} s + {VAL_MIN_S:g} s.{kept}" for a in chosen if a.shortfall > 0]
    evidence = [{**a.row(), "verdict": verdicts.get(a.name, f"no {a.input_class} record wanted")}
                for a in sorted(assessed, key=lambda a: (a.input_class, -a.score))]
    count = {k: sum(v.startswith(k) for v in verdicts.values()) for k in ("chosen", "refused", "not chosen")}
    reasons = [f"Of {len(assessed)} records, {count['chosen']} chosen, {count['refused']} refused and "
               f"{count['not chosen']} not chosen for a lower score or an α farther from α*: each record's verdict is "
               "its row of the table."]
    if forced is not None:
        forced_set = {str(n) for n in forced}
        rule_set = {n for names in choice.values() for n in names}
        if forced_set != rule_set:
            by_name = {a.name: a for a in assessed}
            for name in sorted(forced_set - rule_set):
                a = by_name.get(name)
                if a is not None and a.refusals:
                    cautions.append(f"{name} is forced by the config although the rule refuses it: "
                                    + "; ".join(a.refusals) + ".")
            for row in evidence:
                if row["record"] in forced_set - rule_set:
                    row["verdict"] += "; used: forced by the config"
            reasons.insert(0, f"The config forces {sorted(forced_set)}; the rule would choose {sorted(rule_set)}.")
            return Decision("records", RECORDS_RULE, {"forced": sorted(forced_set), "rule": choice}, evidence,
                            reasons, forced=True, cautions=cautions)
    return Decision("records", RECORDS_RULE, choice, evidence, reasons, cautions=cautions)


def verdicts(decision: Decision) -> dict[str, str]:
    """Each record's verdict in a records decision (its evidence rows' ``verdict``), by record name."""
    return {str(r["record"]): str(r["verdict"]) for r in decision.evidence if "verdict" in r}


# ------------------------------------------------------------------------------------- length and α
LENGTH_RULE = (
    "Trim the start transient detected on the record (start_transient: the leading 0.25 s blocks whose mean "
    "output lies more than 4 robust standard deviations from the settled level, at most 5 s); split the rest "
    f"evenly when both halves hold {EST_MIN_S:g} s, else {EST_MIN_S:g} s of estimation data when the rest holds "
    f"{VAL_MIN_S:g} s of validation data, else in the ratio {EST_MIN_S:g} : {VAL_MIN_S:g} with a caution.")


def length_decision(rows: Sequence[dict]) -> Decision:
    """The data-length decision from one row per dataset: ``dataset``, ``transient_s`` (detected), ``trim_s``
    and ``split`` (used), ``est_s``, ``val_s``.  A caution names every dataset below the lab's minimum and
    every trim shorter than the detected transient; a trim other than the detected transient was set by the
    config (``forced``), and a reason says why it is kept (longer than the transient: it drops the transient all
    the same) or what it leaves in (shorter)."""
    choice, reasons, cautions = {}, [], []
    set_by_config = [r["dataset"] for r in rows if abs(r["trim_s"] - r["transient_s"]) > 1e-9]
    longer = [r["dataset"] for r in rows if r["trim_s"] - r["transient_s"] > 1e-9]
    shorter = [n for n in set_by_config if n not in longer]
    if longer:
        reasons.append(f"The trim of {', '.join(longer)} is set by the config (dataset.preprocess.trim), not the "
                       "detected start transient beside it, and kept: it is longer than the transient, so the "
                       "transient is dropped all the same and only settled output goes too.")
    if shorter:
        reasons.append(f"The trim of {', '.join(shorter)} is set by the config (dataset.preprocess.trim), shorter "
                       "than the detected start transient beside it: part of the transient is identified (a caution "
                       "below).")
    short = []
    for r in rows:
        name = r["dataset"]
        choice[name] = {"trim_s": r["trim_s"], "est_s": r["est_s"], "val_s": r["val_s"], "split": r["split"]}
        met = r["est_s"] >= EST_MIN_S - 1e-9 and r["val_s"] >= VAL_MIN_S - 1e-9
        if not met:
            short.append(name)
            cautions.append(f"{name}: {r['est_s']:.2f} s estimation and {r['val_s']:.2f} s validation data, less than "
                            f"the lab's {EST_MIN_S:g} s and {VAL_MIN_S:g} s: the record is too short after its "
                            f"{r['trim_s']:.2f} s start transient.")
        if r["trim_s"] + 1e-9 < r["transient_s"]:
            cautions.append(f"{name}: the trim {r['trim_s']:.2f} s is shorter than the detected start transient "
                            f"{r['transient_s']:.2f} s.")
    minimum = f"the lab's {EST_MIN_S:g} s of estimation and {VAL_MIN_S:g} s of validation data after"
    reasons.append(f"{len(rows) - len(short)} of the {len(rows)} records hold {minimum} their trim; "
                   f"{', '.join(short)} {'does' if len(short) == 1 else 'do'} not (a caution below)." if short else
                   f"Every record holds {minimum} its trim.")
    evidence = [{"dataset": r["dataset"], "start transient (s)": r["transient_s"], "trim (s)": r["trim_s"],
                 "estimation share": r["split"], "estimation (s)": r["est_s"], "validation (s)": r["val_s"]}
                for r in rows]
    return Decision("data_length", LENGTH_RULE, choice, evidence, reasons, forced=bool(set_by_config),
                    cautions=cautions)


ALPHA_TOLERANCE = 0.02


def alpha_decision(rows: Sequence[dict]) -> Decision:
    """α of each binary record from its switching rate on the recorded sample axis, beside its design value
    (rows: ``dataset``, ``alpha``, ``design`` (None when unknown), ``samples``)."""
    choice, reasons, cautions = {}, [], []
    for r in rows:
        choice[r["dataset"]] = r["alpha"]
        if r.get("design") is None:
            reasons.append(f"{r['dataset']}: α = {r['alpha']:.4f} (switches in {r['alpha']:.2%} of "
                           f"{r['samples']} recorded samples).")
            continue
        off = abs(r["alpha"] - r["design"])
        (reasons if off <= ALPHA_TOLERANCE else cautions).append(
            f"{r['dataset']}: α = {r['alpha']:.4f} from its switching rate, design value {r['design']:g}: "
            + (f"within {ALPHA_TOLERANCE:g}." if off <= ALPHA_TOLERANCE else f"off by {off:.3f}, more than "
               f"{ALPHA_TOLERANCE:g}: the record is not the signal its name says."))
    rule = ("α = share of the recorded (not decimated) samples where the binary input switches level, the lab's "
            f"per-sample switching probability; compared with the design value (tolerance {ALPHA_TOLERANCE:g}).")
    evidence = [{"dataset": r["dataset"], "α (switching rate)": r["alpha"], "design α": r.get("design"),
                 "recorded samples": r["samples"]} for r in rows]
    return Decision("alpha", rule, choice, evidence, reasons, cautions=cautions)
