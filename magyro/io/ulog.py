"""Importing PX4 ULog flight logs (.ulg) with pyulog (`pip install 'magyro[ulog]'`).

Which topics (auto, in this order of preference, for the selected `instance`):

- gyro: `sensor_gyro` (the per-sensor driver output, x y z in rad/s), else `sensor_combined`
  (`gyro_rad[0..2]`, rad/s);
- magnetometer: with `sensor_gyro`, `sensor_mag` (x y z in gauss) first; with `sensor_combined`,
  `vehicle_magnetometer` (`magnetometer_ga[0..2]`) first, then `sensor_mag`; last the older layout's
  magnetometer inside `sensor_combined` (`magnetometer_ga[0..2]`, stamped
  `timestamp + magnetometer_timestamp_relative`);
- accelerometer (optional: a log without one imports without `ax ay az`): `sensor_accel` (the per-sensor
  driver output, x y z in m/s^2, its own `timestamp_sample`), else `sensor_combined`
  (`accelerometer_m_s2[0..2]`, m/s^2, stamped `timestamp + accelerometer_timestamp_relative`, the gyro's
  `timestamp` when the offset is 0, as PX4 logs it). Samples PX4 flagged as clipped (`clip_counter`,
  `accelerometer_clipping`) are kept and counted in the metadata (`ulog_acc_clipping`).

A topic is taken only when it has at least `MIN_SAMPLES` fresh samples (many logs record
`sensor_gyro`, `sensor_mag` and `sensor_accel` at 1 Hz only); `topics=(gyro_topic, mag_topic)` forces a
pair (the accelerometer is then still chosen as above).

Fresh samples only: each sample is stamped with its own `timestamp_sample` when the topic
has one, else `timestamp` (microseconds), and a row whose stamp is not after the previous
kept stamp (a repeated, held sample) is dropped. Times are (stamp - first stamp) / 1e6 s,
the first stamp being the earliest gyro, magnetometer or accelerometer sample imported; it is kept in the
metadata (`ulog_time_origin_us`). Values are the log's float32 numbers as float64, unchanged.

PX4 logs are usually already calibrated by the autopilot; the metadata says what each
used topic holds (`px4_calibration`) and carries the log's CAL_GYRO*/CAL_MAG*/CAL_ACC* parameters.
"""
from __future__ import annotations

import importlib.metadata
import json
from pathlib import Path

import numpy as np

from magyro.errors import InputError, one_line
from magyro.io.checks import MIN_SAMPLES, session_from_table
from magyro.io.columns import ACC_COLUMNS, GYRO_COLUMNS, MAG_COLUMNS
from magyro.io.session_file import import_to_file, table_of_groups
from magyro.session import Session

ULOG_MAGIC = b"ULog\x01\x12\x35"
GYRO_TOPICS = ("sensor_gyro", "sensor_combined")
MAG_TOPICS = ("sensor_mag", "vehicle_magnetometer", "sensor_combined")
ACC_TOPICS = ("sensor_accel", "sensor_combined")
RELATIVE_TIMESTAMP_INVALID = 0x7FFFFFFF  # PX4's "no sample" marker in *_timestamp_relative
ULOG_INSTALL_HINT = "install it with pip install 'magyro[ulog]' (or pip install pyulog)"

_FIELDS = {  # (topic, sensor) -> the three value fields
    ("sensor_gyro", "gyro"): ("x", "y", "z"),
    ("sensor_combined", "gyro"): ("gyro_rad[0]", "gyro_rad[1]", "gyro_rad[2]"),
    ("sensor_mag", "mag"): ("x", "y", "z"),
    ("vehicle_magnetometer", "mag"): ("magnetometer_ga[0]", "magnetometer_ga[1]", "magnetometer_ga[2]"),
    ("sensor_combined", "mag"): ("magnetometer_ga[0]", "magnetometer_ga[1]", "magnetometer_ga[2]"),
    ("sensor_accel", "acc"): ("x", "y", "z"),
    ("sensor_combined", "acc"): ("accelerometer_m_s2[0]", "accelerometer_m_s2[1]", "accelerometer_m_s2[2]"),
}
_RELATIVE_STAMPS = {  # sensor_combined's sensors other than the gyro: stamped timestamp + this field
    "mag": "magnetometer_timestamp_relative",
    "acc": "accelerometer_timestamp_relative",
}

