"""Order and delay selection for ARX models (MATLAB's ``arxstruc``, ``selstruc``, ``delayest``).

Choosing na, nb and the delay nk is the first step of every identification in the
lab: ARX fits are linear least squares, so a whole grid of them is cheap and its
validation losses point at sensible orders for the slower ARMAX/OE/BJ fits.  The
regressor matrix is built once for the largest orders and every model in the grid
uses a slice of its columns over the same rows, so the losses are comparable and the
grid costs one small least-squares solve per model.
"""

from __future__ import annotations

import math
from collections.abc import Iterable

import numpy as np
import pandas as pd

from ..data import IOData
from .least_squares import regression
from ..structures import PolySpec
from ..threads import single_threaded_blas

TABLE_COLUMNS = ("na", "nb", "nk", "loss", "n_params", "n_estimation")


@single_threaded_blas  # ≈ 100 small solves: two BLAS threads on a busy 2-core machine cost 3-18x the CPU
def arxstruc(
    est: IOData,
    val: IOData,
    na_range: int | Iterable[int],
    nb_range: int | Iterable[int],
    nk_range: int | Iterable[int],
) -> pd.DataFrame:
    """Validation losses of ARX models for every (na, nb, nk) in the given ranges.

    Each ARX model is fitted by least squares on ``est`` and its loss is the mean
    squared one-step prediction error on ``val`` (MATLAB's arxstruc loss).  All
    models use the same rows t ≥ max(na) and t ≥ max(nk) + max(nb) − 1 of both
    records, so no pre-sample data are needed.  Columns: ``na, nb, nk, loss,
    n_params`` (= na + nb) and ``n_estimation`` (samples in ``est``, used by
    :func:`selstruc`).  Combinations with na = nb = 0 are skipped, and nb = 0
    appears once (with the smallest nk).
    """
    for name, data in (("est", est), ("val", val)):
        if not isinstance(data, IOData):
            raise TypeError(f"arxstruc: {name} must be an IOData, got {type(data).__name__}")
    if not math.isclose(est.Ts, val.Ts, rel_tol=1e-9):
        raise ValueError(f"arxstruc: est has Ts = {est.Ts:g} s but val has Ts = {val.Ts:g} s; expected equal")
    nas = _orders(na_range, "na_range")
    nbs = _orders(nb_range, "nb_range")
    nks = _orders(nk_range, "nk_range")
    na_max, nb_max, nk_min = max(nas), max(nbs), min(nks)
    n_u = max(nks) + nb_max - nk_min if nb_max else 0  # input lags nk_min … max(nk)+max(nb)-1
    first = max(na_max, nk_min + n_u - 1, 0)
    spec = PolySpec("pem", na=na_max, nb=n_u, nk=nk_min)
    d_max = na_max + nb_max
    for name, data in (("est", est), ("val", val)):
        if data.N - first < 2 * d_max + 1:
            raise ValueError(
                f"arxstruc: {name} has {data.N} samples; orders up to na={na_max}, nb={nb_max} with "
                f"delays up to {max(nks)} need at least {first + 2 * d_max + 1}"
            )
    phi_e, y_e = regression(est.y, est.u, spec, first)
    phi_v, y_v = regression(val.y, val.u, spec, first)
    rows = []
    for na in nas:
        for nb in nbs:
            if na + nb == 0:
                continue
            for nk in nks if nb else nks[:1]:  # nk means nothing without an input path
                cols = list(range(na)) + [na_max + nk - nk_min + j for j in range(nb)]
                theta = _lstsq_scaled(phi_e[:, cols], y_e)
                err = y_v - phi_v[:, cols] @ theta
                rows.append((na, nb, nk, float(err @ err) / err.size, na + nb, est.N))
    if not rows:
        raise ValueError("arxstruc: every combination has na = nb = 0; expected at least one parameter")
    return pd.DataFrame(rows, columns=list(TABLE_COLUMNS))


