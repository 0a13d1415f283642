"""Tests for the importers of magyro.io (BROAD trials, CSV exports), the shipped real sessions,
trim/cut/decimate, and the `magyro import broad|csv` commands."""
from __future__ import annotations

import dataclasses
import importlib.util
import json
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from magyro.errors import InputError
from magyro.io import (BROAD_CITATION, MIN_SAMPLES, broad_movement_span, convert_broad, cut, decimate,
                       guess_column_map, import_broad, import_broad_movement, import_csv, load_session,
                       parse_column_map, trim, write_imported, write_session)
from magyro.session import Session
from magyro.studies.scenario import load_problem
from magyro.studies.simulate import simulate

REPO = Path(__file__).resolve().parents[1]
DATA = REPO / "data"
BROAD_DIR = Path(__file__).resolve().parents[2] / "shared" / "data" / "broad"
BROAD_02 = BROAD_DIR / "02_undisturbed_slow_rotation_B.mat"
BROAD_RATE_HZ = 2000.0 / 7.0  # 285.714 Hz

needs_broad = pytest.mark.skipif(not BROAD_02.is_file(), reason=f"BROAD trials not found at {BROAD_DIR}")


def with_truth(session: Session) -> Session:
    """A synthetic truth quaternion on the gyro times (a slow yaw), for the trim tests."""
    t = session.t_gyro_s
    half = 0.05 * t
    q = np.column_stack([np.cos(half), 0 * t, 0 * t, np.sin(half)])
    return dataclasses.replace(session, t_quat_s=t.copy(), quat_wxyz=q,
                               t_acc_s=t.copy(), acc_m_s2=np.tile([0.0, 0.0, 9.81], (len(t), 1)))


@pytest.fixture(scope="module")
def phone_session() -> Session:
    session, _ = simulate(load_problem("phone-module"), 1)
    return with_truth(session)


# --------------------------------------------------------------------------- BROAD (source files)


@pytest.mark.broad
@needs_broad
def test_import_broad_reads_a_real_trial():
    s = import_broad(BROAD_02)
    assert s.gyro_rate_hz == pytest.approx(BROAD_RATE_HZ, rel=1e-9)
    assert s.t_gyro_s[0] == 0.0 and s.t_gyro_s[1] == pytest.approx(1 / BROAD_RATE_HZ)
    assert len(s.t_gyro_s) == len(s.t_mag_s) == len(s.t_acc_s) == 53240
    assert s.mag_unit == "uT"
    assert 30 < np.median(np.linalg.norm(s.mag, axis=1)) < 70            # the earth's field, in uT
    assert np.median(np.linalg.norm(s.acc_m_s2, axis=1)) == pytest.approx(9.81, abs=0.3)
    # truth: the rows where the markers were lost are dropped, the rest are unit quaternions
    assert s.t_quat_s is not None and 0.9 * 53240 < len(s.t_quat_s) < 53240
    assert np.isfinite(s.quat_wxyz).all()
    assert np.allclose(np.linalg.norm(s.quat_wxyz, axis=1), 1.0, atol=1e-6)
    assert np.isin(s.t_quat_s, s.t_gyro_s).all()
    assert "CC BY 4.0" in s.metadata["license"] and "Laidig" in s.metadata["license"]
    assert s.metadata["trial"] == "02_undisturbed_slow_rotation_B"
    t0, t1 = broad_movement_span(BROAD_02)
    assert (t0, t1) == pytest.approx((40.07, 153.05), abs=0.01)
    assert s.metadata["movement_span_s"] == f"{t0!r} {t1!r}"


@pytest.mark.broad
@needs_broad
def test_converted_broad_trial_round_trips_through_the_session_file(tmp_path):
    out = tmp_path / "broad.parquet"
    s = convert_broad(BROAD_02, out, movement=True, rest_s=1.0, decimate_by=4)
    loaded = load_session(out)
    t0, t1 = broad_movement_span(BROAD_02)
    assert loaded.t_gyro_s[0] >= t0 - 1.0 - 1e-9 and loaded.t_gyro_s[-1] <= t1 + 1.0 + 1e-9
    assert loaded.gyro_rate_hz == pytest.approx(BROAD_RATE_HZ / 4, rel=1e-6)
    np.testing.assert_array_equal(loaded.gyro_rad_s, s.gyro_rad_s)
    np.testing.assert_array_equal(loaded.quat_wxyz, s.quat_wxyz)
    assert loaded.metadata["license"] == s.metadata["license"]
    assert loaded.metadata["decimated_by"] == "4"


