"""How the cluster path's costs grow with the sweep: 24 runs against ≥ 200, launched on a single-node Slurm
cluster into one MLflow server on PostgreSQL with basic auth (the recipe of docs/cluster.md, every service
started here on 127.0.0.1 and stopped after, as tests/cluster does).

    python bench/cluster_scale.py [--small 24] [--large 200] [--raw FILE] [--write-docs]

Each sweep is ``python study.py -m hydra/launcher=slurm tracking=cluster …`` on simulated records (the tests'
4-second records, figures off: what is measured is the path into the store, not matplotlib): every config
a Slurm array task, as many at once as the partition has CPUs.  Measured per size:

- per-run overhead beyond estimation: a run's time in the store (start to end) minus its estimation
  (``fit_seconds``), median over the runs;
- the server's side of the sweep: requests per run (counted in the server's access log, by endpoint) and
  the CPU seconds of the server's workers and the database's backends per run and per request;
- ranking: load the sweep's runs from the server, rank, draw and log the ranking run (wall s, and CPU s of
  this process, the server's workers and the database's backends together);
- report: build the HTML report and upload it (the same);
- the UI's runs table: ``POST runs/search`` as the UI asks for its first page (100 runs, newest first),
  and every run of the experiment (pages of 1000), median of 5 calls.

Before the sweeps, the server CPU of one authenticated request is probed with MLflow's credential cache
(``auth_cache_ttl_seconds``) off and on.  Ranking and report must not grow worse than linearly: the verdict
lines compare each one's growth with the growth in runs.  ``--raw FILE`` keeps the raw numbers of each
size (a pass that fails later resumes from them).  ``--write-docs`` puts the output into
docs/cluster.md (after ``<!-- cluster_scale -->``).
"""

from __future__ import annotations

import argparse
import io
import json
import os
import re
import statistics
import subprocess
import sys
import tempfile
import time
import urllib.error
import urllib.request
from base64 import b64encode
from collections import Counter
from contextlib import redirect_stdout
from pathlib import Path

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ[_var] = "1"

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))

from tests.cluster import services  # noqa: E402

# Binary records only, several seeds each: the two sizes differ in their number of records, not in what a run
# estimates.
SIMULATED = ["binary_a025", "binary_a05", "binary_a075"]
STRUCTURES = ["arx", "armax", "oe", "bj"]
TINY = ["dataset.duration_s=4", "dataset.preprocess.trim=500"]


ORDERS = 2  # orders 1 and 2 of every structure: each dataset × seed is 8 configs, the sweep's shape


def grid(runs: int) -> tuple[list[str], int]:
    """Sweep overrides of at least ``runs`` configs: datasets × seeds × the 4 structures × orders 1…2.  A larger
    sweep has more records (datasets, then seeds), not higher orders, so its estimations cost what the
    smaller one's do and the rows compare the path into the store."""
    shape = len(STRUCTURES) * ORDERS
    for seeds in range(1, 1000):
        for n_data in range(1, len(SIMULATED) + 1):
            if n_data * seeds * shape >= runs:
                return ([f"dataset={','.join(SIMULATED[:n_data])}", f"dataset.seed=range(1,{seeds + 1})",
                         f"structure={','.join(STRUCTURES)}", f"structure.order=range(1,{ORDERS + 1})"],
                        n_data * seeds * shape)
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


ACCESS = re.compile(r'"(GET|POST|PUT|PATCH|DELETE) (/[^ ?"]*)')


def requests_since(log: Path, offset: int) -> Counter:
    """Requests the server logged (uvicorn's access lines) after byte ``offset`` of its log, by method and
    endpoint (an artifact's path folded into ``mlflow-artifacts/artifacts/…``)."""
    with open(log, "rb") as fh:
        fh.seek(offset)
        text = fh.read().decode(errors="replace")
    out: Counter = Counter()
    for method, path in ACCESS.findall(text):
        path = path.removeprefix("/ajax-api").removeprefix("/api").removeprefix("/2.0/").removeprefix("mlflow/")
        if path.startswith("mlflow-artifacts/artifacts/"):
            path = "mlflow-artifacts/artifacts/…"
        if path != "/health":
            out[f"{method} {path}"] += 1
    return out


