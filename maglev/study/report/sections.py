"""The sections of the lab report (EL2820 Lab 3 §5), each as HTML stating its numbers next to its figures.

Every function takes what the sweep logged (the ranking, the parent run's lab steps, the
datasets rebuilt from the runs' configs) and returns an HTML fragment; :mod:`maglev.study.report`
assembles them into one page.  Figures arrive as PNG bytes and are embedded as base64.
"""

from __future__ import annotations

import base64
import html
import math
from collections.abc import Iterable, Sequence

import numpy as np
import pandas as pd

from maglev.lab.records import ALPHA_TOLERANCE, EST_MIN_S, INPUT_OUTSIDE_MAX, VAL_MIN_S, share_outside
from maglev.model import CANCEL_TOL, PolyModel
from maglev.structures import get as get_structure
from maglev.study.cautions import ORDER_MARGIN, order_choice
from maglev.study.ranking import validation_note
from maglev.study.report.verdicts import validation_data
from maglev.units import U_UNIT, Y_UNIT
from maglev.validation import TEST_LEVEL, format_p


# ---------------------------------------------------------------------------- HTML helpers
FIGURE = "{{figure}}"  # replaced by the figure's number when the page is assembled (number_figures)


def esc(x) -> str:
    return html.escape(str(x))


def num(x, digits: int = 2) -> str:
    if x is None or (isinstance(x, float) and math.isnan(x)):
        return "–"
    if isinstance(x, (int, np.integer)):
        return str(int(x))
    x = float(x)
    return f"{x:.{digits}f}" if 1e-3 <= abs(x) < 1e6 or x == 0 else f"{x:.3g}"


def img(data: bytes | None, caption: str, cls: str = "") -> str:
    """A numbered figure with its caption (plain text, escaped here); ``cls``: ``half`` (two per row), ``side``
    (beside the text) or full width."""
    if not data:
        return f"<p class='missing'>(figure not available: {esc(caption)})</p>"
    b64 = base64.b64encode(data).decode()
    return (f"<figure class='{cls}'><img alt='{esc(caption)}' src='data:image/png;base64,{b64}'>"
            f"<figcaption><b>Figure {FIGURE}.</b> {esc(caption)}</figcaption></figure>")


def number_figures(page: str) -> str:
    """Number the figures of ``page`` in reading order."""
    parts = page.split(FIGURE)
    return "".join(p + (str(i + 1) if i < len(parts) - 1 else "") for i, p in enumerate(parts))


def table(df: pd.DataFrame, digits: int = 2) -> str:
    return df.to_html(index=False, escape=True, na_rep="–", border=0, classes="t",
                      float_format=lambda v: num(v, digits))


def section(anchor: str, title: str, *parts: str) -> str:
    return f"<section id='{anchor}'><h2>{esc(title)}</h2>\n" + "\n".join(p for p in parts if p) + "</section>\n"


def para(text: str) -> str:
    return f"<p>{text}</p>"


def bullets(items: Iterable[str]) -> str:
    return "<ul>" + "".join(f"<li>{i}</li>" for i in items) + "</ul>"


EVIDENCE_ROWS = 4  # a decision's evidence table stays in its section up to this many rows, else goes to Appendix E
# the columns of a long evidence table its section prints whatever its length (one row per record: its verdict)
SUMMARY_COLUMNS = {"records": ("record", "class", "u range (A)", "α", "score", "verdict")}


def decision(decisions: dict | None, name: str) -> str:
    """A lab decision the sweep logged (``lab/decisions.json``, :class:`maglev.lab.decision.Decision`): its choice in
    words, its rule, reasons and cautions, with its evidence table when it is short (Appendix E holds the long ones;
    of those, the :data:`SUMMARY_COLUMNS` of every row stay in the section); "" when the sweep logged none of that
    name."""
    d = (decisions or {}).get(name)
    if d is None:
        return ""
    rows = d.rows()
    rule, choice = (next(v for label, v in rows if label == key) for key in ("rule", "choice"))
    extra = [f"{label}: {value}" for label, value in rows if label not in ("rule", "choice")]
    header, cells = d.table_rows()
    short = 0 < len(cells) <= EVIDENCE_ROWS
    keep = [header.index(c) for c in SUMMARY_COLUMNS.get(name, ()) if c in header]
    summary = not short and len(keep) == len(SUMMARY_COLUMNS.get(name, ())) > 0
    where = "" if short or not cells else (" (the table below; all its evidence in Appendix E)" if summary else
                                           f" (evidence: {len(cells)} rows, Appendix E)")
    table_ = (evidence_table(header, cells) if short else
              evidence_table([header[i] for i in keep], [[r[i] for i in keep] for r in cells]) if summary else "")
    return para(f"<b>Decision on the {esc(d.title)}: {choice}.</b> Rule: {rule.rstrip('.')}{where}.") + (
        bullets(extra) if extra else "") + table_


