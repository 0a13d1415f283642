"""Importing real recordings into a `Session`: BROAD trials and phone/logger CSV exports.

- `import_broad(path)` reads a trial of the BROAD benchmark (Laidig et al., Data 6(7):72,
  2021; CC BY 4.0): gyro (rad/s), accelerometer (m/s^2), magnetometer (uT) and the optical
  orientation (unit quaternion [w x y z], IMU frame to ENU) as truth, all on one time base
  t = k / sampling_rate. Rows where the optical markers were lost (NaN) are left out of the
  truth. `broad_movement_span(path)` gives the movement phase the benchmark marks.
- `import_csv(path, column_map, gyro_unit, mag_unit, ...)` reads a CSV with its own column
  names and units (time in s, ms, us or ns; gyro rad/s or deg/s; accelerometer m/s^2, g or
  mg) and maps it onto the SPEC columns.
- `trim(session, t0_s, t1_s)` and `decimate(session, n)` cut a session in time.
- `write_session_parquet(session, path, compression="zstd")` writes the SPEC table like
  `sessions.write_session`, with a chosen Parquet compression.

Whatever is imported goes through the same validation as `sessions.load_session` (strictly
increasing time, finite values, whole sensor groups, plausible gyro rates, enough samples),
so an imported session is exactly what loading its written file gives back.
"""
from __future__ import annotations

import csv
import json
import re
from dataclasses import replace
from pathlib import Path

import numpy as np
import pandas as pd

from magyro.io import sessions
from magyro.errors import InputError
from magyro.session import Session

# --------------------------------------------------------------------------- BROAD

BROAD_SUFFIXES_MAT = (".mat",)
BROAD_SUFFIXES_HDF5 = (".hdf5", ".h5")
BROAD_KEYS = ("imu_gyr", "imu_acc", "imu_mag", "opt_quat", "movement", "sampling_rate")
BROAD_CITATION = ('D. Laidig, M. Caruso, A. Cereatti, T. Seel, "BROAD - A Benchmark for Robust '
                  'Inertial Orientation Estimation", Data 6(7):72, 2021')
BROAD_LICENSE = f"CC BY 4.0 (https://creativecommons.org/licenses/by/4.0/); {BROAD_CITATION}"
BROAD_SOURCE = "BROAD benchmark, https://github.com/dlaidig/broad"


def import_broad(path) -> Session:
    """A BROAD trial (.mat, or .hdf5/.h5 with h5py installed) as a Session with optical truth.

    Time is t = k / sampling_rate (s) for sample k of the file. The metadata carries
    `source`, `trial`, `license`, `sampling_rate_hz`, `movement_span_s` and the units.
    """
    path = Path(path)
    arrays = _read_broad_arrays(path)
    rate_hz = arrays["sampling_rate"]
    n = len(arrays["imu_gyr"])
    t_s = np.arange(n) / rate_hz
    table = pd.DataFrame({sessions.TIME_COLUMN: t_s})
    for names, key in ((sessions.GYRO_COLUMNS, "imu_gyr"), (sessions.MAG_COLUMNS, "imu_mag"),
                       (sessions.ACC_COLUMNS, "imu_acc"), (sessions.QUAT_COLUMNS, "opt_quat")):
        if key in arrays:
            for k, name in enumerate(names):
                table[name] = arrays[key][:, k]
    if "opt_quat" in arrays:
        # a lost marker sometimes leaves a partial row: a truth sample is whole or absent
        q = table[list(sessions.QUAT_COLUMNS)].to_numpy()
        table.loc[~np.isfinite(q).all(axis=1), list(sessions.QUAT_COLUMNS)] = np.nan
    movement = arrays.get("movement")
    metadata = {
        "source": f"{BROAD_SOURCE}, file {path.name}",
        "trial": path.stem,
        "license": BROAD_LICENSE,
        "sampling_rate_hz": repr(float(rate_hz)),
        "gyro_unit": "rad/s",
        "mag_unit": "uT",
        "acc_unit": "m/s^2",
        "truth": "qw qx qy qz: optical orientation, unit quaternion, IMU frame to ENU (NaN where markers were lost)",
    }
    if movement is not None and movement.any():
        idx = np.flatnonzero(movement)
        metadata["movement_span_s"] = f"{float(t_s[idx[0]])!r} {float(t_s[idx[-1]])!r}"
    return session_from_table(table, metadata, str(path), gyro_unit="rad/s", mag_unit="uT")