def test_import_broad_rejects_what_is_not_a_trial(tmp_path):
    with pytest.raises(InputError, match="no such file"):
        import_broad(tmp_path / "missing.mat")
    other = tmp_path / "trial.txt"
    other.write_text("x")
    with pytest.raises(InputError, match=r"\.mat"):
        import_broad(other)
    h5 = tmp_path / "trial.hdf5"
    h5.write_bytes(b"not an hdf5 file")
    has_h5py = importlib.util.find_spec("h5py") is not None
    with pytest.raises(InputError, match="cannot be read as HDF5" if has_h5py else "needs the h5py package"):
        import_broad(h5)
    import scipy.io
    mat = tmp_path / "not_broad.mat"
    scipy.io.savemat(mat, {"something": np.zeros((3, 3))})
    with pytest.raises(InputError, match="not a BROAD trial.*imu_gyr"):
        import_broad(mat)


def test_import_broad_on_a_small_synthetic_mat(tmp_path):
    """The .mat layout of BROAD, NaN truth rows and a partial truth row dropped, movement span."""
    import scipy.io
    n, rate = 600, 100.0
    t = np.arange(n) / rate
    gyr = np.column_stack([0.2 * np.sin(t), 0.1 * np.cos(t), 0.05 + 0 * t])
    mag = np.column_stack([30 * np.cos(t), 30 * np.sin(t), -20 + 0 * t])
    quat = np.tile([1.0, 0.0, 0.0, 0.0], (n, 1))
    quat[:50] = np.nan
    quat[100, 2] = np.nan
    movement = ((t > 1.0) & (t < 5.0)).astype(np.uint8)[:, None]
    path = tmp_path / "99_synthetic.mat"
    scipy.io.savemat(path, {"imu_gyr": gyr, "imu_acc": np.tile([0, 0, 9.81], (n, 1)), "imu_mag": mag,
                            "opt_quat": quat, "movement": movement, "sampling_rate": np.array([[rate]])})
    s = import_broad(path)
    assert len(s.t_quat_s) == n - 51
    assert s.t_quat_s[0] == pytest.approx(0.5)
    np.testing.assert_allclose(s.gyro_rad_s, gyr)
    assert broad_movement_span(path) == pytest.approx((1.01, 4.99))


# --------------------------------------------------------------------------- the shipped real sessions


@pytest.mark.parametrize("name, trial", [("broad-02", "02_undisturbed_slow_rotation_B"),
                                         ("broad-07", "07_undisturbed_fast_rotation_B")])
def test_shipped_broad_session_loads_with_truth(name, trial):
    path = DATA / f"{name}.parquet"
    assert path.stat().st_size < 2.6e6
    s = load_session(path)
    assert s.gyro_rate_hz == pytest.approx(BROAD_RATE_HZ, rel=1e-3)
    assert s.mag_rate_hz == pytest.approx(BROAD_RATE_HZ, rel=1e-3)
    assert s.mag_unit == "uT"
    assert 100 < s.duration_s < 140
    assert s.t_quat_s is not None and len(s.t_quat_s) > 0.9 * len(s.t_gyro_s)
    assert np.allclose(np.linalg.norm(s.quat_wxyz, axis=1), 1.0, atol=1e-6)
    assert s.t_acc_s is not None
    assert s.metadata["trial"] == trial
    assert "CC BY 4.0" in s.metadata["license"] and "Laidig" in s.metadata["license"]
    # ~3 s of rest kept at each end, before and after the marked movement
    t0, t1 = (float(x) for x in s.metadata["movement_span_s"].split())
    assert t0 - s.t_gyro_s[0] == pytest.approx(3.0, abs=0.01)
    assert s.t_gyro_s[-1] - t1 == pytest.approx(3.0, abs=0.01)
    for rest in (s.t_gyro_s < s.t_gyro_s[0] + 2.5, s.t_gyro_s > s.t_gyro_s[-1] - 2.5):
        assert np.rad2deg(np.linalg.norm(s.gyro_rad_s[rest], axis=1)).max() < 3.0   # still, up to bias and noise
    moving = (s.t_gyro_s > t0 + 5) & (s.t_gyro_s < t1 - 5)
    assert np.rad2deg(np.linalg.norm(s.gyro_rad_s[moving], axis=1)).max() > 50.0


