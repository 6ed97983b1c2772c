"""The report's verdicts, drawn from numbers: binary vs uniform input, best vs worst model, the conclusion.

Pure functions of ranked tables, residual tests and fitted models (no MLflow, no HTML), so
each verdict can be checked on constructed numbers: when the numbers change, the verdict
changes with them.  :mod:`maglev.study.report.sections` writes them into the report.

A residual test is only evidence when it could have failed.  The independence test checks
that the residuals are uncorrelated with the input; on a record whose output the input
barely explains (every model simulates it at FIT ≈ 0 %), the residuals of *any* model —
even G = 0 — are nearly the output itself, uncorrelated with the input, so the test passes
whatever G is.  Below ``EXPLAINED_MIN`` of the output variance explained by the input the
report calls it a test *without power*, never a pass in the model's favour.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
import pandas as pd

from maglev.validation import TEST_LEVEL, format_p

EXPLAINED_MIN = 0.05  # share of the output variance the input must explain for the independence test to have power
UNIT_CIRCLE = 0.995  # |pole| from which a pole counts as on the unit circle (an integrator or a drift, not a mode)
GAIN_TOL = 0.20  # a static gain within this relative distance of the staircase slope matches it
SIM_MARGIN = 1.0  # simulation FIT points that make one model's G better than another's
NAIVE_MARGIN = 1.0  # FIT points a model must gain over y(t−1) to add anything one step ahead
WORKING_POINT_SHARE = 0.10  # mean input this far from u* (share of the working region's width) is another point
MODE_RATIO = 2.0  # a model's mode within this factor of a physical mode's natural frequency is that mode


def validation_data(val_dataset: str) -> str:
    """A ranked run's validation set in words: ``name[val]`` (the ranking's label) is name's validation data."""
    name = str(val_dataset)
    return f"{name.removesuffix('[val]')}'s validation data" if name.endswith("[val]") else name


def explained_share(fit_sim: float) -> float:
    """Share of the output variance a simulation with FIT ``fit_sim`` % explains: 1 − (1 − FIT/100)², at least 0
    (FIT = 100 (1 − ‖y − ŷ‖/‖y − ȳ‖), so ‖y − ŷ‖²/‖y − ȳ‖² = (1 − FIT/100)²)."""
    if fit_sim is None or not math.isfinite(fit_sim):
        return math.nan
    return max(0.0, 1.0 - (1.0 - fit_sim / 100.0) ** 2)


def explained_by_dataset(table: pd.DataFrame) -> dict[str, float]:
    """For each validation dataset, the largest share of its output any ranked model's simulation explains: how
    much of the output the input explains linearly, as far as the sweep's models can tell."""
    if "val_fit_sim" not in table:
        return {}
    best = table.groupby("val_dataset")["val_fit_sim"].max()
    return {str(k): explained_share(float(v)) for k, v in best.items()}


# ---------------------------------------------------------------------------- the records
def region_text(outside: float, limit: float) -> str:
    """Where a record's input lies against the working region, from the ``outside`` share of its samples beyond
    it and the records rule's ``limit`` (:data:`maglev.lab.records.INPUT_OUTSIDE_MAX`)."""
    if outside <= 0:
        return "inside the working region"
    if outside <= limit:
        return f"{100 * outside:.1f} % of its samples outside the working region (the rule allows {100 * limit:g} %)"
    return (f"<b>leaves the working region</b> in {100 * outside:.1f} % of its samples (the rule refuses more than "
            f"{100 * limit:g} %)")


