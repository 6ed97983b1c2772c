"""The slow and service lists of tests/conftest.py name tests that exist: a renamed or moved test would otherwise fall
back into the development loop (`python -m pytest -q -m "not slow" -n 2`) or out of the service stage unnoticed."""

from __future__ import annotations

import ast

import pytest

from tests.conftest import SERVICE, SLOW, TESTS


@pytest.mark.parametrize("listing, entries", [("SLOW", SLOW), ("SERVICE", SERVICE)])
def test_every_entry_names_a_test_file_or_function(listing, entries):
    for entry in entries:
        path, _, name = entry.partition("::")
        file = TESTS / path
        assert file.is_file(), f"{listing} names {path}, which is not a test file"
        if name:
            defined = {n.name for n in ast.walk(ast.parse(file.read_text(encoding="utf-8")))
                       if isinstance(n, ast.FunctionDef)}
            assert name in defined, f"{listing} names {entry}, which {path} does not define"
