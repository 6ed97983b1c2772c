"""The environment record of a sweep: pip's ``name==version`` format, read back exactly, and the
differences named one package at a time (the sweep's parent run and ``maglev reproduce`` are
checked on a real sweep in test_sweep.py)."""

from __future__ import annotations

import importlib.metadata

from maglev.study import environment


def test_the_record_lists_every_installed_distribution_and_reads_back_exactly():
    env = environment.current()
    text = environment.requirements(env)
    assert text.startswith(f"# python=={env['python']}\n") and f"\nnumpy=={importlib.metadata.version('numpy')}\n" in text
    assert len(text.splitlines()) == len(env) and environment.parse(text) == env
    assert len(env) == 1 + len({environment.canonical(d.metadata["Name"]) for d in importlib.metadata.distributions()
                                if d.metadata["Name"]})


def test_differences_name_each_package_python_first():
    logged = {"python": "3.11.9", "numpy": "2.3.1", "scipy": "1.16.0", "gone": "1.0"}
    now = {"python": "3.12.1", "numpy": "2.4.6", "scipy": "1.16.0", "Added": "0.2"}
    assert environment.differences(logged, now) == [
        "python 3.11.9 (now 3.12.1)", "Added (new, 0.2)", "gone 1.0 (now absent)", "numpy 2.3.1 (now 2.4.6)"]
    assert environment.differences(now, now) == []
    assert environment.parse("Typing_Extensions==4.12.2\n-e git+https://x#egg=maglev\n") == {"typing-extensions": "4.12.2"}
