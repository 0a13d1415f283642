"""`magyro import csv` with one file per sensor, --preset sensor-logger|phyphox, --skip-rows/--header-line.

The fixtures are written in the exact layouts verified in real public exports (no real file
with a redistributable license was found, see data/csv/README.md):
Sensor Logger `time,seconds_elapsed,z,y,x` with epoch-ns integer stamps (GyroscopeUncalibrated.csv,
MagnetometerUncalibrated.csv of simorxb/quaternion-complementary-filter; units from
tszheichoi/awesome-sensor-logger UNITS.md); phyphox `"Time (s)","X (µT)",...` with numbers
like 8.025970834E-2 (Magnetometer.csv of Slmaking/Reorientation-of-smartphone) and the
single-sensor headers `"Time (s)","Gyroscope x (rad/s)",...,"Absolute (rad/s)"`.
"""
from __future__ import annotations

import hashlib
import json
import zipfile
from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

from magyro.cli import app
from magyro.errors import InputError
from magyro.io import import_csv, import_csv_files, import_preset, load_session, parse_file_column_map

T0_NS = 1699734109846237400  # a real Sensor Logger stamp: ns since the epoch, beyond float64 precision
GYRO_STEP_NS = 10_000_000    # 100 Hz
MAG_STEP_NS = 20_000_000     # 50 Hz
N_GYRO, N_MAG = 300, 150


def gyro_rad_s(n):
    k = np.arange(n)
    return np.column_stack([0.5 * np.sin(0.05 * k), 0.3 * np.cos(0.07 * k), 0.1 * np.sin(0.11 * k + 1)])


def mag_ut(n):
    k = np.arange(n)
    return np.column_stack([20 + 5 * np.cos(0.1 * k), -3 + 5 * np.sin(0.1 * k), -40 + np.sin(0.03 * k)])


def sensor_logger_csv(path, t_first_ns, step_ns, xyz):
    """A Sensor Logger per-sensor file: time (epoch ns), seconds_elapsed, z, y, x."""
    lines = ["time,seconds_elapsed,z,y,x"]
    for k, (x, y, z) in enumerate(xyz):
        t = t_first_ns + k * step_ns
        lines.append(f"{t},{(t - T0_NS) / 1e9 + 0.12},{float(z)!r},{float(y)!r},{float(x)!r}")
    path.write_text("\n".join(lines) + "\n")
    return path


def sensor_logger_export(folder, mag_offset_ns=3_000_000, with_calibrated=False):
    folder.mkdir(parents=True, exist_ok=True)
    sensor_logger_csv(folder / "GyroscopeUncalibrated.csv", T0_NS, GYRO_STEP_NS, gyro_rad_s(N_GYRO))
    sensor_logger_csv(folder / "MagnetometerUncalibrated.csv", T0_NS - mag_offset_ns, MAG_STEP_NS, mag_ut(N_MAG))
    if with_calibrated:
        sensor_logger_csv(folder / "Gyroscope.csv", T0_NS, GYRO_STEP_NS, gyro_rad_s(N_GYRO) - 0.01)
        sensor_logger_csv(folder / "Magnetometer.csv", T0_NS, MAG_STEP_NS, mag_ut(N_MAG) - 1.0)
    (folder / "Metadata.csv").write_text("version,device name\n3,phone\n")
    return folder


def phyphox_csv(path, header, t_s, xyz, sep=",", decimal="."):
    def num(v):
        return f"{v:.9E}".replace(".", decimal)
    rows = [sep.join(f'"{h}"' for h in header)]
    for t, row in zip(t_s, xyz):
        cells = [num(t), *map(num, row)] + ([num(float(np.linalg.norm(row)))] if len(header) == 5 else [])
        rows.append(sep.join(cells))
    path.write_text("\n".join(rows) + "\n", encoding="utf-8")
    return path


def phyphox_export(folder, sep=",", decimal="."):
    folder.mkdir(parents=True, exist_ok=True)
    t_gyro = 0.0103 + 0.01 * np.arange(N_GYRO)
    t_mag = 0.0802 + 0.02 * np.arange(N_MAG)
    phyphox_csv(folder / "Gyroscope.csv", ["Time (s)", "Gyroscope x (rad/s)", "Gyroscope y (rad/s)",
                                           "Gyroscope z (rad/s)", "Absolute (rad/s)"],
                t_gyro, gyro_rad_s(N_GYRO), sep, decimal)
    phyphox_csv(folder / "Magnetometer.csv", ["Time (s)", "X (µT)", "Y (µT)", "Z (µT)"],
                t_mag, mag_ut(N_MAG), sep, decimal)
    (folder / "meta").mkdir(exist_ok=True)
    (folder / "meta" / "time.csv").write_text('"event";"experiment time";"system time"\n"START";0;1.75E9\n')
    return folder, t_gyro, t_mag


