"""Importing ROS bags (ROS1 `.bag` files, ROS2 bag folders) with rosbags (`pip install 'magyro[rosbag]'`).

Topics: the gyro is a `sensor_msgs/msg/Imu` topic (`angular_velocity`, rad/s; its
`linear_acceleration`, m/s^2, is the accelerometer unless the messages mark it absent with
`linear_acceleration_covariance[0] == -1`), the magnetometer a `sensor_msgs/msg/MagneticField`
topic (`magnetic_field`, tesla, imported in uT: value * 1e6) or, from older drivers, a
`geometry_msgs/msg/Vector3Stamped` topic (`vector`). Vector3Stamped carries no unit: the
drivers that published it (phidgets_imu, razor_imu_9dof before MagneticField) wrote gauss, or a
unit vector (the Razor's normalised heading field). Readings whose norm is 1 within 1 % on every
sample are read as they are with the unit "normalised" (so is a MagneticField whose |B| is 1 T on every
sample), and `magyro import rosbag` (`convert_rosbag`) refuses them naming the cause; others as gauss, imported in uT
(value * 100): the imu_tools Phidgets bag of 2013 reads 0.37-0.38 there, the same samples
its 2017 MagneticField version gives as 3.7e-5 T. A MagneticField topic is preferred when both
exist. Each is the topic named, or else the only topic of its type in the bag; several of a
type and none named is refused with the list of candidates.

Times are the message header stamps (sec + nanosec, integer nanoseconds), not the bag's
receive times; in the bag's order, a message whose stamp is not after every earlier stamp of
its topic is dropped. Times are (stamp - first stamp) / 1e9 s, the first stamp being the
earliest gyro or magnetometer stamp imported; it is kept in the metadata
(`rosbag_time_origin_ns`). Gyro and accelerometer values are the messages' float64 numbers,
unchanged.
"""
from __future__ import annotations

import importlib.metadata
from pathlib import Path

import numpy as np

from magyro.errors import InputError, one_line
from magyro.io.checks import MIN_SAMPLES, session_from_table
from magyro.io.columns import ACC_COLUMNS, GYRO_COLUMNS, MAG_COLUMNS
from magyro.io.session_file import import_to_file, table_of_groups
from magyro.session import Session

IMU_TYPE = "sensor_msgs/msg/Imu"
MAG_TYPE = "sensor_msgs/msg/MagneticField"
OLD_MAG_TYPE = "geometry_msgs/msg/Vector3Stamped"   # older drivers' magnetometer, in gauss (or normalised)
TESLA_TO_UT = 1e6
GAUSS_TO_UT = 100.0
UNIT_NORM_TOLERANCE = 0.01         # every |vector| within 1 % of 1: a normalised field, not gauss
ROSBAG_INSTALL_HINT = "install it with pip install 'magyro[rosbag]' (or pip install rosbags)"


