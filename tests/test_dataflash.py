"""`magyro import dataflash` (issues 38, 41): ArduPilot DataFlash logs, .bin (read through pymavlink after the
framing is checked), Mission Planner's .log text and .mat exports.

The .bin files are written here, in the DataFlash format (0xA3 0x95 TYPE, the FMT messages of type 128 and 89
bytes that lay out every other message), so a fresh clone tests the binary path and the round trip is exact.
Broken and hostile logs are refused with one message, exit 2, nothing written. The real logs of ../shared
(a real ArduCopter .bin cut at 80 KiB, the ArduPlane TestLog2.mat) are read when present.
"""
from __future__ import annotations

import struct
from pathlib import Path

import numpy as np
import pytest

from cli_clean import refusal, run_clean

WILD = Path(__file__).resolve().parents[2] / "shared" / "data" / "wild"   # ../shared beside the repository
REAL_BIN = WILD / "ardupilot" / "backend_log_80k.bin"
TESTLOG2 = WILD / "inertialnav" / "TestLog2.mat"

HEAD = b"\xa3\x95"
LAYOUTS = {  # name -> (type, format, columns): a modern log's layout, with the instance column I
    "PARM": (129, "QNf", "TimeUS,Name,Value"),
    "IMU": (130, "QBffffff", "TimeUS,I,GyrX,GyrY,GyrZ,AccX,AccY,AccZ"),
    "MAG": (131, "QBhhhhhh", "TimeUS,I,MagX,MagY,MagZ,OfsX,OfsY,OfsZ"),
    "ATT": (132, "Qfff", "TimeUS,Roll,Pitch,Yaw"),
}
STRUCTS = {"Q": "Q", "B": "B", "f": "f", "h": "h", "N": "16s"}
N_IMU, N_MAG, N_ATT = 300, 150, 150          # per instance: 3 s of IMU at 100 Hz, MAG and ATT at 50 Hz
PARAMS = {"INS_GYROFFS_X": -0.029, "INS_GYROFFS_Y": 0.086, "INS_GYROFFS_Z": -0.0125, "COMPASS_LEARN": 1.0}


def body_struct(fmt: str) -> struct.Struct:
    return struct.Struct("<" + "".join(STRUCTS[c] for c in fmt))


def fmt_message(msg_type: int, length: int, name: str, fmt: str, columns: str) -> bytes:
    return HEAD + bytes([128]) + struct.pack("<BB4s16s64s", msg_type, length, name.encode(), fmt.encode(),
                                             columns.encode())


def message(name: str, *values) -> bytes:
    msg_type, fmt, _ = LAYOUTS[name]
    return HEAD + bytes([msg_type]) + body_struct(fmt).pack(*values)


