"""Importing phone and logger CSV exports: column names guessed or mapped, units converted.

`import_csv(path, column_map, gyro_unit, mag_unit, ...)` reads a CSV with its own column
names and units (time in s, ms, us or ns; gyro rad/s or deg/s; accelerometer m/s^2, g or
mg) and maps it onto the session columns. `guess_column_map` knows the usual header
spellings; `parse_column_map` reads the `--map NAME=COLUMN` items of `magyro import csv`.

`import_csv_files(paths, ...)` merges one CSV per sensor (a gyro file, a magnetometer file,
optionally an accelerometer file) on time into one session; `parse_file_column_map` reads
its `--map NAME=FILE:COLUMN` items. Both importers take `skip_rows` (lines right after the
header, e.g. a units row) and `header_line` (lines before the header, a preamble).

An imported CSV goes through the same checks as a loaded session file
(`magyro.io.checks`), so it is exactly what loading its written file gives back.
"""
from __future__ import annotations

import csv
import json
import re
from pathlib import Path

import numpy as np
import pandas as pd

from magyro.errors import InputError, one_line
from magyro.io.checks import canonical_gyro_unit, check_file_exists, check_time_unit, session_from_table
from magyro.io.columns import (ACC_COLUMNS, GYRO_COLUMNS, MAG_COLUMNS, OPTIONAL_GROUPS, QUAT_COLUMNS,
                               REQUIRED_COLUMNS, SPEC_NAMES, TIME_COLUMN)
from magyro.session import Session

TIME_UNITS = {"s": 1.0, "sec": 1.0, "second": 1.0, "seconds": 1.0,
              "ms": 1e-3, "msec": 1e-3, "millisecond": 1e-3, "milliseconds": 1e-3,
              "us": 1e-6, "µs": 1e-6, "μs": 1e-6, "usec": 1e-6, "microsecond": 1e-6, "microseconds": 1e-6,
              "ns": 1e-9, "nsec": 1e-9, "nanosecond": 1e-9, "nanoseconds": 1e-9}
ACC_UNITS = {"m/s^2": 1.0, "m/s2": 1.0, "m/s²": 1.0, "m/s/s": 1.0, "mps2": 1.0,
             "g": 9.80665, "mg": 9.80665e-3}
# the magnetometer keeps its unit (results come back in it); these are the labels accepted
MAG_UNITS = {"ut": "uT", "µt": "uT", "μt": "uT", "microtesla": "uT", "nt": "nT", "nanotesla": "nT",
             "mt": "mT", "millitesla": "mT", "t": "T", "tesla": "T",
             "g": "G", "gauss": "G", "mg": "mG", "milligauss": "mG",
             "counts": "counts", "count": "counts", "lsb": "counts", "raw": "counts", "adc": "counts",
             "a.u.": "a.u.", "au": "a.u.", "arb": "a.u.", "unitless": "unitless", "1": "unitless",
             "unknown": "unknown"}

# common header spellings (lower case, non-alphanumerics and unit suffixes removed)
_AXIS_PREFIXES = {
    "g": ("g", "gyr", "gyro", "gyroscope", "w", "omega", "angularvelocity", "angvel",
          "rotationrate", "rot", "rate"),
    "m": ("m", "mag", "magn", "magnetometer", "magneticfield", "magfield", "field", "b"),
    "a": ("a", "acc", "accel", "accelerometer", "acceleration", "linearacceleration"),
}
_TIME_NAMES = ("t", "time", "times", "timestamp", "timestamps", "ts", "secondselapsed",
               "elapsed", "elapsedtime", "timeelapsed", "sensortime", "timestampsensor")
_UNIT_SUFFIXES = ("rads", "rad", "degs", "dps", "deg", "ut", "nt", "gauss", "mss", "ms2", "mps2",
                  "ms", "us", "ns", "sec", "s", "g")


# --------------------------------------------------------------------------- column maps


