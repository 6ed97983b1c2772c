"""Shared test fixtures: where the real lab recordings are, and a non-interactive matplotlib."""

from __future__ import annotations

import os
from pathlib import Path

import matplotlib
import pytest

matplotlib.use("Agg")

REPO = Path(__file__).resolve().parents[1]


def refdata_dir() -> Path:
    """``$MAGLEV_REFDATA`` or ``../shared/refdata`` beside the repository."""
    return Path(os.environ.get("MAGLEV_REFDATA", REPO.parent / "shared" / "refdata"))


@pytest.fixture
def refdata() -> Path:
    path = refdata_dir()
    if not (path / "el2820_maglev_2022").is_dir():
        pytest.skip(f"real lab data not found at {path} (set MAGLEV_REFDATA or place ../shared/refdata)")
    return path
