"""Regenerate the canonical-problem table of docs/observability.md (section 5) from `magyro observe`.

    python docs/make_observability_table.py [PAGE]      (default: docs/observability.md)

Every problem of problems/ named in `CANONICAL` is simulated with noise seed 0 and
observed; the table (rank against the theorem's, condition, time to full rank,
sphere visited, verdict, 3 significant digits) replaces the block between the
page's `TABLE_START` and `TABLE_END` markers. tests/test_observe.py imports this
script and fails when the page and the tool disagree.
"""
from __future__ import annotations

import re
import sys
from pathlib import Path

from magyro.observability import ObservabilityReport, observe
from magyro.observability.report import fmt

PAGE = Path(__file__).resolve().parent / "observability.md"
CANONICAL = (  # problem, motion, rank the theorem predicts (docs/observability.md derives it)
    ("static", "none", 2),
    ("axis-x", "about gyro x only", 6),
    ("axis-y", "about gyro y only", 6),
    ("axis-z", "about gyro z only", 6),
    ("two-axes", "x, then y", 9),
    ("three-axes", "x, then y, then z", 12),
    ("paper-table1", "x, y, z at once (Table I)", 12),
)
TABLE_START = "<!-- table:canonical:start -->"
TABLE_END = "<!-- table:canonical:end -->"


def canonical_reports(seed: int = 0) -> dict[str, ObservabilityReport]:
    """observe() on every canonical problem of problems/, simulated with `seed`."""
    from magyro.studies.scenario import load_problem
    from magyro.studies.simulate import simulate

    return {name: observe(simulate(load_problem(name), seed)[0]) for name, _, _ in CANONICAL}


def canonical_table(seed: int = 0, reports: dict | None = None) -> str:
    """The rank/condition table of the canonical problems as the tool reports them (3 significant digits)."""
    reports = reports or canonical_reports(seed)
    lines = ["| problem | motion | rank (theorem) | rank (magyro) | condition | full rank at (s) | sphere visited | verdict |",
             "|---|---|---:|---:|---:|---:|---:|---|"]
    for name, motion, theorem in CANONICAL:
        r = reports[name]
        lines.append(f"| {name} | {motion} | {theorem} | {r.rank} | {fmt(r.condition)} | "
                     f"{'never' if r.full_rank_at_s is None else fmt(r.full_rank_at_s)} | "
                     f"{100 * r.coverage.sphere_fraction:.0f}% | {r.verdict} |")
    return "\n".join(lines)


def table_in_page(text: str) -> str:
    """The text between the canonical-table markers of a page."""
    m = re.search(re.escape(TABLE_START) + r"\n(.*?)\n" + re.escape(TABLE_END), text, flags=re.S)
    if not m:
        raise ValueError(f"no {TABLE_START} ... {TABLE_END} block in the page")
    return m.group(1)


def update_page(path, table: str) -> None:
    """Replace the canonical table of a page (docs/observability.md) with `table`."""
    path = Path(path)
    text = path.read_text(encoding="utf-8")
    old = table_in_page(text)
    path.write_text(text.replace(f"{TABLE_START}\n{old}\n{TABLE_END}", f"{TABLE_START}\n{table}\n{TABLE_END}"),
                    encoding="utf-8")


def main(argv: list[str]) -> None:
    page = Path(argv[0]) if argv else PAGE
    if not page.is_file():
        sys.exit(f"no page at {page}")
    new = canonical_table()
    print(new)
    update_page(page, new)
    print(f"updated {page}")


if __name__ == "__main__":
    main(sys.argv[1:])
