"""What every section of the report is made of: `Section` (numbers, one sentence, a status, a figure and
the details) with its status words, and the HTML pieces the sections write (`esc`, `num`, `table`).
"""
from __future__ import annotations

import html
from dataclasses import dataclass

import numpy as np

GOOD, FAIR, POOR = "good", "fair", "poor"


@dataclass
class Section:
    key: str                  # the HTML id
    title: str
    status: str               # good | fair | poor | "" (not judged)
    headline: str             # a few words for the summary table
    sentence: str             # ONE sentence: what it means and whether it is good
    figure: object = None     # the embedded figure (magyro.report.embed.EmbeddedFigure), or None
    figure_alt: str = ""
    details: str = ""         # HTML (tables, lists), already escaped
    caveat: str = ""          # a short clause for the verdict when the status is not good


def esc(text) -> str:
    return html.escape(str(text), quote=True)


def num(value: float, digits: int = 3) -> str:
    """A number for prose: `digits` significant figures, no exponent for ordinary sizes."""
    if value is None or not np.isfinite(value):
        return "n/a"
    if value == 0:
        return "0"
    magnitude = int(np.floor(np.log10(abs(value))))
    decimals = max(0, digits - 1 - magnitude)
    return f"{value:.{decimals}f}"


def table(header: list, rows: list, classes: str = "") -> str:
    """An HTML table; cells are escaped unless given as ("html", text)."""
    def cell(c, tag):
        if isinstance(c, tuple) and c and c[0] == "html":
            return f"<{tag}>{c[1]}</{tag}>"
        return f"<{tag}>{esc(c)}</{tag}>"

    head = "".join(cell(h, "th") for h in header)
    body = "".join("<tr>" + "".join(cell(c, "td") for c in row) + "</tr>" for row in rows)
    return f'<table class="{classes}"><thead><tr>{head}</tr></thead><tbody>{body}</tbody></table>'
