"""maglev.study.heap: a study process holds full garbage collections off while it imports, then freezes
what it holds and collects as usual; a process that never held is left as it is."""

from __future__ import annotations

import contextlib
import gc
import io
import subprocess
import sys
import weakref
from types import SimpleNamespace

import pytest

from maglev.study import heap

from .harness import LEAN, REPO, TINY, launch

pytestmark = pytest.mark.filterwarnings("ignore:The .*noload.* loader strategy is deprecated")


@pytest.fixture
def held():
    """:func:`heap.hold` in this process, settled again whatever the test does (what it froze stays frozen)."""
    gc.collect()  # the garbage of earlier tests is not frozen with what the test settles
    before = gc.get_threshold(), gc.get_freeze_count()
    heap.hold()
    yield before
    heap.settle()
    assert gc.get_threshold() == before[0]


class Node:
    pass


def test_held_full_collections_wait_for_settle_while_young_garbage_cycles_are_still_freed(held):
    thresholds, frozen = held
    assert gc.get_threshold() == (*thresholds[:2], 1_000_000)
    freed = []
    gc.collect(0)  # counts restart: the node below is made and dropped before the next young collection
    node = Node()
    node.me = node  # a cycle: only the collector frees it
    weakref.finalize(node, freed.append, True)
    del node
    keep = [[] for _ in range(20 * thresholds[0])]  # enough new containers for the young generations' turn
    assert freed == [True] and keep
    heap.settle()
    assert gc.get_threshold() == thresholds and gc.get_freeze_count() > frozen
    again = gc.get_freeze_count()
    heap.settle()  # once settled (or never held), settle changes nothing
    assert gc.get_freeze_count() == again and gc.get_threshold() == thresholds


def test_study_py_holds_full_collections_from_its_first_imports():
    code = f"import gc, runpy; runpy.run_path({str(REPO / 'study.py')!r}); print(gc.get_threshold()[2])"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True, cwd=REPO)
    assert out.stdout.split() == ["1000000"], out.stderr


@pytest.mark.parametrize("multirun", [True, False], ids=["sweep", "single run"])
def test_a_sweep_settles_at_its_start_and_a_single_run_once_it_has_its_store(held, migrated_store, monkeypatch,
                                                                              multirun):
    from maglev.study import job

    thresholds, frozen = held
    seen = []  # the full collections' threshold as each job reaches its settle()

    def settle():
        seen.append(gc.get_threshold()[2])
        heap.settle()

    monkeypatch.setattr(job, "heap", SimpleNamespace(settle=settle))
    with contextlib.redirect_stdout(io.StringIO()):
        launch(migrated_store, "dataset=binary_a025", "structure=arx", *TINY, *LEAN, multirun=multirun)
    assert gc.get_threshold() == thresholds and gc.get_freeze_count() > frozen
    assert seen == ([thresholds[2]] if multirun else [1_000_000])  # a sweep's job starts settled


def test_the_parallel_launchers_workers_start_held():
    """``hydra/launcher=parallel`` is joblib's launcher with :func:`heap.hold` as each worker's initializer: a
    worker holds full collections from its start, through its imports, until its first job has its store and
    settles (``job.run``, as a single run does)."""
    pytest.importorskip("hydra_plugins.hydra_joblib_launcher", reason="hydra-joblib-launcher is not installed")
    from hydra import compose, initialize_config_dir
    from hydra.utils import instantiate
    from joblib import Parallel, delayed

    import maglev.study.schema  # noqa: F401

    with initialize_config_dir(version_base="1.3", config_dir=str(REPO / "conf")):
        conf = compose("config", ["hydra/launcher=parallel"], return_hydra_config=True).hydra.launcher
    launcher = instantiate(conf)
    assert launcher.joblib["initializer"] is heap.hold
    # new workers (another idle timeout than an earlier parallel sweep's in this process, whose workers settled)
    fresh = {**launcher.joblib, "backend": "loky", "idle_worker_timeout": 61}
    workers = Parallel(**fresh)(delayed(gc.get_threshold)() for _ in range(4))
    assert [threshold[2] for threshold in workers] == [1_000_000] * 4