def records_head(outside: dict[str, float], limit: float, forced: bool | None) -> str:
    """Why the report's records are these, from each record's share of input samples ``outside`` the working
    region, the rule's ``limit`` and whether the config ``forced`` them (None: the sweep logged no records
    decision): the rule's reason when it chose them, the records that break it when they do."""
    leaving = [n for n, x in outside.items() if x > limit]
    left = f"{', '.join(leaving)} {'leaves' if len(leaving) == 1 else 'leave'} the working region"
    rule = (f"the rule refuses a record whose input leaves the working region in more than {100 * limit:g} % of "
            "its samples (a linear model is valid there only), then prefers one centred at u* that covers as much "
            "of the region as it can (the most excitation the linear range allows)")
    if forced is None:
        return f"The sweep logged no records decision; {rule}" + (f": {left}." if leaving else ".")
    if not forced:
        return f"These records are the records rule's choice: {rule}."
    if leaving:
        return f"These records are forced by the config, not chosen: {left}, and {rule}."
    return f"These records are forced by the config, not chosen; each stays inside the working region, and {rule}."


# ---------------------------------------------------------------------------- binary vs uniform
@dataclass
class ClassComparison:
    """One structure's models, one per estimation dataset (its best at the final order), on every validation set."""

    matrix: pd.DataFrame  # rows: estimation dataset, columns: validation dataset, one-step FIT %
    models: dict[str, str]  # estimation dataset -> the model's name
    classes: dict[str, str]  # dataset -> input class
    higher: str  # "binary", "uniform" or "split": which class's model is higher on every common validation set
    own_class_wins: bool  # on every validation set the best model was estimated on that set's input class
    transfer: pd.Series  # estimation dataset -> mean FIT on the other datasets' validation sets
    sentences: list[str] = field(default_factory=list)


