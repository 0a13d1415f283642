"""Importing trials of the BROAD benchmark (Laidig et al., Data 6(7):72, 2021; CC BY 4.0).

A trial holds gyro (rad/s), accelerometer (m/s^2), magnetometer (uT) and the optical
orientation (unit quaternion [w x y z], IMU frame to ENU) as truth, all on one time base
t = k / sampling_rate. Rows where the optical markers were lost (NaN) are left out of the
truth. `broad_movement_span(path)` gives the movement phase the benchmark marks;
`convert_broad` is `magyro import broad`: a trial, cut, decimated, written.

An imported trial goes through the same checks as a loaded session file
(`magyro.io.checks`), so it is exactly what loading its written file gives back.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd

from magyro.errors import InputError, one_line
from magyro.io.checks import session_from_table
from magyro.io.columns import ACC_COLUMNS, GYRO_COLUMNS, MAG_COLUMNS, QUAT_COLUMNS, TIME_COLUMN
from magyro.io.cutting import cut, decimate, trim
from magyro.io.session_file import import_to_file
from magyro.session import Session

BROAD_SUFFIXES_MAT = (".mat",)
BROAD_SUFFIXES_HDF5 = (".hdf5", ".h5")
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
    table = pd.DataFrame({TIME_COLUMN: t_s})
    for names, key in ((GYRO_COLUMNS, "imu_gyr"), (MAG_COLUMNS, "imu_mag"),
                       (ACC_COLUMNS, "imu_acc"), (QUAT_COLUMNS, "opt_quat")):
        if key in arrays:
            for k, name in enumerate(names):
                table[name] = arrays[key][:, k]
    if "opt_quat" in arrays:
        # a lost marker sometimes leaves a partial row: a truth sample is whole or absent
        q = table[list(QUAT_COLUMNS)].to_numpy()
        table.loc[~np.isfinite(q).all(axis=1), list(QUAT_COLUMNS)] = np.nan
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


def import_broad_movement(path, margin_s: float) -> Session:
    """A BROAD trial cut to its marked movement span +/- `margin_s` seconds of the rests."""
    t0_s, t1_s = broad_movement_span(path)
    return trim(import_broad(path), t0_s - margin_s, t1_s + margin_s)


def convert_broad(path, output, *, movement: bool = False, rest_s: float = 3.0,
                  start_s: float | None = None, end_s: float | None = None, decimate_by: int = 1,
                  compression_level: int | None = None) -> Session:
    """`magyro import broad`: a BROAD trial, cut, decimated, written to `output` (`write_imported`).

    `movement` keeps the marked movement span +/- `rest_s`; then `start_s`/`end_s` cut
    (`cut`); then every `decimate_by`-th sample is kept. The shipped data/broad-*.parquet
    are `convert_broad(trial, output, movement=True, compression_level=19)`
    (data/PROVENANCE.md). Returns the written session. An `output` that is the trial
    file or cannot be written is refused before the trial is read.
    """
    def read() -> Session:
        session = import_broad_movement(path, rest_s) if movement else import_broad(path)
        return decimate(cut(session, start_s, end_s), decimate_by)

    return import_to_file([path], output, read, compression_level)


# --------------------------------------------------------------------------- reading the file


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
        raise InputError(f"{path}: cannot be read as a MATLAB file ({one_line(exc)})") from None
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
        raise InputError(f"{path}: cannot be read as HDF5 ({one_line(exc)})") from None
