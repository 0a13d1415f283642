"""Hostile CSV and zip imports (issue 25): each is exit 0 with the right session, or exit 2 with one message naming
the problem, before any work; never a traceback, a Python warning or "nan"; inputs unchanged; nothing written
when refused; a zip bomb never reaches memory (caps on what members inflate to, checked before unpacking)."""
from __future__ import annotations

import hashlib
import json
import struct
import sys
import warnings
import zipfile
from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

from magyro.cli import app
from magyro.errors import InputError
from magyro.io import import_csv, import_preset, load_session

sys.path.insert(0, str(Path(__file__).resolve().parent))
from test_import_csv_files import (GYRO_STEP_NS, N_GYRO, N_MAG, T0_NS, gyro_rad_s, mag_ut,  # noqa: E402
                                   phyphox_export, sensor_logger_csv, sensor_logger_export)


def digest(paths) -> dict:
    return {str(p): hashlib.sha256(Path(p).read_bytes()).hexdigest() for p in paths}


def import_cli(*args) -> tuple[int, str]:
    """`magyro import csv ARGS` in this process: (exit code, output); no Python warning may be raised."""
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        result = CliRunner().invoke(app, ["import", "csv", *map(str, args)])
    text = result.output  # stdout and stderr, as a terminal shows them
    assert not caught, [str(w.message) for w in caught]
    assert "Traceback" not in text and "internal error" not in text and "nan" not in text.lower().split(), text
    return result.exit_code, " ".join(text.split())


def refused(tmp_path, *args) -> str:
    out = tmp_path / "refused.parquet"
    code, text = import_cli(*args, "-o", out)
    assert code == 2, (code, text)
    assert text.count("magyro:") == 1, text
    assert not out.exists()
    return text


# --------------------------------------------------------------------------- zips


def export_zip(tmp_path, compression=zipfile.ZIP_DEFLATED) -> Path:
    folder = sensor_logger_export(tmp_path / "rec")
    archive = tmp_path / "rec.zip"
    with zipfile.ZipFile(archive, "w", compression) as z:
        for f in sorted(folder.glob("*.csv")):
            z.write(f, f"rec/{f.name}")
    return archive


def patch_headers(archive: Path, *, flag_bits: int = 0, method: int | None = None, size: int | None = None) -> None:
    """Rewrite every member's local and central header: OR `flag_bits`, set the method and the inflated size."""
    data = bytearray(archive.read_bytes())
    for signature, flags_at, method_at, size_at in ((b"PK\x03\x04", 6, 8, 22), (b"PK\x01\x02", 8, 10, 24)):
        i = data.find(signature)
        while i >= 0:
            struct.pack_into("<H", data, i + flags_at, struct.unpack_from("<H", data, i + flags_at)[0] | flag_bits)
            if method is not None:
                struct.pack_into("<H", data, i + method_at, method)
            if size is not None:
                struct.pack_into("<I", data, i + size_at, size)
            i = data.find(signature, i + 4)
    archive.write_bytes(bytes(data))


@pytest.mark.parametrize("case, message", [
    ("encrypted", "member rec/GyroscopeUncalibrated.csv is encrypted; unzip it with its password"),
    ("deflate64", "member rec/GyroscopeUncalibrated.csv is compressed with Deflate64, which magyro cannot read"),
    ("bad_crc", "member rec/GyroscopeUncalibrated.csv is damaged (its data fail their CRC-32 check)"),
    ("declared_3_GiB", "member rec/GyroscopeUncalibrated.csv inflates to 3072 MiB, beyond the 128 MiB cap on one "
                       "CSV member"),
    ("truncated", "rec.zip: not a readable zip (no zip directory at its end: cut short, or not a zip)"),
])
def test_unreadable_zips_are_one_message_naming_the_member_and_the_cause(case, message, tmp_path):
    archive = export_zip(tmp_path, zipfile.ZIP_STORED if case == "bad_crc" else zipfile.ZIP_DEFLATED)
    if case == "encrypted":
        patch_headers(archive, flag_bits=0x1)
    elif case == "deflate64":
        patch_headers(archive, method=9)
    elif case == "declared_3_GiB":
        patch_headers(archive, size=3 * 2**30)
    elif case == "bad_crc":
        data = bytearray(archive.read_bytes())
        data[data.find(b"time,seconds_elapsed") + 300] ^= 0x01  # inside the first member's (gyro's) data
        archive.write_bytes(bytes(data))
    elif case == "truncated":
        archive.write_bytes(archive.read_bytes()[:5000])
    before = digest([archive])
    text = refused(tmp_path, archive, "--preset", "sensor-logger")
    assert message in text, text
    assert digest([archive]) == before


