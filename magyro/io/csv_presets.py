"""Presets for phone apps' CSV exports: `magyro import csv FILES... --preset sensor-logger|phyphox`.

A preset knows an app's export: which file holds which sensor, the column names, the units
and the time column, so no --gyro-unit/--mag-unit/--map is needed. The sources are the
per-sensor CSV files, or the export folder, or the zip the app writes (read in place,
never changed).

- `sensor-logger` (Sensor Logger by Kelvin Choi, Android/iOS): GyroscopeUncalibrated.csv or
  Gyroscope.csv (rad/s), MagnetometerUncalibrated.csv or Magnetometer.csv (uT), optional
  TotalAcceleration.csv (m/s^2, with gravity); columns time (epoch ns), seconds_elapsed, z,
  y, x. The uncalibrated sensors are preferred when both are present: for a calibration the
  phone's own bias correction must not be in the data. The metadata says which were used.
- `phyphox` (RWTH Aachen): one file per sensor of one experiment, "Time (s)" (the
  experiment clock, shared by its sensors) and axis columns whose unit says the sensor:
  "Gyroscope x (rad/s)" or "X (rad/s)", "Magnetic Field x (µT)" or "X (µT)",
  "Acceleration x (m/s^2)"; any of phyphox's CSV flavours (comma, tab or semicolon, decimal
  point or comma).
"""
from __future__ import annotations

import re
import tempfile
import zipfile
from dataclasses import dataclass
from pathlib import Path

from magyro.errors import InputError
from magyro.io.csv_export import csv_header, import_csv_files
from magyro.session import Session

PRESETS = ("sensor-logger", "phyphox")
_GROUP_COLUMNS = {"gyro": ("gx", "gy", "gz"), "magnetometer": ("mx", "my", "mz"),
                  "accelerometer": ("ax", "ay", "az")}


@dataclass(frozen=True)
class SensorFile:
    """One file of an export: where it is read from, how it is shown, the sensor and its columns."""

    path: Path
    label: str
    group: str
    columns: dict  # session name -> column
    note: str = ""


# --------------------------------------------------------------------------- entry point


def import_preset(sources, preset: str, skip_rows: int = 0, header_line: int = 0,
                  delimiter: str | None = None) -> Session:
    """An app's export (its per-sensor CSV files, its folder or its zip) as a Session, by `preset`."""
    if preset not in PRESETS:
        raise InputError(f"unknown preset {preset!r}; the presets are {', '.join(PRESETS)}")
    sources = [Path(s) for s in sources]
    with tempfile.TemporaryDirectory(prefix="magyro-csv-") as unpacked:
        files = _csv_files(sources, Path(unpacked))
        explicit = not any(s.is_dir() or zipfile.is_zipfile(s) for s in sources if s.exists())
        chosen = _chosen_files(preset, files, explicit, delimiter, header_line)
        units = {"sensor-logger": dict(time_unit="ns"), "phyphox": dict(time_unit="s")}[preset]
        extra = {"preset": preset, "source_given": ", ".join(map(str, sources)),
                 "sensor_note": "; ".join(f.note for f in chosen if f.note)}
        return import_csv_files([f.path for f in chosen], {i: f.columns for i, f in enumerate(chosen)},
                                gyro_unit="rad/s", mag_unit="uT", acc_unit="m/s^2", delimiter=delimiter,
                                skip_rows=skip_rows, header_line=header_line,
                                labels=[f.label for f in chosen], extra_metadata=extra, **units)


def _chosen_files(preset: str, files: list[tuple[Path, str]], explicit: bool, delimiter, header_line) -> list:
    recognise = {"sensor-logger": _sensor_logger_file, "phyphox": _phyphox_file}[preset]
    found = []
    for path, label in files:
        sensor_file = recognise(path, label, delimiter, header_line, explicit)
        if sensor_file is not None:
            found.append(sensor_file)
    chosen = _preferred_per_sensor(preset, found)
    missing = [g for g in ("gyro", "magnetometer") if g not in {f.group for f in chosen}]
    if missing:
        raise InputError(f"no {' and no '.join(missing)} file among {', '.join(l for _, l in files) or '(none)'}; "
                         f"the {preset} preset needs {_needed(preset, missing)}")
    return chosen


# --------------------------------------------------------------------------- sources


