"""Importing phone and logger CSV exports: one file holding every sensor, or one file per sensor.

`import_csv(path, column_map, gyro_unit, mag_unit, ...)` reads a CSV with its own column
names and units (time in s, ms, us or ns, or a sample counter with `rate_hz`; gyro rad/s or
deg/s; accelerometer m/s^2, g or mg) and maps it onto the session columns
(`magyro.io.csv_columns`). `import_csv_files(paths, ...)` merges one CSV per sensor (a gyro
file, a magnetometer file, optionally an accelerometer file) on time into one session.
Both take `skip_rows` (lines right after the header, e.g. a units row) and `header_line`
(lines before the header, a preamble); the text is read by `magyro.io.csv_text`.

Every reading must be a number: an infinite one or one beyond +-MAX_ABS_READING (no sensor
reads that; e.g. 1e300 from a broken logger) is refused naming its row, before any check.
An imported CSV goes through the same checks as a loaded session file
(`magyro.io.checks`), so it is exactly what loading its written file gives back.
"""
from __future__ import annotations

import json
import re
from pathlib import Path

import numpy as np
import pandas as pd

from magyro.errors import InputError
from magyro.io.checks import MAX_PLAUSIBLE_STEP_S, MIN_PLAUSIBLE_STEP_S, check_time_unit, session_from_table
from magyro.io.columns import ACC_COLUMNS, GYRO_COLUMNS, MAG_COLUMNS, OPTIONAL_GROUPS, QUAT_COLUMNS, TIME_COLUMN
from magyro.io.csv_columns import (SENSOR_GROUPS, groups_in, resolved_column_map, sensor_file_columns)
from magyro.io.csv_text import checked_read_options, read_csv_table
from magyro.io.csv_units import (ACC_UNITS, acc_factor, acc_unit_from_gravity, gyro_unit_label, header_units,
                                 mag_unit_label, resolved_unit, time_factor, time_unit_label)
from magyro.session import Session

MAX_ABS_READING = 1e9        # beyond any sensor reading in any unit accepted (nT, counts of a 24-bit ADC, mg)
MAX_ABS_TIME = 1e19          # beyond an epoch stamp in ns (1.7e18 in 2024)
ACC_AUTO = "auto"            # the accelerometer's unit told from gravity: g when |a| is near 1, m/s^2 near 9.8


