"""Where a study run's time goes, and how long the default lab sweep takes.

    python bench/study_overhead.py [--repeats 5] [--structures arx,oe,armax,bj] [--sweep]
    python bench/study_overhead.py --launch [--repeats 5] [--baseline CHECKOUT] [--markdown docs/benchmarks-study.md]

``--launch`` times only what a user waits for, each as a process and as the median of the repeats:
the default sweep with every BLA cached (into a fresh store), the seconds from the command to its
first line of output, and the relaunch of the finished sweep (issue 39's targets: 5 s, 20 s, 5 s).
With ``--baseline`` another checkout (``git archive main | tar -x -C DIR``) takes turns with this one
and the table gives the ratio of the medians; ``--markdown`` writes the table to a file, headed by the command
and the fingerprint of what it measured (``bench/fingerprints.py``).

Per run (the default lab dataset uniform_wide, 24 s; the job's own functions): data
(simulate + preprocess, cached per process in a sweep, so shown apart), estimation
(the estimator call), validation (compare, resid, naive FIT, BLA distance — everything
else ``identify`` does), tracking (skip query, run, params, artifacts, metrics), and
the five figures (PNG at the runs' dpi, drawn on the previous run's as the renderer does),
which a sweep on the basic launcher draws in a background process (:mod:`maglev.study.render`)
while the next run estimates.
"beyond estimation, critical path" is validation + tracking + handing the figure
inputs to the renderer (pickling); the figures are shown beside it.  Medians over the
repeats, single-threaded BLAS.  ``--sweep`` also times ``python study.py -m +sweep=lab``
as a process into a temporary store (wall and CPU seconds, its ranking and report included)
and reads the sweep's own per-run cost from its runs: the time from one run's start to the
next one's minus the first one's estimation (``fit_seconds``), which adds what the parts
above leave out (Hydra composing each job's config, twice; the launcher; sharing the CPU with
the renderer), and where the rest of the wall time goes (before the first run: imports, a
fresh MLflow database, the lab steps; after the last run's start: its job, the last figures,
the ranking and the report).  The machine's load average is printed with it.
"""

from __future__ import annotations

import argparse
import os
import pickle
import resource
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
import warnings
from pathlib import Path

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ[_var] = "1"

import matplotlib  # noqa: E402

matplotlib.use("Agg")
warnings.filterwarnings("ignore", message="The .*noload.* loader strategy is deprecated")
REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))
sys.path.insert(0, str(REPO / "bench"))

import fingerprints  # noqa: E402

from omegaconf import OmegaConf  # noqa: E402

from maglev.study import claims, datasets, tracking  # noqa: E402
from maglev.study.config import config_hash, flatten  # noqa: E402
from maglev.study.figures import RUN_DPI, png, run_figures  # noqa: E402
from maglev.study.identify import identify, run_label  # noqa: E402

FIGURES: dict = {}  # the renderer's figures, drawn again for every run
TARGET_BEYOND_S = 0.3  # target: per-run time beyond estimation (median)
TARGET_SWEEP_S = 30.0  # target: the default lab sweep on the 2-core machine


def config(structure: str, uri: str, art: str) -> dict:
    from hydra import compose, initialize_config_dir

    import maglev.study.schema  # noqa: F401
    from maglev.study.config import task_config

    with initialize_config_dir(version_base="1.3", config_dir=str(REPO / "conf")):
        cfg = compose("config", overrides=[f"structure={structure}", "dataset=uniform_wide",
                                           f"tracking.uri={uri}", f"tracking.artifact_location={art}"])
    return task_config(cfg)