def roots_of(server: services.Server, pg: services.Postgres) -> list[int]:
    """The processes whose trees do the server's side: the server (its workers below it) and PostgreSQL."""
    return [server.proc.pid, int((pg.home / "data" / "postmaster.pid").read_text().split()[0])]


def request_cpu_ms(server: services.Server, roots: list[int], user: tuple[str, str], n: int = 40) -> float:
    """Server + database CPU milliseconds of one authenticated request (``experiments/get-by-name``),
    averaged over ``n`` after a warm-up call per worker."""
    def call() -> None:
        try:
            server.rest("experiments/get-by-name?experiment_name=Default", auth=user)
        except urllib.error.HTTPError:  # the probe's cost is the request's, found or not
            pass

    for _ in range(5 * WORKERS):  # each worker verifies the password once
        call()
    before = tree_cpu(roots)
    for _ in range(n):
        call()
    return 1000 * (tree_cpu(roots) - before) / n


def measure(size: int, server: services.Server, slurm: services.Slurm, env: dict, work: Path,
            roots: list[int], user: tuple[str, str]) -> dict:
    overrides, n = grid(size)
    name = f"scale{n}"
    cmd = [sys.executable, str(REPO / "study.py"), "-m", "hydra/launcher=slurm", "tracking=cluster",
           f"hydra.launcher.partition={slurm.partition}", f"tracking.experiment={name}", f"study.name={name}",
           *overrides, *TINY, "study.true_plant=false", "lab.enabled=false", "tracking.log_figures=false",
           f"hydra.sweep.dir={work}/{name}", "~hydra.callbacks.maglev_rank"]
    log = server.home / "server.log"
    offset, back = log.stat().st_size, tree_cpu(roots)
    tic = time.perf_counter()
    proc = subprocess.run(cmd, cwd=work, env=env, capture_output=True, text=True)
    sweep_s = time.perf_counter() - tic
    sweep_cpu = tree_cpu(roots) - back
    if proc.returncode:
        raise SystemExit(f"cluster_scale: the {n}-run sweep failed: {proc.stderr.strip().splitlines()[-1:]}")
    requests = requests_since(log, offset)

    from mlflow import MlflowClient

    from maglev.study.ranking import compute
    from maglev.study.report import ranking_run_for, write_report
    from maglev.study.store import load_sweep

    client = MlflowClient(server.url)
    exp_id = client.get_experiment_by_name(name).experiment_id
    models = client.search_runs([exp_id], "tags.kind = 'model' and attributes.status = 'FINISHED'",
                                max_results=50000)
    beyond = [(r.info.end_time - r.info.start_time) / 1000 - r.data.metrics["fit_seconds"] for r in models]

    wall, cpu, back = time.perf_counter(), time.process_time(), tree_cpu(roots)
    with redirect_stdout(io.StringIO()):
        sweep = load_sweep(server.url, name, None)
        ranking = compute(sweep)
        run_id = ranking_run_for(ranking)
    rank_s, rank_cpu = time.perf_counter() - wall, time.process_time() - cpu
    rank_cpu += tree_cpu(roots) - back
    wall, cpu, back = time.perf_counter(), time.process_time(), tree_cpu(roots)
    write_report(ranking, run_id, work / "reports")
    report_s, report_cpu = time.perf_counter() - wall, time.process_time() - cpu
    report_cpu += tree_cpu(roots) - back
    page_s, all_s = ui_query_s(Rest(server.url, user), exp_id)
    total = sum(requests.values())
    return {"runs": len(models), "sweep_s": sweep_s, "beyond_ms": 1000 * statistics.median(beyond),
            "requests_per_run": total / len(models), "server_cpu_per_run": sweep_cpu / len(models),
            "server_ms_per_request": 1000 * sweep_cpu / total if total else float("nan"),
            "rank_s": rank_s, "rank_cpu": rank_cpu, "report_s": report_s, "report_cpu": report_cpu,
            "ui_page_ms": 1000 * page_s, "ui_all_ms": 1000 * all_s,
            "endpoints": {k: v / len(models) for k, v in requests.most_common()}}


