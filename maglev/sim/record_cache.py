"""Simulated records kept on disk: a record is simulated once per machine, not once per sweep.

A lab record of 20 s costs ≈ 0.5 s of CPU to simulate (the integrator is a Python loop over
substeps), and every sweep of the study simulates the same ones again: its datasets and, for the
records decision, the whole simulated lab set (≈ 7 s per sweep).  A record is a deterministic
function of its spec, the plant and the simulator's code, so it is kept under
``$MAGLEV_CACHE/records`` (:func:`maglev.paths.cache_root`) keyed by a hash of all three: the
spec, the plant's parameters and flags, the source of the modules that compute a record and the
numpy and scipy versions.  Any change to the simulator's code makes new entries; the least
recently used beyond :data:`KEEP` are removed.  A hit returns the arrays that were saved, bit for
bit, so a cached record is the record :func:`maglev.sim.labdata.experiment` simulates.
"""

from __future__ import annotations

import contextlib
import functools
import hashlib
import json
import os
from dataclasses import asdict
from pathlib import Path
from typing import Callable

import numpy as np
import scipy

from maglev.data import IOData
from maglev.paths import cache_root, save_npz

__all__ = ["cache_dir", "cache_key", "cached", "KEEP"]

KEEP = 400  # entries kept (≈ 0.8 MB for a 20 s record): the least recently used beyond it are removed
_ARRAYS = ("z", "h", "current")  # the true heights and the coil current the simulator adds to ``meta``
# the modules whose code computes a record: the integrator and its force laws, the input signals, IOData
_SOURCES = ("sim/plant.py", "sim/forces.py", "sim/labdata.py", "lab/signals.py", "data.py")


def cache_dir() -> Path:
    """``$MAGLEV_CACHE/records`` or ``~/.cache/maglev/records``."""
    return cache_root() / "records"


@functools.lru_cache(maxsize=1)
def _code_digest() -> str:
    root = Path(__file__).resolve().parents[1]
    digest = hashlib.sha256()
    for name in _SOURCES:
        digest.update(name.encode())
        digest.update((root / name).read_bytes())
    digest.update(f"numpy {np.__version__} scipy {scipy.__version__}".encode())
    return digest.hexdigest()


def cache_key(spec, name: str, plant) -> str:
    """Hash of everything a simulated record depends on: ``spec`` (an ExperimentSpec), its ``name``, the
    plant (class, parameters, time base, logger quirk) and the simulator's code."""
    what = {"spec": asdict(spec), "name": name, "plant": type(plant).__qualname__, "params": asdict(plant.params),
            "physical_time": plant.physical_time, "zero_at_10": plant.zero_at_10, "code": _code_digest()}
    return hashlib.sha256(json.dumps(what, sort_keys=True, default=float).encode()).hexdigest()[:24]


def _save(path: Path, data: IOData) -> None:
    """Write ``data`` (atomically: processes share the directory); an unwritable directory only costs the
    next launch the simulation."""
    meta = {k: v for k, v in data.meta.items() if k not in _ARRAYS}
    if save_npz(path, u=data.u, y=data.y, meta=json.dumps({"Ts": data.Ts, "name": data.name, "meta": meta}),
                **{k: data.meta[k] for k in _ARRAYS if k in data.meta}):
        _prune(path.parent)


def _load(path: Path) -> IOData | None:
    try:
        with np.load(path) as z:
            head = json.loads(str(z["meta"]))
            arrays = {k: z[k] for k in _ARRAYS if k in z.files}
            u, y = z["u"], z["y"]
    except (OSError, ValueError, KeyError):  # missing, half-written by a crash, unreadable: simulate afresh
        return None
    with contextlib.suppress(OSError):
        os.utime(path)  # recently used: kept by _prune
    return IOData(u=u, y=y, Ts=head["Ts"], name=head["name"], meta={**head["meta"], **arrays})


def _prune(directory: Path) -> None:
    """Remove the least recently used entries beyond :data:`KEEP`."""
    try:
        entries = sorted(directory.glob("*.npz"), key=lambda p: p.stat().st_mtime, reverse=True)
    except OSError:  # an entry removed meanwhile by another process: prune at the next write
        return
    for old in entries[KEEP:]:
        with contextlib.suppress(OSError):
            old.unlink()


def cached(spec, name: str, plant, simulate: Callable[[], IOData]) -> IOData:
    """The record ``simulate()`` gives for (``spec``, ``name``, ``plant``): loaded from :func:`cache_dir` when
    it was simulated before with the same code, else simulated and saved."""
    path = cache_dir() / f"{cache_key(spec, name, plant)}.npz"
    data = _load(path) if path.is_file() else None
    if data is None:
        data = simulate()
        _save(path, data)
    return data
