"""End to end: tiny sweeps of the study (in-process, Hydra's API) into a temporary MLflow store."""

from __future__ import annotations

import contextlib
import json
import math
import os
import shutil
import signal
import socket
import subprocess
import sys
import urllib.request
from pathlib import Path

import pytest

from maglev.study.shutdown import descendants

from .harness import LEAN, REPO, TINY, all_runs, artifact_paths, default_ctrl_c, launch, study_log

FIGURES = {"figures/compare.png", "figures/resid.png", "figures/pzmap.png", "figures/bode.png", "figures/step.png"}

pytestmark = pytest.mark.filterwarnings("ignore:The .*noload.* loader strategy is deprecated")


@pytest.fixture(scope="module")
def sweep(tmp_path_factory, migrated_db):
    """2 datasets × 2 structures into an empty store; the study's log lines are kept."""
    store = tmp_path_factory.mktemp("study")
    shutil.copyfile(migrated_db, store / "mlflow.db")
    args = ["dataset=uniform_narrow,binary_a025", "structure=arx,oe", *TINY, "study.name=tiny"]
    with study_log() as lines:
        launch(store, *args)
    return store, args, lines


def test_sweep_runs_are_finished_children_with_metrics_and_artifacts(sweep):
    store, _, lines = sweep
    client, _, runs = all_runs(store)
    parents = [r for r in runs if r.data.tags.get("kind") == "sweep"]
    kids = [r for r in runs if r.data.tags.get("kind") == "model"]
    assert len(parents) == 1 and len(kids) == 4
    parent = parents[0]
    assert parent.info.run_name == "tiny" and parent.info.status == "FINISHED"
    assert parent.data.metrics["runs_finished"] == 4
    assert {"lab/working_region.png", "lab/rise_time.png", "lab/output_spectrum.png", "lab/alpha.png",
            "lab/lab.json", "lab/decisions.json"} <= artifact_paths(client, parent.info.run_id)
    assert 0 < parent.data.metrics["lab.alpha_star"] <= 1
    assert any("lab steps" in line and "made in the background while the runs go on" in line for line in lines)
    from maglev.lab.decision import read_decisions  # the schema the report reads: every decision, with its rule
    decisions = read_decisions(json.loads(open(client.download_artifacts(parent.info.run_id, "lab/decisions.json")).read()))
    assert {"working_region", "records", "data_length", "alpha", "delay"} <= set(decisions)
    assert decisions["records"].forced and all(d.rule and d.reasons for d in decisions.values())
    names = set()
    for r in kids:
        assert r.info.status == "FINISHED"
        assert r.data.tags["mlflow.parentRunId"] == parent.info.run_id
        t, m = r.data.tags, r.data.metrics
        assert t["input_class"] == ("binary" if t["dataset"] == "binary_a025" else "uniform")
        assert t["val_dataset"] == f"{t['dataset']}[val]" and len(t["config_hash"]) == 40
        assert t["git_commit"] and t["orders"] == "[2 2 2]" and t["sweep"] == "tiny"
        for key in ("val_fit", "val_fit_sim", "est_fit", "loss", "fpe", "aic", "bic", "n_params",
                    "fit_seconds", "iterations", "whiteness_pvalue", "whiteness_pass",
                    "independence_pvalue", "independence_pass", "g_h2_rel_err", "dcgain_rel_err",
                    "val_fit_naive", "g_bla_err", "g_bla_err_stationary", "g_bla_err_unweighted", "bla_fit_ceiling", "near_cancellations"):
            assert key in m, key
        # ARX one step ahead is at least y(t-1): far above it on the binary input, at most a point below it on white
        # noise, where the default plant's wander (driven by small command steps) owns much of the output, as on
        # the rig's white_noise_2 (ARX 76.64 % against y(t-1)'s 76.6 % at 1 ms). Output error's prediction is its
        # simulation, which must still beat the output's mean, as OE(2,2,2) does on the rig's binary_signal_1-3
        # (docs/decisions/0002-default-plant.md)
        binary = t["dataset"] == "binary_a025"
        if t["structure"] == "arx":
            assert m["val_fit"] > m["val_fit_naive"] + (5 if binary else -1), (r.info.run_name, m["val_fit"])
        else:
            assert m["val_fit"] > 0, (r.info.run_name, m["val_fit"])
        assert m["n_params"] == 4 and m["n_est"] == m["n_val"] == 875
        assert r.data.params["structure.name"] == t["structure"]
        assert r.data.params["dataset.duration_s"] == "4.0"
        paths = artifact_paths(client, r.info.run_id)
        assert FIGURES | {"config/config.yaml", "config/hydra/config.yaml", "config/hydra/overrides.yaml",
                          "model/model.json", "resid/resid.json"} <= paths
        names.add(r.info.run_name)
    assert "oe 2-2-2 · binary_a025" in names


