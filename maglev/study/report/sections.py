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

from maglev.model import CANCEL_TOL, PolyModel
from maglev.plots import U_UNIT, Y_UNIT
from maglev.structures import get as get_structure
from maglev.study.cautions import ORDER_MARGIN, away_from_bla, order_choice
from maglev.study.figures import orders_figure, png
from maglev.study.ranking import validation_note
from maglev.validation import format_p

MIN_EST_S, MIN_VAL_S = 10.0, 7.0  # the lab's minimum estimation / validation lengths (§3.4)


# ---------------------------------------------------------------------------- HTML helpers
def esc(x) -> str:
    return html.escape(str(x))


def num(x, digits: int = 2) -> str:
    if x is None or (isinstance(x, float) and math.isnan(x)):
        return "–"
    if isinstance(x, (int, np.integer)):
        return str(int(x))
    x = float(x)
    return f"{x:.{digits}f}" if 1e-3 <= abs(x) < 1e6 or x == 0 else f"{x:.3g}"


def img(data: bytes | None, alt: str) -> str:
    if not data:
        return f"<p class='missing'>(figure {esc(alt)} not available)</p>"
    b64 = base64.b64encode(data).decode()
    return (f"<figure><img alt='{esc(alt)}' src='data:image/png;base64,{b64}'>"
            f"<figcaption>{esc(alt)}</figcaption></figure>")


def table(df: pd.DataFrame, digits: int = 2) -> str:
    return df.to_html(index=False, escape=True, na_rep="–", border=0, classes="t",
                      float_format=lambda v: num(v, digits))


def section(anchor: str, title: str, *parts: str) -> str:
    return f"<section id='{anchor}'><h2>{esc(title)}</h2>\n" + "\n".join(parts) + "</section>\n"


def para(text: str) -> str:
    return f"<p>{text}</p>"


def bullets(items: Iterable[str]) -> str:
    return "<ul>" + "".join(f"<li>{i}</li>" for i in items) + "</ul>"


# ---------------------------------------------------------------------------- analysis helpers
def cz(z: complex) -> str:
    return f"{z.real:.3f}{z.imag:+.3f}j" if abs(z.imag) > 1e-9 else f"{z.real:.3f}"


# ---------------------------------------------------------------------------- sections
def cautions(items: list) -> str:
    """What the numbers below undermine (:mod:`maglev.study.cautions`), first, so nobody reads the ranking without it."""
    if not items:
        return section("cautions", "Cautions", para("No caution applies: the top model passes its residual tests, "
                                                    "beats y(t−1) and simulates about as well as it predicts; no "
                                                    "structure's best order is at the edge of the swept grid."))
    return section("cautions", f"Cautions ({len(items)})",
                   para("Each is computed from the runs' numbers; read the ranking with them in mind."),
                   bullets(esc(c.text) for c in items))


def working_region(lab: dict, lab_png: dict, ts_used: list[float]) -> str:
    if "lab.u_min" not in lab:
        return section("working-region", "1. Working region and sampling period",
                       para("The sweep's parent run has no lab-level steps (lab.enabled=false or they failed)."))
    g = lab.get
    facts = [
        f"Staircase of the input within the plant's [0, 10] A ({esc(lab.get('staircase', 'staircase'))}): the "
        f"widest range of levels where the stationary averages ȳ vs ū stay on a straight line (every point "
        f"within 5 % of the ȳ range from the least-squares line, every neighbour-to-neighbour slope within "
        f"0.5–1.5 times its slope) is <b>ū ∈ [{num(g('lab.u_min'))}, {num(g('lab.u_max'))}] A</b>: "
        "the working region.",
        f"Least-squares slope in the region: {num(g('lab.slope'), 4)} {Y_UNIT}/{U_UNIT}; "
        f"working point u* = (u_min + u_max)/2 = <b>{num(g('lab.u_star'))} A</b>.",
        f"10–90 % rise time of steps inside the region: {num(g('lab.rise_time_samples'), 1)} samples = "
        f"{num(1000 * g('lab.rise_time_s'), 1)} ms, so 4–10 samples per rise time means "
        f"Ts ∈ [{num(1000 * g('lab.Ts_min'), 2)}, {num(1000 * g('lab.Ts_max'), 2)}] ms; decimation by "
        f"{int(g('lab.decimation'))} (suggested).",
        "Sampling period used by the models: " + ", ".join(f"{num(1000 * t, 2)} ms" for t in ts_used) + ".",
    ]
    return section("working-region", "1. Working region and sampling period", bullets(facts),
                   "<div class='row'>" + img(lab_png.get("working_region.png"), "working region: ȳ vs ū")
                   + img(lab_png.get("rise_time.png"), "averaged step response and rise time") + "</div>")


