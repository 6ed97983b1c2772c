"""Cautions drawn from a ranked sweep's numbers: where the ranking's conclusion does not hold.

A top-four table by one-step FIT reads like a verdict; these checks say when the
numbers beside it undermine it — the top model fails its residual tests, predicts no
better than y(t−1), simulates far worse than it predicts, lies far from the best
linear approximation; a structure's best order sits at the edge of the swept grid;
the compared datasets sit at different working points; a model is unstable or has
near pole-zero cancellations.  Each caution is generated from the numbers it states
and appears exactly when its condition holds; the ranking run, the report and the
console print the same list.

Orders are judged by the simulation FIT (:func:`order_choice`), not by the one-step FIT
or AIC.  At Ts = 2 ms the one-step FIT is mostly y(t−1), and it keeps rising with the
noise model's order: on the lab sweep's three simulated datasets (orders 1 to 8) ARX's
mean one-step FIT rises at every order from 4 to 8, and the mean AIC of ARX, ARMAX and
BJ falls to order 7 or 8, so a grid judged by either ends at its edge.  The simulation
FIT measures G alone, the part an order is for.  An order counts as needed when it
gains more than ``ORDER_MARGIN`` = 1 point of mean simulation FIT: above order 4 the
mean moves by at most 0.63 points from one order to the next, either way, while order
3 to 4 gains 7.0 to 8.3 points for ARX, ARMAX and BJ (measured on an earlier plant:
docs/decisions/0003-orders-by-simulation-fit.md).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import pandas as pd

from maglev.validation import TEST_LEVEL, format_p

NAIVE_MARGIN = 1.0  # FIT points a model must gain over y(t−1) to count as adding something
SIM_GAP = 20.0  # FIT points between one-step and simulation FIT that flag a poor input-output model
WORKING_POINT_SHARE = 0.10  # mean input this far (as a share of the working region's width) from u* differs
BLA_RATIO = 2.0  # top model this many times farther from the BLA than the closest model of its dataset
ORDER_MARGIN = 1.0  # simulation FIT points a higher order must gain to count as needed (the parsimony rule)


@dataclass(frozen=True)
class Caution:
    """One caution: a key naming the check, the sentence, and the numbers it states."""

    key: str
    text: str
    numbers: dict = field(default_factory=dict)


def _names(rows: pd.DataFrame, limit: int = 4) -> str:
    names = list(rows["name"])
    return ", ".join(names[:limit]) + (f" and {len(names) - limit} more" if len(names) > limit else "")


def residual_tests(table: pd.DataFrame) -> list[Caution]:
    """The top model failing whiteness or independence, and how many ranked runs fail each test."""
    out = []
    top = table.iloc[0]
    for metric, test, what in (("whiteness_pvalue", "whiteness", "its residuals are correlated in time: the "
                                "noise model misses structure"),
                               ("independence_pvalue", "independence", "its residuals correlate with the input: "
                                "G misses dynamics or the delay")):
        if metric not in table:
            continue
        failing = table[table[metric] < TEST_LEVEL]
        if top[metric] < TEST_LEVEL:
            out.append(Caution(f"top_fails_{test}",
                               f"The #1 model {top['name']} fails the {test} test (p = {format_p(top[metric])} < "
                               f"{TEST_LEVEL}): {what}.", {"p": float(top[metric])}))
        if len(failing):
            out.append(Caution(f"runs_fail_{test}",
                               f"{len(failing)} of {len(table)} ranked models fail the {test} test at the "
                               f"{TEST_LEVEL:.0%} level.", {"failing": len(failing), "ranked": len(table)}))
    return out


def naive_baseline(table: pd.DataFrame) -> list[Caution]:
    """Models whose one-step FIT is no better than the naive predictor y(t−1) on the same data."""
    if "val_fit_naive" not in table:
        return []
    gain = table["val_fit"] - table["val_fit_naive"]
    out = []
    top = table.iloc[0]
    if gain.iloc[0] < NAIVE_MARGIN:
        out.append(Caution("top_no_better_than_naive",
                           f"The #1 model {top['name']} predicts one step ahead with FIT {top['val_fit']:.2f} %, "
                           f"but y(t−1) alone scores {top['val_fit_naive']:.2f} % on the same data: it adds "
                           f"{gain.iloc[0]:+.2f} points to the naive predictor.",
                           {"val_fit": float(top["val_fit"]), "val_fit_naive": float(top["val_fit_naive"])}))
    weak = table[gain < NAIVE_MARGIN]
    if len(weak):
        out.append(Caution("runs_no_better_than_naive",
                           f"{len(weak)} of {len(table)} ranked models gain less than {NAIVE_MARGIN:g} FIT point "
                           f"over y(t−1): {_names(weak)}.", {"weak": len(weak), "ranked": len(table)}))
    return out


def simulation_gap(table: pd.DataFrame) -> list[Caution]:
    """The top model simulating the validation data far worse than it predicts them one step ahead."""
    if "val_fit_sim" not in table:
        return []
    top = table.iloc[0]
    gap = top["val_fit"] - top["val_fit_sim"]
    if not gap > SIM_GAP:
        return []
    return [Caution("top_simulates_poorly",
                    f"The #1 model {top['name']} simulates the validation data at FIT {top['val_fit_sim']:.2f} % "
                    f"against {top['val_fit']:.2f} % one step ahead ({gap:.1f} points lower): its one-step FIT "
                    "comes from the noise model's use of past outputs, not from G.",
                    {"val_fit": float(top["val_fit"]), "val_fit_sim": float(top["val_fit_sim"])})]


def bla_distance(table: pd.DataFrame) -> list[Caution]:
    """The top model far from the best linear approximation, compared with its dataset's closest model."""
    if "g_bla_err" not in table or table["g_bla_err"].isna().all():
        return []
    top = table.iloc[0]
    same = table[table["dataset"] == top["dataset"]].dropna(subset=["g_bla_err"])
    if math.isnan(top["g_bla_err"]) or same.empty:
        return []
    closest = same.loc[same["g_bla_err"].idxmin()]
    if not top["g_bla_err"] > BLA_RATIO * closest["g_bla_err"]:
        return []
    return [Caution("top_far_from_bla",
                    f"The #1 model {top['name']} is {top['g_bla_err']:.3g} (relative, on records of the validation "
                    f"length) from the best linear approximation of {top['dataset']}; {closest['name']} is "
                    f"{closest['g_bla_err']:.3g}: the better-predicting model is the worse model of the plant.",
                    {"top": float(top["g_bla_err"]), "closest": float(closest["g_bla_err"]),
                     "closest_run": closest["name"]})]