def parse_column_map(items) -> dict[str, str]:
    """NAME=COLUMN items (each may hold several, comma-separated) as {NAME: COLUMN}, stripped.

    `items` None or empty gives {}; a later item for the same NAME wins.
    """
    mapping = {}
    for item in items or []:
        for pair in item.split(","):
            name, sep, column = pair.partition("=")
            if not sep or not name.strip() or not column.strip():
                raise InputError(f"--map {pair!r}: expected NAME=COLUMN, e.g. --map gx=gyroX")
            mapping[name.strip()] = column.strip()
    return mapping


def guess_column_map(columns) -> dict[str, str]:
    """session column name -> source column for headers spelled the usual ways (gyroX, Gyroscope x (rad/s), ...).

    Only unambiguous matches are returned; names that match nothing are left out.
    """
    by_key: dict[str, list[str]] = {}
    for col in columns:
        for key in _candidate_keys(str(col)):
            by_key.setdefault(key, []).append(str(col))
    out = {}
    for name in SPEC_NAMES:
        hits = by_key.get(name, [])
        if len(set(hits)) == 1:
            out[name] = hits[0]
    return out


def _candidate_keys(column: str) -> set[str]:
    """The session column names a header could mean."""
    text = re.sub(r"[\(\[\{].*?[\)\]\}]", "", column).lower()  # drop "(rad/s)", "[uT]"
    norm = re.sub(r"[^a-z0-9]", "", text)
    variants = {norm}
    for suffix in _UNIT_SUFFIXES:  # "gyro_x_rad_s" -> "gyroxrads" -> "gyrox"
        if norm.endswith(suffix) and len(norm) > len(suffix) + 1:
            variants.add(norm[: -len(suffix)])
    keys = set()
    for v in variants:
        if v in _TIME_NAMES:
            keys.add(TIME_COLUMN)
        if v in ("qw", "qx", "qy", "qz"):
            keys.add(v)
        if len(v) >= 2 and v[-1] in "xyz" and v[:-1] in _AXIS_PREFIXES["g"] + _AXIS_PREFIXES["m"] + _AXIS_PREFIXES["a"]:
            for sensor, prefixes in _AXIS_PREFIXES.items():
                if v[:-1] in prefixes:
                    keys.add(sensor + v[-1])
    return keys


# --------------------------------------------------------------------------- import


def import_csv(path, column_map: dict | None, gyro_unit: str, mag_unit: str,
               time_unit: str = "s", acc_unit: str = "m/s^2", delimiter: str | None = None,
               skip_rows: int = 0, header_line: int = 0) -> Session:
    """A CSV export with its own column names and units, as a Session.

    `column_map` maps session column names (t gx gy gz mx my mz, optional ax ay az, qw qx qy qz) to the
    file's columns; names it leaves out are guessed from common spellings
    (`guess_column_map`), `None` guesses all. Times are taken relative to the first
    timestamp (epoch stamps in ns keep full precision) and converted to seconds; the gyro to
    rad/s; the accelerometer to m/s^2; the magnetometer keeps its unit (`mag_unit` is its
    label). Rows stamped with the same time (e.g. a gyro row and a magnetometer row) are
    merged; rows holding none of the mapped sensors are dropped; the rows are ordered by
    time. The delimiter (, ; tab |) is detected unless given, and so is a decimal comma when
    the delimiter is not a comma. `header_line` lines come before the header, `skip_rows`
    lines right after it (a units row) are skipped.
    """
    path = Path(path)
    gyro_unit_c = _gyro_unit(path, gyro_unit)
    mag_unit_c = _mag_unit(path, mag_unit)
    time_scale = _unit_factor(path, time_unit, TIME_UNITS, "time")
    acc_scale = _unit_factor(path, acc_unit, ACC_UNITS, "accelerometer")
    raw = _read_csv_any_delimiter(path, delimiter, skip_rows, header_line)
    mapping = _resolve_column_map(path, raw, column_map)

    table = _sensor_file_samples(path, raw, mapping, acc_scale)
    t_first = table[TIME_COLUMN].iloc[0]
    table[TIME_COLUMN] = (table[TIME_COLUMN] - t_first).astype(float) * time_scale
    _check_time_unit(path, table, time_unit)

    metadata = {
        "source": str(path),
        "gyro_unit": "rad/s",
        "mag_unit": mag_unit_c,
        "acc_unit": "m/s^2",
        "imported_from": f"CSV, time unit {time_unit}, gyro unit {gyro_unit}, acc unit {acc_unit}",
        "column_map": json.dumps(mapping),
        "time_origin": f"{t_first} {time_unit} (t = 0 s)",
    }
    return session_from_table(table, metadata, str(path), gyro_unit=gyro_unit_c, mag_unit=mag_unit_c)


