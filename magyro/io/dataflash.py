"""Importing ArduPilot DataFlash logs: `.bin` (with pymavlink, `pip install 'magyro[dataflash]'`), Mission
Planner's text `.log` and its MATLAB `.mat` export (`magyro.io.dataflash_read` reads each into columns), and the
InertialNav text zips of autopilot logs (IMU.txt, MAG.txt, ATT.txt; `magyro.io.dataflash_zip`).

What a session gets, for the IMU and compass instances chosen (`imu`, `mag`: the `I` column of modern logs,
else the messages IMU/IMU2/IMU3 and MAG/MAG2/MAG3 of older ones):

- gyro: IMU GyrX..Z, rad/s, as logged. The autopilot has already applied its gyro offsets (INS_GYROFFS_*,
  INS_GYR2OFFS_*, ... for the other instances; the log has no raw gyro): the metadata names them
  (`dataflash_gyro_offsets_applied`), so a calibration estimates what is left after them;
- accelerometer: IMU AccX..Z, m/s^2, as logged (ArduPilot's own offsets and scales applied);
- magnetometer: the raw reading, in uT. ArduPilot logs MAG MagX..Z with its corrections applied
  (field = M (raw + Ofs) + MO: offsets Ofs, the soft-iron matrix M of COMPASS_DIA*/ODI*, the motor
  compensation MO), in milligauss; the raw reading is M^-1 (Mag - MO) - Ofs with the offsets in force at each
  sample (the Ofs columns of the same MAG message: learned in flight with COMPASS_LEARN they change), or the
  COMPASS_OFS* parameters of a log without Ofs columns. 1 mG = 0.1 uT;
- reference quaternion (qw qx qy qz): ATT Roll, Pitch, Yaw (degrees), ArduPilot's attitude estimate (DCM or
  EKF: a reference, not truth). ArduPilot's body frame is FRD (x forward, y right, z down), its earth frame
  NED, and its Euler angles are the 3-2-1 (yaw, then pitch, then roll) sequence: the rotation body -> NED is
  R = Rz(yaw) Ry(pitch) Rx(roll), v_ned = R v_body, which is the session's "body to reference" quaternion
  (docs/spec.md section 2). The gyro is in the same body frame (AHRS_ORIENTATION applied by the autopilot).

Times are the log's TimeUS (microseconds) or, in older logs, TimeMS, from the earliest IMU, MAG or ATT stamp
(kept in `dataflash_time_origin`); a message whose stamp is not after the previous kept one is dropped. Every
parameter of the log (PARM) is kept in the metadata as JSON (`dataflash_parameters`).
"""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from magyro.errors import InputError
from magyro.io.checks import MIN_SAMPLES, session_from_table
from magyro.io.columns import ACC_COLUMNS, GYRO_COLUMNS, MAG_COLUMNS, QUAT_COLUMNS
from magyro.io.dataflash_read import MESSAGES_PER_SENSOR, LogTables, read_log
from magyro.io.session_file import import_to_file, table_of_groups
from magyro.session import Session

MILLIGAUSS_TO_UT = 0.1
GAUSS_TO_UT = 100.0
TIME_COLUMNS_S = {"TimeUS": 1e-6, "TimeMS": 1e-3}
AXES = ("X", "Y", "Z")
MAG_UNITS_TO_UT = {"mGauss": MILLIGAUSS_TO_UT, "mG": MILLIGAUSS_TO_UT, "Gauss": GAUSS_TO_UT, "G": GAUSS_TO_UT}
OPTIONS = {"IMU": "--imu", "MAG": "--mag"}


