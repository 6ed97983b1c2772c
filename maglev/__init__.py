"""maglev: identify linear models of a magnetic levitator from input-output data.

The library is plain numpy/scipy/python-control: ``maglev.data`` (records),
``maglev.estimation`` (ARX, ARMAX, OE, BJ, PEM), ``maglev.model`` (the fitted
``PolyModel``), ``maglev.validation`` (FIT, compare, resid).  Hydra and MLflow appear
only in the study/tracking modules.

The names below are imported on first use (PEP 562): ``from maglev import arx`` works as
before, while a command that needs none of them (``maglev ui``, a launch refused by its
config) does not pay for scipy.signal and the estimators (≈ 1 s of CPU per process).
"""

from __future__ import annotations

import importlib
import importlib.util
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from .data import IOData
    from .estimation import armax, arx, bj, oe, pem
    from .model import FitReport, PolyModel
    from .structures import PolySpec

__all__ = ["IOData", "PolyModel", "PolySpec", "FitReport", "arx", "armax", "oe", "bj", "pem"]
__version__ = "0.1.0"
_HOME = {"IOData": "data", "PolyModel": "model", "FitReport": "model", "PolySpec": "structures",
         **{name: "estimation" for name in ("arx", "armax", "oe", "bj", "pem")}}


def __getattr__(name: str) -> Any:
    """A top-level name (``arx``, ``IOData``, ...) or a submodule (``maglev.validation``), imported now."""
    if name in _HOME:
        value = getattr(importlib.import_module(f"maglev.{_HOME[name]}"), name)
    elif not name.startswith("__") and importlib.util.find_spec(f"maglev.{name}") is not None:
        value = importlib.import_module(f"maglev.{name}")  # `import maglev; maglev.validation.fit` as before
    else:
        raise AttributeError(f"module 'maglev' has no attribute {name!r}")
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    return sorted({*globals(), *__all__})
