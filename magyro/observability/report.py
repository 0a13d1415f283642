"""What `magyro observe` reports, as data: the report and its parts, its JSON and its terminal table.

`excitation.observe` fills an `ObservabilityReport` from a session; `plot.plot_report`
draws it. Every time in the report is session time: the `t` of the session's samples
(the session file's `t_s`, the time axis of every magyro output), so `full_rank_at_s`
lies between `t_start_s` (the first gyro sample's `t`) and `t_start_s + duration_s`.
The JSON layout (schema `SCHEMA`) is described in docs/observability.md, section 4.
"""
from __future__ import annotations

import dataclasses
import json
import math
from dataclasses import dataclass, field

import numpy as np

from magyro.observability.advice import describe_direction, direction_snr
from magyro.observability.gate import AXES, FLOOR_FACTOR, WELL_CONDITIONED, ObservabilityAnalysis
from magyro.observability.matrix import PARAMETER_NAMES
from magyro.result.parts import Std
from magyro.targets import Targets  # noqa: F401  (re-exported: the one set of accuracy targets)
from magyro.text import significant

SCHEMA = "magyro.observability/1"
SPHERE_BANDS = 12                 # equal-area grid of field directions: bands of equal height in z ...
SPHERE_SECTORS = 12               # ... times sectors of equal longitude
SPHERE_GRID = (f"{SPHERE_BANDS * SPHERE_SECTORS} equal-area cells: {SPHERE_BANDS} bands of equal height in z "
               f"(equal area, Archimedes) x {SPHERE_SECTORS} sectors of {360 // SPHERE_SECTORS} deg longitude, "
               "in the magnetometer frame")
UPPER_OFF_DIAGONAL = ((0, 1), (0, 2), (1, 2))


def sphere_cell(directions: np.ndarray, bands: int = SPHERE_BANDS, sectors: int = SPHERE_SECTORS) -> np.ndarray:
    """Index of the equal-area cell of each unit vector (N, 3): band of equal height in z, sector of longitude."""
    u = unit_rows(directions)
    band = np.clip(np.floor((u[:, 2] + 1.0) / 2.0 * bands), 0, bands - 1).astype(int)
    lon = np.arctan2(u[:, 1], u[:, 0])
    sector = np.clip(np.floor((lon + np.pi) / (2 * np.pi) * sectors), 0, sectors - 1).astype(int)
    return band * sectors + sector


def unit_rows(v: np.ndarray) -> np.ndarray:
    """The rows of v (N, 3) scaled to unit length (zero rows stay zero)."""
    v = np.asarray(v, dtype=float)
    n = np.linalg.norm(v, axis=1, keepdims=True)
    return v / np.where(n > 0, n, 1.0)


@dataclass
class Timeline:
    """The cumulative integral of M^T M at checkpoints through the session."""

    t_s: np.ndarray               # (C,) session time (the session's own t)
    eigenvalues: np.ndarray       # (C, 12) ascending, raw units
    signal_to_noise: np.ndarray   # (C, 12) ascending: each eigenvalue over what noise alone puts in its direction
    rank: np.ndarray              # (C,)
    condition: np.ndarray         # (C,) inf while singular


@dataclass
class Coverage:
    """How far the device turned about each gyro axis, and how much of the sphere the field direction visited."""

    angle_turned_deg: np.ndarray    # (3,) integral of |w_i| dt per gyro axis
    peak_rate_deg_s: np.ndarray     # (3,) max |w_i|
    rate_reference: str             # how the bias was taken out of the rates
    cells_visited: int              # of the equal-area grid SPHERE_GRID (`sphere_cell`)
    cells: int

    @property
    def sphere_fraction(self) -> float:
        return self.cells_visited / self.cells