def input_signals(datasets: dict, configs: dict, lab: dict, lab_png: dict) -> str:
    """``datasets``: name -> Prepared; ``configs``: name -> run config."""
    u_lo, u_hi = lab.get("lab.u_min", math.nan), lab.get("lab.u_max", math.nan)
    alpha_star = lab.get("lab.alpha_star", math.nan)
    rows, why = [], []
    for name, prep in datasets.items():
        ds = configs[name]["dataset"]
        trim = int(ds["preprocess"]["trim"])
        u = prep.raw.u[trim:]
        lo, hi = float(np.min(u)), float(np.max(u))
        inside = lo >= u_lo - 1e-9 and hi <= u_hi + 1e-9
        cover = (hi - lo) / (u_hi - u_lo) if u_hi > u_lo else math.nan
        alpha = ds.get("alpha") if ds["input_class"] == "binary" else None
        rows.append({"dataset": name, "class": ds["input_class"], "source": ds["source"], "u min (A)": lo,
                     "u max (A)": hi, "mean u (A)": prep.u0, "std u (A)": float(np.std(u)),
                     "inside working region": "yes" if inside else "NO", "share of region width": cover,
                     "α": alpha})
        text = (f"<b>{esc(name)}</b> ({esc(ds['input_class'])}): range [{num(lo)}, {num(hi)}] A, "
                f"{num(100 * cover, 0)} % of the working region's width, mean {num(prep.u0)} A vs u* = "
                f"{num(lab.get('lab.u_star'))} A; " + ("stays inside the working region" if inside else
                                                    "<b>leaves the working region</b>"))
        if alpha is not None:
            text += (f"; switching probability α = {num(alpha)}" +
                     (" = α*, the value matching the output's energy band" if math.isclose(alpha, alpha_star)
                      else f" (α* = {num(alpha_star)})"))
        why.append(text + ".")
    shares = lab.get("alpha_shares", {})
    spectrum = []
    if "lab.band_low" in lab:
        spectrum.append(
            f"The output spectrum |FFT(y − ȳ)| of {esc(lab.get('spectrum_dataset', 'the base dataset'))} holds 80 % "
            f"of its energy in ω ∈ [{num(lab['lab.band_low'], 3)}, {num(lab['lab.band_high'], 3)}] rad/sample "
            f"([{num(lab['lab.band_low'] / math.pi, 3)}, {num(lab['lab.band_high'] / math.pi, 3)}]·π). Share of the "
            "binary signal's power in that band for each α: "
            + ", ".join(f"α = {a}: {num(100 * s, 1)} %" for a, s in shares.items())
            + f"; the largest share gives <b>α* = {num(alpha_star)}</b>.")
    return section("inputs", "2. Input signals", bullets(why), table(pd.DataFrame(rows)),
                   bullets(spectrum) if spectrum else "",
                   "<div class='row'>" + img(lab_png.get("output_spectrum.png"), "output spectrum and energy band")
                   + img(lab_png.get("alpha.png"), "binary-signal spectra for the lab's α values") + "</div>")