def _canonical_key(unit: str) -> str:
    return "".join(str(unit).split()).lower()


def _gyro_unit(path: Path, unit: str) -> str:
    try:
        return canonical_gyro_unit(unit, "--gyro-unit")
    except InputError as exc:
        raise InputError(f"{path}: {exc}") from None


def _mag_unit(path: Path, unit: str) -> str:
    key = _canonical_key(unit)
    if key not in MAG_UNITS:
        known = sorted(set(MAG_UNITS.values()))
        raise InputError(f"{path}: unknown magnetometer unit {unit!r}; use one of {', '.join(known)} "
                         f"(the readings keep their unit, it is only a label)")
    return MAG_UNITS[key]


def _unit_factor(path: Path, unit: str, table: dict, what: str) -> float:
    key = _canonical_key(unit)
    folded = {_canonical_key(k): v for k, v in table.items()}
    if key not in folded:
        shown = ", ".join(dict.fromkeys(k for k in table if k.isascii()))
        raise InputError(f"{path}: unknown {what} unit {unit!r}; use one of {shown}")
    return folded[key]


def _text_lines(path: Path, header_line: int, n_lines: int) -> list[str]:
    """Up to `n_lines` lines of the file from its header on (the `header_line` lines before it left out)."""
    lines = []
    with open(path, "r", encoding="utf-8", errors="replace") as f:
        for i, line in enumerate(f):
            if i >= header_line:
                lines.append(line.rstrip("\r\n"))
            if len(lines) >= n_lines:
                break
    return lines


def _sniff_delimiter(path: Path, header_line: int = 0) -> str:
    head = "\n".join(_text_lines(path, header_line, 200))
    try:
        return csv.Sniffer().sniff(head, delimiters=",;\t|").delimiter
    except csv.Error:
        first = head.splitlines()[0] if head else ""
        counts = {d: first.count(d) for d in ",;\t|"}
        best = max(counts, key=counts.get)
        return best if counts[best] > 0 else ","


_DECIMAL_COMMA_NUMBER = re.compile(r'^"?[+-]?\d+,\d+([eE][+-]?\d+)?"?$')


def _decimal_mark(path: Path, sep: str, skip_rows: int, header_line: int) -> str:
    """"," when the first data row writes its numbers with a decimal comma (only possible when
    the delimiter is not a comma, e.g. phyphox's "semicolon, decimal comma" export), else "."."""
    if sep == ",":
        return "."
    lines = _text_lines(path, header_line, 2 + skip_rows)
    if len(lines) < 2 + skip_rows:
        return "."
    cells = [c.strip() for c in lines[1 + skip_rows].split(sep)]
    return "," if any(_DECIMAL_COMMA_NUMBER.match(c) for c in cells) else "."


