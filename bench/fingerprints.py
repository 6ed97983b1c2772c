"""The benchmark tables in docs/: the one command that writes each, and the fingerprint of what it measured.

Timings change from run to run, so a table is *current* when it measured what the checkout holds today, not
when its numbers repeat.  Each page carries, in its header, the command that wrote it and a fingerprint: a
SHA-256 over the files that decide what was measured, read as bytes (no import, no benchmark run: a test
recomputes it in a fraction of a second, ``tests/test_bench.py``).

- ``docs/benchmarks.md`` (the estimators): ``bench/estimators.py`` (its cases — true systems, structures,
  orders, record lengths — are in it) and every module of ``maglev`` it imports, followed through their
  own ``maglev`` imports: the estimators and what they call (data, model, structures, polynomials,
  validation, ...).  A change to one of them makes the table stale; a change to the study, the simulator,
  the tests or the docs does not.
- ``docs/benchmarks-study.md`` (what a user of the study waits for): ``bench/study_overhead.py``,
  ``study.py``, every config under ``conf/`` (they decide the default sweep's jobs) and the package's
  version in ``pyproject.toml``.  The study's code is not digested: nearly every module of ``maglev`` runs
  in a sweep, and the table takes minutes to measure and means little on a loaded machine, so it is
  measured again when the sweep's jobs or the bench change, and for each version (docs/development.md).

Standard library only: the scripts import it, and so does the test, at no cost.
"""

from __future__ import annotations

import ast
import hashlib
import re
from dataclasses import dataclass
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
FINGERPRINT = re.compile(r"Fingerprint `([0-9a-f]{16})`")


@dataclass(frozen=True)
class Table:
    """A benchmark page: where it is, the one command that writes it, and how its fingerprint is taken."""

    page: str  # relative to the repository
    command: str
    script: str
    follow_imports: bool  # digest the maglev modules the script imports (and theirs)
    also: tuple[str, ...] = ()  # further files or folders (every .yaml below a folder)
    version: bool = False  # the package's version from pyproject.toml


TABLES = {
    "estimators": Table("docs/benchmarks.md", "python bench/estimators.py --no-peers --markdown docs/benchmarks.md",
                        "bench/estimators.py", follow_imports=True),
    "study": Table("docs/benchmarks-study.md",
                   "python bench/study_overhead.py --launch --markdown docs/benchmarks-study.md",
                   "bench/study_overhead.py", follow_imports=False, also=("study.py", "conf"), version=True),
}


def maglev_imports(path: Path) -> set[str]:
    """The ``maglev`` modules a source file imports anywhere in it (function-level imports too), by name."""
    tree = ast.parse(path.read_bytes(), filename=str(path))
    package = _module_name(path) if path.is_relative_to(REPO / "maglev") else None
    out = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            out |= {a.name for a in node.names if a.name.split(".")[0] == "maglev"}
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:  # relative: from the importing module's package
                if package is None:
                    continue
                parts = package.split(".")
                if path.name != "__init__.py":
                    parts = parts[:-1]
                parts = parts[: len(parts) - node.level + 1]
                base = ".".join([*parts, base] if base else parts)
            if base.split(".")[0] != "maglev":
                continue
            out.add(base)
            out |= {f"{base}.{a.name}" for a in node.names}  # `from maglev.x import y` may name a module y
    return out


def module_files(script: Path) -> list[Path]:
    """The files of the ``maglev`` modules ``script`` imports, followed through their imports (a package's
    ``__init__.py`` with each module inside it), sorted."""
    seen: set[Path] = set()
    todo = [script]
    while todo:
        for name in maglev_imports(todo.pop()):
            parts = name.split(".")
            for i in range(1, len(parts) + 1):  # importing maglev.a.b runs maglev/__init__ and maglev/a/__init__
                path = _module_path(parts[:i])
                if path is not None and path not in seen:
                    seen.add(path)
                    todo.append(path)
    return sorted(seen)


def files(table: Table) -> list[Path]:
    """Every file whose bytes make the table's fingerprint, sorted (the script first)."""
    out = [REPO / table.script]
    if table.follow_imports:
        out += module_files(REPO / table.script)
    for extra in table.also:
        path = REPO / extra
        out += sorted(path.rglob("*.yaml")) if path.is_dir() else [path]
    return out


def fingerprint(table: Table, paths: list[Path] | None = None) -> str:
    """The first 16 hex digits of a SHA-256 over the table's files (relative path and bytes of each) and, if
    asked, the package's version.  ``paths``: ``files(table)``, if the caller has them (following the imports
    parses every module they reach)."""
    digest = hashlib.sha256()
    for path in files(table) if paths is None else paths:
        digest.update(path.relative_to(REPO).as_posix().encode() + b"\0" + path.read_bytes() + b"\0")
    if table.version:
        digest.update(b"version\0" + package_version().encode())
    return digest.hexdigest()[:16]


def package_version() -> str:
    """``version`` of ``[project]`` in pyproject.toml."""
    import tomllib

    return tomllib.loads((REPO / "pyproject.toml").read_text(encoding="utf-8"))["project"]["version"]


def header(table: Table, command: str) -> str:
    """The sentence a page's header carries: the command that wrote it (``command``, as it was run) and the
    fingerprint of what it measured."""
    paths = files(table)
    n = len(paths)
    what = (f"{table.script} and the {n - 1} files of maglev it imports" if table.follow_imports
            else f"{', '.join([table.script, *table.also])} ({n} files) and version {package_version()}")
    return (f"Written by `{command}`. Fingerprint `{fingerprint(table, paths)}` of {what}: a test checks that it is "
            "today's (docs/development.md).")


REPEATS = r"(?: --(?:repeats|reps|sweeps) \d+)*"  # options that change how often a case is timed, not what


def written_by(table: Table, text: str) -> bool:
    """Whether the page says it was written by the table's command, with at most other repeat counts."""
    head, _, tail = table.command.partition(" --markdown ")
    return re.search(f"Written by `{re.escape(head)}{REPEATS} --markdown {re.escape(tail)}`", text) is not None


def stale(table: Table) -> str | None:
    """Why the page is not current (a line ending in the command to run), or None when it is."""
    page = REPO / table.page
    text = page.read_text(encoding="utf-8") if page.is_file() else ""
    found = FINGERPRINT.search(text)
    if not written_by(table, text):
        why = "was not written by its command"
    elif found is None:
        why = "carries no fingerprint"
    elif found.group(1) != (today := fingerprint(table)):
        why = f"measured other code or cases (fingerprint {found.group(1)}, today {today})"
    else:
        return None
    return f"{table.page} {why}: run `{table.command}` to regenerate"


def _module_name(path: Path) -> str:
    parts = list(path.relative_to(REPO).with_suffix("").parts)
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def _module_path(parts: list[str]) -> Path | None:
    base = REPO.joinpath(*parts)
    for path in (base / "__init__.py", base.with_suffix(".py")):
        if path.is_file():
            return path
    return None
