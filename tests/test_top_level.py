"""``maglev``'s top-level names and submodules are reachable from ``import maglev`` although the package
imports them on first use (maglev/__init__.py): a notebook's ``maglev.arx`` and ``maglev.validation.fit``."""

from __future__ import annotations

import sys

import pytest

import maglev


@pytest.mark.parametrize("name, home", [("arx", "maglev.estimation"), ("IOData", "maglev.data"),
                                        ("PolyModel", "maglev.model"), ("PolySpec", "maglev.structures")])
def test_a_top_level_name_is_its_modules_object(monkeypatch, name, home):
    monkeypatch.delitem(maglev.__dict__, name, raising=False)  # as in a fresh interpreter
    assert getattr(maglev, name) is getattr(sys.modules[home] if home in sys.modules else
                                            __import__(home, fromlist=[name]), name)
    assert name in dir(maglev) and name in maglev.__all__


@pytest.mark.parametrize("module", ["validation", "polynomials", "spectral"])
def test_a_submodule_is_an_attribute_of_the_package(monkeypatch, module):
    monkeypatch.delitem(maglev.__dict__, module, raising=False)
    assert getattr(maglev, module) is sys.modules[f"maglev.{module}"]


def test_an_unknown_name_is_an_attribute_error():
    with pytest.raises(AttributeError, match="module 'maglev' has no attribute 'armx'"):
        maglev.armx  # noqa: B018
