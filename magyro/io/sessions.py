"""Reading and writing session files (SPEC section 2), and atomic output.

A session file is one table, Parquet or CSV, one row per timestamp:
``t gx gy gz mx my mz`` and optionally ``ax ay az`` and a truth quaternion
``qw qx qy qz``. Sensors sampled at different instants share the table; a row
leaves NaN the sensors with no sample at that instant. Each sensor gets its own
time base in the loaded `Session`.

Everything wrong with an input raises `InputError` (exit code 2) with one plain
message naming the problem, where it is, and what to do. Rows are numbered from
0, not counting the header. Every message starts with the file's path. Input files are only read, never written.

Outputs are written atomically: to a temporary file in the target directory,
then `os.replace`d onto the target, so a file is either whole or absent.
"""
from __future__ import annotations

import os
import tempfile
from pathlib import Path
from typing import Callable

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq

from magyro.errors import InputError
from magyro.session import Session

MIN_SAMPLES = 100
MAX_PLAUSIBLE_RATE_RAD_S = 40.0  # ~2300 deg/s, beyond any MEMS gyro full scale

TIME_COLUMN = "t"
GYRO_COLUMNS = ("gx", "gy", "gz")
MAG_COLUMNS = ("mx", "my", "mz")
ACC_COLUMNS = ("ax", "ay", "az")
QUAT_COLUMNS = ("qw", "qx", "qy", "qz")
REQUIRED_COLUMNS = (TIME_COLUMN, *GYRO_COLUMNS, *MAG_COLUMNS)
SENSOR_GROUPS = {"gyro": GYRO_COLUMNS, "magnetometer": MAG_COLUMNS, "accelerometer": ACC_COLUMNS}

PARQUET_SUFFIXES = (".parquet", ".pq")
PARQUET_MAGIC = b"PAR1"

GYRO_UNIT_ALIASES = {
    "rad/s": "rad/s", "rad/sec": "rad/s", "rads": "rad/s", "rad_s": "rad/s",
    "rps": "rad/s", "radian/s": "rad/s", "radians/s": "rad/s",
    "deg/s": "deg/s", "deg/sec": "deg/s", "degs": "deg/s", "deg_s": "deg/s",
    "dps": "deg/s", "degree/s": "deg/s", "degrees/s": "deg/s", "°/s": "deg/s",
}
DEFAULT_GYRO_UNIT = "rad/s"
DEFAULT_MAG_UNIT = "unknown"


def _pd():
    """pandas, imported when first needed: a numeric Parquet session never needs it (0.35 s saved)."""
    import pandas

    return pandas


class ColumnTable:
    """A table of float64 numpy columns (a numeric Parquet file), with the traits the checks use."""

    def __init__(self, columns: dict[str, np.ndarray]):
        self._columns = columns

    @property
    def columns(self) -> list[str]:
        return list(self._columns)

    def __getitem__(self, name: str) -> np.ndarray:
        return self._columns[name]

    def __len__(self) -> int:
        return len(next(iter(self._columns.values()))) if self._columns else 0


# --------------------------------------------------------------------------- loading


def load_session(path, gyro_unit: str | None = None, mag_unit: str | None = None) -> Session:
    """Read and validate a session file; gyro converted to rad/s.

    Unit precedence: argument (CLI flag) > Parquet key-value metadata > default
    ("rad/s" for the gyro, "unknown" for the magnetometer).
    """
    path = Path(path)
    table, metadata = _read_table(path)
    try:
        return session_from_table(table, metadata, str(path), gyro_unit, mag_unit)
    except InputError as exc:
        raise InputError(f"{path}: {exc}") from None


def session_from_table(table, metadata: dict, source: str,
                        gyro_unit: str | None, mag_unit: str | None) -> Session:
    """Validate the table's content and split it into per-sensor time bases."""
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
    gyro_rad_s = gyro * _gyro_scale_to_rad_s(gyro_unit)
    _check_gyro_rate_plausible(gyro_rad_s, gyro_unit)

    t_acc_s, acc_m_s2 = _optional_group(t_s, values, ACC_COLUMNS)
    t_quat_s, quat_wxyz = _optional_group(t_s, values, QUAT_COLUMNS)
    return Session(
        t_gyro_s=t_gyro_s, gyro_rad_s=gyro_rad_s, t_mag_s=t_mag_s, mag=mag,
        mag_unit=str(mag_unit), t_acc_s=t_acc_s, acc_m_s2=acc_m_s2,
        t_quat_s=t_quat_s, quat_wxyz=quat_wxyz, source=source, metadata=metadata,
    )