def one_run(cfg: dict, client, exp_id: str) -> dict[str, float]:
    t: dict[str, float] = {}
    datasets._simulate.cache_clear()
    tic = time.perf_counter()
    datasets.load(cfg["dataset"], cfg["data_dir"])
    t["data (once per sweep)"] = time.perf_counter() - tic
    tic = time.perf_counter()
    out = identify(cfg)  # the data are cached now, as in a sweep
    t["estimation"] = out.metrics["fit_seconds"]
    t["validation"] = time.perf_counter() - tic - t["estimation"]
    tic = time.perf_counter()
    chash = config_hash(cfg)
    with tracking.store_lock(cfg["tracking"]["uri"]):  # the job's claim: look the config up, then create its run
        claims.holder(client, exp_id, chash)  # (its answer ignored: the bench repeats one config)
        run_id = client.create_run(exp_id, run_name=run_label(cfg), tags={"config_hash": chash}).info.run_id
    tracking.log_batch(client, run_id, params=flatten(cfg))
    tracking.log_files(client, run_id, {"model/model.json": out.model.to_json(), "resid/resid.json": out.resid,
                                        "config/config.yaml": OmegaConf.to_yaml(OmegaConf.create(cfg)),
                                        "data/data.json": out.prepared.info()})
    tracking.log_batch(client, run_id, metrics=out.metrics)
    client.set_terminated(run_id, "FINISHED")
    t["tracking"] = time.perf_counter() - tic
    tic = time.perf_counter()
    pickle.dumps(out.figure_inputs)
    t["hand-off to renderer"] = time.perf_counter() - tic
    tic = time.perf_counter()
    for fig in run_figures(out.figure_inputs, reuse=FIGURES).values():
        png(fig, RUN_DPI)
    t["figures (background)"] = time.perf_counter() - tic
    return t


def sweep_time() -> dict[str, float]:
    """``python study.py -m +sweep=lab`` into a fresh temporary store: wall and CPU seconds, and from its runs
    the median per-run time beyond estimation and the wall time before the first run and after the last
    one's start."""
    with tempfile.TemporaryDirectory(prefix="bench-sweep-") as tmp:
        uri = f"sqlite:///{tmp}/mlflow.db"
        cmd = [sys.executable, str(REPO / "study.py"), "-m", "+sweep=lab", f"tracking.uri={uri}",
               f"tracking.artifact_location={tmp}/art", f"hydra.sweep.dir={tmp}/multirun",
               f"hydra.callbacks.maglev_rank.report_dir={tmp}/reports"]
        before = resource.getrusage(resource.RUSAGE_CHILDREN)
        load = os.getloadavg()[0]
        t0 = time.time()
        tic = time.perf_counter()
        proc = subprocess.run(cmd, capture_output=True, text=True, cwd=tmp)
        wall = time.perf_counter() - tic
        t1 = time.time()
        after = resource.getrusage(resource.RUSAGE_CHILDREN)
        if proc.returncode:
            raise SystemExit(f"the sweep failed:\n{proc.stderr[-3000:]}")
        from mlflow import MlflowClient

        client = MlflowClient(tracking_uri=uri)
        exp = client.get_experiment_by_name("maglev")
        runs = sorted((r for r in client.search_runs([exp.experiment_id], "tags.kind = 'model'", max_results=1000)),
                      key=lambda r: r.info.start_time)
    starts = [r.info.start_time / 1000 for r in runs]
    beyond = [b - a - r.data.metrics["fit_seconds"] for a, b, r in zip(starts, starts[1:], runs)]
    return {"wall": wall, "cpu": (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime),
            "runs": len(runs), "per_run_beyond": statistics.median(beyond), "before_first": starts[0] - t0,
            "after_last": t1 - starts[-1], "estimation": sum(r.data.metrics["fit_seconds"] for r in runs),
            "load_before": load, "load_after": os.getloadavg()[0]}


# ---------------------------------------------------------------------------- what a user waits for
TARGET_RELAUNCH_S = 5.0  # issue 39: relaunching the finished default sweep
TARGET_DEFAULT_S = 20.0  # issue 39: the default sweep with every BLA cached
TARGET_FIRST_LINE_S = 5.0  # issue 39: its first line of progress


def launch_process(study: Path, store: Path) -> dict[str, float]:
    """``python STUDY -m +sweep=lab`` into ``store`` as a process: wall seconds, CPU seconds (the process and
    its children: the renderer, the BLA process), and seconds from the command to its first line of output."""
    uri = f"sqlite:///{store}/mlflow.db"
    cmd = [sys.executable, str(study), "-m", "+sweep=lab", f"tracking.uri={uri}",
           f"tracking.artifact_location={store}/art", f"hydra.sweep.dir={store}/multirun",
           f"hydra.callbacks.maglev_rank.report_dir={store}/reports"]
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    tic = time.perf_counter()
    proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, cwd=store)
    first, out = None, []
    for line in proc.stdout:
        if first is None and line.strip():
            first = time.perf_counter() - tic
        out.append(line)
    code = proc.wait()
    wall = time.perf_counter() - tic
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    if code:
        raise SystemExit(f"{study} failed ({code}):\n{''.join(out)[-3000:]}")
    cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    return {"wall": wall, "cpu": cpu, "first": first if first is not None else wall}