def csv_header(path, delimiter: str | None = None, header_line: int = 0) -> list[str]:
    """The column names of a CSV file (its header line after `header_line` preamble lines), stripped."""
    path = Path(path)
    check_file_exists(path)
    sep = delimiter if delimiter is not None else _sniff_delimiter(path, header_line)
    lines = _text_lines(path, header_line, 1)
    if not lines:
        return []
    return [c.strip() for c in next(csv.reader([lines[0]], delimiter=sep, skipinitialspace=True))]


def _check_row_counts(path: Path, skip_rows: int, header_line: int) -> None:
    for value, option in ((skip_rows, "--skip-rows"), (header_line, "--header-line")):
        if not isinstance(value, (int, np.integer)) or value < 0:
            raise InputError(f"{path}: {option} must be a whole number >= 0, not {value!r}")


def _read_csv_any_delimiter(path: Path, delimiter: str | None, skip_rows: int = 0,
                            header_line: int = 0) -> pd.DataFrame:
    check_file_exists(path)
    _check_row_counts(path, skip_rows, header_line)
    with open(path, "rb") as f:
        if b"\x00" in f.read(8192):
            raise InputError(f"{path}: binary data, not a CSV text file")
    sep = delimiter if delimiter is not None else _sniff_delimiter(path, header_line)
    skipped = [*range(header_line), *range(header_line + 1, header_line + 1 + skip_rows)]
    try:
        decimal = _decimal_mark(path, sep, skip_rows, header_line)
        table = pd.read_csv(path, sep=sep, encoding="utf-8", comment=None, skipinitialspace=True,
                            skiprows=skipped or None, decimal=decimal)
    except pd.errors.EmptyDataError:
        raise InputError(f"{path}: the file holds no header and no data rows") from None
    except UnicodeDecodeError:
        raise InputError(f"{path}: not UTF-8 text; save the export as UTF-8 CSV") from None
    except Exception as exc:
        raise InputError(f"{path}: cannot be read as CSV ({one_line(exc)})") from None
    table.columns = [str(c).strip() for c in table.columns]
    if len(table) == 0:
        raise InputError(f"{path}: the file has a header but no data rows")
    return table


def _resolve_column_map(path: Path, raw: pd.DataFrame, column_map: dict | None) -> dict[str, str]:
    """session column name -> an existing column of `raw`; explicit entries first, then guesses."""
    column_map = dict(column_map or {})
    found = list(raw.columns)
    mapping = _mapped_and_guessed_columns(path, found, column_map)
    missing = [c for c in REQUIRED_COLUMNS if c not in mapping]
    if missing:
        raise InputError(f"{path}: no column for {', '.join(missing)}; found columns: {_shown(found)}. "
                         f"Map them, e.g. --map {missing[0]}=COLUMN (Python: column_map={{'{missing[0]}': 'COLUMN'}})")
    return _without_double_use(path, mapping)


def _mapped_and_guessed_columns(path, found: list[str], column_map: dict) -> dict[str, str]:
    """session column name -> a column of `found`: explicit entries (case-insensitive when
    unambiguous), then guesses; an optional group all or nothing."""
    unknown = [k for k in column_map if k not in SPEC_NAMES]
    if unknown:
        raise InputError(f"{path}: unknown session column name(s) {', '.join(map(str, unknown))} in the "
                         f"column map; the names are {' '.join(SPEC_NAMES)}")
    lower = {}
    for c in found:
        lower.setdefault(c.lower(), []).append(c)
    mapping, absent = {}, []
    for name, source in column_map.items():
        source = str(source).strip()
        if source in found:
            mapping[name] = source
        elif len(lower.get(source.lower(), [])) == 1:
            mapping[name] = lower[source.lower()][0]
        else:
            absent.append(f"{name}={source}")
    if absent:
        raise InputError(f"{path}: column(s) not in the file: {', '.join(absent)}; found columns: "
                         f"{_shown(found)}")
    taken = set(mapping.values())
    for name, source in guess_column_map(c for c in found if c not in taken).items():
        mapping.setdefault(name, source)
    for group in OPTIONAL_GROUPS:  # an optional group all or nothing
        present = [c for c in group if c in mapping]
        if present and len(present) < len(group):
            explicit = [c for c in present if c in column_map]
            if explicit:
                raise InputError(f"{path}: the column map gives {', '.join(present)} but not "
                                 f"{', '.join(c for c in group if c not in mapping)}; map all of "
                                 f"{' '.join(group)} or none")
            for c in present:  # a partial guess is no guess
                del mapping[c]
    return mapping


