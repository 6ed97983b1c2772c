"""``StudySweeper``: Hydra's basic sweeper with an order grid per structure (:mod:`maglev.study.sweeper`).

Only the jobs it builds differ from the basic sweeper's; batching, validation and launching are
the basic sweeper's.  The logic lives in :mod:`maglev.study.sweeper`, imported on first use so
that Hydra's plugin scan, which imports this module in every process, stays light.
"""

from __future__ import annotations

from typing import Any

from hydra._internal.core_plugins.basic_sweeper import BasicSweeper
from hydra.core.override_parser.types import Override
from omegaconf import OmegaConf


class StudySweeper(BasicSweeper):
    """``hydra.sweeper``: ``params`` as the basic sweeper's, ``orders`` structure → its orders."""

    def __init__(self, max_batch_size: int | None = None, params: dict | None = None,
                 orders: dict | None = None) -> None:
        super().__init__(max_batch_size, params)
        self.orders = OmegaConf.to_container(orders) if OmegaConf.is_config(orders) else orders
        self.arguments: list[str] = []

    def sweep(self, arguments: list[str]) -> Any:
        self.arguments = list(arguments)
        try:
            return super().sweep(arguments)
        except BaseException:  # a job's error, raised once the jobs are done: the sweep's end is not reached
            from maglev.study import shutdown

            shutdown.raise_if_received()  # a signal held since the last job ends the sweep as it says
            raise

    def split_arguments(self, overrides: list[Override], max_batch_size: int | None) -> list[list[list[str]]]:
        """The jobs of :func:`maglev.study.sweeper.expand` in batches of ``max_batch_size`` (the basic sweeper's
        static method, called on the instance by ``BasicSweeper.sweep``)."""
        from hydra.core.override_parser.overrides_parser import OverridesParser

        from maglev.study.sweeper import expand, order_grids

        loader = self.hydra_context.config_loader
        grids = order_grids(self.orders, loader.get_group_options("structure"))
        given = [o.key_or_group for o in OverridesParser.create().parse_overrides(self.arguments)]
        default = self.config.hydra.runtime.choices.get("structure")
        jobs = expand(overrides, grids, given, default)
        return [list(batch) for batch in self.split_overrides_to_chunks(jobs, max_batch_size)]
