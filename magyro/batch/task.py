"""One device of a batch, as a worker solves it: read its session, calibrate, return its row and JSON.

`calibrate_device(task)` runs on any executor (`magyro.executor`): it never raises
(but on Ctrl-C); whatever stops the run becomes the row's exit code, class and
message (`magyro.batch.row.row_from_failure`). It writes nothing: the client writes
the calibration JSON (and the report) it returns, so a worker on another machine needs
only to read the session, and every output is written whole by one process.
"""
from __future__ import annotations

import time
from dataclasses import dataclass, field

from magyro.batch.row import row_from_calibration, row_from_failure
from magyro.options import Options


@dataclass(frozen=True)
class DeviceTask:
    """What a worker needs to calibrate one device."""

    device_id: str
    session: str                        # the session file's path, as the workers see it
    options: Options
    method: str = "nls"
    knobs: dict = field(default_factory=dict)   # the method's own settings
    gyro_unit: str | None = None
    mag_unit: str | None = None
    report: bool = False                # also build the HTML report (needs magyro[plot])


def calibrate_device(task: DeviceTask) -> dict:
    """{"row": the device's row, "calibration_json": its JSON text or None, "report_html": the page or None,
    "seconds": the time spent in the worker}."""
    from magyro.api import calibrate, method_named
    from magyro.io import load_session

    t0 = time.perf_counter()
    text = page = None
    try:
        session = load_session(task.session, gyro_unit=task.gyro_unit, mag_unit=task.mag_unit)
        cal = calibrate(session, task.options, method_named(task.method, **task.knobs))
        text = cal.to_json() + "\n"
        row = row_from_calibration(task.device_id, task.session, cal)
        if task.report:
            page = device_report(session, cal, task)
    except Exception as exc:   # every failure is this device's row, never the batch's end
        row = row_from_failure(task.device_id, task.session, exc)
    seconds = time.perf_counter() - t0
    row["seconds"] = seconds
    return {"row": row, "calibration_json": text, "report_html": page, "seconds": seconds}


def device_report(session, cal, task: DeviceTask) -> str | None:
    """The device's HTML page (`magyro report`, without the split-half check unless the calibration has one), or
    None without matplotlib (the row keeps the calibration)."""
    try:
        import matplotlib  # noqa: F401
    except ImportError:
        return None
    from magyro.report.build import build_report

    return build_report(session, cal, split_check=False, session_path=task.session,
                        calibration_path=f"{task.device_id}.json").html
