"""Tests for `magyro.io.rosbag` and `magyro import rosbag`, on real bags written here with rosbags.

The bags (ROS1 with `rosbags.rosbag1.Writer`, ROS2 with `rosbags.rosbag2.Writer`, messages
serialised with the typestores) carry the gyro, accelerometer and magnetometer samples of the
shipped BROAD trial `data/broad-02.parquet`: gyro rad/s and acceleration m/s^2 as they are,
the magnetometer uT / 1e6 in tesla, header stamps round(t * 1e9) ns. The bags' receive times
are deliberately not the stamps, so a reader of the wrong clock fails.
"""
from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("rosbags")
from rosbags.rosbag1 import Writer as Writer1  # noqa: E402
from rosbags.rosbag2 import Writer as Writer2  # noqa: E402
from rosbags.typesys import Stores, get_typestore  # noqa: E402

import magyro  # noqa: E402
from magyro.errors import InputError  # noqa: E402
from magyro.io import convert_rosbag, import_rosbag, load_session  # noqa: E402

REPO = Path(__file__).resolve().parents[1]
TRIAL = REPO / "data" / "broad-02.parquet"
IMU, MAG = "sensor_msgs/msg/Imu", "sensor_msgs/msg/MagneticField"
OLD_MAG = "geometry_msgs/msg/Vector3Stamped"   # older drivers' magnetometer (gauss, or a unit vector)
PART_S = 40.0  # every sample of the trial's first 40 s in the small bags


@pytest.fixture(scope="module")
def trial():
    return load_session(TRIAL)


def stamps_ns(t_s: np.ndarray) -> np.ndarray:
    return np.round(np.asarray(t_s) * 1e9).astype(np.int64)


