"""The general polynomial model  A(q) y = B(q)/F(q) u + C(q)/D(q) e  (MATLAB's ``pem``/``idpoly``)."""

from maglev.structures.registry import Structure, register

PEM = register(Structure(
    "pem", ("na", "nb", "nc", "nd", "nf", "nk"), "A(q) y = B(q)/F(q) u + C(q)/D(q) e",
    "Every polynomial free; the structures above are its special cases (prediction-error minimisation)."))
