"""ARMAX  A(q) y = B(q) u + C(q) e  (MATLAB's ``armax [na nb nc nk]``): prediction-error minimisation."""

from maglev.structures.registry import Structure, register

ARMAX = register(Structure(
    "armax", ("na", "nb", "nc", "nk"), "A(q) y = B(q) u + C(q) e",
    "Adds a moving-average noise numerator C, so coloured noise no longer biases G (prediction-error "
    "minimisation)."))