def test_sweep_logs_progress_as_jobs_done_of_total(sweep):
    _, _, lines = sweep
    for k in range(1, 5):
        assert any(line.startswith(f"[{k}/4] ") for line in lines), lines


def test_sweep_size_is_the_product_of_sweeper_params_and_command_line_sweeps():
    from omegaconf import OmegaConf

    from maglev.study.callbacks import sweep_size

    def cfg(params, task):
        return OmegaConf.create({"hydra": {"sweeper": {"params": params}, "overrides": {"task": task}}})

    assert sweep_size(cfg({"dataset": "a,b,c", "structure": "arx,oe"}, ["+sweep=lab"])) == 6
    # the command line replaces a sweeper param of the same key; range() stops before its end
    assert sweep_size(cfg({"dataset": "a,b,c"}, ["dataset=a", "structure.order=range(2,5)"])) == 3
    assert sweep_size(cfg({}, ["x=1"])) == 1


def test_model_and_resid_artifacts_are_loadable(sweep):
    from maglev.model import PolyModel
    from maglev.study.tracking import download_text

    store, _, _ = sweep
    client, _, runs = all_runs(store)
    r = next(r for r in runs if r.data.tags.get("structure") == "arx")
    model = PolyModel.from_json(download_text(client, r.info.run_id, "model/model.json"))
    assert model.structure == "arx" and model.orders == (2, 2, 2)
    res = json.loads(download_text(client, r.info.run_id, "resid/resid.json"))
    assert len(res["auto_corr"]) == len(res["auto_lags"]) and res["auto_band"] > 0
    assert res["whiteness_pvalue"] == r.data.metrics["whiteness_pvalue"]


def test_runs_explain_themselves_in_the_ui(sweep):
    """Dataset inputs, descriptions, source, key.* columns and readable names on every model run; the
    parent described; the experiment tagged for the UI's model-training mode with its shared view."""
    from maglev.study.datasets import load
    from maglev.study.store import run_config
    from maglev.study.tracking import SHARE_KEY, data_digest

    store, _, _ = sweep
    client, exp_id, runs = all_runs(store)
    tags = client.get_experiment(exp_id).tags
    assert tags["mlflow.experimentKind"] == "custom_model_development"
    view = json.loads(tags[f"mlflow.sharedViewState.{SHARE_KEY}"])
    assert view["orderByKey"] == "metrics.`val_fit`" and not view["orderByAsc"]
    for r in (r for r in runs if r.data.tags.get("kind") == "model"):
        t, m = r.data.tags, r.data.metrics
        prep = load(run_config(client, r.info.run_id)["dataset"], "")
        inputs = {i.tags[0].value: i.dataset for i in r.inputs.dataset_inputs}
        assert set(inputs) == {"estimation", "validation"}
        for context, part in (("estimation", prep.est), ("validation", prep.val)):
            ds = inputs[context]
            assert (ds.name, ds.digest) == (part.name, data_digest(part))
            profile = json.loads(ds.profile)
            assert (profile["num_rows"], profile["u_unit"], profile["y_unit"]) == (part.N, "A", "cm")
        assert inputs["validation"].name == t["val_dataset"] and prep.val.N == m["n_val"]
        note = t["mlflow.note.content"]
        assert note.startswith(f"{t['structure'].upper()} {t['orders']} on {t['dataset']}: 1-step validation FIT "
                               f"{m['val_fit']:.2f} %")
        assert ("Residuals white" if m["whiteness_pass"] else "Residuals not white") in note
        assert t["mlflow.source.name"] == "study.py" and t["mlflow.source.git.commit"] == t["git_commit"]
        assert {k: v for k, v in m.items() if k.startswith("key.")} == {  # the columns compared first, rounded
            "key.val_fit": round(m["val_fit"], 2), "key.sim_fit": round(m["val_fit_sim"], 2),
            "key.naive_fit": round(m["val_fit_naive"], 2), "key.white_p": float(f"{m['whiteness_pvalue']:.3g}"),
            "key.indep_p": float(f"{m['independence_pvalue']:.3g}"), "key.n_params": 4,
            "key.white_log10p": round(-math.log10(max(m["whiteness_pvalue"], 1e-300)), 2),
            "key.indep_log10p": round(-math.log10(max(m["independence_pvalue"], 1e-300)), 2)}
        structure, orders, _, dataset = r.info.run_name.split(" ")
        assert (structure, orders.split("-"), dataset) == (t["structure"], t["orders"].strip("[]").split(),
                                                          t["dataset"])
        assert len(r.info.run_name) <= 26
    parent = next(r for r in runs if r.data.tags.get("kind") == "sweep")
    assert parent.data.tags["mlflow.note.content"].startswith(
        "Sweep tiny: 4 model runs (4 FINISHED) of 2 dataset(s) (uniform_narrow, binary_a025) × 2 structure(s) "
        "(arx, oe) × orders 2.")
    assert "Not ranked yet" in parent.data.tags["mlflow.note.content"]