def _without_double_use(path, mapping: dict[str, str]) -> dict[str, str]:
    """`mapping` in SPEC_NAMES order; refused when one column feeds two session columns."""
    dupes = {s for s in mapping.values() if list(mapping.values()).count(s) > 1}
    if dupes:
        raise InputError(f"{path}: column {', '.join(sorted(dupes))} is mapped to more than one "
                         f"session column")
    return {name: mapping[name] for name in SPEC_NAMES if name in mapping}


def _shown(found: list[str]) -> str:
    return (", ".join(found[:40]) + (", ..." if len(found) > 40 else "")) or "(none)"


def _time_values(path: Path, series: pd.Series, column: str) -> np.ndarray:
    """The time column as numbers (int64 kept exact for epoch ns stamps), all finite."""
    if pd.api.types.is_integer_dtype(series):
        return series.to_numpy(dtype=np.int64)
    values = _numbers(path, series, column)
    bad = ~np.isfinite(values)
    if bad.any():
        i = int(np.flatnonzero(bad)[0])
        raise InputError(f"{path}: row {i}, time column {column} is {series.iloc[i]!r}; every row "
                         f"needs a finite time (rows numbered from 0, not counting the header)")
    return values


def _numbers(path: Path, series: pd.Series, column: str) -> np.ndarray:
    if pd.api.types.is_bool_dtype(series):
        raise InputError(f"{path}: column {column} holds true/false values, not numbers")
    numeric = pd.to_numeric(series, errors="coerce")
    bad = numeric.isna().to_numpy() & series.notna().to_numpy()
    if pd.api.types.is_object_dtype(series) or pd.api.types.is_string_dtype(series):
        bad &= series.astype(str).str.strip().ne("").to_numpy()
    if bad.any():
        i = int(np.flatnonzero(bad)[0])
        raise InputError(f"{path}: row {i}, column {column} holds {series.iloc[i]!r}, which is not a "
                         f"number (rows numbered from 0, not counting the header){_units_row_hint(i)}")
    return numeric.to_numpy(dtype=float, na_value=np.nan)


def _units_row_hint(row: int) -> str:
    """For text in the first data rows: most likely a units row or a second header row."""
    if row >= 3:
        return ""
    return (f"; if the first {row + 1} line(s) under the header are units or a second header, skip them "
            f"with --skip-rows {row + 1} (Python: skip_rows={row + 1}); a preamble above the header "
            f"is --header-line N")


