"""Presets for phone apps' CSV exports: `magyro import csv FILES... --preset sensor-logger|phyphox`.

A preset knows an app's export: which file holds which sensor, the column names, the units
and the time column, so no --gyro-unit/--mag-unit/--map is needed. The sources are the
per-sensor CSV files, or the export folder, or the zip the app writes (read in place,
never changed); a zip is unpacked with caps on what it inflates to (`magyro.io.csv_zip`).

Without --preset, `recognised_preset(sources)` finds files in either app's layout (Sensor
Logger's `time, seconds_elapsed, z, y, x`; phyphox's `"Time (s)"` and axes with units), and
`magyro import csv` reads them by that preset.

- `sensor-logger` (Sensor Logger by Kelvin Choi, Android/iOS): GyroscopeUncalibrated.csv or
  Gyroscope.csv (rad/s), MagnetometerUncalibrated.csv or Magnetometer.csv (uT), optional
  AccelerometerUncalibrated.csv (with gravity; g on iOS, m/s^2 on Android: told from |a|) or
  TotalAcceleration.csv (m/s^2, with gravity); columns time (epoch ns), seconds_elapsed, z,
  y, x. The uncalibrated sensors are preferred when both are present: for a calibration the
  phone's own bias correction must not be in the data. The metadata says which were used.
  The zip may hold the CSVs at its top level or in a folder.
- `phyphox` (RWTH Aachen): one file per sensor of one experiment, "Time (s)" (the
  experiment clock, shared by its sensors) and axis columns whose unit says the sensor:
  "Gyroscope x (rad/s)" or "X (rad/s)", "Magnetic Field x (µT)" or "X (µT)",
  "Acceleration x (m/s^2)"; any of phyphox's CSV flavours (comma, tab or semicolon, decimal
  point or comma).
"""
from __future__ import annotations

import re
import tempfile
from dataclasses import dataclass
from pathlib import Path

from magyro.errors import InputError
from magyro.io.csv_import import ACC_AUTO, import_csv_files
from magyro.io.csv_text import checked_read_options, csv_header
from magyro.io.csv_zip import is_zip, unpack_csv_members
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
    acc_unit_from_gravity: bool = False  # g or m/s^2, told from |a| (Sensor Logger's AccelerometerUncalibrated.csv)


# --------------------------------------------------------------------------- entry point