def alive(pid: int) -> bool:
    try:
        return Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0] != "Z"
    except OSError:
        return False


def _blocks_sigint(task: Path) -> bool:
    """Whether the thread ``/proc/<pid>/task/<tid>`` blocks SIGINT (its ``SigBlk`` mask)."""
    try:
        mask = next(line.split()[1] for line in (task / "status").read_text().splitlines()
                    if line.startswith("SigBlk:"))
    except (OSError, StopIteration):
        return True
    return bool(int(mask, 16) >> (signal.SIGINT - 1) & 1)


def interrupt_a_side_thread(pid: int) -> None:
    """SIGINT to one of ``pid``'s threads other than the main one when it has any (Linux x86-64 ``tgkill``):
    the kernel may hand a terminal's Ctrl-C to any thread that does not block it, and a main thread blocked
    in ``waitpid`` then never sees it.  Threads that block every signal (jemalloc's background thread, in
    some installs the lowest side thread) would hold it pending for ever, which no terminal does, so they
    are passed over.  Elsewhere, to the process."""
    import ctypes
    import platform

    side = sorted(int(t.name) for t in Path(f"/proc/{pid}/task").iterdir()
                  if int(t.name) != pid and not _blocks_sigint(t))
    if side and sys.platform == "linux" and platform.machine() == "x86_64":
        assert ctypes.CDLL(None, use_errno=True).syscall(234, pid, side[0], signal.SIGINT) == 0  # tgkill
    else:
        os.kill(pid, signal.SIGINT)


def test_maglev_ui_serves_the_store_lightly_opened_on_the_sweep_in_model_training_mode(sweep, tmp_path):
    store, _, _ = sweep
    uri = f"sqlite:///{store}/mlflow.db"
    _, exp, _ = all_runs(store)
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    env = {k: v for k, v in os.environ.items() if k != "MLFLOW_TRACKING_URI"}
    with open(tmp_path / "ui.err", "w") as err:
        proc = subprocess.Popen([sys.executable, "-m", "maglev", "ui", "--tracking-uri", uri, "--port", str(port)],
                                stdout=subprocess.PIPE, stderr=err, text=True, cwd=REPO, env=env,
                                preexec_fn=default_ctrl_c)
    try:
        line = proc.stdout.readline()  # printed once the server answers /health
        base = f"http://127.0.0.1:{port}"
        assert line.startswith(f"MLflow UI: {base}/#/experiments/{exp}/runs?workflowType=machine_learning"
                               "&viewStateShareKey=sweep-tiny "), (line, (tmp_path / "ui.err").read_text()[-3000:])
        server = descendants(proc.pid)
        assert 1 <= len(server) <= 3  # one web worker, no job runner (the default starts 15 processes)
        url = f"{base}/api/2.0/mlflow/experiments/get-by-name?experiment_name=maglev"
        with urllib.request.urlopen(url, timeout=30) as r:
            tags = {t["key"]: t["value"] for t in json.load(r)["experiment"]["tags"]}
        assert tags["mlflow.experimentKind"] == "custom_model_development"
        view = json.loads(tags["mlflow.sharedViewState.sweep-tiny"])  # the view the printed URL opens
        assert view["searchFilter"] == "tags.sweep = 'tiny'" and view["orderByKey"] == "metrics.`val_fit`"
        assert view["selectedColumns"][0] == "metrics.`key.val_fit`" and "attributes.`Dataset`" in view["selectedColumns"]
    finally:
        server = descendants(proc.pid)
        interrupt_a_side_thread(proc.pid)  # Ctrl-C: maglev ui stops its server
        try:
            code = proc.wait(timeout=60)
        except subprocess.TimeoutExpired:
            for pid in [proc.pid, *server]:  # leave no MLflow server running after a failure
                with contextlib.suppress(OSError):
                    os.kill(pid, signal.SIGKILL)
            raise
    assert code == 0 and not [pid for pid in server if alive(pid)]


