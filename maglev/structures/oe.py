"""Output error  y = B(q)/F(q) u + e  (MATLAB's ``oe [nb nf nk]``): prediction-error minimisation."""

from maglev.structures.registry import Structure, register

OE = register(Structure(
    "oe", ("nb", "nf", "nk"), "y = B(q)/F(q) u + e",
    "Models G only, with white output noise; G is unbiased even when the noise is coloured, and the "
    "one-step prediction equals the simulation."))
