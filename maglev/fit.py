"""FIT %, the lab's and MATLAB's normalised measure of how well a model reproduces data.

FIT = 100 (1 − ‖y − ŷ‖ / ‖y − mean(y)‖): 100 is a perfect reproduction, 0 is no better
than the mean.  It lives in its own module because both the fitted model's report
(:mod:`maglev.model`) and validation (:mod:`maglev.validation`) use it.
"""

from __future__ import annotations

import numpy as np


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