def launch_times(studies: dict[str, Path], repeats: int, sweeps: int) -> dict[str, dict[str, list[float]]]:
    """For each checkout (name -> its study.py), taking turns: ``sweeps`` default sweeps into fresh stores
    (BLAs cached by a warm-up sweep first, whose first line counts too) and ``repeats`` relaunches of a
    finished one.  Each time is also printed to stderr as it is measured."""
    times = {name: {k: [] for k in ("sweep", "sweep_cpu", "first", "relaunch", "relaunch_cpu", "relaunch_first")}
             for name in studies}

    def note(name: str, what: str, t: dict) -> None:
        print(f"{name}: {what} {t['wall']:.1f} s wall, {t['cpu']:.1f} s CPU, first line {t['first']:.1f} s",
              file=sys.stderr, flush=True)

    with tempfile.TemporaryDirectory(prefix="bench-launch-") as tmp:
        finished = {}
        for name, study in studies.items():  # warm-up: caches the BLAs; its store is the finished sweep
            finished[name] = Path(tmp) / f"{name}-finished".replace(" ", "-")
            finished[name].mkdir()
            t = launch_process(study, finished[name])
            times[name]["first"].append(t["first"])
            note(name, "warm-up sweep", t)
        for i in range(max(repeats, sweeps)):
            for name, study in studies.items():
                if i < sweeps:
                    store = Path(tmp) / f"{name}-{i}".replace(" ", "-")
                    store.mkdir()
                    t = launch_process(study, store)
                    note(name, "default sweep", t)
                    times[name]["sweep"].append(t["wall"])
                    times[name]["sweep_cpu"].append(t["cpu"])
                    times[name]["first"].append(t["first"])
                    shutil.rmtree(store)
                if i >= repeats:
                    continue
                t = launch_process(study, finished[name])
                note(name, "relaunch", t)
                times[name]["relaunch"].append(t["wall"])
                times[name]["relaunch_cpu"].append(t["cpu"])
                times[name]["relaunch_first"].append(t["first"])
    return times


