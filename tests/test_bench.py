"""The benchmark scripts still run (smallest settings); their numbers are not checked here.

Each script's ``main(argv)`` is called in this process: what is tested is that the scripts run against
today's package, not how they start (a process start would cost more than their smallest settings).  The
pages they write into docs/ are checked to be current: measured on today's code and cases
(``bench/fingerprints.py``), since the numbers themselves vary from run to run."""

from __future__ import annotations

import importlib.util
import shutil
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
BENCH = ROOT / "bench"


def _load(script: str):
    spec = importlib.util.spec_from_file_location(f"bench_{Path(script).stem}", BENCH / script)
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module  # dataclasses look their module up
    spec.loader.exec_module(module)
    return module


@pytest.mark.parametrize("script, args, expect", [
    ("estimators.py", ["--quick", "--no-peers", "--reps", "1", "--markdown", "page.md"], "target"),
    ("study_overhead.py", ["--repeats", "1", "--structures", "arx"], "beyond estimation: at most"),
    ("simulator.py", ["--repeats", "1"], "Levitator.simulate"),
    ("prediction.py", ["--samples", "200", "--repeats", "1"], "worst:"),
])
def test_benchmark_script_runs(tmp_path, monkeypatch, capsys, script, args, expect):
    module = _load(script)
    monkeypatch.chdir(tmp_path)
    assert module.main(args) in (0, None)
    assert expect in capsys.readouterr().out
    if "--markdown" in args:  # the page names the command as it ran and today's fingerprint
        fp = _load("fingerprints.py")
        page = (tmp_path / "page.md").read_text(encoding="utf-8")
        assert f"Written by `python bench/{script} {' '.join(args)}`" in page
        assert fp.FINGERPRINT.search(page).group(1) == fp.fingerprint(fp.TABLES["estimators"])
        assert "BJ 4 lev [4 2 2 4 1] at N = 1000, 10000" in page


# ---------------------------------------------------------------------------- the pages are current
@pytest.mark.parametrize("name", ["estimators", "study"])
def test_the_benchmark_pages_measured_what_the_checkout_holds(name):
    # docs/benchmarks*.md carry the fingerprint of the files that decide what they measured (bench/fingerprints.py);
    # timings vary, so this is what "current" means: the same code and cases, not the same numbers
    fp = _load("fingerprints.py")
    problem = fp.stale(fp.TABLES[name])
    assert problem is None, problem


@pytest.fixture
def copy(tmp_path, monkeypatch):
    """A copy of what the fingerprints read, with each page as its command would head it; fingerprints.py on it."""
    for part in ("bench", "maglev", "conf"):
        shutil.copytree(ROOT / part, tmp_path / part, ignore=shutil.ignore_patterns("__pycache__"))
    for part in ("study.py", "pyproject.toml"):
        shutil.copyfile(ROOT / part, tmp_path / part)
    fp = _load("fingerprints.py")
    monkeypatch.setattr(fp, "REPO", tmp_path)
    (tmp_path / "docs").mkdir()
    for table in fp.TABLES.values():
        (tmp_path / table.page).write_text(f"# A page\n\n{fp.header(table, table.command)}\n\n| a |\n|---|\n| 1 |\n")
    return fp, tmp_path


def _touch(path: Path) -> None:
    path.write_text(path.read_text(encoding="utf-8") + "\n# changed\n", encoding="utf-8")


@pytest.mark.parametrize("changed, stale", [
    ("maglev/estimation/starts.py", {"estimators"}),  # the estimators' code
    ("maglev/polynomials.py", {"estimators"}),  # code they call
    ("bench/estimators.py", {"estimators"}),  # the cases
    ("maglev/study/ranking.py", set()),  # the study's code: measured again per version (docs/development.md)
    ("maglev/sim/plant.py", set()),
    ("conf/sweep/lab.yaml", {"study"}),  # the default sweep's jobs
    ("bench/study_overhead.py", {"study"}),
    ("pyproject.toml", {"study"}),  # a new version (below)
])
def test_a_page_is_stale_when_what_it_measured_changes_and_names_its_command(copy, changed, stale):
    fp, root = copy
    assert {n: fp.stale(t) for n, t in fp.TABLES.items()} == {"estimators": None, "study": None}
    if changed == "pyproject.toml":
        text = (root / changed).read_text(encoding="utf-8")
        (root / changed).write_text(text.replace(f'version = "{fp.package_version()}"', 'version = "9.9.9"'))
        assert fp.package_version() == "9.9.9"
    else:
        _touch(root / changed)
    found = {n: fp.stale(t) for n, t in fp.TABLES.items()}
    assert {n for n, why in found.items() if why} == stale
    for name in stale:
        table = fp.TABLES[name]
        assert found[name] == (f"{table.page} measured other code or cases (fingerprint "
                               f"{fp.FINGERPRINT.search((root / table.page).read_text()).group(1)}, today "
                               f"{fp.fingerprint(table)}): run `{table.command}` to regenerate")
        # the command writes the header again: current
        (root / table.page).write_text(f"# A page\n\n{fp.header(table, table.command)}\n")
        assert fp.stale(table) is None


