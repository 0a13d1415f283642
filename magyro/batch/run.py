"""`magyro batch`: many devices calibrated on an executor, each kept on disk as it arrives, then the fleet summary.

OUTDIR holds, per device, `calibrations/ID.json` (the calibration, as `magyro solve -o`
writes it), `reports/ID.html` with `--reports`, and `rows/ID.json` (its summary row and
the hashes it was made from); then `summary.parquet`, `summary.csv` and `summary.html`
for the whole batch (`magyro.batch.summary`), with each device's acceptance verdict
against the limits (`magyro.batch.limits`).

Kernels: the first device is solved alone, then the rest side by side, so on a machine whose
kernel cache is empty the solver's kernels are compiled once, not by every worker at once.

Resuming: a device whose row is on disk with the same input hash (SHA-256 of the
session file's bytes) and the same options hash (the options, method, knobs, units
and magyro's version) is not solved again; `redo=True` solves everything. The limits
are not in the options hash: new limits re-judge the fleet without a solve. Each file
is written whole by the client as its device finishes (the row last), so a batch killed
at any moment and run again finishes the rest without redoing a device.

Isolation: a device that fails, whatever the cause (an unusable file, too little
motion, a solver failure, a worker that dies under it), is a row with its exit code and
message; the others go on. A device that crashed (a bug, a dead worker) is tried again by a rerun. Memory: at most a few devices per worker are in flight, and
the client keeps only their rows' file names until the summary is written.
"""
from __future__ import annotations

import dataclasses
import hashlib
import json
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Callable

from magyro.batch.inputs import Device, devices_from_inputs
from magyro.batch.row import CRASHED, row_from_failure
from magyro.batch.task import DeviceTask, calibrate_device
from magyro.errors import InputError
from magyro.io.atomic import check_outputs
from magyro.options import Options

ROW_SCHEMA = "magyro.batch-row/1"
HASH_CHUNK_BYTES = 1 << 20


@dataclass
class BatchResult:
    """What a batch did: its devices' rows (with verdicts), the counts, where the summary is."""

    rows: list
    solved: int                 # devices solved in this run
    reused: int                 # devices whose row was on disk (resumed)
    seconds: float
    executor: str
    summary_paths: dict

    def count(self, verdict: str) -> int:
        return sum(1 for r in self.rows if r.get("verdict") == verdict)

    def table(self) -> str:
        lines = [f"{len(self.rows)} devices: {self.count('accepted')} accepted, {self.count('rejected')} rejected, "
                 f"{self.count('failed')} failed ({self.solved} solved now, {self.reused} kept from an earlier run, "
                 f"{self.seconds:.1f} s on {self.executor})"]
        for r in self.rows:
            if r.get("verdict") != "accepted":
                lines.append(f"  {r['device_id']}: {r.get('verdict')}: {r.get('verdict_reason')}")
        return "\n".join(lines)


def run_batch(inputs: list, outdir, options: Options | None = None, *, method: str = "nls",
              knobs: dict | None = None, limits=None, jobs: int = 1, scheduler: str | None = None,
              redo: bool = False, reports: bool = False, gyro_unit: str | None = None, mag_unit: str | None = None,
              progress: Callable[[int, int, dict], None] | None = None, executor=None) -> BatchResult:
    """Calibrate every device the inputs name (see `magyro.batch.inputs`) into `outdir`; the fleet's summary.

    `limits` is a `magyro.batch.limits.Limits` (or None: every calibrated device is accepted);
    `progress(done, total, row)` is called as each device finishes (resumed ones included).
    `executor` (a `magyro.executor` executor, not yet entered) replaces the one `jobs` and `scheduler` choose.
    """
    from magyro.batch.limits import with_verdicts
    from magyro.batch.summary import write_summary
    from magyro.executor import executor_for, run_unordered

    t0 = time.perf_counter()
    options = options or Options()
    devices = devices_from_inputs([str(i) for i in inputs])
    executor = executor or executor_for(jobs, scheduler)
    executor.check()   # before any output is made
    out = prepare_outdir(outdir, devices, reports)
    digest = options_digest(options, method, knobs or {}, gyro_unit, mag_unit, reports)
    tasks, rows, reused = [], {}, 0
    for device in devices:
        input_digest = file_digest(device.session)
        kept = None if redo else kept_row(out, device, input_digest, digest)
        if kept is not None:
            rows[device.device_id] = kept
            reused += 1
            if progress is not None:
                progress(len(rows), len(devices), kept)
        else:
            tasks.append((DeviceTask(device.device_id, str(device.session), options, method, dict(knobs or {}),
                                     gyro_unit, mag_unit, reports), input_digest))

    def done(item, result, error) -> None:
        task, input_digest = item
        if error is not None:   # the worker died under it, or the result could not come back
            result = {"row": row_from_failure(task.device_id, task.session, error), "calibration_json": None,
                      "report_html": None}
        row = store_device(out, task.device_id, result, input_digest, digest)
        rows[task.device_id] = row
        if progress is not None:
            progress(len(rows), len(devices), row)

    with executor:
        run_unordered(executor, calibrate_device, tasks, done, arguments=lambda item: (item[0],), warm_first=True)
    ordered = with_verdicts([rows[d.device_id] for d in devices], limits)
    paths = write_summary(ordered, out, limits)
    return BatchResult(ordered, len(tasks), reused, time.perf_counter() - t0, executor.describe(), paths)