def write_bag(path: Path, session, n: int | None = None, ros: int = 2, imu_topics=("/imu",), mag_topics=("/mag",),
              stamp_ns=None, acc_absent: bool = False, mag_as: str = "tesla") -> Path:
    """A bag with the session's first n samples on every topic given (imu_topics may be empty); the magnetometer
    as MagneticField in tesla (or unit vectors with `mag_as` "unit-tesla"), or (`mag_as` "gauss" or "unit") as an
    older driver's Vector3Stamped."""
    n = len(session.t_gyro_s) if n is None else n
    assert np.array_equal(session.t_gyro_s, session.t_mag_s) and np.array_equal(session.t_gyro_s, session.t_acc_s)
    stamps = stamps_ns(session.t_gyro_s[:n]) if stamp_ns is None else np.asarray(stamp_ns, dtype=np.int64)
    store = get_typestore(Stores.ROS1_NOETIC if ros == 1 else Stores.ROS2_HUMBLE)
    T = store.types
    Header, Time, Vector3 = T["std_msgs/msg/Header"], T["builtin_interfaces/msg/Time"], T["geometry_msgs/msg/Vector3"]
    Quaternion, Imu, MagneticField = T["geometry_msgs/msg/Quaternion"], T[IMU], T[MAG]
    no_orientation = np.array([-1.0] + [0.0] * 8)
    zero = np.zeros(9)
    acc_cov = no_orientation if acc_absent else zero

    def header(k, ns):
        fields = {"stamp": Time(sec=int(ns // 10**9), nanosec=int(ns % 10**9)), "frame_id": "imu_link"}
        return Header(seq=k, **fields) if ros == 1 else Header(**fields)

    def vector(v):
        return Vector3(x=float(v[0]), y=float(v[1]), z=float(v[2]))

    serialize = store.serialize_ros1 if ros == 1 else store.serialize_cdr
    writer = Writer1(path) if ros == 1 else Writer2(path, version=9)
    with writer:
        imu_conns = [writer.add_connection(t, IMU, typestore=store) for t in imu_topics]
        mag_type = MAG if mag_as in ("tesla", "unit-tesla") else OLD_MAG
        mag_conns = [writer.add_connection(t, mag_type, typestore=store) for t in mag_topics]
        for k in range(n):
            ns = int(stamps[k])
            received = 10**18 + 1000 * k  # the bag's clock: not the header stamps
            if imu_conns:
                imu = Imu(header=header(k, ns), orientation=Quaternion(x=0.0, y=0.0, z=0.0, w=1.0),
                          orientation_covariance=no_orientation, angular_velocity=vector(session.gyro_rad_s[k]),
                          angular_velocity_covariance=zero, linear_acceleration=vector(session.acc_m_s2[k]),
                          linear_acceleration_covariance=acc_cov)
                data = serialize(imu, IMU)
                for c in imu_conns:
                    writer.write(c, received, data)
            if mag_conns:
                if mag_as in ("tesla", "unit-tesla"):
                    b = session.mag[k] / (1e6 if mag_as == "tesla" else np.linalg.norm(session.mag[k]))
                    mag = MagneticField(header=header(k, ns), magnetic_field=vector(b),
                                        magnetic_field_covariance=zero)
                else:
                    m = session.mag[k] / (100.0 if mag_as == "gauss" else np.linalg.norm(session.mag[k]))
                    mag = T[OLD_MAG](header=header(k, ns), vector=vector(m))
                data = serialize(mag, mag_type)
                for c in mag_conns:
                    writer.write(c, received + 1, data)
    return path


def part(trial) -> int:
    return int(np.searchsorted(trial.t_gyro_s, trial.t_gyro_s[0] + PART_S))


@pytest.fixture(scope="module")
def bags(trial, tmp_path_factory):
    d = tmp_path_factory.mktemp("bags")
    n = part(trial)
    return {"ROS1": write_bag(d / "part.bag", trial, n, ros=1), "ROS2": write_bag(d / "part_ros2", trial, n, ros=2)}


def assert_equals_trial(s, trial, n):
    """Times and values equal the bag's to the last bit, after the importer's own arithmetic."""
    ns = stamps_ns(trial.t_gyro_s[:n])
    # the stamps are the trial's times to the nanosecond
    assert np.all(np.abs(ns / 1e9 - trial.t_gyro_s[:n]) <= 0.5e-9 + 1e-15 * trial.t_gyro_s[:n])
    expected_t = (ns - ns[0]) / 1e9
    assert expected_t[0] == 0.0
    np.testing.assert_array_equal(s.t_gyro_s, expected_t)
    np.testing.assert_array_equal(s.t_mag_s, expected_t)
    np.testing.assert_array_equal(s.t_acc_s, expected_t)
    np.testing.assert_array_equal(s.gyro_rad_s, trial.gyro_rad_s[:n])  # float64 as is
    np.testing.assert_array_equal(s.acc_m_s2, trial.acc_m_s2[:n])
    np.testing.assert_array_equal(s.mag, (trial.mag[:n] / 1e6) * 1e6)  # uT -> T in the bag, T -> uT back
    np.testing.assert_allclose(s.mag, trial.mag[:n], rtol=4e-16, atol=0)


@pytest.mark.parametrize("ros", ["ROS1", "ROS2"])
def test_bag_equals_the_trial_to_the_last_bit(bags, trial, ros):
    s = import_rosbag(bags[ros])
    assert_equals_trial(s, trial, part(trial))
    assert s.mag_unit == "uT"
    m = s.metadata
    assert m["source"] == str(bags[ros]) and m["rosbag_file"] == bags[ros].name
    assert m["rosbag_ros_version"] == ros
    assert (m["rosbag_imu_topic"], m["rosbag_mag_topic"]) == ("/imu", "/mag")
    assert (m["rosbag_imu_type"], m["rosbag_mag_type"]) == (IMU, MAG)
    assert "header.stamp" in m["rosbag_stamp_source"]
    assert int(m["rosbag_time_origin_ns"].split()[0]) == 37_072_000_000
    assert m["gyro_unit"] == "rad/s" and m["mag_unit"] == "uT" and m["acc_unit"] == "m/s^2"


def test_written_session_loads_back_the_same(bags, tmp_path):
    out = tmp_path / "s.parquet"
    bag = bags["ROS1"]
    before = bag.read_bytes()
    written = convert_rosbag(bag, out)
    assert bag.read_bytes() == before
    back = load_session(out)
    for name in ("t_gyro_s", "gyro_rad_s", "t_mag_s", "mag", "t_acc_s", "acc_m_s2"):
        np.testing.assert_array_equal(getattr(back, name), getattr(written, name))
    assert back.mag_unit == "uT"
    for key in ("rosbag_file", "rosbag_imu_topic", "rosbag_mag_topic", "rosbag_ros_version",
                "rosbag_stamp_source", "rosbag_time_origin_ns"):
        assert back.metadata[key] == written.metadata[key]


@pytest.mark.heavy
def test_the_whole_trial_solves_to_the_shipped_calibration(trial, tmp_path, broad02_solved, broad02_acc_solved):
    """The imported trial solves as the trial does once its times are rebased by the same arithmetic (1e-6).

    Against the trial's own times (37.072 s onwards) the solve moves by up to 7e-6 in K_g, under
    1 % of its std: the solve itself moves that much under ulp-level changes of the times (the
    trial's times shifted by +37.072 s and back give the same), so that bound is in std.
    """
    bag = write_bag(tmp_path / "whole", trial, ros=2)
    s = import_rosbag(bag)
    assert len(s.t_gyro_s) == len(trial.t_gyro_s)
    ns = stamps_ns(trial.t_gyro_s)
    t = (ns - ns[0]) / 1e9
    rebased = replace(trial, t_gyro_s=t, t_mag_s=t, t_acc_s=t, t_quat_s=None, quat_wxyz=None)
    got, want = magyro.calibrate(s), magyro.calibrate(rebased)
    shipped = (broad02_acc_solved if got.accelerometer is not None else broad02_solved)[1]   # the trial's, shared
    for name in ("K_g", "bias_rad_s", "C_b_m", "R", "h", "field_i"):
        a, b = getattr(got, name), getattr(want, name)
        assert np.max(np.abs(a - b)) <= 1e-6 * np.max(np.abs(b)), name
    for name in ("K_g", "R", "h"):
        std = getattr(shipped.std, name)
        diff = np.abs(getattr(got, name) - getattr(shipped, name))
        assert np.all(diff <= 0.02 * std + 1e-15), name


def test_stamps_that_do_not_increase_are_dropped_and_acc_marked_absent_is_not_imported(trial, tmp_path):
    n = 300
    ns = stamps_ns(trial.t_gyro_s[:n])
    ns[10] = ns[9]       # a repeat
    ns[20] = ns[15]      # a step back
    bag = write_bag(tmp_path / "odd", trial, n, ros=2, stamp_ns=ns, acc_absent=True)
    s = import_rosbag(bag)
    keep = np.setdiff1d(np.arange(n), [10, 20])
    np.testing.assert_array_equal(s.t_gyro_s, (ns[keep] - ns[0]) / 1e9)
    np.testing.assert_array_equal(s.gyro_rad_s, trial.gyro_rad_s[keep])
    assert s.acc_m_s2 is None and "not imported" in s.metadata["rosbag_units"]
    assert s.metadata["rosbag_rows_dropped"].startswith("gyro 2 of 300, magnetometer 2 of 300")


def test_topics_chosen_by_name(trial, tmp_path):
    bag = write_bag(tmp_path / "two.bag", trial, 200, ros=1, imu_topics=("/imu/a", "/imu/b"))
    s = import_rosbag(bag, imu_topic="/imu/b", mag_topic="/mag")
    assert s.metadata["rosbag_imu_topic"] == "/imu/b"
    np.testing.assert_array_equal(s.gyro_rad_s, trial.gyro_rad_s[:200])


# --------------------------------------------------------------------------- refusals


def refused(*args, **kwargs) -> str:
    with pytest.raises(InputError) as info:
        import_rosbag(*args, **kwargs)
    message = str(info.value)
    assert "\n" not in message
    return message


def test_refuses_what_is_not_a_bag(tmp_path):
    fake = tmp_path / "fake.bag"
    fake.write_text("t,gx,gy,gz\n0,0,0,0\n")
    assert "not a ROS bag" in refused(fake)
    (tmp_path / "empty_dir").mkdir()
    assert "not a ROS bag" in refused(tmp_path / "empty_dir")
    assert "no such file" in refused(tmp_path / "absent.bag")


def test_refuses_a_bag_without_imu_or_magnetometer(trial, tmp_path):
    message = refused(write_bag(tmp_path / "no_imu.bag", trial, 100, ros=1, imu_topics=()))
    assert f"no {IMU} topic" in message and "/mag" in message
    message = refused(write_bag(tmp_path / "no_mag", trial, 100, ros=2, mag_topics=()))
    assert f"no {MAG} topic" in message


def test_refuses_two_imu_topics_unnamed_and_names_that_do_not_exist(trial, tmp_path):
    bag = write_bag(tmp_path / "two.bag", trial, 100, ros=1, imu_topics=("/imu/a", "/imu/b"))
    message = refused(bag)
    assert "several" in message and "/imu/a, /imu/b" in message and "--imu-topic" in message
    message = refused(bag, imu_topic="/imu/c")
    assert "/imu/c does not exist" in message and "/imu/a, /imu/b" in message
    assert f"is {MAG}, not {IMU}" in refused(bag, imu_topic="/mag")


def test_refuses_unset_stamps_and_an_output_that_is_the_bag(trial, tmp_path):
    bag = write_bag(tmp_path / "zero.bag", trial, 100, ros=1, stamp_ns=np.zeros(100))
    assert "increasing header stamps" in refused(bag)
    with pytest.raises(InputError):
        convert_rosbag(bag, bag)
    assert bag.is_file() and "increasing header stamps" in refused(bag)


# --------------------------------------------------------------------------- the command


def test_cli_import_rosbag(run_magyro, assert_plain_failure, bags, trial, tmp_path):
    out = tmp_path / "s.parquet"
    n = part(trial)
    done = run_magyro("import", "rosbag", bags["ROS2"], "-o", out, "--imu-topic", "/imu")
    assert done.returncode == 0, done.stderr
    assert f"{n} gyro samples" in done.stdout and f"{n} magnetometer samples" in done.stdout
    assert "/imu" in done.stdout and "/mag" in done.stdout and out.is_file()
    assert_equals_trial(load_session(out), trial, n)
    fake = tmp_path / "fake.bag"
    fake.write_text("not a bag\n")
    message = assert_plain_failure(run_magyro("import", "rosbag", fake, "-o", tmp_path / "f.parquet"), 2)
    assert "not a ROS bag" in message
    message = assert_plain_failure(run_magyro("import", "rosbag", bags["ROS1"], "-o", tmp_path / "g.parquet",
                                              "--mag-topic", "/nope"), 2)
    assert "/nope does not exist" in message
    assert not (tmp_path / "f.parquet").exists() and not (tmp_path / "g.parquet").exists()


@pytest.mark.parametrize("mag_as, unit", [("gauss", "uT"), ("unit", "normalised")])
def test_an_older_drivers_vector3stamped_magnetometer_is_read(trial, tmp_path, mag_as, unit):
    """phidgets_imu and razor_imu_9dof published geometry_msgs/Vector3Stamped before MagneticField: gauss (imported
    in uT), or unit vectors (kept, unit "normalised", which the recording check then refuses by name)."""
    n = 500
    s = import_rosbag(write_bag(tmp_path / "old.bag", trial, n, ros=1, mag_as=mag_as))
    assert s.mag_unit == unit and s.metadata["rosbag_mag_type"] == OLD_MAG
    expected = trial.mag[:n] if mag_as == "gauss" else trial.mag[:n] / np.linalg.norm(trial.mag[:n], axis=1)[:, None]
    np.testing.assert_allclose(s.mag, expected, rtol=1e-12, atol=1e-12)


@pytest.mark.parametrize("mag_as, ros, mag_type", [("unit", 1, OLD_MAG), ("unit-tesla", 2, MAG)])
def test_import_refuses_a_normalised_magnetometer_naming_it(trial, tmp_path, mag_as, ros, mag_type):
    """Before: `magyro import rosbag` wrote a session of unit vectors without a word (a MagneticField of unit vectors
    even as 1e6 uT), and only solve's exit 2 said why. Now the import is refused, naming the topic and the cause;
    the Python reader still reads it, labelled "normalised"."""
    n = 300
    bag = write_bag(tmp_path / f"normalised-{ros}{'.bag' if ros == 1 else ''}", trial, n, ros=ros, mag_as=mag_as)
    out = tmp_path / "s.parquet"
    from typer.testing import CliRunner

    from magyro.cli import app

    result = CliRunner().invoke(app, ["import", "rosbag", str(bag), "-o", str(out)])
    message = " ".join(result.output.split())
    assert result.exit_code == 2 and message.startswith("magyro: ") and "Traceback" not in message, message
    assert "/mag" in message and mag_type in message and "normalised" in message and "|v| is 1.000-1.000" in message
    assert not out.exists()
    s = import_rosbag(bag)
    assert s.mag_unit == "normalised" and s.metadata["mag_unit"] == "normalised"
    np.testing.assert_allclose(np.linalg.norm(s.mag, axis=1), 1.0, rtol=1e-12)
