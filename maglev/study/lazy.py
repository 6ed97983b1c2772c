"""Modules imported when first used, so that a command that ends early never pays for them."""

from __future__ import annotations

import importlib.util
import sys
from types import ModuleType


def lazy_module(name: str) -> ModuleType:
    """The module ``name``, executed on its first attribute access (the standard library's ``LazyLoader``);
    the module itself when it is imported already."""
    if name in sys.modules:
        return sys.modules[name]
    spec = importlib.util.find_spec(name)
    if spec is None or spec.loader is None:
        raise ImportError(f"no module named {name!r}")
    loader = importlib.util.LazyLoader(spec.loader)
    spec.loader = loader
    module = importlib.util.module_from_spec(spec)
    sys.modules[name] = module
    loader.exec_module(module)
    return module


def loaded(module: ModuleType) -> bool:
    """Whether ``module`` has run (a lazy module turns into a plain one on its first attribute access).  Code
    that runs at interpreter exit asks first: importing then can fail (no new atexit hooks, threads refused)."""
    return type(module) is ModuleType
