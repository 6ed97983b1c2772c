"""How the cluster path's costs grow with the sweep: 24 runs against ≥ 200, into one MLflow server on
PostgreSQL with basic auth (the recipe of docs/cluster.md, started here on 127.0.0.1 and stopped after).

    python bench/cluster_scale.py [--small 24] [--large 200] [--jobs 4] [--write-docs]

Each sweep is ``python study.py -m tracking=cluster hydra/launcher=parallel hydra.launcher.n_jobs=JOBS …``
on simulated records (the tests' 4-second records, figures off: what is measured is the store, not
matplotlib): JOBS worker processes log at once, as a cluster's jobs do (a Slurm job would add its own
process start, the same for every size).  Measured per size:

- per-run overhead beyond estimation: a run's time in the store (start to end) minus its estimation
  (``fit_seconds``), median over the runs;
- ranking: load the sweep's runs from the server, rank, draw and log the ranking run (wall s, and CPU s of
  this process, the server's workers and the database's backends together);
- report: build the HTML report and upload it (the same);
- the UI's runs table: ``POST runs/search`` as the UI asks for its first page (100 runs, newest first),
  and every run of the experiment (pages of 1000), median of 5 calls.

Ranking and report must not grow worse than linearly: the verdict line compares each one's growth with
the growth in runs.  ``--write-docs`` puts the output into docs/cluster.md (after ``<!-- cluster_scale -->``).
"""

from __future__ import annotations

import argparse
import io
import json
import os
import statistics
import subprocess
import sys
import tempfile
import time
import urllib.request
from base64 import b64encode
from contextlib import redirect_stdout
from pathlib import Path

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ[_var] = "1"

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))

from tests.cluster import services  # noqa: E402

SIMULATED = ["binary_a025", "binary_a05", "binary_a075", "uniform_narrow", "uniform_wide"]
STRUCTURES = ["arx", "armax", "oe", "bj"]
TINY = ["dataset.duration_s=4", "dataset.preprocess.trim=500"]


def grid(runs: int) -> tuple[list[str], int]:
    """Sweep overrides of at least ``runs`` configs: datasets × the 4 structures × orders 1…k."""
    for k in range(1, 40):
        for n_data in range(1, len(SIMULATED) + 1):
            if n_data * len(STRUCTURES) * k >= runs:
                return ([f"dataset={','.join(SIMULATED[:n_data])}", f"structure={','.join(STRUCTURES)}",
                         f"structure.order=range(1,{k + 1})"], n_data * len(STRUCTURES) * k)
    raise ValueError(f"no grid of {runs} runs")


class Rest:
    def __init__(self, url: str, auth: tuple[str, str]) -> None:
        self.url, self.token = url, b64encode(f"{auth[0]}:{auth[1]}".encode()).decode()

    def __call__(self, endpoint: str, body: dict) -> dict:
        req = urllib.request.Request(f"{self.url}/api/2.0/mlflow/{endpoint}", data=json.dumps(body).encode(),
                                     headers={"Content-Type": "application/json",
                                              "Authorization": f"Basic {self.token}"})
        with urllib.request.urlopen(req, timeout=120) as resp:
            return json.loads(resp.read())


def ui_query_s(rest: Rest, exp_id: str) -> tuple[float, float]:
    """Median seconds of the UI's first page of the runs table, and of listing every run."""
    def first_page() -> None:
        rest("runs/search", {"experiment_ids": [exp_id], "max_results": 100, "run_view_type": "ACTIVE_ONLY",
                             "order_by": ["attributes.start_time DESC"]})

    def everything() -> None:
        token = None
        while True:
            page = rest("runs/search", {"experiment_ids": [exp_id], "max_results": 1000,
                                        **({"page_token": token} if token else {})})
            token = page.get("next_page_token")
            if not token:
                return

    out = []
    for call in (first_page, everything):
        times = []
        for _ in range(5):
            tic = time.perf_counter()
            call()
            times.append(time.perf_counter() - tic)
        out.append(statistics.median(times))
    return out[0], out[1]