def broad_movement_span(path) -> tuple[float, float]:
    """(t0, t1) in seconds of the first and last sample the trial marks as movement."""
    path = Path(path)
    arrays = _read_broad_arrays(path)
    movement = arrays.get("movement")
    if movement is None:
        raise InputError(f"{path}: no `movement` array; is this a BROAD trial file?")
    idx = np.flatnonzero(movement)
    if idx.size == 0:
        raise InputError(f"{path}: the `movement` mask marks no sample as movement")
    rate_hz = arrays["sampling_rate"]
    return float(idx[0] / rate_hz), float(idx[-1] / rate_hz)


def _read_broad_arrays(path: Path) -> dict:
    """The BROAD arrays as float (N, k) arrays, `movement` as bool (N,), rate as float."""
    if not path.exists():
        raise InputError(f"{path}: no such file; check the path")
    if not path.is_file():
        raise InputError(f"{path}: not a regular file; pass a BROAD trial (.mat or .hdf5)")
    suffix = path.suffix.lower()
    if suffix in BROAD_SUFFIXES_HDF5:
        raw = _read_hdf5(path)
    elif suffix in BROAD_SUFFIXES_MAT:
        raw = _read_mat(path)
    else:
        raise InputError(f"{path}: unknown file type {path.suffix!r}; a BROAD trial is a .mat "
                         f"(MATLAB) or .hdf5/.h5 file")
    missing = [k for k in ("imu_gyr", "imu_mag", "sampling_rate") if k not in raw]
    if missing:
        raise InputError(f"{path}: not a BROAD trial, missing {', '.join(missing)}; found keys: "
                         f"{', '.join(sorted(raw)) or '(none)'}")
    try:
        rate_hz = float(np.asarray(raw["sampling_rate"], dtype=float).reshape(-1)[0])
    except (TypeError, ValueError, IndexError):
        raise InputError(f"{path}: sampling_rate is not a number") from None
    if not np.isfinite(rate_hz) or rate_hz <= 0:
        raise InputError(f"{path}: sampling_rate is {rate_hz}; it must be a positive rate in Hz")
    out: dict = {"sampling_rate": rate_hz}
    n = None
    for key, width in (("imu_gyr", 3), ("imu_mag", 3), ("imu_acc", 3), ("opt_quat", 4)):
        if key not in raw:
            continue
        a = _as_columns(path, key, raw[key], width)
        if n is not None and len(a) != n:
            raise InputError(f"{path}: {key} has {len(a)} samples but imu_gyr has {n}; "
                             f"the arrays of a trial must have the same length")
        n = len(a) if n is None else n
        out[key] = a
    if "movement" in raw:
        m = np.asarray(raw["movement"]).reshape(-1)
        if len(m) != n:
            raise InputError(f"{path}: movement has {len(m)} samples but imu_gyr has {n}")
        out["movement"] = m.astype(bool)
    return out


def _as_columns(path: Path, key: str, a, width: int) -> np.ndarray:
    """An (N, width) float array; (width, N) as some HDF5 writers store it is transposed."""
    try:
        a = np.asarray(a, dtype=float)
    except (TypeError, ValueError):
        raise InputError(f"{path}: {key} does not hold numbers") from None
    if a.ndim == 2 and a.shape[1] != width and a.shape[0] == width:
        a = a.T
    if a.ndim != 2 or a.shape[1] != width:
        raise InputError(f"{path}: {key} has shape {a.shape}; expected N x {width}")
    return a


def _read_mat(path: Path) -> dict:
    import scipy.io

    try:
        raw = scipy.io.loadmat(str(path))
    except NotImplementedError:  # MATLAB v7.3 files are HDF5
        return _read_hdf5(path)
    except Exception as exc:
        raise InputError(f"{path}: cannot be read as a MATLAB file ({sessions.one_line(exc)})") from None
    return {k: v for k, v in raw.items() if not k.startswith("__")}


