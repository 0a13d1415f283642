"""The input checks of docs/spec.md section 2, and `session_from_table`, which runs them on a table.

A table (a pandas DataFrame, or a `ColumnTable` read from a numeric Parquet file) in the
session layout becomes a `Session` only when: the required columns are there and an
optional group is all or nothing; `t` is numeric, finite and strictly increasing; every
sensor value is a finite number or empty, and a sensor group is on a row whole or not at
all; there are at least `MIN_SAMPLES` gyro and magnetometer samples; the time is in
seconds (a gyro sampled between 1 Hz and 33 kHz: stamps in ms, us or ns are named as
such, before any check on the rates could blame the gyro); the gyro unit is known and
the gyro rates are plausible in it (deg/s data read as rad/s is caught).

Everything wrong raises `InputError` (exit code 2) with one plain message naming the
problem, where it is, and what to do. Rows are numbered from 0, not counting the header.
pandas is imported only for a DataFrame: a numeric Parquet session never needs it.
"""
from __future__ import annotations

from pathlib import Path
from typing import Callable

import numpy as np

from magyro.errors import InputError
from magyro.io.columns import (ACC_COLUMNS, GYRO_COLUMNS, MAG_COLUMNS, OPTIONAL_GROUPS, QUAT_COLUMNS,
                               REQUIRED_COLUMNS, SENSOR_GROUPS, TIME_COLUMN, ColumnTable)
from magyro.session import Session

MIN_SAMPLES = 100
MAX_PLAUSIBLE_RATE_RAD_S = 40.0  # ~2300 deg/s, beyond any MEMS gyro full scale
MIN_PLAUSIBLE_STEP_S = 3e-5      # a gyro sampled faster than 33 kHz (the fastest MEMS output is 32 kHz): not seconds
MAX_PLAUSIBLE_STEP_S = 1.0       # slower than 1 Hz: no hand motion can be integrated; likely ms, us or ns
TYPICAL_GYRO_RATE_HZ = 200.0     # among plausible readings of the stamps, the one nearest this is named
TIME_UNITS_S = {"s": ("seconds", 1.0), "ms": ("milliseconds", 1e-3), "us": ("microseconds", 1e-6),
                "ns": ("nanoseconds", 1e-9)}

GYRO_UNIT_ALIASES = {
    "rad/s": "rad/s", "rad/sec": "rad/s", "rads": "rad/s", "rad_s": "rad/s",
    "rps": "rad/s", "radian/s": "rad/s", "radians/s": "rad/s",
    "deg/s": "deg/s", "deg/sec": "deg/s", "degs": "deg/s", "deg_s": "deg/s",
    "dps": "deg/s", "degree/s": "deg/s", "degrees/s": "deg/s", "°/s": "deg/s",
}
DEFAULT_GYRO_UNIT = "rad/s"
DEFAULT_MAG_UNIT = "unknown"


def session_from_table(table, metadata: dict, source: str,
                       gyro_unit: str | None = None, mag_unit: str | None = None) -> Session:
    """A session table through every check, split into per-sensor time bases; messages start with `source`.

    Unit precedence: argument > the table's metadata (`gyro_unit`, `mag_unit`) > default
    ("rad/s" for the gyro, "unknown" for the magnetometer). The gyro comes out in rad/s.
    """
    try:
        return _checked_session(table, dict(metadata), source, gyro_unit, mag_unit)
    except InputError as exc:
        raise InputError(f"{source}: {exc}") from None


