"""Model validation on fresh data: FIT %, MATLAB-style ``compare``, residual tests.

The lab ranks models by the one-step-ahead FIT on validation data,
FIT = 100 (1 − ‖y − ŷ‖ / ‖y − ȳ‖), and checks residual whiteness and independence
from the input (``resid``).  ``compare`` follows MATLAB: the initial state of the
predictor is fitted to the data by least squares unless told otherwise.
"""

from __future__ import annotations

import math

import numpy as np

from .data import IOData
from .models import PolyModel


def fit_percent(y: np.ndarray, yhat: np.ndarray) -> float:
    """Normalised root-mean-square fit in percent: 100 (1 − ‖y − ŷ‖ / ‖y − mean(y)‖)."""
    y = np.asarray(y, dtype=float)
    yhat = np.asarray(yhat, dtype=float)
    if y.shape != yhat.shape:
        raise ValueError(f"fit_percent: y has shape {y.shape} but yhat has {yhat.shape}")
    spread = np.linalg.norm(y - y.mean())
    if spread == 0:
        raise ValueError("fit_percent: y is constant, so FIT is undefined")
    return float(100.0 * (1.0 - np.linalg.norm(y - yhat) / spread))


def compare(
    data: IOData,
    model: PolyModel,
    horizon: int | float = 1,
    initial_condition: str = "estimate",
) -> tuple[float, np.ndarray]:
    """(FIT %, ŷ) of ``model``'s ``horizon``-step prediction of ``data`` (``math.inf``: simulation)."""
    if not isinstance(data, IOData):
        raise TypeError(f"compare: data must be an IOData, got {type(data).__name__}")
    if not math.isclose(data.Ts, model.Ts, rel_tol=1e-9):
        raise ValueError(
            f"compare: data {data.name or ''} has Ts = {data.Ts:g} s but the model has Ts = {model.Ts:g} s"
        )
    yhat = model.predict(data, horizon, initial_condition)
    return fit_percent(data.y, yhat), yhat