def digest(paths):
    return {str(p): hashlib.sha256(Path(p).read_bytes()).hexdigest() for p in paths}


def cli(*args):
    return CliRunner().invoke(app, ["import", "csv", *map(str, args)])


def refused(result) -> str:
    """The one-line message of a refused import (exit code 2, no traceback)."""
    text = result.output + (getattr(result, "stderr", "") if result.stderr_bytes is not None else "")
    assert result.exit_code == 2, (result.exit_code, text, result.exception)
    assert "Traceback" not in text
    return " ".join(text.split())


# --------------------------------------------------------------------------- Sensor Logger


def test_sensor_logger_preset_merges_exact_times_and_values(tmp_path):
    folder = sensor_logger_export(tmp_path / "rec")
    files = [folder / "GyroscopeUncalibrated.csv", folder / "MagnetometerUncalibrated.csv"]
    before = digest(files)
    out = tmp_path / "s.parquet"
    r = cli(*files, "--preset", "sensor-logger", "-o", out)
    assert r.exit_code == 0, r.output
    assert digest(files) == before

    s = load_session(out)
    origin_ns = T0_NS - 3_000_000  # the magnetometer starts 3 ms before the gyro
    np.testing.assert_array_equal(s.t_gyro_s, (np.arange(N_GYRO) * GYRO_STEP_NS + 3_000_000) * 1e-9)
    np.testing.assert_array_equal(s.t_mag_s, np.arange(N_MAG) * MAG_STEP_NS * 1e-9)
    np.testing.assert_array_equal(s.gyro_rad_s, gyro_rad_s(N_GYRO))
    np.testing.assert_array_equal(s.mag, mag_ut(N_MAG))
    assert s.gyro_rate_hz == pytest.approx(100.0) and s.mag_rate_hz == pytest.approx(50.0)
    m = s.metadata
    assert m["preset"] == "sensor-logger" and m["mag_unit"] == "uT" and m["gyro_unit"] == "rad/s"
    assert json.loads(m["source"]) == [str(f) for f in files]
    assert json.loads(m["sensor_files"]) == {"gyro": str(files[0]), "magnetometer": str(files[1])}
    assert m["time_origin"].startswith(f"{origin_ns} ns")
    assert "GyroscopeUncalibrated.csv (uncalibrated)" in m["sensor_note"]


def test_sensor_logger_folder_and_zip_prefer_uncalibrated(tmp_path):
    folder = sensor_logger_export(tmp_path / "rec", with_calibrated=True)
    s = import_preset([folder], "sensor-logger")
    used = json.loads(s.metadata["sensor_files"])
    assert used == {"gyro": str(folder / "GyroscopeUncalibrated.csv"),
                    "magnetometer": str(folder / "MagnetometerUncalibrated.csv")}
    np.testing.assert_array_equal(s.gyro_rad_s, gyro_rad_s(N_GYRO))  # not the calibrated (-0.01) file

    archive = tmp_path / "rec.zip"
    with zipfile.ZipFile(archive, "w") as z:
        for f in sorted(folder.iterdir()):
            z.write(f, f"2024-01-01_10-00-00/{f.name}")
    before = digest([archive])
    out = tmp_path / "z.parquet"
    r = cli(archive, "--preset", "sensor-logger", "-o", out)
    assert r.exit_code == 0, r.output
    assert digest([archive]) == before
    z_session = load_session(out)
    np.testing.assert_array_equal(z_session.t_gyro_s, s.t_gyro_s)
    assert "MagnetometerUncalibrated.csv" in json.loads(z_session.metadata["sensor_files"])["magnetometer"]


def test_sensor_logger_calibrated_only_is_used_and_said(tmp_path):
    folder = tmp_path / "rec"
    folder.mkdir()
    sensor_logger_csv(folder / "Gyroscope.csv", T0_NS, GYRO_STEP_NS, gyro_rad_s(N_GYRO))
    sensor_logger_csv(folder / "Magnetometer.csv", T0_NS, MAG_STEP_NS, mag_ut(N_MAG))
    s = import_preset([folder / "Gyroscope.csv", folder / "Magnetometer.csv"], "sensor-logger")
    assert "calibrated by the phone" in s.metadata["sensor_note"]


