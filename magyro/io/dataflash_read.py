"""Reading the messages of an ArduPilot DataFlash log into columns: `.bin` (pymavlink's DFReader, after
`dataflash_frames.check_framing`), `.log` (Mission Planner's text export) and `.mat` (Mission Planner's MATLAB
export, scipy.io.loadmat); the InertialNav text zips (IMU.txt, MAG.txt, ATT.txt) by `magyro.io.dataflash_zip`.

Each reader returns a `LogTables`: for every message name of `WANTED` the log has, its columns as numpy arrays
(strings stay strings), the parameters (PARM Name -> Value, the last value logged) and what the reader knows of
the units (the FMTU messages of a modern .bin). Only the messages magyro uses are kept.
"""
from __future__ import annotations

import contextlib
import io
from pathlib import Path

import numpy as np

from magyro.errors import InputError, one_line
from magyro.io.dataflash_tables import LogTables  # noqa: F401  (importable from here too)

DATAFLASH_INSTALL_HINT = "install it with pip install 'magyro[dataflash]' (or pip install pymavlink)"
MESSAGES_PER_SENSOR = ("", "2", "3")   # IMU, IMU2, IMU3: the instances of logs older than the I column
WANTED = tuple(f"{name}{k}" for name in ("IMU", "MAG") for k in MESSAGES_PER_SENSOR) + ("ATT", "PARM")
TEXT_FIELDS = set("nNZa")              # DataFlash format characters that hold text
MAX_TEXT_LINE_CHARS = 4096             # a Mission Planner .log line is < 300 characters




def read_log(path: Path) -> LogTables:
    """The log at `path` read by its content: DataFlash binary (starts 0xA3 0x95), MATLAB (.mat), else text."""
    _check_file(path)
    with open(path, "rb") as f:
        head = f.read(128)
    if head.startswith(b"\xa3\x95"):
        return read_bin(path)
    if head.startswith(b"PK\x03\x04"):
        from magyro.io.dataflash_zip import read_inertialnav_zip
        return read_inertialnav_zip(path)
    if path.suffix.lower() == ".mat" or head.startswith(b"MATLAB"):
        return read_mat(path)
    if path.suffix.lower() == ".bin":
        raise InputError(f"{path}: not a DataFlash .bin log (it does not start with the message header "
                         f"0xa3 0x95); pass an ArduPilot .bin, a Mission Planner .log or .mat")
    return read_text(path)


def _check_file(path: Path) -> None:
    if not path.exists():
        raise InputError(f"{path}: no such file; check the path")
    if not path.is_file():
        raise InputError(f"{path}: not a regular file; pass an ArduPilot log (.bin, .log or .mat)")
    if path.stat().st_size == 0:
        raise InputError(f"{path}: the file is empty (0 bytes)")


# --------------------------------------------------------------------------- .bin through pymavlink


def read_bin(path: Path) -> LogTables:
    from magyro.io.dataflash_frames import check_framing

    try:
        from pymavlink import DFReader
    except ImportError:
        raise InputError(f"{path}: reading DataFlash .bin logs needs the pymavlink package; "
                         f"{DATAFLASH_INSTALL_HINT}") from None
    data = path.read_bytes()
    framing = check_framing(data, path, DFReader.FORMAT_TO_STRUCT)
    present = [name for name in WANTED if framing.counts.get(name)]
    tables = LogTables("DataFlash .bin", counts=dict(framing.counts))
    if framing.tail_bytes:
        tables.notes.append(f"the log ends inside a message: its last {framing.tail_bytes} bytes (a message cut "
                            f"short) dropped")
    rows: dict = {name: [] for name in present}
    try:
        with contextlib.redirect_stdout(io.StringIO()), contextlib.redirect_stderr(io.StringIO()):
            reader = DFReader.DFReader_binary(str(path), zero_time_base=False)
            columns = {name: list(reader.formats[reader.name_to_id[name]].columns) for name in present}
            tables.units = _fmtu_units(reader, present)
            while present:
                msg = reader.recv_match(type=present)
                if msg is None:
                    break
                name = msg.get_type()
                rows[name].append(tuple(getattr(msg, c) for c in columns[name]))
    except InputError:
        raise
    except Exception as exc:
        raise InputError(f"{path}: cannot be read as a DataFlash log ({one_line(exc)})") from None
    for name in present:
        tables.messages[name] = _columns_of(rows[name], columns[name])
    tables.parameters = _parameters(tables.messages.pop("PARM", None))
    return tables