def class_comparison(comp: pd.DataFrame, common: pd.DataFrame, u_star: float | None = None,
                     width: float | None = None) -> ClassComparison:
    """The lab's "which one is higher? discuss" (§3.7) for one structure.

    ``comp``: the structure's ranked runs (``name, dataset, input_class, val_fit, val_fit_naive``, optionally
    ``u0`` and ``final_order``); ``common``: FIT % of each run (index: name) on each dataset's validation data
    (columns ``<dataset>[val]``).  Each dataset is represented by its structure's model with the highest FIT on its
    own validation data among the runs at the structure's final order (the orders decision, where ``final_order``
    marks any of the dataset's runs; else among all its runs), so the comparison is of the models §5 settles on.  The verdict compares the best binary-input and the best uniform-input model on each common
    validation set; the discussion says whether each class wins on its own class, which model transfers best
    to the other records, how far each FIT is above y(t−1)'s on the same data, and which records sit at another
    operating point than u*."""
    if "final_order" in comp:
        final = comp["final_order"].astype(bool)
        comp = comp[final | ~comp["dataset"].isin(comp.loc[final, "dataset"])]
    own = comp.loc[comp.groupby("dataset")["val_fit"].idxmax()].set_index("dataset")
    classes = {str(d): str(c) for d, c in own["input_class"].items()}
    datasets = sorted(own.index, key=lambda d: (classes[d], d))
    matrix = pd.DataFrame(index=datasets, columns=datasets, dtype=float)
    for d in datasets:
        for v in datasets:
            col = f"{v}[val]"
            matrix.loc[d, v] = float(common.loc[own.loc[d, "name"], col]) if col in common else math.nan
    naive = {str(d): float(own.loc[d, "val_fit_naive"]) for d in datasets if "val_fit_naive" in own}
    out, winners, wins = [], {}, {"binary": 0, "uniform": 0}
    for v in datasets:
        col = matrix[v].dropna()
        if col.empty:
            continue
        by_class = {c: col[[d for d in col.index if classes[d] == c]].max() for c in ("binary", "uniform")}
        if any(math.isnan(x) for x in by_class.values()):
            continue
        top = "binary" if by_class["binary"] > by_class["uniform"] else "uniform"
        wins[top] += 1
        winners[v] = col.idxmax()
        base = naive.get(v, math.nan)
        out.append(f"On {v}'s validation data ({classes[v]} input) the {top}-input model is higher: binary "
                   f"{by_class['binary']:.2f} % vs uniform {by_class['uniform']:.2f} %"
                   + (f"; y(t−1) alone scores {base:.2f} % there, so they add {by_class['binary'] - base:+.2f} and "
                      f"{by_class['uniform'] - base:+.2f} points to it" if math.isfinite(base) else "") + ".")
    n = wins["binary"] + wins["uniform"]
    higher = "binary" if n and wins["binary"] == n else "uniform" if n and wins["uniform"] == n else "split"
    own_class = bool(winners) and all(classes[w] == classes[v] for v, w in winners.items())
    if higher == "split":
        head = (f"Neither class is higher everywhere: the binary-input model is higher on {wins['binary']} and the "
                f"uniform-input model on {wins['uniform']} of the {n} common validation sets.")
    else:
        head = f"The {higher}-input model is higher on all {n} common validation sets."
    if own_class:
        head += " Each validation set is won by a model estimated on its own input class."
    elif winners:
        away = [v for v, w in winners.items() if classes[w] != classes[v]]
        head += (" The model estimated on the other class wins on " + ", ".join(away)
                 + ": that class's model describes this record's dynamics better than its own class's.")
    off = matrix.where(~np.eye(len(datasets), dtype=bool))
    transfer = off.mean(axis=1, skipna=True)
    if transfer.notna().any():
        t = transfer.idxmax()
        out.append(f"Across the other records' validation sets, the model from {t} ({classes[t]}) transfers best: "
                   f"mean FIT {transfer[t]:.2f} % against "
                   + ", ".join(f"{d} {transfer[d]:.2f} %" for d in datasets if d != t and math.isfinite(transfer[d]))
                   + ".")
    high_naive = {d: x for d, x in naive.items() if math.isfinite(x)}
    if high_naive:
        d = max(high_naive, key=high_naive.get)
        own_fit = matrix.loc[d, d]
        out.append(f"A high one-step FIT is not a good model by itself: on {d} y(t−1) already scores {naive[d]:.2f} %, "
                   f"and the model from it reaches {own_fit:.2f} % ({own_fit - naive[d]:+.2f} points)"
                   + "; on " + ", ".join(f"{e} y(t−1) scores {naive[e]:.2f} % and its model {matrix.loc[e, e]:.2f} % "
                                         f"({matrix.loc[e, e] - naive[e]:+.2f})" for e in datasets if e != d) + ".")
    if u_star is not None and width and "u0" in own and math.isfinite(u_star):
        far = {d: float(own.loc[d, "u0"]) for d in datasets
               if abs(float(own.loc[d, "u0"]) - u_star) > WORKING_POINT_SHARE * width}
        if far:
            one = len(far) == 1
            out.append("Operating points: " + ", ".join(f"{d} is centred at {u:.2f} A" for d, u in far.items())
                       + f", not at u* = {u_star:.2f} A (more than {WORKING_POINT_SHARE:.0%} of the working region's "
                       + ("width away): its model linearises the plant at another point, which the comparison mixes "
                          "with the input class." if one else
                          "width away): their models linearise the plant at other points than u*, which the "
                          "comparison mixes with the input class."))
        else:
            out.append(f"Every record is centred within {WORKING_POINT_SHARE:.0%} of the working region's width of "
                       f"u* = {u_star:.2f} A, so the comparison is one of input classes, not of operating points.")
    return ClassComparison(matrix=matrix, models={str(d): str(own.loc[d, "name"]) for d in datasets},
                           classes=classes, higher=higher, own_class_wins=own_class, transfer=transfer,
                           sentences=[head, *out])