def import_dataflash(path, imu: int = 0, mag: int = 0) -> Session:
    """An ArduPilot log (.bin, .log or .mat) as a Session: gyro rad/s, raw magnetometer uT, accelerometer m/s^2,
    ATT as the reference quaternion. Raises `InputError` for a damaged or hostile log, a log without IMU or MAG
    messages, or an instance it does not have."""
    path = Path(path)
    imu, mag = _check_instance(imu, "--imu"), _check_instance(mag, "--mag")
    tables = read_log(path)
    imu_name, imu_rows = sensor_rows(path, tables, "IMU", imu)
    mag_name, mag_rows = sensor_rows(path, tables, "MAG", mag)
    t_imu, imu_scale, imu_keep = _fresh_times(path, imu_name, imu_rows)
    t_mag, mag_scale, mag_keep = _fresh_times(path, mag_name, mag_rows)
    gyro_rad_s = _vector(path, imu_name, imu_rows, "Gyr")[imu_keep]
    acc_m_s2 = _vector(path, imu_name, imu_rows, "Acc", required=False)
    mag_uT, mag_note = raw_magnetometer_uT(path, tables, mag_name, mag_rows, mag)
    for what, name, n in (("IMU", imu_name, len(t_imu)), ("MAG", mag_name, len(t_mag))):
        if n < MIN_SAMPLES:
            raise InputError(f"{path}: {name}{_instance_text(what, name, imu if what == 'IMU' else mag)} has {n} "
                             f"samples; at least {MIN_SAMPLES} are needed (the log is too short"
                             f"{', and cut inside a message' if any('cut short' in s for s in tables.notes) else ''})")
    att = _attitude(path, tables)

    stamps = [t_imu, t_mag] + ([att[0]] if att is not None else [])
    scales = {imu_scale, mag_scale} | ({att[1]} if att is not None else set())
    if len(scales) > 1:
        raise InputError(f"{path}: the IMU, MAG and ATT messages are stamped in different time units; the log is "
                         f"damaged")
    origin = min(float(s[0]) for s in stamps)
    scale = scales.pop()
    groups = [((t_imu - origin) * scale, gyro_rad_s, GYRO_COLUMNS),
              ((t_mag - origin) * scale, mag_uT[mag_keep], MAG_COLUMNS)]
    if acc_m_s2 is not None:
        groups.append(((t_imu - origin) * scale, acc_m_s2[imu_keep], ACC_COLUMNS))
    if att is not None:
        groups.append(((att[0] - origin) * scale, att[2], QUAT_COLUMNS))
    metadata = _metadata(path, tables, imu_name, imu, mag_name, mag, mag_note, origin, scale,
                         len(t_imu), len(t_mag), acc_m_s2 is not None, att)
    return session_from_table(table_of_groups(groups), metadata, str(path), gyro_unit="rad/s", mag_unit="uT")


def convert_dataflash(path, output, imu: int = 0, mag: int = 0, compression_level: int | None = None) -> Session:
    """`magyro import dataflash`: `import_dataflash(path, imu, mag)` written to `output` (`write_imported`).

    An `output` that is the log or cannot be written is refused before the log is read. Returns the session."""
    return import_to_file([path], output, lambda: import_dataflash(path, imu=imu, mag=mag), compression_level)


# --------------------------------------------------------------------------- instances and columns


def _check_instance(instance, option: str) -> int:
    if isinstance(instance, bool) or not isinstance(instance, (int, np.integer)) or instance < 0:
        raise InputError(f"{option} {instance!r}: an instance is an integer 0, 1, 2, ...")
    return int(instance)


def sensor_rows(path: Path, tables: LogTables, sensor: str, instance: int) -> tuple[str, dict]:
    """(message name, its columns) of `sensor` ("IMU" or "MAG") instance `instance`: the rows with I ==
    instance of a log with an I column, else the message IMU / IMU2 / IMU3 (MAG ...)."""
    messages = tables.messages
    base = messages.get(sensor)
    if base is not None and "I" in base:
        found = sorted({int(i) for i in base["I"]})
        if instance not in found:
            raise InputError(f"{path}: {sensor} instance {instance} does not exist; the log's {sensor} instances "
                             f"are {', '.join(map(str, found))}; choose one with {OPTIONS[sensor]}")
        rows = base["I"] == instance
        return sensor, {c: v[rows] for c, v in base.items()}
    names = [sensor + k for k in MESSAGES_PER_SENSOR if sensor + k in messages]
    if not names:
        listed = ", ".join(f"{n} ({c})" for n, c in sorted(tables.counts.items(), key=lambda kv: -kv[1])[:12])
        raise InputError(f"{path}: no {sensor} messages in the log ({tables.kind}; it has {listed or 'none'}); "
                         f"magyro needs the {'gyro (IMU)' if sensor == 'IMU' else 'compass (MAG)'} messages: "
                         f"log them (LOG_BITMASK)")
    wanted = sensor + MESSAGES_PER_SENSOR[instance] if instance < len(MESSAGES_PER_SENSOR) else None
    if wanted not in messages:
        listed = ", ".join(f"{n} (instance {MESSAGES_PER_SENSOR.index(n[len(sensor):])})" for n in names)
        raise InputError(f"{path}: {sensor} instance {instance} does not exist; the log has {listed}; choose one "
                         f"with {OPTIONS[sensor]}")
    return wanted, messages[wanted]


def _instance_text(sensor: str, name: str, instance: int) -> str:
    return f" instance {instance}" if name == sensor else ""


