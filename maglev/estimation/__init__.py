"""Estimation: models from data by least squares or prediction-error minimisation.

``estimate`` (by structure name and MATLAB order vector) and MATLAB's ``arx``,
``armax``, ``oe``, ``bj``, ``pem`` in :mod:`.estimators`; ARX's regression and the
starting points' regressions in :mod:`.least_squares`; Levenberg–Marquardt on the
one-step prediction error in :mod:`.prediction_error`; where it starts from in
:mod:`.starts`; delay and order selection (``delayest``, ``arxstruc``, ``selstruc``)
in :mod:`.selection`.
"""

from .estimators import ExcitationWarning, armax, arx, bj, estimate, oe, pem

__all__ = ["ExcitationWarning", "armax", "arx", "bj", "estimate", "oe", "pem"]