ROWS = [("runs (FINISHED)", "runs", "{:.0f}"), ("sweep, whole command (s)", "sweep_s", "{:.1f}"),
        ("per-run overhead beyond estimation, median (ms)", "beyond_ms", "{:.0f}"),
        ("requests to the server per run", "requests_per_run", "{:.1f}"),
        ("server + database CPU per run (s)", "server_cpu_per_run", "{:.2f}"),
        ("server + database CPU per request (ms)", "server_ms_per_request", "{:.1f}"),
        ("ranking: load + rank + log (s)", "rank_s", "{:.2f}"),
        ("ranking CPU, client + server + database (s)", "rank_cpu", "{:.2f}"),
        ("report: build + upload (s)", "report_s", "{:.2f}"),
        ("report CPU, client + server + database (s)", "report_cpu", "{:.2f}"),
        ("UI runs table, first page of 100 (ms)", "ui_page_ms", "{:.0f}"),
        ("UI: every run of the experiment (ms)", "ui_all_ms", "{:.0f}")]


def table(small: dict, large: dict) -> str:
    """The two sizes side by side, the growth of each row, and how each cost grows per run: the overhead,
    the server's CPU, and whether ranking and report grow worse than linearly (their CPU, which the
    machine's other load does not inflate)."""
    lines = [f"| {'':48} | {small['runs']:>8.0f} runs | {large['runs']:>8.0f} runs | growth |",
             f"|{'-' * 50}|{'-' * 15}|{'-' * 15}|--------|"]
    for label, key, fmt in ROWS:
        growth = large[key] / small[key] if small[key] else float("nan")
        lines.append(f"| {label:48} | {fmt.format(small[key]):>13} | {fmt.format(large[key]):>13} | "
                     f"{growth:5.2f}× |")
    n = large["runs"] / small["runs"]
    per_run = {label: (large[key] / large["runs"]) / (small[key] / small["runs"]) for label, key in
               (("overhead beyond estimation", "beyond_ms"), ("server + database CPU", "server_cpu_per_run"),
                ("ranking CPU", "rank_cpu"), ("report CPU", "report_cpu"))}
    per_run["overhead beyond estimation"] *= n  # already a per-run median
    per_run["server + database CPU"] *= n
    verdict = (f"Growth per run, {small['runs']:.0f} → {large['runs']:.0f} runs (1.00×: the total grows linearly; "
               f"within {TOLERANCE:.0%} counts as linear): "
               + ", ".join(f"{label} {g:.2f}× ({growth_word(g)})" for label, g in per_run.items()) + ".")
    return "\n".join(lines + ["", verdict])


TOLERANCE = 0.25  # CPU seconds of one pass on a shared machine scatter by about this much


def growth_word(per_run: float) -> str:
    """How a total grows with the runs, from its growth per run: within ``TOLERANCE`` of flat is linear."""
    if per_run > 1 + TOLERANCE:
        return "WORSE THAN LINEAR"
    return "linear" if per_run >= 1 - TOLERANCE else "less than linear"


