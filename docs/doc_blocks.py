"""The generated blocks of README.md and docs/*.md: finding, rewriting and checking them, and formatting numbers.

A page's numbers sit between `<!-- numbers:NAME:start -->` and `<!-- numbers:NAME:end -->` markers. A page
generator (docs/make_*_numbers.py) makes every block of its page anew and hands them to `main`, which either
rewrites the page (the text outside the markers is kept) or, with `--check`, exits 1 naming the stale blocks.
Numbers have 3 significant digits, as `magyro observe` prints them (`fmt`); a constant of the code is written as
it is in the code (`g`).
"""
from __future__ import annotations

import json
import re
import sys
from pathlib import Path
from typing import Callable

DOCS = Path(__file__).resolve().parent
ROOT = DOCS.parent
RECORDS = DOCS / "numbers"        # machine-readable records of the expensive measurements (Monte Carlo, BROAD)


# --------------------------------------------------------------------------- formatting


def fmt(x) -> str:
    """3 significant digits, as `magyro observe` prints them."""
    from magyro.observability.report import fmt as tool_fmt

    return tool_fmt(x)


def g(x) -> str:
    """A constant of the code as written (no trailing zeros)."""
    return f"{x:g}"


def fixed(x: float, digits: int, sign: bool = False) -> str:
    """`x` with `digits` decimals (as the tool's tables print them); `sign`: always a sign."""
    return f"{x:+.{digits}f}" if sign else f"{x:.{digits}f}"


def span(values, digits: int | None = None) -> str:
    """'lo-hi' of `values` (3 significant digits, or `digits` decimals); one number when they are all equal."""
    values = [float(v) for v in values]
    show = fmt if digits is None else (lambda v: fixed(v, digits))
    lo, hi = show(min(values)), show(max(values))
    return lo if lo == hi else f"{lo}-{hi}"


def table(header: list[str], rows: list[list[str]], left: tuple = (0, -1)) -> str:
    """A Markdown table: the columns `left` (indices) left-aligned, the others (numbers) right-aligned."""
    lefts = {i % len(header) for i in left}
    align = ["---" if i in lefts else "---:" for i in range(len(header))]
    return "\n".join("| " + " | ".join(r) + " |" for r in [header, align, *rows])


def notes(lines: list[str]) -> str:
    """A Markdown list, one item a line."""
    return "\n".join(f"- {line}" for line in lines)


def escape(text: str) -> str:
    """Text for a Markdown table cell."""
    return text.replace("|", "\\|")


# --------------------------------------------------------------------------- records of expensive measurements


def read_record(name: str) -> dict:
    """docs/numbers/NAME.json, written by the script that measured it."""
    return json.loads((RECORDS / f"{name}.json").read_text(encoding="utf-8"))


def has_record(name: str) -> bool:
    """Whether docs/numbers/NAME.json exists (a page renders a record's blocks once it has been measured)."""
    return (RECORDS / f"{name}.json").is_file()


def commit() -> str:
    """The short commit of the working tree a record is measured on."""
    import subprocess

    done = subprocess.run(["git", "-C", str(ROOT), "rev-parse", "--short", "HEAD"], capture_output=True, text=True)
    return done.stdout.strip() or "unknown"


def write_record(name: str, record: dict, compact: bool = False) -> Path:
    """docs/numbers/NAME.json; `compact`: one line (a record of many runs)."""
    RECORDS.mkdir(exist_ok=True)
    path = RECORDS / f"{name}.json"
    text = (json.dumps(record, sort_keys=True, separators=(",", ":"), default=float) if compact
            else json.dumps(record, indent=1, sort_keys=True, default=float))
    path.write_text(text + "\n", encoding="utf-8")
    return path


# --------------------------------------------------------------------------- the blocks of a page


def marker(name: str, end: str) -> str:
    return f"<!-- numbers:{name}:{end} -->"


def block_pattern(name: str) -> re.Pattern:
    """A block: its own lines between the marker lines, or (inline) a phrase between markers within a line."""
    return re.compile(re.escape(marker(name, "start")) + r"(\n?)(.*?)(\n?)" + re.escape(marker(name, "end")),
                      flags=re.S)


def block_in_page(text: str, name: str) -> str:
    """The text between a block's markers ("" when there is none yet)."""
    m = block_pattern(name).search(text)
    if not m:
        raise ValueError(f"no {marker(name, 'start')} ... {marker(name, 'end')} block in the page")
    return m.group(2)


def rewritten(m: re.Match, name: str, body: str) -> str:
    """A block's markers around `body`, on their own lines unless the block sits inside a line."""
    inline = not m.group(1) and not m.group(3) and "\n" not in m.group(2)
    if inline and "\n" in body:
        raise ValueError(f"block {name} sits inside a line; its text must be one line")
    sep = "" if inline else "\n"
    return f"{marker(name, 'start')}{sep}{body}{sep}{marker(name, 'end')}"


def block_names_in_page(text: str) -> list[str]:
    """Every block a page has markers for, in page order."""
    return re.findall(r"<!-- numbers:([\w.-]+):start -->", text)


def with_blocks(text: str, new: dict[str, str]) -> str:
    """The page with every block's text replaced by `new`'s."""
    for name, body in new.items():
        block_in_page(text, name)   # the markers must be there
        text = block_pattern(name).sub(lambda m: rewritten(m, name, body), text, count=1)
    return text


def stale(text: str, new: dict[str, str]) -> list[str]:
    """The names of the blocks whose text differs from `new` (or that the page lacks)."""
    return [name for name in new if not block_pattern(name).search(text) or block_in_page(text, name) != new[name]]


def main(argv: list[str], page: Path, make_blocks: Callable[[], dict[str, str]], command: str) -> int:
    """`command [--check] [PAGE]`: rewrite the page's blocks with `make_blocks()`, or (--check) exit 1 when stale."""
    check = "--check" in argv
    args = [a for a in argv if a != "--check"]
    page = Path(args[0]) if args else page
    if not page.is_file():
        sys.exit(f"no page at {page}")
    text = page.read_text(encoding="utf-8")
    new = make_blocks()
    old = stale(text, new)
    if check:
        if old:
            print(f"{page} is stale: {', '.join(old)}; regenerate it with `{command}`")
            return 1
        print(f"{page} is up to date")
        return 0
    for name, body in new.items():
        print(f"--- {name}\n{body}")
    page.write_text(with_blocks(text, new), encoding="utf-8")
    print(f"updated {page} ({', '.join(old) or 'nothing changed'})")
    return 0
