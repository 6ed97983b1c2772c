"""The study's sweeper: the basic sweeper's cartesian product with an order grid per structure
(maglev.study.sweeper, hydra_plugins.maglev_sweeper)."""

from __future__ import annotations

import pytest
from hydra.core.override_parser.overrides_parser import OverridesParser

from maglev.study.config import StudyConfigError
from maglev.study.sweeper import order_grids, sweep_jobs

from .harness import LEAN, TINY, all_runs, launch

pytestmark = pytest.mark.filterwarnings("ignore:The .*noload.* loader strategy is deprecated")

PARAMS = {"dataset": "a,b", "structure": "arx,oe", "structure.order": "1,2"}


def jobs_of(params, arguments=(), grids=None, default=None, structures=None):
    return sweep_jobs(params, list(arguments), grids, default, structures)


def test_without_grids_the_jobs_are_the_basic_sweepers_product():
    from hydra._internal.core_plugins.basic_sweeper import BasicSweeper

    specs = [f"{k}={v}" for k, v in PARAMS.items()] + ["structure.nk=3", "dataset=c,a"]
    basic = BasicSweeper.split_arguments(OverridesParser.create().parse_overrides(specs), None)[0]
    assert jobs_of(PARAMS, ["structure.nk=3", "dataset=c,a"]) == basic
    assert len(basic) == 2 * 2 * 2


def test_a_structures_grid_replaces_the_common_orders_for_its_jobs_only():
    jobs = jobs_of(PARAMS, grids={"arx": "1,2,3"})
    assert jobs == [[f"dataset={d}", f"structure={s}", f"structure.order={o}"]
                    for d in "ab" for s, orders in (("arx", (1, 2, 3)), ("oe", (1, 2))) for o in orders]
    # the same job is written as the cartesian sweep writes it: its config, hash and run are the same
    assert all(job in jobs for job in jobs_of(PARAMS))


def test_a_grid_adds_the_order_key_where_the_params_have_none_and_follows_the_default_structure():
    params = {"dataset": "a"}
    assert jobs_of(params, grids={"arx": [3, 4]}, default="arx") == [["dataset=a", "structure.order=3"],
                                                                     ["dataset=a", "structure.order=4"]]
    assert jobs_of(params, grids={"arx": [3, 4]}, default="oe") == [["dataset=a"]]
    # a structure fixed on the command line takes its grid
    assert jobs_of(PARAMS, ["structure=arx"], {"arx": "range(3,6)"}) == [
        [f"dataset={d}", "structure=arx", f"structure.order={o}"] for d in "ab" for o in (3, 4, 5)]


def test_structure_order_on_the_command_line_applies_to_every_structure():
    assert jobs_of(PARAMS, ["structure.order=5,6"], {"arx": "1,2,3"}) == jobs_of(PARAMS, ["structure.order=5,6"])
    assert {j[2] for j in jobs_of(PARAMS, ["structure.order=5"], {"arx": "1,2,3"})} == {"structure.order=5"}


@pytest.mark.parametrize("raw, grids", [
    ({"arx": "4,5,6,7"}, {"arx": [4, 5, 6, 7]}),
    ({"arx": [7, 4, 5, 4]}, {"arx": [4, 5, 7]}),
    ({"arx": 6, "oe": "range(2,4)"}, {"arx": [6], "oe": [2, 3]}),
    (None, {}),
])
def test_grids_are_read_in_the_params_syntax_or_as_lists(raw, grids):
    assert order_grids(raw, ["arx", "oe"]) == grids


@pytest.mark.parametrize("raw, needle", [
    ({"arxx": "4,5"}, "hydra.sweeper.orders.arxx: no structure 'arxx' (conf/structure has arx, oe)"),
    ({"arx": "four"}, "hydra.sweeper.orders.arx: expected orders as integers ≥ 1"),
    ({"arx": [0, 1]}, "hydra.sweeper.orders.arx: expected orders as integers ≥ 1"),
    ({"arx": "4,,5"}, "hydra.sweeper.orders.arx: '4,,5' is not a list of orders"),
    ("4,5", "hydra.sweeper.orders: expected a mapping structure → orders"),
])
def test_a_wrong_grid_is_refused_with_one_line_naming_the_key(raw, needle):
    with pytest.raises(StudyConfigError) as err:
        order_grids(raw, ["arx", "oe"])
    assert str(err.value).startswith(needle) and "\n" not in str(err.value)


