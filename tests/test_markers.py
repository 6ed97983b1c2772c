"""The slow marks of tests/conftest.py name tests that exist: a renamed or moved test would otherwise fall back into
the development loop (`python -m pytest -q -m "not slow"`) unnoticed."""

from __future__ import annotations

import ast

from tests.conftest import SLOW, TESTS


def test_every_slow_entry_names_a_test_file_or_function():
    for entry in SLOW:
        path, _, name = entry.partition("::")
        file = TESTS / path
        assert file.is_file(), f"SLOW names {path}, which is not a test file"
        if name:
            defined = {n.name for n in ast.walk(ast.parse(file.read_text(encoding="utf-8")))
                       if isinstance(n, ast.FunctionDef)}
            assert name in defined, f"SLOW names {entry}, which {path} does not define"
