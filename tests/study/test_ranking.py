"""Ranking on a store built here with known metrics (MlflowClient runs in a tmp SQLite store).

Expected orders follow from the metrics set below (val_fit descending, ties to fewer
n_params), never from the code's output.
"""

from __future__ import annotations

import json
import os
import shutil
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from maglev.model import PolyModel

pytestmark = pytest.mark.filterwarnings("ignore:The .*noload.* loader strategy is deprecated")

# name: (structure, orders, dataset, input_class, val_fit, n_params)
RUNS = {
    "arx[2 2 2] · uniform_wide": ("arx", "[2 2 2]", "uniform_wide", "uniform", 90.0, 4),
    "arx[2 2 2] · binary_a025": ("arx", "[2 2 2]", "binary_a025", "binary", 93.0, 4),
    "oe[3 3 2] · uniform_wide": ("oe", "[3 3 2]", "uniform_wide", "uniform", 95.0, 6),
    "oe[2 2 2] · uniform_wide": ("oe", "[2 2 2]", "uniform_wide", "uniform", 95.0, 4),  # tie: simpler wins
    "bj[2 2 2 2 2] · binary_a025": ("bj", "[2 2 2 2 2]", "binary_a025", "binary", 97.5, 8),
    "bj[2 2 2 2 2] · uniform_narrow": ("bj", "[2 2 2 2 2]", "uniform_narrow", "uniform", 80.0, 8),
}
EXPECTED = ["bj[2 2 2 2 2] · binary_a025", "oe[2 2 2] · uniform_wide", "oe[3 3 2] · uniform_wide",
            "arx[2 2 2] · binary_a025", "arx[2 2 2] · uniform_wide", "bj[2 2 2 2 2] · uniform_narrow"]


def model(structure: str, fit: float) -> PolyModel:
    """A small stable model; the pole depends on the FIT so best and worst differ."""
    pole = 0.5 + fit / 400
    A, F = ([1.0, -pole], [1.0]) if structure in ("arx", "armax") else ([1.0], [1.0, -pole])
    return PolyModel(A=A, B=[0.0, 0.0, 0.3], C=[1.0], D=[1.0], F=F, nk=2, Ts=0.002, structure=structure)


def resid_json(outside: float) -> dict:
    lags = list(range(6))
    return {"auto_lags": lags, "auto_corr": [1.0, outside, 0, 0, 0, 0], "auto_band": 0.1,
            "cross_lags": list(range(-5, 6)), "cross_corr": [0.0] * 11, "cross_band": 0.1,
            "whiteness_stat": 3.0, "whiteness_dof": 5, "whiteness_pvalue": 0.5, "white": True,
            "independence_stat": 2.0, "independence_dof": 11, "independence_pvalue": 0.9, "independent": True,
            "auto_outside": outside, "cross_outside": 0.0}


def make_store(tmp_path: Path) -> tuple[str, dict]:
    """A sweep with the RUNS above FINISHED, plus a better FAILED run and a better RUNNING one."""
    from maglev.study import tracking

    uri = f"sqlite:///{tmp_path}/mlflow.db"
    client, exp = tracking.connect({"uri": uri, "experiment": "maglev", "artifact_location": str(tmp_path / "a")})
    parent = client.create_run(exp, run_name="s", tags={"kind": "sweep", "sweep": "s"}).info.run_id
    ids = {}

    def add(name, structure, orders, dataset, cls, fit, n, status):
        tags = {"kind": "model", "structure": structure, "orders": orders, "dataset": dataset,
                "input_class": cls, "val_dataset": f"{dataset}[val]", "sweep": "s", "mlflow.parentRunId": parent,
                "host": "test", "pid": str(os.getpid())}
        rid = client.create_run(exp, run_name=name, tags=tags).info.run_id
        tracking.log_batch(client, rid, metrics={"val_fit": fit, "n_params": n, "val_fit_sim": fit - 1})
        tracking.log_files(client, rid, {"model/model.json": model(structure, fit).to_json(),
                                         "resid/resid.json": resid_json(1 - fit / 100)})
        if status != "RUNNING":
            client.set_terminated(rid, status)
        ids[name] = rid

    for name, spec in RUNS.items():
        add(name, *spec, "FINISHED")
    add("arx[9 9 2] · uniform_wide", "arx", "[9 9 2]", "uniform_wide", "uniform", 99.9, 18, "FAILED")
    add("oe[9 9 2] · binary_a025", "oe", "[9 9 2]", "binary_a025", "binary", 99.8, 18, "RUNNING")
    client.set_terminated(parent, "FINISHED")
    return uri, {"parent": parent, **ids}


@pytest.fixture(scope="module")
def store(tmp_path_factory, migrated_db):
    path = tmp_path_factory.mktemp("rank")
    shutil.copyfile(migrated_db, path / "mlflow.db")
    return make_store(path)