def import_csv(path, column_map: dict | None, gyro_unit: str | None = None, mag_unit: str | None = None,
               time_unit: str | None = None, acc_unit: str | None = None, delimiter: str | None = None,
               skip_rows: int = 0, header_line: int = 0, rate_hz: float | None = None) -> Session:
    """A CSV export with its own column names and units, as a Session.

    `column_map` maps session column names (t gx gy gz mx my mz, optional ax ay az, qw qx qy qz) to the
    file's columns; names it leaves out are guessed from common spellings
    (`guess_column_map`), `None` guesses all. Times are taken relative to the first
    timestamp (epoch stamps in ns keep full precision) and converted to seconds; the gyro to
    rad/s; the accelerometer to m/s^2; the magnetometer keeps its unit (`mag_unit` is its
    label). With `rate_hz`, the time column is a sample counter (t = count / rate_hz), or,
    when the file has none, the row number is. Rows stamped with the same time (e.g. a gyro row and a
    magnetometer row) are merged; rows holding none of the mapped sensors are dropped; the rows are
    ordered by time. The delimiter (, ; tab |) is detected unless given, and so is a decimal comma when
    the delimiter is not a comma. `header_line` lines come before the header, `skip_rows`
    lines right after it (a units row) are skipped. A unit left out (None) is read from the header when its
    columns say it in brackets ("gx (deg/s)", "mag_x [uT]", "Time (ms)"; `magyro.io.csv_units.header_units`),
    else time is in s and the accelerometer in m/s^2, and the gyro's and magnetometer's are asked for; a unit
    given that the header contradicts is refused naming both.
    """
    path = Path(path)
    checked_read_options(delimiter, skip_rows, header_line)
    checked_unit_labels(path, gyro_unit, mag_unit, time_unit, acc_unit)
    if rate_hz is not None:
        checked_rate_hz(rate_hz)
    raw = read_csv_table(path, delimiter, skip_rows, header_line)
    mapping = resolved_column_map(path, list(raw.columns), column_map, time_needed=rate_hz is None)
    gyro_unit, mag_unit, time_unit, acc_unit = units_of(path, header_units(path, mapping), gyro_unit, mag_unit,
                                                        time_unit, acc_unit)
    gyro_unit_c, mag_unit_c = gyro_unit_label(path, gyro_unit), mag_unit_label(path, mag_unit)
    time_scale = 1.0 / checked_rate_hz(rate_hz) if rate_hz is not None else time_factor(path, time_unit)
    acc_scale = acc_factor(path, acc_unit)
    if TIME_COLUMN not in mapping:  # a rate and no time column: the row number counts the samples
        raw = raw.assign(**{"(row number)": np.arange(len(raw), dtype=np.int64)})
        mapping = {TIME_COLUMN: "(row number)", **mapping}

    table = sensor_file_samples(path, raw, mapping, acc_scale)
    t_first = table[TIME_COLUMN].iloc[0]
    t_raw = table[TIME_COLUMN].to_numpy()
    table[TIME_COLUMN] = (table[TIME_COLUMN] - t_first).astype(float) * time_scale
    if rate_hz is None:
        check_csv_time_unit(path, table, time_unit, t_raw, mapping[TIME_COLUMN])
    clock = f"sample counter at {rate_hz:g} Hz" if rate_hz is not None else f"time unit {time_unit}"
    metadata = {
        "source": str(path),
        "gyro_unit": "rad/s",
        "mag_unit": mag_unit_c,
        "acc_unit": "m/s^2",
        "imported_from": f"CSV, {clock}, gyro unit {gyro_unit}, acc unit {acc_unit}",
        "column_map": json.dumps(mapping),
        "time_origin": (f"sample {t_first} (t = 0 s), {rate_hz:g} Hz" if rate_hz is not None
                        else f"{t_first} {time_unit} (t = 0 s)"),
    }
    return session_from_table(table, metadata, str(path), gyro_unit=gyro_unit_c, mag_unit=mag_unit_c)


def checked_unit_labels(where, gyro_unit, mag_unit, time_unit, acc_unit) -> None:
    """The units given (not None) are known labels, checked before any file is read."""
    for unit, check in ((gyro_unit, gyro_unit_label), (mag_unit, mag_unit_label), (time_unit, time_factor)):
        if unit is not None:
            check(where, unit)
    if acc_unit is not None and acc_unit != ACC_AUTO:
        acc_factor(where, acc_unit)


def units_of(where, said: dict, gyro_unit, mag_unit, time_unit, acc_unit) -> tuple[str, str, str, str]:
    """The gyro, magnetometer, time and accelerometer units: given, else the header's (`said`), else time in s
    and the accelerometer in m/s^2; a gyro or magnetometer unit neither given nor in the header is asked for."""
    gyro_unit = resolved_unit(where, "gyro", gyro_unit, said)
    mag_unit = resolved_unit(where, "magnetometer", mag_unit, said)
    missing = [option for option, unit in (("--gyro-unit", gyro_unit), ("--mag-unit", mag_unit)) if unit is None]
    if missing:
        raise InputError(f"{where}: give {' and '.join(missing)} (the units of the CSV columns; the header does "
                         f"not say them, as in \"gx (deg/s)\" or \"mag_x [uT]\"), or --preset sensor-logger|phyphox "
                         f"for those apps' exports")
    return (gyro_unit, mag_unit, resolved_unit(where, "time", time_unit, said, "s"),
            resolved_unit(where, "accelerometer", acc_unit, said, "m/s^2"))


