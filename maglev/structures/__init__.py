"""Model structures: the registry (:mod:`.registry`), the parameter layout (:class:`PolySpec`) and the built-ins.

Importing this package registers ARX, ARMAX, OE, BJ and the general polynomial model;
a new structure is one module calling :func:`register` (see ``docs/architecture.md``).
"""

from maglev.structures import arx, armax, oe, bj, pem  # noqa: F401, I001  (register the built-ins, MATLAB's order)
from maglev.structures.registry import Structure, get, names, register, unregister
from maglev.structures.spec import PolySpec

__all__ = ["Structure", "PolySpec", "register", "unregister", "get", "names"]