def test_rank_table_orders_by_fit_then_fewer_parameters():
    from maglev.study.ranking import rank_table

    runs = pd.DataFrame([{"run_id": n, "name": n, "structure": s, "orders": o, "dataset": d, "input_class": c,
                          "val_dataset": f"{d}[val]", "val_fit": f, "n_params": k}
                         for n, (s, o, d, c, f, k) in RUNS.items()])
    table = rank_table(runs.sample(frac=1.0, random_state=3))
    assert list(table["name"]) == EXPECTED
    assert list(table["rank"]) == list(range(1, len(EXPECTED) + 1))


def test_choose_structure_prefers_best_structure_with_both_input_classes():
    from maglev.study.ranking import choose_structure, rank_table
    from maglev.study.store import SweepError

    runs = pd.DataFrame([{"run_id": n, "name": n, "structure": s, "orders": o, "dataset": d, "input_class": c,
                          "val_dataset": f"{d}[val]", "val_fit": f, "n_params": k}
                         for n, (s, o, d, c, f, k) in RUNS.items()])
    table = rank_table(runs)
    assert choose_structure(table) == "bj"  # arx and bj have both classes; bj fits best
    assert choose_structure(table, "arx") == "arx"
    with pytest.raises(SweepError, match="only uniform"):
        choose_structure(table, "oe")
    assert choose_structure(table[table["input_class"] == "uniform"]) is None


def test_rank_cli_logs_the_ranking_run(store, capsys):
    from mlflow import MlflowClient

    from maglev.study.cli import main

    uri, ids = store
    assert main(["rank", "--tracking-uri", uri]) == 0
    out = capsys.readouterr().out
    lines = [ln for ln in out.splitlines() if ln.strip()[:2] in ("1.", "2.", "3.", "4.")]
    assert [next(n for n in RUNS if n in ln) for ln in lines] == EXPECTED[:4]
    assert "[9 9 2]" not in out  # FAILED and RUNNING runs are ignored
    assert "1 FAILED" in out and "1 RUNNING" in out

    client = MlflowClient(tracking_uri=uri)
    exp = client.get_experiment_by_name("maglev").experiment_id
    [run] = client.search_runs([exp], filter_string="tags.kind = 'ranking'")
    tags = run.data.tags
    assert tags["sweep_parent"] == ids["parent"] and "mlflow.parentRunId" not in tags
    assert tags["best_run"] == ids[EXPECTED[0]] and tags["worst_run"] == ids[EXPECTED[-1]]
    assert tags["compared_structure"] == "bj"
    assert client.get_run(ids["parent"]).data.tags["ranking_run"] == run.info.run_id
    assert run.data.metrics["n_ranked"] == len(RUNS)
    paths = {a.path for d in ("ranking", "best_vs_worst", "binary_vs_uniform") for a in client.list_artifacts(
        run.info.run_id, d)}
    assert {"ranking/table.csv", "ranking/table.md", "ranking/top4.csv", "ranking/top4.md",
            "best_vs_worst/bode.png", "best_vs_worst/pzmap.png", "best_vs_worst/resid.png",
            "binary_vs_uniform/table.csv", "binary_vs_uniform/table.md", "binary_vs_uniform/fit.png"} <= paths
    local = Path(client.download_artifacts(run.info.run_id, "ranking"))
    assert list(pd.read_csv(local / "table.csv")["name"]) == EXPECTED
    assert list(pd.read_csv(local / "top4.csv")["name"]) == EXPECTED[:4]
    assert "validated on different data" in (local / "top4.md").read_text()
    comp = pd.read_csv(Path(client.download_artifacts(run.info.run_id, "binary_vs_uniform")) / "table.csv")
    assert set(comp["name"]) == {n for n, spec in RUNS.items() if spec[0] == "bj"}


def test_ranking_twice_reuses_the_ranking_run_and_force_logs_a_new_one(store, capsys):
    from mlflow import MlflowClient

    from maglev.study.cli import main

    uri, ids = store
    client = MlflowClient(tracking_uri=uri)
    exp = client.get_experiment_by_name("maglev").experiment_id

    def rankings() -> list[str]:
        return [r.info.run_id for r in client.search_runs([exp], filter_string="tags.kind = 'ranking'")]

    assert main(["rank", "--tracking-uri", uri]) == 0
    before = rankings()
    assert main(["rank", "--tracking-uri", uri]) == 0
    assert rankings() == before and "(reused: it ranked these same runs; --force logs a new one)" in \
        capsys.readouterr().out
    assert main(["rank", "--tracking-uri", uri, "--force"]) == 0
    [new] = set(rankings()) - set(before)
    assert client.get_run(ids["parent"]).data.tags["ranking_run"] == new

    # the ranking run and the parent say what was ranked, with names and links, not bare ids
    run = client.get_run(new)
    link = lambda name: f"[{name.replace('[', '(').replace(']', ')')}](#/experiments/{exp}/runs/{ids[name]}?"  # noqa: E731
    assert (run.data.tags["best_run_name"], run.data.tags["worst_run_name"]) == (EXPECTED[0], EXPECTED[-1])
    note = run.data.tags["mlflow.note.content"]
    assert note.startswith(f"Ranking of sweep s: {len(RUNS)} FINISHED model runs by one-step validation FIT "
                           f"(ties to fewer parameters), 1 FAILED, 1 RUNNING not ranked. Best {EXPECTED[0]} (97.50 %), "
                           f"worst {EXPECTED[-1]} (80.00 %).")
    top = note[note.index("### Top four"):note.index("### Cautions")]
    assert [top.index(link(n)) for n in EXPECTED[:4]] == sorted(top.index(link(n)) for n in EXPECTED[:4])
    assert link(EXPECTED[4]) not in top and "### Cautions (" in note
    parent = client.get_run(ids["parent"]).data.tags["mlflow.note.content"]
    assert parent.startswith(f"Sweep s: {len(RUNS) + 2} model runs (1 FAILED, {len(RUNS)} FINISHED, 1 RUNNING) of ")
    assert f"Best {EXPECTED[0]} with one-step validation FIT 97.50 %" in parent
    assert all(link(n) in parent for n in EXPECTED[:4]) and "### Cautions (" in parent