def order_choice(runs: pd.DataFrame, margin: float = ORDER_MARGIN) -> dict | None:
    """The order a structure's runs support, by mean simulation FIT (``val_fit_sim``) over the datasets swept at
    every order, with the parsimony rule: the smallest order within ``margin`` FIT points of the best.

    Returns ``{"chosen", "best", "grid", "fit": {order: mean FIT}, "datasets", "edge", "suggest", "bla",
    "bla_datasets", "cancellations"}`` (None with fewer than two orders).  ``chosen`` is the orders decision's
    (:func:`maglev.lab.orders.final_order`: the orders from the first one whose added poles are cancelled by
    zeros, and an order whose models move away from the best linear approximation, do not count).  ``edge`` is
    ``"upper"`` when the chosen order is the largest swept (every lower order simulates more than ``margin`` worse:
    the FIT still rises at the top of the grid), ``"lower"`` when the smallest swept order (> 1) simulates more
    than ``margin`` better than every other (the FIT falls as the order rises from the bottom), else None: the FIT levels off inside the grid or within
    the margin across it.  ``bla`` is the mean ``g_bla_err`` by order over the ``bla_datasets`` datasets that
    have it at every order (empty for recorded data), which the orders rule reads.
    """
    if "val_fit_sim" not in runs or "order" not in runs:
        return None
    by = runs.pivot_table(index="dataset", columns="order", values="val_fit_sim", aggfunc="mean").dropna()
    if by.shape[1] < 2 or by.empty:
        return None
    from maglev.lab.orders import final_order

    fit = {int(o): float(v) for o, v in by.mean().sort_index().items()}
    grid = list(fit)
    best = max(fit, key=fit.get)
    bla, n_bla = mean_by_order(runs, "g_bla_err")
    cancel = mean_by_order(runs, "near_cancellations", list(by.index))[0]
    chosen, settled = final_order(fit, margin, bla, cancel)  # the orders decision's rule (maglev.lab.orders)
    edge, suggest = None, None
    if not settled:
        edge, suggest = "upper", grid[-1] + 1
    elif best == grid[0] > 1 and all(fit[best] - fit[o] > margin for o in grid[1:]):
        edge, suggest = "lower", grid[0] - 1
    return {"chosen": chosen, "best": best, "grid": grid, "fit": fit, "datasets": len(by), "edge": edge,
            "suggest": suggest, "bla": bla, "bla_datasets": n_bla, "cancellations": cancel}


