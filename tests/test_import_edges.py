"""Rough edges of the importers (issue 40, item 6): units a CSV header says, the accelerometer beside Sensor
Logger files given one by one, an unreadable file inside an export folder. On the real recordings of
../shared/data/wild where the issue met them (skipped, saying why, when the corpus is absent)."""
from __future__ import annotations

import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from unprivileged import run_unprivileged, unprivileged_folder  # noqa: F401 (a fixture)
from typer.testing import CliRunner

from magyro.cli import app
from magyro.errors import InputError
from magyro.io import import_csv, load_session

WILD = Path(__file__).resolve().parents[2] / "shared" / "data" / "wild"   # ../shared beside the repository
FUSION = WILD / "fusion" / "sensor_data.csv"
SIMORXB = WILD / "simorxb"
needs_wild = pytest.mark.skipif(not WILD.is_dir(), reason=f"the corpus of real recordings ({WILD}) is absent")


def imported(*args):
    return CliRunner().invoke(app, ["import", "csv", *map(str, args)])


def refused(result) -> str:
    text = result.output + (result.stderr if result.stderr_bytes is not None else "")
    assert result.exit_code == 2, (result.exit_code, text, result.exception)
    assert "Traceback" not in text and "cannot write output" not in text
    return " ".join(text.split())


def fusion_head(tmp_path, rows=1500) -> Path:
    """The first rows of x-io's Fusion recording: "Gyroscope X (deg/s)", "Accelerometer X (g)",
    "Magnetometer X (uT)", "Time (s)"."""
    path = tmp_path / "sensor_data.csv"
    path.write_text("".join(FUSION.open().readlines()[: rows + 1]))
    return path


# --------------------------------------------------------------------------- 1: units from the header


@needs_wild
def test_csv_units_read_from_the_header_of_a_real_recording(tmp_path):
    """Before: `magyro import csv sensor_data.csv` asked for --gyro-unit and --mag-unit though every column
    says its unit."""
    src = fusion_head(tmp_path)
    out = tmp_path / "s.parquet"
    result = imported(src, "-o", out)
    assert result.exit_code == 0, result.output
    s = load_session(out)
    raw = pd.read_csv(src)
    np.testing.assert_allclose(s.gyro_rad_s, np.deg2rad(raw[[f"Gyroscope {a} (deg/s)" for a in "XYZ"]].to_numpy()))
    assert s.mag_unit == "uT"
    acc = s.acc_m_s2 if hasattr(s, "acc_m_s2") else s.accelerometer
    assert 9.0 < float(np.median(np.linalg.norm(acc, axis=1))) < 10.6  # (g) read as g, in m/s^2

    # an option the header contradicts is refused naming both; one that agrees is fine
    message = refused(imported(src, "-o", tmp_path / "x.parquet", "--gyro-unit", "rad/s"))
    assert "--gyro-unit rad/s" in message and "Gyroscope X (deg/s)" in message and "deg/s" in message
    message = refused(imported(src, "-o", tmp_path / "x.parquet", "--acc-unit", "m/s^2"))
    assert "--acc-unit m/s^2" in message and "(g)" in message
    assert imported(src, "-o", tmp_path / "y.parquet", "--gyro-unit", "deg/s", "--mag-unit", "uT").exit_code == 0
    assert not (tmp_path / "x.parquet").exists()


@pytest.mark.parametrize("annotation, unit", [("(mG)", "mG"), ("(gauss)", "G"), ("(nT)", "nT"), ("[uT]", "uT"),
                                              ("(G)", "G")])
def test_header_units_spellings(annotation, unit):
    from magyro.io.csv_units import header_units
    mapping = {"t": "time [ms]", "gx": "gx (rad/s)", "gy": "gy (rad/s)", "gz": "gz (rad/s)",
               "mx": f"mag_x {annotation}", "my": f"mag_y {annotation}", "mz": f"mag_z {annotation}",
               "ax": "ax (m/s^2)", "ay": "ay (m/s^2)", "az": "az (m/s^2)"}
    said = header_units("f.csv", mapping)
    assert {k: u for k, (u, _) in said.items()} == {"time": "ms", "gyro": "rad/s", "magnetometer": unit,
                                                    "accelerometer": "m/s^2"}
    acc_g = header_units("f.csv", {"ax": "Accelerometer X (g)", "ay": "Y (g)", "az": "Z (g)"})
    assert acc_g["accelerometer"][0] == "g"
    assert header_units("f.csv", {"gx": "gx (axis 1)", "gy": "gy", "gz": "gz"}) == {}  # no unit: none read
    with pytest.raises(InputError, match="different units"):
        header_units("f.csv", {"gx": "gx (rad/s)", "gy": "gy (deg/s)", "gz": "gz (rad/s)"})


