"""The user docs stay what a user reads: short, undated, with links that resolve and without retired words.

README.md is the entry (≤ 200 lines), docs/simulator.md the simulator's design and known gaps (≤ 300 lines);
history goes to CHANGELOG.md and docs/decisions/, so no doc carries a date.  The glossary of
docs/architecture.md gives each word one meaning; the words it retires are spot-checked here in the package,
the configs and the docs.  Measured times are quoted only by the pages the benchmarks write.  (docs/validation.md's
currency is checked beside the comparison it is written from: tests/sim/test_sim_vs_real.py; the benchmark pages'
in tests/test_bench.py.)"""

from __future__ import annotations

import re
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]
DOCS = sorted([REPO / "README.md", REPO / "CHANGELOG.md", *REPO.glob("docs/**/*.md")])
LINK = re.compile(r"\[[^\]]*\]\(([^)\s]+)\)")
DATE = re.compile(r"\b20\d\d-[01]\d-[0-3]\d\b")
ORDINALS = ("first|second|third|fourth|fifth|sixth|seventh|eighth|ninth|tenth|eleventh|twelfth|thirteenth|"
            "fourteenth|fifteenth|sixteenth")
# (pattern, what it retires): docs/architecture.md, "Glossary"
RETIRED = [
    (re.compile(r"\bissue[ -]?#?\d+|_issue\d+", re.I), "a tracker's issue number"),
    (re.compile(r"done-when", re.I), "a tracker's done-when"),
    (re.compile(rf"\b(?:{ORDINALS})(?: and (?:{ORDINALS}))? (?:look|looks|attempt)\b", re.I),
     "a calibration stage told as a look or an attempt"),
    (re.compile(r"simulated experiment|experiment spec\b", re.I), "'experiment' for an input class"),
]


def _slug(heading: str) -> str:
    """GitHub's anchor of a Markdown heading."""
    text = re.sub(r"[^\w\- ]", "", heading.strip().lower().replace("`", ""))
    return text.replace(" ", "-")


def _anchors(path: Path) -> set[str]:
    return {_slug(line.lstrip("#")) for line in path.read_text(encoding="utf-8").splitlines() if line.startswith("#")}


def test_the_readme_and_the_simulator_page_are_short():
    assert len((REPO / "README.md").read_text(encoding="utf-8").splitlines()) <= 200
    assert len((REPO / "docs" / "simulator.md").read_text(encoding="utf-8").splitlines()) <= 300


@pytest.mark.parametrize("doc", DOCS, ids=lambda p: p.relative_to(REPO).as_posix())
def test_every_relative_link_resolves_to_a_file_and_its_heading(doc):
    for target in LINK.findall(doc.read_text(encoding="utf-8")):
        if re.match(r"[a-z]+://|mailto:", target):
            continue
        path, _, anchor = target.partition("#")
        resolved = (doc.parent / path).resolve() if path else doc
        assert resolved.exists(), f"{doc.relative_to(REPO)}: link {target!r} points nowhere"
        if anchor and resolved.suffix == ".md":
            assert anchor in _anchors(resolved), f"{doc.relative_to(REPO)}: no heading #{anchor} in {path or doc.name}"


@pytest.mark.parametrize("doc", DOCS, ids=lambda p: p.relative_to(REPO).as_posix())
def test_no_doc_carries_a_date(doc):
    assert DATE.findall(doc.read_text(encoding="utf-8")) == []


TIMING = re.compile(r"\d ?(?:s|ms|seconds|µs|ns)(?: of)? (?:CPU|wall)\b|\bCPU (?:time )?(?:of )?\d|\d ?ms CPU", re.I)
BENCHMARK_PAGES = {REPO / "docs" / "benchmarks.md", REPO / "docs" / "benchmarks-study.md"}


@pytest.mark.parametrize("doc", sorted(set(DOCS) - BENCHMARK_PAGES), ids=lambda p: p.relative_to(REPO).as_posix())
def test_no_doc_but_the_benchmark_pages_quotes_a_cpu_or_wall_time(doc):
    # a measured time is written by its benchmark's command (docs/benchmarks*.md, checked current in
    # tests/test_bench.py; docs/cluster.md's scale block, written by `bench/cluster_scale.py --write-docs`
    # below its marker); a doc links to that output instead of copying a number by hand
    assert TIMING.findall(_by_hand(doc.read_text(encoding="utf-8"))) == []


def _by_hand(text: str) -> str:
    """The text without the block a benchmark command writes below its marker (up to the block's end)."""
    marker = "<!-- cluster_scale -->"
    if marker not in text:
        return text
    head, _, tail = text.partition(marker)
    opening = tail.index("```")
    closing = tail.index("\n```", opening + 3) + 4
    return head + tail[closing:]


def test_a_commands_block_is_left_out_and_nothing_else():
    text = "a 4.3 s CPU claim\n<!-- cluster_scale -->\n\n```text\nranking CPU 0.22×\n```\nthen 46 s wall\n"
    assert TIMING.findall(_by_hand(text)) == ["3 s CPU", "6 s wall"]


def test_the_timing_pattern_catches_hand_copied_timings():
    for text in ("takes 919 ms CPU", "4.3 s CPU", "relaunch: CPU 2.8 s", "38.9 s of CPU", "46 s wall"):
        assert TIMING.search(text), text
    for text in ("substeps of at most 1.7 ms of physics", "10 s / 7 s", "within 30 s"):
        assert not TIMING.search(text), text


def test_the_glossarys_retired_words_are_used_nowhere():
    files = [*REPO.glob("maglev/**/*.py"), *REPO.glob("maglev/**/*.toml"), *REPO.glob("conf/**/*.yaml"),
             REPO / "study.py", *DOCS]
    found = []
    for path in files:
        text = path.read_text(encoding="utf-8")
        for pattern, what in RETIRED:
            found += [f"{path.relative_to(REPO)}: {m.group(0)!r} ({what})" for m in pattern.finditer(text)
                      if not (path.name == "architecture.md" and "Retired words" in text[max(0, m.start() - 400):m.start()])]
    assert found == []


def test_the_slug_of_a_heading_is_githubs():
    assert _slug(" Where maglev differs from MATLAB") == "where-maglev-differs-from-matlab"
    assert _slug(" Is the best linear approximation the truth?") == "is-the-best-linear-approximation-the-truth"
    assert _slug(" The `maglev` command") == "the-maglev-command"
