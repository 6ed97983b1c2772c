"""ARX  A(q) y = B(q) u + e  (MATLAB's ``arx [na nb nk]``): linear least squares."""

from maglev.structures.registry import Structure, register

ARX = register(Structure(
    "arx", ("na", "nb", "nk"), "A(q) y = B(q) u + e",
    "G and H share the poles of A; linear least squares, so cheap and unique, but the noise model 1/A "
    "is forced."))