# --------------------------------------------------------------------------- on disk


def prepare_outdir(outdir, devices: list[Device], reports: bool) -> Path:
    """OUTDIR and its folders, made before any work; InputError when it cannot be, or when an input is inside
    the folders magyro writes."""
    out = Path(outdir)
    if out.exists() and not out.is_dir():
        raise InputError(f"{out}: the batch's output must be a folder, and this is a file")
    folders = [out / "calibrations", out / "rows"] + ([out / "reports"] if reports else [])
    for d in devices:
        if any(_inside(d.session, f) for f in folders):
            raise InputError(f"{d.session} is inside {out}'s own folders, which the batch writes: move the sessions "
                             "or choose another output folder")
    made = [f for f in [out] + folders if not f.exists()]
    try:
        for folder in folders:
            folder.mkdir(parents=True, exist_ok=True)
        check_outputs([d.session for d in devices], output_paths(out, devices, reports))  # an output is never an input
    except (OSError, InputError) as exc:
        for folder in reversed(made):   # refused before any work: leave no folder behind
            try:
                folder.rmdir()
            except OSError:
                pass
        if isinstance(exc, InputError):
            raise
        raise InputError(f"{out}: cannot make the batch's output folders ({exc.strerror or exc})") from None
    return out


def output_paths(out: Path, devices: list[Device], reports: bool) -> list[Path]:
    """Every file the batch may write, each confined to its folder: per device its calibration, row (and report),
    then the summary's files."""
    from magyro.batch.summary import FILES
    from magyro.io.atomic import confined

    paths = []
    for d in devices:
        paths += [confined(out / "calibrations", f"{d.device_id}.json"), confined(out / "rows", f"{d.device_id}.json")]
        if reports:
            paths.append(confined(out / "reports", f"{d.device_id}.html"))
    return paths + [out / name for name in FILES.values()]


def _inside(path: Path, folder: Path) -> bool:
    try:
        Path(path).resolve().relative_to(folder.resolve())
        return True
    except ValueError:
        return False


def file_digest(path) -> str:
    """SHA-256 of a file's bytes."""
    h = hashlib.sha256()
    with open(path, "rb") as f:
        for chunk in iter(lambda: f.read(HASH_CHUNK_BYTES), b""):
            h.update(chunk)
    return h.hexdigest()


def options_digest(options: Options, method: str, knobs: dict, gyro_unit, mag_unit, reports: bool) -> str:
    """SHA-256 of everything that changes a device's result besides its session: options, method, knobs, units,
    whether a report is made, and magyro's version."""
    import magyro

    text = json.dumps({"options": dataclasses.asdict(options), "method": method, "knobs": knobs,
                       "gyro_unit": gyro_unit, "mag_unit": mag_unit, "reports": reports,
                       "version": magyro.__version__}, sort_keys=True, default=str)
    return hashlib.sha256(text.encode()).hexdigest()


def row_path(out: Path, device_id: str) -> Path:
    return out / "rows" / f"{device_id}.json"


def kept_row(out: Path, device: Device, input_digest: str, digest: str) -> dict | None:
    """The device's row from an earlier run with the same input and options, or None (then it is solved)."""
    try:
        stored = json.loads(row_path(out, device.device_id).read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return None
    row = stored.get("row") if isinstance(stored, dict) and stored.get("schema") == ROW_SCHEMA else None
    if not isinstance(row, dict) or row.get("input_sha256") != input_digest or row.get("options_sha256") != digest:
        return None
    if row.get("calibration") and not (out / row["calibration"]).is_file():
        return None
    if row.get("exit_class") == CRASHED:   # a bug or a dead worker, not the session's own verdict: try again
        return None
    return row


def store_device(out: Path, device_id: str, result: dict, input_digest: str, digest: str) -> dict:
    """Write the device's calibration (and report), then its row; the row as stored."""
    from magyro.io import write_text_atomically

    row = dict(result["row"], input_sha256=input_digest, options_sha256=digest, calibration="")
    if result.get("calibration_json"):
        row["calibration"] = f"calibrations/{device_id}.json"
        write_text_atomically(out / row["calibration"], result["calibration_json"])
    if result.get("report_html"):
        write_text_atomically(out / "reports" / f"{device_id}.html", result["report_html"])
    write_text_atomically(row_path(out, device_id), json.dumps({"schema": ROW_SCHEMA, "row": row}) + "\n")
    return row
