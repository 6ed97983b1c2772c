"""The real KTH lab records, read in place from the shared reference data.

Why: calibration, its comparison and the tests all need the same record names,
variable names and search path, and the records must never be copied into the
repository.  The folder is :func:`maglev.paths.refdata_dir` (``$MAGLEV_REFDATA`` or
``../shared/refdata`` next to the checkout; None when absent: callers skip or say so).
"""

from __future__ import annotations

from pathlib import Path

from maglev.data import IOData
from maglev.paths import refdata_dir

__all__ = ["KTH_2022", "RECORDS", "DESIGN_ALPHA", "load_record"]

KTH_2022 = "el2820_maglev_2022"
# record name -> (input variable, output variable, Ts if the file lacks it)
RECORDS: dict[str, tuple[str, str, float | None]] = {
    "working_region": ("u", "y", None),
    "binary_signal_1": ("ub", "yb", 1e-3),
    **{f"binary_signal_{i}": ("u", "y", None) for i in range(2, 11)},
    "white_noise_1": ("u1", "y1", None),
    "white_noise_2": ("u2", "y2", None),
    "white_noise_3": ("u", "y", None),
    "white_noise_4": ("u", "y", None),
}
# the binary records' design switching probability α (the set's datasets.xlsx; 9 and 10 hold a constant input)
DESIGN_ALPHA: dict[str, float] = {f"binary_signal_{i}": a for i, a in
                                  enumerate((0.25, 0.25, 0.5, 0.5, 0.75, 0.75, 1.0, 1.0, 0.0, 0.0), start=1)}


def load_record(name: str, root: Path | None = None) -> IOData:
    """One of the real 2022 KTH records by file stem (e.g. ``"working_region"``)."""
    if name not in RECORDS:
        raise ValueError(f"record must be one of {sorted(RECORDS)}, got {name!r}")
    root = root or refdata_dir()
    if root is None:
        raise ValueError("no reference data: set MAGLEV_REFDATA or provide ../shared/refdata")
    u, y, Ts = RECORDS[name]
    return IOData.from_mat(root / KTH_2022 / f"{name}.mat", u=u, y=y, Ts=Ts)
