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

from maglev.units import U_UNIT, Y_UNIT

__all__ = ["Decision", "DECISION_NAMES", "read_decisions", "write_decisions", "jsonable"]

DECISION_NAMES = ("working_region", "records", "data_length", "alpha", "delay", "orders")
TITLES = {"working_region": "working region", "records": "records", "data_length": "amount of data",
          "alpha": "α of the binary record", "delay": "delay", "orders": "model orders"}


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
        """The choice as a sentence a control engineer reads, with units (:data:`CHOICE_SENTENCES`); a choice of
        other than the schema's dict (a hand-made decision) as its values."""
        if not isinstance(self.choice, dict):
            return _values(self.choice) + (" (forced by the config)" if self.forced else "")
        text = CHOICE_SENTENCES[self.name](self.choice)
        said = "forced" in self.choice or "rule" in self.choice  # records and delay say it in their sentence
        forced = " (the trim is the config's)" if self.name == "data_length" else " (forced by the config)"
        return text + (forced if self.forced and not said else "")

    @property
    def title(self) -> str:
        """The decision's name in words (its key stays in ``decisions.json``)."""
        return TITLES[self.name]

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


# ------------------------------------------------------------------------------------- the choice in words
def _values(v: Any) -> str:
    """A choice's values (floats to 4 significant digits)."""
    if isinstance(v, float):
        return f"{v:.4g}"
    if isinstance(v, dict):
        return ", ".join(_values(x) for x in v.values())
    if isinstance(v, list):
        return ", ".join(_values(x) for x in v)
    return str(v)


def _listed(names: list) -> str:
    """``a``, ``a and b``, ``a, b and c``."""
    names = [str(n) for n in names]
    return " and ".join(names) if len(names) < 3 else ", ".join(names[:-1]) + " and " + names[-1]


def _region(c: dict) -> str:
    text = (f"working region {c['u_min']:.3g}–{c['u_max']:.3g} {U_UNIT}, working point u* = {c['u_star']:.3g} "
            f"{U_UNIT}, static gain (slope of ȳ against ū) {c['slope']:.3g} {Y_UNIT}/{U_UNIT}")
    if c.get("u_sat_model") is not None:
        text += f"; the physical model's current regulator saturates at {c['u_sat_model']:.3g} {U_UNIT}"
    return text


CLASS_WORDS = {"uniform": ("uniform white-noise record", "uniform white-noise records"),
               "binary": ("random binary record", "random binary records")}


def _by_class(choice: dict) -> str:
    parts = []
    for cls, names in choice.items():
        one, many = CLASS_WORDS.get(cls, (f"{cls} record", f"{cls} records"))
        parts.append(f"{one if len(names) == 1 else many} {_listed(names)}" if names else f"no {one}")
    return "; ".join(parts)


def _records(c: dict) -> str:
    if "forced" in c:
        return (f"the records the config names, {_listed(c['forced'])}, forced by the config (the rule would choose "
                f"{_by_class(c['rule'])})")
    return _by_class(c)


def _length(c: dict) -> str:
    texts = {name: f"{v['trim_s']:.2f} s trimmed, {v['est_s']:.2f} s estimation + {v['val_s']:.2f} s validation"
             for name, v in c.items()}
    if len(set(texts.values())) == 1 and len(texts) > 1:
        return "each record " + next(iter(texts.values()))
    return "; ".join(f"{name} {t}" for name, t in texts.items())


def _alpha(c: dict) -> str:
    return "; ".join(f"α = {a:.3f} for {name} (its measured switching probability per recorded sample)"
                     for name, a in c.items())


def _delay(c: dict) -> str:
    ts = f" = {1000 * c['nk'] * c['Ts']:.3g} ms" if c.get("Ts") else ""
    text = f"an input delay of nk = {int(c['nk'])} samples{ts}"
    if "rule" in c:
        text += f", set by the config (the rule's answer is nk = {int(c['rule'])})"
    return text


def _orders(c: dict) -> str:
    return ", ".join(f"{st.upper()} order {int(o)}" for st, o in c.items())


# the sentence of each decision's choice (its shape: the schema at the top of this module)
CHOICE_SENTENCES = {"working_region": _region, "records": _records, "data_length": _length, "alpha": _alpha,
                    "delay": _delay, "orders": _orders}


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