@dataclass
class ObservabilityReport:
    """Everything `magyro observe` reports; `to_dict()` is the JSON, `table()` the terminal text."""

    source: str
    duration_s: float
    t_start_s: float
    gyro_samples: int
    mag_samples: int
    gyro_rate_hz: float
    mag_rate_hz: float
    analysis: ObservabilityAnalysis
    ellipsoid_fitted: bool
    ellipsoid_problem: str | None           # why it could not be fitted
    ellipsoid_rms_norm_error: float | None
    timeline: Timeline
    full_rank_at_s: float | None            # session time, like every time here
    well_conditioned_at_s: float | None
    coverage: Coverage
    predicted_std: Std | None               # like Calibration.std (inf where unobservable), or None
    prediction: dict                        # how it was computed (stride, seconds, note)
    targets: Targets
    verdict: str
    reason: str
    weak_directions: list[str]
    advice: list[str]
    noise: dict
    analysed_span_s: list          # [start, end] the gate analyses (the rests at both ends trimmed)
    rests_s: list                  # rests found, [[start, end], ...]
    mag_unit: str
    recording: object = None       # the recording check (magyro.front.findings.RecordingCheck), via magyro.observe
    accelerometer: object = None   # gravity as a second reference vector (gravity.AccelerometerObservability), or None
    # for the figure only (not in the JSON)
    t_mag_s: np.ndarray = field(repr=False, default=None)
    field_directions: np.ndarray = field(repr=False, default=None)   # (Nm, 3) unit
    t_gyro_s: np.ndarray = field(repr=False, default=None)
    rates_deg_s: np.ndarray = field(repr=False, default=None)        # (Ng, 3), bias taken out

    # ------------------------------------------------------------------ views
    @property
    def rank(self) -> int:
        return self.analysis.rank

    @property
    def condition(self) -> float:
        return self.analysis.condition

    @property
    def eigenvalues(self) -> np.ndarray:
        """Normalised (largest = 1), ascending."""
        return self.analysis.eigenvalues_normalised

    @property
    def exit_code(self) -> int:
        return 3 if self.verdict == "insufficient" else 0

    def to_dict(self) -> dict:
        a = self.analysis
        tl = self.timeline
        return {
            "schema": SCHEMA,
            "source": self.source,
            "verdict": self.verdict,
            "reason": self.reason,
            "rank": int(a.rank),
            "condition": _num(a.condition),
            "eigenvalues": _arr(a.eigenvalues_normalised),
            "largest_eigenvalue": _num(np.max(a.eigenvalues)),
            "parameters": list(PARAMETER_NAMES),
            "directions": directions_dict(a),
            "floor_factor": FLOOR_FACTOR,
            "full_rank_at_s": _num(self.full_rank_at_s),
            "well_conditioned_at_s": _num(self.well_conditioned_at_s),
            "well_conditioned_below": WELL_CONDITIONED,
            "weak_directions": list(self.weak_directions),
            "advice": list(self.advice),
            "coverage": {
                "axes": {AXES[i]: {"angle_turned_deg": _num(self.coverage.angle_turned_deg[i]),
                                   "peak_rate_deg_s": _num(self.coverage.peak_rate_deg_s[i])} for i in range(3)},
                "rate_reference": self.coverage.rate_reference,
                "sphere": {"fraction_visited": _num(self.coverage.sphere_fraction),
                           "cells_visited": int(self.coverage.cells_visited),
                           "cells": int(self.coverage.cells), "grid": SPHERE_GRID},
            },
            "predicted_std": _std_dict(self.predicted_std),
            "prediction": self.prediction,
            "targets": dataclasses.asdict(self.targets),
            "ellipsoid": {"fitted": self.ellipsoid_fitted, "problem": self.ellipsoid_problem,
                          "rms_norm_error": _num(self.ellipsoid_rms_norm_error)},
            "noise": self.noise,
            "session": {"duration_s": self.duration_s, "t_start_s": self.t_start_s,
                        "analysed_span_s": self.analysed_span_s, "rests_s": self.rests_s,
                        "gyro_samples": self.gyro_samples, "magnetometer_samples": self.mag_samples,
                        "gyro_rate_hz": self.gyro_rate_hz, "magnetometer_rate_hz": self.mag_rate_hz,
                        "magnetometer_unit": self.mag_unit},
            "timeline": {"t_s": _arr(tl.t_s), "rank": [int(r) for r in tl.rank], "condition": _arr(tl.condition),
                         "eigenvalues": _arr(tl.eigenvalues), "signal_to_noise": _arr(tl.signal_to_noise)},
            **({"recording": self.recording.to_dict()} if self.recording is not None else {}),
            **({"accelerometer": self.accelerometer.to_dict()} if self.accelerometer is not None else {}),
        }

    def to_json(self) -> str:
        return json.dumps(self.to_dict(), indent=2, allow_nan=False)

    def table(self) -> str:
        """The report for people: verdict first, then why, then what to do."""
        a, c, t = self.analysis, self.coverage, self.targets
        out = [f"magyro observe: {self.source or 'session'} ({self.duration_s:.1f} s, session time "
               f"{self.t_start_s:.1f}-{self.t_start_s + self.duration_s:.1f} s, gyro {self.gyro_rate_hz:.0f} Hz, "
               f"magnetometer {self.mag_rate_hz:.0f} Hz)",
               f"verdict: {self.verdict.upper()}: {self.reason}",
               *([self.recording.summary()] if self.recording is not None else []),
               "",
               f"observability (integral of M^T M, paper eq. 10-11): rank {a.rank} of 12, condition {fmt(a.condition)}"]
        out.append("  eigenvalues / largest: " + " ".join(f"{v:.2g}" for v in a.eigenvalues_normalised))
        out.append(f"  full rank at (session time):        {_when(self.full_rank_at_s)}")
        out.append(f"  well conditioned at (session time): {_when(self.well_conditioned_at_s)} "
                   f"(condition < {WELL_CONDITIONED:g})")
        if self.weak_directions:
            out.append("weak directions:")
            out += [f"  - {w}" for w in self.weak_directions]
        if self.advice:
            out.append("to improve the recording:")
            out += [f"  - {w}" for w in self.advice]
        out.append("coverage (gyro axes, " + c.rate_reference + "):")
        out.append("  axis   angle turned (deg)   peak rate (deg/s)")
        for i in range(3):
            out.append(f"  {AXES[i]:>4}   {c.angle_turned_deg[i]:18.0f}   {c.peak_rate_deg_s[i]:17.1f}")
        out.append(f"  field directions: {100 * c.sphere_fraction:.0f}% of the sphere visited "
                   f"({c.cells_visited} of {c.cells} equal-area cells)")
        out.append("predicted one-sigma (Fisher information at the initial estimate) vs target:")
        if self.predicted_std is None:
            out.append("  not available: " + self.prediction.get("note", "the calibration is not determined"))
        else:
            for label, values, unit, target in accuracy_rows(self.predicted_std, t):
                cells = "  ".join(fmt(v) for v in values)
                worst = np.max(values) if np.all(np.isfinite(values)) else np.inf
                mark = "ok" if worst <= target else "ABOVE TARGET"
                out.append(f"  {label:<32} {cells:<30} {unit:<6} target {target:g}  {mark}")
            s = self.predicted_std
            out.append(f"  {'magnetometer h (' + self.mag_unit + ')':<32} " + "  ".join(fmt(v) for v in s.h))
            out.append(f"  {'magnetometer R diagonal':<32} " + "  ".join(fmt(s.R[i][i]) for i in range(3)))
        if self.accelerometer is not None:
            out += self.accelerometer.table_lines()
        return "\n".join(out)


