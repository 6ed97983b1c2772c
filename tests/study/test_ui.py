"""``maglev ui``: a missing store, a taken port, a non-loopback host, SIGTERM (the server on a sweep's store is
tested in test_sweep.py, on its sweep)."""

from __future__ import annotations

import pytest


def test_maglev_ui_refuses_a_missing_store_in_one_line(tmp_path, capsys):
    from maglev.study.cli import main

    missing = tmp_path / "mlflow.db"
    assert main(["ui", "--tracking-uri", f"sqlite:///{missing}"]) == 2
    assert capsys.readouterr().err.strip().splitlines() == [
        f"maglev ui: no MLflow store at {missing}; run a sweep first (python study.py -m +sweep=lab) or pass "
        "--tracking-uri"]
    assert not missing.exists()  # the server would have created it


def test_maglev_ui_refuses_a_taken_port_and_warns_beyond_loopback(migrated_store, capsys):
    """Before: it printed a URL that the other server answered, failed to bind and exited 0."""
    import socket

    from maglev.study.cli import main

    uri = f"sqlite:///{migrated_store}/mlflow.db"
    with socket.socket() as other:  # another server on the port
        other.bind(("127.0.0.1", 0))
        other.listen()
        port = other.getsockname()[1]
        assert main(["ui", "--tracking-uri", uri, "--port", str(port)]) == 2
        err = capsys.readouterr().err.strip()
        assert err == f"maglev ui: port {port} on 127.0.0.1 is taken (Address already in use); pass --port N", err
        assert main(["ui", "--tracking-uri", uri, "--port", str(port), "--host", "0.0.0.0"]) == 2
        warning, refusal = capsys.readouterr().err.strip().splitlines()
    assert warning.startswith("maglev ui: warning: --host 0.0.0.0 serves the store to every machine") and \
        "without authentication" in warning
    assert refusal.startswith(f"maglev ui: port {port} on 0.0.0.0 is taken")


@pytest.mark.slow
def test_sigterm_to_maglev_ui_stops_its_server(migrated_store):
    """Before: SIGTERM ended the command and left its MLflow server running."""
    import signal
    import subprocess
    import sys
    import time
    import urllib.request

    from maglev.study.shutdown import descendants

    from .conftest import free_port
    from .harness import process_env

    port = free_port()
    proc = subprocess.Popen([sys.executable, "-m", "maglev", "ui", "--tracking-uri",
                             f"sqlite:///{migrated_store}/mlflow.db", "--port", str(port)],
                            stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, text=True, env=process_env())
    try:
        line = proc.stdout.readline()  # printed once the server answers
        assert line.startswith(f"MLflow UI: http://127.0.0.1:{port}/"), line
        server = descendants(proc.pid)
        assert server
        proc.send_signal(signal.SIGTERM)
        proc.wait(timeout=60)
        deadline = time.monotonic() + 20
        while time.monotonic() < deadline and any(_running(p) for p in server):
            time.sleep(0.2)
        assert not [p for p in server if _running(p)]
        with pytest.raises(OSError):
            urllib.request.urlopen(f"http://127.0.0.1:{port}/health", timeout=2)
    finally:
        if proc.poll() is None:
            proc.kill()


def _running(pid: int) -> bool:
    try:
        with open(f"/proc/{pid}/stat") as fh:
            return fh.read().rsplit(")", 1)[1].split()[0] != "Z"
    except OSError:
        return False
