"""A CSV file's text as a table: options checked, delimiter and decimal mark detected, a BOM dropped.

`checked_read_options(delimiter, skip_rows, header_line)` refuses, before any file is read,
a delimiter that is not one character and line counts that are not whole numbers in
[0, MAX_SKIPPED_LINES]; `read_csv_table(path, ...)` reads the file (UTF-8, with or without a
byte-order mark) into a DataFrame of its columns as written; `csv_header(path)` reads only
its column names.
"""
from __future__ import annotations

import csv
import re
from pathlib import Path

import numpy as np
import pandas as pd

from magyro.errors import InputError, one_line
from magyro.io.checks import check_file_exists

MAX_SKIPPED_LINES = 1_000_000   # --skip-rows/--header-line: a units row or a preamble is a few lines
DETECTED_DELIMITERS = ",;\t|"
DELIMITER_NAMES = {"tab": "\t", "\\t": "\t", "comma": ",", "semicolon": ";", "pipe": "|", "space": " "}
_NOT_DELIMITERS = "\"'.+-\r\n"   # a quote, a number's own characters, a line break
TEXT_ENCODING = "utf-8-sig"     # UTF-8; a byte-order mark (Excel, some phone apps) is dropped
BYTE_ORDER_MARK = "\ufeff"


def checked_read_options(delimiter: str | None, skip_rows, header_line) -> str | None:
    """The delimiter to use (None: detect), after refusing unusable --delimiter/--skip-rows/--header-line."""
    for value, option, name in ((skip_rows, "--skip-rows", "skip_rows"), (header_line, "--header-line", "header_line")):
        if not isinstance(value, (int, np.integer)) or isinstance(value, bool) or value < 0:
            raise InputError(f"{option} must be a whole number >= 0, not {value!r}")
        if value > MAX_SKIPPED_LINES:
            raise InputError(f"{option} {value} is more lines than can be skipped (at most {MAX_SKIPPED_LINES}; "
                             f"a units row or a preamble is a few lines; Python: {name}=)")
    if delimiter is None:
        return None
    sep = DELIMITER_NAMES.get(str(delimiter).lower(), str(delimiter))
    if len(sep) != 1 or sep in _NOT_DELIMITERS or sep.isalnum():
        raise InputError(f"--delimiter {delimiter!r}: a delimiter is one character, e.g. , ; | or tab "
                         f"(not a letter, digit, '.', '+', '-', quote or line break); leave it out to detect "
                         f"one of , ; tab |")
    return sep


def check_readable_csv(path: Path) -> None:
    """An input CSV that exists, is a regular file with bytes in it and can be opened for reading; else
    InputError naming it (a folder named *.csv, a file without read permission), never an I/O error that
    would read as the output's."""
    path = Path(path)
    if path.is_dir():
        raise InputError(f"{path}: a folder, not a CSV file; an input CSV must be a file (replace it with the "
                         f"app's export of that sensor, or leave it out)")
    check_file_exists(path)
    try:
        with open(path, "rb"):
            pass
    except OSError as exc:
        why = "no permission to read it" if isinstance(exc, PermissionError) else one_line(exc)
        raise InputError(f"{path}: the input file cannot be read ({why}); make it readable or leave it "
                         f"out") from None


def check_text(path: Path) -> None:
    """Refuses a file whose first 8 kB hold a NUL byte: binary data (garbage, another format), not CSV text."""
    with open(path, "rb") as f:
        if b"\x00" in f.read(8192):
            raise InputError(f"{path}: binary data, not a CSV text file")


def text_lines(path: Path, header_line: int, n_lines: int) -> list[str]:
    """Up to `n_lines` lines of the file from its header on (the `header_line` lines before it left out)."""
    lines = []
    with open(path, "r", encoding=TEXT_ENCODING, errors="replace") as f:
        for i, line in enumerate(f):
            if i >= header_line:
                lines.append(line.rstrip("\r\n"))
            if len(lines) >= n_lines:
                break
    return lines


def sniff_delimiter(path: Path, header_line: int = 0) -> str:
    head = "\n".join(text_lines(path, header_line, 200))
    try:
        return csv.Sniffer().sniff(head, delimiters=DETECTED_DELIMITERS).delimiter
    except csv.Error:
        first = head.splitlines()[0] if head else ""
        counts = {d: first.count(d) for d in DETECTED_DELIMITERS}
        best = max(counts, key=counts.get)
        return best if counts[best] > 0 else ","


_DECIMAL_COMMA_NUMBER = re.compile(r'^"?[+-]?\d+,\d+([eE][+-]?\d+)?"?$')


def decimal_mark(path: Path, sep: str, skip_rows: int, header_line: int) -> str:
    """"," when the first data row writes its numbers with a decimal comma (only possible when
    the delimiter is not a comma, e.g. phyphox's "semicolon, decimal comma" export), else "."."""
    if sep == ",":
        return "."
    lines = text_lines(path, header_line, 2 + skip_rows)
    if len(lines) < 2 + skip_rows:
        return "."
    cells = [c.strip() for c in lines[1 + skip_rows].split(sep)]
    return "," if any(_DECIMAL_COMMA_NUMBER.match(c) for c in cells) else "."


def clean_column_name(name) -> str:
    return str(name).strip().lstrip(BYTE_ORDER_MARK).strip()


def csv_header(path, delimiter: str | None = None, header_line: int = 0) -> list[str]:
    """The column names of a CSV file (its header line after `header_line` preamble lines), stripped."""
    path = Path(path)
    check_readable_csv(path)
    check_text(path)
    sep = checked_read_options(delimiter, 0, header_line) or sniff_delimiter(path, header_line)
    lines = text_lines(path, header_line, 1)
    if not lines:
        return []
    return [clean_column_name(c) for c in next(csv.reader([lines[0]], delimiter=sep, skipinitialspace=True))]


def read_csv_table(path: Path, delimiter: str | None, skip_rows: int = 0, header_line: int = 0) -> pd.DataFrame:
    """The file's rows under its header as written (`skip_rows` lines after the header and
    `header_line` lines before it left out); refused when binary, not UTF-8, empty or headless."""
    sep = checked_read_options(delimiter, skip_rows, header_line)
    check_readable_csv(path)
    check_text(path)
    sep = sep or sniff_delimiter(path, header_line)
    skipped = [*range(header_line), *range(header_line + 1, header_line + 1 + skip_rows)]
    try:
        decimal = decimal_mark(path, sep, skip_rows, header_line)
        table = pd.read_csv(path, sep=sep, encoding=TEXT_ENCODING, comment=None, skipinitialspace=True,
                            skiprows=skipped or None, decimal=decimal)
    except pd.errors.EmptyDataError:
        raise InputError(f"{path}: the file holds no header and no data rows") from None
    except UnicodeDecodeError:
        raise InputError(f"{path}: not UTF-8 text; save the export as UTF-8 CSV") from None
    except Exception as exc:
        raise InputError(f"{path}: cannot be read as CSV ({one_line(exc)})") from None
    table.columns = [clean_column_name(c) for c in table.columns]
    if len(table) == 0:
        raise InputError(f"{path}: the file has a header but no data rows")
    return table
