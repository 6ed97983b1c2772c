"""The final order of each structure (EL2820 Lab 3 §3.5): where the validation simulation FIT levels off.

The one-step FIT and AIC keep improving with the noise model's order at Ts = 2 ms, so the
order is judged by the mean simulation FIT on the validation data (what G alone explains)
with a parsimony margin: the smallest swept order within ``margin`` FIT points of the best.
Two kinds of order do not count, whatever FIT they gain:

* an order whose added poles the models cancel with zeros (:func:`cancelling_order`): its
  models carry at least one more near pole-zero cancellation each, on average, per order
  added, than the order below's, so the data support no further pole; the search stops
  there, and the orders above it do not count either;
* an order whose models lie farther from the best linear approximation than those of every
  lower order (:func:`away_from_bla`, simulated data): what it gains is output the input
  does not explain linearly.

The choice is *settled* when a higher order was swept (it gained less than the margin, or
did not count); at the top of the swept grid it is not, and the decision says which order
to add.  The information criterion's minimum and the physical model's number of states are
shown beside it as evidence.  Why cancellations stop the search: docs/decisions/0006-orders-stop-at-cancelled-poles.md.
"""

from __future__ import annotations

import math

from maglev.lab.decision import Decision

__all__ = ["ORDER_MARGIN", "away_from_bla", "cancelling_order", "final_order", "order_status", "orders_decision",
           "statuses"]

ORDER_MARGIN = 1.0  # simulation FIT points a higher order must gain to count as needed
CANCEL_STEP = 1.0  # mean near cancellations per model, per order added, from which the added poles are cancelled


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


def cancelling_order(cancellations: dict[int, float] | None, grid: list[int]) -> int | None:
    """The lowest swept order whose models carry, on average, at least ``CANCEL_STEP`` more near pole-zero
    cancellations per order added than those of the swept order below (``cancellations``: mean count per model
    by order): the poles it adds are cancelled by zeros, so the data support no further pole.  None when no
    order does (or without counts)."""
    if not cancellations:
        return None
    counted = [o for o in grid if o in cancellations]
    for low, high in zip(counted, counted[1:]):
        if cancellations[high] - cancellations[low] >= CANCEL_STEP * (high - low) - 1e-9:
            return high
    return None


def _eligible(grid: list[int], bla: dict[int, float] | None, cancellations: dict[int, float] | None) -> list[int]:
    cut = cancelling_order(cancellations, grid)
    away = away_from_bla(bla, grid)
    return [o for o in grid if (cut is None or o < cut) and o not in away]


def final_order(fit: dict[int, float], margin: float = ORDER_MARGIN, bla: dict[int, float] | None = None,
                cancellations: dict[int, float] | None = None) -> tuple[int, bool]:
    """(order, settled) for one structure's mean validation simulation FIT by order: the smallest order within
    ``margin`` points of the best among the orders that count — below the first order whose added poles are
    cancelled (:func:`cancelling_order`; mean near cancellations per model ``cancellations``) and not moving away
    from the BLA (:func:`away_from_bla`; mean distance ``bla``); settled when a higher order was swept (it gained
    less than ``margin``, or did not count)."""
    if not fit:
        raise ValueError("final_order: no orders with a FIT")
    grid = sorted(fit)
    eligible = _eligible(grid, bla, cancellations)
    best = max(fit[o] for o in eligible)
    chosen = min(o for o in eligible if fit[o] >= best - margin)
    return chosen, chosen < grid[-1]


def order_status(fit: dict[int, float], margin: float = ORDER_MARGIN, bla: dict[int, float] | None = None,
                 cancellations: dict[int, float] | None = None) -> dict[int, str]:
    """Each swept order's place in :func:`final_order`'s choice, as a phrase: ``"final"`` (settled), ``"final, not
    settled"``, or why it is not the final order (its poles cancelled, above a cancelling order, away from the
    BLA, within ``margin`` of the final order, more than ``margin`` below the best)."""
    grid = sorted(fit)
    chosen, settled = final_order(fit, margin, bla, cancellations)
    cut = cancelling_order(cancellations, grid)
    away = away_from_bla(bla, grid)
    best = max(fit[o] for o in _eligible(grid, bla, cancellations))
    out = {}
    for o in grid:
        if o == chosen:
            out[o] = "final" if settled else "final, not settled"
        elif cut is not None and o == cut:
            out[o] = "its added poles are cancelled by zeros"
        elif cut is not None and o > cut:
            out[o] = f"above order {cut}, whose added poles are cancelled by zeros"
        elif o in away:
            out[o] = "its models move away from the best linear approximation"
        elif o > chosen:
            out[o] = f"gains {fit[o] - fit[chosen]:+.2f} points over order {chosen}, less than {margin:g}"
        else:
            out[o] = f"{best - fit[o]:.2f} points below the best, more than {margin:g}"
    return out