@pytest.mark.parametrize("case, message", [
    ("no_mag", "no magnetometer file"),
    ("wrong_file", "not a file the sensor-logger preset reads"),
    ("wrong_columns", "not a Sensor Logger gyro export"),
    ("twice", "the gyro is given twice"),
    ("units_given", "leave out --gyro-unit"),
])
def test_sensor_logger_refusals(case, message, tmp_path):
    folder = sensor_logger_export(tmp_path / "rec")
    gyro, mag = folder / "GyroscopeUncalibrated.csv", folder / "MagnetometerUncalibrated.csv"
    args = {"no_mag": [gyro],
            "wrong_file": [gyro, mag, folder / "Metadata.csv"],
            "twice": [gyro, mag, sensor_logger_export(tmp_path / "other") / "GyroscopeUncalibrated.csv"],
            "units_given": [gyro, mag, "--gyro-unit", "rad/s"]}.get(case, [gyro, mag])
    if case == "wrong_columns":
        gyro.write_text("t,a,b,c\n1,2,3,4\n")
    before = digest([gyro, mag])
    text = refused(cli(*args, "--preset", "sensor-logger", "-o", tmp_path / "s.parquet"))
    assert message in text, text
    assert digest([gyro, mag]) == before
    assert not (tmp_path / "s.parquet").exists()


# --------------------------------------------------------------------------- phyphox


@pytest.mark.parametrize("sep, decimal", [(",", "."), (";", ","), ("\t", ",")])
def test_phyphox_preset_every_csv_flavour(sep, decimal, tmp_path):
    folder, t_gyro, t_mag = phyphox_export(tmp_path / "Gyro 2024-01-01", sep, decimal)
    s = import_preset([folder], "phyphox")
    t0 = t_gyro[0]
    np.testing.assert_allclose(s.t_gyro_s, t_gyro - t0, rtol=0, atol=1e-12)
    np.testing.assert_allclose(s.t_mag_s, t_mag - t0, rtol=0, atol=1e-12)
    np.testing.assert_allclose(s.gyro_rad_s, gyro_rad_s(N_GYRO), rtol=1e-9)
    np.testing.assert_allclose(s.mag, mag_ut(N_MAG), rtol=1e-9)
    assert s.gyro_rate_hz == pytest.approx(100.0) and s.mag_rate_hz == pytest.approx(50.0)
    assert s.metadata["mag_unit"] == "uT" and s.metadata["preset"] == "phyphox"
    assert json.loads(s.metadata["sensor_files"])["magnetometer"].endswith("Magnetometer.csv")


def test_phyphox_cli_refuses_linear_acceleration_and_missing_gyro(tmp_path):
    folder, _, t_mag = phyphox_export(tmp_path / "exp")
    linear = phyphox_csv(tmp_path / "exp" / "Linear Accelerometer.csv",
                         ["Time (s)", "Linear Acceleration x (m/s^2)", "Linear Acceleration y (m/s^2)",
                          "Linear Acceleration z (m/s^2)"], t_mag, mag_ut(N_MAG))
    text = refused(cli(folder / "Gyroscope.csv", folder / "Magnetometer.csv", linear, "--preset", "phyphox",
                       "-o", tmp_path / "s.parquet"))
    assert "linear acceleration leaves gravity out" in text
    text = refused(cli(folder / "Magnetometer.csv", "--preset", "phyphox", "-o", tmp_path / "s.parquet"))
    assert "no gyro file" in text


# --------------------------------------------------------------------------- files without a preset


def test_files_merged_with_file_column_map(tmp_path):
    folder = sensor_logger_export(tmp_path / "rec")
    gyro, mag = folder / "GyroscopeUncalibrated.csv", folder / "MagnetometerUncalibrated.csv"
    out = tmp_path / "s.parquet"
    r = cli(gyro, mag, "-o", out, "--gyro-unit", "rad/s", "--mag-unit", "uT", "--time-unit", "ns",
            "-m", f"t={gyro.name}:time,gx={gyro.name}:x,gy={gyro.name}:y,gz={gyro.name}:z",
            "-m", f"t={mag}:time", "-m", f"mx={mag.name}:x,my={mag.name}:y,mz={mag.name}:z")
    assert r.exit_code == 0, r.output
    s = load_session(out)
    np.testing.assert_array_equal(s.gyro_rad_s, gyro_rad_s(N_GYRO))
    np.testing.assert_array_equal(s.t_mag_s, np.arange(N_MAG) * MAG_STEP_NS * 1e-9)
    assert json.loads(s.metadata["column_map"])[str(gyro)] == {"t": "time", "gx": "x", "gy": "y", "gz": "z"}