def checked_rate_hz(rate_hz) -> float:
    """`--rate HZ`, a sampling rate a gyro can have (1 Hz to 100 kHz), or InputError."""
    try:
        rate = float(rate_hz)
    except (TypeError, ValueError):
        rate = float("nan")
    if not (1.0 / MAX_PLAUSIBLE_STEP_S <= rate <= 1.0 / MIN_PLAUSIBLE_STEP_S):
        raise InputError(f"--rate {rate_hz!r}: the sampling rate in Hz must be between "
                         f"{1 / MAX_PLAUSIBLE_STEP_S:g} and {1 / MIN_PLAUSIBLE_STEP_S:g} (Python: rate_hz=)")
    return rate


# --------------------------------------------------------------------------- values


def time_values(path, series: pd.Series, column: str) -> np.ndarray:
    """The time column as numbers (int64 kept exact for epoch ns stamps), all finite and below MAX_ABS_TIME."""
    if pd.api.types.is_signed_integer_dtype(series) or (pd.api.types.is_unsigned_integer_dtype(series)
                                                          and series.max() <= np.iinfo(np.int64).max):
        return series.to_numpy(dtype=np.int64)
    values = numbers(path, series, column, limit=MAX_ABS_TIME)
    bad = np.isnan(values)
    if bad.any():
        i = int(np.flatnonzero(bad)[0])
        raise InputError(f"{path}: row {i}, time column {column} is {series.iloc[i]!r}; every row "
                         f"needs a finite time (rows numbered from 0, not counting the header)")
    return values


def numbers(path, series: pd.Series, column: str, limit: float = MAX_ABS_READING) -> np.ndarray:
    """A column as float (empty cells NaN); text, infinities and magnitudes beyond `limit` refused by row."""
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
    values = numeric.to_numpy(dtype=float, na_value=np.nan)
    with np.errstate(invalid="ignore"):
        absurd = np.flatnonzero(np.abs(values) > limit)
    if absurd.size:
        i = int(absurd[0])
        raise InputError(f"{path}: row {i}, column {column} holds {values[i]:g}, which no sensor reads "
                         f"({absurd.size} row(s) of this column are infinite or beyond +-{limit:g}; rows numbered "
                         f"from 0, not counting the header); the logger wrote garbage there: delete those rows "
                         f"and import again")
    return values


def _units_row_hint(row: int) -> str:
    """For text in the first data rows: most likely a units row or a second header row."""
    if row >= 3:
        return ""
    return (f"; if the first {row + 1} line(s) under the header are units or a second header, skip them "
            f"with --skip-rows {row + 1} (Python: skip_rows={row + 1}); a preamble above the header "
            f"is --header-line N")


def sensor_file_samples(label, raw: pd.DataFrame, mapping: dict, acc_scale: float | None) -> pd.DataFrame:
    """One file's samples: raw time stamps (int64 kept) and its sensor columns, rows ordered and checked.
    `acc_scale` None: the accelerometer's unit told from gravity (`acc_scale_from_gravity`)."""
    table = pd.DataFrame({TIME_COLUMN: time_values(label, raw[mapping[TIME_COLUMN]], mapping[TIME_COLUMN])})
    for name, source in mapping.items():
        if name != TIME_COLUMN:
            table[name] = numbers(label, raw[source], source)
    if ACC_COLUMNS[0] in table:
        scale = acc_scale if acc_scale is not None else acc_scale_from_gravity(label, table[list(ACC_COLUMNS)])
        for name in ACC_COLUMNS:
            table[name] = table[name] * scale
    return merge_rows(label, table)


