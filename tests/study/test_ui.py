"""``maglev ui`` without a store (the server on a sweep's store is tested in test_sweep.py, on its sweep)."""

from __future__ import annotations


def test_maglev_ui_refuses_a_missing_store_in_one_line(tmp_path, capsys):
    from maglev.study.cli import main

    missing = tmp_path / "mlflow.db"
    assert main(["ui", "--tracking-uri", f"sqlite:///{missing}"]) == 2
    assert capsys.readouterr().err.strip().splitlines() == [
        f"maglev ui: no MLflow store at {missing}; run a sweep first (python study.py -m +sweep=lab) or pass "
        "--tracking-uri"]
    assert not missing.exists()  # the server would have created it