def _merge_rows(path: Path, table: pd.DataFrame) -> pd.DataFrame:
    """Rows ordered by time, one per time stamp; each sensor's own stamps strictly increasing."""
    groups = [g for g in (GYRO_COLUMNS, MAG_COLUMNS, *OPTIONAL_GROUPS) if g[0] in table]
    t = table[TIME_COLUMN].to_numpy()
    any_sample = np.zeros(len(table), dtype=bool)
    for group in groups:
        values = table[list(group)].to_numpy()
        if group != QUAT_COLUMNS:  # a truth row may be partly NaN: it then counts as absent
            n_finite = np.isfinite(values).sum(axis=1)
            partial = np.flatnonzero((n_finite > 0) & (n_finite < len(group)))
            if partial.size:
                i = int(partial[0])
                raise InputError(f"{path}: row {i} has {', '.join(c for c, v in zip(group, values[i]) if np.isfinite(v))} "
                                 f"but not {', '.join(c for c, v in zip(group, values[i]) if not np.isfinite(v))}; "
                                 f"a sample needs all of {' '.join(group)} (rows numbered from 0, not counting the header)")
        rows = np.flatnonzero(np.isfinite(values).all(axis=1))
        any_sample[rows] = True
        if rows.size > 1:
            step = np.diff(t[rows])
            bad = np.flatnonzero(step <= 0)
            if bad.size:
                i, j = int(rows[bad[0]]), int(rows[bad[0] + 1])
                what = "the same time as" if step[bad[0]] == 0 else "an earlier time than"
                raise InputError(f"{path}: row {j} has {what} row {i} ({t[j]} vs {t[i]}) for the "
                                 f"{'/'.join(group)} sample; each sensor's time stamps must increase "
                                 f"(rows numbered from 0, not counting the header)")
    table = table[any_sample]
    if len(table) == 0:
        raise InputError(f"{path}: no row holds a complete gyro or magnetometer sample")
    table = table.sort_values(TIME_COLUMN, kind="stable")
    if table[TIME_COLUMN].duplicated().any():
        table = table.groupby(TIME_COLUMN, sort=True, as_index=False).first()
    return table.reset_index(drop=True)


def _check_time_unit(path: Path, table: pd.DataFrame, time_unit: str) -> None:
    """The gyro's median sample interval must be between 10 us and 1 s; else name the unit that fits."""
    g = table[list(GYRO_COLUMNS)].notna().all(axis=1).to_numpy()
    factor = _unit_factor(path, time_unit, TIME_UNITS, "time")
    read_as = {1.0: "s", 1e-3: "ms", 1e-6: "us", 1e-9: "ns"}[factor]
    try:
        check_time_unit(table[TIME_COLUMN].to_numpy()[g], read_as,
                        fix=lambda unit: f"import with --time-unit {unit} (Python: time_unit='{unit}')")
    except InputError as exc:
        raise InputError(f"{path}: with time unit {time_unit!r}, {exc}") from None


# --------------------------------------------------------------------------- one CSV per sensor

SENSOR_GROUPS = {"gyro": GYRO_COLUMNS, "magnetometer": MAG_COLUMNS, "accelerometer": ACC_COLUMNS,
                 "truth quaternion": QUAT_COLUMNS}


def parse_file_column_map(items, paths) -> dict[int, dict[str, str]]:
    """`--map NAME=FILE:COLUMN` items as {index of FILE in `paths`: {NAME: COLUMN}}.

    FILE is a path as given or its file name (when only one given file has that name);
    the split is at the last ':' whose left part names a given file, so columns may hold ':'.
    """
    paths = [Path(p) for p in paths]
    out: dict[int, dict[str, str]] = {}
    for item in items or []:
        for pair in item.split(","):  # pair by pair: each file has its own t
            ((name, target),) = parse_column_map([pair]).items()
            index, column = _file_and_column(name, target, paths)
            out.setdefault(index, {})[name] = column
    return out


def _file_and_column(name: str, target: str, paths: list[Path]) -> tuple[int, str]:
    for cut_at in [i for i, ch in enumerate(target) if ch == ":"][::-1]:
        index = _file_index(target[:cut_at].strip(), paths)
        if index is not None and target[cut_at + 1:].strip():
            return index, target[cut_at + 1:].strip()
    names = ", ".join(p.name for p in paths)
    raise InputError(f"--map {name}={target}: with several files, say which file the column is in: "
                     f"--map {name}=FILE:COLUMN, FILE one of {names}")


def _file_index(text: str, paths: list[Path]) -> int | None:
    exact = [i for i, p in enumerate(paths) if str(p) == text]
    if len(exact) == 1:
        return exact[0]
    by_name = [i for i, p in enumerate(paths) if p.name == text]
    return by_name[0] if len(by_name) == 1 else None