def data_amounts(table_: pd.DataFrame, datasets: dict, configs: dict) -> str:
    rows = []
    for name, prep in datasets.items():
        pp = configs[name]["dataset"]["preprocess"]
        est_s, val_s = prep.est.N * prep.est.Ts, prep.val.N * prep.val.Ts
        ok = est_s >= MIN_EST_S and val_s >= MIN_VAL_S
        rows.append({"dataset": name, "record (samples)": prep.raw.N, "raw Ts (ms)": 1000 * prep.raw.Ts,
                     "trimmed": int(pp["trim"]), "decimation": int(pp["decimate"]), "Ts (ms)": 1000 * prep.data.Ts,
                     "estimation": f"{prep.est.N} samples = {num(est_s)} s",
                     "validation": f"{prep.val.N} samples = {num(val_s)} s ({esc(prep.val_name)})",
                     "lab minimum (10 s / 7 s)": "met" if ok else "NOT met"})
    per_model = table_[["rank", "name", "n_est", "n_val", "val_dataset"]].copy()
    per_model["n_est"] = per_model["n_est"].astype("Int64")
    per_model["n_val"] = per_model["n_val"].astype("Int64")
    text = para("Each record: the start-up transient is trimmed, means removed, decimated to Ts, then split "
                "— the first part estimates, the rest (never seen by the estimator) validates. Every model "
                "is validated on the validation part of its own dataset (column val_dataset). Units: u is the "
                f"coil current command in {U_UNIT}, y the upper magnet's height in {Y_UNIT} (the rig's laser sensor "
                f"after its two-point calibration); gains are in {Y_UNIT}/{U_UNIT}.")
    return section("data", "3. Data for estimation and validation", text, table(pd.DataFrame(rows)),
                   "<details><summary>Per model</summary>" + table(per_model) + "</details>")


def delay_evidence(models: Sequence[PolyModel], delayest_nk: int | None = None) -> str:
    """Whether the identified models support their delay: how many have a first B coefficient b_nk more than
    two standard errors from zero (a response already at lag nk), against ``delayest``'s nk when given."""
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
        text += (f"most models find no response at lag {shown}, so the swept delay is too small for the data"
                 + (f" (delayest: nk = {delayest_nk})." if delayest_nk is not None else "."))
    return text


def order_sentence(oc: dict) -> str:
    """The report's sentence on a structure's order (:func:`maglev.study.cautions.order_choice`): the mean
    simulation FIT by order, the order the rule chooses, the orders that do not count because their models move
    away from the best linear approximation, and where the choice lies in the swept grid."""
    from maglev.lab.orders import away_from_bla as moving_away

    grid, chosen, bla = oc["grid"], oc["chosen"], oc["bla"]
    away = sorted(moving_away(bla, grid))
    listed = ", ".join(f"{o}: {num(f)} %" for o, f in oc["fit"].items())
    among = ""
    if away:
        among = (" among the orders whose models do not move away from the best linear approximation (order(s) "
                 f"{', '.join(map(str, away))} do: mean distance " + ", ".join(f"{o}: {num(bla[o], 3)}" for o in grid
                                                                              if o in bla) + ")")
    if oc["edge"]:
        where = f", at the {oc['edge']} edge of the swept orders: add order {oc['suggest']}."
    elif chosen == grid[0]:
        counted = [o for o in grid if o > chosen and o not in away]
        where = (", the smallest swept" + (f": the higher orders{' that count' if away else ''} add at most "
                                           f"{ORDER_MARGIN:g} point" if counted else "")
                 + " (no smaller order was swept).")
    else:
        where = ", inside the swept orders."
    return (f"Mean simulation FIT by order ({listed}): the smallest order within {ORDER_MARGIN:g} point of the best"
            f"{among} is <b>{chosen}</b>{where}")