def evidence_table(header: list[str], cells: list[list[str]]) -> str:
    """A decision's evidence rows (already escaped) as a table."""
    return ("<table class='t'><tr>" + "".join(f"<th>{h}</th>" for h in header) + "</tr>"
            + "".join("<tr>" + "".join(f"<td>{c}</td>" for c in row) + "</tr>" for row in cells) + "</table>")


def decisions_evidence(decisions: dict | None) -> str:
    """Appendix E: the evidence of every decision too long to print in its section."""
    parts = []
    for d in (decisions or {}).values():
        header, cells = d.table_rows()
        if len(cells) > EVIDENCE_ROWS:
            parts.append(f"<h3>Decision on the {esc(d.title)}</h3>" + evidence_table(header, cells))
    return section("decisions-evidence", "E. Evidence of the lab decisions", *parts) if parts else ""


# ---------------------------------------------------------------------------- analysis helpers
def cz(z: complex) -> str:
    return f"{z.real:.3f}{z.imag:+.3f}j" if abs(z.imag) > 1e-9 else f"{z.real:.3f}"


# ---------------------------------------------------------------------------- sections
def working_region(lab: dict, lab_png: dict, ts_used: list[float], decisions: dict | None = None) -> str:
    """§3.1: the working region from the staircase's stationary averages, with its plot and motivation."""
    title = "2. Working region"
    if "lab.u_min" not in lab:
        return section("working-region", title,
                       para("The sweep's parent run has no lab-level steps (lab.enabled=false or they failed)."))
    g = lab.get
    text = (f"The staircase record ({esc(lab.get('staircase', 'staircase'))}) steps the input over the plant's "
            "[0, 10] A; "
            f"getStationaryAverages (Appendix A) averages the last part of each step's response, after its "
            f"transient. The working region is the widest range of levels on which ȳ against ū stays on a "
            f"straight line and off the saturation plateau (every level near the least-squares line, every "
            f"level-to-level slope near the line's; the bands are the decision's rule below): "
            f"<b>ū ∈ [{num(g('lab.u_min'))}, "
            f"{num(g('lab.u_max'))}] A</b>, slope {num(g('lab.slope'), 3)} {Y_UNIT}/{U_UNIT}, working point "
            f"<b>u* = (u_min + u_max)/2 = {num(g('lab.u_star'))} A</b>. Below it the lower magnet still rests on its "
            "seat, above it the current regulator saturates, so the slope changes there, as the figure beside shows.")
    sampling = (f"Sampling: the 10–90 % rise time of steps inside the region is {num(g('lab.rise_time_samples'), 1)} "
                f"samples = {num(1000 * g('lab.rise_time_s'), 1)} ms, so 4–10 samples per rise time allow "
                f"Ts ∈ [{num(1000 * g('lab.Ts_min'), 2)}, {num(1000 * g('lab.Ts_max'), 2)}] ms; the models use "
                + ", ".join(f"{num(1000 * t, 2)} ms" for t in ts_used)
                + f" (decimation by {int(g('lab.decimation'))} of the 1 ms records).")
    fig = img(lab_png.get("working_region.png"), "Working region: stationary output ȳ (cm) against step level ū "
              "(A) of the staircase; filled squares are the levels inside the region, the line its least-squares "
              "fit, the dotted line the working point u*.", "side")
    return section("working-region", title, fig, para(text), para(sampling),
                   decision(decisions, "working_region"), "<div class='clear'></div>")


