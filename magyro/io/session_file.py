"""Reading and writing session files (docs/spec.md section 2).

A session file is one table, Parquet or CSV, one row per timestamp, in the layout of
`magyro.io.columns`. Sensors sampled at different instants share the table; a row leaves
NaN the sensors with no sample at that instant. Each sensor gets its own time base in
the loaded `Session`.

Loading runs every check of `magyro.io.checks`; every message starts with the file's
path. Input files are only read, never written. Outputs are written atomically
(`magyro.io.atomic`). A numeric Parquet file is read straight from its Arrow buffers,
without pandas (0.35 s saved on every solve).
"""
from __future__ import annotations

from pathlib import Path
from typing import Callable

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq

from magyro.errors import InputError, one_line
from magyro.io.atomic import write_atomically
from magyro.io.checks import MIN_SAMPLES, check_file_exists, session_from_table
from magyro.io.columns import (ACC_COLUMNS, GYRO_COLUMNS, MAG_COLUMNS, QUAT_COLUMNS, TIME_COLUMN,
                               ColumnTable)
from magyro.session import Session

PARQUET_SUFFIXES = (".parquet", ".pq")
PARQUET_MAGIC = b"PAR1"


# --------------------------------------------------------------------------- loading


def load_session(path, gyro_unit: str | None = None, mag_unit: str | None = None) -> Session:
    """Read and validate a session file; gyro converted to rad/s.

    Unit precedence: argument (CLI flag) > Parquet key-value metadata > default
    ("rad/s" for the gyro, "unknown" for the magnetometer).
    """
    path = Path(path)
    table, metadata = _read_table(path)
    check_unit_label(path, mag_unit if mag_unit is not None else metadata.get("mag_unit", ""))
    return session_from_table(table, metadata, str(path), gyro_unit, mag_unit)


def check_unit_label(path, unit) -> None:
    """InputError when the magnetometer's unit label (printed in tables, written into exports) holds control or
    bidi characters or is too long to be a unit: it would act on a terminal or in a C comment."""
    from magyro.text import escaped, unsafe_characters

    unit = str(unit)
    bad = unsafe_characters(unit)
    if bad or len(unit) > 40:
        why = f"it holds control or bidi characters ({', '.join(bad)})" if bad else "longer than 40 characters"
        raise InputError(f"{path}: the magnetometer unit '{escaped(unit[:40])}' is not a unit: {why}")


def _read_table(path: Path) -> tuple:
    """The file as a table (ColumnTable or DataFrame) plus its key-value metadata (empty for CSV)."""
    check_file_exists(path)
    check_file_readable(path)
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


def check_file_readable(path: Path) -> None:
    """InputError naming the file when this user may not read it (before a reader calls it corrupt)."""
    try:
        with open(path, "rb"):
            pass
    except PermissionError:
        raise InputError(f"{path}: cannot be read: permission denied (unreadable input)") from None


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
        head = f.read(8192)
    if b"\x00" in head:
        raise InputError(f"{path}: binary data, not a CSV text file; "
                         f"pass a CSV or a .parquet session file")
    if head.lstrip().startswith(b"{"):   # a JSON file given where a session goes: say what it is
        import re

        found = re.search(rb'"schema"\s*:\s*"(magyro\.[a-z-]+)/', head)
        what = f"a magyro JSON file ({found.group(1).decode()})" if found else "a JSON file"
        raise InputError(f"{path}: this is {what}, not a session; pass a Parquet or CSV session file "
                         "(apply, validate and report take SESSION then CALIB)")
    import pandas as pd

    try:
        table = pd.read_csv(path, encoding="utf-8")
    except pd.errors.EmptyDataError:
        raise InputError(f"{path}: the file holds no header and no data rows") from None
    except Exception as exc:
        raise InputError(f"{path}: cannot be read as CSV ({one_line(exc)})") from None
    table.columns = [str(c).strip() for c in table.columns]
    return table


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


def write_imported(session: Session, path, compression_level: int | None = None) -> None:
    """`write_session` for imported recordings: Parquet with zstd (metadata kept), or CSV by suffix.

    zstd makes the smallest files (the shipped data/broad-*.parquet use level 19);
    `compression_level` None is pyarrow's default level.
    """
    from magyro.progress import step

    step(f"writing {Path(path).name}")
    write_session(session, path, compression="zstd", compression_level=compression_level)


def import_to_file(sources, output, read: Callable[[], Session], compression_level: int | None = None) -> Session:
    """What every `magyro import` does: an `output` that is a source or cannot be written refused before anything
    is read, the recording read by `read()`, the session written whole (`write_imported`). Returns it."""
    from magyro.io.atomic import check_outputs
    from magyro.progress import step

    sources = [Path(s) for s in sources]
    check_outputs(sources, [output])
    step("reading " + ", ".join(s.name for s in sources))
    session = read()
    write_imported(session, output, compression_level=compression_level)
    return session


def session_table(session: Session, truth_quat: bool = True):
    """The session table (docs/spec.md section 2) (a DataFrame): one row per distinct time over all sensors, NaN where not sampled."""
    groups = [(session.t_gyro_s, session.gyro_rad_s, GYRO_COLUMNS),
              (session.t_mag_s, session.mag, MAG_COLUMNS)]
    if session.t_acc_s is not None and session.acc_m_s2 is not None:
        groups.append((session.t_acc_s, session.acc_m_s2, ACC_COLUMNS))
    if truth_quat and session.t_quat_s is not None and session.quat_wxyz is not None:
        groups.append((session.t_quat_s, session.quat_wxyz, QUAT_COLUMNS))
    return table_of_groups(groups)


def table_of_groups(groups):
    """A session table (DataFrame) from (times, samples, column names) per sensor: one row per distinct time over
    all of them, NaN where a sensor has no sample (the writer's and the importers' one layout)."""
    import pandas as pd

    t_s = np.unique(np.concatenate([np.asarray(t, dtype=float) for t, _, _ in groups]))
    columns = {TIME_COLUMN: t_s}
    for t_group_s, samples, names in groups:
        columns.update(_spread_onto_times(t_s, t_group_s, samples, names))
    return pd.DataFrame(columns)


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