def _read_hdf5(path: Path) -> dict:
    try:
        import h5py
    except ImportError:
        raise InputError(f"{path}: reading HDF5 needs the h5py package; install it "
                         f"(pip install h5py) or use the trial's .mat file") from None
    try:
        with h5py.File(path, "r") as f:
            return {k: f[k][()] for k in f.keys() if isinstance(f[k], h5py.Dataset)}
    except OSError as exc:
        raise InputError(f"{path}: cannot be read as HDF5 ({sessions.one_line(exc)})") from None


def import_broad_movement(path, margin_s: float) -> Session:
    """A BROAD trial cut to its marked movement span +/- `margin_s` seconds of the rests."""
    t0_s, t1_s = broad_movement_span(path)
    return trim(import_broad(path), t0_s - margin_s, t1_s + margin_s)


def convert_broad(path, output, rest_s: float = 3.0, decimate_by: int = 1,
                  compression: str = "zstd", compression_level: int | None = 19) -> Session:
    """A BROAD trial cut to its movement span +/- `rest_s`, every `decimate_by`-th sample, written.

    This is how `data/broad-*.parquet` were made (see data/PROVENANCE.md).
    """
    session = import_broad_movement(path, rest_s)
    if decimate_by > 1:
        session = decimate(session, decimate_by)
    write_session_parquet(session, output, compression=compression, compression_level=compression_level)
    return session


# --------------------------------------------------------------------------- CSV

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
SPEC_OPTIONAL_GROUPS = (sessions.ACC_COLUMNS, sessions.QUAT_COLUMNS)
SPEC_NAMES = (*sessions.REQUIRED_COLUMNS, *sessions.ACC_COLUMNS, *sessions.QUAT_COLUMNS)
MIN_PLAUSIBLE_STEP_S = 1e-5   # 100 kHz
MAX_PLAUSIBLE_STEP_S = 1.0    # 1 Hz

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


