"""Tests for `magyro.io.ulog` and `magyro import ulog`, on real PX4 logs.

`data/px4-sample-appended-multiple.ulg` (shipped, BSD 3-Clause, data/PROVENANCE.md) has the older
layout: gyro, magnetometer and accelerometer all in `sensor_combined`; the board lies still. `sample_log_small.ulg` in
../shared/data/ulog (newer layout: sensor_gyro/sensor_mag at 1 Hz, sensor_combined,
vehicle_magnetometer; sensor_accel at 1 Hz too; the board still on the ground) is used when present. The expected values are read here with pyulog
directly, independently of the importer.
"""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("pyulog")
from pyulog import ULog  # noqa: E402

from magyro.errors import InputError  # noqa: E402
from magyro.front.rests import find_rests  # noqa: E402
from magyro.io import MIN_SAMPLES, convert_ulog, import_ulog, load_session  # noqa: E402
from magyro.io.ulog import _choose_optional, _stream, parse_topics  # noqa: E402

REPO = Path(__file__).resolve().parents[1]
SHIPPED = REPO / "data" / "px4-sample-appended-multiple.ulg"
SHARED = Path(__file__).resolve().parents[2] / "shared" / "data" / "ulog"
SMALL = SHARED / "sample_log_small.ulg"

STANDARD_GRAVITY = 9.80665
needs_small = pytest.mark.skipif(not SMALL.is_file(), reason=f"sample_log_small.ulg not found in {SHARED}")


def fresh(stamps: np.ndarray, values: np.ndarray):
    """Rows whose stamp differs from the previous row's (the log's held samples dropped)."""
    keep = np.concatenate([[True], np.diff(stamps) != 0])
    return stamps[keep], values[keep]


def expected_old_layout(path: Path):
    """(gyro stamps, gyro, mag stamps, mag) of sensor_combined, stamps in us, read with pyulog."""
    d = ULog(str(path)).get_dataset("sensor_combined").data
    ts = d["timestamp"].astype(np.int64)
    gyro = np.column_stack([d[f"gyro_rad[{k}]"] for k in range(3)]).astype(np.float64)
    mag_ts = ts + d["magnetometer_timestamp_relative"].astype(np.int64)
    mag = np.column_stack([d[f"magnetometer_ga[{k}]"] for k in range(3)]).astype(np.float64)
    return (ts, gyro) + fresh(mag_ts, mag)


def expected_acc_combined(path: Path):
    """(stamps in us, accelerometer in m/s^2) of sensor_combined read with pyulog: stamped timestamp +
    accelerometer_timestamp_relative (0 in both logs: the gyro's sample)."""
    d = ULog(str(path), ["sensor_combined"]).get_dataset("sensor_combined").data
    ts = d["timestamp"].astype(np.int64) + d["accelerometer_timestamp_relative"].astype(np.int64)
    return ts, np.column_stack([d[f"accelerometer_m_s2[{k}]"] for k in range(3)]).astype(np.float64)


def norm_at_rests(s) -> float:
    """|mean accelerometer| over the rests `find_rests` finds (at least one second of them)."""
    rests = find_rests(s)
    assert rests.seconds >= 1.0
    at = np.any([(s.t_acc_s >= a) & (s.t_acc_s <= b) for a, b in rests.segments_s], axis=0)
    return float(np.linalg.norm(s.acc_m_s2[at].mean(axis=0)))


def assert_session_is(s, ts_g, gyro, ts_m, mag):
    """Times and values equal the log's to the last bit (t = (stamp - first stamp) / 1e6)."""
    origin = min(ts_g[0], ts_m[0])
    np.testing.assert_array_equal(s.t_gyro_s, (ts_g - origin) / 1e6)
    np.testing.assert_array_equal(s.t_mag_s, (ts_m - origin) / 1e6)
    np.testing.assert_array_equal(s.gyro_rad_s, gyro)
    np.testing.assert_array_equal(s.mag, mag)
    assert min(s.t_gyro_s[0], s.t_mag_s[0]) == 0.0


@pytest.fixture(scope="module")
def shipped():
    return import_ulog(SHIPPED)