def structures(table_: pd.DataFrame, models: dict, lab: dict, lab_png: dict, tol: float = CANCEL_TOL) -> str:
    """``models``: run id -> PolyModel for every ranked run; ``lab``: the sweep's lab steps (order selection)."""
    parts = []
    if "lab.arx_na" in lab:
        parts.append(para(
            f"Before fitting: on {esc(lab.get('spectrum_dataset', 'the base dataset'))}, delayest (ARX [2 2 nk]) "
            f"gives the delay nk = {int(lab['lab.nk'])} samples, and ARX order selection (arxstruc over na, nb "
            f"in 1…{int(lab['lab.max_order'])}, selstruc) picks "
            f"na = {int(lab['lab.arx_na'])}, nb = {int(lab['lab.arx_nb'])} by AIC and na = "
            f"{int(lab['lab.arx_na_mdl'])}, nb = {int(lab['lab.arx_nb_mdl'])} by MDL.")
            + img(lab_png.get("orders.png"), "ARX order selection (selstruc)"))
    delay = delay_evidence([models[i] for i in table_["run_id"]], int(lab["lab.nk"]) if "lab.nk" in lab else None)
    if delay:
        parts.append(para(delay))
    for st in dict.fromkeys(table_["structure"]):
        runs = table_[table_["structure"] == st]
        rows, flagged = [], []
        for _, r in runs.sort_values(["dataset", "n_params"]).iterrows():
            cancel = models[r["run_id"]].near_cancellations(tol)
            rows.append({"dataset": r["dataset"], "orders": r["orders"], "n_params": r["n_params"],
                         "loss": r.get("loss"), "FPE": r.get("fpe"), "AIC": r.get("aic"), "val FIT %": r["val_fit"],
                         "near cancellations": len(cancel)})
            flagged += [f"{esc(r['name'])}: {w} pole {cz(p)} vs zero {cz(z)} (|p−z| = {num(d, 3)})"
                        for w, p, z, d in cancel]
        by_order = runs.groupby("orders").agg(aic=("aic", "mean"), fit=("val_fit", "mean"),
                                              n=("n_params", "first"))
        best_aic, best_fit = by_order["aic"].idxmin(), by_order["fit"].idxmax()
        n_cancel = {o: sum(len(models[i].near_cancellations(tol)) for i in runs.loc[runs["orders"] == o, "run_id"])
                    for o in by_order.index}
        choice = (f"Orders tried: {', '.join(esc(o) for o in by_order.index)}. Mean AIC over the datasets is "
                  f"lowest for <b>{esc(best_aic)}</b> ({num(by_order.loc[best_aic, 'aic'])}) and mean validation "
                  f"FIT highest for <b>{esc(best_fit)}</b> ({num(by_order.loc[best_fit, 'fit'])} %); near pole-zero "
                  "cancellations per order: " + ", ".join(f"{esc(o)}: {n}" for o, n in n_cancel.items()) + ". ")
        if best_aic == best_fit:
            choice += "Both criteria pick the same orders."
        else:
            choice += (f"The criteria disagree: {esc(best_fit)} validates "
                       f"{num(by_order.loc[best_fit, 'fit'] - by_order.loc[best_aic, 'fit'])} FIT points "
                       f"{'better' if by_order.loc[best_fit, 'fit'] >= by_order.loc[best_aic, 'fit'] else 'worse'} "
                       f"than {esc(best_aic)}, which has the lower AIC.")
        oc = order_choice(runs)
        if oc is not None:
            choice += " " + order_sentence(oc)
            undermined = away_from_bla(oc)
            if undermined:
                choice += " " + esc(undermined)
        if flagged:
            choice += " Near cancellations mean the order is higher than the data support."
        entry = get_structure(st)
        parts.append(f"<h3>{esc(st.upper())}</h3>" + para(f"{esc(st.upper())} {esc(entry.equation)}: "
                                                          f"{esc(entry.description)}") + para(choice)
                     + table(pd.DataFrame(rows), 4)
                     + (f"<details><summary>{len(flagged)} near cancellation(s), |p−z| &lt; {tol}</summary>"
                        + bullets(flagged) + "</details>" if flagged else ""))
    intro = para(f"Each structure was fitted at every order of the sweep; the order is motivated by the "
                 f"estimation loss, FPE and AIC against the number of parameters, the validation FIT, and "
                 f"pole-zero pairs closer than {tol} in the z-plane (a cancellation: a superfluous order).")
    return section("structures", "4. Model structures and orders", intro, *parts,
                   img(png(orders_figure(table_)), "loss, AIC and validation FIT against the number of parameters"))