def test_zip_members_past_the_caps_are_refused_naming_the_cap(tmp_path, monkeypatch):
    """The caps (here made small) hold for one member and for all members; what stays within them imports."""
    import magyro.io.csv_zip as csv_zip

    archive = export_zip(tmp_path)
    sizes = {i.filename: i.file_size for i in zipfile.ZipFile(archive).infolist() if "Metadata" not in i.filename}
    monkeypatch.setattr(csv_zip, "MAX_MEMBER_BYTES", 2**14)
    text = refused(tmp_path, archive, "--preset", "sensor-logger")
    assert (f"member rec/GyroscopeUncalibrated.csv inflates to {sizes['rec/GyroscopeUncalibrated.csv'] / 2**20:.3f} "
            f"MiB, beyond the 0.016 MiB cap on one CSV member") in text, text
    monkeypatch.setattr(csv_zip, "MAX_MEMBER_BYTES", max(sizes.values()))
    monkeypatch.setattr(csv_zip, "MAX_TOTAL_BYTES", 2**15)
    assert sum(sizes.values()) > 2**15
    text = refused(tmp_path, archive, "--preset", "sensor-logger")
    assert "its CSV members inflate to 0.038 MiB, beyond the 0.031 MiB cap on one zip" in text, text
    monkeypatch.setattr(csv_zip, "MAX_TOTAL_BYTES", sum(sizes.values()))
    np.testing.assert_array_equal(import_preset([archive], "sensor-logger").gyro_rad_s, gyro_rad_s(N_GYRO))


