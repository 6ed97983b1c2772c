"""The screenshots of the real-data report in docs/report/, made by one command, never by hand.

    nice -n 5 python bench/report_pages.py                   # sweep lab_real into a temporary store first
    python bench/report_pages.py --tracking-uri sqlite:////abs/mlflow.db [--parent RUN_ID]   # a finished sweep

Without ``--tracking-uri`` it runs ``python study.py -m +sweep=lab_real`` (the real sweep, every run) into a
temporary store.  Then, as ``maglev report --pdf`` does, it ranks the sweep, writes its report and prints it to A4
with headless Chromium, and rasterises each page before the appendix with ``pdftoppm -r 56 -png``
(poppler-utils) to ``docs/report/real-page-<n>.png``; pages left from a longer report are removed.  Needs the
real records (``$MAGLEV_REFDATA`` or ``../shared/refdata``), Chromium and pdftoppm; each missing one stops it
in one line before anything is written.  It is not a benchmark: it sits with the scripts that write docs pages.
"""

from __future__ import annotations

import argparse
import os
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")
REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))
OUT = REPO / "docs" / "report"
PREFIX = "real-page-"
DPI = 56  # an A4 page 463 px wide: readable headings, small files


def sweep(store: Path) -> str:
    """Run the real sweep into a fresh store under ``store``; its tracking URI."""
    uri = f"sqlite:///{store}/mlflow.db"
    cmd = [sys.executable, str(REPO / "study.py"), "-m", "+sweep=lab_real", f"tracking.uri={uri}",
           f"tracking.artifact_location={store}/art", f"hydra.sweep.dir={store}/multirun",
           f"hydra.callbacks.maglev_rank.report_dir={store}/reports"]
    print(f"sweeping lab_real into {store} ...", flush=True)
    proc = subprocess.run(cmd, cwd=store, capture_output=True, text=True)
    if proc.returncode:
        raise SystemExit(f"report_pages: the real sweep failed ({proc.returncode}):\n{proc.stderr[-2000:]}")
    return uri


def rasterise(pdf: Path, pages: int, out: Path) -> list[Path]:
    """``pdftoppm -r DPI -png`` of pages 1..``pages`` to ``out/real-page-<n>.png``; older pages beyond removed."""
    out.mkdir(parents=True, exist_ok=True)
    written = []
    for n in range(1, pages + 1):
        target = out / f"{PREFIX}{n}"
        subprocess.run(["pdftoppm", "-r", str(DPI), "-png", "-f", str(n), "-l", str(n), "-singlefile", str(pdf),
                        str(target)], check=True)
        written.append(target.with_suffix(".png"))
    for old in out.glob(f"{PREFIX}*.png"):
        if old not in written:
            old.unlink()
    return written


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--tracking-uri", help="a store holding a finished lab_real sweep (default: sweep one first)")
    p.add_argument("--experiment", default="maglev")
    p.add_argument("--parent", help="the sweep's parent run id (default: the store's latest sweep)")
    p.add_argument("--out", type=Path, default=OUT, help=f"where the PNGs go (default: {OUT.relative_to(REPO)})")
    a = p.parse_args(argv)
    from maglev.paths import refdata_dir
    from maglev.study.report.pdf import chromium

    needs = {"Chromium (apt-get install chromium)": chromium(),
             "pdftoppm (apt-get install poppler-utils)": shutil.which("pdftoppm")}
    if not a.tracking_uri:
        needs["the real records ($MAGLEV_REFDATA or ../shared/refdata)"] = refdata_dir()
    missing = [what for what, found in needs.items() if not found]
    if missing:
        raise SystemExit(f"report_pages: needs {', '.join(missing)}")
    from maglev.study.report import rank_and_report
    from maglev.study.report.pdf import page_texts, pages_before_appendix

    with tempfile.TemporaryDirectory(prefix="report-pages-") as tmp:
        uri = a.tracking_uri or sweep(Path(tmp))
        _, page = rank_and_report(uri, a.experiment, a.parent, out=Path(tmp) / "report" / "real.html", pdf=True)
        pdf = page.with_suffix(".pdf")
        pages = pages_before_appendix(page_texts(pdf))
        written = rasterise(pdf, pages, a.out)
    print(f"{pages} pages before the appendix: " + ", ".join(str(w.relative_to(REPO)) if w.is_relative_to(REPO)
                                                             else str(w) for w in written))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
