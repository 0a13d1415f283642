"""`magyro import csv` on what real users have (issue 22 item 6): Sensor Logger's AccelerometerUncalibrated.csv
(g on iOS, m/s^2 on Android), its zip with the CSVs at the top level, app exports given without --preset, time
columns that are sample or packet counters (--rate), and real public exports (../shared/data/wild, skipped when
absent; data/wild shipped)."""
from __future__ import annotations

import json
import sys
import zipfile
from pathlib import Path

import numpy as np
import pytest

from magyro.io import import_csv, import_preset, load_session
from magyro.io.checks import MIN_PLAUSIBLE_STEP_S

sys.path.insert(0, str(Path(__file__).resolve().parent))
from test_import_csv_files import (GYRO_STEP_NS, N_GYRO, T0_NS, cli, digest, gyro_rad_s, mag_ut,  # noqa: E402
                                   phyphox_export, refused, sensor_logger_csv, sensor_logger_export)

WILD = Path(__file__).resolve().parents[1] / ".." / "shared" / "data" / "wild"


def wild(folder: str) -> Path:
    path = WILD / folder
    if not path.is_dir():
        pytest.skip(f"needs the public recordings in ../shared/data/wild/{folder} (absent in a fresh clone)")
    return path


def acc_g(n):
    """An accelerometer holding gravity, in g: mostly +z, tilting."""
    k = np.arange(n)
    tilt = 0.3 * np.sin(0.02 * k)
    return np.column_stack([np.sin(tilt), 0.05 * np.cos(0.1 * k), np.cos(tilt)])


@pytest.mark.parametrize("unit, scale", [("g", 1.0), ("m/s^2", 9.80665)], ids=["iOS-g", "Android-m_s2"])
def test_sensor_logger_reads_accelerometer_uncalibrated_in_either_unit(unit, scale, tmp_path):
    """iOS writes AccelerometerUncalibrated.csv in g, Android in m/s^2 (Sensor Logger's UNITS.md): both come out in m/s^2."""
    folder = sensor_logger_export(tmp_path / "rec")
    sensor_logger_csv(folder / "AccelerometerUncalibrated.csv", T0_NS, GYRO_STEP_NS, acc_g(N_GYRO) * scale)
    s = import_preset([folder], "sensor-logger")
    np.testing.assert_allclose(s.acc_m_s2, acc_g(N_GYRO) * 9.80665, rtol=1e-12)
    np.testing.assert_array_equal(s.t_acc_s, s.t_gyro_s)
    assert json.loads(s.metadata["sensor_files"])["accelerometer"].endswith("AccelerometerUncalibrated.csv")
    assert "AccelerometerUncalibrated.csv" in s.metadata["sensor_note"]


def test_sensor_logger_accelerometer_of_no_known_unit_is_refused(tmp_path):
    folder = sensor_logger_export(tmp_path / "rec")
    sensor_logger_csv(folder / "AccelerometerUncalibrated.csv", T0_NS, GYRO_STEP_NS, acc_g(N_GYRO) * 1000)
    text = refused(cli(folder, "--preset", "sensor-logger", "-o", tmp_path / "s.parquet"))
    assert "cannot tell the accelerometer's unit: its median |a| is 1001, neither about 1 (g) nor about 9.8" in text, text


def test_sensor_logger_zip_with_its_csvs_at_the_top_level(tmp_path):
    folder = sensor_logger_export(tmp_path / "rec", with_calibrated=True)
    archive = tmp_path / "top.zip"
    with zipfile.ZipFile(archive, "w", zipfile.ZIP_DEFLATED) as z:
        for f in sorted(folder.iterdir()):
            z.write(f, f.name)
    s = import_preset([archive], "sensor-logger")
    assert json.loads(s.metadata["sensor_files"]) == {"gyro": f"{archive}:GyroscopeUncalibrated.csv",
                                                      "magnetometer": f"{archive}:MagnetometerUncalibrated.csv"}
    np.testing.assert_array_equal(s.gyro_rad_s, gyro_rad_s(N_GYRO))


