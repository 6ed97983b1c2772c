"""Where the project's things are: the checkout, the real records, the MLflow store, the reports.

One place for the lookups every layer needs (the library's tests, the simulator's
calibration, the study and its commands), with no Hydra or MLflow import, so that
``$MAGLEV_ROOT``, ``$MAGLEV_REFDATA`` and ``$MLFLOW_TRACKING_URI`` mean the same
everywhere.
"""

from __future__ import annotations

import os
from pathlib import Path

__all__ = ["project_root", "refdata_dir", "default_store_uri", "reports_dir", "cache_root", "save_npz"]


def project_root() -> Path:
    """``$MAGLEV_ROOT``, else the checkout holding ``study.py`` and ``conf/``, else the current directory."""
    env = os.environ.get("MAGLEV_ROOT")
    if env:
        return Path(env).resolve()
    here = Path(__file__).resolve().parents[1]
    if (here / "study.py").is_file() and (here / "conf").is_dir():
        return here
    return Path.cwd().resolve()


def refdata_dir() -> Path | None:
    """The real records: ``$MAGLEV_REFDATA``, else ``../shared/refdata`` beside the checkout; None if absent."""
    env = os.environ.get("MAGLEV_REFDATA")
    root = Path(env) if env else project_root().parent / "shared" / "refdata"
    return root if root.is_dir() else None


def default_store_uri() -> str:
    """``$MLFLOW_TRACKING_URI``, else the project's local store ``sqlite:///<root>/mlruns/mlflow.db``."""
    return os.environ.get("MLFLOW_TRACKING_URI", f"sqlite:///{project_root()}/mlruns/mlflow.db")


def reports_dir() -> Path:
    """Where the lab reports are written by default: ``<root>/reports``."""
    return project_root() / "reports"


def cache_root() -> Path:
    """Where results that are costly to recompute and never change are kept: ``$MAGLEV_CACHE``, else
    ``~/.cache/maglev`` (best linear approximations, the empty MLflow store)."""
    root = os.environ.get("MAGLEV_CACHE")
    return Path(root) if root else Path.home() / ".cache" / "maglev"


def save_npz(path: Path, **arrays) -> bool:
    """Write ``arrays`` to the cache entry ``path`` (``numpy.savez``) atomically: a temporary file beside it, then
    renamed, since processes share the cache.  False when it could not be written (an unwritable directory only
    costs the next caller the computation)."""
    import numpy as np

    tmp = path.with_suffix(f".{os.getpid()}.tmp.npz")
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        np.savez(tmp, **arrays)
        os.replace(tmp, path)
    except OSError:
        return False
    return True
