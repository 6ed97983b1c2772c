"""The lab's report template (EL2820 Lab 3 §5) as data: what the report must include, where each item is answered.

``REQUIRED`` is §5's list "The report must include", in its order, each mapped to the report
section(s) (their HTML ids) that answer it; ``GRADING`` is the grading template's content
questions, each mapped likewise.  :func:`grading_template` fills the template in: a question
counts as answered when every section it maps to is in the page and has text beyond its title.
"""

from __future__ import annotations

import html
import re

REQUIRED: list[tuple[str, tuple[str, ...]]] = [
    ("the grading template", ("grading-template",)),
    ("solutions for the preparatory tasks", ("preparation", "code")),
    ("motivation for the choice of the working region (with a plot)", ("working-region",)),
    ("why the 3 chosen input signals were selected", ("inputs",)),
    ("the amount of data used for identification and validation", ("data",)),
    ("3 model structures", ("structures",)),
    ("a motivation for the model order of each structure", ("structures",)),
    ("a rank of the top 4 models by FIT", ("top4",)),
    ("for one structure, binary vs uniform input compared", ("binary-vs-uniform",)),
    ("best vs worst model: Bode, poles and zeros, resid", ("best-vs-worst",)),
]

GRADING: list[tuple[str, tuple[str, ...]]] = [
    ("The preparation task is solved and motivated?", ("preparation", "code")),
    ("The working region is defined and motivated?", ("working-region",)),
    ("A detailed description of the input signal is given and the choice is motivated?", ("inputs",)),
    ("The amount of data used for estimation and validation is specified?", ("data",)),
    ("Models of three different model structures have been estimated?", ("structures",)),
    ("The model order of each model is motivated?", ("structures",)),
    ("A top 4 ranking of the estimated models has been made?", ("top4",)),
    ("The best and worst models have been compared using Bode plots, pole/zeros and correlation analysis (resid)?",
     ("best-vs-worst",)),
]

TITLE = "10. Grading template"
_SECTION = re.compile(r"<section id='([^']+)'><h2>(.*?)</h2>(.*?)</section>", re.S)


def sections_of(page: str) -> dict[str, tuple[str, str]]:
    """Section id -> (title, body text without tags) of every section in ``page``."""
    return {sid: (html.unescape(title), " ".join(html.unescape(re.sub(r"<[^>]+>", " ", body)).split()))
            for sid, title, body in _SECTION.findall(page)}


def answered(page: str, anchors: tuple[str, ...], min_chars: int = 40) -> bool:
    """Whether every section in ``anchors`` is in ``page`` with at least ``min_chars`` characters of text."""
    found = sections_of(page)
    return all(a in found and len(found[a][1]) >= min_chars for a in anchors)


def grading_template(page: str) -> str:
    """The grading template filled in for ``page`` (the report without this section): each content question with
    the section(s) answering it and whether they are there, then the items of §5's list no question covers."""
    found = sections_of(page)

    def where(anchors: tuple[str, ...]) -> str:
        return ", ".join(f"<a href='#{a}'>{html.escape(found[a][0]) if a in found else TITLE if a == 'grading-template' else a}"
                         "</a>" for a in anchors)

    rows = [("Author names and personal numbers", "–", "to be filled in by the authors")]
    rows += [(q, where(a), "yes" if answered(page, a) else "NO") for q, a in GRADING]
    graded = {a for _, anchors in GRADING for a in anchors}
    must = [("§5 also asks for: " + item, where(a), "yes" if answered(page, a) or a == ("grading-template",) else "NO")
            for item, a in REQUIRED if not set(a) <= graded]
    body = "".join(f"<tr><td style='text-align:left'>{html.escape(q)}</td><td style='text-align:left'>{w}</td>"
                   f"<td>{s}</td></tr>" for q, w, s in rows + must)
    return (f"<section id='grading-template'><h2>{TITLE}</h2>\n<p>The lab's grading template and §5's "
            "list of what the report must include, with the section answering each (\"yes\": the section is there "
            "and not empty).</p><table class='t' style='break-inside:auto'><tr><th>template item</th><th>answered in</th><th>there</th></tr>"
            + body + "</table></section>\n")