def orders_decision(fit: dict[str, dict[int, float]], aic: dict[str, dict[int, float]] | None = None,
                    physics_order: int | None = None, margin: float = ORDER_MARGIN,
                    bla: dict[str, dict[int, float]] | None = None,
                    cancellations: dict[str, dict[int, float]] | None = None) -> Decision:
    """The orders decision: per structure (``fit[structure][order]`` = mean validation simulation FIT over
    the datasets swept at every order; ``aic``, ``bla`` and ``cancellations`` likewise the mean AIC, mean
    distance to the best linear approximation (simulated data only) and mean number of near pole-zero
    cancellations per model), the final order and why; each evidence row's ``status`` is the order's place in
    the choice (:func:`order_status`)."""
    aic, bla, cancellations = aic or {}, bla or {}, cancellations or {}
    choice, rows, reasons, cautions = {}, [], [], []
    for st, by in fit.items():
        st_bla, st_cancel = bla.get(st, {}), cancellations.get(st, {})
        chosen, settled = final_order(by, margin, st_bla, st_cancel)
        status = order_status(by, margin, st_bla, st_cancel)
        grid = sorted(by)
        away = sorted(away_from_bla(st_bla, grid))
        cut = cancelling_order(st_cancel, grid)
        st_aic = aic.get(st, {})
        aic_min = min(st_aic, key=st_aic.get) if st_aic else None
        prev = None
        for o in grid:
            rows.append({"structure": st, "order": o, "mean simulation FIT (%)": by[o],
                         "gain over the order below": None if prev is None else by[o] - by[prev],
                         "mean AIC": st_aic.get(o, math.nan), "mean distance to the BLA": st_bla.get(o, math.nan),
                         "mean near cancellations": st_cancel.get(o, math.nan), "final": o == chosen,
                         "status": status[o]})
            prev = o
        choice[st] = chosen
        listed = ", ".join(f"{o}: {by[o]:.2f} %" for o in grid)
        extra = []
        if aic_min is not None:
            extra.append(f"AIC is lowest at order {aic_min}")
        if physics_order is not None:
            extra.append(f"the physical model has {physics_order} states")
        tail = f" ({'; '.join(extra)})" if extra else ""
        name = st.upper()
        parts = []  # why the orders that do not count do not (the mean FIT by order is the report's table)
        if cut is not None:
            below = max(o for o in grid if o < cut and o in st_cancel)
            above = [o for o in grid if o > cut]
            parts.append(f"order {cut} adds poles its models cancel with zeros ({st_cancel[cut]:.2f} near cancellations "
                         f"per model against {st_cancel[below]:.2f} at order {below}): "
                         + (f"order {cut} and the orders above it ({above}) do not count, whatever FIT they gain"
                            if above else f"order {cut} does not count, whatever FIT it gains"))
        if away:
            parts.append(f"order(s) {away} do not count: their models move away from the best linear approximation "
                         "(mean distance " + ", ".join(f"{o}: {st_bla[o]:.3g}" for o in grid if o in st_bla) + ")")
        if settled:
            counted = [o for o in grid if o > chosen and o not in away and (cut is None or o < cut)]
            if counted:
                parts.append(f"order(s) {counted} gain less than {margin:g} point over order {chosen}: the FIT has "
                             "levelled off")
            reasons.append(f"{name}: order {chosen}, the smallest within {margin:g} point of the best that counts; "
                           + "; ".join(parts) + f"{tail}.")
        else:
            if parts:
                reasons.append(f"{name}: " + "; ".join(parts) + ".")
            cautions.append(f"{name}: order {chosen} is the largest swept ({listed}) and gains more than {margin:g} "
                            f"point over the orders below: its FIT has not levelled off; sweep order {chosen + 1} "
                            f"(++hydra.sweeper.orders.{st}=[{','.join(str(o) for o in [*grid, chosen + 1])}]){tail}.")
    rule = (f"Per structure, the smallest swept order whose mean validation simulation FIT is within {margin:g} "
            "point of the best, among the orders that count: the search stops at the first order whose models carry "
            f"at least {CANCEL_STEP:g} more near pole-zero cancellation each, on average, per order added, than the "
            "order below's (its added poles are cancelled by zeros: the data support no further pole), and an order "
            "whose models move away from the best linear approximation (simulated data) does not count: its FIT gain "
            "is output the input does not explain linearly, not G. The FIT has levelled off when a higher swept order "
            "gained less than that or did not count. AIC's minimum and the physical model's number of states are "
            "shown as evidence.")
    return Decision("orders", rule, choice, rows, reasons, cautions=cautions)


def statuses(decision: Decision | None) -> dict[tuple[str, int], str]:
    """(structure, order) -> the order's status (:func:`order_status`) from an orders decision's evidence rows
    ({} without a decision, or for one logged before its rows had a status)."""
    rows = decision.evidence if decision is not None else []
    return {(str(r["structure"]), int(r["order"])): str(r["status"]) for r in rows if r.get("status")}