def test_sensor_logger_files_given_to_plain_import_are_recognised(tmp_path):
    folder = sensor_logger_export(tmp_path / "rec")
    files = [folder / "GyroscopeUncalibrated.csv", folder / "MagnetometerUncalibrated.csv"]
    out = tmp_path / "s.parquet"
    r = cli(*files, "-o", out)
    assert r.exit_code == 0, r.output
    assert "read as a Sensor Logger export (--preset sensor-logger)" in r.output
    s = load_session(out)
    np.testing.assert_array_equal(s.gyro_rad_s, gyro_rad_s(N_GYRO))
    assert s.metadata["preset"] == "sensor-logger"
    # the app's own units given are fine; others are refused naming the preset
    assert cli(*files, "-o", tmp_path / "t.parquet", "--gyro-unit", "rad/s", "--mag-unit", "uT").exit_code == 0
    text = refused(cli(*files, "-o", tmp_path / "u.parquet", "--gyro-unit", "deg/s", "--mag-unit", "uT"))
    assert "a Sensor Logger export, whose gyro is in rad/s" in text and "--preset sensor-logger" in text


def test_phyphox_files_given_to_plain_import_are_recognised_but_a_logger_csv_is_not(tmp_path):
    folder, t_gyro, _ = phyphox_export(tmp_path / "exp")
    r = cli(folder / "Gyroscope.csv", folder / "Magnetometer.csv", "-o", tmp_path / "p.parquet")
    assert r.exit_code == 0 and "read as a phyphox export" in r.output, r.output
    r = cli(folder, "-o", tmp_path / "f.parquet")  # its folder too, by the files' headers (not their names)
    assert r.exit_code == 0 and "read as a phyphox export" in r.output, r.output
    archive = tmp_path / "exp.zip"
    with zipfile.ZipFile(archive, "w") as z:
        for f in sorted(folder.glob("*.csv")):
            z.write(f, f.name)
    text = refused(cli(archive, "-o", tmp_path / "z.parquet"))  # a zip is only peeked at for Sensor Logger's
    assert "an app's export folder or zip is read with --preset sensor-logger|phyphox" in text, text
    assert "found" not in text  # not taken for Sensor Logger files, whose names phyphox shares
    # "Time (s)" with axes in units, but several sensors and deg/s: an ordinary logger CSV, read by its units
    mixed = tmp_path / "log.csv"
    g, m = gyro_rad_s(N_GYRO), mag_ut(N_GYRO)
    mixed.write_text("Time (s),Gyroscope X (deg/s),Gyroscope Y (deg/s),Gyroscope Z (deg/s),Magnetometer X (uT),"
                     "Magnetometer Y (uT),Magnetometer Z (uT)\n"
                     + "".join(",".join(repr(float(v)) for v in (0.01 * k, *np.rad2deg(g[k]), *m[k])) + "\n"
                               for k in range(N_GYRO)))
    r = cli(mixed, "-o", tmp_path / "m.parquet", "--gyro-unit", "deg/s", "--mag-unit", "uT")
    assert r.exit_code == 0 and "read as" not in r.output, r.output
    np.testing.assert_allclose(load_session(tmp_path / "m.parquet").gyro_rad_s, g, rtol=1e-12)


def counter_csv(path, with_counter=True):
    g, m = gyro_rad_s(N_GYRO), mag_ut(N_GYRO)
    head = "sample,gx,gy,gz,mx,my,mz" if with_counter else "gx,gy,gz,mx,my,mz"
    rows = [",".join(repr(float(v)) if i or not with_counter else str(int(v))
                     for i, v in enumerate(((1000 + k,) if with_counter else ()) + (*g[k], *m[k])))
            for k in range(N_GYRO)]
    path.write_text(head + "\n" + "\n".join(rows) + "\n")
    return path