def test_a_wrong_grid_stops_the_launch_before_any_run(migrated_store):
    from maglev.study.callbacks import SweepRefused

    with pytest.raises(SweepRefused, match=r"sweep refused before any run: hydra\.sweeper\.orders\.arxx: no structure"):
        launch(migrated_store, "dataset=binary_a025", "structure=arx,oe", "hydra.sweeper.orders={arxx:[1,2]}",
               *LEAN, *TINY)
    from mlflow import MlflowClient

    client = MlflowClient(tracking_uri=f"sqlite:///{migrated_store}/mlflow.db")
    exp = client.get_experiment_by_name("maglev")
    assert exp is None or client.search_runs([exp.experiment_id]) == []


def test_a_grid_sweep_runs_only_the_orders_it_adds_and_resumes(migrated_store):
    """A cartesian sweep (arx and oe at orders 1, 2), then the same sweep with arx's grid 1-3: the four configs
    that exist are the same configs (same hash, referenced, not run again), arx 3 alone runs; a relaunch of the
    grid sweep has nothing to do."""
    from maglev.study.callbacks import NothingToDo

    store = migrated_store
    common = ["dataset=binary_a025", "structure=arx,oe", "structure.order=1,2", "study.name=grid", *LEAN, *TINY]
    launch(store, *common)
    _, _, first = all_runs(store)
    launch(store, *common[:2], *common[3:], "hydra.sweeper.orders={arx:'1,2,3',oe:'1,2'}")
    _, _, runs = all_runs(store)
    models = [r for r in runs if r.data.tags.get("kind") == "model"]
    orders = sorted((r.data.tags["structure"], int(r.data.params["structure.order"])) for r in models)
    assert orders == [("arx", 1), ("arx", 2), ("arx", 3), ("oe", 1), ("oe", 2)]
    new = [r for r in models if r.info.run_id not in {f.info.run_id for f in first}]
    assert [(r.data.tags["structure"], r.data.params["structure.order"]) for r in new] == [("arx", "3")]
    parents = sorted((r for r in runs if r.data.tags.get("kind") == "sweep"), key=lambda r: r.info.start_time)
    assert len(parents) == 2 and new[0].data.tags["mlflow.parentRunId"] == parents[1].info.run_id
    assert parents[1].data.metrics["runs_finished"] == 1 and parents[1].data.metrics["runs_referenced"] == 4
    with pytest.raises(NothingToDo):
        launch(store, *common[:2], *common[3:], "hydra.sweeper.orders={arx:'1,2,3',oe:'1,2'}")
    assert len(all_runs(store)[2]) == len(runs)


@pytest.mark.parametrize("name, grids", [
    ("lab", {"arx": [4, 5, 6, 7], "armax": [4, 5, 6], "oe": [3, 4, 5], "bj": [3, 4, 5]}),
    ("lab_real", {"arx": [2, 3, 4, 5, 6], "armax": [2, 3, 4, 5, 6, 7], "oe": [2, 3, 4, 5, 6, 7], "bj": [2, 3, 4, 5, 6]}),
])
def test_the_lab_sweeps_declare_each_structures_orders_and_launch_them(name, grids):
    """What `python study.py -m +sweep=NAME` launches and says it launches, from the config alone."""
    from hydra import compose, initialize_config_dir

    from maglev.study.callbacks import sweep_jobs as launched, sweep_size

    from .harness import CONF

    with initialize_config_dir(version_base="1.3", config_dir=str(CONF)):
        cfg = compose("config", overrides=[f"+sweep={name}"], return_hydra_config=True)
        jobs = launched(cfg)
    datasets = cfg.hydra.sweeper.params["dataset"].split(",")
    swept = {}
    for job in jobs:
        values = dict(o.split("=", 1) for o in job if not o.startswith("+"))
        swept.setdefault(values["structure"], []).append(int(values["structure.order"]))
    assert {st: sorted(set(orders)) for st, orders in swept.items()} == grids
    assert all(len(orders) == len(datasets) * len(grids[st]) for st, orders in swept.items())
    assert sweep_size(cfg) == len(jobs) == len(datasets) * sum(map(len, grids.values()))


def test_the_sweeps_description_lists_each_structures_orders_when_they_differ():
    from types import SimpleNamespace

    from maglev.study.ranking import swept

    def run(i, structure, orders):
        return SimpleNamespace(info=SimpleNamespace(start_time=i),
                               data=SimpleNamespace(tags={"dataset": "b", "structure": structure, "orders": orders}))

    grid = [run(0, "arx", "[4 4 2]"), run(1, "arx", "[6 6 2]"), run(2, "oe", "[4 4 2]"), run(3, "oe", "[5 5 2]")]
    assert swept(grid) == "1 dataset(s) (b) × 2 structure(s) (arx, oe) × orders (arx: 4, 6; oe: 4, 5)"
    assert swept(grid[2:] + [run(4, "arx", "[5 5 2]"), run(5, "arx", "[4 4 2]")]) == \
        "1 dataset(s) (b) × 2 structure(s) (oe, arx) × orders 4, 5"