def test_provenance_and_license_files_credit_broad():
    provenance = (DATA / "PROVENANCE.md").read_text(encoding="utf-8")
    license_text = (DATA / "LICENSE-BROAD.md").read_text(encoding="utf-8")
    for text in (provenance, license_text):
        assert "CC BY 4.0" in text and "Laidig" in text and "Data 6(7):72" in text
    assert "simulated-phone-module" in provenance
    assert "Attribution 4.0 International" in license_text


# --------------------------------------------------------------------------- trim and decimate


def test_trim_cuts_every_sensor_and_the_truth(phone_session):
    before = {f.name: np.copy(getattr(phone_session, f.name)) for f in dataclasses.fields(phone_session)
              if isinstance(getattr(phone_session, f.name), np.ndarray)}
    s = trim(phone_session, 10.0, 20.0)
    for t in (s.t_gyro_s, s.t_mag_s, s.t_acc_s, s.t_quat_s):
        assert t[0] >= 10.0 and t[-1] <= 20.0
    assert len(s.t_gyro_s) == 2001 and len(s.t_mag_s) == 501
    assert len(s.gyro_rad_s) == len(s.t_gyro_s) and len(s.quat_wxyz) == len(s.t_quat_s)
    keep = (phone_session.t_gyro_s >= 10.0) & (phone_session.t_gyro_s <= 20.0)
    np.testing.assert_array_equal(s.gyro_rad_s, phone_session.gyro_rad_s[keep])
    assert s.metadata["trimmed_to_s"] == "10.0 20.0"
    assert "trimmed_to_s" not in phone_session.metadata  # the input is untouched
    for name, array in before.items():
        np.testing.assert_array_equal(getattr(phone_session, name), array, err_msg=name)


def test_trim_refuses_an_empty_or_too_short_window(phone_session):
    with pytest.raises(InputError, match="t0 < t1"):
        trim(phone_session, 5.0, 5.0)
    with pytest.raises(InputError, match="magnetometer samples"):
        trim(phone_session, 10.0, 11.0)  # 51 magnetometer samples < MIN_SAMPLES
    with pytest.raises(InputError, match="keeps 0 gyro samples"):
        trim(phone_session, 100.0, 200.0)


def test_trim_without_truth_keeps_none(phone_session):
    bare = dataclasses.replace(phone_session, t_quat_s=None, quat_wxyz=None, t_acc_s=None, acc_m_s2=None)
    s = trim(bare, 0.0, 30.0)
    assert s.t_quat_s is None and s.t_acc_s is None


def test_cut_with_open_ends(phone_session):
    assert cut(phone_session, None, None) is phone_session
    start_only = cut(phone_session, 50.0, None)
    assert start_only.t_gyro_s[0] == 50.0 and start_only.t_gyro_s[-1] == phone_session.t_gyro_s[-1]
    assert start_only.metadata["trimmed_to_s"] == "50.0 60.0"
    end_only = cut(phone_session, None, 10.0)
    assert end_only.t_gyro_s[0] == phone_session.t_gyro_s[0] and end_only.t_gyro_s[-1] == 10.0
    assert len(end_only.t_gyro_s) == 2001
    with pytest.raises(InputError, match=r"trim window \[59.9, 60\] s keeps 21 gyro samples"):
        cut(phone_session, 59.9, None)


def test_decimate_keeps_every_nth_row(phone_session):
    s = decimate(phone_session, 2)
    # gyro at 200 Hz, magnetometer at 50 Hz on every 4th gyro instant: every 2nd row keeps all of those
    np.testing.assert_array_equal(s.t_gyro_s, phone_session.t_gyro_s[::2])
    np.testing.assert_array_equal(s.gyro_rad_s, phone_session.gyro_rad_s[::2])
    np.testing.assert_array_equal(s.t_mag_s, phone_session.t_mag_s)
    assert s.metadata["decimated_by"] == "2"
    assert decimate(phone_session, 1) is phone_session
    with pytest.raises(InputError):
        decimate(phone_session, 0)