def _fmtu_units(reader, names) -> dict:
    out = {}
    for name in names:
        fmt = reader.formats[reader.name_to_id[name]]
        units = getattr(fmt, "units", None)
        if units:
            out[name] = dict(zip(fmt.columns, units))
    return out


def _columns_of(rows: list, names: list) -> dict:
    out = {}
    for k, name in enumerate(names):
        values = [r[k] for r in rows]
        out[name] = (np.asarray(values, dtype=object) if values and isinstance(values[0], (str, bytes))
                     else np.asarray(values, dtype=np.float64))
    return out


def _parameters(parm: dict | None) -> dict:
    """PARM's Name -> Value (the last value logged for each name)."""
    if not parm or "Name" not in parm or "Value" not in parm:
        return {}
    names = [n.decode("ascii", "replace") if isinstance(n, bytes) else str(n) for n in parm["Name"]]
    return {n.strip(): float(v) for n, v in zip(names, parm["Value"]) if n.strip()}


# --------------------------------------------------------------------------- Mission Planner's text .log


def read_text(path: Path) -> LogTables:
    """A Mission Planner text log: `FMT, type, length, NAME, format, col1, col2, ...` lines define the messages,
    then one message per line, `NAME, v1, v2, ...`, one value per column of its FMT."""
    formats: dict = {}
    rows: dict = {}
    counts: dict = {}
    try:
        with open(path, "r", encoding="ascii", newline=None) as f:
            for number, line in enumerate(f, start=1):
                if len(line) > MAX_TEXT_LINE_CHARS:
                    raise InputError(f"{path}: line {number} is {len(line)} characters long; a DataFlash text "
                                     f"log's lines are short: the file is damaged or not a .log")
                parts = [p.strip() for p in line.split(",")]
                if parts == [""]:
                    continue
                name = parts[0]
                if name == "FMT":
                    _text_fmt(path, number, parts, formats)
                elif name in formats:
                    counts[name] = counts.get(name, 0) + 1
                    if name in WANTED:
                        rows.setdefault(name, []).append(_text_values(path, number, parts, formats[name]))
                else:
                    counts[name] = counts.get(name, 0) + 1
    except UnicodeDecodeError as exc:
        raise InputError(f"{path}: not a DataFlash text log (byte {exc.start} is not text); pass an ArduPilot "
                         f".bin, or Mission Planner's .log or .mat export") from None
    if not formats:
        raise InputError(f"{path}: not a DataFlash text log: no FMT line defines its messages; pass an ArduPilot "
                         f".bin, or Mission Planner's .log or .mat export")
    undefined = sorted(n for n in counts if n not in formats)
    tables = LogTables("Mission Planner .log (DataFlash text)", counts=counts)
    if undefined:
        tables.notes.append(f"lines of messages no FMT defines ignored: {', '.join(undefined[:10])}")
    for name, values in rows.items():
        fmt, cols = formats[name]
        tables.messages[name] = {c: (np.asarray([r[k] for r in values], dtype=object) if fmt[k] in TEXT_FIELDS
                                     else np.asarray([r[k] for r in values], dtype=np.float64))
                                 for k, c in enumerate(cols)}
    tables.parameters = _parameters(tables.messages.pop("PARM", None))
    return tables