def endpoints_line(large: dict) -> str:
    """The requests a run still makes, most frequent first (per run, the large sweep)."""
    parts = [f"{count:.1f} {endpoint}" for endpoint, count in large["endpoints"].items() if count >= 0.05]
    return f"Requests per run ({large['runs']:.0f}-run sweep, launcher and jobs): " + ", ".join(parts) + "."


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--small", type=int, default=24)
    ap.add_argument("--large", type=int, default=200)
    ap.add_argument("--raw", type=Path, help="a file of raw numbers, one JSON line per size and probe: what it "
                    "holds is read, not measured again, and what is measured is appended (a long pass resumed)")
    ap.add_argument("--write-docs", action="store_true", help="put the output into docs/cluster.md")
    a = ap.parse_args()
    keys = ["probe", str(grid(a.small)[1]), str(grid(a.large)[1])]
    raw = {}
    if a.raw and a.raw.exists():
        raw = {rec["key"]: {**rec, "reused": True} for rec in map(json.loads, a.raw.read_text().splitlines())
               if rec["key"] in keys}
    if any(k not in raw for k in keys):
        measure_all(a, keys, raw)
    probe, small, large = (raw[k] for k in keys)
    reused = [f"{rec['runs']:.0f} runs" for rec in (small, large) if rec.get("reused")]
    loads = "; ".join(f"{rec['runs']:.0f} runs: {rec.get('load', 'not recorded')}" for rec in (small, large))
    out = (f"{table(small, large)}\n\n{endpoints_line(large)}\n"
           f"Server + database CPU of one authenticated request: {probe['off']:.0f} ms with MLflow's credential "
           f"cache off (the password hash checked on every request), {probe['on']:.0f} ms with "
           f"auth_cache_ttl_seconds = {probe['ttl']}.\n"
           f"Slurm: one node, {probe['cpus']} CPUs, one job per config, {probe['cpus']} at once; the MLflow server "
           f"({WORKERS} workers) on PostgreSQL {probe['postgres']}, basic auth; load average at the end of each "
           f"sweep: {loads} (wall times grow with the machine's other load; the CPU rows count the client, the "
           "server and the database, not the other load)."
           + (f" Read from an earlier pass of this command (--raw): {', '.join(reused)}." if reused else ""))
    print(out)
    if a.write_docs:
        doc = REPO / "docs" / "cluster.md"
        text = doc.read_text()
        marker = "<!-- cluster_scale -->"
        head = text[: text.index(marker) + len(marker)]
        doc.write_text(f"{head}\n\n```text\n$ python bench/cluster_scale.py --small {a.small} --large {a.large}\n"
                       f"{out}\n```\n")
    return 0


def measure_all(a: argparse.Namespace, keys: list[str], raw: dict) -> None:
    """Start Slurm, PostgreSQL and the server, probe one request's cost and run the sweeps ``raw`` lacks;
    each record is added to ``raw`` and appended to ``a.raw``."""
    def keep(rec: dict) -> None:
        raw[rec["key"]] = rec
        print(json.dumps(rec), file=sys.stderr, flush=True)  # the raw numbers, as they come
        if a.raw:
            with open(a.raw, "a") as fh:
                fh.write(json.dumps(rec) + "\n")

    try:
        slurm = services.start_slurm(cpus=os.cpu_count() or 1)
    except services.Unavailable as exc:
        raise SystemExit(f"cluster_scale: {exc}") from None
    try:
        pg = services.start_postgres()
        try:
            off = services.start_server(pg, workers=WORKERS, auth_cache_ttl_s=0)
            try:  # the users live in the auth database: the bench's user serves both servers
                user = off.add_user("bench")
                cost_off = request_cpu_ms(off, roots_of(off, pg), user)
            finally:
                off.close()
            server = services.start_server(pg, workers=WORKERS)
            try:
                roots = roots_of(server, pg)
                keep({"key": "probe", "off": cost_off, "on": request_cpu_ms(server, roots, user),
                      "ttl": services.AUTH_CACHE_TTL_S, "cpus": os.cpu_count(), "postgres": pg_version()})
                env = {k: v for k, v in os.environ.items() if not k.startswith(("MLFLOW_", "MAGLEV_"))}
                env.update(slurm.env, MLFLOW_TRACKING_URI=server.url, MLFLOW_TRACKING_USERNAME=user[0],
                           MLFLOW_TRACKING_PASSWORD=user[1], PYTHONPATH=str(REPO))
                os.environ.update({k: env[k] for k in ("MLFLOW_TRACKING_URI", "MLFLOW_TRACKING_USERNAME",
                                                       "MLFLOW_TRACKING_PASSWORD")})
                with tempfile.TemporaryDirectory(prefix="maglev-scale-") as tmp:
                    for size, key in ((a.small, keys[1]), (a.large, keys[2])):
                        if key not in raw:
                            rec = measure(size, server, slurm, env, Path(tmp), roots, user)
                            rec["load"] = ", ".join(f"{x:.1f}" for x in os.getloadavg())
                            keep({"key": key, **rec})
            finally:
                server.close()
        finally:
            pg.stop()
    finally:
        slurm.stop()


WORKERS = 4  # the recipe's --workers (docs/cluster.md)


def pg_version() -> str:
    out = subprocess.run(["postgres", "--version"], capture_output=True, text=True).stdout.split()
    return out[2] if len(out) > 2 else "?"  # postgres (PostgreSQL) 15.18 (Debian …)


if __name__ == "__main__":
    raise SystemExit(main())