def test_write_imported_uses_zstd_and_round_trips(tmp_path, phone_session):
    import pyarrow.parquet as pq
    path = tmp_path / "s.parquet"
    write_imported(phone_session, path)
    assert pq.ParquetFile(path).metadata.row_group(0).column(0).compression == "ZSTD"
    loaded = load_session(path)
    np.testing.assert_array_equal(loaded.gyro_rad_s, phone_session.gyro_rad_s)
    np.testing.assert_array_equal(loaded.quat_wxyz, phone_session.quat_wxyz)
    assert loaded.metadata["gyro_unit"] == "rad/s"
    assert not [p for p in tmp_path.iterdir() if p.name.endswith(".tmp")]
    smaller = tmp_path / "s19.parquet"
    write_imported(phone_session, smaller, compression_level=19)
    assert smaller.stat().st_size < path.stat().st_size
    np.testing.assert_array_equal(load_session(smaller).gyro_rad_s, phone_session.gyro_rad_s)
    as_csv = tmp_path / "s.csv"
    write_imported(phone_session, as_csv)
    assert as_csv.read_text().startswith("t,gx,gy,gz,mx,my,mz,ax,ay,az,qw,qx,qy,qz\n")
    np.testing.assert_array_equal(load_session(as_csv).gyro_rad_s, phone_session.gyro_rad_s)


# --------------------------------------------------------------------------- CSV exports


def phone_csv(path: Path, sep: str = ",", headers=None, epoch_ms: int = 1_700_000_000_000,
              duration_s: float = 4.0) -> dict:
    """A phone-logger style CSV: ms epoch stamps, gyro (deg/s) rows at 200 Hz and magnetometer
    rows at 50 Hz stamped 1 ms after a gyro sample, plus one magnetometer row on its own line
    at the same ms as a gyro row. Returns the clean arrays."""
    headers = headers or {"t": "timestamp", "gx": "gyroX", "gy": "gyroY", "gz": "gyroZ",
                          "mx": "magX", "my": "magY", "mz": "magZ"}
    n_g = int(duration_s * 200)
    t_g_ms = np.arange(n_g) * 5
    gyro_deg_s = np.column_stack([300 * np.sin(t_g_ms / 300), 10 * np.cos(t_g_ms / 500), 5 + 0 * t_g_ms])
    t_m_ms = np.arange(0, n_g * 5, 20) + 1
    t_m_ms[3] = t_g_ms[12]  # this magnetometer sample shares its stamp with a gyro row
    mag_ut = np.column_stack([30 * np.cos(t_m_ms / 700), 30 * np.sin(t_m_ms / 700), -20 + 0 * t_m_ms])
    rows = [{headers["t"]: epoch_ms + int(t), headers["gx"]: g[0], headers["gy"]: g[1], headers["gz"]: g[2]}
            for t, g in zip(t_g_ms, gyro_deg_s)]
    rows += [{headers["t"]: epoch_ms + int(t), headers["mx"]: m[0], headers["my"]: m[1], headers["mz"]: m[2]}
             for t, m in zip(t_m_ms, mag_ut)]
    table = pd.DataFrame(rows, columns=[headers[k] for k in ("t", "gx", "gy", "gz", "mx", "my", "mz")])
    table = table.sort_values(headers["t"], kind="stable")
    table.to_csv(path, index=False, sep=sep)
    return {"t_g_s": t_g_ms / 1000.0, "gyro_deg_s": gyro_deg_s, "t_m_s": np.sort(t_m_ms) / 1000.0,
            "mag": mag_ut[np.argsort(t_m_ms, kind="stable")]}


COLUMN_MAP = {"t": "timestamp", "gx": "gyroX", "gy": "gyroY", "gz": "gyroZ", "mx": "magX", "my": "magY", "mz": "magZ"}