def _checked_session(table, metadata: dict, source: str,
                     gyro_unit: str | None, mag_unit: str | None) -> Session:
    _check_columns(table)
    t_s = _time_column_s(table)
    values = {col: _numeric_column(table, col) for col in _sensor_columns(table)}
    _check_sensor_values(values)

    gyro_unit = _gyro_unit(gyro_unit, metadata)
    mag_unit = mag_unit if mag_unit is not None else metadata.get("mag_unit", DEFAULT_MAG_UNIT)

    t_gyro_s, gyro = _group_samples(t_s, values, GYRO_COLUMNS)
    t_mag_s, mag = _group_samples(t_s, values, MAG_COLUMNS)
    _check_sample_count("gyro", GYRO_COLUMNS, len(t_gyro_s))
    _check_sample_count("magnetometer", MAG_COLUMNS, len(t_mag_s))
    check_time_unit(t_gyro_s)  # before the rates: time in ms makes every later check blame something else
    gyro_rad_s = gyro * _gyro_scale_to_rad_s(gyro_unit)
    _check_gyro_rate_plausible(gyro_rad_s, gyro_unit)

    t_acc_s, acc_m_s2 = _optional_group(t_s, values, ACC_COLUMNS)
    t_quat_s, quat_wxyz = _optional_group(t_s, values, QUAT_COLUMNS)
    return Session(
        t_gyro_s=t_gyro_s, gyro_rad_s=gyro_rad_s, t_mag_s=t_mag_s, mag=mag,
        mag_unit=str(mag_unit), t_acc_s=t_acc_s, acc_m_s2=acc_m_s2,
        t_quat_s=t_quat_s, quat_wxyz=quat_wxyz, source=source, metadata=metadata,
    )


def check_file_exists(path: Path) -> None:
    if not path.exists():
        raise InputError(f"{path}: no such file; check the path")
    if not path.is_file():
        raise InputError(f"{path}: not a regular file; pass a Parquet or CSV session file")
    if path.stat().st_size == 0:
        raise InputError(f"{path}: the file is empty (0 bytes)")


# --------------------------------------------------------------------------- columns and values


def _check_columns(table) -> None:
    """Every required column present; an optional group all or nothing."""
    found = list(table.columns)
    missing = [c for c in REQUIRED_COLUMNS if c not in found]
    for group in OPTIONAL_GROUPS:
        present = [c for c in group if c in found]
        if present and len(present) < len(group):
            missing += [c for c in group if c not in found]
    if missing:
        shown = ", ".join(found[:30]) + (", ..." if len(found) > 30 else "")
        raise InputError(
            f"missing column(s) {', '.join(missing)}; found columns: {shown or '(none)'}. "
            f"A session needs {' '.join(REQUIRED_COLUMNS)} (optional: "
            f"{' '.join(ACC_COLUMNS)}, {' '.join(QUAT_COLUMNS)})")


def _sensor_columns(table) -> list[str]:
    optional = [c for c in (*ACC_COLUMNS, *QUAT_COLUMNS) if c in table.columns]
    return [*GYRO_COLUMNS, *MAG_COLUMNS, *optional]


def _numeric_column(table, col: str) -> np.ndarray:
    """A column as float64; a value that is present but not a number is an error."""
    if isinstance(table, ColumnTable):
        return table[col]  # already float64, read from a numeric Parquet column
    import pandas as pd

    series = table[col]
    if pd.api.types.is_bool_dtype(series) or not (
            pd.api.types.is_numeric_dtype(series) or _is_text(series)):
        raise InputError(f"column {col} has type {series.dtype}; it must hold plain numbers"
                         f"{' (seconds)' if col == TIME_COLUMN else ''}")
    numeric = pd.to_numeric(series, errors="coerce")
    bad = numeric.isna().to_numpy() & series.notna().to_numpy()
    if bad.any():
        i = int(np.flatnonzero(bad)[0])
        raise InputError(f"row {i}, column {col} holds {series.iloc[i]!r}, which is not a number; "
                         f"fix or remove that value")
    return numeric.to_numpy(dtype=float, na_value=np.nan)


def _num(x) -> str:
    """A number as the shortest text that reads back exactly (NaN, inf, -inf spelled so)."""
    x = float(x)
    if np.isnan(x):
        return "NaN"
    return repr(x)


def _is_text(series) -> bool:
    import pandas as pd

    return pd.api.types.is_object_dtype(series) or pd.api.types.is_string_dtype(series)