def test_sample_counter_time_takes_a_rate_and_the_hint_says_so(tmp_path):
    src = counter_csv(tmp_path / "log.csv")
    for extra in ([], ["--time-unit", "us"]):
        text = refused(cli(src, "-o", tmp_path / "s.parquet", "--gyro-unit", "rad/s", "--mag-unit", "uT",
                           "-m", "t=sample", *extra))
        assert "the time column sample counts samples or packets" in text and "--rate HZ" in text, text
        assert "millisecond" not in text
    out = tmp_path / "s.parquet"
    r = cli(src, "-o", out, "--gyro-unit", "rad/s", "--mag-unit", "uT", "-m", "t=sample", "--rate", "250")
    assert r.exit_code == 0, r.output
    s = load_session(out)
    np.testing.assert_allclose(s.t_gyro_s, np.arange(N_GYRO) / 250.0, rtol=0, atol=1e-12)
    assert s.gyro_rate_hz == pytest.approx(250.0)
    np.testing.assert_array_equal(s.gyro_rad_s, gyro_rad_s(N_GYRO))


def test_no_time_column_hints_at_rate_and_takes_the_row_number(tmp_path):
    src = counter_csv(tmp_path / "log.csv", with_counter=False)
    text = refused(cli(src, "-o", tmp_path / "s.parquet", "--gyro-unit", "rad/s", "--mag-unit", "uT"))
    assert "no column for t" in text and "--rate HZ" in text
    s = import_csv(src, None, "rad/s", "uT", rate_hz=50)
    np.testing.assert_allclose(s.t_gyro_s, np.arange(N_GYRO) / 50.0, rtol=0, atol=1e-12)
    for bad in ("0", "nan", "1e9"):
        text = refused(cli(src, "-o", tmp_path / "s.parquet", "--gyro-unit", "rad/s", "--mag-unit", "uT",
                           "--rate", bad))
        assert f"sampling rate in Hz must be between 1 and {1 / MIN_PLAUSIBLE_STEP_S:g}" in text   # as steps are checked
    folder = sensor_logger_export(tmp_path / "rec")
    text = refused(cli(folder, "--preset", "sensor-logger", "--rate", "100", "-o", tmp_path / "s.parquet"))
    assert "--rate is for one CSV file" in text


def test_real_sensor_logger_android_export_with_accelerometer_uncalibrated(tmp_path):
    """simorxb (Android, Sensor Logger): its AccelerometerUncalibrated.csv holds |a| about 1, i.e. g; read as m/s^2."""
    folder = wild("simorxb")
    before = digest(sorted(folder.iterdir()))
    out = tmp_path / "s.parquet"
    r = cli(folder, "-o", out)  # recognised without --preset
    assert r.exit_code == 0, r.output
    assert digest(sorted(folder.iterdir())) == before
    s = load_session(out)
    assert json.loads(s.metadata["sensor_files"])["accelerometer"].endswith("AccelerometerUncalibrated.csv")
    assert 9.0 < float(np.median(np.linalg.norm(s.acc_m_s2, axis=1))) < 10.5
    assert s.gyro_rate_hz == pytest.approx(100.0, rel=0.02) and len(s.t_gyro_s) == 2706
    assert 500 < float(np.median(np.linalg.norm(s.mag, axis=1))) < 700   # the phone's hard iron, about 600 uT