def test_import_csv_phone_export_ms_epoch_renamed_columns(tmp_path):
    path = tmp_path / "phone.csv"
    truth = phone_csv(path)
    s = import_csv(path, COLUMN_MAP, gyro_unit="deg/s", mag_unit="uT", time_unit="ms")
    np.testing.assert_allclose(s.t_gyro_s, truth["t_g_s"], atol=1e-12)
    np.testing.assert_allclose(s.gyro_rad_s, np.deg2rad(truth["gyro_deg_s"]))
    np.testing.assert_allclose(s.t_mag_s, truth["t_m_s"], atol=1e-12)
    np.testing.assert_allclose(s.mag, truth["mag"])
    assert s.mag_unit == "uT" and s.metadata["gyro_unit"] == "rad/s"
    assert "1700000000000 ms" in s.metadata["time_origin"]
    assert json.loads(s.metadata["column_map"]) == COLUMN_MAP
    # what import gives is what the written session file gives back
    out = tmp_path / "session.parquet"
    write_session(s, out)
    loaded = load_session(out)
    np.testing.assert_array_equal(loaded.gyro_rad_s, s.gyro_rad_s)
    np.testing.assert_array_equal(loaded.t_mag_s, s.t_mag_s)


def test_import_csv_guesses_common_headers_and_delimiter(tmp_path):
    path = tmp_path / "phyphox.csv"
    headers = {"t": "Time (ms)", "gx": "Gyroscope x (deg/s)", "gy": "Gyroscope y (deg/s)",
               "gz": "Gyroscope z (deg/s)", "mx": "Magnetic field x (µT)", "my": "Magnetic field y (µT)",
               "mz": "Magnetic field z (µT)"}
    truth = phone_csv(path, sep=";", headers=headers, epoch_ms=0)
    assert guess_column_map(headers.values()) == headers
    s = import_csv(path, None, gyro_unit="deg/s", mag_unit="µT", time_unit="ms")
    np.testing.assert_allclose(s.gyro_rad_s, np.deg2rad(truth["gyro_deg_s"]))
    assert len(s.t_mag_s) == len(truth["t_m_s"])
    assert s.mag_unit == "uT"


def test_parse_column_map():
    assert parse_column_map(None) == {} and parse_column_map([]) == {}
    assert parse_column_map(["t=timestamp", " gx = gyro X ,gy=gyroY", "gx=gyroX"]) == \
        {"t": "timestamp", "gx": "gyroX", "gy": "gyroY"}  # stripped; the last gx wins
    assert parse_column_map(["mx=a=b"]) == {"mx": "a=b"}  # split at the first "="
    for bad in ("gx", "gx=", "=gyroX", "t=time,"):
        with pytest.raises(InputError, match=r"--map '.*': expected NAME=COLUMN, e.g. --map gx=gyroX"):
            parse_column_map([bad])


def test_guess_column_map_spellings():
    assert guess_column_map(["t", "gx", "gy", "gz", "mx", "my", "mz"])["gz"] == "gz"
    got = guess_column_map(["timestamp_ns", "gyro_x_rad_s", "gyro_y_rad_s", "gyro_z_rad_s",
                            "mag_x_uT", "mag_y_uT", "mag_z_uT", "acc_x", "acc_y", "acc_z"])
    assert got == {"t": "timestamp_ns", "gx": "gyro_x_rad_s", "gy": "gyro_y_rad_s", "gz": "gyro_z_rad_s",
                   "mx": "mag_x_uT", "my": "mag_y_uT", "mz": "mag_z_uT", "ax": "acc_x", "ay": "acc_y", "az": "acc_z"}
    assert "gx" not in guess_column_map(["gyroX", "gyro_x"])  # ambiguous: no guess


def test_import_csv_epoch_ns_keeps_precision_and_converts_acc(tmp_path):
    n = 300
    t_ns = 1_700_000_000_123_456_789 + np.arange(n) * 10_000_000  # 100 Hz
    table = pd.DataFrame({"time_ns": t_ns, "wx": 0.1, "wy": -0.2, "wz": 0.3, "bx": 20.0, "by": 5.0, "bz": -40.0,
                          "accX": 0.0, "accY": 0.0, "accZ": 1.0})
    path = tmp_path / "logger.csv"
    table.to_csv(path, index=False)
    cmap = {"t": "time_ns", "gx": "wx", "gy": "wy", "gz": "wz", "mx": "bx", "my": "by", "mz": "bz",
            "ax": "accX", "ay": "accY", "az": "accZ"}
    s = import_csv(path, cmap, gyro_unit="rad/s", mag_unit="counts", time_unit="ns", acc_unit="g")
    np.testing.assert_allclose(np.diff(s.t_gyro_s), 0.01, rtol=0, atol=1e-12)
    np.testing.assert_allclose(s.acc_m_s2[:, 2], 9.80665)
    assert s.mag_unit == "counts"