def test_reproduce_refuses_what_it_cannot_reproduce_in_one_line(store, capsys):
    from maglev.study.cli import main

    uri, ids = store
    failed = ids["arx[9 9 2] · uniform_wide"]
    for run_id, message in [("nonsense", f"no run 'nonsense' in {uri}"),
                            (ids["parent"], f"run {ids['parent']} (s) is a sweep's parent run, not a model run"),
                            (failed, f"run {failed} (arx[9 9 2] · uniform_wide) is FAILED, not FINISHED")]:
        assert main(["reproduce", run_id, "--tracking-uri", uri]) == 2
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and err[0].startswith(f"maglev reproduce: {message}"), err


def test_structure_option_and_its_errors(store, capsys):
    from maglev.study.cli import main

    uri, _ = store
    assert main(["rank", "--tracking-uri", uri, "--structure", "arx"]) == 0
    assert main(["rank", "--tracking-uri", uri, "--structure", "oe"]) == 2
    assert "needs both binary- and uniform-input runs" in capsys.readouterr().err


def test_missing_store_unknown_and_empty_experiment_are_clear_errors(tmp_path, capsys):
    from maglev.study import tracking
    from maglev.study.cli import main

    def rank(*args: str) -> tuple[int, str]:
        code = main(["rank", *args])
        err = capsys.readouterr().err
        assert len(err.strip().splitlines()) == 1, err  # one line, no traceback
        return code, err

    missing = tmp_path / "none" / "mlflow.db"
    code, err = rank("--tracking-uri", f"sqlite:///{missing}")
    assert code == 2 and "no MLflow store" in err
    assert not missing.exists()  # looking must not create a store

    uri = f"sqlite:///{tmp_path}/mlflow.db"
    client, exp = tracking.connect({"uri": uri, "experiment": "maglev", "artifact_location": str(tmp_path / "a")})
    capsys.readouterr()  # MLflow's own messages while creating the store
    code, err = rank("--tracking-uri", uri, "--experiment", "nope")
    assert code == 2 and "no experiment 'nope'" in err
    code, err = rank("--tracking-uri", uri)
    assert code == 2 and "no sweep yet" in err

    parent = client.create_run(exp, run_name="empty", tags={"kind": "sweep", "sweep": "empty"}).info.run_id
    failed = client.create_run(exp, tags={"kind": "model", "mlflow.parentRunId": parent}).info.run_id
    client.set_terminated(failed, "FAILED")
    code, err = rank("--tracking-uri", uri, "--parent", parent)
    assert code == 2 and "no FINISHED model runs (1 FAILED)" in err
    code, err = rank("--tracking-uri", uri, "--parent", failed)
    assert code == 2 and "not a sweep parent run" in err


def test_parent_id_comes_from_the_environment_else_the_sweep_dir(tmp_path, monkeypatch):
    from maglev.study.tracking import PARENT_ENV, PARENT_FILE, sweep_parent

    monkeypatch.delenv(PARENT_ENV, raising=False)
    assert sweep_parent(str(tmp_path)) is None
    (tmp_path / PARENT_FILE).write_text("from-file\n")
    assert sweep_parent(str(tmp_path)) == "from-file"  # a cluster job: only the shared sweep dir
    # the launching process and its local workers: exact even when another sweep of the same
    # name (same sweep dir) has rewritten the file meanwhile
    monkeypatch.setenv(PARENT_ENV, "from-env")
    assert sweep_parent(str(tmp_path)) == "from-env"
    assert sweep_parent(None) is None  # not a sweep: no parent, whatever the environment says


def test_markdown_table_escapes_and_formats():
    from maglev.study.ranking import markdown

    text = markdown(pd.DataFrame({"a": ["x|y"], "b": [1.23456], "c": [np.nan]}))
    assert text.splitlines() == ["| a | b | c |", "|---|---|---|", "| x\\|y | 1.23 |  |"]


def test_resid_json_round_trips_into_a_resid_result():
    from maglev.validation import ResidResult

    r = ResidResult.from_dict(json.loads(json.dumps(resid_json(0.2))))
    assert r.white and r.auto_outside == 0.2 and list(r.cross_lags) == list(range(-5, 6))
