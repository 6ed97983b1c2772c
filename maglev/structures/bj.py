"""Box–Jenkins  y = B(q)/F(q) u + C(q)/D(q) e  (MATLAB's ``bj [nb nc nd nf nk]``): prediction-error minimisation."""

from maglev.structures.registry import Structure, register

BJ = register(Structure(
    "bj", ("nb", "nc", "nd", "nf", "nk"), "y = B(q)/F(q) u + C(q)/D(q) e",
    "Independent dynamics and noise models, the most flexible of the four (prediction-error "
    "minimisation)."))