def top_four(ranking) -> str:
    cols = ["rank", "name", "structure", "orders", "dataset", "val_fit", "val_fit_naive", "val_fit_sim", "n_params",
            "val_dataset"]
    note = validation_note(ranking.top)
    text = para(f"{len(ranking.table)} FINISHED models ranked by one-step-ahead FIT on validation data "
                "(ties to fewer parameters)"
                + (", ignored: " + ", ".join(f"{n} {s}" for s, n in sorted(ranking.sweep.ignored.items()))
                   if ranking.sweep.ignored else "") + ". Beside each: the naive predictor ŷ(t) = y(t−1) on the "
                "same data (val_fit_naive; a model must beat it to add anything) and the simulation FIT "
                "(val_fit_sim; how well G alone reproduces the output).")
    lines = [f"#{int(r['rank'])} <b>{esc(r['name'])}</b>: FIT {num(r['val_fit'])} % on {esc(r['val_dataset'])} "
             f"(y(t−1): {num(r['val_fit_naive'])} %, simulation: {num(r['val_fit_sim'])} %), "
             f"{r['n_params']} parameters" for _, r in ranking.top.iterrows()]
    return section("top4", "5. Top four models", text, bullets(lines),
                   para(f"<b>Note:</b> the top four were {esc(note)}.") if note else "",
                   table(ranking.top[cols]),
                   "<details><summary>All ranked models</summary>" + table(ranking.table[cols]) + "</details>")


def binary_vs_uniform(ranking) -> str:
    if ranking.comparison is None:
        return section("binary-vs-uniform", "6. Binary vs uniform input", para(esc("; ".join(ranking.notes))))
    comp, st = ranking.comparison, ranking.structure
    best = comp.loc[comp.groupby("input_class")["val_fit"].idxmax()].set_index("input_class")
    lines = [f"Structure <b>{esc(st)}</b> (the best-fitting structure with both input classes, or --structure). "
             f"Best binary-input model {esc(best.loc['binary', 'name'])}: FIT {num(best.loc['binary', 'val_fit'])} % "
             f"on {esc(best.loc['binary', 'val_dataset'])}; best uniform-input model "
             f"{esc(best.loc['uniform', 'name'])}: {num(best.loc['uniform', 'val_fit'])} % on "
             f"{esc(best.loc['uniform', 'val_dataset'])}."]
    note = validation_note(comp)
    if note:
        lines.append(f"These FITs were {esc(note)} — so the same models are also evaluated on every validation set:")
    parts = [bullets(lines), table(comp[["rank", "name", "input_class", "orders", "val_fit", "val_fit_sim",
                                         "n_params", "val_dataset"]])]
    if ranking.common is not None:
        common = ranking.common
        cls = dict(zip(comp["name"], comp["input_class"]))
        wins = []
        for col in common.columns:
            c = common[col].dropna()
            if c.empty:
                continue
            winner = c.idxmax()
            wins.append(f"on {esc(col)} the best is {esc(winner)} ({esc(cls[winner])}, {num(c.max())} %); best "
                        f"binary {num(c[[n for n in c.index if cls[n] == 'binary']].max())} % vs best uniform "
                        f"{num(c[[n for n in c.index if cls[n] == 'uniform']].max())} %")
        parts += [table(common.reset_index(names="model")), bullets(wins)]
    elif ranking.notes:
        parts.append(para(esc("; ".join(ranking.notes))))
    parts.append(img(ranking.files.get("binary_vs_uniform/fit.png"), f"{st}: FIT by input class"))
    return section("binary-vs-uniform", f"6. Binary vs uniform input ({st})", *parts)


def test_comparison(test: str, best_passes: bool, worst_passes: bool, p_best: float, p_worst: float,
                    failing_means: str) -> str:
    """One sentence comparing the best and worst model on one residual test, from the two outcomes."""
    ps = f"p = {format_p(p_best)} for the best, {format_p(p_worst)} for the worst"
    if best_passes and worst_passes:
        return f"Both pass the {test} test ({ps})."
    if not best_passes and not worst_passes:
        return f"Both fail the {test} test ({ps}): {failing_means}, in both."
    if best_passes:
        return f"Only the best passes the {test} test ({ps}); the worst has {failing_means}."
    return (f"The worst passes the {test} test and the best fails it ({ps}): the best has {failing_means}, so "
            "its higher one-step FIT does not make it the better model on this test.")