def test_header_units_of_a_written_csv_and_still_asked_without(tmp_path):
    n = 400
    t_ms = np.arange(n) * 10.0
    g = np.column_stack([np.sin(t_ms / 300), np.cos(t_ms / 400), 0.2 * np.ones(n)])
    m = np.column_stack([200 * np.cos(t_ms / 500), 200 * np.sin(t_ms / 500), -400 * np.ones(n)])
    table = {"timestamp (ms)": t_ms, **{f"gyro_{a} (deg/s)": g[:, i] for i, a in enumerate("xyz")},
             **{f"mag_{a} [mG]": m[:, i] for i, a in enumerate("xyz")}}
    src = tmp_path / "log.csv"
    pd.DataFrame(table).to_csv(src, index=False)
    s = import_csv(src, None)
    np.testing.assert_allclose(s.gyro_rad_s, np.deg2rad(g))
    assert s.mag_unit == "mG" and s.t_gyro_s[-1] == pytest.approx((n - 1) * 0.01)
    plain = tmp_path / "plain.csv"
    pd.DataFrame({"t": t_ms / 1e3, "gx": g[:, 0], "gy": g[:, 1], "gz": g[:, 2],
                  "mx": m[:, 0], "my": m[:, 1], "mz": m[:, 2]}).to_csv(plain, index=False)
    message = refused(imported(plain, "-o", tmp_path / "p.parquet"))
    assert "--gyro-unit and --mag-unit" in message and "header" in message


# --------------------------------------------------------------------------- 2: the accelerometer beside


@needs_wild
def test_sensor_logger_files_one_by_one_say_the_accelerometer_left_out(tmp_path):
    """Before: the README's two-file form read no accelerometer and said nothing, where the folder form reads
    AccelerometerUncalibrated.csv."""
    out = tmp_path / "s.parquet"
    result = imported(SIMORXB / "GyroscopeUncalibrated.csv", SIMORXB / "MagnetometerUncalibrated.csv",
                      "--preset", "sensor-logger", "-o", out)
    assert result.exit_code == 0, result.output
    text = " ".join(result.output.split())
    assert "no accelerometer: AccelerometerUncalibrated.csv beside the given files was left out" in text
    assert "give it too" in text
    assert load_session(out).t_acc_s is None
    # the third file given: read, and no such note
    result = imported(SIMORXB / "GyroscopeUncalibrated.csv", SIMORXB / "MagnetometerUncalibrated.csv",
                      SIMORXB / "AccelerometerUncalibrated.csv", "--preset", "sensor-logger", "-o", tmp_path / "a.parquet")
    assert result.exit_code == 0, result.output
    assert "left out" not in result.output and load_session(tmp_path / "a.parquet").t_acc_s is not None


# --------------------------------------------------------------------------- 4: an unreadable input file


@needs_wild
@pytest.mark.parametrize("how", ["folder", "garbage", "header"])
def test_unreadable_file_in_a_sensor_logger_folder_is_named(how, tmp_path):
    """Before: a file that cannot be read inside the export folder said 'cannot write output' (exit 1)."""
    folder = tmp_path / "export"
    shutil.copytree(SIMORXB, folder)
    bad = folder / "MagnetometerUncalibrated.csv"
    bad.unlink()
    if how == "folder":
        bad.mkdir()
    elif how == "garbage":
        bad.write_bytes(bytes(range(256)) * 8)
    else:
        bad.write_text("a,b\n1,2\n")
    message = refused(imported(folder, "-o", tmp_path / "s.parquet"))
    assert str(bad) in message
    assert not (tmp_path / "s.parquet").exists()


@needs_wild
def test_file_without_read_permission_is_an_input_error(unprivileged_folder):
    """A file of the export its reader may not read (root reads a chmod 000 file, so as root the import runs as the
    user nobody): the permission names the input, exit 2, nothing written."""
    work, env = unprivileged_folder
    folder = work / "export"
    shutil.copytree(SIMORXB, folder)
    (folder / "GyroscopeUncalibrated.csv").chmod(0)
    for path in (folder, *folder.iterdir()):
        shutil.chown(path, *owner_of(work))
    out = work / "s.parquet"
    code = ("import sys; from magyro.cli import app; sys.argv = ['magyro', 'import', 'csv', sys.argv[1], '-o', "
            "sys.argv[2]]; app()")
    run = run_unprivileged([sys.executable, "-c", code, str(folder), str(out)], cwd=work,
                           env={**env, "MAGYRO_JIT": "0"}, timeout=120)
    assert run.returncode == 2, run.stderr
    assert "GyroscopeUncalibrated.csv: the input file cannot be read (no permission" in run.stderr
    assert "cannot write output" not in run.stderr and not out.exists()


def owner_of(path: Path) -> tuple[int, int]:
    stat = path.stat()
    return stat.st_uid, stat.st_gid