def test_old_layout_equals_pyulog_to_the_last_bit(shipped):
    ts_g, gyro, ts_m, mag = expected_old_layout(SHIPPED)
    assert len(ts_m) < len(ts_g) / 3  # the magnetometer is held between its samples in sensor_combined
    assert_session_is(shipped, ts_g, gyro, ts_m, mag)
    assert shipped.mag_unit == "G"
    assert shipped.metadata["ulog_mag_time_field"] == "timestamp + magnetometer_timestamp_relative"


def test_old_layout_accelerometer_in_m_s2_on_the_gyro_stamps(shipped):
    ts_a, acc = expected_acc_combined(SHIPPED)
    origin = int(shipped.metadata["ulog_time_origin_us"].split()[0])
    np.testing.assert_array_equal(shipped.t_acc_s, (ts_a - origin) / 1e6)
    np.testing.assert_array_equal(shipped.t_acc_s, shipped.t_gyro_s)  # sampled with the gyro, in one message
    np.testing.assert_array_equal(shipped.acc_m_s2, acc)
    # at its rest (the first 1.6 s; the board is nudged after) |a| is gravity in m/s^2, not g: 9.94, PX4's own
    # calibration leaves it 1.4 % high
    assert abs(norm_at_rests(shipped) / STANDARD_GRAVITY - 1) < 0.02
    m = shipped.metadata
    assert m["acc_unit"] == "m/s^2" and m["ulog_acc_topic"] == "sensor_combined"
    assert m["ulog_acc_fields"] == "accelerometer_m_s2[0] accelerometer_m_s2[1] accelerometer_m_s2[2]"
    assert m["ulog_acc_time_field"] == "timestamp + accelerometer_timestamp_relative"
    assert m["ulog_acc_clipping"] == "not logged (sensor_combined has no accelerometer_clipping)"
    assert "accelerometer sensor_combined" in m["imported_from"]


def test_metadata_carries_the_provenance(shipped):
    m = shipped.metadata
    assert m["source"] == str(SHIPPED) and m["ulog_file"] == SHIPPED.name
    assert m["ulog_gyro_topic"] == m["ulog_mag_topic"] == "sensor_combined" and m["ulog_instance"] == "0"
    assert m["ulog_gyro_fields"] == "gyro_rad[0] gyro_rad[1] gyro_rad[2]"
    assert m["ulog_mag_fields"] == "magnetometer_ga[0] magnetometer_ga[1] magnetometer_ga[2]"
    assert m["gyro_unit"] == "rad/s" and m["mag_unit"] == "G"
    assert "already calibrated" in m["px4_calibration"]
    assert int(m["ulog_time_origin_us"].split()[0]) == 12243661
    assert "CAL_GYRO0_XOFF" in json.loads(m["px4_calibration_parameters"])
    assert m["px4_board"] == "PX4FMU_V4PRO"


def test_written_session_loads_back_the_same(shipped, tmp_path):
    out = tmp_path / "s.parquet"
    before = SHIPPED.read_bytes()
    written = convert_ulog(SHIPPED, out)
    assert SHIPPED.read_bytes() == before
    back = load_session(out)
    for name in ("t_gyro_s", "gyro_rad_s", "t_mag_s", "mag", "t_acc_s", "acc_m_s2"):
        np.testing.assert_array_equal(getattr(back, name), getattr(shipped, name))
        np.testing.assert_array_equal(getattr(written, name), getattr(shipped, name))
    assert back.mag_unit == "G"
    for key in ("ulog_file", "ulog_gyro_topic", "ulog_mag_topic", "ulog_instance", "px4_calibration",
                "ulog_time_origin_us", "acc_unit", "ulog_acc_topic"):
        assert back.metadata[key] == shipped.metadata[key]


