"""The registry of model structures: one entry per structure, read by everything that needs to know one.

A :class:`Structure` says which polynomials of A y = B/F u + C/D e are free (MATLAB's
order vector, e.g. ``[nb nc nd nf nk]`` for BJ), how it is estimated (least squares
when only A and B are free, prediction-error minimisation otherwise — derived, not
declared), and a description for reports.  The parameter layout (:class:`PolySpec`),
the fitted model's order vector, the study's config schemas, the report's text and
the ranking's choices all read it, so adding a structure is one module that calls
:func:`register` (plus a ``conf/structure/<name>.yaml`` for the study).
"""

from __future__ import annotations

from dataclasses import dataclass

__all__ = ["POLYNOMIAL_ORDERS", "Structure", "register", "unregister", "get", "names"]

POLYNOMIAL_ORDERS = ("na", "nb", "nc", "nd", "nf")  # orders of A, B, C, D, F (nk is B's delay)


@dataclass(frozen=True)
class Structure:
    """One model structure: its name, MATLAB order vector, equation and description."""

    name: str
    orders: tuple[str, ...]  # MATLAB's order vector, nk last
    equation: str  # e.g. "y = B(q)/F(q) u + C(q)/D(q) e"
    description: str  # what it models and how it is estimated, one or two sentences

    def __post_init__(self) -> None:
        if not self.name.isidentifier() or self.name != self.name.lower():
            raise ValueError(f"structure name must be a lower-case identifier, got {self.name!r}")
        unknown = [k for k in self.orders if k not in POLYNOMIAL_ORDERS + ("nk",)]
        if unknown or not self.orders or self.orders[-1] != "nk" or "nb" not in self.orders:
            raise ValueError(f"structure {self.name!r}: orders must be some of {list(POLYNOMIAL_ORDERS)} "
                             f"including nb, then nk last; got {list(self.orders)}")

    @property
    def free(self) -> tuple[str, ...]:
        """The free polynomial orders (the order vector without nk)."""
        return self.orders[:-1]

    @property
    def least_squares(self) -> bool:
        """Only A and B free: the one-step predictor is linear in the parameters (MATLAB's arx)."""
        return set(self.free) <= {"na", "nb"}

    @property
    def label(self) -> str:
        """The order vector as MATLAB writes it, e.g. ``[nb nc nd nf nk]``."""
        return "[" + " ".join(self.orders) + "]"


_REGISTRY: dict[str, Structure] = {}


def register(structure: Structure) -> Structure:
    """Add ``structure`` (a name registered twice must be the same structure); return it."""
    known = _REGISTRY.get(structure.name)
    if known is not None and known != structure:
        raise ValueError(f"structure {structure.name!r} is already registered as {known}")
    _REGISTRY[structure.name] = structure
    return structure


def unregister(name: str) -> None:
    """Remove a structure (for structures registered by a test or a notebook session)."""
    _REGISTRY.pop(name, None)


def get(name: str) -> Structure:
    """The registered structure ``name``, or a ValueError listing the known ones."""
    try:
        return _REGISTRY[name]
    except (KeyError, TypeError):
        raise ValueError(f"unknown structure {name!r}; expected one of {list(_REGISTRY)}") from None


def names() -> tuple[str, ...]:
    """Registered structure names, in registration order."""
    return tuple(_REGISTRY)