def input_signals(datasets: dict, configs: dict, lab: dict, lab_png: dict, decisions: dict | None = None) -> str:
    """§3.3: why these three records: two uniform, one binary, each inside the working region, centred at u*,
    as wide as it allows, and the binary one's α = α* from the output spectrum; each record's share of input
    samples outside the region beside the records rule's limit, and whether the rule chose them.
    ``datasets``: name -> Prepared; ``configs``: name -> run config."""
    from maglev.study.report.verdicts import records_head, region_text

    u_lo, u_hi = lab.get("lab.u_min", math.nan), lab.get("lab.u_max", math.nan)
    u_star = lab.get("lab.u_star", math.nan)
    alpha_star = lab.get("lab.alpha_star", math.nan)
    why, outside = [], {}
    for name, prep in datasets.items():
        ds = configs[name]["dataset"]
        trim = int(ds["preprocess"]["trim"])
        u = prep.raw.u[trim:]
        lo, hi = float(np.min(u)), float(np.max(u))
        outside[name] = share_outside(u, (u_lo, u_hi)) if u_hi > u_lo else math.nan
        cover = (hi - lo) / (u_hi - u_lo) if u_hi > u_lo else math.nan
        alpha = binary_alpha(name, ds, decisions) if ds["input_class"] == "binary" else None
        text = (f"<b>{esc(name)}</b> ({esc(ds['input_class'])}): [{num(lo)}, {num(hi)}] A, "
                f"{num(100 * cover, 0)} % of the working region's width, mean {num(prep.u0)} A "
                f"({num(round(prep.u0 - u_star, 2) + 0.0, 2)} A from u*); " + region_text(outside[name], INPUT_OUTSIDE_MAX))
        if alpha is not None:
            text += "; " + alpha_text(alpha, alpha_star, (decisions or {}).get("records"))
        why.append(text + ".")
    classes = [configs[n]["dataset"]["input_class"] for n in datasets]
    records = (decisions or {}).get("records")
    head = (f"The lab asks for two uniform white-noise inputs and one random binary input (§3.3): this sweep uses "
            f"{classes.count('uniform')} uniform and {classes.count('binary')} binary record(s). "
            + records_head(outside, INPUT_OUTSIDE_MAX, None if records is None else records.forced))
    shares = lab.get("alpha_shares", {})
    spectrum = ""
    if "lab.band_low" in lab:
        spectrum = para(
            f"α*: the output spectrum |FFT(y − ȳ)| of {esc(lab.get('spectrum_dataset', 'the base dataset'))} holds "
            f"80 % of its energy below ω = {num(lab['lab.band_high'], 3)} rad/sample (from {num(lab['lab.band_low'], 3)}"
            f"; {num(lab['lab.band_high'] / math.pi, 3)}·π, π = the Nyquist frequency of the record as identified). "
            "Share of a binary signal's power in that band: "
            + ", ".join(f"α = {a}: {num(100 * s, 1)} %" for a, s in shares.items())
            + f"; the largest gives <b>α* = {num(alpha_star)}</b>.")
    figs = ("<div class='row'>" + img(lab_png.get("output_spectrum.png"), "Output spectrum |Y(ω)| (cm) of the base "
                                      "dataset against ω/π; the shaded band holds 80 % of its energy.", "half")
            + img(lab_png.get("alpha.png"), "Spectrum Φ_s(ω) of a unit binary signal for the lab's α values "
                  "(the lab's Fig. 5), with the output's band shaded.", "half") + "</div>")
    return section("inputs", "3. Input signals", para(head), bullets(why), spectrum,
                   decision(decisions, "records"), decision(decisions, "alpha"), figs)


def binary_alpha(name: str, ds: dict, decisions: dict | None) -> float | None:
    """A binary record's α: the one the alpha decision measured from its switching rate, else its config's design
    value (a real record's config has none), else None."""
    measured = (decisions or {}).get("alpha")
    if measured is not None and isinstance(measured.choice, dict) and name in measured.choice:
        return float(measured.choice[name])
    return None if ds.get("alpha") is None else float(ds["alpha"])


def alpha_text(alpha: float, alpha_star: float, records=None) -> str:
    """A binary record's α against α* (within the alpha decision's tolerance), and why it is not α* when it is not:
    the records rule's choice (no binary record nearer α* passes it: the records at α* it refuses are named, from
    its evidence rows' verdicts) or the config's (``records``: the records decision, None when the sweep logged
    none)."""
    if not math.isfinite(alpha_star):
        return f"α = {num(alpha)}"
    if abs(alpha - alpha_star) <= ALPHA_TOLERANCE:
        return f"α = {num(alpha)} = α*, the α whose spectrum puts most power in the output's band"
    if records is None:
        why = ""
    elif records.forced:
        why = "; the config forces this record"
    else:
        at_star = [str(r["record"]) for r in records.evidence if r.get("class") == "binary" and r.get("α") is not None
                   and abs(r["α"] - alpha_star) <= ALPHA_TOLERANCE and str(r.get("verdict", "")).startswith("refused")]
        why = (f"; the records rule refuses the binary record{'s' if len(at_star) > 1 else ''} at α*, "
               + ", ".join(at_star) + " (the table below)" if at_star else
               "; no binary record with α nearer α* passes the records rule (the table below)")
    return f"<b>α = {num(alpha)}, not α* = {num(alpha_star)}</b>{why}"


def data_amounts(table_: pd.DataFrame, datasets: dict, configs: dict, decisions: dict | None = None) -> str:
    """§3.4: samples and seconds used for estimation and validation, per record, against the lab's minimum."""
    rows = []
    for name, prep in datasets.items():
        pp = configs[name]["dataset"]["preprocess"]
        est_s, val_s = prep.est.N * prep.est.Ts, prep.val.N * prep.val.Ts
        ok = est_s >= EST_MIN_S and val_s >= VAL_MIN_S
        rows.append({"dataset": name, "record (samples)": prep.raw.N, "trimmed": int(pp["trim"]),
                     "Ts (ms)": 1000 * prep.data.Ts, "estimation": f"{prep.est.N} samples = {num(est_s)} s",
                     "validation": f"{prep.val.N} samples = {num(val_s)} s",
                     "≥ 10 s / 7 s": "met" if ok else "NOT met"})
    text = para("Each record: the start-up transient is trimmed, the means removed, the record decimated to Ts and "
                "split — the first part estimates, the rest (never seen by the estimator) validates; every model is "
                "validated on its own record's validation part, and the binary-vs-uniform comparison (§7) also on "
                f"the others'. Units: u is the coil current command in {U_UNIT}, y the upper magnet's height in "
                f"{Y_UNIT}.")
    return section("data", "4. Amount of data", text, table(pd.DataFrame(rows)), decision(decisions, "data_length"))