# ---------------------------------------------------------------------------- best vs worst
@dataclass
class ModelFacts:
    """What the best-vs-worst comparison reads of one model (all from its run and its fitted polynomials)."""

    name: str
    rank: int
    val_fit: float
    val_fit_sim: float
    val_dataset: str
    explained: float  # share of the validation output the input explains (explained_by_dataset)
    white: bool
    whiteness_p: float
    independent: bool
    independence_p: float
    unit_poles: int  # poles with |p| >= UNIT_CIRCLE
    cancellations: int  # near pole-zero cancellations
    nmp_zeros: int  # zeros of G outside the unit circle
    dominant: tuple[float, float] | None  # (ωn rad/s, ζ) of the slowest mode
    dcgain: float
    bla_err: float = math.nan  # relative distance to the best linear approximation (simulated data only)

    @property
    def power(self) -> bool:
        """Whether the independence test could fail: the input explains at least EXPLAINED_MIN of the output."""
        return math.isfinite(self.explained) and self.explained >= EXPLAINED_MIN


def dominant_mode(poles: np.ndarray, Ts: float) -> tuple[float, float] | None:
    """(natural frequency ωn in rad/s, damping ζ) of the slowest stable mode (largest |p| < 1), from s = ln(p)/Ts;
    None without a stable pole off the origin."""
    stable = [complex(p) for p in poles if 1e-9 < abs(p) < 1.0]
    if not stable:
        return None
    p = max(stable, key=lambda x: (abs(x), x.imag))
    s = np.log(p) / Ts
    return float(abs(s)), float(-s.real / abs(s))


def model_facts(row: pd.Series, resid, model, explained: float) -> ModelFacts:
    """``row``: a ranked run; ``resid``: its ResidResult; ``model``: its PolyModel."""
    from maglev.model import CANCEL_TOL

    poles, zeros = model.poles(), model.zeros()
    return ModelFacts(name=str(row["name"]), rank=int(row["rank"]), val_fit=float(row["val_fit"]),
                      val_fit_sim=float(row.get("val_fit_sim", math.nan)), val_dataset=str(row["val_dataset"]),
                      explained=explained, white=bool(resid.white), whiteness_p=float(resid.whiteness_pvalue),
                      independent=bool(resid.independent), independence_p=float(resid.independence_pvalue),
                      unit_poles=int(np.sum(np.abs(poles) >= UNIT_CIRCLE)),
                      cancellations=len(model.near_cancellations(CANCEL_TOL)),
                      nmp_zeros=int(np.sum(np.abs(zeros) > 1.0)), dominant=dominant_mode(poles, model.Ts),
                      dcgain=float(model.dcgain()), bla_err=float(row.get("g_bla_err", math.nan)))


def independence_text(f: ModelFacts) -> str:
    """The independence test's outcome for one model, with its power."""
    p = format_p(f.independence_p)
    if not f.power:
        share = "nothing" if f.explained <= 0 else f"{100 * f.explained:.1f} %"
        return (f"the independence test of {f.name} (p = {p}) is without power: on {validation_data(f.val_dataset)} "
                f"the input explains {share} of the output (less than {EXPLAINED_MIN:.0%}; the best simulation of any model "
                "there), so the residuals of any G, even G = 0, are uncorrelated with the input — not a pass in its "
                "favour")
    return (f"{f.name} {'passes' if f.independent else 'fails'} the independence test (p = {p}; the input explains "
            f"{100 * f.explained:.1f} % of the output on {validation_data(f.val_dataset)}, so the test has power)")


@dataclass
class BestWorst:
    """The checks that explain the ranking: each favours ``best``, ``worst`` or neither, with its sentence."""

    better: str  # "best" or "worst": the better model of the plant by the checks below
    checks: list[tuple[str, str | None, str]]  # (check, favoured side or None, sentence)

    @property
    def tally(self) -> dict[str, int]:
        return {side: sum(1 for _, s, _ in self.checks if s == side) for side in ("best", "worst")}


