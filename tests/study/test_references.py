"""A sweep's ranking waits for its configs' runs in other launches (two users sweeping into one server):
``claims.wait_for_references``, bounded; the cluster harness runs the two users for real."""

from __future__ import annotations

import os
import socket
import threading
import time

import pytest

pytestmark = pytest.mark.filterwarnings("ignore:The .*noload.* loader strategy is deprecated")


@pytest.fixture
def store(migrated_store):
    from maglev.study import tracking

    uri = f"sqlite:///{migrated_store}/mlflow.db"
    return tracking.connect({"uri": uri, "experiment": "maglev", "artifact_location": str(migrated_store / "a")})


def referenced_running(client, exp, parent, pid: int) -> str:
    """A model run of another sweep, RUNNING in process ``pid`` of this host, that ``parent`` references."""
    from maglev.study.claims import reference

    run = client.create_run(exp, tags={"kind": "model", "config_hash": "h", "host": socket.gethostname(),
                                       "pid": str(pid)})
    reference(client, client.get_run(run.info.run_id), parent, "mine")
    return run.info.run_id


def test_the_ranking_waits_for_a_referenced_run_until_it_ends(store):
    from maglev.study.claims import wait_for_references

    client, exp = store
    parent = client.create_run(exp, tags={"kind": "sweep"}).info.run_id
    other = referenced_running(client, exp, parent, os.getpid())  # a live process: its run is not stale
    threading.Timer(1.0, client.set_terminated, (other, "FINISHED")).start()
    tic = time.monotonic()
    assert wait_for_references(client, exp, parent, timeout_s=60, poll_s=0.2) == []
    assert 0.9 < time.monotonic() - tic < 30


def test_the_wait_is_bounded_and_names_what_is_still_running(store):
    from maglev.study.claims import wait_for_references

    client, exp = store
    parent = client.create_run(exp, tags={"kind": "sweep"}).info.run_id
    other = referenced_running(client, exp, parent, os.getpid())
    tic = time.monotonic()
    left = wait_for_references(client, exp, parent, timeout_s=0.5, poll_s=0.1)
    assert [r.info.run_id for r in left] == [other] and time.monotonic() - tic < 10


def test_a_referenced_run_of_a_dead_process_is_not_waited_for(store):
    import subprocess
    import sys

    from maglev.study.claims import wait_for_references

    client, exp = store
    parent = client.create_run(exp, tags={"kind": "sweep"}).info.run_id
    gone = subprocess.run([sys.executable, "-c", "import os; print(os.getpid())"], capture_output=True, text=True)
    referenced_running(client, exp, parent, int(gone.stdout))
    assert wait_for_references(client, exp, parent, timeout_s=60, poll_s=0.1) == []