_CALIBRATION_NOTES = {
    "sensor_gyro": "sensor_gyro is the driver's output: raw or already corrected with the CAL_GYRO* offsets "
                   "depending on the PX4 version (raw in recent versions, which correct it downstream)",
    "sensor_combined": "sensor_combined is PX4's corrected sensor data (usually calibrated: CAL_* offsets applied, "
                       "board rotation applied)",
    "sensor_accel": "sensor_accel is the driver's output: raw or already corrected with the CAL_ACC* offsets/scales "
                    "depending on the PX4 version",
    "sensor_mag": "sensor_mag is the driver's output: raw or already corrected with the CAL_MAG* offsets/scales "
                  "depending on the PX4 version",
    "vehicle_magnetometer": "vehicle_magnetometer is calibrated by PX4 (CAL_MAG* offsets and scales, rotation to "
                            "the body frame)",
}
PX4_NOTE = ("PX4 logs are usually already calibrated by the autopilot, so a calibration of them estimates the "
            "errors left after PX4's own calibration")


def import_ulog(path, instance: int = 0, topics=None) -> Session:
    """A PX4 ULog file as a Session: gyro in rad/s, magnetometer in gauss (`mag_unit="G"`), accelerometer
    in m/s^2 when the log has one.

    `instance` selects the multi-instance of the topics (e.g. the second IMU); `topics`
    is None (chosen as in the module docstring) or a pair (gyro_topic, mag_topic) of
    `GYRO_TOPICS` x `MAG_TOPICS`, also as "gyro_topic,mag_topic". Raises `InputError` for a
    file that is not a ULog, a log without a usable gyro or magnetometer topic, or an
    instance the log does not have.
    """
    path = Path(path)
    instance = _check_instance(instance)
    forced = _check_topics(topics) if topics is not None and not isinstance(topics, str) else parse_topics(topics)
    ulog, pyulog_version = _read_ulog(path)
    datasets = {(d.name, int(d.multi_id)): d.data for d in ulog.data_list}

    gyro = _choose(path, datasets, "gyro", GYRO_TOPICS if forced is None else (forced[0],), instance)
    if forced is not None:
        mag_order = (forced[1],)
    elif gyro["topic"] == "sensor_gyro":
        mag_order = MAG_TOPICS  # the per-sensor pair
    else:
        mag_order = ("vehicle_magnetometer", "sensor_mag", "sensor_combined")
    mag = _choose(path, datasets, "mag", mag_order, instance)
    acc, acc_skipped = _choose_optional(path, datasets, "acc", ACC_TOPICS, instance)
    streams = [gyro, mag] + ([acc] if acc is not None else [])

    origin_us = int(min(stream["stamps_us"][0] for stream in streams))
    groups = [((stream["stamps_us"] - origin_us) / 1e6, stream["values"], columns)
              for stream, columns in zip(streams, (GYRO_COLUMNS, MAG_COLUMNS, ACC_COLUMNS))]
    table = table_of_groups(groups)

    info = ulog.msg_info_dict
    cal_params = {k: v for k, v in sorted(ulog.initial_parameters.items())
                  if k.startswith(("CAL_GYRO", "CAL_MAG", "CAL_ACC"))}
    metadata = {
        "source": str(path),
        "ulog_file": path.name,
        "imported_from": (f"PX4 ULog (pyulog {pyulog_version}): gyro {_describe(gyro)}; "
                          f"magnetometer {_describe(mag)}"
                          + (f"; accelerometer {_describe(acc)}" if acc is not None else "; no accelerometer")),
        "gyro_unit": "rad/s",
        "mag_unit": "G",
        "ulog_instance": str(instance),
        "ulog_gyro_topic": gyro["topic"],
        "ulog_gyro_fields": " ".join(gyro["fields"]),
        "ulog_gyro_time_field": gyro["time_field"],
        "ulog_mag_topic": mag["topic"],
        "ulog_mag_fields": " ".join(mag["fields"]),
        "ulog_mag_time_field": mag["time_field"],
        "ulog_time_origin_us": f"{origin_us} (t = 0 s; t = (stamp - origin) / 1e6)",
        "ulog_rows_dropped": (f"gyro {gyro['dropped']} of {gyro['rows']}, magnetometer {mag['dropped']} of "
                              f"{mag['rows']}"
                              + (f", accelerometer {acc['dropped']} of {acc['rows']}" if acc is not None else "")
                              + " (not fresh: stamp not after the previous sample's)"),
        "ulog_topic_choice": "; ".join(gyro["skipped"] + mag["skipped"] + acc_skipped) or "preferred topics used",
        "ulog_dropouts": (f"{len(ulog.dropouts)} logging dropouts, "
                          f"{sum(int(d.duration) for d in ulog.dropouts)} ms in all"),
        "px4_calibration": "; ".join([PX4_NOTE] + [_CALIBRATION_NOTES[stream["topic"]] for stream in
                                                   {s["topic"]: s for s in streams}.values()]),
        "px4_calibration_parameters": json.dumps(cal_params),
        "px4_version": str(info.get("ver_sw", "unknown")),
        "px4_board": str(info.get("ver_hw", "unknown")),
        "px4_system": str(info.get("sys_name", "unknown")),
    }
    if acc is not None:
        metadata.update({
            "acc_unit": "m/s^2",
            "ulog_acc_topic": acc["topic"],
            "ulog_acc_fields": " ".join(acc["fields"]),
            "ulog_acc_time_field": acc["time_field"],
            "ulog_acc_clipping": acc["clipping"],
        })
    return session_from_table(table, metadata, str(path), gyro_unit="rad/s", mag_unit="G")