def best_vs_worst(b: ModelFacts, w: ModelFacts, slope: float | None = None) -> BestWorst:
    """Which of the best and worst model (by one-step FIT) is the better model of the plant, and why.

    Checks, each favouring one side or neither: the simulation FIT (G alone, margin SIM_MARGIN), the static gain
    against the staircase's slope ``slope`` (cm/A), poles on the unit circle, near pole-zero cancellations,
    the whiteness test, the independence test — only where it has power — and the distance to the best linear
    approximation (where known).  The better model wins more checks; a tie leaves the one-step ranking standing."""
    checks: list[tuple[str, str | None, str]] = []

    def side(x_best: float, x_worst: float, lower_is_better: bool, margin: float = 0.0) -> str | None:
        if not (math.isfinite(x_best) and math.isfinite(x_worst)) or abs(x_best - x_worst) <= margin:
            return None
        return "best" if (x_best < x_worst) == lower_is_better else "worst"

    s = side(b.val_fit_sim, w.val_fit_sim, False, SIM_MARGIN)
    checks.append(("simulation", s, f"Simulation FIT (G alone): {b.name} {b.val_fit_sim:.2f} %, {w.name} "
                   f"{w.val_fit_sim:.2f} %" + (f": the {s}'s G reproduces its validation output better."
                                                if s else f", within {SIM_MARGIN:g} point.")))
    if slope and math.isfinite(slope):
        rb, rw = b.dcgain / slope - 1.0, w.dcgain / slope - 1.0
        s = side(abs(rb), abs(rw), True, 0.05)
        checks.append(("static gain", s, f"Static gain against the staircase slope {slope:.3f} cm/A: {b.name} "
                       f"{b.dcgain:.3f} cm/A ({100 * rb:+.0f} %), {w.name} {w.dcgain:.3f} cm/A ({100 * rw:+.0f} %)"
                       + (f"; the {s}'s matches the plant's static behaviour better"
                          + (f" (within {GAIN_TOL:.0%})" if abs(rb if s == 'best' else rw) <= GAIN_TOL else "")
                          if s else "; equally close") + "."))
    s = side(b.unit_poles, w.unit_poles, True)
    checks.append(("unit-circle poles", s, f"Poles with |p| ≥ {UNIT_CIRCLE}: {b.name} {b.unit_poles}, {w.name} "
                   f"{w.unit_poles}" + ("; a pole on the unit circle is an integrator or a drift the plant (open-loop "
                                        f"stable) does not have, so the {s} is more plausible." if s else ".")))
    s = side(b.cancellations, w.cancellations, True)
    checks.append(("cancellations", s, f"Near pole-zero cancellations: {b.name} {b.cancellations}, {w.name} "
                   f"{w.cancellations}" + (f"; each is an order the data do not support, fewer in the {s}."
                                           if s else ".")))
    s = None if b.white == w.white else ("best" if b.white else "worst")
    checks.append(("whiteness", s, f"Whiteness: {b.name} {'passes' if b.white else 'fails'} (p = "
                   f"{format_p(b.whiteness_p)}), {w.name} {'passes' if w.white else 'fails'} (p = "
                   f"{format_p(w.whiteness_p)})" + ("; residuals correlated in time mean the noise model misses "
                                                    f"structure, which the {s} does not." if s else ".")))
    ok_b, ok_w = (b.independent if b.power else None), (w.independent if w.power else None)
    s = None if ok_b is None or ok_w is None or ok_b == ok_w else ("best" if ok_b else "worst")
    checks.append(("independence", s, f"Independence: {independence_text(b)}; {independence_text(w)}."))
    s = side(b.bla_err, w.bla_err, True)
    if s:
        checks.append(("BLA distance", s, f"Distance to the best linear approximation: {b.name} {b.bla_err:.3g}, "
                       f"{w.name} {w.bla_err:.3g}: the {s} is closer to what a linear model of this input class "
                       "should be."))
    tally = {k: sum(1 for _, x, _ in checks if x == k) for k in ("best", "worst")}
    return BestWorst(better="worst" if tally["worst"] > tally["best"] else "best", checks=checks)