# --------------------------------------------------------------------------- accuracy against the targets


def accuracy_rows(std: Std, targets: Targets) -> list[tuple[str, np.ndarray, str, float]]:
    """(label, predicted one-sigma values, unit, target) for each target of the verdict."""
    K = np.asarray(std.K_g, dtype=float)
    return [
        ("scale factor (K_g diagonal)", 1e6 * np.diag(K), "ppm", targets.scale_factor_ppm),
        ("non-orthogonality (K_g upper)", np.rad2deg([K[i, j] for i, j in UPPER_OFF_DIAGONAL]), "deg",
         targets.non_orthogonality_deg),
        ("gyro bias", np.asarray(std.bias_deg_s, dtype=float), "deg/s", targets.bias_deg_s),
        ("misalignment (roll pitch yaw)", np.asarray(std.misalignment_deg, dtype=float), "deg",
         targets.misalignment_deg),
    ]


# --------------------------------------------------------------------------- JSON and text


def directions_dict(a: ObservabilityAnalysis) -> list[dict]:
    """Every eigen-direction of the integral, weakest (signal to noise) first: what the gate counts."""
    snr = direction_snr(a)
    order = np.argsort(snr, kind="stable")
    top = float(np.max(a.eigenvalues))
    return [{"eigenvalue": _num(a.eigenvalues[k] / top), "signal_to_noise": _num(snr[k]),
             "excited": bool(i >= 12 - a.rank), "vector": _arr(a.eigenvectors[:, k]),
             "in_words": describe_direction(a.eigenvectors[:, k])} for i, k in enumerate(order)]


def _num(x):
    """A JSON number, or None for missing / inf / NaN."""
    if x is None:
        return None
    x = float(x)
    return x if math.isfinite(x) else None


def _arr(a):
    a = np.asarray(a, dtype=float)
    if a.ndim == 0:
        return _num(a)
    return [_arr(v) for v in a]


def _std_dict(std: Std | None) -> dict:
    """The predicted std as JSON, laid out like the calibration file's `std`; null where not finite (all when None)."""
    if std is None:
        return {k: _arr(np.full(shape, np.nan)) for k, shape in Std.SHAPES.items()}
    return {f.name: _arr(getattr(std, f.name)) for f in dataclasses.fields(std)}


def fmt(x) -> str:
    """A number for people: 3 significant digits, '-' when missing, 'inf' when not finite."""
    if x is None:
        return "-"
    x = float(x)
    if not math.isfinite(x):
        return "inf"
    return significant(x)


def _when(t_s) -> str:
    """A session time for people, or 'never'."""
    return "never (within this session)" if t_s is None else f"{t_s:.1f} s"

