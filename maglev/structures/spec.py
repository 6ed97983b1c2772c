"""The unfitted model: a structure's orders and its parameter layout (scikit-learn's estimator spec).

A `PolySpec` validates the orders once against the structure's registry entry
(:mod:`maglev.structures.registry`), knows the parameter layout ``[a, b, c, d, f]``
and turns a parameter vector into the five polynomials.  MATLAB's order conventions
are kept: ``arx [na nb nk]``, ``armax [na nb nc nk]``, ``oe [nb nf nk]``,
``bj [nb nc nd nf nk]``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from maglev.structures.registry import POLYNOMIAL_ORDERS, get


@dataclass(frozen=True)
class PolySpec:
    """Orders of A(q) y = B(q)/F(q) u + C(q)/D(q) e for one structure."""

    structure: str
    na: int = 0
    nb: int = 0
    nc: int = 0
    nd: int = 0
    nf: int = 0
    nk: int = 1

    def __post_init__(self) -> None:
        entry = get(self.structure)
        for key in ("na", "nb", "nc", "nd", "nf", "nk"):
            value = getattr(self, key)
            if isinstance(value, (bool, np.bool_)) or not isinstance(value, (int, np.integer)):
                if isinstance(value, (float, np.floating)) and float(value).is_integer():
                    object.__setattr__(self, key, int(value))
                    value = int(value)
                else:
                    raise ValueError(f"{self.structure}: order {key} must be an integer >= 0, got {value!r}")
            if value < 0:
                raise ValueError(f"{self.structure}: order {key} must be >= 0, got {value}")
            object.__setattr__(self, key, int(value))
        if "na" not in entry.free and self.nb < 1:
            raise ValueError(f"{self.structure}: nb must be >= 1 (a model with no input path), got {self.nb}")
        if self.na + self.nb == 0:
            raise ValueError(f"{self.structure}: na and nb are both 0; there is nothing to estimate")
        for key in POLYNOMIAL_ORDERS:
            if key not in entry.free and getattr(self, key) != 0:
                raise ValueError(f"{self.structure}: has no {key} (orders are {list(entry.orders)})")

    @classmethod
    def from_orders(cls, structure: str, orders) -> "PolySpec":
        """Build from a MATLAB order vector, e.g. ``("bj", [2, 2, 2, 2, 1])``."""
        names = get(structure).orders
        if isinstance(orders, (str, bytes)) or not hasattr(orders, "__len__"):
            raise ValueError(f"{structure} takes orders [{' '.join(names)}] (a list of {len(names)} integers), "
                             f"got {orders!r}")
        orders = list(orders)
        if len(orders) != len(names):
            raise ValueError(
                f"{structure} takes orders [{' '.join(names)}] ({len(names)} numbers), got {orders}"
            )
        return cls(structure, **dict(zip(names, orders)))

    @property
    def orders(self) -> tuple[int, ...]:
        return tuple(getattr(self, k) for k in get(self.structure).orders)

    @property
    def label(self) -> str:
        return f"{self.structure}[{' '.join(str(o) for o in self.orders)}]"

    @property
    def n_params(self) -> int:
        return self.na + self.nb + self.nc + self.nd + self.nf

    @property
    def max_lag(self) -> int:
        return max(self.na, self.nb + self.nk - 1, self.nc, self.nd, self.nf, 0)

    def polys(self, theta: np.ndarray) -> tuple[np.ndarray, ...]:
        """(A, B, C, D, F) from the parameter vector ``[a, b, c, d, f]``."""
        theta = np.asarray(theta, dtype=float)
        i = 0
        out = []
        for key in ("na", "nb", "nc", "nd", "nf"):
            n = getattr(self, key)
            part = theta[i : i + n]
            i += n
            if key == "nb":
                out.append(np.concatenate([np.zeros(self.nk), part]))
            else:
                out.append(np.concatenate([[1.0], part]))
        return tuple(out)

    def theta(self, A=None, B=None, C=None, D=None, F=None) -> np.ndarray:
        """Parameter vector from polynomials (missing monic ones are 1, missing B is 0)."""
        theta = np.zeros(self.n_params)
        i = 0
        for key, p in zip(("na", "nb", "nc", "nd", "nf"), (A, B, C, D, F)):
            n = getattr(self, key)
            if p is not None:
                first = self.nk if key == "nb" else 1
                vals = np.asarray(p, float)[first : first + n]
                theta[i : i + vals.size] = vals  # missing trailing coefficients stay 0
            i += n
        return theta