def tree_cpu(roots: list[int]) -> float:
    """CPU seconds (user + system) used so far by the processes ``roots`` and everything below them: the
    tracking server's workers and the database's backends, whose work a request costs besides the client's."""
    from maglev.study.shutdown import descendants

    tick = os.sysconf("SC_CLK_TCK")
    total = 0.0
    for pid in {p for root in roots for p in (root, *descendants(root))}:
        try:
            with open(f"/proc/{pid}/stat") as fh:
                fields = fh.read().rsplit(")", 1)[1].split()
            total += (int(fields[11]) + int(fields[12])) / tick
        except (OSError, IndexError, ValueError):
            continue
    return total


def measure(size: int, server: services.Server, env: dict, work: Path, services_roots: list[int],
            jobs: int) -> dict:
    overrides, n = grid(size)
    name = f"scale{n}"
    cmd = [sys.executable, str(REPO / "study.py"), "-m", "tracking=cluster", f"tracking.experiment={name}",
           "hydra/launcher=parallel", f"hydra.launcher.n_jobs={jobs}",
           f"study.name={name}", *overrides, *TINY, "study.true_plant=false", "lab.enabled=false",
           "tracking.log_figures=false", f"hydra.sweep.dir={work}/{name}", "~hydra.callbacks.maglev_rank"]
    tic = time.perf_counter()
    proc = subprocess.run(cmd, cwd=work, env=env, capture_output=True, text=True)
    sweep_s = time.perf_counter() - tic
    if proc.returncode:
        raise SystemExit(f"cluster_scale: the {n}-run sweep failed: {proc.stderr.strip().splitlines()[-1:]}")

    from mlflow import MlflowClient

    from maglev.study.ranking import compute
    from maglev.study.report import ranking_run_for, write_report
    from maglev.study.store import load_sweep

    client = MlflowClient(server.url)
    exp_id = client.get_experiment_by_name(name).experiment_id
    models = client.search_runs([exp_id], "tags.kind = 'model' and attributes.status = 'FINISHED'",
                                max_results=50000)
    beyond = [(r.info.end_time - r.info.start_time) / 1000 - r.data.metrics["fit_seconds"] for r in models]

    wall, cpu, back = time.perf_counter(), time.process_time(), tree_cpu(services_roots)
    with redirect_stdout(io.StringIO()):
        sweep = load_sweep(server.url, name, None)
        ranking = compute(sweep)
        run_id = ranking_run_for(ranking)
    rank_s, rank_cpu = time.perf_counter() - wall, time.process_time() - cpu
    rank_cpu += tree_cpu(services_roots) - back
    wall, cpu, back = time.perf_counter(), time.process_time(), tree_cpu(services_roots)
    write_report(ranking, run_id, work / "reports")
    report_s, report_cpu = time.perf_counter() - wall, time.process_time() - cpu
    report_cpu += tree_cpu(services_roots) - back
    page_s, all_s = ui_query_s(Rest(server.url, server.admin), exp_id)
    return {"runs": len(models), "sweep_s": sweep_s, "beyond_ms": 1000 * statistics.median(beyond),
            "rank_s": rank_s, "rank_cpu": rank_cpu, "report_s": report_s, "report_cpu": report_cpu,
            "ui_page_ms": 1000 * page_s, "ui_all_ms": 1000 * all_s}