def pole_zero_text(f: ModelFacts, physics: list[tuple[float, float]] | None = None,
                   bla_peak: float | None = None) -> str:
    """The pole-zero analysis of one model in a sentence: unit-circle poles, cancellations, non-minimum-phase zeros,
    the slowest mode against the physics' modes (ωn, ζ) and the BLA's resonance frequency (rad/s), where known."""
    text = (f"{f.name}: {f.unit_poles} pole(s) with |p| ≥ {UNIT_CIRCLE}, {f.cancellations} near cancellation(s), "
            f"{f.nmp_zeros} zero(s) outside the unit circle (non-minimum phase)")
    if f.dominant:
        wn, zeta = f.dominant
        text += f"; slowest mode ωn = {wn:.1f} rad/s, ζ = {zeta:.2f}"
        if physics:
            pw, pz = min(physics, key=lambda m: abs(m[0] - wn))
            near = pw / MODE_RATIO <= wn <= pw * MODE_RATIO
            text += (f" (nearest mode of the linearised physics: {pw:.1f} rad/s, ζ = {pz:.2f})" if near else
                     f", not a mode of the linearised physics (the nearest, {pw:.1f} rad/s, ζ = {pz:.2f}, is more "
                     f"than a factor {MODE_RATIO:g} away)")
        if bla_peak:
            text += f"; the BLA peaks at {bla_peak:.1f} rad/s"
    return text + "."


# ---------------------------------------------------------------------------- conclusion
@dataclass
class Conclusion:
    simulation: str  # name of the model to simulate with
    prediction: str | None  # name of the model to predict one step ahead with (None: y(t−1) does as well)
    sentences: list[str]


def _points(a: float, b: float) -> float:
    """a − b as the two FITs printed with two decimals show it (so the difference stated beside them adds up)."""
    return round(float(a), 2) - round(float(b), 2)


def _orders_rule(table: pd.DataFrame, orders) -> tuple[str, str]:
    """(the sentence stating among which models the conclusion chooses, "those" or "the") from the orders
    decision ``orders`` and the ranked ``table``'s ``final_order`` column."""
    from maglev.lab.orders import statuses

    n, total = int(table["final_order"].sum()), len(table)
    choice = orders.choice if orders is not None else {}
    if not choice:
        return (f"No orders decision: each structure was swept at one order, so the model to use is chosen among "
                f"all {total} models.", "the")
    status = statuses(orders)
    unsettled = [st for st, o in choice.items() if status.get((st, o)) == "final, not settled"]
    listed = ", ".join(f"{st.upper()} {o}" + (" (the largest swept, its FIT still rising)" if st in unsettled else "")
                       for st, o in choice.items())
    single = [st for st in dict.fromkeys(table["structure"]) if st not in choice]
    if single:
        listed += "; " + ", ".join(f"{st.upper()} its one swept order" for st in single)
    head = ("the orders the orders rule chose, where each structure's FIT levels off" if not unsettled
            else "the orders the orders rule chose, not all of them where the FIT levels off")
    return f"The model to use is chosen among {head} (§5: {listed}): {n} of the {total} models.", "those"


def _not_final(row: pd.Series, orders) -> str:
    """Why a run's order is not the one the orders rule chose for its structure, from the orders decision's status
    of that order."""
    from maglev.lab.orders import statuses

    st, o = str(row["structure"]), int(row["order"])
    why = statuses(orders).get((st, o))
    final = orders.choice.get(st) if orders is not None else None
    return f"its order {o} is not the order {final} the orders rule chose for {st.upper()}" + (
        f" ({why}; §5)" if why else " (§5)")