def test_real_sensor_logger_iphone_calibrated_files(tmp_path):
    """bennyjhui (iPhone 12): calibrated files only; Accelerometer.csv (no gravity) and a non-app CSV are left out."""
    folder = wild("bennyjhui")
    s = import_preset([folder], "sensor-logger")
    assert "calibrated by the phone" in s.metadata["sensor_note"]
    assert s.acc_m_s2 is None and len(s.t_gyro_s) == 1038
    # said, so that --accelerometer can say why there is none
    assert s.metadata["sensor_note"].endswith("no accelerometer: Accelerometer.csv left out, it is the phone's "
                                              "acceleration without gravity; record TotalAcceleration or "
                                              "AccelerometerUncalibrated to calibrate the accelerometer")
    archive = tmp_path / "top.zip"
    with zipfile.ZipFile(archive, "w", zipfile.ZIP_DEFLATED) as z:
        for f in sorted(folder.iterdir()):
            z.write(f, f.name)
    z_session = import_preset([archive], "sensor-logger")
    np.testing.assert_array_equal(z_session.gyro_rad_s, s.gyro_rad_s)
    np.testing.assert_array_equal(z_session.t_mag_s, s.t_mag_s)
    assert z_session.metadata["sensor_note"] == s.metadata["sensor_note"]


SHIPPED_WILD = Path(__file__).resolve().parents[1] / "data" / "wild"


def test_shipped_x_io_csv_through_plain_import(tmp_path):
    """The shipped data/wild/fusion/sensor_data.csv (x-io IMU, MIT; "Time (s)", "Gyroscope X (deg/s)", ...): read
    by its units, not taken for phyphox; 135 s at 100 Hz, gravity 1 g, a field of Earth's strength in uT."""
    src = SHIPPED_WILD / "fusion" / "sensor_data.csv"
    before = digest([src])
    r = cli(src, "-o", tmp_path / "f.parquet", "--gyro-unit", "deg/s", "--mag-unit", "uT", "--acc-unit", "g")
    assert r.exit_code == 0 and "read as" not in r.output, r.output
    assert digest([src]) == before
    s = load_session(tmp_path / "f.parquet")
    assert len(s.t_gyro_s) == 13514 and s.gyro_rate_hz == pytest.approx(100.0, rel=0.01)
    assert s.duration_s == pytest.approx(135.3, abs=0.1)
    assert 9.6 < float(np.median(np.linalg.norm(s.acc_m_s2, axis=1))) < 10.0
    assert 25 < float(np.median(np.linalg.norm(s.mag, axis=1))) < 65  # Earth's field, uT
    assert s.metadata["mag_unit"] == "uT"


def test_x_imu_packet_numbers_are_a_counter_not_milliseconds(tmp_path):
    """x-IMU's CalInertialAndMag.csv ("Packet number" stepping by 2 or 3, as in xioTechnologies'
    Oscillatory-Motion-Tracking-With-x-IMU LoggedData): once taken for ms, now a counter given its rate."""
    g, m = gyro_rad_s(N_GYRO), mag_ut(N_GYRO)
    packets = np.cumsum(np.where(np.arange(N_GYRO) % 12 == 11, 3, 2)) - 2
    src = tmp_path / "LoggedData_CalInertialAndMag.csv"
    src.write_text("Packet number,Gyroscope X (deg/s),Gyroscope Y (deg/s),Gyroscope Z (deg/s),Magnetometer X (G),"
                   "Magnetometer Y (G),Magnetometer Z (G)\n" + "".join(
                       f"{p}," + ",".join(repr(float(v)) for v in (*np.rad2deg(g[k]), *m[k] / 100)) + "\n"
                       for k, p in enumerate(packets)))
    units = ["--gyro-unit", "deg/s", "--mag-unit", "G"]
    text = refused(cli(src, "-o", tmp_path / "s.parquet", *units))
    assert "no column for t" in text and "--rate HZ" in text
    text = refused(cli(src, "-o", tmp_path / "s.parquet", *units, "-m", "t=Packet number"))
    assert "the time column Packet number counts samples or packets" in text and "millisecond" not in text, text
    s = import_csv(src, {"t": "Packet number"}, "deg/s", "G", rate_hz=512)
    np.testing.assert_allclose(s.t_gyro_s, packets / 512, rtol=0, atol=1e-12)
    np.testing.assert_allclose(s.gyro_rad_s, g, rtol=1e-12)
