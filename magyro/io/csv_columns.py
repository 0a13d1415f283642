"""Which CSV column feeds which session column: `--map` items read, usual header spellings guessed.

`parse_column_map` reads the `--map NAME=COLUMN` items of `magyro import csv`,
`parse_file_column_map` its `--map NAME=FILE:COLUMN` items (one CSV per sensor);
`guess_column_map` knows the usual header spellings (gyroX, "Gyroscope x (rad/s)", mag_z_uT, ...).
`resolved_column_map` (one file holding every sensor) and `sensor_file_columns` (one file per
sensor) combine the explicit entries with the guesses and refuse what cannot be used.
"""
from __future__ import annotations

import re
from pathlib import Path

from magyro.errors import InputError
from magyro.io.columns import (ACC_COLUMNS, GYRO_COLUMNS, MAG_COLUMNS, OPTIONAL_GROUPS, QUAT_COLUMNS,
                               REQUIRED_COLUMNS, SPEC_NAMES, TIME_COLUMN)

SENSOR_GROUPS = {"gyro": GYRO_COLUMNS, "magnetometer": MAG_COLUMNS, "accelerometer": ACC_COLUMNS,
                 "truth quaternion": QUAT_COLUMNS}

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


def resolved_column_map(path, found: list[str], column_map: dict | None, time_needed: bool = True) -> dict[str, str]:
    """One file holding every sensor: session column name -> an existing column; explicit entries first,
    then guesses. `time_needed` False (a rate is given) lets a file without a time column through."""
    column_map = dict(column_map or {})
    mapping = mapped_and_guessed_columns(path, found, column_map)
    missing = [c for c in REQUIRED_COLUMNS if c not in mapping and (time_needed or c != TIME_COLUMN)]
    if missing:
        raise InputError(f"{path}: no column for {', '.join(missing)}; found columns: {shown_columns(found)}. "
                         f"Map them, e.g. --map {missing[0]}=COLUMN (Python: column_map={{'{missing[0]}': 'COLUMN'}})"
                         f"{_COUNTER_HINT if TIME_COLUMN in missing else ''}")
    return without_double_use(path, mapping)


_COUNTER_HINT = ("; a file whose only time is a sample counter (or none) takes its rate instead: --rate HZ "
                 "(Python: rate_hz=HZ), with the counter mapped as t if it has one")


def mapped_and_guessed_columns(path, found: list[str], column_map: dict) -> dict[str, str]:
    """session column name -> a column of `found`: explicit entries (case-insensitive when
    unambiguous), then guesses; an optional group all or nothing."""
    unknown = [k for k in column_map if k not in SPEC_NAMES]
    if unknown:
        raise InputError(f"{path}: unknown session column name(s) {', '.join(map(str, unknown))} in the "
                         f"column map; the names are {' '.join(SPEC_NAMES)}")
    lower: dict[str, list[str]] = {}
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
                         f"{shown_columns(found)}")
    taken = set(mapping.values())
    for name, source in guess_column_map(c for c in found if c not in taken).items():
        mapping.setdefault(name, source)
    for group in OPTIONAL_GROUPS:  # an optional group all or nothing
        _drop_partial_guess(path, mapping, column_map, group)
    return mapping


def _drop_partial_guess(path, mapping: dict, column_map: dict, group: tuple) -> None:
    """A group of which only some columns were found: refused when mapped explicitly, else left out."""
    present = [c for c in group if c in mapping]
    if present and len(present) < len(group):
        if any(c in column_map for c in present):
            raise InputError(f"{path}: the column map gives {', '.join(present)} but not "
                             f"{', '.join(c for c in group if c not in mapping)}; map all of "
                             f"{' '.join(group)} or none")
        for c in present:  # a partial guess is no guess
            del mapping[c]


def without_double_use(path, mapping: dict[str, str]) -> dict[str, str]:
    """`mapping` in SPEC_NAMES order; refused when one column feeds two session columns."""
    dupes = {s for s in mapping.values() if list(mapping.values()).count(s) > 1}
    if dupes:
        raise InputError(f"{path}: column {', '.join(sorted(dupes))} is mapped to more than one "
                         f"session column")
    return {name: mapping[name] for name in SPEC_NAMES if name in mapping}


def shown_columns(found: list[str]) -> str:
    return (", ".join(found[:40]) + (", ..." if len(found) > 40 else "")) or "(none)"


# --------------------------------------------------------------------------- one CSV per sensor


def sensor_file_columns(label: str, found: list[str], column_map: dict) -> dict[str, str]:
    """One sensor file's {session name: column}: its time column and the complete sensor groups."""
    mapping = mapped_and_guessed_columns(label, found, column_map)
    for group in (GYRO_COLUMNS, MAG_COLUMNS):  # all or nothing here too: a file may hold either
        _drop_partial_guess(label, mapping, column_map, group)
    if TIME_COLUMN not in mapping:
        raise InputError(f"{label}: no time column; found columns: {shown_columns(found)}. Map it, e.g. "
                         f"--map t={Path(label).name}:COLUMN")
    if not groups_in(mapping):
        raise InputError(f"{label}: no sensor columns recognised; found columns: {shown_columns(found)}. Map them, "
                         f"e.g. --map gx={Path(label).name}:COLUMN (and gy, gz; or mx my mz, ax ay az)")
    return without_double_use(label, mapping)


def groups_in(mapping: dict) -> list[str]:
    return [name for name, group in SENSOR_GROUPS.items() if group[0] in mapping]


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