def test_files_with_guessed_headers_and_degrees(tmp_path):
    gyro = tmp_path / "gyro.csv"
    mag = tmp_path / "mag.csv"
    k = np.arange(N_GYRO)
    gyro.write_text("timestamp,gyro_x,gyro_y,gyro_z\n" + "".join(
        f"{1000 + 5 * i},{10.0 * np.sin(i / 20)},{5.0},{-2.0}\n" for i in k))
    mag.write_text("timestamp,mag_x,mag_y,mag_z\n" + "".join(
        f"{1002 + 10 * i},{20.0 + i / 10},{-3.0},{-40.0}\n" for i in range(N_MAG)))
    s = import_csv_files([gyro, mag], None, gyro_unit="deg/s", mag_unit="uT", time_unit="ms")
    np.testing.assert_allclose(s.gyro_rad_s[:, 1], np.deg2rad(5.0))
    np.testing.assert_array_equal(s.t_mag_s, (2 + 10 * np.arange(N_MAG)) * 1e-3)
    assert s.gyro_rate_hz == pytest.approx(200.0) and s.mag_rate_hz == pytest.approx(100.0)


@pytest.mark.parametrize("case, message", [
    ("no_overlap", "time ranges do not overlap"),
    ("two_gyros", "the gyro (gx gy gz) is in two files"),
    ("map_without_file", "say which file the column is in"),
])
def test_files_refusals(case, message, tmp_path):
    a = sensor_logger_export(tmp_path / "a")
    gyro, mag = a / "GyroscopeUncalibrated.csv", a / "MagnetometerUncalibrated.csv"
    maps = ["-m", f"t={gyro.name}:time,gx={gyro.name}:x,gy={gyro.name}:y,gz={gyro.name}:z",
            "-m", f"t={mag.name}:time,mx={mag.name}:x,my={mag.name}:y,mz={mag.name}:z"]
    files = [gyro, mag]
    if case == "no_overlap":
        sensor_logger_csv(mag, T0_NS + 10 * 10**9, MAG_STEP_NS, mag_ut(N_MAG))
    if case == "two_gyros":
        g2 = tmp_path / "g2.csv"
        g2.write_text(gyro.read_text())
        files.append(g2)
        maps += ["-m", "t=g2.csv:time,gx=g2.csv:x,gy=g2.csv:y,gz=g2.csv:z"]
    if case == "map_without_file":
        maps = ["-m", "gx=x"]
    text = refused(cli(*files, "-o", tmp_path / "s.parquet", "--gyro-unit", "rad/s", "--mag-unit", "uT",
                       "--time-unit", "ns", *maps))
    assert message in text, text
    if case == "no_overlap":
        assert "0.000 s to 2.990 s" in text and "10.000 s to 12.980 s" in text


# --------------------------------------------------------------------------- --skip-rows, --header-line


def units_row_csv(path, preamble=()):
    rows = [*preamble, "t,gx,gy,gz,mx,my,mz", "s,rad/s,rad/s,rad/s,uT,uT,uT"]
    g, m = gyro_rad_s(N_GYRO), mag_ut(N_GYRO)
    rows += [",".join(repr(float(v)) for v in (0.01 * k, *g[k], *m[k])) for k in range(N_GYRO)]
    path.write_text("\n".join(rows) + "\n")
    return path


def test_units_row_refused_with_skip_rows_hint_then_skipped(tmp_path):
    src = units_row_csv(tmp_path / "log.csv")
    text = refused(cli(src, "-o", tmp_path / "s.parquet", "--gyro-unit", "rad/s", "--mag-unit", "uT"))
    assert "not a number" in text and "--skip-rows 1" in text
    s = import_csv(src, None, "rad/s", "uT", skip_rows=1)
    np.testing.assert_array_equal(s.gyro_rad_s, gyro_rad_s(N_GYRO))


def test_header_line_and_skip_rows_via_cli(tmp_path):
    src = units_row_csv(tmp_path / "log.csv", preamble=("Logger v2", "device: imu-7", ""))
    before = digest([src])
    out = tmp_path / "s.parquet"
    r = cli(src, "-o", out, "--gyro-unit", "rad/s", "--mag-unit", "uT", "--header-line", "3", "--skip-rows", "1")
    assert r.exit_code == 0, r.output
    s = load_session(out)
    np.testing.assert_array_equal(s.t_gyro_s, 0.01 * np.arange(N_GYRO))
    np.testing.assert_array_equal(s.mag, mag_ut(N_GYRO))
    assert digest([src]) == before


def test_parse_file_column_map_names_files_by_name_or_path(tmp_path):
    paths = [tmp_path / "a" / "gyro.csv", tmp_path / "b" / "mag.csv"]
    got = parse_file_column_map([f"gx=gyro.csv:x,t={paths[1]}:time", "mx=mag.csv:a:b"], paths)
    assert got == {0: {"gx": "x"}, 1: {"t": "time", "mx": "a:b"}}
    with pytest.raises(InputError, match="say which file"):
        parse_file_column_map(["gx=other.csv:x"], paths)

