"""The jobs of a sweep: Hydra's basic sweeper's cartesian product, with an order grid per structure.

A sweep config's ``hydra.sweeper.params`` and the command line's sweeps are combined as Hydra's
basic sweeper combines them (every combination; the command line replaces a param of the same
key).  ``hydra.sweeper.orders`` then gives structures their own orders (``{arx: "4,5,6,7",
armax: "4,5"}``, in the params' syntax, or a list): a job of such a structure is swept over
its grid in place of the ``structure.order`` param.  So the structure whose validation
simulation FIT still rises at the top of the common grid is swept further, alone
(:mod:`maglev.lab.orders` decides each structure's order from its own grid).  A
``structure.order`` on the command line applies to every structure: the grids step aside.

Each job keeps the overrides a cartesian sweep gives the same job (``structure=arx
structure.order=6``), so its config, config hash and run are those of the same job in any
other sweep, and a relaunch skips it once it has a FINISHED run.  The sweeper itself is
``hydra_plugins.maglev_sweeper.sweeper.StudySweeper`` (Hydra loads sweepers from the
``hydra_plugins`` package only); :func:`maglev.study.callbacks.check_sweep` checks the grids
before any run exists.
"""

from __future__ import annotations

import itertools
from collections.abc import Iterable, Mapping, Sequence

from hydra.core.override_parser.overrides_parser import OverridesParser
from hydra.core.override_parser.types import Override
from hydra.errors import HydraException

from maglev.study.config import StudyConfigError

__all__ = ["ORDER", "STRUCTURE", "order_grids", "expand", "sweep_jobs"]

STRUCTURE, ORDER = "structure", "structure.order"
GRIDS = "hydra.sweeper.orders"


def _orders(key: str, value: object) -> list[int]:
    """One grid: an int, a list of ints, or a string in the params' syntax (``4,5,6``, ``range(4,8)``)."""
    if isinstance(value, str):
        try:
            parsed = OverridesParser.create().parse_override(f"{ORDER}={value}")
        except HydraException:
            raise StudyConfigError(f"{key}: {value!r} is not a list of orders (expected e.g. 4,5,6 or "
                                   "range(4,8))") from None
        value = list(parsed.sweep_string_iterator()) if parsed.is_sweep_override() else [parsed.value()]
    values = list(value) if isinstance(value, Sequence) and not isinstance(value, str) else [value]
    try:
        orders = sorted({int(str(v)) for v in values})
    except ValueError:
        orders = []
    if not orders or orders[0] < 1:
        raise StudyConfigError(f"{key}: expected orders as integers ≥ 1 (e.g. [4, 5, 6]), got {value!r}")
    return orders


def order_grids(raw: Mapping | None, structures: Iterable[str] | None = None) -> dict[str, list[int]]:
    """``hydra.sweeper.orders`` checked (structure → its orders, ascending); ``structures``: the known
    structure configs (None: not checked).  A mistake raises :class:`StudyConfigError` naming the key."""
    if raw is None:
        return {}
    if not isinstance(raw, Mapping):
        raise StudyConfigError(f"{GRIDS}: expected a mapping structure → orders (e.g. {{arx: '4,5,6'}}), got {raw!r}")
    known = None if structures is None else sorted(structures)
    grids = {}
    for name, value in raw.items():
        key = f"{GRIDS}.{name}"
        if known is not None and name not in known:
            raise StudyConfigError(f"{key}: no structure {name!r} (conf/structure has {', '.join(known)})")
        grids[str(name)] = _orders(key, value)
    return grids


def expand(overrides: Sequence[Override], grids: Mapping[str, list[int]], given: Iterable[str] = (),
           default_structure: str | None = None) -> list[list[str]]:
    """Every job's overrides: the cartesian product of ``overrides`` (the params', then the command line's) as
    ``BasicSweeper.split_arguments`` builds it, with the jobs of each structure in ``grids`` swept over its own
    orders.  ``given``: the keys set on the command line (a ``structure.order`` there applies to every
    structure); ``default_structure``: the structure of jobs that do not override it."""
    lists: dict[str, list[str]] = {}
    for o in overrides:  # a later override of a key replaces an earlier one, in the earlier one's place
        key = o.get_key_element()
        if o.is_sweep_override():
            if not o.is_discrete_sweep():
                raise HydraException(f"the sweeper does not support sweep type: {o.value_type.name}")
            lists[key] = [f"{key}={v}" for v in o.sweep_string_iterator()]
        else:
            lists[key] = [f"{key}={o.get_value_element_as_str()}"]
    if not grids or ORDER in set(given):
        return [list(job) for job in itertools.product(*lists.values())]
    keys = list(lists) if ORDER in lists else [*lists, ORDER]
    at = keys.index(ORDER)
    jobs = []
    for combo in itertools.product(*(lists[k] for k in keys if k != ORDER)):
        structure = next((s.partition("=")[2] for s in combo if s.partition("=")[0] == STRUCTURE), default_structure)
        orders = [f"{ORDER}={o}" for o in grids[structure]] if structure in grids else lists.get(ORDER, [None])
        for order in orders:
            jobs.append(list(combo) if order is None else [*combo[:at], order, *combo[at:]])
    return jobs


def sweep_jobs(params: Mapping | None, arguments: Sequence[str], raw_grids: Mapping | None,
               default_structure: str | None = None, structures: Iterable[str] | None = None,
               parser: OverridesParser | None = None) -> list[list[str]]:
    """Every job's overrides of a sweep: its ``hydra.sweeper.params``, the command line's ``arguments`` and its
    ``hydra.sweeper.orders`` (checked against ``structures``, the known structure configs)."""
    parser = parser or OverridesParser.create()
    grids = order_grids(raw_grids, structures)
    given = [o.key_or_group for o in parser.parse_overrides(list(arguments))]
    specs = [f"{k}={v}" for k, v in (params or {}).items()] + list(arguments)
    return expand(parser.parse_overrides(specs), grids, given, default_structure)
