"""Shared test fixtures: where the real lab recordings are, and a non-interactive matplotlib."""

from __future__ import annotations

from pathlib import Path

import matplotlib
import pytest

matplotlib.use("Agg")  # before anything imports pyplot (python-control does)

from maglev.calibrate import refdata_dir  # noqa: E402

REPO = Path(__file__).resolve().parents[1]


@pytest.fixture
def refdata() -> Path:
    """The real recordings (``$MAGLEV_REFDATA`` or ``../shared/refdata``), or skip with the reason."""
    path = refdata_dir()
    if path is None or not (path / "el2820_maglev_2022").is_dir():
        pytest.skip(f"real lab data not found at {path or REPO.parent / 'shared' / 'refdata'} "
                    "(set MAGLEV_REFDATA or place ../shared/refdata)")
    return path
