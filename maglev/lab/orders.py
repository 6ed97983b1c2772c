"""The final order of each structure (EL2820 Lab 3 §3.5): where the validation simulation FIT levels off.

The one-step FIT and AIC keep improving with the noise model's order at Ts = 2 ms, so the
order is judged by the mean simulation FIT on the validation data (what G alone explains)
with a parsimony margin: the smallest swept order within ``margin`` FIT points of the best.
It is *settled* when a higher order was swept and gained less than the margin (the FIT
has levelled off); at the top of the swept grid it is not, and the decision says which
order to add.  The information criterion's minimum and the physical model's number of
states are shown beside it as evidence.
"""

from __future__ import annotations

import math

from maglev.lab.decision import Decision

__all__ = ["ORDER_MARGIN", "final_order", "orders_decision"]

ORDER_MARGIN = 1.0  # simulation FIT points a higher order must gain to count as needed


def away_from_bla(bla: dict[int, float] | None, grid: list[int]) -> set[int]:
    """The orders whose models lie farther from the best linear approximation (mean distance ``bla``) than
    those of every lower order: what they gain in FIT is output the input does not explain linearly."""
    if not bla:
        return set()
    out, closest = set(), math.inf
    for o in grid:
        if o not in bla:
            continue
        if bla[o] > closest:
            out.add(o)
        else:
            closest = bla[o]
    return out


def final_order(fit: dict[int, float], margin: float = ORDER_MARGIN,
                bla: dict[int, float] | None = None) -> tuple[int, bool]:
    """(order, settled) for one structure's mean validation simulation FIT by order: the smallest order
    within ``margin`` points of the best among the orders not moving away from the BLA
    (:func:`away_from_bla`; all orders without one); settled when a higher order was swept (it gained
    less than ``margin``, or moved away from the BLA)."""
    if not fit:
        raise ValueError("final_order: no orders with a FIT")
    grid = sorted(fit)
    eligible = [o for o in grid if o not in away_from_bla(bla, grid)]
    best = max(fit[o] for o in eligible)
    chosen = min(o for o in eligible if fit[o] >= best - margin)
    return chosen, chosen < grid[-1]


def orders_decision(fit: dict[str, dict[int, float]], aic: dict[str, dict[int, float]] | None = None,
                    physics_order: int | None = None, margin: float = ORDER_MARGIN,
                    bla: dict[str, dict[int, float]] | None = None) -> Decision:
    """The orders decision: per structure (``fit[structure][order]`` = mean validation simulation FIT over
    the datasets swept at every order; ``aic`` and ``bla`` likewise the mean AIC and mean distance to the
    best linear approximation, simulated data only), the final order and why."""
    aic, bla = aic or {}, bla or {}
    choice, rows, reasons, cautions = {}, [], [], []
    for st, by in fit.items():
        st_bla = bla.get(st, {})
        chosen, settled = final_order(by, margin, st_bla)
        grid = sorted(by)
        away = sorted(away_from_bla(st_bla, grid))
        st_aic = aic.get(st, {})
        aic_min = min(st_aic, key=st_aic.get) if st_aic else None
        prev = None
        for o in grid:
            rows.append({"structure": st, "order": o, "mean simulation FIT (%)": by[o],
                         "gain over the order below": None if prev is None else by[o] - by[prev],
                         "mean AIC": st_aic.get(o, math.nan), "mean distance to the BLA": st_bla.get(o, math.nan),
                         "final": o == chosen})
            prev = o
        choice[st] = chosen
        listed = ", ".join(f"{o}: {by[o]:.2f} %" for o in grid)
        extra = []
        if aic_min is not None:
            extra.append(f"AIC is lowest at order {aic_min}")
        if physics_order is not None:
            extra.append(f"the physical model has {physics_order} states")
        tail = f" ({'; '.join(extra)})" if extra else ""
        if away:
            reasons.append(f"{st}: order(s) {away} do not count: their models' mean distance to the best linear "
                           "approximation grows (" + ", ".join(f"order {o}: {st_bla[o]:.3g}" for o in grid if o in st_bla)
                           + "), so their FIT gain is output the input does not explain linearly, not G.")
        if settled:
            higher = [o for o in grid if o > chosen]
            reasons.append(f"{st}: order {chosen} — mean simulation FIT {listed}; order(s) {higher} gain less than "
                           f"{margin:g} point over it or move away from the BLA: the FIT has levelled off{tail}.")
        else:
            cautions.append(f"{st}: order {chosen} is the largest swept ({listed}) and gains more than {margin:g} "
                            f"point over the orders below: not settled; sweep order {chosen + 1} "
                            f"(++hydra.sweeper.orders.{st}=[{','.join(str(o) for o in [*grid, chosen + 1])}]){tail}.")
    rule = (f"Per structure, the smallest swept order whose mean validation simulation FIT is within {margin:g} "
            "point of the best, among the orders whose models do not move away from the best linear approximation "
            "(simulated data); settled when a higher swept order gained less than that or moved away from the BLA. "
            "AIC's minimum and the physical model's number of states are shown as evidence.")
    return Decision("orders", rule, choice, rows, reasons, cautions=cautions)