def test_import_csv_plain_errors(tmp_path):
    path = tmp_path / "phone.csv"
    phone_csv(path)
    kw = dict(gyro_unit="deg/s", mag_unit="uT", time_unit="ms")
    with pytest.raises(InputError, match=r"unknown session column name\(s\) gyro_x.*t gx gy gz"):
        import_csv(path, {**COLUMN_MAP, "gyro_x": "gyroX"}, **kw)
    with pytest.raises(InputError, match=r"not in the file: gx=GyroXX; found columns: timestamp, gyroX"):
        import_csv(path, {**COLUMN_MAP, "gx": "GyroXX"}, **kw)
    with pytest.raises(InputError, match="unknown gyro unit 'rpm'"):
        import_csv(path, COLUMN_MAP, gyro_unit="rpm", mag_unit="uT", time_unit="ms")
    with pytest.raises(InputError, match="unknown magnetometer unit 'furlongs'"):
        import_csv(path, COLUMN_MAP, gyro_unit="deg/s", mag_unit="furlongs", time_unit="ms")
    with pytest.raises(InputError, match="unknown time unit 'fortnight'.*ms"):
        import_csv(path, COLUMN_MAP, gyro_unit="deg/s", mag_unit="uT", time_unit="fortnight")
    with pytest.raises(InputError, match="unknown accelerometer unit"):
        import_csv(path, COLUMN_MAP, gyro_unit="deg/s", mag_unit="uT", time_unit="ms", acc_unit="furlong/s^2")
    with pytest.raises(InputError, match=r"time unit 's', the time column looks like milliseconds \(median step 5 "
                                         r"'seconds' = 200 Hz if ms\); import with --time-unit ms"):  # ms read as s
        import_csv(path, COLUMN_MAP, gyro_unit="deg/s", mag_unit="uT", time_unit="s")
    with pytest.raises(InputError, match=r"looks like milliseconds \(median step 5 'ns' = 200 Hz if ms\); "
                                         r"import with --time-unit ms"):  # ms read as ns
        import_csv(path, COLUMN_MAP, gyro_unit="deg/s", mag_unit="uT", time_unit="ns")
    with pytest.raises(InputError, match="deg/s"):  # deg/s data labelled rad/s: io's plausibility check
        import_csv(path, COLUMN_MAP, gyro_unit="rad/s", mag_unit="uT", time_unit="ms")
    # mapping some magnetometer axes explicitly, the rest are guessed from the headers
    partly = {k: v for k, v in COLUMN_MAP.items() if k not in ("my", "mz")}
    assert import_csv(path, partly, **kw).mag.shape[1] == 3
    unnamed = tmp_path / "unnamed.csv"
    pd.read_csv(path).rename(columns={"magX": "B1", "magY": "B2", "magZ": "B3"}).to_csv(unnamed, index=False)
    with pytest.raises(InputError, match=r"no column for mx, my, mz; found columns: .*B1, B2, B3. Map them"):
        import_csv(unnamed, None, **kw)
    with pytest.raises(InputError, match=r"gives ax but not ay, az"):
        import_csv(path, {**COLUMN_MAP, "ax": "gyroX"}, **kw)


