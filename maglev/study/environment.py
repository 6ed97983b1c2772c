"""The Python environment a sweep ran in, recorded on its parent run and compared by ``maglev reproduce``.

Each sweep logs ``environment/requirements.txt`` on its parent run: every installed
distribution as ``name==version`` (read with :mod:`importlib.metadata`, as ``pip freeze``
lists them) and the Python version as a comment, so ``pip install -r`` on that file rebuilds
the environment.  ``maglev reproduce`` reads it back and names each package whose version
differs now (or that is missing on one side): a metric that does not reproduce is then
explained by the environment or not.
"""

from __future__ import annotations

import platform
import re

ARTIFACT = "environment/requirements.txt"
PYTHON = "python"  # the interpreter's entry (a comment in the file: pip does not install it)


def canonical(name: str) -> str:
    """A distribution name as pip compares them (PEP 503): lower case, runs of ``-_.`` as one ``-``."""
    return re.sub(r"[-_.]+", "-", name).lower()


def current() -> dict[str, str]:
    """``{name: version}`` of every installed distribution, and ``python``: the interpreter's version."""
    from importlib.metadata import distributions

    found = {PYTHON: platform.python_version()}
    for dist in distributions():
        name = dist.metadata["Name"]
        if name:
            found.setdefault(canonical(name), dist.version)  # the first on sys.path wins, as for imports
    return found


def requirements(env: dict[str, str]) -> str:
    """The ``pip freeze``-style text of ``env`` (python as a comment line)."""
    lines = [f"# {PYTHON}=={env[PYTHON]}"] if PYTHON in env else []
    lines += [f"{name}=={version}" for name, version in sorted(env.items()) if name != PYTHON]
    return "\n".join(lines) + "\n"


def parse(text: str) -> dict[str, str]:
    """Inverse of :func:`requirements` (lines that are not ``name==version`` are skipped)."""
    env = {}
    for line in text.splitlines():
        entry = line.lstrip("# ").strip() if line.startswith(f"# {PYTHON}==") else line.strip()
        if "==" in entry and not entry.startswith("#"):
            name, version = entry.split("==", 1)
            env[canonical(name.strip())] = version.strip()
    return env


def differences(logged: dict[str, str], now: dict[str, str]) -> list[str]:
    """One phrase per package whose version differs: ``numpy 2.3.1 (now 2.4.6)``, ``foo 1.0 (now absent)``,
    ``bar (new, 2.0)``; python first, then by name."""
    out = []
    for name in sorted(set(logged) | set(now), key=lambda n: (n != PYTHON, n)):
        was, is_ = logged.get(name), now.get(name)
        if was == is_:
            continue
        out.append(f"{name} (new, {is_})" if was is None else f"{name} {was} (now {is_ or 'absent'})")
    return out
