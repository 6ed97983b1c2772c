"""Stationary averages of a staircase response (EL2820 Lab 3, preparation tasks 2-3).

The lab asks for two small functions, ``getAverage`` and ``getStationaryAverages``, and
for their code in the report; they live alone in this module so the report can attach
its source (``inspect.getsource``) and every other lab step can reuse them.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

__all__ = ["get_average", "get_stationary_averages", "check_tail"]


def check_tail(tail: float) -> float:
    """``tail`` as a float percentage in (0, 100], or a ValueError naming it."""
    tail_f = float(tail)
    if not 0.0 < tail_f <= 100.0:
        raise ValueError(f"tail must be a percentage in (0, 100], got {tail!r}")
    return tail_f


def get_average(v: Sequence[float] | np.ndarray, tail: float) -> float:
    """Mean of the last ``tail`` percent of ``v`` (at least one sample), the lab's ``getAverage``."""
    tail = check_tail(tail)
    arr = np.asarray(v, dtype=float).reshape(-1)
    if arr.size == 0:
        raise ValueError("v must hold at least one sample, got an empty vector")
    n = max(1, int(round(arr.size * tail / 100.0)))
    return float(arr[-n:].mean())


def get_stationary_averages(y_step: Sequence[float] | np.ndarray, nwr: int, tail: float) -> np.ndarray:
    """``get_average`` of each of the ``nwr`` equal-length levels of a staircase response."""
    y = np.asarray(y_step, dtype=float).reshape(-1)
    if isinstance(nwr, (bool, np.bool_)) or not isinstance(nwr, (int, np.integer)) or nwr < 1:
        raise ValueError(f"nwr must be a positive integer number of levels, got {nwr!r}")
    if y.size == 0 or y.size % nwr:
        raise ValueError(
            f"y_step has {y.size} samples, which is not a multiple of nwr={nwr}; "
            "expected len(y_step) = nwr * samples per level"
        )
    check_tail(tail)
    return np.array([get_average(seg, tail) for seg in y.reshape(nwr, -1)])