def delay_evidence(models: Sequence[PolyModel], delayest_nk: int | None = None, rejected: Sequence[int] = ()) -> str:
    """Whether the identified models support their delay: how many have a first B coefficient b_nk more than
    two standard errors from zero (a response already at lag nk), against ``delayest``'s nk when given.  When most
    do not, but the delay decision ``rejected`` the longer delays (the nk its rule refuses: a longer delay leaves the
    input at the skipped lags in the residuals), the sentence says the response at lag nk is small, not absent."""
    z = []
    for m in models:
        se = m.std_errors
        if se is None or m.nb == 0:
            continue
        j = m.parameter_names.index(f"b{m.nk}")
        z.append(abs(m.parameters[j]) / se[j] if se[j] > 0 else math.inf)
    if not z:
        return ""
    nks = sorted({m.nk for m in models if m.nb})
    shown = ", ".join(str(k) for k in nks)
    text = f"The swept structures use nk = {shown}" + (f"; delayest gives {delayest_nk}" if delayest_nk is not None
                                                      else "") + ". "
    significant = sum(v > 2 for v in z)
    text += (f"The first B coefficient (b at lag nk) is more than two standard errors from zero in {significant} of "
             f"{len(z)} models (median |b|/σ {num(float(np.median(z)), 1)}): ")
    if 2 * significant > len(z):
        text += f"the response is there at lag {shown}, as the swept delay assumes"
        later = [k for k in nks if delayest_nk is not None and delayest_nk > k]
        text += (f"; delayest's nk = {delayest_nk} (from ARX [2 2 nk]) would leave that coefficient out." if later
                 else ".")
    else:
        longer = sorted(k for k in rejected if k > max(nks))
        if longer:
            text += (f"most models find no significant response at lag {shown}, yet the delay decision below rejects "
                     f"nk = {', '.join(map(str, longer))}: a longer delay leaves the input at the lags it skips in the "
                     f"residuals, so the response at lag {shown} is small, not absent"
                     + (f" (delayest, which fits ARX [2 2 nk] only, gives nk = {delayest_nk})." if delayest_nk
                        is not None else "."))
        else:
            text += (f"most models find no response at lag {shown}, so the swept delay is too small for the data"
                     + (f" (delayest: nk = {delayest_nk})." if delayest_nk is not None else "."))
    return text


def order_sentence(oc: dict) -> str:
    """The report's sentence on a structure's order (:func:`maglev.study.cautions.order_choice`): the mean
    simulation FIT by order, the order the rule chooses, the orders that do not count (from the first one whose added
    poles its models cancel, and those whose models move away from the best linear approximation), and where the
    choice lies in the swept grid."""
    from maglev.lab.orders import away_from_bla, cancelling_order

    grid, chosen, bla, cancel = oc["grid"], oc["chosen"], oc["bla"], oc.get("cancellations") or {}
    away = sorted(away_from_bla(bla, grid))
    cut = cancelling_order(cancel, grid)
    listed = ", ".join(f"{o}: {num(f)} %" for o, f in oc["fit"].items())
    among = ""
    if cut is not None:
        among += (f" below order {cut}, whose added poles its models cancel with zeros (mean near cancellations per "
                  "model " + ", ".join(f"{o}: {num(cancel[o])}" for o in grid if o in cancel) + ")")
    if away:
        among += ((" and" if among else "") + " among the orders whose models do not move away from the best linear "
                  f"approximation (order(s) {', '.join(map(str, away))} do: mean distance "
                  + ", ".join(f"{o}: {num(bla[o], 3)}" for o in grid if o in bla) + ")")
    if oc["edge"]:
        where = f", at the {oc['edge']} edge of the swept orders: add order {oc['suggest']}."
    elif chosen == grid[0]:
        counted = [o for o in grid if o > chosen and o not in away and (cut is None or o < cut)]
        where = (", the smallest swept" + (f": the higher orders{' that count' if away or cut else ''} add at most "
                                           f"{ORDER_MARGIN:g} point" if counted else "")
                 + " (no smaller order was swept).")
    else:
        where = ", inside the swept orders."
    return (f"Mean simulation FIT by order ({listed}): the smallest order within {ORDER_MARGIN:g} point of the best"
            f"{among} is <b>{chosen}</b>{where}")