@needs_small
def test_new_layout_falls_back_from_1_hz_raw_topics_and_equals_pyulog():
    s = import_ulog(SMALL)
    u = ULog(str(SMALL))
    c = u.get_dataset("sensor_combined").data
    v = u.get_dataset("vehicle_magnetometer").data
    ts_g = c["timestamp"].astype(np.int64)
    gyro = np.column_stack([c[f"gyro_rad[{k}]"] for k in range(3)]).astype(np.float64)
    ts_m, mag = fresh(v["timestamp"].astype(np.int64),
                      np.column_stack([v[f"magnetometer_ga[{k}]"] for k in range(3)]).astype(np.float64))
    assert_session_is(s, ts_g, gyro, ts_m, mag)
    m = s.metadata
    assert (m["ulog_gyro_topic"], m["ulog_mag_topic"]) == ("sensor_combined", "vehicle_magnetometer")
    assert "sensor_gyro instance 0 has only 6 fresh gyro samples" in m["ulog_topic_choice"]
    forced = import_ulog(SMALL, topics="sensor_combined,vehicle_magnetometer")
    np.testing.assert_array_equal(forced.mag, s.mag)


@needs_small
def test_new_layout_accelerometer_falls_back_from_1_hz_sensor_accel_to_sensor_combined():
    s = import_ulog(SMALL)
    ts_a, acc = expected_acc_combined(SMALL)
    origin = int(s.metadata["ulog_time_origin_us"].split()[0])
    np.testing.assert_array_equal(s.t_acc_s, (ts_a - origin) / 1e6)
    np.testing.assert_array_equal(s.acc_m_s2, acc)
    np.testing.assert_array_equal(s.t_acc_s, s.t_gyro_s)
    m = s.metadata
    assert m["ulog_acc_topic"] == "sensor_combined" and m["acc_unit"] == "m/s^2"
    assert "sensor_accel instance 0 has only 6 fresh accelerometer samples" in m["ulog_topic_choice"]
    assert m["ulog_acc_clipping"] == "0 of 1298 samples flagged clipped by PX4 (accelerometer_clipping)"
    # still on the ground all 6.5 s: gravity in m/s^2 (sensor_combined reads 9.62, 1.9 % low; the raw sensor_accel
    # instances 0.4-1.2 % low)
    assert find_rests(s).segments_s == [(s.t_gyro_s[0], s.t_gyro_s[-1])]
    assert abs(norm_at_rests(s) / STANDARD_GRAVITY - 1) < 0.025
    assert "CAL_ACC0_XOFF" in json.loads(m["px4_calibration_parameters"])


@needs_small
def test_sensor_accel_uses_its_own_sample_stamps_and_clip_counters():
    data = ULog(str(SMALL), ["sensor_accel"]).get_dataset("sensor_accel", 2).data
    stream = _stream(data, "sensor_accel", "acc")
    assert stream["time_field"] == "timestamp_sample" and stream["fields"] == ("x", "y", "z")
    np.testing.assert_array_equal(stream["stamps_us"], data["timestamp_sample"].astype(np.int64))
    np.testing.assert_array_equal(stream["values"], np.column_stack([data[k] for k in "xyz"]).astype(np.float64))
    assert abs(np.median(np.linalg.norm(stream["values"], axis=1)) / STANDARD_GRAVITY - 1) < 0.02
    assert stream["clipping"] == "0 of 6 samples flagged clipped by PX4 (clip_counter[0..2])"
    data = dict(data)
    data["clip_counter[1]"] = np.array([0, 2, 0, 0, 1, 0], dtype=np.uint8)
    assert _stream(data, "sensor_accel", "acc")["clipping"].startswith("2 of 6 samples flagged clipped")


def test_a_log_without_an_accelerometer_imports_without_one():
    gyro_only = {("sensor_combined", 0): {"timestamp": np.arange(200, dtype=np.uint64),
                                          "gyro_rad[0]": np.zeros(200, np.float32)}}
    stream, why = _choose_optional(SHIPPED, gyro_only, "acc", ("sensor_accel", "sensor_combined"), 0)
    assert stream is None and why == ["no accelerometer imported (no accelerometer topic; the log has none of "
                                      "sensor_accel, sensor_combined with accelerometer fields)"]