def order_edges(table: pd.DataFrame) -> list[Caution]:
    """A structure whose order supported by the simulation FIT (:func:`order_choice`) sits at an edge of the
    swept orders: the FIT still changes by more than ``ORDER_MARGIN`` points toward that edge.  An order whose
    models move away from the best linear approximation is never an upper edge: the orders rule does not count
    it (:func:`maglev.lab.orders.away_from_bla`), so the order below it is settled."""
    out = []
    for st, runs in table.groupby("structure", sort=False):
        c = order_choice(runs)
        if c is None or c["edge"] is None:
            continue
        fit, grid = c["fit"], c["grid"]
        numbers = {"chosen": c["chosen"], "grid": grid, "suggest": c["suggest"], "edge": c["edge"], "fit": fit,
                   "margin": ORDER_MARGIN}
        listed = ", ".join(f"order {o}: {fit[o]:.2f} %" for o in grid)
        over = f"mean simulation FIT over {c['datasets']} dataset(s) ({listed})"
        if c["edge"] == "upper":
            why = (f"{st}: the {over} still rises by more than {ORDER_MARGIN:g} point at the largest swept order "
                   f"{grid[-1]}: the smallest order within {ORDER_MARGIN:g} point of the best is {c['chosen']}, the "
                   f"edge of the swept orders {grid}")
        else:
            why = (f"{st}: the {over} is highest at the smallest swept order {grid[0]}, more than "
                   f"{ORDER_MARGIN:g} point above every other: it falls as the order rises from the edge of the swept "
                   f"orders {grid}")
        wider = ",".join(str(o) for o in sorted({*grid, c["suggest"]}))
        text = f"{why}; add order {c['suggest']} (++hydra.sweeper.orders.{st}=[{wider}]) before concluding."
        out.append(Caution(f"order_at_edge_{st}", text, numbers))
    return out


def mean_by_order(runs: pd.DataFrame, metric: str, datasets: list[str] | None = None) -> tuple[dict[int, float], int]:
    """Mean ``metric`` per order over the datasets (of ``datasets``, if given) that have it at every order, and how
    many they are; ``({}, 0)`` when no run logged it (real datasets have no ``g_bla_err``; runs logged before
    ``near_cancellations`` existed have none)."""
    if metric not in runs or runs[metric].isna().all():
        return {}, 0
    if datasets is not None:
        runs = runs[runs["dataset"].isin(datasets)]
    by = runs.pivot_table(index="dataset", columns="order", values=metric, aggfunc="mean").dropna()
    return {int(o): float(v) for o, v in by.mean().items()}, len(by)


def working_points(datasets: dict[str, float], u_star: float | None, width: float | None) -> list[Caution]:
    """Compared datasets whose mean input lies away from the working point (``datasets``: name → mean u in A)."""
    if u_star is None or width is None or not width > 0 or math.isnan(u_star):
        return []
    off = {n: u0 for n, u0 in datasets.items() if abs(u0 - u_star) > WORKING_POINT_SHARE * width}
    if not off:
        return []
    where = ", ".join(f"{n} is centred at {u0:.2f} A" for n, u0 in off.items())
    return [Caution("working_points_differ",
                    f"{where}; the working point is {u_star:.2f} A: models of a nonlinear plant from inputs at "
                    "different working points are linearisations at different points, so their comparison mixes "
                    "the input class with the operating point.", {"u0": off, "u_star": u_star})]


def model_health(table: pd.DataFrame, top: int = 4) -> list[Caution]:
    """Unstable models among the ranked, near pole-zero cancellations among the top four."""
    out = []
    if "max_pole_radius" in table:
        unstable = table[table["max_pole_radius"] >= 1.0]
        if len(unstable):
            out.append(Caution("unstable_models",
                               f"{len(unstable)} ranked model(s) have a pole on or outside the unit circle: "
                               f"{_names(unstable)} (largest |pole| {unstable['max_pole_radius'].max():.4f}).",
                               {"unstable": len(unstable)}))
    if "near_cancellations" in table:
        flagged = table.head(top)[table.head(top)["near_cancellations"] > 0]
        if len(flagged):
            out.append(Caution("top_cancellations",
                               f"Near pole-zero cancellations in the top four: " + ", ".join(
                                   f"{r['name']} ({int(r['near_cancellations'])})" for _, r in flagged.iterrows())
                               + ": their orders are higher than the data support.",
                               {"flagged": list(flagged["name"])}))
    return out


def cautions(table: pd.DataFrame, datasets_u0: dict[str, float] | None = None, u_star: float | None = None,
             width: float | None = None) -> list[Caution]:
    """Every caution that applies to the ranked ``table`` (best first), in reading order."""
    if table.empty:
        return []
    return (residual_tests(table) + naive_baseline(table) + simulation_gap(table) + bla_distance(table)
            + order_edges(table) + working_points(datasets_u0 or {}, u_star, width) + model_health(table))
