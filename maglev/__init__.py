"""maglev: identify linear models of a magnetic levitator from input-output data.

The library is plain numpy/scipy/python-control: ``maglev.data`` (records),
``maglev.estimation`` (ARX, ARMAX, OE, BJ, PEM), ``maglev.model`` (the fitted
``PolyModel``), ``maglev.validation`` (FIT, compare, resid).  Hydra and MLflow appear
only in the study/tracking modules.
"""

from .data import IOData
from .estimation import armax, arx, bj, oe, pem
from .model import FitReport, PolyModel
from .structures import PolySpec

__all__ = ["IOData", "PolyModel", "PolySpec", "FitReport", "arx", "armax", "oe", "bj", "pem"]
__version__ = "0.1.0"