def table(small: dict, large: dict) -> str:
    rows = [("runs (FINISHED)", "runs", "{:.0f}"), ("sweep, whole command (s)", "sweep_s", "{:.1f}"),
            ("per-run overhead beyond estimation, median (ms)", "beyond_ms", "{:.0f}"),
            ("ranking: load + rank + log (s)", "rank_s", "{:.2f}"),
            ("ranking CPU, client + server + database (s)", "rank_cpu", "{:.2f}"),
            ("report: build + upload (s)", "report_s", "{:.2f}"),
            ("report CPU, client + server + database (s)", "report_cpu", "{:.2f}"),
            ("UI runs table, first page of 100 (ms)", "ui_page_ms", "{:.0f}"),
            ("UI: every run of the experiment (ms)", "ui_all_ms", "{:.0f}")]
    lines = [f"| {'':48} | {small['runs']:>8.0f} runs | {large['runs']:>8.0f} runs | growth |",
             f"|{'-' * 50}|{'-' * 15}|{'-' * 15}|--------|"]
    for label, key, fmt in rows:
        growth = large[key] / small[key] if small[key] else float("nan")
        lines.append(f"| {label:48} | {fmt.format(small[key]):>13} | {fmt.format(large[key]):>13} | "
                     f"{growth:5.2f}× |")
    n = large["runs"] / small["runs"]
    verdicts = []
    for label, key in (("ranking", "rank_cpu"), ("report", "report_cpu")):
        g = large[key] / small[key]
        verdicts.append(f"{label} CPU grows {g:.2f}× for {n:.2f}× the runs: "
                        f"{'not worse than linear' if g <= n else 'WORSE THAN LINEAR'}")
    return "\n".join(lines + [""] + verdicts)


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--small", type=int, default=24)
    ap.add_argument("--large", type=int, default=200)
    ap.add_argument("--jobs", type=int, default=4, help="worker processes logging at once")
    ap.add_argument("--write-docs", action="store_true", help="put the output into docs/cluster.md")
    a = ap.parse_args()
    pg = services.start_postgres()
    try:
        server = services.start_server(pg, workers=4)
        try:
            user = server.add_user("bench")
            env = {k: v for k, v in os.environ.items() if not k.startswith(("MLFLOW_", "MAGLEV_"))}
            env.update(MLFLOW_TRACKING_URI=server.url, MLFLOW_TRACKING_USERNAME=user[0],
                       MLFLOW_TRACKING_PASSWORD=user[1], PYTHONPATH=str(REPO))
            os.environ.update({k: env[k] for k in ("MLFLOW_TRACKING_URI", "MLFLOW_TRACKING_USERNAME",
                                                   "MLFLOW_TRACKING_PASSWORD")})
            with tempfile.TemporaryDirectory(prefix="maglev-scale-") as tmp:
                roots = [server.proc.pid, int((pg.home / "data" / "postmaster.pid").read_text().split()[0])]
                small = measure(a.small, server, env, Path(tmp), roots, a.jobs)
                print(json.dumps(small), file=sys.stderr, flush=True)  # the raw numbers, as they come
                large = measure(a.large, server, env, Path(tmp), roots, a.jobs)
                print(json.dumps(large), file=sys.stderr, flush=True)
        finally:
            server.close()
    finally:
        pg.stop()
    load = ", ".join(f"{x:.1f}" for x in os.getloadavg())
    out = (f"{table(small, large)}\n\n{a.jobs} processes logging at once into one MLflow server (4 workers) on PostgreSQL {pg_version()}, basic auth, "
           f"on {os.cpu_count()} cores; load average while it ran: {load} (wall times grow with the load; "
           "the CPU rows count the client, the server and the database, not the other load).")
    print(out)
    if a.write_docs:
        doc = REPO / "docs" / "cluster.md"
        text = doc.read_text()
        marker = "<!-- cluster_scale -->"
        head = text[: text.index(marker) + len(marker)]
        doc.write_text(f"{head}\n\n```text\n$ python bench/cluster_scale.py --small {a.small} --large {a.large} --jobs {a.jobs}\n"
                       f"{out}\n```\n")
    return 0


def pg_version() -> str:
    out = subprocess.run(["postgres", "--version"], capture_output=True, text=True).stdout.split()
    return out[2] if len(out) > 2 else "?"  # postgres (PostgreSQL) 15.18 (Debian …)


if __name__ == "__main__":
    raise SystemExit(main())