def _fresh_times(path: Path, name: str, rows: dict) -> tuple[np.ndarray, float, np.ndarray]:
    """(the stamps kept, seconds per stamp unit, which rows kept): strictly increasing stamps."""
    column = next((c for c in TIME_COLUMNS_S if c in rows), None)
    if column is None:
        raise InputError(f"{path}: the {name} messages have no TimeUS or TimeMS column (columns "
                         f"{', '.join(rows)}); the log is damaged or of an unknown layout")
    stamps = np.asarray(rows[column], dtype=np.float64)
    keep = np.ones(len(stamps), dtype=bool)
    if len(stamps) > 1:
        keep[1:] = stamps[1:] > np.maximum.accumulate(stamps)[:-1]
    return stamps[keep], TIME_COLUMNS_S[column], keep


def _vector(path: Path, name: str, rows: dict, prefix: str, required: bool = True) -> np.ndarray | None:
    columns = [prefix + a for a in AXES]
    missing = [c for c in columns if c not in rows]
    if missing:
        if not required:
            return None
        raise InputError(f"{path}: the {name} messages have no {', '.join(missing)} column (columns "
                         f"{', '.join(rows)}); the log is of an unknown layout")
    return np.column_stack([np.asarray(rows[c], dtype=np.float64) for c in columns])


# --------------------------------------------------------------------------- the magnetometer


def raw_magnetometer_uT(path: Path, tables: LogTables, name: str, rows: dict, instance: int) -> tuple[np.ndarray, str]:
    """(raw magnetometer in uT, how it was made): M^-1 (Mag - MO) - Ofs (module docstring), times the unit."""
    logged_mG = _vector(path, name, rows, "Mag")
    unit = tables.units.get(name, {}).get("MagX", "mGauss")
    if unit not in MAG_UNITS_TO_UT:
        raise InputError(f"{path}: the {name} MagX column is in {unit!r} (its FMTU); magyro knows mGauss and Gauss")
    params = tables.parameters
    motor = _vector(path, name, rows, "MO", required=False)
    if motor is None:
        motor_note = "no motor compensation columns (MO)"
        motor = np.zeros_like(logged_mG)
    else:
        motor_note = "motor compensation MOX..Z subtracted"
    matrix = soft_iron_matrix(params, instance)
    identity = np.array_equal(matrix, np.eye(3))   # no product then: the logged numbers pass unchanged
    corrected = (logged_mG - motor) if identity else (logged_mG - motor) @ np.linalg.inv(matrix).T
    offsets = _vector(path, name, rows, "Ofs", required=False)
    if offsets is not None:
        distinct = np.unique(offsets, axis=0)
        offsets_note = (f"offsets in force at each sample from the MAG OfsX..Z columns ({len(distinct)} distinct "
                        f"offset vector(s), first ({_triple(offsets[0])}), last ({_triple(offsets[-1])}) {unit})")
    else:
        offsets = np.broadcast_to(compass_offsets(params, instance), logged_mG.shape)
        offsets_note = (f"offsets from the parameters {_ofs_names(instance)} ({_triple(offsets[0])} {unit}); the "
                        f"MAG messages have no Ofs columns")
    scale = params.get(_param_name("COMPASS_SCALE", instance), 0.0) or 1.0
    raw = (corrected - offsets) / scale
    matrix_note = ("soft-iron matrix identity (no COMPASS_DIA/ODI)" if identity
                   else f"soft-iron matrix of COMPASS_DIA/ODI inverted: {np.round(matrix, 4).tolist()}")
    note = (f"raw = M^-1 (Mag - MO) - Ofs{' divided by COMPASS_SCALE ' + str(scale) if scale != 1.0 else ''}: "
            f"{offsets_note}; {motor_note}; {matrix_note}; {unit} * {MAG_UNITS_TO_UT[unit]:g} = uT")
    return raw * MAG_UNITS_TO_UT[unit], note


def _param_name(stem: str, instance: int) -> str:
    """ArduPilot's per-instance parameter names: COMPASS_OFS_X, COMPASS_OFS2_X, ...; COMPASS_DIA_X, ..."""
    if "_" in stem.removeprefix("COMPASS_"):
        head, axis = stem.rsplit("_", 1)
        return f"{head}{'' if instance == 0 else instance + 1}_{axis}"
    return f"{stem}{'' if instance == 0 else instance + 1}"


def compass_offsets(params: dict, instance: int) -> np.ndarray:
    return np.array([params.get(_param_name(f"COMPASS_OFS_{a}", instance), 0.0) for a in AXES])


def _ofs_names(instance: int) -> str:
    return "/".join(_param_name(f"COMPASS_OFS_{a}", instance) for a in AXES)


def soft_iron_matrix(params: dict, instance: int) -> np.ndarray:
    """ArduPilot's compass matrix [[DIA_X, ODI_X, ODI_Y], [ODI_X, DIA_Y, ODI_Z], [ODI_Y, ODI_Z, DIA_Z]];
    identity where the log has no such parameters (a diagonal of 0 means 'not set', as ArduPilot reads it)."""
    dia = [params.get(_param_name(f"COMPASS_DIA_{a}", instance), 0.0) for a in AXES]
    odi = [params.get(_param_name(f"COMPASS_ODI_{a}", instance), 0.0) for a in AXES]
    if any(d == 0.0 for d in dia):
        return np.eye(3)
    return np.array([[dia[0], odi[0], odi[1]], [odi[0], dia[1], odi[2]], [odi[1], odi[2], dia[2]]])