def import_rosbag(path, imu_topic: str | None = None, mag_topic: str | None = None) -> Session:
    """A ROS1 bag file or ROS2 bag folder as a Session: gyro rad/s, magnetometer uT (`mag_unit="uT"`).

    `imu_topic` (a sensor_msgs/msg/Imu topic) and `mag_topic` (a sensor_msgs/msg/MagneticField
    topic) name the topics; None finds the only one of the type. Raises `InputError` for a
    path that is not a bag, a bag without such a topic, several candidates and none named, a
    named topic the bag does not have or of the wrong type, or too few stamped samples.
    """
    path = Path(path)
    AnyReader, get_typestore, Stores, rosbags_version = _rosbags(path)
    try:
        reader = AnyReader([path], default_typestore=get_typestore(Stores.LATEST))
        reader.open()
    except Exception as exc:
        raise InputError(f"{path}: not a ROS bag ({one_line(exc)}); pass a ROS1 .bag file or a ROS2 bag folder") \
            from None
    try:
        topics = {c.topic: c.msgtype for c in reader.connections}
        imu_name = _choose(path, topics, IMU_TYPE, imu_topic, "--imu-topic")
        mag_type = _magnetometer_type(topics, mag_topic)
        mag_name = _choose(path, topics, mag_type, mag_topic, "--mag-topic")
        imu = _read(path, reader, imu_name, IMU_TYPE)
        mag = _read(path, reader, mag_name, mag_type)
        ros_version = "ROS2" if reader.is2 else "ROS1"
    except InputError:
        raise
    except Exception as exc:
        raise InputError(f"{path}: cannot be read as a ROS bag ({one_line(exc)})") from None
    finally:
        reader.close()

    origin_ns = min(imu["stamps_ns"][0], mag["stamps_ns"][0])
    t_imu_s = (imu["stamps_ns"] - origin_ns) / 1e9
    t_mag_s = (mag["stamps_ns"] - origin_ns) / 1e9
    with_acc = bool(imu["acc_present"].any())
    groups = [(t_imu_s, imu["gyro"], GYRO_COLUMNS), (t_mag_s, mag["mag"], MAG_COLUMNS)]
    table = table_of_groups(groups + ([(t_imu_s, imu["acc"], ACC_COLUMNS)] if with_acc else []))

    metadata = {
        "source": str(path),
        "rosbag_file": path.name,
        "imported_from": (f"{ros_version} bag (rosbags {rosbags_version}): "
                          f"gyro{' and accelerometer' if with_acc else ''} "
                          f"{_describe(imu)}; magnetometer {_describe(mag)}"),
        "gyro_unit": "rad/s",
        "mag_unit": "uT",
        "rosbag_ros_version": ros_version,
        "rosbag_imu_topic": imu_name,
        "rosbag_imu_type": IMU_TYPE,
        "rosbag_mag_topic": mag_name,
        "rosbag_mag_type": MAG_TYPE,
        "rosbag_stamp_source": "header.stamp (sec + nanosec), not the bag's receive time",
        "rosbag_time_origin_ns": f"{origin_ns} (t = 0 s; t = (stamp - origin) / 1e9)",
        "rosbag_rows_dropped": (f"gyro {imu['dropped']} of {imu['rows']}, magnetometer {mag['dropped']} of "
                                f"{mag['rows']} (stamp not after an earlier message's)"),
        "rosbag_units": ("angular_velocity rad/s as is; magnetic_field tesla * 1e6 = uT"
                         + ("; linear_acceleration m/s^2 as is" if with_acc else
                            "; linear_acceleration marked absent (covariance[0] = -1), not imported")),
    }
    if mag_type == OLD_MAG_TYPE:
        metadata.update({"rosbag_mag_type": OLD_MAG_TYPE, "mag_unit": mag["unit"]})
        metadata["rosbag_units"] = metadata["rosbag_units"].replace(
            "magnetic_field tesla * 1e6 = uT", "vector (Vector3Stamped) " + (
                "normalised (every |v| = 1), kept as is" if mag["unit"] == "normalised" else "gauss * 100 = uT"))
    elif mag["unit"] == "normalised":
        metadata["mag_unit"] = "normalised"
        metadata["rosbag_units"] = metadata["rosbag_units"].replace(
            "magnetic_field tesla * 1e6 = uT", "magnetic_field normalised (every |B| = 1), kept as is")
    if with_acc:
        metadata["acc_unit"] = "m/s^2"
    return session_from_table(table, metadata, str(path), gyro_unit="rad/s", mag_unit=metadata["mag_unit"])


def convert_rosbag(path, output, imu_topic: str | None = None, mag_topic: str | None = None,
                   compression_level: int | None = None) -> Session:
    """`magyro import rosbag`: `import_rosbag(path, imu_topic, mag_topic)` written to `output` (`write_imported`).

    An `output` that is the bag or cannot be written is refused before the bag is read; a normalised
    magnetometer (unit vectors, `check_not_normalised`) is refused before anything is written.
    Returns the written session.
    """
    def read() -> Session:
        session = import_rosbag(path, imu_topic=imu_topic, mag_topic=mag_topic)
        check_not_normalised(path, session)
        return session

    return import_to_file([path], output, read, compression_level)


# --------------------------------------------------------------------------- reading the bag


def _rosbags(path: Path):
    if not path.exists():
        raise InputError(f"{path}: no such file or folder; check the path")
    try:
        from rosbags.highlevel import AnyReader
        from rosbags.typesys import Stores, get_typestore
    except ImportError:
        raise InputError(f"{path}: reading ROS bags needs the rosbags package; {ROSBAG_INSTALL_HINT}") from None
    try:
        version = importlib.metadata.version("rosbags")
    except importlib.metadata.PackageNotFoundError:
        version = "unknown"
    return AnyReader, get_typestore, Stores, version


def _magnetometer_type(topics: dict, named: str | None) -> str:
    """MagneticField, unless the topic named (or, none named, every magnetometer topic) is a Vector3Stamped."""
    if named is not None:
        return OLD_MAG_TYPE if topics.get(named) == OLD_MAG_TYPE else MAG_TYPE
    return OLD_MAG_TYPE if OLD_MAG_TYPE in topics.values() and MAG_TYPE not in topics.values() else MAG_TYPE


def _choose(path: Path, topics: dict, msgtype: str, named: str | None, option: str) -> str:
    """The topic named (checked), else the only topic of `msgtype`."""
    candidates = sorted(t for t, typ in topics.items() if typ == msgtype)
    if named is not None:
        if named not in topics:
            listed = ", ".join(candidates) if candidates else f"none of type {msgtype}"
            raise InputError(f"{path}: topic {named} does not exist in the bag; its {msgtype} topics: {listed}")
        if topics[named] != msgtype:
            raise InputError(f"{path}: topic {named} is {topics[named]}, not {msgtype}")
        return named
    if not candidates:
        raise InputError(f"{path}: no {msgtype} topic in the bag (its topics: "
                         f"{', '.join(f'{t} ({typ})' for t, typ in sorted(topics.items())) or 'none'})")
    if len(candidates) > 1:
        raise InputError(f"{path}: several {msgtype} topics: {', '.join(candidates)}; choose one with {option}")
    return candidates[0]