def _time_column_s(table) -> np.ndarray:
    """The `t` column in seconds: numeric, finite, strictly increasing."""
    t_s = _numeric_column(table, TIME_COLUMN)
    not_finite = ~np.isfinite(t_s)
    if not_finite.any():
        i = int(np.flatnonzero(not_finite)[0])
        raise InputError(f"row {i}: time t is {_num(t_s[i])}; every row needs a finite time in seconds")
    _check_strictly_increasing(t_s)
    return t_s


def _check_strictly_increasing(t_s: np.ndarray) -> None:
    step_s = np.diff(t_s)
    bad = np.flatnonzero(step_s <= 0)
    if bad.size == 0:
        return
    i = int(bad[0]) + 1
    if step_s[i - 1] == 0:
        raise InputError(
            f"row {i}: duplicate time t = {_num(t_s[i])} s, the same as row {i - 1}; "
            f"put samples taken at the same instant on one row")
    raise InputError(
        f"row {i}: time goes backwards, t = {_num(t_s[i])} s after t = {_num(t_s[i - 1])} s at row {i - 1}; "
        f"t must be strictly increasing (sort the rows by t)")


def _check_sensor_values(values: dict[str, np.ndarray]) -> None:
    """No inf anywhere; a sensor group is on a row either whole or not at all."""
    for col, v in values.items():
        inf = np.isinf(v)
        if inf.any():
            i = int(np.flatnonzero(inf)[0])
            raise InputError(f"{_num(v[i])} where a sample should be: row {i}, column {col}; "
                             f"sensor values must be finite numbers (leave the cell empty if there "
                             f"was no sample)")
    for sensor, group in SENSOR_GROUPS.items():
        if group[0] in values:
            _check_group_whole(sensor, group, values)


def _check_group_whole(sensor: str, group: tuple, values: dict[str, np.ndarray]) -> None:
    finite = np.column_stack([np.isfinite(values[c]) for c in group])
    n_finite = finite.sum(axis=1)
    partial = np.flatnonzero((n_finite > 0) & (n_finite < len(group)))
    if partial.size == 0:
        return
    i = int(partial[0])
    nan_col = group[int(np.flatnonzero(~finite[i])[0])]
    ok_col = group[int(np.flatnonzero(finite[i])[0])]
    raise InputError(
        f"NaN where a sample should be: row {i}, column {nan_col} is NaN but {ok_col} = "
        f"{_num(values[ok_col][i])}; a {sensor} sample needs {', '.join(group)} all present "
        f"(leave all three empty if there was no {sensor} sample at that instant)")


# --------------------------------------------------------------------------- per-sensor samples


def _group_samples(t_s: np.ndarray, values: dict, group: tuple) -> tuple[np.ndarray, np.ndarray]:
    """Times and (N, k) values of the rows where every column of the group is finite."""
    stacked = np.column_stack([values[c] for c in group])
    rows = np.isfinite(stacked).all(axis=1)
    return t_s[rows].copy(), stacked[rows].copy()


def _optional_group(t_s: np.ndarray, values: dict, group: tuple):
    """Like `_group_samples`, or (None, None) when the group is absent or never sampled."""
    if group[0] not in values:
        return None, None
    t_group_s, samples = _group_samples(t_s, values, group)
    if len(t_group_s) == 0:
        return None, None
    return t_group_s, samples


def _check_sample_count(sensor: str, group: tuple, n_samples: int) -> None:
    if n_samples < MIN_SAMPLES:
        raise InputError(
            f"too few {sensor} samples: found {n_samples} (rows with {', '.join(group)} all "
            f"present), need at least {MIN_SAMPLES}; record a longer session")


# --------------------------------------------------------------------------- units and rates


