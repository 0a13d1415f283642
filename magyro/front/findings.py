"""The recording check's result: findings (what, where, how much it matters, the fix), per-sensor clock
statistics, and the gyro holes an integration must not cross (JSON schema magyro.recording/1).
"""
from __future__ import annotations

import json
from dataclasses import dataclass, field

import numpy as np

from magyro.session import HOLE_FACTOR

SCHEMA = "magyro.recording/1"
SENSORS = ("gyro", "magnetometer")
SEVERITIES = ("info", "warning", "error")
# every kind of finding the check makes (magyro.front: recording, signals, repairs); acceptance limits name them
KINDS = ("acc_unit", "bursts", "clock_drift", "field", "field_anomaly", "gaps", "gyro_holes", "gyro_unit", "held",
         "jitter", "normalised", "overlap", "samples", "saturation", "slow", "spikes", "stuck", "time_offset",
         "time_unit")
GAP_PERIODS = HOLE_FACTOR         # an interval longer than this many periods is a gap: the solve's hole


@dataclass(frozen=True)
class Finding:
    """One thing the recording gets wrong (or worth knowing), in plain words."""

    kind: str                     # time_unit, bursts, gaps, held, saturation, spikes, overlap, clock_drift,
    sensor: str                   # time_offset, gyro_unit, acc_unit, jitter, gyro_holes (KINDS);
                                  # sensor: gyro | magnetometer | accelerometer | both
    message: str                  # what, with the numbers
    where_s: tuple = ()           # ((t0, t1), ...) session times
    severity: str = "warning"     # info | warning | error (error: unusable as it is, exit 2)
    matters: str = ""             # how much it matters for the calibration
    fix: str = ""                 # what the user or magyro does
    repaired: bool = False        # magyro repaired it (repair_recording)
    numbers: dict = field(default_factory=dict)  # the measured values, machine-readable
    repair: str = ""              # the repair that fixes it, as `--no-repair` names it (Repairs.NAMES), if any
    fix_off: str = ""             # the fix when that repair is off (repair_recording puts it in `fix`)

    def __post_init__(self):
        if self.kind not in KINDS:   # a new kind must be added to KINDS, where limits files look them up
            raise ValueError(f"unknown finding kind {self.kind!r}; add it to magyro.front.findings.KINDS")

    def to_dict(self) -> dict:
        return {"kind": self.kind, "sensor": self.sensor, "severity": self.severity, "message": self.message,
                "where_s": [[float(a), float(b)] for a, b in self.where_s], "matters": self.matters,
                "fix": self.fix, "repaired": self.repaired, "numbers": _plain(self.numbers)}


def repairable(repair: str, does: str, kept: str, advice: str = "") -> dict:
    """The fix of a finding that the repair `repair` fixes, as keywords of Finding: what magyro does and the flag
    that keeps `kept` as recorded, and (fix_off) what is true when that flag is given."""
    flag = f"--no-repair {repair}"
    tail = f"; {advice}" if advice else ""
    return {"repair": repair, "fix": f"{does} ({flag} keeps {kept}){tail}",
            "fix_off": f"not repaired ({flag}): {kept} are kept as recorded{tail}"}


@dataclass(frozen=True)
class SensorStats:
    """One sensor's clock and values as recorded."""

    sensor: str
    samples: int
    start_s: float
    end_s: float
    rate_hz: float                # (samples - 1) / span
    period_s: float               # typical interval (the mean of the intervals that are not gaps)
    median_interval_s: float
    jitter_s: float               # robust std of the intervals (1.4826 MAD)
    max_interval_s: float
    bursty: bool
    gaps: int
    gap_seconds: float
    held_fraction: float          # rows equal to the previous row
    distinct_rate_hz: float       # rate of rows that differ from the previous one

    def to_dict(self) -> dict:
        return _plain(self.__dict__)