def _read_table(path: Path) -> tuple:
    """The file as a table (ColumnTable or DataFrame) plus its key-value metadata (empty for CSV)."""
    check_file_exists(path)
    try:
        if _is_parquet(path):
            table, metadata = _read_parquet(path)
        else:
            table, metadata = _read_csv(path), {}
    except OSError as exc:
        raise InputError(f"{path}: cannot be read ({exc.strerror or one_line(exc)})") from None
    if len(table) == 0:
        raise InputError(f"{path}: the file has no data rows; a session needs at least "
                         f"{MIN_SAMPLES} gyro and {MIN_SAMPLES} magnetometer samples")
    return table, metadata


def check_file_exists(path: Path) -> None:
    if not path.exists():
        raise InputError(f"{path}: no such file; check the path")
    if not path.is_file():
        raise InputError(f"{path}: not a regular file; pass a Parquet or CSV session file")
    if path.stat().st_size == 0:
        raise InputError(f"{path}: the file is empty (0 bytes)")


def _is_parquet(path: Path) -> bool:
    if path.suffix.lower() in PARQUET_SUFFIXES:
        return True
    with open(path, "rb") as f:
        return f.read(len(PARQUET_MAGIC)) == PARQUET_MAGIC


def _read_parquet(path: Path) -> tuple:
    try:
        arrow_table = pq.ParquetFile(path).read()  # not read_table: its dataset layer imports pandas
        table = _numeric_columns(arrow_table)
        if table is None:  # some column is not numeric: pandas gives the precise message
            table = arrow_table.to_pandas()
            table.columns = [str(c).strip() for c in table.columns]
    except Exception as exc:  # pyarrow raises many types for corrupt files
        raise InputError(f"{path}: cannot be read as Parquet ({one_line(exc)}); "
                         f"the file is corrupt or not a Parquet file") from None
    return table, _user_metadata(arrow_table.schema.metadata)


def _numeric_columns(arrow_table: pa.Table) -> ColumnTable | None:
    """Every column as float64 (nulls as NaN), or None when a column is not an int or float column."""
    columns = {}
    for name, column in zip(arrow_table.column_names, arrow_table.columns):
        if not (pa.types.is_floating(column.type) or pa.types.is_integer(column.type)):
            return None
        columns[str(name).strip()] = _float64_values(column.combine_chunks())
    return ColumnTable(columns)


def _float64_values(array: pa.Array) -> np.ndarray:
    """An int or float Arrow array as float64 numpy, nulls as NaN, straight from its buffers.

    (Array.to_numpy with nulls, ChunkedArray.to_numpy and fill_null import
    pandas, 0.3 s; Array.cast imports pyarrow.compute, 0.09 s.)
    """
    n, offset = len(array), array.offset
    validity, data = array.buffers()[:2]
    dtype = np.dtype(f"{'f' if pa.types.is_floating(array.type) else 'i' if pa.types.is_signed_integer(array.type) else 'u'}"
                     f"{array.type.bit_width // 8}")
    values = np.frombuffer(data, dtype=dtype, count=offset + n)[offset:].astype(np.float64)
    if array.null_count:
        bits = np.unpackbits(np.frombuffer(validity, dtype=np.uint8), bitorder="little")[offset: offset + n]
        values[bits == 0] = np.nan
    return values


def _user_metadata(raw: dict | None) -> dict:
    """Parquet key-value metadata as str -> str, without pandas/arrow internals."""
    metadata = {}
    for key, value in (raw or {}).items():
        key = key.decode("utf-8", "replace") if isinstance(key, bytes) else str(key)
        if key == "pandas" or key.startswith("ARROW:"):
            continue
        metadata[key] = value.decode("utf-8", "replace") if isinstance(value, bytes) else str(value)
    return metadata


def _read_csv(path: Path):
    with open(path, "rb") as f:
        if b"\x00" in f.read(8192):
            raise InputError(f"{path}: binary data, not a CSV text file; "
                             f"pass a CSV or a .parquet session file")
    pd = _pd()
    try:
        table = pd.read_csv(path, encoding="utf-8")
    except pd.errors.EmptyDataError:
        raise InputError(f"{path}: the file holds no header and no data rows") from None
    except Exception as exc:
        raise InputError(f"{path}: cannot be read as CSV ({one_line(exc)})") from None
    table.columns = [str(c).strip() for c in table.columns]
    return table


def one_line(exc: BaseException, limit: int | None = 200) -> str:
    """An exception's message on one line (cut to `limit` characters; None keeps it whole)."""
    text = " ".join(str(exc).split()) or type(exc).__name__
    return text if limit is None else text[:limit]


