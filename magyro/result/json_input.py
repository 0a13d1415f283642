"""A JSON file given to magyro, read with bounds (issue 25): its size, its nesting, its integers' digits.

`read_json_object(source, what)` returns the JSON object in a file (or in a string of JSON text) or raises
InputError with one message: no such file, unreadable, a file of another kind (a session, a recording, a
zip: named for what it is), a file cut short, too large, nested too deep, an integer too long, not an object.
Nothing here knows what a calibration holds; `magyro.result.calibration` checks that.
"""
from __future__ import annotations

import json
import os
import re
from pathlib import Path

from magyro.errors import InputError, one_line
from magyro.io.bounds import MAX_DEPTH, MAX_INT_DIGITS, tree_problem

MAX_JSON_BYTES = 16 * 2 ** 20   # a calibration is a few kB; a report with series a few MB

# the first bytes of files that are not JSON, to name what was given instead
MAGIC = ((b"PAR1", "a session (Parquet, magyro's session file)"),
         (b"ULog", "a PX4 ULog recording"),
         (b"PK\x03\x04", "a zip archive"),
         (b"MATLAB", "a MATLAB .mat file"),
         (b"\x89HDF", "an HDF5 (.mat v7.3) file"),
         (b"#ROSBAG", "a ROS 1 bag"),
         (b"SQLite format 3", "a SQLite file (a ROS 2 bag)"))
_STRING = re.compile(r'"(?:[^"\\]|\\.)*"', re.DOTALL)


def looks_like_json_text(source) -> bool:
    """True for a str that is JSON text rather than a path: it starts with '{', ends with '}' and names no file."""
    if not isinstance(source, str):
        return False
    s = source.strip()
    return s.startswith("{") and s.endswith("}") and not os.path.exists(source)


def read_json_object(source, what: str = "calibration", hint: str = "") -> dict:
    """The JSON object in the file at `source` (a path) or in `source` itself (JSON text, see
    `looks_like_json_text`); InputError naming the file and the problem otherwise."""
    if looks_like_json_text(source):
        return parse_json_object(source, "", what)
    path = Path(source)
    where = f"{path}: "
    try:
        size = path.stat().st_size
        if path.is_dir():
            raise InputError(f"{where}is a folder, not a {what} file{hint}")
        if size > MAX_JSON_BYTES:
            raise InputError(f"{where}{size} bytes is larger than a {what} can be ({MAX_JSON_BYTES // 2 ** 20} MiB at most)")
        raw = path.read_bytes()
    except FileNotFoundError:
        raise InputError(f"{where}no such file{hint}") from None
    except PermissionError:
        raise InputError(f"{where}cannot be read: permission denied (unreadable input)") from None
    except OSError as exc:
        raise InputError(f"{where}cannot be read ({exc.strerror or one_line(exc)})") from None
    except ValueError as exc:   # a NUL in the path
        raise InputError(f"{where}not a usable path ({one_line(exc)})") from None
    kind = next((name for magic, name in MAGIC if raw.startswith(magic)), None)
    if kind is not None:
        order = " (apply, validate and report take SESSION then CALIB)" if kind.startswith("a session") and what == "calibration" else ""
        raise InputError(f"{where}this is {kind}, not a {what}{hint}{order}")
    try:
        text = raw.decode("utf-8")
    except UnicodeDecodeError as exc:
        raise InputError(f"{where}not a {what}: not UTF-8 text (byte {exc.start}){hint}") from None
    return parse_json_object(text, where, what)


def _bounded_int(digits: str) -> int:
    if len(digits.lstrip("-")) > MAX_INT_DIGITS:
        raise InputError(f"an integer of {len(digits.lstrip('-'))} digits (at most {MAX_INT_DIGITS})")
    return int(digits)


def cut_short(text: str) -> bool:
    """True when JSON text ends inside a string, an object or an array: a file cut short (empty included)."""
    if not text.strip():
        return True
    rest = _STRING.sub("", text)
    if '"' in rest:
        return True    # a string never closed
    return rest.count("{") + rest.count("[") > rest.count("}") + rest.count("]")


def parse_json_object(text: str, where: str = "", what: str = "calibration") -> dict:
    """A JSON object from text, with bounded depth and integers; InputError naming the problem."""
    if len(text) > MAX_JSON_BYTES:
        raise InputError(f"{where}larger than a {what} can be ({MAX_JSON_BYTES // 2 ** 20} MiB at most)")
    try:
        data = json.loads(text, parse_int=_bounded_int)
    except InputError as exc:
        raise InputError(f"{where}not a {what}: {exc}") from None
    except RecursionError:
        raise InputError(f"{where}not a {what}: JSON nested deeper than {MAX_DEPTH} levels") from None
    except json.JSONDecodeError as exc:
        if cut_short(text):
            raise InputError(f"{where}a {what} cut short (the JSON ends early, at line {exc.lineno}): "
                             "the file is incomplete; write it again") from None
        first = text.lstrip()[:1]
        kind = "" if first in "{[" else " (it looks like text or CSV, not JSON)"
        raise InputError(f"{where}not valid JSON{kind}: {exc.msg} at line {exc.lineno}") from None
    except ValueError as exc:   # e.g. Python's own limit on integer digits
        raise InputError(f"{where}not a {what}: {one_line(exc)}") from None
    if not isinstance(data, dict):
        raise InputError(f"{where}a {what} is a JSON object, not a {type(data).__name__}")
    problem = tree_problem(data, MAX_DEPTH, MAX_INT_DIGITS)
    if problem is not None:
        raise InputError(f"{where}not a {what}: {problem}")
    return data