@needs_small
def test_raw_sensor_topics_use_their_own_sample_stamps():
    data = ULog(str(SMALL), ["sensor_gyro"]).get_dataset("sensor_gyro", 1).data
    stream = _stream(data, "sensor_gyro", "gyro")
    assert stream["time_field"] == "timestamp_sample"
    np.testing.assert_array_equal(stream["stamps_us"], data["timestamp_sample"].astype(np.int64))
    np.testing.assert_array_equal(stream["values"][:, 2], data["z"].astype(np.float64))


def test_repeated_and_backward_stamps_are_not_fresh():
    data = {"timestamp": np.array([10, 20, 20, 30, 25, 40], dtype=np.uint64),
            "timestamp_sample": np.array([5, 15, 15, 25, 22, 35], dtype=np.uint64),
            "x": np.arange(6, dtype=np.float32), "y": np.zeros(6, np.float32), "z": np.zeros(6, np.float32)}
    stream = _stream(data, "sensor_mag", "mag")
    np.testing.assert_array_equal(stream["stamps_us"], [5, 15, 25, 35])
    np.testing.assert_array_equal(stream["values"][:, 0], [0, 1, 3, 5])
    assert stream["dropped"] == 2


# --------------------------------------------------------------------------- refusals


def refused(*args, **kwargs) -> str:
    with pytest.raises(InputError) as info:
        import_ulog(*args, **kwargs)
    message = str(info.value)
    assert "\n" not in message
    return message


def test_refuses_a_file_that_is_not_a_ulog(tmp_path):
    fake = tmp_path / "fake.ulg"
    fake.write_text("t,gx,gy,gz\n0,0,0,0\n")
    assert "not a ULog file" in refused(fake)
    assert "no such file" in refused(tmp_path / "absent.ulg")


def test_refuses_a_missing_instance_listing_those_that_exist():
    message = refused(SHIPPED, instance=1)
    assert "instance 1 does not exist" in message and "sensor_combined: 0" in message


@needs_small
def test_refuses_missing_instances_and_too_slow_topics_on_the_new_layout():
    message = refused(SMALL, instance=5)
    assert "instance 5 does not exist" in message and "sensor_gyro: 0, 1, 2" in message
    message = refused(SMALL, topics=("sensor_gyro", "sensor_mag"))
    assert "only 6 fresh gyro samples" in message and str(MIN_SAMPLES) in message


def test_refuses_a_log_without_gyro_or_magnetometer(tmp_path):
    cut_short = tmp_path / "cut.ulg"
    cut_short.write_bytes(SHIPPED.read_bytes()[:20000])  # header and definitions, no data
    assert "no gyro topic" in refused(cut_short)
    message = refused(SHIPPED, topics=("sensor_combined", "vehicle_magnetometer"))
    assert "no magnetometer topic" in message and "vehicle_magnetometer" in message


def test_refuses_bad_topic_names_and_an_output_that_is_the_log(tmp_path):
    with pytest.raises(InputError, match="gyro topic"):
        parse_topics("sensor_accel,sensor_mag")
    with pytest.raises(InputError):
        convert_ulog(SHIPPED, SHIPPED)
    assert SHIPPED.stat().st_size == 486737


# --------------------------------------------------------------------------- the command


def test_cli_import_ulog(run_magyro, assert_plain_failure, tmp_path):
    out = tmp_path / "s.parquet"
    done = run_magyro("import", "ulog", SHIPPED, "-o", out)
    assert done.returncode == 0, done.stderr
    assert "2373 gyro samples" in done.stdout and "444 magnetometer samples" in done.stdout
    assert "2373 accelerometer samples (m/s^2) from sensor_combined" in done.stdout
    assert "sensor_combined" in done.stdout and out.is_file()
    fake = tmp_path / "fake.ulg"
    fake.write_text("not a log\n")
    message = assert_plain_failure(run_magyro("import", "ulog", fake, "-o", tmp_path / "f.parquet"), 2)
    assert "not a ULog file" in message
    message = assert_plain_failure(run_magyro("import", "ulog", SHIPPED, "-o", tmp_path / "g.parquet",
                                              "--instance", "2"), 2)
    assert "instance 2 does not exist" in message
    assert not (tmp_path / "f.parquet").exists() and not (tmp_path / "g.parquet").exists()