def lower_edge_text(chosen: int, oc: dict | None) -> str:
    """A sentence when the chosen order is the smallest swept one above 1: the rule takes the smallest order within
    the margin of the best, so a smaller order, never swept, might have done as well; "" otherwise."""
    if oc is None or int(chosen) != oc["grid"][0] or int(chosen) <= 1:
        return ""
    return (f" It is the smallest order swept: order {int(chosen) - 1} was not, so whether it would simulate within "
            f"{ORDER_MARGIN:g} point as well is untested.")


def order_summary(table_: pd.DataFrame, models: dict, tol: float = CANCEL_TOL) -> pd.DataFrame:
    """One row per structure: its mean simulation FIT (%) over the datasets at each swept order (the number an order
    is chosen by, one column per order: a grid of any size stays a few rows) and its near cancellations in all."""
    rows = []
    for st, g in table_.groupby("structure", sort=False):
        row = {"structure": st}
        for order, h in sorted(g.groupby("order"), key=lambda x: x[0]):
            row[f"order {int(order)}: sim FIT %"] = h["val_fit_sim"].mean()
        row["cancellations"] = sum(len(models[i].near_cancellations(tol)) for i in g["run_id"])
        rows.append(row)
    return pd.DataFrame(rows)


def structures(table_: pd.DataFrame, models: dict, lab: dict, decisions: dict | None = None,
               tol: float = CANCEL_TOL) -> str:
    """§3.5: the structures (at least three) and the motivation of each structure's order, from the sweep's
    numbers (``models``: run id -> PolyModel for every ranked run)."""
    names = list(dict.fromkeys(table_["structure"]))
    parts = [para(f"{len(names)} structures were estimated ({', '.join(n.upper() for n in names)}; the lab asks for "
                  "three): from the simplest, ARX, whose noise shares the plant's poles, through ARMAX, to OE and BJ, "
                  "whose G has poles of its own — the structure the physics suggests (§1).")]
    if "lab.arx_na" in lab:
        parts.append(para(
            f"Before any PEM fit: delayest (ARX [2 2 nk]) gives nk = {int(lab['lab.nk'])} samples, and ARX order "
            f"selection (arxstruc, na and nb in 1…{int(lab['lab.max_order'])}) picks na = {int(lab['lab.arx_na'])}, "
            f"nb = {int(lab['lab.arx_nb'])} by AIC and na = {int(lab['lab.arx_na_mdl'])}, nb = "
            f"{int(lab['lab.arx_nb_mdl'])} by MDL (Figure in Appendix D)."))
    delay_rule = (decisions or {}).get("delay")
    rejected = [int(r["nk"]) for r in delay_rule.evidence if r.get("rejected")] if delay_rule is not None else []
    delay = delay_evidence([models[i] for i in table_["run_id"]], int(lab["lab.nk"]) if "lab.nk" in lab else None,
                           rejected)
    if delay:
        parts.append(para(delay))
    lines = []
    for st in names:
        runs = table_[table_["structure"] == st]
        entry = get_structure(st)
        text = f"<b>{esc(st.upper())}</b> {esc(entry.equation)}. "
        oc = order_choice(runs)
        chosen = (decisions or {}).get("orders")
        if chosen is not None and isinstance(chosen.choice, dict) and st in chosen.choice:
            text += f"Order <b>{esc(chosen.choice[st])}</b>, by the orders decision below."
            text += esc(lower_edge_text(chosen.choice[st], oc))
        elif oc is None:
            text += f"One order swept ({esc(', '.join(sorted(set(runs['orders']))))}): no choice to motivate."
        else:
            text += order_sentence(oc)
        n_cancel = sum(len(models[i].near_cancellations(tol)) for i in runs["run_id"])
        final = runs[runs["final_order"].astype(bool)] if "final_order" in runs else runs.iloc[:0]
        if n_cancel:
            at_final = sum(len(models[i].near_cancellations(tol)) for i in final["run_id"])
            text += (f" {n_cancel} near pole-zero cancellation(s) (|p−z| &lt; {tol}) among its models"
                     + (f", {at_final} of them at order {int(final['order'].iloc[0])}." if len(final) else "."))
        lines.append(text)
    note = para("A near cancellation is a pole the data may not support: the orders rule stops where they grow by "
                "one per model and order.") if any("near pole-zero cancellation" in t for t in lines) else ""
    parts += [bullets(lines), note, table(order_summary(table_, models, tol)), decision(decisions, "orders"),
              decision(decisions, "delay")]
    return section("structures", "5. Model structures and orders", *parts)