def convert_ulog(path, output, instance: int = 0, topics=None,
                 compression_level: int | None = None) -> Session:
    """`magyro import ulog`: `import_ulog(path, instance, topics)` written to `output` (`write_imported`).

    An `output` that is the log or cannot be written is refused before the log is read.
    Returns the written session.
    """
    return import_to_file([path], output, lambda: import_ulog(path, instance=instance, topics=topics), compression_level)


def parse_topics(text: str | None):
    """'GYRO_TOPIC,MAG_TOPIC' (the CLI's --topics) as a checked pair, or None for None/empty."""
    if text is None or not text.strip():
        return None
    return _check_topics(tuple(p.strip() for p in text.split(",")))


# --------------------------------------------------------------------------- reading the log


def _check_instance(instance) -> int:
    if isinstance(instance, bool) or not isinstance(instance, (int, np.integer)) or instance < 0:
        raise InputError(f"instance {instance!r}: the topic instance is an integer 0, 1, 2, ...")
    return int(instance)


def _check_topics(topics) -> tuple[str, str]:
    pair = tuple(topics) if not isinstance(topics, str) else (topics,)
    if len(pair) != 2 or pair[0] not in GYRO_TOPICS or pair[1] not in MAG_TOPICS:
        raise InputError(f"topics {', '.join(map(str, pair))}: give a gyro topic ({' or '.join(GYRO_TOPICS)}) "
                         f"and a magnetometer topic ({' or '.join(MAG_TOPICS)}), e.g. "
                         f"sensor_combined,vehicle_magnetometer")
    return pair


def _read_ulog(path: Path):
    if not path.exists():
        raise InputError(f"{path}: no such file; check the path")
    if not path.is_file():
        raise InputError(f"{path}: not a regular file; pass a PX4 ULog file (.ulg)")
    with open(path, "rb") as f:
        head = f.read(len(ULOG_MAGIC))
    if head != ULOG_MAGIC:
        raise InputError(f"{path}: not a ULog file (it does not start with the ULog header); pass a PX4 log (.ulg)")
    try:
        import pyulog
        from pyulog import ULog
    except ImportError:
        raise InputError(f"{path}: reading ULog files needs the pyulog package; {ULOG_INSTALL_HINT}") from None
    try:
        ulog = ULog(str(path), list(dict.fromkeys(GYRO_TOPICS + MAG_TOPICS + ACC_TOPICS)))
    except Exception as exc:
        raise InputError(f"{path}: cannot be read as a ULog file ({one_line(exc)})") from None
    try:
        version = importlib.metadata.version("pyulog")
    except importlib.metadata.PackageNotFoundError:
        version = getattr(pyulog, "__version__", "unknown")
    return ulog, version


def _choose_optional(path: Path, datasets: dict, sensor: str, candidates: tuple, instance: int):
    """(`_choose`'s stream, the topics passed over) for a sensor the log may lack: (None, why) when none of
    `candidates` is usable; a log without the sensor imports without it."""
    try:
        stream = _choose(path, datasets, sensor, candidates, instance)
    except InputError as exc:
        return None, [f"no accelerometer imported ({str(exc).removeprefix(f'{path}: ')})"]
    return stream, stream["skipped"]


_SENSOR_NAMES = {"gyro": "gyro", "mag": "magnetometer", "acc": "accelerometer"}