def _read(path: Path, reader, topic: str, msgtype: str) -> dict:
    """A topic's messages: int64 stamps (ns) strictly increasing and float64 values, in the bag's order."""
    connections = [c for c in reader.connections if c.topic == topic]
    stamps, gyro, acc, acc_present, mag = [], [], [], [], []
    for connection, _, rawdata in reader.messages(connections=connections):
        msg = reader.deserialize(rawdata, connection.msgtype)
        stamp = msg.header.stamp
        stamps.append(int(stamp.sec) * 1_000_000_000 + int(stamp.nanosec))
        if msgtype == IMU_TYPE:
            w, a = msg.angular_velocity, msg.linear_acceleration
            gyro.append((w.x, w.y, w.z))
            acc.append((a.x, a.y, a.z))
            acc_present.append(msg.linear_acceleration_covariance[0] != -1)
        else:
            b = msg.magnetic_field if msgtype == MAG_TYPE else msg.vector
            mag.append((b.x, b.y, b.z))
    stamps = np.asarray(stamps, dtype=np.int64)
    rows = len(stamps)
    keep = np.ones(rows, dtype=bool)
    if rows > 1:  # strictly after every earlier stamp
        keep[1:] = stamps[1:] > np.maximum.accumulate(stamps)[:-1]
    stream = {"topic": topic, "stamps_ns": stamps[keep], "rows": rows, "dropped": rows - int(keep.sum())}
    name = "gyro" if msgtype == IMU_TYPE else "magnetometer"
    if len(stream["stamps_ns"]) < MIN_SAMPLES:
        raise InputError(f"{path}: topic {topic} has {len(stream['stamps_ns'])} {name} messages with increasing "
                         f"header stamps (of {rows}); at least {MIN_SAMPLES} are needed (are the stamps set?)")
    if msgtype == IMU_TYPE:
        stream["gyro"] = np.asarray(gyro, dtype=np.float64).reshape(-1, 3)[keep]
        stream["acc_present"] = np.asarray(acc_present, dtype=bool)[keep]
        stream["acc"] = np.asarray(acc, dtype=np.float64).reshape(-1, 3)[keep]
        stream["acc"][~stream["acc_present"]] = np.nan  # marked absent: no accelerometer sample
    elif msgtype == MAG_TYPE:
        field = np.asarray(mag, dtype=np.float64).reshape(-1, 3)[keep]
        if _is_unit_vectors(field):  # |B| = 1 T on every sample is no field a device reads: a normalised one
            stream["mag"], stream["unit"] = field, "normalised"
        else:
            stream["mag"], stream["unit"] = field * TESLA_TO_UT, "uT"
    else:
        stream["mag"], stream["unit"] = _vector3_field(np.asarray(mag, dtype=np.float64).reshape(-1, 3)[keep])
    return stream


def _vector3_field(vector: np.ndarray) -> tuple[np.ndarray, str]:
    """(field, unit) of a Vector3Stamped magnetometer: unit vectors stay as they are ("normalised"), anything
    else is gauss, returned in uT. Rows without a number (a driver's empty messages) stay empty."""
    if _is_unit_vectors(vector):
        return vector, "normalised"
    return vector * GAUSS_TO_UT, "uT"


def _is_unit_vectors(vector: np.ndarray) -> bool:
    """Every finite |v| within UNIT_NORM_TOLERANCE of 1: a normalised field (a heading), not a field."""
    norm = np.linalg.norm(vector, axis=1)
    norm = norm[np.isfinite(norm)]
    return bool(len(norm) and np.all(np.abs(norm - 1.0) < UNIT_NORM_TOLERANCE))


def check_not_normalised(path, session: Session) -> None:
    """Refuses (InputError, exit 2) a session whose magnetometer is normalised: unit vectors carry no field
    strength, so neither the hard iron nor the scale, nor the gyro through them, can be calibrated from it."""
    if session.mag_unit != "normalised":
        return
    m = session.metadata
    norm = np.linalg.norm(session.mag, axis=1)
    norm = norm[np.isfinite(norm)]
    raise InputError(
        f"{path}: the magnetometer on {m.get('rosbag_mag_topic', 'its topic')} ({m.get('rosbag_mag_type', '')}) is "
        f"normalised: |v| is {norm.min():.3f}-{norm.max():.3f} on every sample, a unit vector (a heading), not a "
        f"field in {'tesla' if m.get('rosbag_mag_type') == MAG_TYPE else 'gauss'}; without the field's strength "
        f"no calibration is possible (solve would refuse it). Record the raw magnetometer (sensor_msgs/"
        f"MagneticField in tesla, or the driver's unnormalised output) and import that")


def _describe(stream: dict) -> str:
    return (f"{stream['topic']} (header stamps, {len(stream['stamps_ns'])} samples, "
            f"{stream['dropped']} dropped)")