def _csv_files(sources: list[Path], unpack_to: Path) -> list[tuple[Path, str]]:
    """(path to read, label) of every CSV given: files as given, a folder's *.csv, a zip's *.csv (unpacked)."""
    files = []
    for source in sources:
        if source.is_dir():
            files += [(p, str(p)) for p in sorted(source.glob("*.csv")) + sorted(source.glob("*.CSV"))]
        elif source.is_file() and zipfile.is_zipfile(source):
            files += _zip_csv_files(source, unpack_to / f"{len(files)}")
        else:
            files.append((source, str(source)))
    return files


def _zip_csv_files(archive: Path, unpack_to: Path) -> list[tuple[Path, str]]:
    """The zip's CSV members outside meta/ folders, unpacked to `unpack_to`, labelled ARCHIVE:MEMBER."""
    out = []
    with zipfile.ZipFile(archive) as z:
        for i, member in enumerate(sorted(z.namelist())):
            parts = Path(member).parts
            if not member.lower().endswith(".csv") or "meta" in parts[:-1] or parts[0] == "__MACOSX":
                continue
            target = unpack_to / f"{i}" / Path(member).name
            target.parent.mkdir(parents=True, exist_ok=True)
            target.write_bytes(z.read(member))
            out.append((target, f"{archive}:{member}"))
    return out


def _preferred_per_sensor(preset: str, found: list[SensorFile]) -> list[SensorFile]:
    """One file per sensor: an uncalibrated file over a calibrated one; two of a kind refused."""
    chosen: dict[str, SensorFile] = {}
    for f in found:
        other = chosen.get(f.group)
        if other is None:
            chosen[f.group] = f
        elif _is_uncalibrated(f) != _is_uncalibrated(other):
            chosen[f.group] = f if _is_uncalibrated(f) else other
        else:
            raise InputError(f"the {f.group} is given twice, by {other.label} and {f.label}; "
                             f"give one {f.group} file (the {preset} preset reads one file per sensor)")
    return [chosen[g] for g in ("gyro", "magnetometer", "accelerometer") if g in chosen]


def _is_uncalibrated(f: SensorFile) -> bool:
    return "uncalibrated" in Path(f.label).name.lower()


# --------------------------------------------------------------------------- Sensor Logger

_SENSOR_LOGGER = {  # file stem (lower case) -> sensor, note for the metadata
    "gyroscopeuncalibrated": ("gyro", "gyro from GyroscopeUncalibrated.csv (uncalibrated)"),
    "gyroscope": ("gyro", "gyro from Gyroscope.csv (calibrated by the phone; GyroscopeUncalibrated.csv is "
                          "better for a calibration)"),
    "magnetometeruncalibrated": ("magnetometer", "magnetometer from MagnetometerUncalibrated.csv (uncalibrated)"),
    "magnetometer": ("magnetometer", "magnetometer from Magnetometer.csv (calibrated by the phone; "
                                     "MagnetometerUncalibrated.csv is better for a calibration)"),
    "totalacceleration": ("accelerometer", "accelerometer from TotalAcceleration.csv (with gravity)"),
}
_SENSOR_LOGGER_COLUMNS = ("time", "seconds_elapsed", "z", "y", "x")


def _sensor_logger_file(path: Path, label: str, delimiter, header_line, explicit: bool) -> SensorFile | None:
    kind = _SENSOR_LOGGER.get(Path(label).stem.lower())
    if kind is None:
        if explicit:
            raise InputError(f"{label}: not a file the sensor-logger preset reads; it reads "
                             f"{', '.join(_sensor_logger_names())} (Accelerometer.csv is without gravity: "
                             f"use TotalAcceleration.csv)")
        return None
    group, note = kind
    header = csv_header(path, delimiter, header_line)
    if not {"time", "x", "y", "z"} <= set(header):
        raise InputError(f"{label}: not a Sensor Logger {group} export: expected the columns "
                         f"{', '.join(_SENSOR_LOGGER_COLUMNS)}, found {', '.join(header) or '(none)'}")
    columns = {"t": "time", **dict(zip(_GROUP_COLUMNS[group], ("x", "y", "z")))}
    return SensorFile(path, label, group, columns, note)


def _sensor_logger_names() -> list[str]:
    return ["GyroscopeUncalibrated.csv", "Gyroscope.csv", "MagnetometerUncalibrated.csv", "Magnetometer.csv",
            "TotalAcceleration.csv"]


# --------------------------------------------------------------------------- phyphox

_PHYPHOX_TIME = re.compile(r"^time\s*\(s\)$", re.IGNORECASE)
_PHYPHOX_AXIS = re.compile(r"(?:^|\s)([xyz])\s*\(([^)]*)\)\s*$", re.IGNORECASE)
_PHYPHOX_UNITS = {"rad/s": "gyro", "µt": "magnetometer", "μt": "magnetometer", "ut": "magnetometer",
                  "m/s^2": "accelerometer", "m/s²": "accelerometer", "m/s2": "accelerometer"}


