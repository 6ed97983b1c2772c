"""The input delay nk (EL2820 Lab 3 §3.2, §3.5): one rule weighing three pieces of evidence.

* the step's dead time — where the averaged step response of the staircase first reaches
  ``DEAD_LEVEL`` of its change; for a smooth (high-order) response this is later than the
  pure delay, so it bounds nk from above;
* ``delayest`` — MATLAB's ARX [2 2 nk] loss minimum; a second-order model of a fourth-order
  plant moves its delay toward the visible dead time, so it is an upper bound as well;
* the residual–input correlation — an ARX [n n nk] whose delay is too long leaves the input
  at the lags it skips in its residuals: their correlation with u(t−τ), τ < nk, leaves the
  99 % band.  The delay is the largest nk, up to the two bounds, below the first one a dataset rejects.

Plain numpy on :class:`~maglev.data.IOData`; the answer comes back as a
:class:`~maglev.lab.decision.Decision`.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from maglev.data import IOData
from maglev.lab.decision import Decision

__all__ = ["DEAD_LEVEL", "dead_time", "residual_rejects", "delay_decision"]

DEAD_LEVEL = 0.05  # share of the step's change at which the output has visibly moved


def dead_time(response: np.ndarray, level: float = DEAD_LEVEL) -> int:
    """Samples before the normalised step ``response`` (0 before, 1 after) first reaches ``level``."""
    idx = np.flatnonzero(np.asarray(response, dtype=float) >= level)
    if idx.size == 0:
        raise ValueError(f"the step response never reaches {level:.0%} of its change")
    return int(idx[0])


def residual_rejects(est: IOData, val: IOData, nk: int, order: int = 8, lags: int = 25) -> float:
    """How far the input at the lags an ARX [order order nk] skips (0..nk−1) still shows in its residuals on
    ``val``: the largest |r_eu(τ)|, τ < nk, over the 99 % band (> 1: the delay is too long; 0 for nk = 0)."""
    from maglev.estimation import estimate
    from maglev.validation import resid

    if nk == 0:
        return 0.0
    model = estimate(est, "arx", [order, order, nk], "auto")
    r = resid(val, model, lags=max(lags, nk))
    skipped = (r.cross_lags >= 0) & (r.cross_lags < nk)
    return float(np.max(np.abs(r.cross_corr[skipped])) / r.cross_band)


DELAY_RULE = (
    "Upper bound: the smaller of the step's dead time (the averaged staircase step response reaching "
    f"{100 * DEAD_LEVEL:g} % of its change, in model samples) and delayest (ARX [2 2 nk]). Below it, a delay nk "
    "is rejected by a dataset when an ARX [n n nk] leaves residuals correlated with u(t−τ) beyond the 99 % band "
    "at a lag τ < nk it skips. nk = the largest delay up to the bound below the first rejected one.")


def delay_decision(datasets: Sequence[tuple[str, IOData, IOData]], step_dead_samples: float | None,
                   delayest_nk: dict[str, int], order: int = 8, configured: int | None = None) -> Decision:
    """The delay decision over ``datasets`` ((name, est, val) on the models' time base).

    ``step_dead_samples``: the step's dead time in model samples (None without a staircase);
    ``delayest_nk``: delayest's answer per dataset name; ``configured``: the nk the sweep's config sets —
    when it differs from the rule's the decision is ``forced`` and a caution says so."""
    bounds = [int(v) for v in delayest_nk.values()]
    if step_dead_samples is not None:
        bounds.append(int(math.floor(step_dead_samples)))
    upper = min(bounds) if bounds else 10
    rows, rejected = [], set()
    for nk in range(upper + 1):
        row: dict = {"nk": nk}
        for name, est, val in datasets:
            ratio = residual_rejects(est, val, nk, order)
            row[f"{name} |r_eu| / band"] = ratio
            if ratio > 1:
                rejected.add(nk)
        row["rejected"] = nk in rejected
        rows.append(row)
    nk = min(rejected) - 1 if rejected else upper  # a delay skipping a lag that matters is too long, and so is any longer
    reasons = []
    if step_dead_samples is not None:
        reasons.append(f"The step's dead time is {step_dead_samples:.2f} model samples.")
    reasons.append("delayest gives " + ", ".join(f"nk = {v} on {n}" for n, v in delayest_nk.items()) + "; the "
                   f"upper bound is nk = {upper}.")
    above = sorted(rejected)
    if above:
        worst = {k: max(v for key, v in rows[k].items() if key.endswith("/ band")) for k in above}
        reasons.append("Rejected by the residual–input correlation: " + ", ".join(
            f"nk = {k} (up to {worst[k]:.2f} × the 99 % band)" for k in above) + ".")
    reasons.append(f"nk = {nk}: the largest delay up to the bound below the first one a dataset's residuals reject.")
    choice = {"nk": nk}
    cautions = []
    forced = configured is not None and configured != nk
    if forced:
        cautions.append(f"The sweep's config sets structure.nk = {configured}, not the rule's nk = {nk}.")
        choice = {"nk": configured, "rule": nk}
    return Decision("delay", DELAY_RULE, choice, rows, reasons, forced=forced, cautions=cautions)
