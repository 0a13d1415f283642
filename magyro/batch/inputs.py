"""What a batch calibrates: its inputs (files, folders, globs, manifests) as one list of devices.

Each input of `magyro batch INPUTS...` is one of:

- a session file (.parquet or .csv): one device, named by the file's stem;
- a folder: every session file directly in it (sorted), each named by its stem;
- a glob (`runs/*/session.parquet`, quoted so the shell leaves it): every match, sorted;
- a manifest: a CSV file with a header holding `device_id` and `session` (the session's
  path, relative to the manifest's folder), one device per row; other columns are kept
  out of the way. `magyro simulate PROBLEM --seeds A-B -o DIR` writes one.

A device id names the device's files in OUTDIR, so it must be unique in the batch and
made of letters, digits, '.', '_' and '-' (a file stem with other characters has them
replaced by '_'; a manifest's id is taken as it is, and refused if it does not fit).
Everything is checked before any work: a missing input, an empty folder or glob, a
manifest without its columns or naming a missing file, two devices with one id: one
InputError (exit 2) naming it.
"""
from __future__ import annotations

import csv
import glob
import re
from dataclasses import dataclass
from pathlib import Path

from magyro.errors import InputError

SESSION_SUFFIXES = (".parquet", ".csv")
MANIFEST_COLUMNS = ("device_id", "session")
ID_PATTERN = re.compile(r"^[A-Za-z0-9._-]{1,128}$")


@dataclass(frozen=True)
class Device:
    """One device of the batch: its id and its session file."""

    device_id: str
    session: Path


def devices_from_inputs(inputs: list[str]) -> list[Device]:
    """Every device the inputs name, in the order given; InputError (exit 2) on anything unusable."""
    if not inputs:
        raise InputError("no inputs: give session files, folders, globs or a manifest CSV (device_id,session)")
    devices: list[Device] = []
    for text in inputs:
        devices.extend(devices_from_input(str(text)))
    check_unique(devices)
    check_readable(devices)
    return devices


def devices_from_input(text: str) -> list[Device]:
    path = Path(text)
    if path.is_dir():
        candidates = sorted(p for p in path.iterdir() if p.suffix.lower() in SESSION_SUFFIXES
                            and p.name != "manifest.csv" and not p.name.startswith("."))
        check_links(candidates)
        files = [p for p in candidates if p.is_file() and not is_batch_summary(p)]
        if not files:
            raise InputError(f"{text}: a folder with no session file (.parquet or .csv) directly in it")
        return [device_from_file(p) for p in files]
    if path.is_file():
        return manifest_devices(path) if is_manifest(path) else [device_from_file(path)]
    if glob.has_magic(text):
        matches = sorted(Path(p) for p in glob.glob(text, recursive=True))
        check_links(matches)
        files = [p for p in matches if p.is_file()]
        if not files:
            raise InputError(f"{text}: no file matches this pattern")
        return [device_from_file(p) for p in files]
    raise InputError(f"{text}: no such file or folder")


def check_links(paths: list[Path]) -> None:
    """InputError for a symbolic link that leads nowhere (dangling, or a loop): named, not silently dropped."""
    for p in paths:
        if p.is_symlink() and not p.exists():
            raise InputError(f"{p}: a symbolic link that leads to no file (dangling, or a loop); remove it or fix "
                             "its target")


def is_batch_summary(path: Path) -> bool:
    """True for a fleet summary a batch wrote (summary.parquet / summary.csv with the summary's columns): in a
    folder that is also OUTDIR it is the batch's own output, never a device. A recording of that name is not."""
    from magyro.batch.summary import ACC_COLUMNS, FILES, SUMMARY_COLUMNS, columns_for

    if path.name not in (FILES["parquet"], FILES["csv"]):
        return False
    layouts = (list(SUMMARY_COLUMNS), columns_for([dict.fromkeys(ACC_COLUMNS)]))   # with the accelerometer's too
    try:
        if path.suffix == ".parquet":
            import pyarrow.parquet as pq

            return pq.read_schema(path).names in layouts
        with open(path, newline="", encoding="utf-8", errors="replace") as f:
            return next(csv.reader(f), []) in layouts
    except Exception:   # noqa: BLE001 - unreadable as a summary: then it is not one (the device reader says why)
        return False


def check_readable(devices: list[Device]) -> None:
    """InputError naming the first session that cannot be opened for reading (before any work)."""
    for d in devices:
        try:
            with open(d.session, "rb"):
                pass
        except PermissionError:
            raise InputError(f"{d.session}: cannot be read: permission denied (unreadable input)") from None
        except OSError as exc:
            raise InputError(f"{d.session}: cannot be read ({exc.strerror or exc})") from None


def device_from_file(path: Path) -> Device:
    if path.suffix.lower() not in SESSION_SUFFIXES:
        raise InputError(f"{path}: not a session file (.parquet or .csv) nor a manifest")
    return Device(re.sub(r"[^A-Za-z0-9._-]", "_", path.stem)[:128] or "device", path)


def is_manifest(path: Path) -> bool:
    """A CSV whose header names device_id and session."""
    if path.suffix.lower() != ".csv":
        return False
    try:
        with open(path, "rb") as f:
            first = f.readline(1 << 16).decode("utf-8", errors="replace").lstrip("\ufeff")
    except OSError:
        return False
    header = next(csv.reader([first]), [])
    return all(c in [h.strip() for h in header] for c in MANIFEST_COLUMNS)


def manifest_text(path: Path) -> str:
    """The manifest's text; InputError naming the first line that is not UTF-8."""
    try:
        raw = path.read_bytes()
    except PermissionError:
        raise InputError(f"{path}: cannot be read: permission denied (unreadable input)") from None
    try:
        return raw.decode("utf-8-sig")
    except UnicodeDecodeError as exc:
        line = raw.count(b"\n", 0, exc.start) + 1
        raise InputError(f"{path} line {line}: not UTF-8 text (byte {exc.start}); a manifest is a UTF-8 CSV") from None


def manifest_devices(path: Path) -> list[Device]:
    """The devices of a manifest CSV (device_id, session relative to the manifest's folder)."""
    devices = []
    import io

    with io.StringIO(manifest_text(path), newline="") as f:
        for line, record in enumerate(csv.DictReader(f), start=2):
            record = {(k or "").strip(): (v or "").strip() for k, v in record.items()}
            device_id, session = record.get("device_id", ""), record.get("session", "")
            if not device_id and not session:
                continue
            if not ID_PATTERN.match(device_id):
                raise InputError(f"{path} line {line}: device_id {device_id!r} must be 1-128 letters, digits, "
                                 "'.', '_' or '-' (it names the device's files)")
            file = Path(session) if Path(session).is_absolute() else path.parent / session
            if not session or not file.is_file():
                raise InputError(f"{path} line {line}: device {device_id}'s session {session!r} is not a file "
                                 f"(looked for {file})")
            devices.append(Device(device_id, file))
    if not devices:
        raise InputError(f"{path}: a manifest with no device in it")
    return devices


def check_unique(devices: list[Device]) -> None:
    seen: dict[str, Path] = {}
    for d in devices:
        if d.device_id in seen:
            raise InputError(f"two sessions have the device id {d.device_id}: {seen[d.device_id]} and {d.session}; "
                             "rename one, or list them in a manifest with their own ids")
        seen[d.device_id] = d.session