def test_a_page_written_by_another_command_or_by_hand_is_stale(copy):
    fp, root = copy
    table = fp.TABLES["estimators"]
    page = root / table.page
    page.write_text(f"# A page\n\n{fp.header(table, 'python bench/estimators.py --quick --markdown x.md')}\n")
    assert fp.stale(table) == (f"{table.page} was not written by its command: run `{table.command}` to regenerate")
    page.write_text(f"# A page\n\nWritten by `{table.command}`.\n")
    assert fp.stale(table).startswith(f"{table.page} carries no fingerprint: run `{table.command}`")
    # more or fewer repeats measure the same cases; --quick (other N) does not
    study = fp.TABLES["study"]
    with_repeats = study.command.replace(" --markdown", " --repeats 5 --sweeps 3 --markdown")
    (root / study.page).write_text(f"# A page\n\n{fp.header(study, with_repeats)}\n")
    assert fp.stale(study) is None
    quick = table.command.replace(" --markdown", " --quick --markdown")
    page.write_text(f"# A page\n\n{fp.header(table, quick)}\n")
    assert "was not written by its command" in fp.stale(table)


def test_the_estimators_fingerprint_follows_the_imports_of_the_code_it_times():
    fp = _load("fingerprints.py")
    names = {p.relative_to(ROOT).as_posix() for p in fp.files(fp.TABLES["estimators"])}
    assert {"bench/estimators.py", "maglev/estimation/starts.py", "maglev/estimation/prediction_error.py",
            "maglev/structures/bj.py", "maglev/model.py", "maglev/validation.py", "maglev/refdata.py"} <= names
    assert not {n for n in names if n.startswith(("maglev/study/", "maglev/sim/", "maglev/lab/", "tests/", "docs/"))}


# ---------------------------------------------------------------------------- the report's screenshots
def test_the_screenshot_command_stops_in_one_line_without_its_tools(monkeypatch, tmp_path):
    pages = _load("report_pages.py")
    monkeypatch.setattr(pages.shutil, "which", lambda name: None)
    with pytest.raises(SystemExit) as stopped:
        pages.main(["--tracking-uri", f"sqlite:///{tmp_path}/none.db", "--out", str(tmp_path / "png")])
    assert "needs" in str(stopped.value) and "pdftoppm (apt-get install poppler-utils)" in str(stopped.value)
    assert not (tmp_path / "png").exists() and not (tmp_path / "none.db").exists()


@pytest.mark.skipif(shutil.which("pdftoppm") is None, reason="needs pdftoppm (poppler-utils)")
def test_the_screenshots_are_the_pages_before_the_appendix_and_no_older_ones(tmp_path):
    from pypdf import PdfWriter

    pages = _load("report_pages.py")
    writer = PdfWriter()
    for _ in range(3):
        writer.add_blank_page(width=595, height=842)  # A4 in points
    pdf = tmp_path / "r.pdf"
    with open(pdf, "wb") as f:
        writer.write(f)
    out = tmp_path / "png"
    out.mkdir()
    (out / "real-page-7.png").write_bytes(b"left from a longer report")
    (out / "other.png").write_bytes(b"not ours")
    written = pages.rasterise(pdf, 2, out)
    assert written == [out / "real-page-1.png", out / "real-page-2.png"]
    assert sorted(p.name for p in out.iterdir()) == ["other.png", "real-page-1.png", "real-page-2.png"]
    assert (out / "real-page-1.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
