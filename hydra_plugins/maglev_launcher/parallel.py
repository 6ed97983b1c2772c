"""``hydra/launcher=parallel``: hydra-joblib-launcher's launcher whose worker processes hold full garbage
collections off from their start, as ``study.py`` does, until their first job has its store
(:mod:`maglev.study.heap`): a worker imports Hydra, MLflow and SciPy before its first job, and the full
collections those imports set off were a quarter of its CPU until then (0.8 of 3.5 s)."""

from __future__ import annotations

try:
    from hydra_plugins.hydra_joblib_launcher.joblib_launcher import JoblibLauncher as _Joblib
except ImportError:  # hydra-joblib-launcher not installed: hydra/launcher=parallel says so when chosen
    _Joblib = None

if _Joblib is not None:

    class JoblibLauncher(_Joblib):
        def __init__(self, **kwargs) -> None:
            from maglev.study import heap

            kwargs.setdefault("initializer", heap.hold)  # joblib hands it to each new loky worker
            super().__init__(**kwargs)