def top_four(ranking) -> str:
    """§3.7: the top four by one-step validation FIT, with y(t−1)'s FIT and the simulation FIT beside."""
    note = validation_note(ranking.top)
    text = para(f"{len(ranking.table)} models ranked by one-step-ahead FIT on validation data (the lab's eq. 5; ties "
                "to fewer parameters)"
                + (", ignored: " + ", ".join(f"{n} {s}" for s, n in sorted(ranking.sweep.ignored.items()))
                   if ranking.sweep.ignored else "") + ". Beside each: the one-step FIT of the naive predictor "
                "ŷ(t) = y(t−1) on the same data (a model must beat it to add anything) and the simulation FIT (the "
                "output from the input alone: G without the noise model).")
    from maglev.lab.orders import statuses

    status = statuses(ranking.orders)
    lines = [f"#{int(r['rank'])} <b>{esc(r['name'])}</b>: FIT {num(r['val_fit'])} % on "
             f"{esc(validation_data(r['val_dataset']))} (y(t−1): {num(r['val_fit_naive'])} %, simulation: "
             f"{num(r['val_fit_sim'])} %), "
             f"{r['n_params']} parameters; " + esc(order_place(r, status)) + esc(residual_text(r))
             for _, r in ranking.top.iterrows()]
    return section("top4", "6. Top four models", text, bullets(lines), para(esc(residual_summary(ranking.top))),
                   para(esc(final_orders_text(ranking))),
                   para(f"<b>Note:</b> the top four were {esc(note)}.") if note else "")


def order_place(row: pd.Series, status: dict[tuple[str, int], str]) -> str:
    """A ranked run's order against the order the orders rule chose for its structure (column ``final_order``, the
    orders decision's ``status`` by (structure, order))."""
    st, o = str(row["structure"]), int(row["order"])
    if row["final_order"]:
        return (f"order {o}, the one the orders rule chose for {st.upper()}" if (st, o) in status else
                f"order {o}, the one swept")
    why = status.get((st, o))
    return f"order {o}, not the one the orders rule chose for {st.upper()}" + (f": {why}" if why else "")


def residual_text(row: pd.Series) -> str:
    """A ranked run's residual tests in a clause (p-values against the lab's 1 % level); "" without them."""
    tests = [(t, float(row[c])) for t, c in (("whiteness", "whiteness_pvalue"), ("independence", "independence_pvalue"))
             if c in row.index and math.isfinite(float(row[c]))]
    return "".join(f"; {t} {'passes' if p >= TEST_LEVEL else 'fails'} (p = {format_p(p)})" for t, p in tests)


def residual_summary(top: pd.DataFrame) -> str:
    """How many of the top four fail each residual test, and what a failure means for their ranking."""
    parts = [(t, int((top[c] < TEST_LEVEL).sum())) for t, c in (("whiteness", "whiteness_pvalue"),
                                                              ("independence", "independence_pvalue")) if c in top]
    if not parts:
        return ""
    failing = [f"{'all' if k == len(top) else f'{k} of the'} {len(top)} fail the {t} test" for t, k in parts if k]
    if not failing:
        return f"All {len(top)} pass the residual tests at the {TEST_LEVEL:.0%} level."
    return (f"Residual tests at the {TEST_LEVEL:.0%} level: " + " and ".join(failing) + ": the FIT ranks the "
            "predictions, not whether a model has caught the data's structure (§8).")


def final_orders_text(ranking) -> str:
    """How many of the top four are at the order the orders rule chose for their structure, and the best-ranked run
    that is."""
    top, table = ranking.top, ranking.table
    k = int(top["final_order"].sum())
    if k == len(top):
        return f"All {len(top)} are at the order the orders rule chose for their structure (§5)."
    first = table[table["final_order"].astype(bool)].iloc[0]
    return (f"{k} of the top {len(top)} are at the order the orders rule chose for their structure (§5); the other "
            f"{len(top) - k} are at orders it does not choose: ranked here, not recommended (§9). The best-ranked model "
            f"at a chosen order is #{int(first['rank'])} {first['name']} (FIT {num(first['val_fit'])} %).")


def binary_vs_uniform(ranking, lab: dict) -> str:
    """§3.4/§3.7: one structure's binary- and uniform-input models on common validation data, discussed."""
    from maglev.study.report.verdicts import class_comparison

    title = "7. Binary vs uniform input"
    if ranking.comparison is None:
        return section("binary-vs-uniform", title, para(esc("; ".join(ranking.notes))))
    comp, st = ranking.comparison, ranking.structure
    parts = [para(f"Structure <b>{esc(st.upper())}</b> (the best-fitting structure with models of both input "
                  "classes). Each record is represented by its model at the order the orders rule chose (§5) with the "
                  "highest FIT on its own validation data, and every model is evaluated on every record's validation "
                  "data (rows: estimated on, columns: validated on; one-step FIT %):")]
    if ranking.common is None:
        parts.append(para(esc("; ".join(ranking.notes) or "no common validation data")))
        return section("binary-vs-uniform", title, *parts)
    u_star = lab.get("lab.u_star")
    width = lab.get("lab.u_max", math.nan) - lab.get("lab.u_min", math.nan)
    cc = class_comparison(comp, ranking.common, u_star, width if math.isfinite(width) else None)
    matrix = cc.matrix.copy()
    matrix.index = [f"{d} ({cc.classes[d]}): {cc.models[d]}" for d in matrix.index]
    parts.append(table(matrix.reset_index(names="estimated on → validated on")))
    parts.append(para(f"<b>Which one is higher?</b> {esc(cc.sentences[0])}"))
    parts.append(bullets(esc(x) for x in cc.sentences[1:]))
    parts.append(img(ranking.files.get("binary_vs_uniform/fit.png"),
                     f"{st.upper()}: one-step FIT (%) of each model on its own validation data (left; binary hatched, "
                     "axis from 0) and of every compared model on every validation set (right).", "full"))
    return section("binary-vs-uniform", title, *parts)