def import_csv_files(paths, column_maps: dict | None, gyro_unit: str, mag_unit: str,
                     time_unit: str = "s", acc_unit: str = "m/s^2", delimiter: str | None = None,
                     skip_rows: int = 0, header_line: int = 0, labels=None,
                     extra_metadata: dict | None = None) -> Session:
    """Several CSV files, one per sensor, merged on time into one Session.

    Each file has its own time column and its own sensor columns; `column_maps` maps a file's
    index in `paths` to its {session name: column} (t gx gy gz mx my mz ax ay az qw qx qy qz);
    names a file's map leaves out are guessed from its header (`guess_column_map`). Each sensor
    (gyro, magnetometer, accelerometer, truth quaternion) must come from exactly one file; the
    gyro and the magnetometer are required. The times of all files share one origin (epoch
    stamps, an app's experiment clock): t = 0 s is the earliest stamp of all files (int64
    epoch stamps stay exact), and the files' time ranges must overlap. `labels` (default: the
    paths) name the files in messages and metadata. The merged table goes through the same
    checks as a session file.
    """
    paths = [Path(p) for p in paths]
    labels = [str(x) for x in (labels or paths)]
    column_maps = dict(column_maps or {})
    gyro_unit_c = _gyro_unit(labels[0], gyro_unit)
    mag_unit_c = _mag_unit(labels[0], mag_unit)
    time_scale = _unit_factor(labels[0], time_unit, TIME_UNITS, "time")
    acc_scale = _unit_factor(labels[0], acc_unit, ACC_UNITS, "accelerometer")

    mappings, tables = [], []
    for i, (path, label) in enumerate(zip(paths, labels)):
        raw = _read_csv_any_delimiter(path, delimiter, skip_rows, header_line)
        mapping = _sensor_file_columns(label, list(raw.columns), dict(column_maps.get(i, {})))
        mappings.append(mapping)
        tables.append(_sensor_file_samples(label, raw, mapping, acc_scale))
    group_files = _one_file_per_sensor(labels, mappings)

    t_origin = _earliest_stamp(tables)
    for table in tables:
        table[TIME_COLUMN] = _seconds_since(table[TIME_COLUMN].to_numpy(), t_origin, time_scale)
    _check_time_ranges_overlap(labels, tables)
    merged = pd.concat(tables, ignore_index=True).sort_values(TIME_COLUMN, kind="stable")
    merged = merged.groupby(TIME_COLUMN, sort=True, as_index=False).first()
    _check_time_unit(labels[group_files["gyro"]], merged, time_unit)

    metadata = {
        "source": json.dumps(labels),
        "sensor_files": json.dumps({group: labels[i] for group, i in group_files.items()}),
        "gyro_unit": "rad/s",
        "mag_unit": mag_unit_c,
        "acc_unit": "m/s^2",
        "imported_from": f"CSV, one file per sensor ({len(paths)} files), time unit {time_unit}, "
                         f"gyro unit {gyro_unit}, acc unit {acc_unit}",
        "column_map": json.dumps({label: m for label, m in zip(labels, mappings)}),
        "time_origin": f"{t_origin} {time_unit} (t = 0 s, the earliest stamp of all files)",
        **(extra_metadata or {}),
    }
    return session_from_table(merged, metadata, " + ".join(labels),
                              gyro_unit=gyro_unit_c, mag_unit=mag_unit_c)


