"""The text zips of Paul Riseborough's InertialNav test data (autopilot logs as IMU.txt, MAG.txt, ATT.txt) read
into `LogTables`, so that `magyro.io.dataflash` imports them as it imports a DataFlash log.

The members (whitespace-separated numbers, one message per line, as InertialNav's main_closed_loop_float.cpp
reads them):
- IMU.txt: time_ms, time_ms, gyro x y z (rad/s), accelerometer x y z (m/s^2);
- MAG.txt: time_ms, time_ms, mag x y z, offset x y z (the field with the offsets added, as ArduPilot logs it);
- ATT.txt (optional): time_ms, time_ms, roll, pitch, yaw (deg), 0, 0.

The magnetometer's unit is not written: ArduPilot's are milligauss, but the PX4 flight's (InputFilesPX4.zip) are
gauss. It is decided from the size of the field: a median |mag - offset| under `MAX_GAUSS` is gauss, one of
`MIN_MILLIGAUSS`-`MAX_MILLIGAUSS` milligauss (the Earth's field is 250-650 mG), anything else is refused; the
metadata names the decision. A magnetometer repeated on the IMU's rows (the PX4 zips) keeps only the rows where it
changed (a repeated reading there is a held sample, not a new one); the count dropped is in the metadata. A
MAG.txt on its own stamps (the ArduPilot zips) keeps every row.
Members are unpacked within the caps of `magyro.io.csv_zip` (a zip bomb never reaches memory).
"""
from __future__ import annotations

import tempfile
import zipfile
from pathlib import Path

import numpy as np

from magyro.errors import InputError, one_line
from magyro.io.dataflash_tables import LogTables

MEMBERS = {"IMU": ("IMU.txt", ("TimeMS", "TimeMS2", "GyrX", "GyrY", "GyrZ", "AccX", "AccY", "AccZ")),
           "MAG": ("MAG.txt", ("TimeMS", "TimeMS2", "MagX", "MagY", "MagZ", "OfsX", "OfsY", "OfsZ")),
           "ATT": ("ATT.txt", ("TimeMS", "TimeMS2", "Roll", "Pitch", "Yaw", "Zero1", "Zero2"))}
MAX_GAUSS = 5.0
MIN_MILLIGAUSS, MAX_MILLIGAUSS = 100.0, 5000.0


def read_inertialnav_zip(path: Path) -> LogTables:
    from magyro.io.csv_zip import MAX_MEMBERS, _check_readable, _unpacked

    tables = LogTables("InertialNav text zip (IMU.txt, MAG.txt, ATT.txt)")
    try:
        with zipfile.ZipFile(path) as z, tempfile.TemporaryDirectory(prefix="magyro-zip-") as folder:
            infos = z.infolist()
            if len(infos) > MAX_MEMBERS:
                raise InputError(f"{path}: the zip lists {len(infos)} entries, more than {MAX_MEMBERS}; unzip it")
            by_name = {Path(i.filename).name.lower(): i for i in infos
                       if not i.is_dir() and not i.filename.startswith("__MACOSX")}
            missing = [member for name, (member, _) in MEMBERS.items() if name != "ATT" and member.lower() not in by_name]
            if missing:
                raise InputError(f"{path}: the zip has no {' or '.join(missing)} (it holds "
                                 f"{', '.join(sorted(by_name)[:12]) or 'nothing'}); an autopilot text zip needs IMU.txt "
                                 f"and MAG.txt (ATT.txt optional); pass an ArduPilot .bin, .log or .mat otherwise")
            members = [by_name[m.lower()] for m, _ in MEMBERS.values() if m.lower() in by_name]
            _check_readable(path, members)
            budget = [sum(i.file_size for i in members) + 1]
            for name, (member, columns) in MEMBERS.items():
                if member.lower() in by_name:
                    local, label = _unpacked(z, path, by_name[member.lower()], Path(folder) / name, budget)
                    tables.messages[name] = _numbers(local, label, columns)
                    tables.counts[name] = len(tables.messages[name]["TimeMS"])
    except zipfile.BadZipFile as exc:
        raise InputError(f"{path}: not a readable zip ({one_line(exc)})") from None
    _drop_held_magnetometer(tables)
    tables.units["MAG"] = {"MagX": _field_unit(path, tables)}
    return tables


def _numbers(local: Path, label: str, columns: tuple) -> dict:
    try:
        values = np.loadtxt(local, dtype=np.float64, ndmin=2)
    except ValueError as exc:
        raise InputError(f"{label}: not whitespace-separated numbers ({one_line(exc, 120)}); the member is damaged") \
            from None
    if values.shape[1] != len(columns) or len(values) == 0:
        raise InputError(f"{label}: {values.shape[1]} columns, but this member has {len(columns)} "
                         f"({', '.join(columns)}); the member is damaged or of another layout")
    if not np.isfinite(values).all():
        raise InputError(f"{label}: holds values that are not finite numbers; the member is damaged")
    return {c: values[:, k] for k, c in enumerate(columns)}


def _drop_held_magnetometer(tables: LogTables) -> None:
    """On the IMU's rows (the same stamps, as in the PX4 zips), a reading equal to the previous one is held."""
    mag, imu = tables.messages["MAG"], tables.messages["IMU"]
    if len(mag["TimeMS"]) != len(imu["TimeMS"]) or not np.array_equal(mag["TimeMS"], imu["TimeMS"]):
        return   # its own stamps: every row is a sample (an integer reading may repeat)
    field = np.column_stack([mag[c] for c in ("MagX", "MagY", "MagZ")])
    keep = np.ones(len(field), dtype=bool)
    keep[1:] = np.any(field[1:] != field[:-1], axis=1)
    if not keep.all():
        tables.messages["MAG"] = {c: v[keep] for c, v in mag.items()}
        tables.notes.append(f"MAG.txt: {int((~keep).sum())} of {len(keep)} rows repeat the previous reading (held "
                            f"on the IMU's rows) and were dropped")


def _field_unit(path: Path, tables: LogTables) -> str:
    mag = tables.messages["MAG"]
    raw = np.column_stack([mag[f"Mag{a}"] - mag[f"Ofs{a}"] for a in "XYZ"])
    size = float(np.median(np.linalg.norm(raw, axis=1)))
    if size < MAX_GAUSS:
        tables.notes.append(f"MAG.txt read as gauss: median |mag - offset| is {size:.3g} (the Earth's field is "
                            f"0.25-0.65 G)")
        return "Gauss"
    if MIN_MILLIGAUSS <= size <= MAX_MILLIGAUSS:
        tables.notes.append(f"MAG.txt read as milligauss: median |mag - offset| is {size:.4g} (the Earth's field is "
                            f"250-650 mG)")
        return "mGauss"
    raise InputError(f"{path}: MAG.txt's median |mag - offset| is {size:.4g}, neither gauss (under {MAX_GAUSS:g}) "
                     f"nor milligauss ({MIN_MILLIGAUSS:g}-{MAX_MILLIGAUSS:g}); its unit cannot be told")