def reference_response(cfg: dict, prep):
    """What a linear model of this record should be: the simulator's BLA for a simulated record's input class,
    the record's own spectral estimate (Welch; the BLA as the record shows it) for a real one."""
    from maglev.spectral import frequency_response
    from maglev.study.datasets import dataset_bla

    return dataset_bla(cfg["dataset"]) if cfg["dataset"]["source"] == "sim" else frequency_response(prep.data)


def peak_frequency(ref) -> float | None:
    """The BLA's resonance frequency (rad/s) where |G| rises significantly above its low-frequency value."""
    if ref is None or not resonance_rise(ref):
        return None
    keep = ref.w > 0
    return float(ref.w[keep][int(np.argmax(np.abs(ref.G[keep])))])


def best_vs_worst(ranking, models_all: dict, lab: dict, physics_modes: list | None = None,
                  references: dict | None = None) -> str:
    """§3.7: the best and worst model compared with Bode diagrams, pole-zero maps and residual tests, and which
    differences explain the ranking (:func:`maglev.study.report.verdicts.best_vs_worst`).  ``references``:
    validation dataset -> its BLA (or the record's spectral estimate)."""
    from maglev.study.report import verdicts as v

    b, w = ranking.best, ranking.worst
    explained = v.explained_by_dataset(ranking.table)
    fb = v.model_facts(b, ranking.resids[b["run_id"]], models_all[b["run_id"]], explained.get(b["val_dataset"],
                                                                                              math.nan))
    fw = v.model_facts(w, ranking.resids[w["run_id"]], models_all[w["run_id"]], explained.get(w["val_dataset"],
                                                                                              math.nan))
    slope = lab.get("lab.slope")
    bw = v.best_vs_worst(fb, fw, slope)
    refs = references or {}
    question = v.extremes_text(b, w, v.conclusion(ranking.table, slope, ranking.orders), ranking.orders)
    head = (f"{esc(question)} Best <b>{esc(b['name'])}</b> (rank 1, FIT {num(b['val_fit'])} % on "
            f"{esc(validation_data(b['val_dataset']))}); worst <b>{esc(w['name'])}</b> (rank {int(w['rank'])}, FIT "
            f"{num(w['val_fit'])} % on {esc(validation_data(w['val_dataset']))}).")
    tally = bw.tally
    better = fb if bw.better == "best" else fw
    verdict = (f"<b>Why one is better:</b> of the checks below, {tally['best']} favour the best model by one-step "
               f"FIT and {tally['worst']} the worst, so <b>{esc(better.name)}</b> is the better model of the plant"
               + (" — the one-step ranking's order stands." if bw.better == "best" else
                  " — the reverse of the one-step ranking: the best's one-step FIT comes from its noise model's use "
                  "of past outputs, not from G."))
    pz = [v.pole_zero_text(f, physics_modes, peak_frequency(refs.get(f.val_dataset))) for f in (fb, fw)]
    figs = ("<div class='row'>" + img(ranking.files.get("best_vs_worst/bode.png"),
                                      "Bode diagrams of G of the best and worst model; shaded bands: 99 % confidence "
                                      "regions from the estimated parameter covariance.", "half")
            + img(ranking.files.get("best_vs_worst/pzmap.png"), "Poles (x) and zeros (o) of G of the best and worst "
                  "model, with the unit circle; shaded regions: 99 % confidence regions of each root.", "half")
            + "</div>"
            + img(ranking.files.get("best_vs_worst/resid.png"), "Residual analysis (resid) of the best (left) and worst "
                  "(right): autocorrelation of the residuals (top) and their cross-correlation with the input "
                  "(bottom); shaded bands: the 99 % confidence band of white, input-independent residuals.", "wide"))
    return section("best-vs-worst", "8. Best vs worst model", para(head), para(verdict),
                   bullets(esc(s) for _, _, s in bw.checks), para("Pole-zero analysis: " + esc(" ".join(pz))), figs)