def _check_columns(table) -> None:
    """Every required column present; an optional group all or nothing."""
    found = list(table.columns)
    missing = [c for c in REQUIRED_COLUMNS if c not in found]
    for group in (ACC_COLUMNS, QUAT_COLUMNS):
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
    pd = _pd()
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
    pd = _pd()
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


def _gyro_unit(argument: str | None, metadata: dict) -> str:
    """The canonical gyro unit ("rad/s" or "deg/s") from argument > metadata > default."""
    if argument is not None:
        return canonical_gyro_unit(argument, "--gyro-unit")
    if "gyro_unit" in metadata:
        return canonical_gyro_unit(metadata["gyro_unit"], "the file's gyro_unit metadata")
    return DEFAULT_GYRO_UNIT


def canonical_gyro_unit(unit: str, origin: str) -> str:
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


# --------------------------------------------------------------------------- writing


def write_session(session: Session, path, truth_quat: bool = True, compression: str = "snappy",
                  compression_level: int | None = None) -> None:
    """Write `session` as one table (Parquet, or CSV by suffix), atomically."""
    path = Path(path)
    table = session_table(session, truth_quat=truth_quat)
    if path.suffix.lower() in PARQUET_SUFFIXES:
        metadata = {**session.metadata, "gyro_unit": "rad/s", "mag_unit": session.mag_unit}
        write_atomically(path, lambda tmp: _write_parquet(table, metadata, tmp, compression, compression_level))
    else:
        write_atomically(path, lambda tmp: table.to_csv(tmp, index=False))


def session_table(session: Session, truth_quat: bool = True):
    """The SPEC table: one row per distinct time over all sensors, NaN where not sampled."""
    groups = [(session.t_gyro_s, session.gyro_rad_s, GYRO_COLUMNS),
              (session.t_mag_s, session.mag, MAG_COLUMNS)]
    if session.t_acc_s is not None and session.acc_m_s2 is not None:
        groups.append((session.t_acc_s, session.acc_m_s2, ACC_COLUMNS))
    if truth_quat and session.t_quat_s is not None and session.quat_wxyz is not None:
        groups.append((session.t_quat_s, session.quat_wxyz, QUAT_COLUMNS))
    t_s = np.unique(np.concatenate([np.asarray(t, dtype=float) for t, _, _ in groups]))
    columns = {TIME_COLUMN: t_s}
    for t_group_s, samples, names in groups:
        columns.update(_spread_onto_times(t_s, t_group_s, samples, names))
    return _pd().DataFrame(columns)


def _spread_onto_times(t_s, t_group_s, samples, names) -> dict[str, np.ndarray]:
    """A sensor's columns on the union time base `t_s`, NaN where it has no sample."""
    rows = np.searchsorted(t_s, np.asarray(t_group_s, dtype=float))
    out = np.full((len(t_s), len(names)), np.nan)
    out[rows] = np.asarray(samples, dtype=float)
    return {name: out[:, k] for k, name in enumerate(names)}


def _write_parquet(table, metadata: dict, path: str, compression: str = "snappy",
                   compression_level: int | None = None) -> None:
    arrow_table = pa.Table.from_pandas(table, preserve_index=False)
    merged = {**(arrow_table.schema.metadata or {}),
              **{str(k).encode(): str(v).encode() for k, v in metadata.items()}}
    pq.write_table(arrow_table.replace_schema_metadata(merged), path, compression=compression,
                   compression_level=compression_level)


def write_text_atomically(path, text: str) -> None:
    """Write `text` (UTF-8) to `path` so that the file is either whole or absent."""
    def write(tmp: str) -> None:
        with open(tmp, "w", encoding="utf-8") as f:
            f.write(text)
    write_atomically(Path(path), write)


def write_atomically(path: Path, write: Callable[[str], None]) -> None:
    """Call `write(tmp)` on a temp file next to `path`, then rename it onto `path`.

    On any failure the temp file is removed and `path` is left as it was.
    """
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.", suffix=".tmp")
    os.close(fd)
    try:
        write(tmp)
        _fsync_file(tmp)
        os.chmod(tmp, 0o666 & ~_umask())
        os.replace(tmp, path)
    except BaseException:
        if os.path.exists(tmp):
            os.unlink(tmp)
        raise


def _fsync_file(path: str) -> None:
    with open(path, "rb+") as f:
        os.fsync(f.fileno())


def _umask() -> int:
    mask = os.umask(0)
    os.umask(mask)
    return mask