def acc_scale_from_gravity(label, acc: pd.DataFrame) -> float:
    """m/s^2 per unit of an accelerometer that holds gravity: g when its median |a| is 0.5-2, m/s^2 when 4.9-20."""
    norm = np.linalg.norm(acc.dropna().to_numpy(), axis=1)
    median = float(np.median(norm)) if norm.size else float("nan")
    unit = acc_unit_from_gravity(median)
    if unit in ("g", "m/s^2"):   # what the exports it serves use; auto takes no mg
        return ACC_UNITS[unit]
    shown = f"{median:.4g}" if np.isfinite(median) else "not defined (no complete sample)"
    raise InputError(f"{label}: cannot tell the accelerometer's unit: its median |a| is {shown}, neither "
                     f"about 1 (g) nor about 9.8 (m/s^2); give the gyro and magnetometer files without it")


def merge_rows(path, table: pd.DataFrame) -> pd.DataFrame:
    """Rows ordered by time, one per time stamp; each sensor's own stamps strictly increasing."""
    groups = [g for g in (GYRO_COLUMNS, MAG_COLUMNS, *OPTIONAL_GROUPS) if g[0] in table]
    t = table[TIME_COLUMN].to_numpy()
    any_sample = np.zeros(len(table), dtype=bool)
    for group in groups:
        values = table[list(group)].to_numpy()
        if group != QUAT_COLUMNS:  # a truth row may be partly NaN: it then counts as absent
            _check_whole_samples(path, group, values)
        rows = np.flatnonzero(np.isfinite(values).all(axis=1))
        any_sample[rows] = True
        if rows.size > 1:
            _check_increasing(path, group, t, rows)
    table = table[any_sample]
    if len(table) == 0:
        raise InputError(f"{path}: no row holds a complete gyro or magnetometer sample")
    table = table.sort_values(TIME_COLUMN, kind="stable")
    if table[TIME_COLUMN].duplicated().any():
        table = table.groupby(TIME_COLUMN, sort=True, as_index=False).first()
    return table.reset_index(drop=True)


def _check_whole_samples(path, group: tuple, values: np.ndarray) -> None:
    n_finite = np.isfinite(values).sum(axis=1)
    partial = np.flatnonzero((n_finite > 0) & (n_finite < len(group)))
    if partial.size:
        i = int(partial[0])
        raise InputError(f"{path}: row {i} has {', '.join(c for c, v in zip(group, values[i]) if np.isfinite(v))} "
                         f"but not {', '.join(c for c, v in zip(group, values[i]) if not np.isfinite(v))}; "
                         f"a sample needs all of {' '.join(group)} (rows numbered from 0, not counting the header)")


def _check_increasing(path, group: tuple, t: np.ndarray, rows: np.ndarray) -> None:
    step = np.diff(t[rows])
    bad = np.flatnonzero(step <= 0)
    if bad.size:
        i, j = int(rows[bad[0]]), int(rows[bad[0] + 1])
        what = "the same time as" if step[bad[0]] == 0 else "an earlier time than"
        raise InputError(f"{path}: row {j} has {what} row {i} ({t[j]} vs {t[i]}) for the "
                         f"{'/'.join(group)} sample; each sensor's time stamps must increase "
                         f"(rows numbered from 0, not counting the header)")


def check_csv_time_unit(path, table: pd.DataFrame, time_unit: str, t_raw: np.ndarray | None = None,
                        column: str = "") -> None:
    """The gyro's median sample interval must be between 10 us and 1 s; else name the unit that fits, or,
    for a sample counter (`is_sample_counter`), ask for its rate."""
    g = table[list(GYRO_COLUMNS)].notna().all(axis=1).to_numpy()
    read_as = time_unit_label(time_factor(path, time_unit))
    counter = t_raw is not None and is_sample_counter(t_raw[g], column)
    counter_message = (f"{path}: the time column {column} counts samples or packets (whole numbers), it is not a "
                       f"clock; give the counter's rate in counts per second: --rate HZ (Python: rate_hz=HZ)")
    if counter and read_as == "s":  # whole seconds stepping by 1: a 1 Hz gyro is no recording to calibrate
        raise InputError(counter_message)
    try:
        check_time_unit(table[TIME_COLUMN].to_numpy()[g], read_as,
                        fix=lambda unit: f"import with --time-unit {unit} (Python: time_unit='{unit}')")
    except InputError as exc:
        raise InputError(counter_message if counter else f"{path}: with time unit {time_unit!r}, {exc}") from None