def test_reproduce_gives_identical_metrics(sweep, capsys):
    from maglev.study.cli import main

    store, _, _ = sweep
    _, _, runs = all_runs(store)
    r = next(r for r in runs if r.data.tags.get("structure") == "oe")
    assert main(["reproduce", r.info.run_id, "--tracking-uri", f"sqlite:///{store}/mlflow.db"]) == 0
    out = capsys.readouterr().out
    assert "metrics identical" in out and "DIFFERENT" not in out
    assert f"{r.data.metrics['val_fit']:22.15g}" in out
    import numpy
    import scipy

    assert (r.data.tags["lib.numpy"], r.data.tags["lib.scipy"]) == (numpy.__version__, scipy.__version__)


def test_reproduce_tells_rounding_from_a_real_difference_and_names_other_library_versions(sweep, capsys, tmp_path):
    """A run made under other numpy / scipy builds reproduces to their rounding: reported as such (exit 0),
    with the versions named; a metric off by more is DIFFERENT (exit 1). On a copy of the sweep's store."""
    import shutil

    from mlflow import MlflowClient

    from maglev.study.cli import main
    from maglev.study.reproduce import ROUNDING_RELATIVE

    store, _, _ = sweep
    shutil.copy(store / "mlflow.db", tmp_path / "mlflow.db")
    uri = f"sqlite:///{tmp_path}/mlflow.db"
    _, _, runs = all_runs(store)
    r = next(r for r in runs if r.data.tags.get("structure") == "oe")
    client = MlflowClient(tracking_uri=uri)
    client.set_tag(r.info.run_id, "lib.numpy", "1.26.4")
    fit = r.data.metrics["val_fit"]
    client.log_metric(r.info.run_id, "val_fit", fit * (1 + ROUNDING_RELATIVE / 10), step=1)
    assert main(["reproduce", r.info.run_id, "--tracking-uri", uri]) == 0
    out, err = capsys.readouterr()
    assert "metrics equal to rounding (1 differ in their last digits only)" in out and "DIFFERENT" not in out
    assert f"note: run made with numpy 1.26.4 (now {__import__('numpy').__version__})" in err
    client.log_metric(r.info.run_id, "val_fit", fit * (1 + 100 * ROUNDING_RELATIVE), step=2)
    assert main(["reproduce", r.info.run_id, "--tracking-uri", uri]) == 1
    out = capsys.readouterr().out
    assert "1 metric(s) differ" in out and "DIFFERENT" in out


def test_the_sweep_records_its_environment_and_reproduce_names_the_packages_that_differ(sweep, capsys,
                                                                                        monkeypatch):
    """The parent run holds every installed package as ``name==version`` (pip's format); ``maglev reproduce``
    under another environment (here: numpy downgraded, mlflow missing, one package more) names each one."""
    from maglev.study import environment
    from maglev.study.cli import main
    from maglev.study.store import artifact_bytes

    store, _, _ = sweep
    client, _, runs = all_runs(store)
    parent = next(r for r in runs if r.data.tags.get("kind") == "sweep")
    logged = environment.parse(artifact_bytes(client, parent.info.run_id, environment.ARTIFACT).decode())
    now = environment.current()
    assert logged == now and logged["numpy"] == __import__("numpy").__version__ and "mlflow" in logged
    other = {**{k: v for k, v in now.items() if k != "mlflow"}, "numpy": "1.26.4", "extra-pkg": "0.1"}
    monkeypatch.setattr(environment, "current", lambda: other)
    r = next(r for r in runs if r.data.tags.get("structure") == "oe")
    assert main(["reproduce", r.info.run_id, "--tracking-uri", f"sqlite:///{store}/mlflow.db"]) == 0
    err = capsys.readouterr().err
    assert (f"warning: 3 package(s) differ from the sweep's environment: extra-pkg (new, 0.1), mlflow "
            f"{now['mlflow']} (now absent), numpy {now['numpy']} (now 1.26.4); `pip install -r "
            f"environment/requirements.txt` (an artifact of parent run {parent.info.run_id}) rebuilds it") in err


