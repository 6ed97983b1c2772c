"""Shared test fixtures: where the real lab recordings are, and a non-interactive matplotlib."""

from __future__ import annotations

import os
from pathlib import Path

import matplotlib
import pytest

matplotlib.use("Agg")  # before anything imports pyplot (python-control does)

from maglev.paths import refdata_dir  # noqa: E402

REPO = Path(__file__).resolve().parents[1]


@pytest.fixture
def refdata() -> Path:
    """The real recordings (``$MAGLEV_REFDATA`` or ``../shared/refdata``), or skip with the reason."""
    path = refdata_dir()
    if path is None or not (path / "el2820_maglev_2022").is_dir():
        searched = os.environ.get("MAGLEV_REFDATA") or REPO.parent / "shared" / "refdata"
        pytest.skip(f"real lab data not found at {searched} (set MAGLEV_REFDATA or place ../shared/refdata)")
    return path