def residual_caveat(row: pd.Series, purpose: str) -> str:
    """The residual tests of a recommended model (``purpose``: "simulation" or "prediction") and what a failed one
    means for that use; "" when the table has no test p-values or the model passes both."""
    tests = [(t, float(row[c])) for t, c in (("whiteness", "whiteness_pvalue"), ("independence", "independence_pvalue"))
             if c in row.index and math.isfinite(float(row[c]))]
    failed = [(t, p) for t, p in tests if p < TEST_LEVEL]
    if not failed:
        return ""
    names = " and ".join(f"the {t} test (p = {format_p(p)} < {TEST_LEVEL})" for t, p in failed)
    meaning = []
    if any(t == "independence" for t, _ in failed):
        meaning.append("G misses part of the dynamics")
    if any(t == "whiteness" for t, _ in failed):
        meaning.append("its predictions leave structure in the residuals" if purpose == "prediction" else
                       "the disturbance is coloured, which a simulation (G alone) does not use")
    return f"Caution: {row['name']} fails {names}: " + "; ".join(meaning) + "."


def conclusion(table: pd.DataFrame, slope: float | None = None, orders=None) -> Conclusion:
    """The model to use for simulation (the highest simulation FIT: G alone reproduces the output) and for one-step
    prediction (the highest one-step FIT, if it beats y(t−1) by NAIVE_MARGIN points; else y(t−1) itself), each
    chosen among the runs at their structure's final order (``table["final_order"]``, from the orders decision
    ``orders``: :class:`maglev.lab.decision.Decision` or None), and why; a recommended model that fails a residual
    test is said to, with what that means for its use (:func:`residual_caveat`); a run of another order that scores
    higher is named with its number and the reason the orders rule gives against its order."""
    if "final_order" not in table:
        table = table.assign(final_order=True)
    rule, those = _orders_rule(table, orders)
    pool = table[table["final_order"].astype(bool)]
    sim = pool.loc[pool["val_fit_sim"].idxmax()]
    top = pool.iloc[0]
    gain = _points(top["val_fit"], top["val_fit_naive"]) if "val_fit_naive" in pool else math.inf
    lines = [rule, f"For simulation (the output from the input alone) use {sim['name']}: it simulates "
             f"{validation_data(sim['val_dataset'])} at FIT {sim['val_fit_sim']:.2f} %, the highest of {those} "
             f"{len(pool)} models (#{int(sim['rank'])} by one-step FIT)."]
    if "dcgain" in pool and slope and math.isfinite(slope):
        lines[-1] += (f" Its static gain {sim['dcgain']:.3f} cm/A is {100 * (sim['dcgain'] / slope - 1):+.0f} % from "
                      f"the staircase slope {slope:.3f} cm/A.")
        off = abs(sim["dcgain"] / slope - 1.0)
        matching = pool[(pool["dcgain"] / slope - 1.0).abs() <= GAIN_TOL]
        if off > GAIN_TOL and not matching.empty:
            alt = matching.loc[matching["val_fit_sim"].idxmax()]
            lines.append(f"Where the static response matters, {alt['name']} is the better choice: its static gain "
                         f"{alt['dcgain']:.3f} cm/A is within {GAIN_TOL:.0%} of the slope, and it simulates "
                         f"{validation_data(alt['val_dataset'])} at {alt['val_fit_sim']:.2f} %.")
    higher = table.loc[table["val_fit_sim"].idxmax()]
    if not higher["final_order"] and higher["val_fit_sim"] > sim["val_fit_sim"]:
        lines.append(f"{higher['name']} simulates higher, at {higher['val_fit_sim']:.2f} % "
                     f"({_points(higher['val_fit_sim'], sim['val_fit_sim']):+.2f} points), but is not recommended: "
                     f"{_not_final(higher, orders)}.")
    label = (f"The #1 by one-step FIT, {top['name']}," if int(top["rank"]) == 1 else
             f"The best of {those} by one-step FIT, {top['name']} (#{int(top['rank'])}),")
    if sim["name"] != top["name"]:
        same = pool[pool["val_dataset"] == top["val_dataset"]]
        rival = same.loc[same["val_fit_sim"].idxmax()]
        lines.append(f"{label} simulates at {top['val_fit_sim']:.2f} %: its "
                     "one-step FIT comes from the noise model's use of past outputs, not from G"
                     + (f"; on the same validation data {rival['name']} (#{int(rival['rank'])}) simulates at "
                        f"{rival['val_fit_sim']:.2f} %." if rival["name"] != top["name"] else "."))
    if gain >= NAIVE_MARGIN:
        prediction = str(top["name"])
        lines.append(f"For one-step prediction use {top['name']}: FIT {top['val_fit']:.2f} % on "
                     f"{validation_data(top['val_dataset'])}, {gain:+.2f} points above the "
                     f"{top['val_fit_naive']:.2f} % of the naive predictor y(t−1).")
        if prediction == sim["name"]:
            lines.append("One model serves both purposes.")
    else:
        prediction = None
        lines.append(f"For one-step prediction no model is needed: {top['name']} (#{int(top['rank'])}), the best of "
                     f"{those} models one step ahead, scores {top['val_fit']:.2f} % and y(t−1) alone "
                     f"{top['val_fit_naive']:.2f} % on the same data ({gain:+.2f} points, less than {NAIVE_MARGIN:g}).")
    caveats = [residual_caveat(sim, "prediction" if prediction == sim["name"] else "simulation")]
    if prediction is not None and prediction != sim["name"]:
        caveats.append(residual_caveat(top, "prediction"))
    lines += [c for c in caveats if c]
    first = table.iloc[0]
    if not first["final_order"]:
        lines.append(f"The #1 by one-step FIT, {first['name']} ({first['val_fit']:.2f} %, "
                     f"{_points(first['val_fit'], top['val_fit']):+.2f} points over {top['name']}), is not recommended: "
                     f"{_not_final(first, orders)}.")
    return Conclusion(simulation=str(sim["name"]), prediction=prediction, sentences=lines)


