"""One device's row of the fleet summary: a flat dict of plain values, with units in the column names.

A row is what a batch keeps of one session, whatever became of it: the device
and its input, how the run ended (the exit code and class of docs/spec.md
section 3, and its one-line message), the gyro's parameters with their
one-sigma, the recording check's findings and the calibration's warnings by
kind. `row_from_calibration` makes it from a solved calibration,
`row_from_failure` from the exception that stopped the run. The acceptance
verdict is added later by the client (`magyro.batch.limits`), so changing the
limits never re-solves a session.

Columns (every row has every column; a failed run has NaN numbers):

    device_id, session, status ("calibrated" | "failed"), exit_code (0, 1, 2, 3),
    exit_class ("done" | "solver failed" | "unusable input" | "insufficient motion" | "crashed": anything
    outside the contract, a bug or a worker that died; a rerun of the batch tries a crashed device again),
    message, seconds, input_sha256, options_sha256, calibration (the JSON's path, relative to OUTDIR)
    scale_ppm_{x,y,z}, std_scale_ppm_{x,y,z}                 K_g diagonal - 1, ppm
    nonorth_deg_{xy,xz,yz}, std_nonorth_deg_{xy,xz,yz}       K_g above the diagonal, as angles (deg)
    bias_deg_s_{x,y,z}, std_bias_deg_s_{x,y,z}               eps_b
    misalignment_deg_{roll,pitch,yaw}, std_misalignment_deg_{x,y,z}   C_b_m's Euler angles; std of d (spec)
    hard_iron_{x,y,z}, field_strength, mag_unit              the magnetometer's h, 1/cbrt(det R), its unit
    time_offset_s, rank, split_rms_z (NaN without the split-half check)
    findings        the recording check's warning kinds, comma separated (e.g. "saturation,spikes")
    repaired        the kinds magyro repaired
    warning_kinds   every warning's kind, comma separated (recording kinds, split_check, forced, rests, other)
    warnings        the warnings' text, joined by " | "

With an accelerometer in the calibration (`magyro batch --accelerometer`) the row also has
`accelerometer_columns()`, the accelerometer's parameters with their one-sigma (a row without one
has none of these keys, so a fleet without accelerometers has the columns above and no others):

    acc_scale_ppm_{x,y,z}, std_acc_scale_ppm_{x,y,z}                 K_a diagonal - 1, ppm
    acc_nonorth_deg_{xy,xz,yz}, std_acc_nonorth_deg_{xy,xz,yz}       K_a above the diagonal, as angles (deg)
    acc_bias_m_s2_{x,y,z}, std_acc_bias_m_s2_{x,y,z}                 eps_a, m/s^2
    acc_misalignment_deg_{roll,pitch,yaw}, std_acc_misalignment_deg_{x,y,z}   C_b_a's Euler angles; std of d
"""
from __future__ import annotations

import math

import numpy as np

from magyro.errors import MagyroError, one_line
from magyro.text import shortened

MAX_MESSAGE_CHARS = 2000   # a row's message: whole, unless a runaway one (then cut at a word, with "...")

AXES = ("x", "y", "z")
PAIRS = ((0, 1, "xy"), (0, 2, "xz"), (1, 2, "yz"))
EULER = ("roll", "pitch", "yaw")
EXIT_CLASSES = {0: "done", 1: "solver failed", 2: "unusable input", 3: "insufficient motion"}
CRASHED = "crashed"
TEXT_COLUMNS = ("device_id", "session", "status", "exit_class", "message", "input_sha256", "options_sha256",
                "calibration", "mag_unit", "findings", "repaired", "warning_kinds", "warnings")


def parameter_columns() -> list[str]:
    """The numeric columns of the gyro and magnetometer parameters, in summary order."""
    cols = [f"scale_ppm_{a}" for a in AXES] + [f"nonorth_deg_{p}" for *_, p in PAIRS]
    cols += [f"bias_deg_s_{a}" for a in AXES] + [f"misalignment_deg_{e}" for e in EULER]
    cols += [f"std_scale_ppm_{a}" for a in AXES] + [f"std_nonorth_deg_{p}" for *_, p in PAIRS]
    cols += [f"std_bias_deg_s_{a}" for a in AXES] + [f"std_misalignment_deg_{a}" for a in AXES]
    cols += [f"hard_iron_{a}" for a in AXES] + ["field_strength", "time_offset_s", "rank", "split_rms_z"]
    return cols


def accelerometer_columns() -> list[str]:
    """The accelerometer's numeric columns, in summary order (only in rows of calibrations that have one)."""
    cols = [f"acc_scale_ppm_{a}" for a in AXES] + [f"acc_nonorth_deg_{p}" for *_, p in PAIRS]
    cols += [f"acc_bias_m_s2_{a}" for a in AXES] + [f"acc_misalignment_deg_{e}" for e in EULER]
    cols += [f"std_acc_scale_ppm_{a}" for a in AXES] + [f"std_acc_nonorth_deg_{p}" for *_, p in PAIRS]
    cols += [f"std_acc_bias_m_s2_{a}" for a in AXES] + [f"std_acc_misalignment_deg_{a}" for a in AXES]
    return cols


COLUMNS = (["device_id", "session", "status", "exit_code", "exit_class", "message", "seconds", "input_sha256",
            "options_sha256", "calibration"] + parameter_columns()
           + ["mag_unit", "findings", "repaired", "warning_kinds", "warnings"])