def _text_fmt(path: Path, number: int, parts: list, formats: dict) -> None:
    if len(parts) < 6:
        raise InputError(f"{path}: line {number}: an FMT line needs type, length, name, format and columns; "
                         f"it has {len(parts) - 1} fields")
    name, fmt, cols = parts[3], parts[4], [c for c in parts[5:] if c]
    if name in ("FMT",):
        return
    if len(cols) != len(fmt):
        raise InputError(f"{path}: line {number}: the FMT line of {name} names {len(cols)} column(s) for the "
                         f"{len(fmt)} fields of its format {fmt!r}; the log is damaged")
    formats[name] = (fmt, cols)


def _text_values(path: Path, number: int, parts: list, layout) -> tuple:
    fmt, cols = layout
    values = parts[1:]
    if len(values) != len(cols):
        raise InputError(f"{path}: line {number}: {parts[0]} has {len(values)} value(s), but its FMT line names "
                         f"{len(cols)} columns ({', '.join(cols)}); the log is damaged or cut")
    out = []
    for char, col, text in zip(fmt, cols, values):
        if char in TEXT_FIELDS:
            out.append(text)
            continue
        try:
            value = float(text)
        except ValueError:
            raise InputError(f"{path}: line {number}: {parts[0]} {col} is {text[:40]!r}, not a number; the log is "
                             f"damaged") from None
        if not np.isfinite(value):
            raise InputError(f"{path}: line {number}: {parts[0]} {col} is {text[:40]}; the log is damaged")
        out.append(value)
    return tuple(out)


# --------------------------------------------------------------------------- Mission Planner's .mat


def read_mat(path: Path) -> LogTables:
    """Mission Planner's .mat export: per message an array NAME (one row per message, LineNo first) and a cell
    array NAME_label naming its columns; PARM is a cell array of (name, value) rows."""
    try:
        import scipy.io
        mat = scipy.io.loadmat(str(path))
    except Exception as exc:
        raise InputError(f"{path}: cannot be read as a MATLAB .mat file ({one_line(exc)}); pass Mission "
                         f"Planner's .mat export of a DataFlash log") from None
    tables = LogTables("Mission Planner .mat (DataFlash export)")
    for name, value in mat.items():
        if not name.startswith("__") and not name.endswith("_label") and isinstance(value, np.ndarray):
            tables.counts[name] = int(value.shape[0]) if value.ndim else 0
    for name in WANTED:
        if name == "PARM" or name not in mat:
            continue
        labels = _mat_labels(path, mat, name)
        array = mat[name]
        if array.dtype == object or array.ndim != 2 or array.shape[1] != len(labels):
            raise InputError(f"{path}: the array {name} is {array.dtype} of shape {array.shape}, but {name}_label "
                             f"names {len(labels)} columns ({', '.join(labels)}); the file is damaged")
        values = array.astype(np.float64)
        if not np.isfinite(values).all():
            raise InputError(f"{path}: the array {name} holds values that are not finite numbers; the file is "
                             f"damaged")
        tables.messages[name] = {label: values[:, k] for k, label in enumerate(labels)}
    tables.parameters = _mat_parameters(mat.get("PARM"))
    return tables


def _mat_labels(path: Path, mat: dict, name: str) -> list:
    raw = mat.get(f"{name}_label")
    if raw is None:
        raise InputError(f"{path}: the array {name} has no {name}_label naming its columns; pass Mission Planner's "
                         f".mat export unchanged")
    return [str(np.asarray(cell).ravel()[0]) if np.asarray(cell).size else "" for cell in np.asarray(raw).ravel()]


def _mat_parameters(parm) -> dict:
    """PARM rows (name, value) of a cell array (a TimeUS column, if any, is skipped)."""
    if parm is None or parm.dtype != object or parm.ndim != 2:
        return {}
    out = {}
    for row in parm:
        cells = [np.asarray(c).ravel() for c in row]
        names = [c[0] for c in cells if c.size and isinstance(c[0], str)]
        numbers = [c[0] for c in cells if c.size and not isinstance(c[0], str)]
        if names and numbers:
            out[str(names[0]).strip()] = float(numbers[-1])
    return out