def best_vs_worst(ranking, models_all: dict, tol: float = CANCEL_TOL) -> str:
    b, w = ranking.best, ranking.worst
    rb, rw = ranking.resids[b["run_id"]], ranking.resids[w["run_id"]]
    keys = [("val_fit", "validation FIT % (one step)"), ("val_fit_sim", "validation FIT % (simulation)"),
            ("n_params", "parameters"), ("whiteness_pvalue", "whiteness p-value"),
            ("independence_pvalue", "independence p-value"), ("resid_auto_outside", "autocorr. lags outside 99 %"),
            ("resid_cross_outside", "cross-corr. lags outside 99 %"), ("max_pole_radius", "largest |pole|"),
            ("dcgain", "static gain"), ("g_h2_rel_err", "‖G − G_lin‖ / ‖G_lin‖ (small-signal Jacobian)")]
    rows = [{"quantity": label, "best": num(b.get(k), 3), "worst": num(w.get(k), 3)} for k, label in keys
            if k in b.index]
    cb, cw = models_all[b["run_id"]].near_cancellations(tol), models_all[w["run_id"]].near_cancellations(tol)
    rows.append({"quantity": f"near cancellations (|p−z| < {tol})", "best": len(cb), "worst": len(cw)})
    findings = [f"Best <b>{esc(b['name'])}</b> (rank 1, FIT {num(b['val_fit'])} % on {esc(b['val_dataset'])}); "
                f"worst <b>{esc(w['name'])}</b> (rank {int(w['rank'])}, FIT {num(w['val_fit'])} % on "
                f"{esc(w['val_dataset'])})."]
    for who, r, res in (("best", b, rb), ("worst", w, rw)):
        findings.append(
            f"Residuals of the {who}: {'white' if res.white else 'not white'} (p = {format_p(res.whiteness_pvalue)}, "
            f"{num(100 * res.auto_outside, 0)} % of autocorrelation lags outside the band), "
            f"{'independent of' if res.independent else 'correlated with'} the input "
            f"(p = {format_p(res.independence_pvalue)}, {num(100 * res.cross_outside, 0)} % of lags outside).")
    findings += [test_comparison("whiteness", rb.white, rw.white, rb.whiteness_pvalue, rw.whiteness_pvalue,
                                 "residuals correlated in time: the noise model misses structure in the output"),
                 test_comparison("independence", rb.independent, rw.independent, rb.independence_pvalue,
                                 rw.independence_pvalue, "residuals correlated with the input: G misses dynamics "
                                 "or the delay")]
    findings.append(f"Largest pole radius: best {num(b.get('max_pole_radius'), 3)}, worst "
                    f"{num(w.get('max_pole_radius'), 3)}; static gain best {num(b.get('dcgain'), 3)}, worst "
                    f"{num(w.get('dcgain'), 3)}.")
    return section("best-vs-worst", "7. Best vs worst model", bullets(findings), table(pd.DataFrame(rows), 3),
                   "<div class='row'>" + img(ranking.files.get("best_vs_worst/bode.png"), "Bode diagrams of G")
                   + img(ranking.files.get("best_vs_worst/pzmap.png"), "pole-zero maps of G") + "</div>",
                   img(ranking.files.get("best_vs_worst/resid.png"),
                       "residual correlations, best (left) and worst (right)"))


def resonance_rise(b) -> bool:
    """Whether a BLA's |G| rises above its value at the lowest frequency > 0 by more than two standard errors of
    the difference (each magnitude's is std/√2): a peak within the estimate's scatter is no resonance (uniform_wide's
    BLA from 8 s segments peaks 0.2 dB above its 0.8 rad/s value, each with a standard error of 0.18 dB)."""
    keep = b.w > 0
    mag, sd = np.abs(b.G[keep]), b.std[keep] / np.sqrt(2)
    peak = int(np.argmax(mag))
    return bool(peak) and mag[peak] - mag[0] > 2 * np.hypot(sd[peak], sd[0])