_COUNTER_NAME = re.compile(r"packet|sample|count|index|seq|frame|tick", re.IGNORECASE)


def is_sample_counter(t_raw: np.ndarray, column: str = "") -> bool:
    """Whole-number stamps whose median step is exactly 1, or that a counter's name heads (x-IMU's
    "Packet number", which steps by about 2: a sample every other packet)."""
    if len(t_raw) < 2:
        return False
    t = np.asarray(t_raw, dtype=float)
    if not np.all(t == np.round(t)):
        return False
    return bool(np.median(np.diff(t)) == 1.0 or _COUNTER_NAME.search(column))


# --------------------------------------------------------------------------- one CSV per sensor


def import_csv_files(paths, column_maps: dict | None, gyro_unit: str | None = None, mag_unit: str | None = None,
                     time_unit: str | None = None, acc_unit: str | None = None, delimiter: str | None = None,
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
    paths) name the files in messages and metadata. `acc_unit` "auto" tells g from m/s^2 by
    gravity. The merged table goes through the same checks as a session file. Units left out (None) are read
    from the files' headers as by `import_csv`.
    """
    paths = [Path(p) for p in paths]
    labels = [str(x) for x in (labels or paths)]
    checked_read_options(delimiter, skip_rows, header_line)
    checked_unit_labels(labels[0], gyro_unit, mag_unit, time_unit, acc_unit)
    column_maps = dict(column_maps or {})

    mappings, raws, said = [], [], {}
    for i, (path, label) in enumerate(zip(paths, labels)):
        raw = read_csv_table(path, delimiter, skip_rows, header_line)
        mapping = sensor_file_columns(label, list(raw.columns), dict(column_maps.get(i, {})))
        mappings.append(mapping)
        raws.append(raw)
        for kind, (unit, column) in header_units(label, mapping).items():
            if kind in said and said[kind][0] != unit:
                raise InputError(f"the files' {kind} columns say different units: {said[kind][1]!r} says "
                                 f"{said[kind][0]}, {label}'s {column!r} says {unit}; one {kind} unit for all files")
            said.setdefault(kind, (unit, f"{label}: {column}"))
    group_files = _one_file_per_sensor(labels, mappings)
    gyro_unit, mag_unit, time_unit, acc_unit = units_of(" + ".join(labels), said, gyro_unit, mag_unit, time_unit,
                                                        acc_unit)
    gyro_unit_c, mag_unit_c = gyro_unit_label(labels[0], gyro_unit), mag_unit_label(labels[0], mag_unit)
    time_scale = time_factor(labels[0], time_unit)
    acc_scale = None if acc_unit == ACC_AUTO else acc_factor(labels[0], acc_unit)
    tables = [sensor_file_samples(label, raw, mapping, acc_scale) for label, raw, mapping in zip(labels, raws, mappings)]

    t_origin = _earliest_stamp(tables)
    for table in tables:
        table[TIME_COLUMN] = _seconds_since(table[TIME_COLUMN].to_numpy(), t_origin, time_scale)
    _check_time_ranges_overlap(labels, tables)
    merged = pd.concat(tables, ignore_index=True).sort_values(TIME_COLUMN, kind="stable")
    merged = merged.groupby(TIME_COLUMN, sort=True, as_index=False).first()
    check_csv_time_unit(labels[group_files["gyro"]], merged, time_unit)

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


def _one_file_per_sensor(labels: list[str], mappings: list[dict]) -> dict[str, int]:
    """{sensor: index of the file it comes from}; a sensor in two files, or no gyro or magnetometer, refused."""
    group_files: dict[str, int] = {}
    for i, mapping in enumerate(mappings):
        for group in groups_in(mapping):
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