def empty_row(device_id: str, session: str) -> dict:
    """A row with every column: NaN numbers, empty text."""
    row = {c: (math.nan if c not in TEXT_COLUMNS else "") for c in COLUMNS}
    row.update(device_id=device_id, session=session, exit_code=-1, seconds=math.nan)
    return row


def exit_code_of(exc: BaseException) -> int:
    """The contract's exit code for an exception that stopped a run (1 for anything unexpected)."""
    return exc.exit_code if isinstance(exc, MagyroError) else 1


def row_from_failure(device_id: str, session: str, exc: BaseException) -> dict:
    """The row of a run stopped by `exc`: its exit code and class, and one line naming the cause."""
    row = empty_row(device_id, session)
    code = exit_code_of(exc)
    known = isinstance(exc, MagyroError)
    message = shortened(one_line(exc, limit=None), MAX_MESSAGE_CHARS)
    row.update(status="failed", exit_code=code, exit_class=EXIT_CLASSES.get(code, "solver failed") if known else CRASHED,
               message=message if known else f"{type(exc).__name__}: {message}")
    return row


def warning_kind(text: str) -> str:
    """The kind of one calibration warning (recording findings are taken from the check itself)."""
    lower = text.lower()
    if lower.startswith("recording:"):
        return "recording"
    if "split-half" in lower or "two halves" in lower:
        return "split_check"
    if "--force" in lower:
        return "forced"
    if "rest" in lower:
        return "rests"
    return "other"


def row_from_calibration(device_id: str, session: str, cal) -> dict:
    """The row of a solved calibration (a `magyro.result.calibration.Calibration`)."""
    row = empty_row(device_id, session)
    K_g, std = np.asarray(cal.K_g), cal.std
    for i, a in enumerate(AXES):
        row[f"scale_ppm_{a}"] = 1e6 * (K_g[i, i] - 1.0)
        row[f"std_scale_ppm_{a}"] = 1e6 * std.K_g[i, i]
        row[f"bias_deg_s_{a}"] = cal.bias_deg_s[i]
        row[f"std_bias_deg_s_{a}"] = std.bias_deg_s[i]
        row[f"std_misalignment_deg_{a}"] = std.misalignment_deg[i]
        row[f"hard_iron_{a}"] = cal.h[i]
    for i, j, p in PAIRS:
        row[f"nonorth_deg_{p}"] = math.degrees(K_g[i, j])
        row[f"std_nonorth_deg_{p}"] = math.degrees(std.K_g[i, j])
    for e, value in zip(EULER, cal.euler_deg):
        row[f"misalignment_deg_{e}"] = value
    if cal.accelerometer is not None:
        row.update(accelerometer_values(cal.accelerometer))
    row["field_strength"] = float(1.0 / np.cbrt(np.prod(np.diag(cal.R))))
    row["time_offset_s"] = cal.time_offset_s
    row["rank"] = cal.observability.rank
    if cal.consistency is not None and not cal.consistency.failed:
        row["split_rms_z"] = cal.consistency.rms_z
    findings = [f for f in (cal.recording.findings if cal.recording is not None else []) if f.severity != "info"]
    kinds = [w for w in (warning_kind(w) for w in cal.warnings) if w != "recording"]
    unrepaired = [f.kind for f in findings if not f.repaired]
    row.update(status="calibrated", exit_code=0, exit_class="done", mag_unit=cal.mag_unit,
               message=f"calibrated; {len(cal.warnings)} warning(s)" if cal.warnings else "calibrated",
               findings=",".join(dict.fromkeys(f.kind for f in findings)),
               repaired=",".join(dict.fromkeys(f.kind for f in findings if f.repaired)),
               warning_kinds=",".join(dict.fromkeys(unrepaired + kinds)),
               warnings=" | ".join(cal.warnings))
    return {k: (float(v) if isinstance(v, (np.floating, np.integer)) and k != "exit_code" else v)
            for k, v in row.items()}


def accelerometer_values(acc) -> dict:
    """The accelerometer_columns() of a `magyro.result.accelerometer.AccelerometerCalibration`."""
    values = {}
    for i, a in enumerate(AXES):
        values[f"acc_scale_ppm_{a}"] = 1e6 * (acc.K_a[i, i] - 1.0)
        values[f"std_acc_scale_ppm_{a}"] = 1e6 * acc.std_K_a[i, i]
        values[f"acc_bias_m_s2_{a}"] = acc.bias_m_s2[i]
        values[f"std_acc_bias_m_s2_{a}"] = acc.std_bias_m_s2[i]
        values[f"std_acc_misalignment_deg_{a}"] = acc.std_misalignment_deg[i]
    for i, j, p in PAIRS:
        values[f"acc_nonorth_deg_{p}"] = math.degrees(acc.K_a[i, j])
        values[f"std_acc_nonorth_deg_{p}"] = math.degrees(acc.std_K_a[i, j])
    for e, value in zip(EULER, acc.euler_deg):
        values[f"acc_misalignment_deg_{e}"] = value
    return {c: float(values[c]) for c in accelerometer_columns()}


def number_of(value) -> float:
    """A row's value as a float (NaN when it is none: a failed run's parameters, a missing column)."""
    try:
        return float(value)
    except (TypeError, ValueError):
        return math.nan


def text_of(value) -> str:
    """A row's value as text ("" for none or NaN)."""
    if value is None or (isinstance(value, float) and math.isnan(value)):
        return ""
    return str(value)