def launch_table(times: dict[str, dict[str, list[float]]]) -> str:
    """Markdown: medians per checkout (how many measurements in the second column), the ratio of the second
    checkout's to the first's (when two) and the target."""
    names = list(times)
    rows = [("relaunch of the finished default sweep, wall s", "relaunch", TARGET_RELAUNCH_S),
            ("relaunch, CPU s", "relaunch_cpu", None),
            ("default sweep with the BLAs cached, wall s", "sweep", TARGET_DEFAULT_S),
            ("default sweep, CPU s", "sweep_cpu", None),
            ("first line of the default sweep, s after the command", "first", TARGET_FIRST_LINE_S)]
    head = "| median | of | " + " | ".join(names)
    head += " | ratio |" if len(names) == 2 else " |"
    lines = [head + " target |", "|---|---|" + "---|" * (len(names) + (len(names) == 2) + 1)]
    for label, key, target in rows:
        if not all(times[n][key] for n in names):
            continue
        med = [statistics.median(times[n][key]) for n in names]
        cells = [f"{m:.1f}" for m in med]
        if len(names) == 2:
            cells.append(f"{med[1] / med[0]:.2f}")
        verdict = "" if target is None else f"≤ {target:g} s: {'met' if med[-1] <= target else 'not met'}"
        lines.append(f"| {label} | {len(times[names[-1]][key])} | " + " | ".join(cells) + f" | {verdict} |")
    return "\n".join(lines) + "\n"


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--repeats", type=int, default=5)
    p.add_argument("--structures", default="arx,oe,armax,bj")
    p.add_argument("--sweep", action="store_true", help="also time the default lab sweep as a process")
    p.add_argument("--launch", action="store_true",
                   help="only time what a user waits for: the default sweep with BLAs cached, its first line of "
                        "progress and the relaunch of the finished sweep (medians of --repeats, as processes)")
    p.add_argument("--baseline", type=Path, metavar="CHECKOUT",
                   help="with --launch: another checkout (e.g. git archive of main) timed in turn with this one; "
                        "the table gives this one's medians over the baseline's")
    p.add_argument("--markdown", type=Path, metavar="FILE", help="with --launch: also write the table to FILE")
    p.add_argument("--sweeps", type=int, metavar="N",
                   help="with --launch: default sweeps into fresh stores (default: --repeats; each is ~30 s)")
    a = p.parse_args(argv)
    if a.launch:
        studies = {"this checkout": REPO / "study.py"}
        if a.baseline:
            studies = {"baseline": a.baseline.resolve() / "study.py", **studies}
        load = os.getloadavg()
        sweeps = a.repeats if a.sweeps is None else a.sweeps
        times = launch_times(studies, a.repeats, sweeps)
        table = launch_table(times)
        cores = os.cpu_count()
        command = " ".join(["python bench/study_overhead.py", *(argv if argv is not None else sys.argv[1:])])
        note = (f"{fingerprints.header(fingerprints.TABLES['study'], command)} The default sweep "
                f"(`python study.py -m +sweep=lab`): {a.repeats} relaunches, {sweeps} sweeps into fresh stores; "
                f"{cores} cores, load average {load[0]:.1f} before and {os.getloadavg()[0]:.1f} after; single-threaded "
                f"BLAS{'; the checkouts take turns' if a.baseline else ''}.\n")
        print(note + "\n" + table)
        if a.markdown:
            a.markdown.write_text("# What a user of the study waits for\n\n" + note + "\n" + table)
        return 0
    structures = a.structures.split(",")
    with tempfile.TemporaryDirectory() as tmp:
        uri, art = f"sqlite:///{tmp}/mlflow.db", f"{tmp}/artifacts"
        client, exp_id = tracking.connect({"uri": uri, "experiment": "bench", "artifact_location": art})
        cfgs = {s: config(s, uri, art) for s in structures}
        one_run(cfgs[structures[0]], client, exp_id)  # warm-up (imports, BLA cache, first-run costs)
        times = {s: [one_run(cfgs[s], client, exp_id) for _ in range(a.repeats)] for s in structures}
    steps = list(times[structures[0]][0])
    med = {s: {k: statistics.median(r[k] for r in times[s]) for k in steps} for s in structures}
    print(f"median seconds per run over {a.repeats} repeats (dataset uniform_wide, 24 s record)\n")
    header = f"| {'step':34s} |" + "".join(f" {s:>7s} |" for s in structures)
    print(header + "\n|" + "---|" * (len(structures) + 1))
    for k in steps:
        print(f"| {k:34s} |" + "".join(f" {med[s][k]:7.3f} |" for s in structures))
    beyond = {s: med[s]["validation"] + med[s]["tracking"] + med[s]["hand-off to renderer"] for s in structures}
    print(f"| {'beyond estimation, critical path':34s} |" + "".join(f" {beyond[s]:7.3f} |" for s in structures))
    worst = max(beyond.values())
    print(f"\nbeyond estimation: at most {worst:.3f} s per run (target {TARGET_BEYOND_S} s: "
          f"{'met' if worst <= TARGET_BEYOND_S else 'NOT met'})")
    if a.sweep:
        s = sweep_time()
        print(f"default lab sweep (python study.py -m +sweep=lab, {s['runs']} runs, ranking and report): "
              f"{s['wall']:.1f} s wall, {s['cpu']:.1f} s CPU (target {TARGET_SWEEP_S:g} s wall: "
              f"{'met' if s['wall'] <= TARGET_SWEEP_S else 'NOT met'}); load average {s['load_before']:.2f} before, "
              f"{s['load_after']:.2f} after")
        print(f"  before the first run {s['before_first']:.1f} s; estimation {s['estimation']:.1f} s in all; per run "
              f"beyond estimation in the sweep {s['per_run_beyond']:.3f} s (median; target {TARGET_BEYOND_S} s: "
              f"{'met' if s['per_run_beyond'] <= TARGET_BEYOND_S else 'NOT met'}); after the last run's start "
              f"{s['after_last']:.1f} s")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
