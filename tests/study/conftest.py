"""Fixtures shared by the study's test modules."""

from __future__ import annotations

import contextlib
import io

import pytest

from .harness import launch


@pytest.fixture(scope="session")
def default_sweep(tmp_path_factory):
    """The default sweep as a user runs it (``python study.py -m +sweep=lab``: its datasets at full length, its
    structures and orders, the BLA, the lab steps), ranked and reported by the callback, but without the run
    figures (the report draws its own).  Shared by the report's tests and the default sweep's own checks, so
    the suite runs it once.  Returns (store, report dir, stdout)."""
    store = tmp_path_factory.mktemp("default-sweep")
    out = io.StringIO()
    with contextlib.redirect_stdout(out):
        launch(store, "+sweep=lab", "tracking.log_figures=false", rank=True)
    return store, store / "reports", out.getvalue()
