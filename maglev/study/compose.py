"""Each job's config composed once per launch, not three times.

Hydra composes a multirun job's config three times in the launching process: the sweep callback to
check it before any run exists (:func:`maglev.study.callbacks.check_sweep`), the basic sweeper to
validate the batch (``Sweeper.validate_batch_is_legal``) and the basic launcher to run it.  Composing
costs ≈ 90 ms of CPU per job and copying the composed config ≈ 4 ms (2-core machine), so
:func:`memoise` keeps what the check composed and hands the sweeper and the launcher copies of it —
the same configs, 60 compositions fewer in the default sweep's launch of 24 jobs.  A config is
dropped once the launcher has had it; the launchers that compose in other processes (joblib,
submitit) are left alone.
"""

from __future__ import annotations

import copy

USES = 2  # after the check: the sweeper's validation, then the launcher


def memoise(loader) -> None:
    """Make ``loader.load_sweep_config`` (Hydra's config loader of this launch) compose each job once."""
    if getattr(loader, "maglev_memo", None) is not None:
        return
    compose = loader.load_sweep_config
    memo: dict[tuple, list] = {}

    def load_sweep_config(master_config, sweep_overrides):
        key = (id(master_config), tuple(sweep_overrides))
        if key not in memo:
            memo[key] = [compose(master_config, sweep_overrides), -1]  # the first call: the check's own
        entry = memo[key]
        entry[1] += 1
        if entry[1] >= USES:
            del memo[key]
        return copy.deepcopy(entry[0])

    loader.load_sweep_config = load_sweep_config
    loader.maglev_memo = memo