def conclusion(ranking, lab: dict) -> str:
    """The model to use for what (simulation or one-step prediction) and why."""
    from maglev.study.report.verdicts import conclusion as decide

    c = decide(ranking.table, lab.get("lab.slope"), ranking.orders)
    n = len(ranking.cautions)
    tail = (f"{n} caution(s) drawn from the numbers qualify the ranking (Appendix B)." if n else
            "No caution applies to the ranking (Appendix B).")
    return section("conclusion", "9. Conclusion", bullets(esc(s) for s in c.sentences), para(esc(tail)))


def cautions(items: list) -> str:
    """What the numbers undermine (:mod:`maglev.study.cautions`): the ranking's fine print."""
    if not items:
        return section("cautions", "B. Cautions", para("No caution applies: the top model passes its residual "
                                                      "tests, beats y(t−1) and simulates about as well as it "
                                                      "predicts; no structure's best order is at the edge of the "
                                                      "swept grid."))
    return section("cautions", f"B. Cautions ({len(items)})",
                   para("Each is computed from the runs' numbers; read the ranking with them in mind."),
                   bullets(esc(c.text) for c in items))


def all_runs(ranking, models: dict, tol: float = CANCEL_TOL) -> str:
    """Appendix C: every ranked run, and every run's near cancellations."""
    cols = ["rank", "name", "structure", "orders", "dataset", "val_fit", "val_fit_naive", "val_fit_sim", "n_params",
            "aic", "final_order", "val_dataset"]
    flagged = [f"{esc(r['name'])}: {w} pole {cz(p)} vs zero {cz(z)} (|p−z| = {num(d, 3)})"
               for _, r in ranking.table.iterrows() for w, p, z, d in models[r["run_id"]].near_cancellations(tol)]
    return section("all-runs", "C. Every run", table(ranking.table[[c for c in cols if c in ranking.table]]),
                   para(f"Near pole-zero cancellations (|p−z| &lt; {tol}):") + bullets(flagged) if flagged else "")


def extra_figures(figures: list[tuple[bytes | None, str]]) -> str:
    """Appendix D: the figures the main text refers to but has no room for."""
    return section("extra-figures", "D. Further figures", *(img(data, caption, "half") for data, caption in figures))


def resonance_rise(b) -> bool:
    """Whether a BLA's |G| rises above its value at the lowest frequency > 0 by more than two standard errors of
    the difference (each magnitude's is std/√2): a peak within the estimate's scatter is no resonance (uniform_wide's
    BLA from 8 s segments peaks 0.2 dB above its 0.8 rad/s value, each with a standard error of 0.18 dB)."""
    keep = b.w > 0
    mag, sd = np.abs(b.G[keep]), b.std[keep] / np.sqrt(2)
    peak = int(np.argmax(mag))
    return bool(peak) and mag[peak] - mag[0] > 2 * np.hypot(sd[peak], sd[0])




def preparation(p, lin, noise, lab: dict, table_: pd.DataFrame) -> str:
    """§4: the physical model derived (:func:`maglev.study.report.preparation.derivation`), its linearisation at u*,
    the structure and noise model it suggests against what the sweep found, and similar set-ups; the code of
    getAverage and getStationaryAverages is attached in Appendix A.  ``p``: the rig's LevitatorParams; ``lin``:
    the first-principles linearisation (None without a working point); ``noise``: the staircase's noise facts."""
    from maglev.study.report.preparation import derivation

    title = "1. Preparation tasks"
    if lin is None:
        return section("preparation", title, para("No working point: the sweep's lab steps were not logged."))
    d = derivation(p, lin, noise, int(lab["lab.nk"]) if "lab.nk" in lab else None)
    sim = table_.groupby("structure")["val_fit_sim"].mean().sort_values(ascending=False)
    found = ("In the sweep, mean simulation FIT by structure: " + ", ".join(f"{s.upper()} {num(f)} %"
                                                                          for s, f in sim.items()) + ".")
    return section("preparation", title,
                   "<h3>State-space model (task 1)</h3>", bullets(esc(t) for t in d["model"]),
                   "<h3>Is the model linear?</h3>", para(esc(" ".join(d["nonlinear"]))),
                   "<h3>Linearisation at the working point</h3>", para(esc(" ".join(d["linear"]))),
                   "<h3>Does it suggest a model structure?</h3>", para(esc(" ".join(d["structure"]) + " " + found)),
                   "<h3>Similar physical set-ups</h3>", para(esc(" ".join(d["similar"]))),
                   para("Tasks 2–3, getAverage and getStationaryAverages: the code is attached in Appendix A and is what "
                        "§2's working region is computed with."))


def attached_code() -> str:
    """Appendix A: the code of the lab's getAverage and getStationaryAverages (maglev/lab/averages.py)."""
    import inspect

    from maglev.lab import averages

    code = "".join(f"<pre><code>{esc(inspect.getsource(f))}</code></pre>"
                   for f in (averages.get_average, averages.get_stationary_averages))
    return section("code", "A. Attached code: getAverage and getStationaryAverages",
                   para("maglev/lab/averages.py (Python; the lab's getAverage and getStationaryAverages):"), code)