def guess_column_map(columns) -> dict[str, str]:
    """SPEC name -> source column for headers spelled the usual ways (gyroX, Gyroscope x (rad/s), ...).

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
    """The SPEC names a header could mean."""
    text = re.sub(r"[\(\[\{].*?[\)\]\}]", "", column).lower()  # drop "(rad/s)", "[uT]"
    norm = re.sub(r"[^a-z0-9]", "", text)
    variants = {norm}
    for suffix in _UNIT_SUFFIXES:  # "gyro_x_rad_s" -> "gyroxrads" -> "gyrox"
        if norm.endswith(suffix) and len(norm) > len(suffix) + 1:
            variants.add(norm[: -len(suffix)])
    keys = set()
    for v in variants:
        if v in _TIME_NAMES:
            keys.add(sessions.TIME_COLUMN)
        if v in ("qw", "qx", "qy", "qz"):
            keys.add(v)
        if len(v) >= 2 and v[-1] in "xyz" and v[:-1] in _AXIS_PREFIXES["g"] + _AXIS_PREFIXES["m"] + _AXIS_PREFIXES["a"]:
            for sensor, prefixes in _AXIS_PREFIXES.items():
                if v[:-1] in prefixes:
                    keys.add(sensor + v[-1])
    return keys


def import_csv(path, column_map: dict | None, gyro_unit: str, mag_unit: str,
               time_unit: str = "s", acc_unit: str = "m/s^2", delimiter: str | None = None) -> Session:
    """A CSV export with its own column names and units, as a Session.

    `column_map` maps SPEC names (t gx gy gz mx my mz, optional ax ay az, qw qx qy qz) to the
    file's columns; names it leaves out are guessed from common spellings
    (`guess_column_map`), `None` guesses all. Times are taken relative to the first
    timestamp (epoch stamps in ns keep full precision) and converted to seconds; the gyro to
    rad/s; the accelerometer to m/s^2; the magnetometer keeps its unit (`mag_unit` is its
    label). Rows stamped with the same time (e.g. a gyro row and a magnetometer row) are
    merged; rows holding none of the mapped sensors are dropped; the rows are ordered by
    time. The delimiter (, ; tab |) is detected unless given.
    """
    path = Path(path)
    gyro_unit_c = _gyro_unit(path, gyro_unit)
    mag_unit_c = _mag_unit(path, mag_unit)
    time_scale = _unit_factor(path, time_unit, TIME_UNITS, "time")
    acc_scale = _unit_factor(path, acc_unit, ACC_UNITS, "accelerometer")
    raw = _read_csv_any_delimiter(path, delimiter)
    mapping = _resolve_column_map(path, raw, column_map)

    t_raw = _time_values(path, raw[mapping[sessions.TIME_COLUMN]], mapping[sessions.TIME_COLUMN])
    table = pd.DataFrame({sessions.TIME_COLUMN: t_raw})
    for name, source in mapping.items():
        if name != sessions.TIME_COLUMN:
            table[name] = _numbers(path, raw[source], source)
    for name in sessions.ACC_COLUMNS:
        if name in table:
            table[name] = table[name] * acc_scale
    table = _merge_rows(path, table)
    t_first = table[sessions.TIME_COLUMN].iloc[0]
    table[sessions.TIME_COLUMN] = (table[sessions.TIME_COLUMN] - t_first).astype(float) * time_scale
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
        return sessions.canonical_gyro_unit(unit, "--gyro-unit")
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


def _sniff_delimiter(path: Path) -> str:
    with open(path, "r", encoding="utf-8", errors="replace") as f:
        head = f.read(65536)
    try:
        return csv.Sniffer().sniff(head, delimiters=",;\t|").delimiter
    except csv.Error:
        first = head.splitlines()[0] if head else ""
        counts = {d: first.count(d) for d in ",;\t|"}
        best = max(counts, key=counts.get)
        return best if counts[best] > 0 else ","


def _read_csv_any_delimiter(path: Path, delimiter: str | None) -> pd.DataFrame:
    sessions.check_file_exists(path)
    with open(path, "rb") as f:
        if b"\x00" in f.read(8192):
            raise InputError(f"{path}: binary data, not a CSV text file")
    sep = delimiter if delimiter is not None else _sniff_delimiter(path)
    try:
        table = pd.read_csv(path, sep=sep, encoding="utf-8", comment=None, skipinitialspace=True)
    except pd.errors.EmptyDataError:
        raise InputError(f"{path}: the file holds no header and no data rows") from None
    except UnicodeDecodeError:
        raise InputError(f"{path}: not UTF-8 text; save the export as UTF-8 CSV") from None
    except Exception as exc:
        raise InputError(f"{path}: cannot be read as CSV ({sessions.one_line(exc)})") from None
    table.columns = [str(c).strip() for c in table.columns]
    if len(table) == 0:
        raise InputError(f"{path}: the file has a header but no data rows")
    return table


def _resolve_column_map(path: Path, raw: pd.DataFrame, column_map: dict | None) -> dict[str, str]:
    """SPEC name -> an existing column of `raw`; explicit entries first, then guesses."""
    column_map = dict(column_map or {})
    unknown = [k for k in column_map if k not in SPEC_NAMES]
    if unknown:
        raise InputError(f"{path}: unknown session column name(s) {', '.join(map(str, unknown))} in the "
                         f"column map; the names are {' '.join(SPEC_NAMES)}")
    found = list(raw.columns)
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
    for group in SPEC_OPTIONAL_GROUPS:  # an optional group all or nothing
        present = [c for c in group if c in mapping]
        if present and len(present) < len(group):
            explicit = [c for c in present if c in column_map]
            if explicit:
                raise InputError(f"{path}: the column map gives {', '.join(present)} but not "
                                 f"{', '.join(c for c in group if c not in mapping)}; map all of "
                                 f"{' '.join(group)} or none")
            for c in present:  # a partial guess is no guess
                del mapping[c]
    missing = [c for c in sessions.REQUIRED_COLUMNS if c not in mapping]
    if missing:
        raise InputError(f"{path}: no column for {', '.join(missing)}; found columns: {_shown(found)}. "
                         f"Map them, e.g. --map {missing[0]}=COLUMN (Python: column_map={{'{missing[0]}': 'COLUMN'}})")
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
                         f"number (rows numbered from 0, not counting the header)")
    return numeric.to_numpy(dtype=float, na_value=np.nan)


def _merge_rows(path: Path, table: pd.DataFrame) -> pd.DataFrame:
    """Rows ordered by time, one per time stamp; each sensor's own stamps strictly increasing."""
    groups = [g for g in (sessions.GYRO_COLUMNS, sessions.MAG_COLUMNS, *SPEC_OPTIONAL_GROUPS) if g[0] in table]
    t = table[sessions.TIME_COLUMN].to_numpy()
    any_sample = np.zeros(len(table), dtype=bool)
    for group in groups:
        values = table[list(group)].to_numpy()
        if group != sessions.QUAT_COLUMNS:  # a truth row may be partly NaN: it then counts as absent
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
    table = table.sort_values(sessions.TIME_COLUMN, kind="stable")
    if table[sessions.TIME_COLUMN].duplicated().any():
        table = table.groupby(sessions.TIME_COLUMN, sort=True, as_index=False).first()
    return table.reset_index(drop=True)


