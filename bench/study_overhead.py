"""Per-run overhead of tracking and plotting next to estimation, for the study's runs.

    python bench/study_overhead.py [--repeats 5] [--duration 20] [--structures arx,oe,armax,bj]

Each repeat runs, for every structure, the same steps as one study job and times them
separately: data (simulate + preprocess), estimation, validation (compare + resid),
figures (building the four matplotlib figures), and tracking into a fresh temporary
SQLite store (skip-check query, create run, params, PNG encoding + artifact upload,
metrics, finish); PNG encoding is timed on its own ("png-encode").  Prints the medians in a table (seconds) and the tracking+plotting
share of the run.
"""

from __future__ import annotations

import argparse
import math
import shutil
import statistics
import sys
import tempfile
import time
import warnings
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
warnings.filterwarnings("ignore", message="The .*noload.* loader strategy is deprecated")
sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from omegaconf import OmegaConf  # noqa: E402

from maglev.estimate import estimate  # noqa: E402
from maglev.study import datasets, identify as ident, tracking  # noqa: E402
from maglev.structures import get as structure  # noqa: E402
from maglev.study.config import config_hash, flatten  # noqa: E402
from maglev.study.figures import run_figures  # noqa: E402
from maglev.validate import compare, resid  # noqa: E402

STEPS = ("data", "estimate", "validate", "figures", "png-encode", "track:query", "track:run+params",
         "track:artifacts", "track:metrics+end")


def config(structure: str, duration: float, uri: str, art: str) -> dict:
    from hydra import compose, initialize_config_dir

    import maglev.study.schema  # noqa: F401

    conf = Path(__file__).resolve().parents[1] / "conf"
    with initialize_config_dir(version_base="1.3", config_dir=str(conf)):
        cfg = compose("config", overrides=[f"structure={structure}", "dataset=uniform_narrow",
                                           f"dataset.duration_s={duration}", f"tracking.uri={uri}",
                                           f"tracking.artifact_location={art}"])
    return OmegaConf.to_container(cfg, resolve=True, enum_to_str=True)


def one_run(cfg: dict, client, exp_id: str) -> dict[str, float]:
    t: dict[str, float] = {}
    tic = time.perf_counter()

    def lap(name: str) -> None:
        nonlocal tic
        now = time.perf_counter()
        t[name] = now - tic
        tic = now

    datasets._simulate.cache_clear()
    prep = datasets.load(cfg["dataset"], cfg["data_dir"])
    lap("data")
    st = cfg["structure"]
    opts = {} if structure(st["name"]).least_squares else {"max_iterations": st["max_iterations"]}
    model = estimate(prep.est, st["name"], ident.orders_of(st), st["initial_condition"], **opts)
    lap("estimate")
    fit, yhat = compare(prep.val, model, 1)
    fit_sim, ysim = compare(prep.val, model, math.inf)
    rr = resid(prep.val, model)
    true_sys = ident.true_plant(prep)
    metrics = {"val_fit": fit, "val_fit_sim": fit_sim, **ident.true_distance(model, true_sys)}
    lap("validate")
    figs = run_figures(prep, model, rr, yhat, ysim, fit, fit_sim, true_sys, 1)
    lap("figures")
    tmp = Path(tempfile.mkdtemp(prefix="bench-png-"))
    pngs = {}
    for k, f in figs.items():
        f.savefig(tmp / k, dpi=90)
        pngs[f"figures/{k}"] = tmp / k
    lap("png-encode")
    chash = config_hash(cfg)
    tracking.finished_run(client, exp_id, chash)
    lap("track:query")
    run_id = client.create_run(exp_id, run_name=ident.run_label(cfg), tags={"config_hash": chash}).info.run_id
    tracking.log_batch(client, run_id, params=flatten(cfg))
    lap("track:run+params")
    files = dict(pngs)
    files.update({"model/model.json": model.to_json(), "resid/resid.json": rr.to_dict(),
                  "config/config.yaml": OmegaConf.to_yaml(OmegaConf.create(cfg))})
    tracking.log_files(client, run_id, files)
    lap("track:artifacts")
    tracking.log_batch(client, run_id, metrics=metrics)
    client.set_terminated(run_id, "FINISHED")
    lap("track:metrics+end")
    shutil.rmtree(tmp, ignore_errors=True)
    return t


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--repeats", type=int, default=5)
    p.add_argument("--duration", type=float, default=20.0, help="simulated record length (s)")
    p.add_argument("--structures", default="arx,oe,armax,bj")
    a = p.parse_args(argv)
    structures = a.structures.split(",")
    with tempfile.TemporaryDirectory() as tmp:
        uri, art = f"sqlite:///{tmp}/mlflow.db", f"{tmp}/artifacts"
        tic = time.perf_counter()
        client, exp_id = tracking.connect({"uri": uri, "experiment": "bench", "artifact_location": art})
        setup = time.perf_counter() - tic
        cfgs = {s: config(s, a.duration, uri, art) for s in structures}
        one_run(cfgs[structures[0]], client, exp_id)  # warm-up (imports, first-run costs)
        times = {s: [one_run(cfgs[s], client, exp_id) for _ in range(a.repeats)] for s in structures}
    print(f"median seconds per run over {a.repeats} repeats (uniform_narrow, {a.duration:g} s record; "
          f"store creation once: {setup:.2f} s)\n")
    header = f"{'step':20s}" + "".join(f"{s:>10s}" for s in structures)
    print(header)
    print("-" * len(header))
    med = {s: {k: statistics.median(r[k] for r in times[s]) for k in STEPS} for s in structures}
    for k in STEPS:
        print(f"{k:20s}" + "".join(f"{med[s][k]:10.3f}" for s in structures))
    print("-" * len(header))
    rows = {
        "estimation": lambda m: m["estimate"],
        "plotting": lambda m: m["figures"] + m["png-encode"],
        "tracking": lambda m: sum(v for k, v in m.items() if k.startswith("track:")),
        "total": lambda m: sum(m.values()),
    }
    for name, f in rows.items():
        print(f"{name:20s}" + "".join(f"{f(med[s]):10.3f}" for s in structures))
    share = [100 * (rows["plotting"](med[s]) + rows["tracking"](med[s])) / rows["total"](med[s]) for s in structures]
    print(f"{'track+plot share %':20s}" + "".join(f"{v:10.1f}" for v in share))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