def _triple(v) -> str:
    return ", ".join(f"{float(x):.4g}" for x in v)


# --------------------------------------------------------------------------- the reference attitude


def euler_321_deg_to_quat_wxyz(roll_deg, pitch_deg, yaw_deg) -> np.ndarray:
    """The quaternion (w >= 0) of R = Rz(yaw) Ry(pitch) Rx(roll): ArduPilot's body FRD -> NED rotation."""
    r, p, y = (np.radians(np.asarray(a, dtype=np.float64)) / 2.0 for a in (roll_deg, pitch_deg, yaw_deg))
    cr, sr, cp, sp, cy, sy = np.cos(r), np.sin(r), np.cos(p), np.sin(p), np.cos(y), np.sin(y)
    q = np.column_stack([cr * cp * cy + sr * sp * sy,
                         sr * cp * cy - cr * sp * sy,
                         cr * sp * cy + sr * cp * sy,
                         cr * cp * sy - sr * sp * cy])
    return q * np.where(q[:, :1] < 0, -1.0, 1.0)


def _attitude(path: Path, tables: LogTables):
    """(stamps, seconds per unit, quaternions) of ATT, or None for a log without ATT."""
    rows = tables.messages.get("ATT")
    if rows is None or not all(c in rows for c in ("Roll", "Pitch", "Yaw")):
        return None
    stamps, scale, keep = _fresh_times(path, "ATT", rows)
    quat = euler_321_deg_to_quat_wxyz(rows["Roll"][keep], rows["Pitch"][keep], rows["Yaw"][keep])
    return stamps, scale, quat


# --------------------------------------------------------------------------- metadata


def gyro_offsets_text(params: dict, instance: int) -> str:
    stem = "INS_GYROFFS" if instance == 0 else f"INS_GYR{instance + 1}OFFS"
    names = [f"{stem}_{a}" for a in AXES]
    if not all(n in params for n in names):
        return f"the log has no {'/'.join(names)} parameters; the autopilot's gyro offsets are unknown"
    return (f"{', '.join(f'{n} = {params[n]:.6g}' for n in names)} rad/s: already applied by the autopilot (the "
            f"log's gyro is corrected with them; a calibration estimates what is left)")


def _metadata(path, tables, imu_name, imu, mag_name, mag, mag_note, origin, scale, n_imu, n_mag, with_acc, att):
    params = tables.parameters
    unit = "us" if scale == 1e-6 else "ms"
    metadata = {
        "source": str(path),
        "dataflash_file": path.name,
        "imported_from": (f"{tables.kind}: gyro{' and accelerometer' if with_acc else ''} "
                          f"{imu_name}{_instance_text('IMU', imu_name, imu)} ({n_imu} samples), magnetometer "
                          f"{mag_name}{_instance_text('MAG', mag_name, mag)} ({n_mag} samples)"
                          + (f", reference attitude ATT ({len(att[0])} samples)" if att is not None else
                             ", no ATT (no reference attitude)")),
        "gyro_unit": "rad/s",
        "mag_unit": "uT",
        "dataflash_imu": f"{imu_name}{_instance_text('IMU', imu_name, imu)}",
        "dataflash_mag": f"{mag_name}{_instance_text('MAG', mag_name, mag)}",
        "dataflash_units": ("GyrX..Z rad/s as logged; " + ("AccX..Z m/s^2 as logged; " if with_acc else "")
                            + "MagX..Z: " + mag_note),
        "dataflash_mag_raw": mag_note,
        "dataflash_gyro_offsets_applied": gyro_offsets_text(params, imu),
        "dataflash_time_origin": f"{origin:.0f} {unit} (t = 0 s; t = (stamp - origin) * {scale:g})",
        "dataflash_messages": json.dumps(dict(sorted(tables.counts.items()))),
        "dataflash_parameters": json.dumps(dict(sorted(params.items()))),
        "dataflash_notes": "; ".join(tables.notes) or "none",
    }
    if with_acc:
        metadata["acc_unit"] = "m/s^2"
    if att is not None:
        metadata["reference_quaternion"] = (
            "ATT Roll/Pitch/Yaw (deg), ArduPilot's attitude estimate (a reference, not truth): body FRD -> NED, "
            "R = Rz(yaw) Ry(pitch) Rx(roll), v_ned = R v_body")
    return metadata