def _check_time_unit(path: Path, table: pd.DataFrame, time_unit: str) -> None:
    """The gyro's median sample interval must be between 10 us and 1 s."""
    g = table[list(sessions.GYRO_COLUMNS)].notna().all(axis=1).to_numpy()
    t_g = table[sessions.TIME_COLUMN].to_numpy()[g]
    if len(t_g) < 2:
        return
    step_s = float(np.median(np.diff(t_g)))
    if MIN_PLAUSIBLE_STEP_S <= step_s <= MAX_PLAUSIBLE_STEP_S:
        return
    better = [u for u, f in (("s", 1.0), ("ms", 1e-3), ("us", 1e-6), ("ns", 1e-9))
              if MIN_PLAUSIBLE_STEP_S <= step_s / TIME_UNITS[_canonical_key(time_unit)] * f <= MAX_PLAUSIBLE_STEP_S]
    raise InputError(f"{path}: with time unit {time_unit!r} the gyro samples are {step_s:.3g} s apart "
                     f"({1 / step_s:.3g} Hz), which cannot be right; "
                     f"{'pass time unit ' + ' or '.join(better) if better else 'check the time column'}")


# --------------------------------------------------------------------------- validation and cutting


def session_from_table(table: pd.DataFrame, metadata: dict, source: str,
                       gyro_unit: str | None = None, mag_unit: str | None = None) -> Session:
    """A SPEC table through the same checks as `sessions.load_session`; messages start with `source`."""
    try:
        return sessions.session_from_table(table, dict(metadata), source, gyro_unit, mag_unit)
    except InputError as exc:
        raise InputError(f"{source}: {exc}") from None


def trim(session: Session, t0_s: float, t1_s: float) -> Session:
    """The session cut to t0_s <= t <= t1_s: every sensor and the truth; times unchanged."""
    t0_s, t1_s = float(t0_s), float(t1_s)
    if not (np.isfinite(t0_s) and np.isfinite(t1_s)) or t1_s <= t0_s:
        raise InputError(f"trim window [{t0_s}, {t1_s}] s is empty; it needs t0 < t1")
    cut = session.within(t0_s, t1_s)
    for name, t_x in (("gyro", cut.t_gyro_s), ("magnetometer", cut.t_mag_s)):
        if len(t_x) < sessions.MIN_SAMPLES:
            raise InputError(f"trim window [{t0_s:g}, {t1_s:g}] s keeps {len(t_x)} {name} samples, need at least "
                             f"{sessions.MIN_SAMPLES}; the session spans {session.t_gyro_s[0]:g} to "
                             f"{session.t_gyro_s[-1]:g} s")
    return replace(cut, metadata={**session.metadata, "trimmed_to_s": f"{t0_s!r} {t1_s!r}"})


def decimate(session: Session, n: int) -> Session:
    """Every n-th row of the session's table (first row kept), no filtering.

    On a common time base (BROAD) this keeps every n-th sample of every sensor and of the
    truth; samples are original values, not averages.
    """
    n = int(n)
    if n < 1:
        raise InputError(f"decimation factor {n}; it must be a positive integer")
    if n == 1:
        return session
    table = sessions.session_table(session).iloc[::n].reset_index(drop=True)
    metadata = {**session.metadata, "decimated_by": str(n)}
    if "sampling_rate_hz" in metadata:
        metadata["sampling_rate_hz"] = repr(float(metadata["sampling_rate_hz"]) / n)
    return session_from_table(table, metadata, session.source, gyro_unit="rad/s", mag_unit=session.mag_unit)


def write_session_parquet(session: Session, path, compression: str = "zstd",
                          compression_level: int | None = None) -> None:
    """`sessions.write_session` to Parquet with a chosen compression (zstd by default, for shipped data)."""
    sessions.write_session(session, path, compression=compression, compression_level=compression_level)