def test_relaunch_runs_nothing_new_and_reaps_stale_runs(sweep):
    store, args, _ = sweep
    client, exp_id, before = all_runs(store)
    dead = subprocess.Popen([sys.executable, "-c", "pass"])
    dead.wait()
    stale = client.create_run(exp_id, run_name="killed", tags={"kind": "model", "host": socket.gethostname(),
                                                              "pid": str(dead.pid)}).info.run_id
    with study_log() as lines:
        launch(store, *args)
    skips = [m for m in lines if m.startswith("skip ")]
    assert len(skips) == 4
    names = {r.info.run_id: r.info.run_name for r in before if r.data.tags.get("kind") == "model"}
    for line in skips:  # which run holds the config, and how to run it anyway
        run_id = next(i for i in names if i in line)
        assert f"{names[run_id]!r} ({run_id}) already holds this config" in line
        assert line.endswith("to run it again add study.skip_finished=false")
    client, _, after = all_runs(store)
    assert client.get_run(stale).info.status == "KILLED"
    finished = lambda runs: sorted(r.info.run_id for r in runs if r.data.tags.get("kind") == "model"  # noqa: E731
                                   and r.info.status == "FINISHED")
    assert finished(after) == finished(before)
    assert len([r for r in after if r.data.tags.get("kind") == "sweep"]) == 1  # the parent is reused


def test_failing_run_is_failed_and_the_sweep_goes_on(migrated_store, monkeypatch):
    # orders the data cannot support are refused before the sweep (test_faults.py); an error the
    # config cannot foresee happens while estimating: here the estimator fails for order 3
    from maglev.study import job

    def estimate_run(cfg):
        if cfg["structure"]["order"] == 3:
            raise ValueError("uniform_wide: orders too large for the data")
        return real(cfg)

    real = job.estimate_run
    monkeypatch.setattr(job, "estimate_run", estimate_run)
    launch(migrated_store, "dataset=uniform_wide", "structure=arx", "structure.order=2,3", *TINY, *LEAN)
    client, _, runs = all_runs(migrated_store)
    kids = {r.data.tags["orders"]: r for r in runs if r.data.tags.get("kind") == "model"}
    assert kids["[2 2 2]"].info.status == "FINISHED"
    bad = kids["[3 3 2]"]
    assert bad.info.status == "FAILED" and "orders too large" in bad.data.tags["error"]
    assert "error.txt" in artifact_paths(client, bad.info.run_id)
    parent = next(r for r in runs if r.data.tags.get("kind") == "sweep")
    assert parent.info.status == "FINISHED" and parent.data.metrics["runs_failed"] == 1


def test_single_run_without_sweep(migrated_store):
    launch(migrated_store, "dataset=binary_a025", "structure=arx", *TINY, multirun=False)
    _, _, runs = all_runs(migrated_store)
    assert len(runs) == 1 and runs[0].info.status == "FINISHED"
    assert "mlflow.parentRunId" not in runs[0].data.tags and runs[0].data.tags["kind"] == "model"


def test_reap_marks_only_dead_local_processes(migrated_store):
    from maglev.study import tracking
    from maglev.study.reap import reap

    client, exp_id = tracking.connect({"uri": f"sqlite:///{migrated_store}/mlflow.db", "experiment": "maglev",
                                       "artifact_location": str(migrated_store / "a")})
    dead = subprocess.Popen([sys.executable, "-c", "pass"])
    dead.wait()
    host = socket.gethostname()
    gone = client.create_run(exp_id, tags={"host": host, "pid": str(dead.pid)}).info.run_id
    alive = client.create_run(exp_id, tags={"host": host, "pid": str(os.getpid())}).info.run_id
    other = client.create_run(exp_id, tags={"host": "elsewhere", "pid": "1"}).info.run_id
    assert reap(client, [exp_id]) == [gone]
    assert [client.get_run(r).info.status for r in (gone, alive, other)] == ["KILLED", "RUNNING", "RUNNING"]
    assert set(reap(client, [exp_id], older_than_hours=-1)) == {alive, other}
