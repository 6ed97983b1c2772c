"""Full garbage collections held off while a study process imports its libraries.

A study process imports Hydra, MLflow (with SQLAlchemy and pandas), SciPy and maglev before its first
run: some 350 000 objects that live as long as the process.  Python's cyclic collector walks all of
them at every full collection, and the imports themselves set off several.  So ``study.py`` (and the
processes it spawns, which run its first lines again: the figure renderer, the BLA process; and the
workers of ``hydra/launcher=parallel``, from joblib's initializer) holds full collections off from its
start (:func:`hold`; the young generations are still collected, so short-lived garbage cycles are freed
as before) and, once its libraries are in, moves what it holds to the permanent generation the collector
never walks (:func:`settle`, :func:`gc.freeze`), then collects as usual: a full collection walks only
what the process made since.  What a launch gains: docs/benchmarks-study.md.
"""

from __future__ import annotations

import gc

__all__ = ["hold", "settle"]

_held: tuple[int, ...] | None = None  # the collector's thresholds before hold()


def hold() -> None:
    """Hold full collections off until :func:`settle`: their threshold (collections of the middle generation
    between two full ones) set out of reach."""
    global _held
    if _held is None:
        _held = gc.get_threshold()
        gc.set_threshold(_held[0], _held[1], 1_000_000)


def settle() -> None:
    """Freeze what the process holds now (its libraries, its start-up state) and collect as usual from
    here on.  A no-op unless :func:`hold` was called: a test's or a notebook's process is left as it is."""
    global _held
    if _held is not None:
        gc.freeze()
        gc.set_threshold(*_held)
        _held = None