@dataclass(frozen=True)
class RecordingCheck:
    """The findings, per-sensor stats and the gyro holes (no gyro data for over GAP_PERIODS periods, or
    saturated samples cut) that an integration must not cross."""

    findings: tuple
    sensors: dict                 # sensor name -> SensorStats (of the recording as given)
    gyro_holes_s: tuple = ()      # ((t0, t1), ...): the last gyro sample before, the first after
    lag_s: tuple = ()             # magnetometer lag behind the gyro at the start and at the end, when measured
    repairs: dict = field(default_factory=dict)  # repair name -> on/off, after repair_recording
    source: str = ""
    lag_at_s: tuple = ()          # the times lag_s is measured at

    @property
    def errors(self) -> list:
        return [f for f in self.findings if f.severity == "error"]

    @property
    def warnings(self) -> list:
        return [f for f in self.findings if f.severity == "warning"]

    @property
    def usable(self) -> bool:
        return not self.errors

    def find(self, kind: str, sensor: str | None = None) -> list:
        return [f for f in self.findings if f.kind == kind and (sensor is None or f.sensor == sensor)]

    def error_message(self) -> str:
        """The errors on one line, for an exit 2."""
        return "; ".join(f"{f.message}; {f.fix}" if f.fix else f.message for f in self.errors)

    def to_dict(self) -> dict:
        return {"schema": SCHEMA, "source": self.source, "usable": self.usable,
                "sensors": {k: v.to_dict() for k, v in self.sensors.items()},
                "findings": [f.to_dict() for f in self.findings],
                "gyro_holes_s": [[float(a), float(b)] for a, b in self.gyro_holes_s],
                "lag_s": [float(x) for x in self.lag_s], "lag_at_s": [float(x) for x in self.lag_at_s],
                "repairs": dict(self.repairs)}

    def to_json(self) -> str:
        return json.dumps(self.to_dict(), indent=2)

    @classmethod
    def from_dict(cls, data: dict) -> "RecordingCheck":
        """Read back what `to_dict` wrote (the calibration JSON's `recording` section)."""
        def spans(x):
            return tuple(tuple(float(v) for v in s) for s in x)

        try:
            findings = tuple(Finding(**{**f, "where_s": spans(f.get("where_s", ()))}) for f in data.get("findings", ()))
        except (TypeError, ValueError) as exc:   # a key or a kind this magyro does not know: refused, not guessed
            from magyro.errors import InputError
            raise InputError(f"the recording check's findings hold what this magyro does not know ({exc})") from None
        sensors = {k: SensorStats(**v) for k, v in data.get("sensors", {}).items()}
        return cls(findings, sensors, spans(data.get("gyro_holes_s", ())), tuple(data.get("lag_s", ())),
                   dict(data.get("repairs", {})), str(data.get("source", "")), tuple(data.get("lag_at_s", ())))

    def summary(self) -> str:
        """One line for the calibration table: what was repaired, and what the check warns of."""
        repaired = sorted({f"{f.kind} ({f.sensor})" for f in self.findings if f.repaired})
        warned = [f.kind for f in self.warnings if not f.repaired]
        parts = [f"repaired {', '.join(repaired)}" if repaired else "nothing to repair"]
        if warned:
            parts.append(f"warns of {', '.join(warned)}")
        return "recording check: " + "; ".join(parts)

    def table(self) -> str:
        lines = [f"recording check{': ' + self.source if self.source else ''}",
                 f"{'sensor':<13}{'samples':>8}{'rate Hz':>9}{'distinct Hz':>12}{'jitter ms':>10}{'span s':>20}"
                 f"{'held %':>8}{'gaps':>6}  clock"]
        for s in self.sensors.values():
            jitter = f"{s.jitter_s * 1e3:.3f}" if np.isfinite(s.jitter_s) else "bursts"
            lines.append(f"{s.sensor:<13}{s.samples:>8}{s.rate_hz:>9.2f}{s.distinct_rate_hz:>12.2f}"
                         f"{jitter:>10}{f'{s.start_s:.3f}-{s.end_s:.3f}':>20}"
                         f"{100 * s.held_fraction:>8.1f}{s.gaps:>6}  {'bursty' if s.bursty else 'regular'}")
        if len(self.lag_s) == 2:
            lines.append(lag_line(self.lag_s))
        if self.gyro_holes_s:
            lines.append(f"gyro holes (never integrated across): {len(self.gyro_holes_s)}, "
                         f"{sum(b - a for a, b in self.gyro_holes_s):.3f} s")
        if self.repairs:
            on = [name for name, used in self.repairs.items() if used]
            lines.append(f"repairs on: {', '.join(on) or 'none'} ([repaired] marks what they fix)")
        if not self.findings:
            lines.append("no findings: the recording looks clean")
        for f in self.findings:
            lines.append(f"{f.severity.upper():<8}{f.kind} ({f.sensor}){' [repaired]' if f.repaired else ''}: "
                         f"{f.message}")
            lines += [f"        {label}: {text}" for label, text in (("matters", f.matters), ("fix", f.fix)) if text]
        return "\n".join(lines)


def _plain(value):
    """numpy scalars and arrays as plain Python, for JSON."""
    if isinstance(value, dict):
        return {k: _plain(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_plain(v) for v in value]
    if isinstance(value, np.ndarray):
        return value.tolist()
    if isinstance(value, (np.bool_,)):
        return bool(value)
    if isinstance(value, np.generic):
        return value.item()
    if isinstance(value, float) and not np.isfinite(value):
        return None
    return value


LAG_ESTIMATE = ("a coarse cross-correlation of the turning rates on a 5 ms grid over the first and last 35 %, to "
                "find drifting clocks and lags beyond the solve's search; the solve fits its own, finer lag with the "
                "calibration, which may differ by a few ms, and uses that one")


def lag_line(lag_s) -> str:
    """The recording check's lag at the start and the end, saying what it is and why the solve's differs."""
    return (f"magnetometer {lag_words(lag_s[0])} at the start, {lag_words(lag_s[1])} at the end ({LAG_ESTIMATE})")


def lag_words(lag_s: float) -> str:
    """'lags the gyro by 3.5 ms' or 'leads the gyro by 3.5 ms' (a negative lag)."""
    return f"{'lags' if lag_s >= 0 else 'leads'} the gyro by {abs(lag_s) * 1e3:.1f} ms"