def import_preset(sources, preset: str, skip_rows: int = 0, header_line: int = 0,
                  delimiter: str | None = None) -> Session:
    """An app's export (its per-sensor CSV files, its folder or its zip) as a Session, by `preset`."""
    if preset not in PRESETS:
        raise InputError(f"unknown preset {preset!r}; the presets are {', '.join(PRESETS)}")
    delimiter = checked_read_options(delimiter, skip_rows, header_line)
    sources = [Path(s) for s in sources]
    with tempfile.TemporaryDirectory(prefix="magyro-csv-") as unpacked:
        files = _csv_files(sources, Path(unpacked), _WANTED[preset])
        explicit = not any(s.is_dir() or is_zip(s) for s in sources)
        chosen = _chosen_files(preset, files, explicit, delimiter, header_line)
        units = {"sensor-logger": dict(time_unit="ns"), "phyphox": dict(time_unit="s")}[preset]
        acc_unit = ACC_AUTO if any(f.acc_unit_from_gravity for f in chosen) else "m/s^2"
        notes = [f.note for f in chosen if f.note] + _left_out(preset, files, chosen)
        if explicit:
            notes += _accelerometer_beside(preset, sources, chosen, delimiter, header_line)
        extra = {"preset": preset, "source_given": ", ".join(map(str, sources)), "sensor_note": "; ".join(notes)}
        return import_csv_files([f.path for f in chosen], {i: f.columns for i, f in enumerate(chosen)},
                                gyro_unit="rad/s", mag_unit="uT", acc_unit=acc_unit, delimiter=delimiter,
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


def _left_out(preset: str, files: list[tuple[Path, str]], chosen: list) -> list[str]:
    """A note for an export whose only accelerometer file is Sensor Logger's Accelerometer.csv: it is the phone's
    acceleration without gravity, so the session has no accelerometer (and `--accelerometer` says why)."""
    if preset != "sensor-logger" or any(f.group == "accelerometer" for f in chosen):
        return []
    if not any(path.name.lower() == "accelerometer.csv" for path, _ in files):
        return []
    return [ACCELEROMETER_WITHOUT_GRAVITY]


def _accelerometer_beside(preset: str, sources: list[Path], chosen: list, delimiter, header_line) -> list[str]:
    """A note for files given one by one without an accelerometer while the export's accelerometer file lies
    beside them (the folder form would read it): it was left out, and how to read it too."""
    if any(f.group == "accelerometer" for f in chosen):
        return []
    given = {s.resolve() for s in sources}
    recognise = {"sensor-logger": _sensor_logger_file, "phyphox": _phyphox_file}[preset]
    beside = []
    for folder in dict.fromkeys(s.resolve().parent for s in sources):
        for path in sorted(folder.glob("*.csv")) + sorted(folder.glob("*.CSV")):
            if path.resolve() in given or not path.is_file():
                continue
            try:
                found = recognise(path, str(path), delimiter, header_line, False)
            except (InputError, OSError, UnicodeDecodeError):
                continue
            if found is not None and found.group == "accelerometer":
                beside.append(found)
    if not beside:
        return []
    best = next((f for f in beside if _is_uncalibrated(f)), beside[0])
    name, folder = best.path.name, best.path.parent
    return [f"no accelerometer: {name} beside the given files was left out (files given one by one are read "
            f"alone); give it too (magyro import csv ... {name} --preset {preset}) or the export folder "
            f"({folder}) to calibrate the accelerometer as well"]


ACCELEROMETER_WITHOUT_GRAVITY = ("no accelerometer: Accelerometer.csv left out, it is the phone's acceleration "
                                 "without gravity; record TotalAcceleration or AccelerometerUncalibrated to "
                                 "calibrate the accelerometer")


# --------------------------------------------------------------------------- sources


def _csv_files(sources: list[Path], unpack_to: Path, wanted=lambda name: True) -> list[tuple[Path, str]]:
    """(path to read, label) of every CSV given: files as given, a folder's *.csv, a zip's *.csv that
    `wanted(file name)` (unpacked under `unpack_to`, within the caps of `magyro.io.csv_zip`)."""
    files = []
    for source in sources:
        if source.is_dir():
            files += [(p, str(p)) for p in sorted(source.glob("*.csv")) + sorted(source.glob("*.CSV"))]
        elif is_zip(source):
            files += unpack_csv_members(source, unpack_to / f"{len(files)}", wanted)
        elif source.suffix.lower() == ".zip" and source.is_file():
            raise InputError(f"{source}: not a readable zip (no zip directory at its end: cut short, or not a zip); "
                             f"copy or export it again")
        else:
            files.append((source, str(source)))
    return files


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
    return "uncalibrated" in f.path.name.lower()


# --------------------------------------------------------------------------- Sensor Logger

_SENSOR_LOGGER = {  # file stem (lower case) -> sensor, note for the metadata
    "gyroscopeuncalibrated": ("gyro", "gyro from GyroscopeUncalibrated.csv (uncalibrated)"),
    "gyroscope": ("gyro", "gyro from Gyroscope.csv (calibrated by the phone; GyroscopeUncalibrated.csv is "
                          "better for a calibration)"),
    "magnetometeruncalibrated": ("magnetometer", "magnetometer from MagnetometerUncalibrated.csv (uncalibrated)"),
    "magnetometer": ("magnetometer", "magnetometer from Magnetometer.csv (calibrated by the phone; "
                                     "MagnetometerUncalibrated.csv is better for a calibration)"),
    "accelerometeruncalibrated": ("accelerometer", "accelerometer from AccelerometerUncalibrated.csv (with gravity; "
                                                   "g on iOS, m/s^2 on Android, told from |a|)"),
    "totalacceleration": ("accelerometer", "accelerometer from TotalAcceleration.csv (with gravity)"),
}
_SENSOR_LOGGER_COLUMNS = ("time", "seconds_elapsed", "z", "y", "x")


def _sensor_logger_file(path: Path, label: str, delimiter, header_line, explicit: bool) -> SensorFile | None:
    kind = _SENSOR_LOGGER.get(path.stem.lower())  # the file's own name: a zip member's label is ARCHIVE:MEMBER
    if kind is None:
        if explicit:
            raise InputError(f"{label}: not a file the sensor-logger preset reads; it reads "
                             f"{', '.join(_sensor_logger_names())} (Accelerometer.csv is without gravity: "
                             f"use TotalAcceleration.csv)")
        return None
    group, note = kind
    header = csv_header(path, delimiter, header_line)
    if not is_sensor_logger_header(header):
        found = ", ".join(header) or "(none)"
        raise InputError(f"{label}: not a Sensor Logger {group} export: expected the columns "
                         f"{', '.join(_SENSOR_LOGGER_COLUMNS)}, found {found[:200]}{'...' if len(found) > 200 else ''}")
    columns = {"t": "time", **dict(zip(_GROUP_COLUMNS[group], ("x", "y", "z")))}
    return SensorFile(path, label, group, columns, note,
                      acc_unit_from_gravity=path.stem.lower() == "accelerometeruncalibrated")


def is_sensor_logger_header(header: list[str]) -> bool:
    return {"time", "x", "y", "z"} <= set(header)


def _sensor_logger_names() -> list[str]:
    return ["GyroscopeUncalibrated.csv", "Gyroscope.csv", "MagnetometerUncalibrated.csv", "Magnetometer.csv",
            "AccelerometerUncalibrated.csv", "TotalAcceleration.csv"]


def _is_sensor_logger_member(name: str) -> bool:
    """A zip member the preset unpacks: its files, and Accelerometer.csv (not read: its lack of gravity is noted)."""
    return Path(name).stem.lower() in _SENSOR_LOGGER or Path(name).name.lower() == "accelerometer.csv"


_WANTED = {"sensor-logger": _is_sensor_logger_member, "phyphox": lambda name: True}


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
    linear = any("linear" in c.lower() for c in header) or "linear" in path.name.lower()
    if len(time_columns) != 1 or len(complete) != 1 or linear:
        if not explicit:
            return None
        why = ("linear acceleration leaves gravity out; export the accelerometer (with g)" if linear else
               f"expected \"Time (s)\" and x, y, z columns in rad/s, µT or m/s^2, found {', '.join(header) or '(none)'}")
        raise InputError(f"{label}: not a phyphox sensor export the phyphox preset reads: {why}")
    group = complete[0]
    columns = {"t": time_columns[0], **{name: axes[group][a] for name, a in zip(_GROUP_COLUMNS[group], "xyz")}}
    return SensorFile(path, label, group, columns, f"{group} from {path.name}")


def _needed(preset: str, missing: list[str]) -> str:
    if preset == "sensor-logger":
        names = {"gyro": "GyroscopeUncalibrated.csv or Gyroscope.csv",
                 "magnetometer": "MagnetometerUncalibrated.csv or Magnetometer.csv"}
        return " and ".join(names[m] for m in missing) + " (turn those sensors on in Sensor Logger)"
    units = {"gyro": "x, y, z in rad/s (\"Gyroscope x (rad/s)\")",
             "magnetometer": "x, y, z in µT (\"Magnetic Field x (µT)\")"}
    return " and ".join(f"a {m} file with \"Time (s)\" and {units[m]}" for m in missing)


# --------------------------------------------------------------------------- recognised without --preset


def recognised_preset(sources, delimiter: str | None = None, header_line: int = 0) -> str | None:
    """The preset whose layout every source has (Sensor Logger's time, seconds_elapsed, z, y, x under its file
    names; phyphox's "Time (s)" with one sensor's axes in units), or None; a folder is judged by its CSVs, a zip
    by the first line of its Sensor Logger members."""
    sources = [Path(s) for s in sources]
    if not sources or not all(s.exists() for s in sources):
        return None
    if all(is_zip(s) for s in sources):
        return "sensor-logger" if all(_zip_holds_sensor_logger_files(s) for s in sources) else None
    if all(s.is_dir() for s in sources):
        files = [p for s in sources for p in sorted(s.glob("*.csv")) + sorted(s.glob("*.CSV"))]
        logger = [p for p in files if _is_sensor_logger_member(p.name)]
        if logger and _all_in_layout(logger, "sensor-logger", delimiter, header_line):
            return "sensor-logger"
        phyphox = [p for p in files if _readable_phyphox(p, delimiter, header_line)]
        if len(phyphox) >= 2:
            return "phyphox"
        for p in logger:  # Sensor Logger's file names, one of them not its file: name it and why
            if p.stem.lower() in _SENSOR_LOGGER and p not in phyphox:
                _sensor_logger_file(p, str(p), delimiter, header_line, explicit=True)
        return None
    if not all(s.is_file() and not is_zip(s) for s in sources):
        return None
    for preset in PRESETS:
        if _all_in_layout(sources, preset, delimiter, header_line):
            return preset
    return None


def _readable_phyphox(path: Path, delimiter, header_line) -> bool:
    """A folder's CSV in phyphox's layout; one that cannot be read is not (a preset that reads it names it)."""
    try:
        return _is_phyphox_layout(path, csv_header(path, delimiter, header_line), delimiter, header_line)
    except InputError:
        return False


def _all_in_layout(files: list[Path], preset: str, delimiter, header_line) -> bool:
    headers = [csv_header(f, delimiter, header_line) for f in files]
    if preset == "sensor-logger":
        return all(_is_sensor_logger_member(f.name) and is_sensor_logger_header(h) and "seconds_elapsed" in h
                   for f, h in zip(files, headers))
    return all(_is_phyphox_layout(f, h, delimiter, header_line) for f, h in zip(files, headers))


def _is_phyphox_layout(path: Path, header: list[str], delimiter, header_line) -> bool:
    """A phyphox sensor file and nothing else: "Time (s)", one sensor's x y z, and perhaps its "Absolute" column
    (a logger's CSV holding several sensors, in other units too, is no phyphox export)."""
    found = _phyphox_file(path, str(path), delimiter, header_line, explicit=False)
    if found is None:
        return False
    return all(c in found.columns.values() or c.lower().startswith("absolute") for c in header)


_HEADER_PEEK_BYTES = 4096


def _zip_holds_sensor_logger_files(archive: Path) -> bool:
    """Sensor Logger's file names whose first line is its header (at most 4 kB inflated per member); a member
    that cannot be read counts as one, so that the preset's unpacking names what is wrong with it."""
    import zipfile
    import zlib

    with zipfile.ZipFile(archive) as z:
        members = [i for i in z.infolist() if i.filename.lower().endswith(".csv")
                   and _is_sensor_logger_member(Path(i.filename).name)]
        for info in members:
            try:
                with z.open(info) as f:
                    first = f.read(_HEADER_PEEK_BYTES).decode("utf-8", "replace").lstrip("\ufeff").splitlines()
            except (RuntimeError, NotImplementedError, zipfile.BadZipFile, zlib.error, EOFError):
                # encrypted, an unknown compression, damaged: the preset's unpacking refuses it by name
                return True
            header = [c.strip() for c in first[0].split(",")] if first else []
            if not (is_sensor_logger_header(header) and "seconds_elapsed" in header):
                return False
        return bool(members)


_PRESET_UNITS = {"sensor-logger": ("rad/s", "uT"), "phyphox": ("rad/s", "uT")}
_APP_NAMES = {"sensor-logger": "Sensor Logger", "phyphox": "phyphox"}


def _recognised_or_refused(sources, preset: str, gyro_unit, mag_unit) -> None:
    """Sources in an app's layout are read by its preset; units given that are not the app's are refused."""
    from magyro.io.csv_units import gyro_unit_label, mag_unit_label

    app_gyro, app_mag = _PRESET_UNITS[preset]
    wrong = [f"{option} {given}" for option, given, label, app in
             (("--gyro-unit", gyro_unit, gyro_unit_label, app_gyro), ("--mag-unit", mag_unit, mag_unit_label, app_mag))
             if given is not None and label("--preset", given) != label("--preset", app)]
    if wrong:
        raise InputError(f"{', '.join(map(str, sources))}: a {_APP_NAMES[preset]} export, whose gyro is in {app_gyro} and "
                         f"magnetometer in {app_mag}, not {' and '.join(wrong)}; import it with --preset {preset} "
                         f"and without --gyro-unit/--mag-unit")


# --------------------------------------------------------------------------- the command


def convert_csv(sources, output, *, preset: str | None = None, column_map_items=None, gyro_unit: str | None = None,
                mag_unit: str | None = None, time_unit: str | None = None, acc_unit: str | None = None,
                delimiter: str | None = None, skip_rows: int = 0, header_line: int = 0,
                start_s: float | None = None, end_s: float | None = None, rate_hz: float | None = None) -> Session:
    """`magyro import csv`: one CSV, one CSV per sensor, or an app's export (`preset`, or recognised without
    one and without --map), cut to [start_s, end_s] and written to `output` (`write_imported`).
    `column_map_items` are the CLI's --map items (NAME=COLUMN, or NAME=FILE:COLUMN with several files);
    `rate_hz` (--rate) is the sampling rate of one CSV whose time is a sample counter (or absent). Unusable
    options, and an `output` that is a source or cannot be written, are refused before anything is read.
    Returns the written session; its metadata's sensor_note says when a preset was recognised."""
    from magyro.io.csv_columns import parse_column_map, parse_file_column_map
    from magyro.io.csv_import import checked_rate_hz, import_csv
    from magyro.io.cutting import cut
    from magyro.io.session_file import import_to_file

    sources = [Path(s) for s in sources]
    delimiter = checked_read_options(delimiter, skip_rows, header_line)
    if rate_hz is not None:
        checked_rate_hz(rate_hz)
        if preset is not None or len(sources) != 1:
            raise InputError("--rate is for one CSV file whose time column is a sample counter (or which has none); "
                             "leave it out with --preset or several files")

    def read() -> Session:
        chosen, recognised = preset, False
        if chosen is None and not column_map_items and rate_hz is None:
            chosen = recognised_preset(sources, delimiter, header_line)
            recognised = chosen is not None
            if recognised:
                _recognised_or_refused(sources, chosen, gyro_unit, mag_unit)
        if chosen is not None:
            given = [name for name, value in (("--gyro-unit", gyro_unit), ("--mag-unit", mag_unit),
                                              ("--map", column_map_items)) if value and not recognised]
            if given:
                raise InputError(f"--preset {chosen} knows the units and columns; leave out {', '.join(given)}")
            session = import_preset(sources, chosen, skip_rows=skip_rows, header_line=header_line, delimiter=delimiter)
            if recognised:
                note = f"read as a {_APP_NAMES[chosen]} export (--preset {chosen})"
                session.metadata["sensor_note"] = "; ".join(x for x in (note, session.metadata.get("sensor_note")) if x)
        else:
            folders = [str(s) for s in sources if s.is_dir() or is_zip(s)]
            if folders:
                raise InputError(f"{', '.join(folders)}: an app's export folder or zip is read with --preset "
                                 f"sensor-logger|phyphox; give other CSV files one by one")
            units = dict(gyro_unit=gyro_unit, mag_unit=mag_unit, time_unit=time_unit, acc_unit=acc_unit,
                         delimiter=delimiter, skip_rows=skip_rows, header_line=header_line)
            if len(sources) == 1:
                session = import_csv(sources[0], parse_column_map(column_map_items), rate_hz=rate_hz, **units)
            else:
                session = import_csv_files(sources, parse_file_column_map(column_map_items, sources), **units)
        return cut(session, start_s, end_s)

    return import_to_file(sources, output, read)