def _sensor_file_columns(label: str, found: list[str], column_map: dict) -> dict[str, str]:
    """One sensor file's {session name: column}: its time column and the complete sensor groups."""
    mapping = _mapped_and_guessed_columns(label, found, column_map)
    for group in (GYRO_COLUMNS, MAG_COLUMNS):  # all or nothing here too: a file may hold either
        present = [c for c in group if c in mapping]
        if present and len(present) < len(group):
            if any(c in column_map for c in present):
                raise InputError(f"{label}: the column map gives {', '.join(present)} but not "
                                 f"{', '.join(c for c in group if c not in mapping)}; map all of "
                                 f"{' '.join(group)} or none")
            for c in present:
                del mapping[c]
    if TIME_COLUMN not in mapping:
        raise InputError(f"{label}: no time column; found columns: {_shown(found)}. Map it, e.g. "
                         f"--map t={Path(label).name}:COLUMN")
    if not _groups_in(mapping):
        raise InputError(f"{label}: no sensor columns recognised; found columns: {_shown(found)}. Map them, "
                         f"e.g. --map gx={Path(label).name}:COLUMN (and gy, gz; or mx my mz, ax ay az)")
    return _without_double_use(label, mapping)


def _groups_in(mapping: dict) -> list[str]:
    return [name for name, group in SENSOR_GROUPS.items() if group[0] in mapping]


def _sensor_file_samples(label: str, raw: pd.DataFrame, mapping: dict, acc_scale: float) -> pd.DataFrame:
    """One file's samples: raw time stamps (int64 kept) and its sensor columns, rows ordered and checked."""
    table = pd.DataFrame({TIME_COLUMN: _time_values(label, raw[mapping[TIME_COLUMN]], mapping[TIME_COLUMN])})
    for name, source in mapping.items():
        if name != TIME_COLUMN:
            table[name] = _numbers(label, raw[source], source)
    for name in ACC_COLUMNS:
        if name in table:
            table[name] = table[name] * acc_scale
    return _merge_rows(label, table)


def _one_file_per_sensor(labels: list[str], mappings: list[dict]) -> dict[str, int]:
    """{sensor: index of the file it comes from}; a sensor in two files, or no gyro or magnetometer, refused."""
    group_files: dict[str, int] = {}
    for i, mapping in enumerate(mappings):
        for group in _groups_in(mapping):
            if group in group_files:
                raise InputError(f"the {group} ({' '.join(SENSOR_GROUPS[group])}) is in two files, "
                                 f"{labels[group_files[group]]} and {labels[i]}; give one file per sensor")
            group_files[group] = i
    for required in ("gyro", "magnetometer"):
        if required not in group_files:
            raise InputError(f"no {required} file among {', '.join(labels)}; give one holding "
                             f"{' '.join(SENSOR_GROUPS[required])} (or map its columns, e.g. "
                             f"--map {SENSOR_GROUPS[required][0]}=FILE:COLUMN)")
    return group_files


def _earliest_stamp(tables: list[pd.DataFrame]):
    """The earliest raw time stamp of all files: an int when every file has integer stamps."""
    firsts = [table[TIME_COLUMN].iloc[0] for table in tables]
    if all(pd.api.types.is_integer_dtype(table[TIME_COLUMN]) for table in tables):
        return int(min(firsts))
    return float(min(firsts))


def _seconds_since(t_raw: np.ndarray, t_origin, time_scale: float) -> np.ndarray:
    """Raw stamps as seconds after `t_origin` (the difference taken in int64 when both are integers)."""
    if np.issubdtype(t_raw.dtype, np.integer) and isinstance(t_origin, int):
        return (t_raw - np.int64(t_origin)).astype(float) * time_scale
    return (t_raw.astype(float) - float(t_origin)) * time_scale


def _check_time_ranges_overlap(labels: list[str], tables: list[pd.DataFrame]) -> None:
    ranges_s = [(table[TIME_COLUMN].iloc[0], table[TIME_COLUMN].iloc[-1]) for table in tables]
    if max(start for start, _ in ranges_s) < min(end for _, end in ranges_s):
        return
    shown = "; ".join(f"{label} {start:.3f} s to {end:.3f} s" for label, (start, end) in zip(labels, ranges_s))
    raise InputError(f"the files' time ranges do not overlap ({shown}, counted from the earliest stamp of all "
                     f"files); the files must come from one recording whose clocks share an origin")