def check_time_unit(t_gyro: np.ndarray, read_as: str = "s", fix: Callable[[str], str] | None = None) -> None:
    """InputError unless the gyro's median sample interval, with the stamps read in `read_as`, is 30 us to 1 s.

    The stamps may be in another unit of TIME_UNITS_S: the message names the one
    that makes the gyro's rate plausible (nearest TYPICAL_GYRO_RATE_HZ) and how to
    fix it (`fix(unit)`; default: convert to seconds or import with --time-unit).
    `t_gyro` is in seconds as read, i.e. raw stamps times the factor of `read_as`.
    """
    if len(t_gyro) < 2:
        return
    step_s = float(np.median(np.diff(t_gyro)))
    if MIN_PLAUSIBLE_STEP_S <= step_s <= MAX_PLAUSIBLE_STEP_S:
        return
    raise InputError(time_unit_message(step_s, read_as, fix))


def time_unit_message(step_s: float, read_as: str = "s", fix: Callable[[str], str] | None = None) -> str:
    """The message for a median gyro step of `step_s` seconds (stamps read in `read_as`) that no gyro has."""
    raw_step = step_s / TIME_UNITS_S[read_as][1]
    shown = "'seconds'" if read_as == "s" else f"'{read_as}'"
    plausible = {u: raw_step * f for u, (_, f) in TIME_UNITS_S.items()
                 if u != read_as and MIN_PLAUSIBLE_STEP_S <= raw_step * f <= MAX_PLAUSIBLE_STEP_S}
    if not plausible:
        return (f"the time column cannot be right: the gyro's median step is {raw_step:.4g} {shown} "
                f"({1 / step_s:.4g} Hz if {read_as}), and no unit of {', '.join(TIME_UNITS_S)} gives a "
                f"gyro rate between 1 Hz and 33 kHz; check the time column (t in seconds)")
    unit = min(plausible, key=lambda u: abs(np.log(1.0 / plausible[u] / TYPICAL_GYRO_RATE_HZ)))
    how = fix(unit) if fix else (f"convert it to seconds, or import with `magyro import csv --time-unit {unit}`"
                                 if unit != "s" else "import with `magyro import csv --time-unit s`")
    return (f"the time column looks like {TIME_UNITS_S[unit][0]} (median step {raw_step:.4g} {shown} = "
            f"{1.0 / plausible[unit]:.4g} Hz if {unit}); {how}")


def _gyro_unit(argument: str | None, metadata: dict) -> str:
    """The canonical gyro unit ("rad/s" or "deg/s") from argument > metadata > default."""
    if argument is not None:
        return canonical_gyro_unit(argument, "--gyro-unit")
    if "gyro_unit" in metadata:
        return canonical_gyro_unit(metadata["gyro_unit"], "the file's gyro_unit metadata")
    return DEFAULT_GYRO_UNIT


def canonical_gyro_unit(unit: str, origin: str) -> str:
    """The canonical unit, rad/s or deg/s, of any spelling in GYRO_UNIT_ALIASES; `origin` names its source."""
    key = "".join(str(unit).split()).lower()
    if key not in GYRO_UNIT_ALIASES:
        raise InputError(f"unknown gyro unit {unit!r} (from {origin}); use rad/s or deg/s")
    return GYRO_UNIT_ALIASES[key]


def _gyro_scale_to_rad_s(gyro_unit: str) -> float:
    return np.pi / 180.0 if gyro_unit == "deg/s" else 1.0


def _check_gyro_rate_plausible(gyro_rad_s: np.ndarray, gyro_unit: str) -> None:
    """Reject rates beyond any MEMS full scale: usually deg/s data read as rad/s."""
    p999_rad_s = float(np.percentile(np.linalg.norm(gyro_rad_s, axis=1), 99.9))
    if p999_rad_s <= MAX_PLAUSIBLE_RATE_RAD_S:
        return
    if gyro_unit == "rad/s":
        raise InputError(
            f"gyro rates look like deg/s, not rad/s: 99.9th percentile of |gyro| is "
            f"{p999_rad_s:.1f} rad/s, above the plausible {MAX_PLAUSIBLE_RATE_RAD_S:g} rad/s; "
            f"pass --gyro-unit deg/s")
    raise InputError(
        f"gyro rates are implausible: 99.9th percentile of |gyro| is "
        f"{np.degrees(p999_rad_s):.0f} deg/s, beyond any MEMS gyro full scale; "
        f"check the units of gx, gy, gz")