def _lstsq_scaled(phi: np.ndarray, target: np.ndarray) -> np.ndarray:
    """Least squares with unit-norm columns, so the rank cut-off does not depend on the units of u and y."""
    norms = np.linalg.norm(phi, axis=0)
    norms[norms == 0] = 1.0
    theta, *_ = np.linalg.lstsq(phi / norms, target, rcond=None)
    return theta / norms


def selstruc(table: pd.DataFrame, criterion: str | float = "aic") -> tuple[int, int, int]:
    """The (na, nb, nk) of ``table`` (from :func:`arxstruc`) minimising the criterion.

    With V the loss, d = n_params and N the estimation length (MATLAB's selstruc):
    ``"aic"``: V (1 + 2d/N); ``"mdl"``: V (1 + d ln N / N); a number α: V (1 + α d/N)
    (α = 0 picks the smallest validation loss).  Ties go to the fewest parameters.
    """
    if not isinstance(table, pd.DataFrame) or not set(TABLE_COLUMNS) <= set(table.columns):
        raise ValueError(f"selstruc: table must be a DataFrame from arxstruc with columns {list(TABLE_COLUMNS)}")
    if table.empty:
        raise ValueError("selstruc: table is empty")
    N = table["n_estimation"].to_numpy(dtype=float)
    d = table["n_params"].to_numpy(dtype=float)
    if isinstance(criterion, str):
        key = criterion.lower()
        if key == "aic":
            alpha = 2.0
        elif key == "mdl":
            alpha = np.log(N)
        else:
            raise ValueError(f"selstruc: criterion must be 'aic', 'mdl' or a number >= 0, got {criterion!r}")
    elif isinstance(criterion, (int, float, np.integer, np.floating)) and not isinstance(criterion, bool) \
            and math.isfinite(criterion) and criterion >= 0:
        alpha = float(criterion)
    else:
        raise ValueError(f"selstruc: criterion must be 'aic', 'mdl' or a number >= 0, got {criterion!r}")
    modified = table["loss"].to_numpy(dtype=float) * (1.0 + alpha * d / N)
    best = np.lexsort((d, modified))[0]
    row = table.iloc[best]
    return int(row["na"]), int(row["nb"]), int(row["nk"])


def delayest(data: IOData, na: int = 2, nb: int = 2, nk_min: int = 0, nk_max: int = 10) -> int:
    """The delay nk in [nk_min, nk_max] whose ARX [na nb nk] model fits ``data`` best.

    Like MATLAB's delayest: ARX models of fixed orders are fitted for each delay and
    the one with the smallest loss on the same data wins (all have na + nb
    parameters, so no penalty is needed).
    """
    for name, value in (("na", na), ("nb", nb), ("nk_min", nk_min), ("nk_max", nk_max)):
        _orders(value, name)
    if nb < 1:
        raise ValueError(f"delayest: nb must be >= 1 (a delay needs an input path), got {nb}")
    if nk_max < nk_min:
        raise ValueError(f"delayest: nk_max must be >= nk_min = {nk_min}, got {nk_max}")
    table = arxstruc(data, data, na, nb, range(nk_min, nk_max + 1))
    return selstruc(table, 0)[2]


def _orders(values: int | Iterable[int], name: str) -> list[int]:
    """A sorted list of distinct non-negative integers from an integer or an iterable of them."""
    if isinstance(values, (int, np.integer)):
        items = [values]
    elif isinstance(values, Iterable) and not isinstance(values, str):
        items = list(values)
    else:
        raise ValueError(f"{name} must be a non-negative integer or a range of them, got {values!r}")
    if not items:
        raise ValueError(f"{name} must be a non-negative integer or a non-empty range of them, got {values!r}")
    for v in items:
        if isinstance(v, (bool, np.bool_)) or not isinstance(v, (int, np.integer)) or v < 0:
            raise ValueError(f"{name} must hold non-negative integers, got {v!r}")
    return sorted({int(v) for v in items})