def _choose(path: Path, datasets: dict, sensor: str, candidates: tuple, instance: int) -> dict:
    """The first of `candidates` with at least MIN_SAMPLES fresh samples at `instance`."""
    name = _SENSOR_NAMES[sensor]
    present = {}  # topic -> its instances, for topics carrying this sensor's fields
    skipped = []
    for topic in candidates:
        instances = sorted(i for (t, i), data in datasets.items()
                           if t == topic and _FIELDS[(topic, sensor)][0] in data)
        if not instances:
            continue
        present[topic] = instances
        if instance not in instances:
            skipped.append(f"{topic} has no instance {instance}")
            continue
        stream = _stream(datasets[(topic, instance)], topic, sensor)
        if len(stream["stamps_us"]) >= MIN_SAMPLES:
            stream["skipped"] = skipped
            return stream
        skipped.append(f"{topic} instance {instance} has only {len(stream['stamps_us'])} fresh {name} samples "
                       f"(at least {MIN_SAMPLES} needed)")
    if not present:
        raise InputError(f"{path}: no {name} topic; the log has none of {', '.join(candidates)} "
                         f"with {name} fields")
    if not any(instance in inst for inst in present.values()):
        listed = "; ".join(f"{t}: {', '.join(map(str, inst))}" for t, inst in present.items())
        raise InputError(f"{path}: {name} instance {instance} does not exist; the instances in the log are "
                         f"{listed}; choose one with --instance")
    raise InputError(f"{path}: no usable {name} topic: {'; '.join(skipped)}")


def _stream(data: dict, topic: str, sensor: str) -> dict:
    """A topic's fresh samples: int64 stamps (us) strictly increasing, (N, 3) float64 values."""
    fields = _FIELDS[(topic, sensor)]
    if topic == "sensor_combined" and sensor in _RELATIVE_STAMPS and _RELATIVE_STAMPS[sensor] in data:
        relative = np.asarray(data[_RELATIVE_STAMPS[sensor]], dtype=np.int64)
        valid = relative != RELATIVE_TIMESTAMP_INVALID
        stamps = np.asarray(data["timestamp"], dtype=np.int64) + relative
        time_field = f"timestamp + {_RELATIVE_STAMPS[sensor]}"
    else:
        time_field = "timestamp_sample" if "timestamp_sample" in data else "timestamp"
        stamps = np.asarray(data[time_field], dtype=np.int64)
        valid = np.ones(len(stamps), dtype=bool)
    values = np.column_stack([np.asarray(data[f], dtype=np.float64) for f in fields])
    rows = len(stamps)
    clipped, clip_logged = _clipped(data, topic, sensor)
    stamps, values, clipped = stamps[valid], values[valid], clipped[valid]
    keep = np.ones(len(stamps), dtype=bool)
    if len(stamps) > 1:  # fresh: after every earlier stamp (a repeat is a held sample)
        keep[1:] = stamps[1:] > np.maximum.accumulate(stamps)[:-1]
    stream = {"topic": topic, "fields": fields, "time_field": time_field, "stamps_us": stamps[keep],
              "values": values[keep], "rows": rows, "dropped": rows - int(keep.sum())}
    if sensor == "acc":
        n = int(clipped[keep].sum())
        what = "clip_counter[0..2]" if topic == "sensor_accel" else "accelerometer_clipping"
        stream["clipping"] = (f"{n} of {int(keep.sum())} samples flagged clipped by PX4 ({what})" if clip_logged
                              else f"not logged ({topic} has no {what})")
    return stream


def _clipped(data: dict, topic: str, sensor: str) -> tuple[np.ndarray, bool]:
    """(per row: PX4 flagged an accelerometer axis as clipped, whether the log has the flag): sensor_accel's
    clip_counter[k] > 0, sensor_combined's accelerometer_clipping bits; all False for other sensors."""
    rows = len(data["timestamp"])
    names = [] if sensor != "acc" else (
        [f"clip_counter[{k}]" for k in range(3)] if topic == "sensor_accel" else ["accelerometer_clipping"])
    flags = [np.asarray(data[n]) != 0 for n in names if n in data]
    return (np.any(flags, axis=0) if flags else np.zeros(rows, dtype=bool)), bool(flags)


def _describe(stream: dict) -> str:
    return (f"{stream['topic']} ({' '.join(stream['fields'])}, stamped by {stream['time_field']}, "
            f"{len(stream['stamps_us'])} fresh samples)")