def test_a_zip_with_a_lying_size_never_inflates_past_the_cap(tmp_path, monkeypatch):
    """A member whose header declares less than it inflates to: refused, naming the member, never read whole."""
    import magyro.io.csv_zip as csv_zip

    monkeypatch.setattr(csv_zip, "MAX_MEMBER_BYTES", 2**20)
    archive = tmp_path / "bomb.zip"
    line = f"{T0_NS},0.1,0.0,0.0,0.0\n".encode()
    with zipfile.ZipFile(archive, "w", zipfile.ZIP_DEFLATED) as z:
        with z.open("GyroscopeUncalibrated.csv", "w") as w:
            w.write(b"time,seconds_elapsed,z,y,x\n" + line * (3 * 2**20 // len(line)))
    patch_headers(archive, size=1000)
    text = refused(tmp_path, archive, "--preset", "sensor-logger")
    assert "member GyroscopeUncalibrated.csv" in text and ("damaged" in text or "cap" in text), text


def test_members_whose_names_no_file_system_holds_are_unpacked_under_plain_names(tmp_path):
    """A 300-character member name (and one going up with ../) is read, not 'cannot write output'."""
    folder, _, _ = phyphox_export(tmp_path / "exp")
    archive = tmp_path / "exp.zip"
    with zipfile.ZipFile(archive, "w") as z:
        z.write(folder / "Gyroscope.csv", "G" * 300 + ".csv")
        z.write(folder / "Magnetometer.csv", "../../Magnetometer.csv")
    s = import_preset([archive], "phyphox")
    np.testing.assert_allclose(s.gyro_rad_s, gyro_rad_s(N_GYRO), rtol=1e-9)
    np.testing.assert_allclose(s.mag, mag_ut(N_MAG), rtol=1e-9)
    assert json.loads(s.metadata["sensor_files"])["magnetometer"] == f"{archive}:../../Magnetometer.csv"


def test_only_the_apps_files_are_unpacked_from_its_zip(tmp_path, monkeypatch):
    """A Sensor Logger zip's other CSVs (location, audio levels, ...) are not unpacked: they count against no cap."""
    import magyro.io.csv_zip as csv_zip

    archive = export_zip(tmp_path)
    with zipfile.ZipFile(archive, "a", zipfile.ZIP_DEFLATED) as z:
        z.writestr("rec/Location.csv", "time,seconds_elapsed,latitude\n" + "1,2,3\n" * 200_000)
    wanted = {i.filename: i.file_size for i in zipfile.ZipFile(archive).infolist() if "Location" not in i.filename}
    monkeypatch.setattr(csv_zip, "MAX_TOTAL_BYTES", sum(wanted.values()))
    assert len(import_preset([archive], "sensor-logger").t_gyro_s) == N_GYRO


# --------------------------------------------------------------------------- options refused up front


@pytest.mark.parametrize("args, message", [
    (["--skip-rows", "100000000000000000000"], "--skip-rows 100000000000000000000 is more lines than can be skipped"),
    (["--header-line", "2000000"], "--header-line 2000000 is more lines than can be skipped (at most 1000000"),
    (["--delimiter", ";;"], "--delimiter ';;': a delimiter is one character"),
    (["--delimiter", "."], "--delimiter '.': a delimiter is one character"),
    (["--delimiter", '"'], "a delimiter is one character"),
])
@pytest.mark.parametrize("preset", [True, False], ids=["preset", "plain"])
def test_unusable_read_options_are_refused_before_reading(args, message, preset, tmp_path):
    folder = sensor_logger_export(tmp_path / "rec")
    files = [folder / "GyroscopeUncalibrated.csv", folder / "MagnetometerUncalibrated.csv"]
    before = digest(files)
    given = ["--preset", "sensor-logger"] if preset else ["--gyro-unit", "rad/s", "--mag-unit", "uT", "--time-unit",
                                                          "ns", "-m", "t=GyroscopeUncalibrated.csv:time"]
    text = refused(tmp_path, *files, *given, *args)
    assert message in text, text
    assert digest(files) == before


def test_python_api_refuses_the_same_options():
    with pytest.raises(InputError, match="more lines than can be skipped"):
        import_csv("never-read.csv", None, "rad/s", "uT", skip_rows=10**20)
    with pytest.raises(InputError, match="a delimiter is one character"):
        import_preset(["never-read.csv"], "sensor-logger", delimiter="ab")


def test_named_delimiters_are_accepted(tmp_path):
    src = tmp_path / "log.tsv"
    g, m = gyro_rad_s(N_GYRO), mag_ut(N_GYRO)
    src.write_text("t\tgx\tgy\tgz\tmx\tmy\tmz\n" + "".join(
        "\t".join(repr(float(v)) for v in (0.01 * k, *g[k], *m[k])) + "\n" for k in range(N_GYRO)))
    for name in ("tab", "\\t", "\t"):
        np.testing.assert_array_equal(import_csv(src, None, "rad/s", "uT", delimiter=name).gyro_rad_s, g)


# --------------------------------------------------------------------------- a byte-order mark


def with_bom(path: Path) -> Path:
    path.write_bytes(b"\xef\xbb\xbf" + path.read_bytes())
    return path


def test_sensor_logger_and_phyphox_files_with_a_bom_import_as_without(tmp_path):
    plain = import_preset([sensor_logger_export(tmp_path / "a")], "sensor-logger")
    folder = sensor_logger_export(tmp_path / "b")
    for f in folder.glob("*.csv"):
        with_bom(f)
    code, text = import_cli(folder, "-o", tmp_path / "b.parquet")  # recognised through the BOM, too
    assert code == 0, text
    bom = load_session(tmp_path / "b.parquet")
    np.testing.assert_array_equal(bom.gyro_rad_s, plain.gyro_rad_s)
    np.testing.assert_array_equal(bom.t_mag_s, plain.t_mag_s)

    phy, _, _ = phyphox_export(tmp_path / "p")
    plain = import_preset([phy], "phyphox")
    for f in phy.glob("*.csv"):
        with_bom(f)
    bom = import_preset([phy], "phyphox")
    np.testing.assert_array_equal(bom.mag, plain.mag)


def test_a_one_file_csv_with_a_bom_keeps_its_guessed_columns(tmp_path):
    src = tmp_path / "log.csv"
    g, m = gyro_rad_s(N_GYRO), mag_ut(N_GYRO)
    src.write_text("\ufefftime,gyro_x,gyro_y,gyro_z,mag_x,mag_y,mag_z\n" + "".join(
        ",".join(repr(float(v)) for v in (0.01 * k, *g[k], *m[k])) + "\n" for k in range(N_GYRO)), encoding="utf-8")
    s = import_csv(src, None, "rad/s", "uT")
    assert s.metadata["column_map"].startswith('{"t": "time"')
    np.testing.assert_array_equal(s.mag, m)


# --------------------------------------------------------------------------- values no sensor reads


def one_file_csv(path: Path, bad_rows=(), value="1e300", column=1) -> Path:
    g, m = gyro_rad_s(N_GYRO), mag_ut(N_GYRO)
    rows = []
    for k in range(N_GYRO):
        cells = [repr(float(v)) for v in (0.01 * k, *g[k], *m[k])]
        if k in bad_rows:
            cells[column] = value
        rows.append(",".join(cells))
    path.write_text("t,gx,gy,gz,mx,my,mz\n" + "\n".join(rows) + "\n")
    return path


@pytest.mark.parametrize("value, column, rows, message", [
    ("1e300", 1, range(100, 300), "row 100, column gx holds 1e+300, which no sensor reads (200 row(s)"),
    ("1e300", 1, range(N_GYRO), "row 0, column gx holds 1e+300, which no sensor reads (300 row(s)"),
    ("inf", 3, [5], "row 5, column gz holds inf, which no sensor reads (1 row(s)"),
    ("-1e12", 6, [7, 9], "row 7, column mz holds -1e+12, which no sensor reads (2 row(s)"),
    ("1e300", 0, [4], "row 4, column t holds 1e+300, which no sensor reads"),
    ("18446744073709551000", 0, range(N_GYRO), "row 0, column t holds 1.84467e+19, which no sensor reads"),
])
def test_absurd_readings_are_refused_by_row_without_warnings(value, column, rows, message, tmp_path):
    src = one_file_csv(tmp_path / "log.csv", set(rows), value, column)
    before = digest([src])
    text = refused(tmp_path, src, "--gyro-unit", "deg/s", "--mag-unit", "uT")
    assert message in text, text
    assert "percentile" not in text
    assert digest([src]) == before


def test_absurd_readings_in_one_sensor_file_are_refused_too(tmp_path):
    folder = sensor_logger_export(tmp_path / "rec")
    gyro = gyro_rad_s(N_GYRO)
    gyro[50] = 1e300
    sensor_logger_csv(folder / "GyroscopeUncalibrated.csv", T0_NS, GYRO_STEP_NS, gyro)
    text = refused(tmp_path, folder, "--preset", "sensor-logger")
    assert "GyroscopeUncalibrated.csv: row 50, column x holds 1e+300" in text, text