def recording(seed: int = 3) -> dict:
    """The messages of a short log, as the values written: two IMU and two MAG instances, ATT, PARM."""
    rng = np.random.default_rng(seed)
    t_imu_us = 1_000_000 + 10_000 * np.arange(N_IMU)
    t_mag_us = 1_000_000 + 20_000 * np.arange(N_MAG) + 3_000
    gyro = rng.normal(0.0, 0.5, (2, N_IMU, 3)).astype(np.float32)
    acc = (rng.normal(0.0, 0.2, (2, N_IMU, 3)) + [0.0, 0.0, -9.81]).astype(np.float32)
    mag = rng.integers(-600, 600, (2, N_MAG, 3)).astype(np.int16)
    ofs = np.repeat(rng.integers(-200, 200, (2, 1, 3)), N_MAG, axis=1).astype(np.int16)
    ofs[:, N_MAG // 2:] += np.array([5, -3, 2], dtype=np.int16)   # offsets learned in flight: they change
    att = np.column_stack([np.linspace(-30, 30, N_ATT), np.linspace(10, -10, N_ATT),
                           np.linspace(0, 350, N_ATT)]).astype(np.float32)
    return {"t_imu_us": t_imu_us, "t_mag_us": t_mag_us, "gyro": gyro, "acc": acc, "mag": mag, "ofs": ofs,
            "att": att}


def dataflash_bin(rec: dict, *, with_mag: bool = True, layouts=None, params=None) -> bytes:
    """A DataFlash log of `rec`: the FMT messages, PARM, then the messages interleaved in time."""
    layouts = layouts or LAYOUTS
    out = [fmt_message(128, 89, "FMT", "BBnNZ", "Type,Length,Name,Format,Columns")]
    for name, (msg_type, fmt, columns) in layouts.items():
        length = 3 + body_struct(fmt).size if isinstance(fmt, str) else fmt[1]
        out.append(fmt_message(msg_type, length, name, fmt if isinstance(fmt, str) else fmt[0], columns))
    out += [message("PARM", 0, k.encode(), v) for k, v in (params or PARAMS).items()]
    events = []
    for k in range(N_IMU):
        for i in range(2):
            events.append((rec["t_imu_us"][k], 0, message("IMU", int(rec["t_imu_us"][k]), i, *rec["gyro"][i, k],
                                                          *rec["acc"][i, k])))
    for k in range(N_MAG):
        if with_mag:
            for i in range(2):
                events.append((rec["t_mag_us"][k], 1, message("MAG", int(rec["t_mag_us"][k]), i,
                                                              *map(int, rec["mag"][i, k]), *map(int, rec["ofs"][i, k]))))
        events.append((rec["t_mag_us"][k], 2, message("ATT", int(rec["t_mag_us"][k]), *rec["att"][k])))
    out += [m for _, _, m in sorted(events, key=lambda e: (e[0], e[1]))]
    return b"".join(out)


@pytest.fixture(scope="module")
def rec():
    return recording()


@pytest.fixture(scope="module")
def log_bin(rec, tmp_path_factory) -> Path:
    path = tmp_path_factory.mktemp("df") / "flight.bin"
    path.write_bytes(dataflash_bin(rec))
    return path


def expected_t_s(stamps_us, origin_us) -> np.ndarray:
    return (np.asarray(stamps_us, dtype=np.float64) - origin_us) * 1e-6


# --------------------------------------------------------------------------- the binary path, exact


@pytest.mark.parametrize("imu, mag", [(0, 0), (1, 1)])
def test_a_written_bin_imports_exactly_through_the_command(rec, log_bin, tmp_path, imu, mag):
    """Every logged number comes back: the gyro and accelerometer of the chosen IMU as logged (float32), the
    magnetometer as (Mag - Ofs in force) * 0.1 uT, times from the earliest stamp."""
    from magyro.io import load_session

    out = tmp_path / "s.parquet"
    result = run_clean("import", "dataflash", log_bin, "-o", out, "--imu", imu, "--mag", mag)
    assert result.returncode == 0, result.stderr
    s = load_session(out)
    origin_us = rec["t_imu_us"][0]
    np.testing.assert_array_equal(s.t_gyro_s, expected_t_s(rec["t_imu_us"], origin_us))
    np.testing.assert_array_equal(s.gyro_rad_s, rec["gyro"][imu].astype(np.float64))
    np.testing.assert_array_equal(s.acc_m_s2, rec["acc"][imu].astype(np.float64))
    np.testing.assert_array_equal(s.t_mag_s, expected_t_s(rec["t_mag_us"], origin_us))
    raw_mG = rec["mag"][mag].astype(np.float64) - rec["ofs"][mag].astype(np.float64)
    np.testing.assert_array_equal(s.mag, raw_mG * 0.1)
    assert s.mag_unit == "uT" and s.metadata["gyro_unit"] == "rad/s" and s.metadata["acc_unit"] == "m/s^2"
    assert "2 distinct offset vector(s)" in s.metadata["dataflash_mag_raw"]
    offsets = s.metadata["dataflash_gyro_offsets_applied"]
    assert ("INS_GYROFFS_Z = -0.0125" in offsets if imu == 0 else "no INS_GYR2OFFS_X" in offsets), offsets
    assert f"IMU instance {imu}" in result.stdout


def test_att_is_the_body_frd_to_ned_reference_quaternion(rec, log_bin):
    """ATT's roll, pitch, yaw (deg) are the 3-2-1 sequence of the body -> NED rotation: R = Rz Ry Rx."""
    from scipy.spatial.transform import Rotation

    from magyro.io import import_dataflash

    s = import_dataflash(log_bin)
    roll, pitch, yaw = rec["att"].astype(np.float64).T
    expected = Rotation.from_euler("ZYX", np.column_stack([yaw, pitch, roll]), degrees=True)
    got = Rotation.from_quat(s.quat_wxyz[:, [1, 2, 3, 0]])
    assert np.all(s.quat_wxyz[:, 0] >= 0)
    assert np.degrees((got.inv() * expected).magnitude()).max() < 1e-6
    # body x (forward) at yaw 90 deg, level, points east: (0, 1, 0) in NED
    from magyro.io.dataflash import euler_321_deg_to_quat_wxyz
    q = euler_321_deg_to_quat_wxyz([0.0], [0.0], [90.0])
    np.testing.assert_allclose(Rotation.from_quat(q[:, [1, 2, 3, 0]]).apply([1.0, 0.0, 0.0])[0], [0, 1, 0], atol=1e-12)


def test_the_parameters_are_kept_and_the_offsets_come_from_them_without_ofs_columns(rec, tmp_path):
    """A log whose MAG has no Ofs columns: raw = Mag - COMPASS_OFS_*; every parameter kept in the metadata."""
    import json

    from magyro.io import import_dataflash

    layouts = dict(LAYOUTS, MAG=(131, "QBhhhhhh", "TimeUS,I,MagX,MagY,MagZ,MOX,MOY,MOZ"))
    path = tmp_path / "no-ofs.bin"
    path.write_bytes(dataflash_bin(rec, layouts=layouts, params=dict(PARAMS, COMPASS_OFS_X=10.0, COMPASS_OFS_Y=-20.0,
                                                                     COMPASS_OFS_Z=30.0)))
    s = import_dataflash(path)
    motor = rec["ofs"][0].astype(np.float64)     # the Ofs numbers, written in the MO (motor) columns here
    raw_mG = rec["mag"][0].astype(np.float64) - motor - np.array([10.0, -20.0, 30.0])
    np.testing.assert_allclose(s.mag, raw_mG * 0.1, rtol=1e-12, atol=1e-12)
    assert "COMPASS_OFS_X/COMPASS_OFS_Y/COMPASS_OFS_Z" in s.metadata["dataflash_mag_raw"]
    assert json.loads(s.metadata["dataflash_parameters"])["COMPASS_LEARN"] == 1.0


def test_the_text_log_and_the_mat_export_import_as_the_bin_does(rec, log_bin, tmp_path):
    """Mission Planner's .log (FMT lines, then NAME, values) and .mat (arrays + *_label, TimeMS, no I column:
    IMU2/MAG2 are the second instances) of the same messages give the same session."""
    import scipy.io

    from magyro.io import import_dataflash

    lines = ["FMT, 128, 89, FMT, BBnNZ, Type,Length,Name,Format,Columns"]
    for name, (msg_type, fmt, columns) in LAYOUTS.items():
        lines.append(f"FMT, {msg_type}, {3 + body_struct(fmt).size}, {name}, {fmt}, {columns}")
    lines += [f"PARM, 0, {k}, {v!r}" for k, v in PARAMS.items()]
    for k in range(N_IMU):
        for i in range(2):
            values = [float(v) for v in (*rec["gyro"][i, k], *rec["acc"][i, k])]
            lines.append(f"IMU, {rec['t_imu_us'][k]}, {i}, " + ", ".join(map(repr, values)))
    for k in range(N_MAG):
        for i in range(2):
            lines.append(f"MAG, {rec['t_mag_us'][k]}, {i}, " + ", ".join(str(int(v)) for v in
                                                                        (*rec["mag"][i, k], *rec["ofs"][i, k])))
        lines.append(f"ATT, {rec['t_mag_us'][k]}, " + ", ".join(repr(float(v)) for v in rec["att"][k]))
    text_log = tmp_path / "flight.log"
    text_log.write_text("\n".join(lines) + "\n")

    t_imu_ms, t_mag_ms = rec["t_imu_us"] // 1000, rec["t_mag_us"] // 1000   # whole ms here: exact either way
    cell = lambda names: np.array([[n] for n in names], dtype=object)  # noqa: E731
    mat = {"PARM": np.array([[k, v] for k, v in PARAMS.items()], dtype=object),
           "ATT": np.column_stack([np.arange(N_MAG), t_mag_ms, rec["att"].astype(np.float64)]),
           "ATT_label": cell(["LineNo", "TimeMS", "Roll", "Pitch", "Yaw"])}
    for i, suffix in enumerate(("", "2")):
        mat[f"IMU{suffix}"] = np.column_stack([np.arange(N_IMU), t_imu_ms, rec["gyro"][i], rec["acc"][i]])
        mat[f"IMU{suffix}_label"] = cell(["LineNo", "TimeMS", "GyrX", "GyrY", "GyrZ", "AccX", "AccY", "AccZ"])
        mat[f"MAG{suffix}"] = np.column_stack([np.arange(N_MAG), t_mag_ms, rec["mag"][i], rec["ofs"][i]])
        mat[f"MAG{suffix}_label"] = cell(["LineNo", "TimeMS", "MagX", "MagY", "MagZ", "OfsX", "OfsY", "OfsZ"])
    mat_log = tmp_path / "flight.mat"
    scipy.io.savemat(mat_log, mat)

    for imu in (0, 1):
        from_bin = import_dataflash(log_bin, imu=imu, mag=imu)
        for other in (import_dataflash(text_log, imu=imu, mag=imu), import_dataflash(mat_log, imu=imu, mag=imu)):
            np.testing.assert_array_equal(other.gyro_rad_s, from_bin.gyro_rad_s)
            np.testing.assert_array_equal(other.mag, from_bin.mag)
            np.testing.assert_array_equal(other.acc_m_s2, from_bin.acc_m_s2)
            np.testing.assert_allclose(other.t_gyro_s, from_bin.t_gyro_s, atol=1e-9)
            np.testing.assert_allclose(other.quat_wxyz, from_bin.quat_wxyz, atol=1e-12)
    assert "IMU2" in import_dataflash(mat_log, imu=1).metadata["dataflash_imu"]
    message = refusal(run_clean("import", "dataflash", mat_log, "-o", tmp_path / "x.parquet", "--imu", 2), 2)
    assert "IMU instance 2 does not exist" in message and "IMU2 (instance 1)" in message, message


# --------------------------------------------------------------------------- refusals


def hostile(rec, case: str) -> bytes:
    good = dataflash_bin(rec)
    fmt_end = 89 * (1 + len(LAYOUTS))
    if case == "truncated":
        return good[:int(len(good) * 0.3)]
    if case == "garbled":
        data = bytearray(good)
        data[len(good) // 2:len(good) // 2 + 16] = bytes(range(16))
        return bytes(data)
    if case == "fmt lies":
        return dataflash_bin(rec, layouts=dict(LAYOUTS, IMU=(130, ("QBffffff", 30), LAYOUTS["IMU"][2])))
    if case == "absurd length":
        return dataflash_bin(rec, layouts=dict(LAYOUTS, IMU=(130, ("QBffffff", 1), LAYOUTS["IMU"][2])))
    if case == "unknown format":
        data = bytearray(good)
        at = data.find(b"QBffffff")
        data[at] = ord("X")
        return bytes(data)
    if case == "columns miscounted":
        data = bytearray(good)
        at = data.find(b"TimeUS,I,GyrX")
        data[at:at + 13] = b"TimeUS;I;GyrX"
        return bytes(data)
    if case == "no mag":
        return dataflash_bin(rec, with_mag=False)
    if case == "not a log":
        return b"\x89PNG\r\n\x1a\n" + bytes(4000)
    if case == "type undefined":
        return good[:89] + good[fmt_end:]
    raise AssertionError(case)


@pytest.mark.parametrize("case, words", [
    ("truncated", ["samples; at least 100", "cut inside a message"]),
    ("garbled", ["garbled", "byte"]),
    ("fmt lies", ["30 bytes long", "needs 36", "FMT lies"]),
    ("absurd length", ["1 bytes long", "3-byte header"]),
    ("unknown format", ["'XBffffff'", "X that DataFlash does not have"]),
    ("columns miscounted", ["names", "column(s)"]),
    ("no mag", ["no MAG messages"]),
    ("not a log", ["not a DataFlash .bin"]),
    ("type undefined", ["type 129", "no FMT message before it defines"]),
])
def test_a_broken_or_hostile_bin_is_refused_with_one_message_and_nothing_written(rec, tmp_path, case, words):
    path = tmp_path / "hostile.bin"
    path.write_bytes(hostile(rec, case))
    before = path.read_bytes()
    out = tmp_path / "out.parquet"
    message = refusal(run_clean("import", "dataflash", path, "-o", out), 2)
    assert all(w in message for w in words), message
    assert not out.exists() and path.read_bytes() == before


def test_an_instance_the_log_lacks_and_an_empty_file_are_refused(log_bin, tmp_path):
    message = refusal(run_clean("import", "dataflash", log_bin, "-o", tmp_path / "o.parquet", "--mag", 3), 2)
    assert "MAG instance 3 does not exist" in message and "0, 1" in message and "--mag" in message, message
    empty = tmp_path / "empty.bin"
    empty.write_bytes(b"")
    assert "empty" in refusal(run_clean("import", "dataflash", empty, "-o", tmp_path / "o.parquet"), 2)


def test_a_damaged_text_log_is_refused_naming_the_line(tmp_path):
    path = tmp_path / "bad.log"
    path.write_text("FMT, 130, 39, IMU, QBffffff, TimeUS,I,GyrX,GyrY,GyrZ,AccX,AccY,AccZ\n"
                    "IMU, 1000, 0, 0.1, 0.2, 0.3, 0, 0, -9.8\nIMU, 2000, 0, 0.1, oops, 0.3, 0, 0, -9.8\n")
    message = refusal(run_clean("import", "dataflash", path, "-o", tmp_path / "o.parquet"), 2)
    assert "line 3" in message and "GyrY is 'oops'" in message, message


def test_without_pymavlink_a_bin_is_refused_naming_the_extra(log_bin, monkeypatch):
    import sys

    from magyro.errors import InputError
    from magyro.io import import_dataflash

    monkeypatch.setitem(sys.modules, "pymavlink", None)
    with pytest.raises(InputError, match=r"pymavlink.*magyro\[dataflash\]"):
        import_dataflash(log_bin)


# --------------------------------------------------------------------------- real logs (../shared)


@pytest.mark.skipif(not REAL_BIN.is_file(), reason=f"the real ArduCopter log fragment ({REAL_BIN}) is absent")
def test_the_real_80k_copter_bin_is_read_and_refused_as_too_short(tmp_path):
    """Real bytes (FMT, FMTU, UNIT, MULT; IMU and MAG by instance), cut mid-message at 80 KiB: read whole up to the
    cut, two IMU and two compass instances, and too short to calibrate."""
    from magyro.io.dataflash_read import read_log

    tables = read_log(REAL_BIN)
    assert tables.counts["IMU"] == 20 and tables.counts["MAG"] == 8 and tables.counts["PARM"] == 1077
    assert sorted(set(tables.messages["IMU"]["I"])) == [0, 1] and sorted(set(tables.messages["MAG"]["I"])) == [0, 1]
    assert tables.units["MAG"]["MagX"] == "mGauss" and tables.units["IMU"]["GyrX"] == "rad/s"
    assert any("cut short" in note for note in tables.notes)
    message = refusal(run_clean("import", "dataflash", REAL_BIN, "-o", tmp_path / "o.parquet"), 2)
    assert "IMU instance 0 has 10 samples" in message and "cut inside a message" in message, message


@pytest.mark.skipif(not TESTLOG2.is_file(), reason=f"the ArduPlane log TestLog2.mat ({TESTLOG2}) is absent")
def test_the_arduplane_testlog2_mat_imports_with_its_learned_offsets_removed(tmp_path):
    """TestLog2: IMU 50 Hz, MAG 10 Hz with the offsets added (learned in flight, 344 distinct), ATT; the raw
    field is 39.7-82.5 uT (the offsets' own size: |Mag| is nearly constant, |Mag - Ofs| is not)."""
    from magyro.io import load_session

    out = tmp_path / "testlog2.parquet"
    result = run_clean("import", "dataflash", TESTLOG2, "-o", out)
    assert result.returncode == 0, result.stderr
    s = load_session(out)
    assert (len(s.t_gyro_s), len(s.t_mag_s), len(s.t_quat_s)) == (30650, 6129, 30650)
    assert "344 distinct offset vector(s)" in s.metadata["dataflash_mag_raw"]
    norm_uT = np.linalg.norm(s.mag, axis=1)
    assert 39.0 < norm_uT.min() < 40.5 and 82.0 < norm_uT.max() < 83.0
    assert "INS_GYROFFS_Y = 0.086" in s.metadata["dataflash_gyro_offsets_applied"]


# --------------------------------------------------------------------------- an autopilot on the ground, a quad in yaw


def ground_then_flight(seed: int = 5):
    """A 50 Hz gyro and 10 Hz compass still for 120 s as an autopilot on the ground is (x-axis noise bursts
    of +-1.3 deg/s alternating in sign, a bias creeping 0.2 deg/s, one 3.5 uT compass spike), then turning."""
    from magyro.session import Session

    rng = np.random.default_rng(seed)
    t_s = np.arange(0.0, 150.0, 0.02)
    gyro_deg_s = rng.normal(0.0, 0.018, (len(t_s), 3)) + np.outer(t_s.clip(max=120.0) / 120.0, [0.15, 0.2, 0.12])
    for start_s in np.arange(5.0, 115.0, 10.0):                       # a burst a second long every 10 s
        burst = (t_s >= start_s) & (t_s < start_s + 1.0)
        gyro_deg_s[burst, 0] += 1.3 * (-1.0) ** np.arange(burst.sum())
    moving = t_s >= 120.0
    gyro_deg_s[moving] += 40.0 * np.sin(2 * np.pi * 0.2 * (t_s[moving, None] - 120.0) + [0.0, 1.0, 2.0])
    t_mag_s = np.arange(0.05, 150.0, 0.1)
    mag_uT = np.array([-36.4, 4.5, -46.6]) + rng.normal(0.0, 0.43, (len(t_mag_s), 3))
    mag_uT[np.searchsorted(t_mag_s, 50.0), 2] += 3.5
    turning_mag = t_mag_s >= 120.0
    mag_uT[turning_mag] += 20.0 * np.sin(2 * np.pi * 0.2 * (t_mag_s[turning_mag, None] - 120.0) + [0.5, 1.5, 2.5])
    return Session(t_gyro_s=t_s, gyro_rad_s=np.radians(gyro_deg_s), t_mag_s=t_mag_s, mag=mag_uT, mag_unit="uT")


def test_a_vibrating_warming_autopilot_on_the_ground_is_found_at_rest_until_it_moves():
    """Issue 38: the first half second's band alone ends such a rest within seconds; followed second by second
    it lasts until the turning starts (120 s)."""
    from magyro.front.differences import white_noise_std
    from magyro.front.rests import find_rests, still_prefix_s

    session = ground_then_flight()
    first_test_s = still_prefix_s(session.t_gyro_s, session.gyro_rad_s, white_noise_std(session.gyro_rad_s))
    assert first_test_s < 10.0, first_test_s          # what was found before
    (start_s, end_s), = find_rests(session).segments_s[:1]
    assert start_s == 0.05 and 118.0 < end_s <= 120.1, (start_s, end_s)


def yaw_flight(tilt_swing_deg: float, seed: int = 7):
    """A 50 Hz gyro turning in yaw (90 deg/s for 4 s of every 10) while swinging about x and y by
    `tilt_swing_deg` at 0.5-0.7 Hz and back, as a multicopter's attitude control does."""
    from magyro.session import Session

    rng = np.random.default_rng(seed)
    t_s = np.arange(0.0, 120.0, 0.02)
    w = np.zeros((len(t_s), 3))
    w[:, 2] = np.where((t_s % 10.0) < 4.0, np.radians(90.0), 0.0)
    for k, f_hz in ((0, 0.5), (1, 0.7)):   # angle A sin(2 pi f t): rate A 2 pi f cos(2 pi f t)
        w[:, k] = np.radians(tilt_swing_deg) * 2 * np.pi * f_hz * np.cos(2 * np.pi * f_hz * t_s)
    w += rng.normal(0.0, np.radians(0.05), w.shape)
    t_mag_s = np.arange(0.0, 120.0, 0.1)
    return Session(t_gyro_s=t_s, gyro_rad_s=w, t_mag_s=t_mag_s, mag=rng.normal(0.0, 1.0, (len(t_mag_s), 3)))


def test_turning_mostly_in_yaw_with_small_swings_is_named_and_large_tilts_are_not():
    from magyro.front.causes import motion_error, turning

    yaw = turning(yaw_flight(tilt_swing_deg=8.0))
    assert yaw.mostly_one_axis and not yaw.every_axis and abs(yaw.net_main_axis[2]) > 0.99, yaw
    message = str(motion_error(yaw))
    assert "mostly about one axis, its z axis" in message, message
    tumbling = turning(yaw_flight(tilt_swing_deg=60.0))
    assert not tumbling.mostly_one_axis and motion_error(tumbling) is None, tumbling


# --------------------------------------------------------------------------- InertialNav's text zips


def inertialnav_zip(path: Path, mag_scale: float, members=("IMU.txt", "MAG.txt", "ATT.txt")) -> dict:
    """IMU.txt, MAG.txt (field + offsets, in 1/mag_scale gauss) and ATT.txt of 4 s at 50 Hz, zipped."""
    import zipfile

    rng = np.random.default_rng(11)
    t_ms = 20.0 * np.arange(200)
    imu = np.column_stack([t_ms, t_ms, rng.normal(0, 0.3, (200, 3)), rng.normal(0, 0.1, (200, 3)) + [0, 0, -9.8]])
    field_G = rng.normal(0.0, 0.3, (200, 3)) + [0.2, 0.05, 0.4]
    ofs = np.tile([0.01, -0.02, 0.03], (200, 1))
    mag = np.column_stack([t_ms + 3, t_ms + 3, (field_G + ofs) * mag_scale, ofs * mag_scale])
    att = np.column_stack([t_ms, t_ms, rng.normal(0, 5, (200, 3)), np.zeros((200, 2))])
    with zipfile.ZipFile(path, "w", zipfile.ZIP_DEFLATED) as z:
        for name, table in (("IMU.txt", imu), ("MAG.txt", mag), ("ATT.txt", att)):
            if name in members:
                z.writestr(name, "\n".join(" ".join(f"{v:.7e}" for v in row) for row in table) + "\n")
    return {"gyro": imu[:, 2:5], "field_uT": field_G * 100.0}


@pytest.mark.parametrize("mag_scale, unit", [(1.0, "gauss"), (1000.0, "milligauss")])
def test_an_inertialnav_zip_reads_its_field_in_the_unit_its_size_says(tmp_path, mag_scale, unit):
    from magyro.io import import_dataflash

    path = tmp_path / "flight.zip"
    written = inertialnav_zip(path, mag_scale)
    s = import_dataflash(path)
    np.testing.assert_allclose(s.gyro_rad_s, written["gyro"], rtol=1e-6)
    np.testing.assert_allclose(s.mag, written["field_uT"], rtol=1e-5, atol=1e-4)
    assert f"read as {unit}" in s.metadata["dataflash_notes"] and s.quat_wxyz is not None


def test_an_inertialnav_zip_without_mag_txt_is_refused(tmp_path):
    path = tmp_path / "no-mag.zip"
    inertialnav_zip(path, 1000.0, members=("IMU.txt", "ATT.txt"))
    message = refusal(run_clean("import", "dataflash", path, "-o", tmp_path / "o.parquet"), 2)
    assert "no MAG.txt" in message and "IMU.txt" in message, message