def _phyphox_file(path: Path, label: str, delimiter, header_line, explicit: bool) -> SensorFile | None:
    header = csv_header(path, delimiter, header_line)
    time_columns = [c for c in header if _PHYPHOX_TIME.match(c)]
    axes = {}  # sensor -> {axis letter: column}
    for column in header:
        m = _PHYPHOX_AXIS.search(column)
        if m and m.group(2).strip().lower() in _PHYPHOX_UNITS:
            axes.setdefault(_PHYPHOX_UNITS[m.group(2).strip().lower()], {})[m.group(1).lower()] = column
    complete = [g for g, cols in axes.items() if set(cols) == {"x", "y", "z"}]
    linear = any("linear" in c.lower() for c in header) or "linear" in Path(label).name.lower()
    if len(time_columns) != 1 or len(complete) != 1 or linear:
        if not explicit:
            return None
        why = ("linear acceleration leaves gravity out; export the accelerometer (with g)" if linear else
               f"expected \"Time (s)\" and x, y, z columns in rad/s, µT or m/s^2, found {', '.join(header) or '(none)'}")
        raise InputError(f"{label}: not a phyphox sensor export the phyphox preset reads: {why}")
    group = complete[0]
    columns = {"t": time_columns[0], **{name: axes[group][a] for name, a in zip(_GROUP_COLUMNS[group], "xyz")}}
    return SensorFile(path, label, group, columns, f"{group} from {Path(label).name}")


def _needed(preset: str, missing: list[str]) -> str:
    if preset == "sensor-logger":
        names = {"gyro": "GyroscopeUncalibrated.csv or Gyroscope.csv",
                 "magnetometer": "MagnetometerUncalibrated.csv or Magnetometer.csv"}
        return " and ".join(names[m] for m in missing) + " (turn those sensors on in Sensor Logger)"
    units = {"gyro": "x, y, z in rad/s (\"Gyroscope x (rad/s)\")",
             "magnetometer": "x, y, z in µT (\"Magnetic Field x (µT)\")"}
    return " and ".join(f"a {m} file with \"Time (s)\" and {units[m]}" for m in missing)


# --------------------------------------------------------------------------- the command


def convert_csv(sources, output, *, preset: str | None = None, column_map_items=None, gyro_unit: str | None = None,
                mag_unit: str | None = None, time_unit: str = "s", acc_unit: str = "m/s^2",
                delimiter: str | None = None, skip_rows: int = 0, header_line: int = 0,
                start_s: float | None = None, end_s: float | None = None) -> Session:
    """`magyro import csv`: one CSV, one CSV per sensor, or an app's export (`preset`), cut to
    [start_s, end_s] and written to `output` (`write_imported`). `column_map_items` are the CLI's
    --map items (NAME=COLUMN, or NAME=FILE:COLUMN with several files). An `output` that is a source or
    cannot be written is refused before anything is read. Returns the written session."""
    from magyro.io.csv_export import import_csv, parse_column_map, parse_file_column_map
    from magyro.io.cutting import cut
    from magyro.io.session_file import import_to_file

    sources = [Path(s) for s in sources]

    def read() -> Session:
        if preset is not None:
            given = [name for name, value in (("--gyro-unit", gyro_unit), ("--mag-unit", mag_unit),
                                              ("--map", column_map_items)) if value]
            if given:
                raise InputError(f"--preset {preset} knows the units and columns; leave out {', '.join(given)}")
            session = import_preset(sources, preset, skip_rows=skip_rows, header_line=header_line, delimiter=delimiter)
        else:
            missing = [name for name, value in (("--gyro-unit", gyro_unit), ("--mag-unit", mag_unit)) if value is None]
            if missing:
                raise InputError(f"give {' and '.join(missing)} (the units of the CSV columns), or --preset "
                                 f"sensor-logger|phyphox for those apps' exports")
            units = dict(gyro_unit=gyro_unit, mag_unit=mag_unit, time_unit=time_unit, acc_unit=acc_unit,
                         delimiter=delimiter, skip_rows=skip_rows, header_line=header_line)
            if len(sources) == 1:
                session = import_csv(sources[0], parse_column_map(column_map_items), **units)
            else:
                session = import_csv_files(sources, parse_file_column_map(column_map_items, sources), **units)
        return cut(session, start_s, end_s)

    return import_to_file(sources, output, read)