def test_import_csv_rejects_bad_rows(tmp_path):
    n = 200
    base = pd.DataFrame({"t": np.arange(n) / 100.0, "gx": 0.1, "gy": 0.2, "gz": 0.3,
                         "mx": 1.0, "my": 2.0, "mz": 3.0})
    cmap = {c: c for c in base.columns}
    kw = dict(gyro_unit="rad/s", mag_unit="uT")

    def write(table):
        path = tmp_path / "bad.csv"
        table.to_csv(path, index=False)
        return path

    back = base.copy()
    back.loc[50, "t"] = 0.2
    with pytest.raises(InputError, match="row 50 has an earlier time than row 49"):
        import_csv(write(back), cmap, **kw)
    partial = base.copy()
    partial.loc[7, "gy"] = np.nan
    with pytest.raises(InputError, match="row 7 has gx, gz but not gy"):
        import_csv(write(partial), cmap, **kw)
    text = base.astype(object)
    text.loc[3, "mx"] = "1.2.3"
    with pytest.raises(InputError, match="row 3, column mx holds '1.2.3'"):
        import_csv(write(text), cmap, **kw)
    short = base.iloc[: MIN_SAMPLES // 2]
    with pytest.raises(InputError, match="too few gyro samples"):
        import_csv(write(short), cmap, **kw)
    with pytest.raises(InputError, match="no such file"):
        import_csv(tmp_path / "missing.csv", cmap, **kw)
    empty = tmp_path / "empty.csv"
    empty.write_text("t,gx,gy,gz,mx,my,mz\n")
    with pytest.raises(InputError, match="no data rows"):
        import_csv(empty, cmap, **kw)


# --------------------------------------------------------------------------- the import commands


SHIPPED_SIM = DATA / "simulated-phone-module.parquet"


def shipped_as_phone_csv(path: Path) -> Session:
    """The shipped simulated session as a phone-style CSV (its own headers, gyro in deg/s); returns the session."""
    from magyro.io import session_table
    session = load_session(SHIPPED_SIM)
    table = session_table(session)
    table[["gx", "gy", "gz"]] = np.rad2deg(table[["gx", "gy", "gz"]])
    table.rename(columns={"t": "Time (s)", "gx": "gyroX", "gy": "gyroY", "gz": "gyroZ",
                          "mx": "B_1", "my": "B_2", "mz": "B_3"}).to_csv(path, index=False, sep=";")
    return session


def test_cli_import_csv_maps_converts_cuts_and_writes_zstd(tmp_path, run_magyro):
    import pyarrow.parquet as pq
    source = tmp_path / "phone.csv"
    session = shipped_as_phone_csv(source)
    out = tmp_path / "out.parquet"
    r = run_magyro("import", "csv", source, "-o", out, "--gyro-unit", "deg/s", "--mag-unit", "uT",
                   "-m", "mx=B_1,my=B_2", "--map", "mz=B_3", "--start", "5", "--end", "55")
    assert r.returncode == 0, r.stderr
    assert r.stdout.startswith(f"session written to {out}: 10001 gyro samples (200.0 Hz), "
                               f"2501 magnetometer samples (50.0 Hz), 50.0 s; columns "), r.stdout
    assert pq.ParquetFile(out).metadata.row_group(0).column(0).compression == "ZSTD"
    loaded = load_session(out)
    expected = trim(session, 5.0, 55.0)
    np.testing.assert_array_equal(loaded.t_gyro_s, expected.t_gyro_s)
    np.testing.assert_allclose(loaded.gyro_rad_s, expected.gyro_rad_s, rtol=1e-14, atol=1e-15)
    np.testing.assert_array_equal(loaded.t_mag_s, expected.t_mag_s)
    np.testing.assert_array_equal(loaded.mag, expected.mag)
    assert loaded.mag_unit == "uT"
    assert loaded.metadata["trimmed_to_s"] == "5.0 55.0"
    assert json.loads(loaded.metadata["column_map"]) == {
        "t": "Time (s)", "gx": "gyroX", "gy": "gyroY", "gz": "gyroZ", "mx": "B_1", "my": "B_2", "mz": "B_3"}


def test_cli_import_csv_to_csv_without_cut(tmp_path, run_magyro):
    source = tmp_path / "phone.csv"
    session = shipped_as_phone_csv(source)
    out = tmp_path / "out.csv"
    r = run_magyro("import", "csv", source, "-o", out, "--gyro-unit", "deg/s", "--mag-unit", "uT",
                   "-m", "mx=B_1,my=B_2,mz=B_3")
    assert r.returncode == 0, r.stderr
    loaded = load_session(out, mag_unit="uT")
    assert "trimmed_to_s" not in loaded.metadata
    np.testing.assert_array_equal(loaded.t_gyro_s, session.t_gyro_s)
    np.testing.assert_array_equal(loaded.mag, session.mag)


@pytest.mark.parametrize("args, message", [
    (["-m", "mx"], "--map 'mx': expected NAME=COLUMN, e.g. --map gx=gyroX"),
    (["-m", "mx=B_1,my=B_2"], "no column for mz"),
    (["-m", "mx=B_1,my=B_2,mz=B_3", "--start", "20", "--end", "20.1"], "keeps 21 gyro samples"),
])
def test_cli_import_csv_unusable_input_exit_2(args, message, tmp_path, run_magyro, assert_plain_failure):
    source = tmp_path / "phone.csv"
    shipped_as_phone_csv(source)
    out = tmp_path / "out.parquet"
    r = run_magyro("import", "csv", source, "-o", out, "--gyro-unit", "deg/s", "--mag-unit", "uT", *args)
    assert message in assert_plain_failure(r, 2)
    assert not out.exists()


def small_broad_mat(path: Path, n: int = 1200, rate_hz: float = 100.0) -> None:
    """A BROAD-layout .mat file: movement marked from 2 s to 9 s, truth lost in the first 0.5 s."""
    import scipy.io
    t = np.arange(n) / rate_hz
    quat = np.column_stack([np.cos(0.05 * t), 0 * t, 0 * t, np.sin(0.05 * t)])
    quat[:50] = np.nan
    scipy.io.savemat(path, {
        "imu_gyr": np.column_stack([0.2 * np.sin(t), 0.1 * np.cos(t), 0.05 + 0 * t]),
        "imu_acc": np.tile([0, 0, 9.81], (n, 1)),
        "imu_mag": np.column_stack([30 * np.cos(t), 30 * np.sin(t), -20 + 0 * t]),
        "opt_quat": quat, "movement": ((t >= 2.0) & (t <= 9.0)).astype(np.uint8)[:, None],
        "sampling_rate": np.array([[rate_hz]])})


def test_cli_import_broad_cuts_decimates_and_credits(tmp_path, run_magyro):
    trial = tmp_path / "98_small.mat"
    small_broad_mat(trial)
    out = tmp_path / "out.csv"
    r = run_magyro("import", "broad", trial, "-o", out, "--movement", "--rest", "0.5", "--end", "8",
                   "--decimate", "3")
    assert r.returncode == 0, r.stderr
    assert r.stdout.splitlines() == [
        f"session written to {out}: 217 samples at 33.333 Hz, 1.500 to 7.980 s, 217 truth quaternions",
        f"BROAD data are CC BY 4.0; credit {BROAD_CITATION}"]
    expected = decimate(trim(import_broad_movement(trial, 0.5), 1.5, 8.0), 3)
    loaded = load_session(out, mag_unit="uT")
    for name in ("t_gyro_s", "gyro_rad_s", "t_mag_s", "mag", "t_acc_s", "acc_m_s2", "t_quat_s", "quat_wxyz"):
        np.testing.assert_array_equal(getattr(loaded, name), getattr(expected, name), err_msg=name)


def test_cli_import_broad_not_a_trial_exit_2(tmp_path, run_magyro, assert_plain_failure):
    other = tmp_path / "trial.txt"
    other.write_text("x")
    out = tmp_path / "out.parquet"
    r = run_magyro("import", "broad", other, "-o", out)
    assert "unknown file type '.txt'" in assert_plain_failure(r, 2)
    assert not out.exists()


@pytest.mark.broad
@needs_broad
def test_cli_import_broad_movement_remakes_the_shipped_session(tmp_path, run_magyro):
    """data/broad-02.parquet is `magyro import broad --movement` of trial 02 (only the zstd level differs)."""
    out = tmp_path / "broad-02.parquet"
    r = run_magyro("import", "broad", BROAD_02, "-o", out, "--movement")
    assert r.returncode == 0, r.stderr
    assert "33994 samples at 285.714 Hz, 37.072 to 156.047 s, 33994 truth quaternions" in r.stdout
    made, shipped = load_session(out), load_session(DATA / "broad-02.parquet")
    for name in ("t_gyro_s", "gyro_rad_s", "t_mag_s", "mag", "t_acc_s", "acc_m_s2", "t_quat_s", "quat_wxyz"):
        np.testing.assert_array_equal(getattr(made, name), getattr(shipped, name), err_msg=name)
    assert made.metadata == shipped.metadata
