"""``hydra/launcher=slurm``: submitit's Slurm launcher that waits for every job however it ends
(:mod:`maglev.study.slurm` says why), and stops the sweep in one line per job that left no result."""

from __future__ import annotations

from collections.abc import Sequence

try:
    from hydra_plugins.hydra_submitit_launcher.submitit_launcher import SlurmLauncher as _SubmititSlurm
except ImportError:  # hydra-submitit-launcher not installed: hydra/launcher=slurm says so when chosen
    _SubmititSlurm = None

if _SubmititSlurm is not None:

    class SlurmLauncher(_SubmititSlurm):
        def launch(self, job_overrides: Sequence[Sequence[str]], initial_job_idx: int):
            import submitit

            from maglev.study.slurm import collect

            submitted: list = []
            map_array = submitit.AutoExecutor.map_array

            def keep(executor, fn, *iterables):  # submitit's submission, unchanged; the waiting is ours
                submitted.extend(map_array(executor, fn, *iterables))
                return []

            submitit.AutoExecutor.map_array = keep
            try:
                super().launch(job_overrides, initial_job_idx)  # submits and returns [] (nothing to wait for)
            finally:
                submitit.AutoExecutor.map_array = map_array
            return collect(submitted, job_overrides)