def extremes_text(best: pd.Series, worst: pd.Series, recommended: Conclusion, orders=None) -> str:
    """What the best-vs-worst section answers, and how its best relates to the model the conclusion recommends.

    The lab (§3.7) asks for the best and the worst model *in terms of FIT*: the #1 and the last of the one-step
    ranking, whatever their order.  The conclusion recommends models among the orders the orders rule chose
    (``recommended``: :func:`conclusion`; ``orders``: the orders decision), so the #1 may not be one of them: the
    sentence then says why (its order, or a one-step FIT no better than y(t−1)'s) and why both are shown."""
    name = str(best["name"])
    head = (f"The lab's best and worst model in terms of FIT (§3.7) are the #1 and the #{int(worst['rank'])} of the "
            "one-step ranking (§6).")
    uses = [u for u, m in (("simulation", recommended.simulation), ("one-step prediction", recommended.prediction))
            if m == name]
    if uses:
        return head + f" The #1 is also the model the conclusion recommends for {' and '.join(uses)} (§9)."
    if "final_order" in best.index and not bool(best["final_order"]):
        why = _not_final(best, orders)
    else:  # at a chosen order and not recommended for prediction: it does not beat y(t−1) by the margin
        why = (f"one step ahead it adds {_points(best['val_fit'], best['val_fit_naive']):+.2f} points to the naive "
               f"predictor y(t−1), less than {NAIVE_MARGIN:g}, and {recommended.simulation} simulates better")
    if recommended.prediction == recommended.simulation:
        use = f"{recommended.simulation} for simulation and one-step prediction"
    else:
        use = (f"{recommended.simulation} for simulation, "
               + (f"{recommended.prediction}" if recommended.prediction else "y(t−1) itself")
               + " for one-step prediction")
    return (head + f" The #1 is not the model this report recommends (§9: {use}): {why}. Both are named: the #1 "
            "answers the lab's question, the recommended model is the one to use.")