def _friction_text(p) -> str:
    """The friction law F_f of the parameter set ``p`` (maglev.sim.plant.LevitatorParams), with its numbers."""
    parts = [f"viscous {num(p.gamma_upper, 3)} N s/m on the upper magnet in motion"]
    if p.gamma_quiet_upper > 0:
        parts.append(f"up to {num(p.gamma_quiet_upper, 3)} N s/m more while the input is quiet for its class")
    if p.gamma_aged_upper > 0:
        parts.append(f"up to {num(p.gamma_aged_upper, 3)} N s/m more on a contact that has rested")
    if p.coulomb_upper + p.stiction_upper > 0:
        dry = f"Coulomb {num(p.coulomb_upper, 4)} N"
        if p.stiction_upper > 0:
            dry += f" + Stribeck {num(p.stiction_upper, 4)} N"
        parts.append(dry + (" dry friction, set-valued (the magnet sticks)" if p.sticks else " dry friction"))
    return "friction F_f: " + ", ".join(parts)


def preparation(lab: dict, ts_used: list[float], configs: dict, table_: pd.DataFrame) -> str:
    """The lab's preparation tasks (§4): the physical model, why it is nonlinear, its linearisation at the
    sweep's working point beside the best linear approximations, the structure it suggests against what
    identification found, and the code of ``get_average`` / ``get_stationary_averages``."""
    import inspect

    import control as ct

    from maglev.lab import averages
    from maglev.sim.plant import DEFAULT_PLANT, rig
    from maglev.study.datasets import dataset_bla, plant_name
    from maglev.study.figures import preparation_figure

    plants = sorted({plant_name(c["dataset"]) for c in configs.values() if c["dataset"]["source"] == "sim"})
    lev = rig(plants[0] if plants else DEFAULT_PLANT)
    p = lev.params
    u_star = lab.get("lab.u_star")
    Ts = ts_used[0] if ts_used else 0.001
    model = [
        "Two magnets on a glass rod, lower height z and upper height h (cm), mass m = "
        f"{num(p.m, 3)} kg each; the coil current I acts on both. With the state x = (z, h, ż, ḣ):",
        "m z̈ = I / (a (z + b)^n) − c / (h − z + d)^4 − m g − F_f(ż)   (coil push, repulsion, gravity, bushing friction)",
        "m ḧ = −κ I / (a (h + b)^n) + c / (h − z + d)^4 − m g − F_f(ḣ)   (coil pull, repulsion, gravity, friction)",
        ("y = y_off + h" + (f" + max(h − h_k, 0)² / (D − h) (the laser's scale stretches above h_k = "
                            f"{num(p.sensor_knee, 3)} cm, towards D = {num(p.sensor_pole, 3)} cm)" if p.sensor_pole else "")
         + " (+ sensor noise, ADC quantisation); I = min(u, i_sat) (current regulator)."),
        f"Fitted to the rig (maglev calibrate): a = {num(p.a, 4)}, b = {num(p.b, 3)} cm, n = {num(p.n_coil, 3)}, "
        f"κ = {num(p.kappa, 3)}, c = {num(p.c, 0)} N cm⁴, d = {num(p.d, 3)} cm, i_sat = {num(p.i_sat, 3)} A, "
        f"y_off = {num(p.y_off, 3)} cm; {_friction_text(p)} (docs/simulator.md; simulator parameter set "
        f"{', '.join(plants) or DEFAULT_PLANT}).",
    ]
    causes = [f"the coil and repulsion forces fall off with a power of distance (n = {num(p.n_coil, 3)} and 4)",
              "the bushings' friction holds small motions and releases large ones (the response depends on the "
              "input's amplitude and class)", "the lower magnet rests on its seat below lift-off",
              "the upper one hits a stop", f"the regulator saturates at {num(p.i_sat, 3)} A"]
    if p.sensor_pole:
        causes.append(f"the sensor's scale stretches above {num(p.sensor_knee, 3)} cm")
    nonlinear = f"It is nonlinear because {', '.join(causes[:-1])}, and {causes[-1]}."
    parts = [bullets(esc(t) for t in model), para(esc(nonlinear))]
    if u_star is None:
        return section("preparation", "Preparation tasks", *parts,
                       para("No working point: the sweep's lab steps were not logged."))
    lin = lev.linearize(float(u_star), Ts=Ts)
    eq = lin.equilibrium
    modes = "; ".join(f"ωn = {num(w, 1)} rad/s, ζ = {num(z, 3)}" for w, z in lin.modes())
    poles = ", ".join(cz(complex(x)) for x in ct.poles(lin.sys_d))
    zeros = ", ".join(cz(complex(x)) for x in ct.zeros(lin.sys_d)) or "none"
    n_states = lin.sys_c.nstates
    facts = [f"Working point u* = {num(u_star)} A: equilibrium z = {num(eq.z, 3)} cm, h = {num(eq.h, 3)} cm, "
             f"y = {num(eq.y, 3)} cm{' (lower magnet seated)' if eq.lower_seated else ''}.",
             f"Linearisation (small-signal Jacobian, {n_states} states): static gain {num(lin.dc_gain, 3)} cm/A; "
             f"continuous modes {modes}. At Ts = {num(1000 * Ts, 2)} ms: poles {poles}; zeros {zeros}; "
             f"{lin.delay_samples} sample(s) of pure delay beyond the logger's one-sample read-then-write lag."]
    blas = {}
    for name, c in configs.items():
        if c["dataset"]["source"] == "sim":
            b = dataset_bla(c["dataset"])
            blas[name] = b
            keep = b.w > 0
            peak = int(np.argmax(np.abs(b.G[keep])))
            db = b.magnitude_db[keep]
            resonance = (f"resonance peak {num(db[peak], 1)} dB at {num(b.w[keep][peak], 1)} rad/s "
                         f"({num(db[peak] - db[0], 1)} dB above the low-frequency gain)" if resonance_rise(b) else
                         "no resonance peak (|G| rises nowhere above its value at the lowest frequency by more "
                         "than two standard errors)")
            facts.append(f"Best linear approximation for {esc(name)} ({esc(c['dataset']['input_class'])} input, "
                         f"{num(c['dataset']['low'])}–{num(c['dataset']['high'])} A): gain {num(abs(b.G[keep][0]), 3)} "
                         f"cm/A at {num(b.w[keep][0], 1)} rad/s, {resonance}; simulation FIT ceiling "
                         f"{num(b.fit_ceiling, 1)} %.")
    facts.append("The Jacobian is the model of infinitesimal motion about a rest, heavily damped by the friction's "
                 "damping at rest"
                 + (" (it leaves out the set-valued dry friction, which has no slope at rest and holds the magnets "
                    "still under inputs that small)" if p.sticks else "")
                 + "; the lab's inputs move the magnets far beyond that, so "
                 + ("the identified models are compared with the best linear approximation of their input class, as "
                    "in the figure below." if blas else
                    "it is not what a model identified from them should match. This sweep has no simulated dataset, "
                    "so it has no best linear approximation to compare with; the figure shows the Jacobian alone."))
    best = table_.iloc[0]
    suggestion = (f"The physical model suggests {n_states} poles in G (OE/BJ nf = {n_states}, ARX/ARMAX "
                  f"na = {n_states}) and a delay of about {lin.delay_samples + 1} sample(s). ")
    if "lab.arx_na" in lab:
        suggestion += (f"ARX order selection on the data (arxstruc/selstruc, AIC) picked na = {int(lab['lab.arx_na'])}, "
                       f"nb = {int(lab['lab.arx_nb'])} and delayest nk = {int(lab['lab.nk'])}. ")
    suggestion += (f"Identification ranked {esc(best['name'])} first ({esc(best['structure'])} orders "
                   f"{esc(best['orders'])}).")
    fig = img(png(preparation_figure(lin, blas)), "small-signal Jacobian and best linear approximations")
    code = "".join(f"<pre><code>{esc(inspect.getsource(f))}</code></pre>"
                   for f in (averages.get_average, averages.get_stationary_averages))
    return section("preparation", "Preparation tasks", *parts, bullets(facts), para(suggestion), fig,
                   para("The code of the lab's getAverage and getStationaryAverages (maglev/lab/averages.py):"),
                   code)
