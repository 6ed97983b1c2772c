"""A lab decision as data: the rule, the choice, and the numbers that justify it.

Every choice the lab makes before (and after) identification — working region, records,
data length and trim, α of the binary records, delay, orders — is made by a function of
the records (:mod:`maglev.lab.decisions`) that returns a :class:`Decision`.  The study logs
all of a sweep's decisions as ONE JSON artifact and the report prints each one's rule,
evidence and choice, so every sentence the report writes about a choice stands beside the
numbers it was drawn from.

Schema of ``decisions.json`` (logged on the sweep's **parent run** as ``lab/decisions.json``;
the pre-run decisions at the sweep's start, re-logged with ``orders`` added when the sweep is
ranked)::

    {
      "working_region": <Decision>,   # choice: {"u_min", "u_max", "u_star", "slope"}            (A, cm/A)
      "records":        <Decision>,   # choice: {"uniform": [dataset names], "binary": [dataset names]}
      "data_length":    <Decision>,   # choice: {dataset name: {"trim_s", "est_s", "val_s", "split"}}
      "alpha":          <Decision>,   # choice: {dataset name: α estimated on the recorded sample axis}
      "delay":          <Decision>,   # choice: {"nk": int, "Ts": seconds}
      "orders":         <Decision>    # choice: {structure: final order}
    }

    <Decision> = {
      "name":     str,          # one of the keys above
      "rule":     str,          # the rule in one or two sentences, with its thresholds as numbers
      "choice":   JSON value,   # what was chosen (shape per key above)
      "evidence": [ {column: value, ...}, ... ],   # table rows, same keys in every row, first row's
                                                   # key order is the column order
      "reasons":  [str, ...],   # sentences generated from the evidence: why the choice wins/others lose
      "forced":   bool,         # True when the config forced the choice (e.g. ``dataset=`` overrides);
                                # the rule's evidence is still shown, the choice is the config's
      "cautions": [str, ...]    # where the rule could not be met (e.g. a record too short), else []
    }

A key may be missing when its step did not run (e.g. ``orders`` before the ranking).
:func:`read_decisions` / :func:`write_decisions` convert the whole file; :meth:`Decision.rows`
gives the (label, HTML-escaped text) rows a report section shows.
"""

from __future__ import annotations

import html
import json
import math
from dataclasses import asdict, dataclass, field
from typing import Any

import numpy as np

__all__ = ["Decision", "DECISION_NAMES", "read_decisions", "write_decisions", "jsonable"]

DECISION_NAMES = ("working_region", "records", "data_length", "alpha", "delay", "orders")


def jsonable(value: Any) -> Any:
    """``value`` with numpy scalars/arrays and tuples turned into JSON types (non-finite floats to None)."""
    if isinstance(value, dict):
        return {str(k): jsonable(v) for k, v in value.items()}
    if isinstance(value, (list, tuple, np.ndarray)):
        return [jsonable(v) for v in value]
    if isinstance(value, (bool, np.bool_)):
        return bool(value)
    if isinstance(value, (int, np.integer)):
        return int(value)
    if isinstance(value, (float, np.floating)):
        return float(value) if math.isfinite(value) else None
    return value


@dataclass(frozen=True)
class Decision:
    """One lab decision: ``rule`` applied to the ``evidence`` rows gives ``choice``, for the ``reasons``."""

    name: str
    rule: str
    choice: Any
    evidence: list[dict] = field(default_factory=list)
    reasons: list[str] = field(default_factory=list)
    forced: bool = False
    cautions: list[str] = field(default_factory=list)

    def __post_init__(self) -> None:
        if self.name not in DECISION_NAMES:
            raise ValueError(f"decision name must be one of {DECISION_NAMES}, got {self.name!r}")

    def to_dict(self) -> dict:
        return jsonable(asdict(self))

    @classmethod
    def from_dict(cls, d: dict) -> Decision:
        missing = {"name", "rule", "choice"} - set(d)
        if missing:
            raise ValueError(f"a decision needs the keys name, rule, choice; missing {sorted(missing)} in {d!r}")
        return cls(name=d["name"], rule=d["rule"], choice=d["choice"], evidence=list(d.get("evidence", [])),
                   reasons=list(d.get("reasons", [])), forced=bool(d.get("forced", False)),
                   cautions=list(d.get("cautions", [])))

    def choice_text(self) -> str:
        """The choice as one short line (dicts as ``key: value`` pairs)."""
        def fmt(v: Any) -> str:
            if isinstance(v, float):
                return f"{v:.4g}"
            if isinstance(v, dict):
                return ", ".join(f"{k}: {fmt(x)}" for k, x in v.items())
            if isinstance(v, list):
                return ", ".join(fmt(x) for x in v)
            return str(v)
        return fmt(self.choice) + (" (forced by the config)" if self.forced else "")

    def rows(self) -> list[tuple[str, str]]:
        """(label, HTML-escaped text) rows: rule, choice, reasons, cautions — the evidence table is
        :meth:`table_rows`."""
        out = [("rule", html.escape(self.rule)), ("choice", html.escape(self.choice_text()))]
        out += [("why", html.escape(r)) for r in self.reasons]
        out += [("caution", html.escape(c)) for c in self.cautions]
        return out

    def table_rows(self) -> tuple[list[str], list[list[str]]]:
        """The evidence as (header, rows of HTML-escaped cells); floats to 4 significant digits."""
        if not self.evidence:
            return [], []
        header = list(self.evidence[0])
        def cell(v: Any) -> str:
            if isinstance(v, float):
                return f"{v:.4g}"
            if isinstance(v, bool):
                return "yes" if v else "no"
            return html.escape("" if v is None else str(v))
        return [html.escape(h) for h in header], [[cell(r.get(h)) for h in header] for r in self.evidence]


def write_decisions(decisions: dict[str, Decision] | list[Decision]) -> dict:
    """The ``decisions.json`` content (a dict keyed by decision name) of some decisions."""
    items = decisions.values() if isinstance(decisions, dict) else decisions
    return {d.name: d.to_dict() for d in items}


def read_decisions(content: dict | str | bytes | None) -> dict[str, Decision]:
    """The decisions of a ``decisions.json`` content (parsed or text); {} for None."""
    if content is None:
        return {}
    if isinstance(content, (str, bytes)):
        content = json.loads(content)
    return {k: Decision.from_dict(v) for k, v in content.items()}
