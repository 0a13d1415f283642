"""The calibration result: what every method returns, its JSON (docs/spec.md section 4) and its table."""
from __future__ import annotations

import json
from pathlib import Path
from dataclasses import dataclass, field

import numpy as np

from magyro import so3
from magyro.errors import InputError
from magyro.front.ellipsoid import calibrated_field
from magyro.front.findings import RecordingCheck
from magyro.front.stills import POSE_APART_DEG, Stills
from magyro.result.accelerometer import HAND_REACH_M, AccelerometerCalibration
from magyro.result.consistency_record import SplitCheck
from magyro.result.fit import FilterFit, LeastSquaresFit, fit_from_dict
from magyro.result.trajectory import AttitudeTrajectory
from magyro.text import escaped, unsafe_characters, significant
from magyro.result.parts import (Excitation, NoiseReport, RestCheck, SolverReport, Std, as_list, read_array, solver_summary,
                                 read_number, read_section)

SCHEMA = "magyro.calibration/1"
UNITS = {"angular_rate": "rad/s", "time": "s", "angle": "deg"}   # and the magnetometer's own unit
KNOWN_SCHEMAS = {  # what other magyro files are, to say so when one is given as a calibration
    "magyro.truth/1": "the true parameters of a simulated session (magyro simulate), not a calibration",
    "magyro.observability/1": "an excitation report (magyro observe), not a calibration",
    "magyro.validation/1": "a dead-reckoning report (magyro validate), not a calibration",
    "magyro.montecarlo/1": "a Monte Carlo study (magyro montecarlo), not a calibration",
}


@dataclass
class Calibration:
    """What every method returns: the model's parameters, their one-sigma, and how they were found.

    The model (docs/spec.md section 1): the gyro measures y_g with w_ib^b = K_g y_g + eps_b
    (rad/s, gyro frame b), or w^m = K y_g + eps in the magnetometer frame
    (K = C_b_m K_g, eps = C_b_m eps_b); the magnetometer's calibrated field is
    m^m = R (y_m - h), of unit norm. `apply` is the one place this is evaluated.
    """

    K_g: np.ndarray                # (3, 3) upper triangular: scale factors and non-orthogonality
    bias_rad_s: np.ndarray         # eps_b, added: w = K_g y + eps_b
    K: np.ndarray                  # C_b_m K_g
    eps_rad_s: np.ndarray          # C_b_m eps_b
    C_b_m: np.ndarray              # gyro frame to magnetometer frame
    R: np.ndarray                  # (3, 3) upper triangular, magnetometer unit^-1
    h: np.ndarray                  # hard iron, magnetometer unit
    mag_unit: str
    field_i: np.ndarray            # unit field in the inertial frame
    std: Std
    observability: Excitation
    solver: SolverReport
    noise: NoiseReport | None = None
    fit: LeastSquaresFit | FilterFit | None = None   # the method's own fit statistics
    time_offset_s: float = 0.0     # magnetometer lag behind the gyro
    time_offset_estimated: bool = False
    rests: RestCheck | None = None
    warnings: list = field(default_factory=list)
    consistency: SplitCheck | None = None     # the split-half check, when asked for
    recording: RecordingCheck | None = None   # the recording check and what it repaired (magyro.calibrate)
    trajectory: AttitudeTrajectory | None = None   # the least squares' attitudes, when asked for (not in the JSON)
    std_white: Std | None = None   # the least squares' std from the white-noise weights alone (`std` adds the room)
    accelerometer: AccelerometerCalibration | None = None   # when the accelerometer joined the least squares
    stills: Stills | None = None   # the poses held still between the end rests (magyro.front.stills, issue 39)

    @property
    def bias_deg_s(self) -> np.ndarray:
        return np.rad2deg(self.bias_rad_s)

    @property
    def euler_deg(self) -> np.ndarray:
        """[roll, pitch, yaw] of C_b_m, C = Rz(yaw) Ry(pitch) Rx(roll)."""
        return so3.dcm_to_euler(self.C_b_m)

    def apply(self, gyro_rad_s, mag=None, frame: str = "b") -> tuple[np.ndarray, np.ndarray | None]:
        """(rates, field): the calibrated angular rate in rad/s and, given magnetometer readings, the calibrated field.

        rates = K_g y + eps_b in the gyro frame (`frame="b"`), or K y + eps in the
        magnetometer frame (`frame="m"`); field = R (y_m - h), of unit norm in a
        homogeneous field. Rows are samples; the inputs are not changed.
        """
        y = np.asarray(gyro_rad_s, dtype=float)
        if frame == "b":
            rates = y @ self.K_g.T + self.bias_rad_s
        elif frame == "m":
            rates = y @ self.K.T + self.eps_rad_s
        else:
            raise InputError(f"unknown frame '{frame}'; use b (the gyro's) or m (the magnetometer's)")
        field_m = None if mag is None else calibrated_field(self.R, self.h, np.asarray(mag, dtype=float))
        return rates, field_m

    def apply_accelerometer(self, acc_m_s2, frame: str = "b") -> np.ndarray:
        """The calibrated specific force (m/s^2) in the frame `apply` gives the rates in: the gyro's,
        C_b_a^T (K_a y_a + eps_a) (`frame="b"`), or the magnetometer's, C_b_m of that (`frame="m"`). Rows are
        samples; the input is not changed. InputError when the calibration has no accelerometer."""
        if self.accelerometer is None:
            raise InputError("the calibration has no accelerometer (solve with --accelerometer to calibrate one)")
        if frame not in ("b", "m"):
            raise InputError(f"unknown frame '{frame}'; use b (the gyro's) or m (the magnetometer's)")
        f_b = self.accelerometer.apply(acc_m_s2, frame="b")
        return f_b if frame == "b" else f_b @ self.C_b_m.T

    @classmethod
    def from_parameters(cls, K_g, bias_rad_s, C_b_m=None, R=None, h=None, mag_unit: str = "unknown",
                        field_i=None, method: str = "given") -> "Calibration":
        """A calibration of known parameters (a truth, or numbers from elsewhere), with zero std."""
        C = np.eye(3) if C_b_m is None else np.asarray(C_b_m, dtype=float)
        K_g, bias = np.asarray(K_g, dtype=float), np.asarray(bias_rad_s, dtype=float)
        return cls(K_g=K_g, bias_rad_s=bias, K=C @ K_g, eps_rad_s=C @ bias, C_b_m=C,
                   R=np.eye(3) if R is None else np.asarray(R, dtype=float),
                   h=np.zeros(3) if h is None else np.asarray(h, dtype=float), mag_unit=mag_unit,
                   field_i=np.array([1.0, 0.0, 0.0]) if field_i is None else np.asarray(field_i, dtype=float),
                   std=Std.zero(), observability=Excitation(12, float("nan"), float("nan")),
                   solver=SolverReport(method, "given", 0, 0.0))

    def to_dict(self) -> dict:
        return {
            "schema": SCHEMA,
            "units": {**UNITS, "magnetometer": self.mag_unit},
            "gyro": {
                "K_g": as_list(self.K_g),
                "bias_rad_s": as_list(self.bias_rad_s),
                "bias_deg_s": as_list(self.bias_deg_s),
                "K": as_list(self.K),
                "eps_m_rad_s": as_list(self.eps_rad_s),
            },
            "misalignment": {"C_b_m": as_list(self.C_b_m), "euler_deg": as_list(self.euler_deg)},
            "magnetometer": {"R": as_list(self.R), "h": as_list(self.h), "unit": self.mag_unit,
                             "field_strength": float(1.0 / np.cbrt(np.prod(np.diag(self.R))))},
            "field_i": as_list(self.field_i),
            "time_offset_s": float(self.time_offset_s),
            "time_offset_estimated": self.time_offset_estimated,
            **({"accelerometer": self.accelerometer.to_dict()} if self.accelerometer is not None else {}),
            "std": {**self.std.to_dict(),
                    **({"accelerometer": self.accelerometer.std_dict()} if self.accelerometer is not None else {})},
            **({"std_white": self.std_white.to_dict()} if self.std_white is not None else {}),
            "rests": None if self.rests is None else self.rests.to_dict(),
            **({"stills": self.stills.to_dict()} if self.stills is not None else {}),
            "warnings": list(self.warnings),
            "observability": self.observability.to_dict(),
            "solver": self.solver.to_dict(),
            "noise": None if self.noise is None else self.noise.to_dict(),
            "fit": None if self.fit is None else self.fit.to_dict(),
            **({"consistency": self.consistency.to_dict()} if self.consistency is not None else {}),
            **({"recording": self.recording.to_dict()} if self.recording is not None else {}),
        }

    def to_json(self, path=None) -> str:
        """The calibration JSON (schema magyro.calibration/1); written whole or not at all when `path` is given."""
        text = json.dumps(self.to_dict(), indent=2)
        if path is not None:
            from magyro.io import write_text_atomically

            write_text_atomically(path, text + "\n")
        return text

    @classmethod
    def from_json(cls, source) -> "Calibration":
        """Read a calibration JSON (a path, or its text); refuse anything that is not one this version wrote."""
        return calibration_from_dict(read_json(source))

    def table(self) -> str:
        """A short, truth-free human summary: estimate +/- one sigma (like the paper's Tables I/II)."""
        s = self.std
        lines = ["gyro K_g (scale on diagonal, non-orthogonality above), +/- 1 sigma"]
        for i in range(3):
            cells = [" " * 22 if j < i else f"{self.K_g[i, j]:9.5f} +/- {s.K_g[i][j]:8.5f}" for j in range(3)]
            lines.append("  " + "  ".join(cells))
        b, sb = self.bias_deg_s, s.bias_deg_s
        lines.append("gyro bias (deg/s)      " + "  ".join(f"{b[i]:+8.4f} +/- {sb[i]:.4f}" for i in range(3)))
        e, se = self.euler_deg, s.misalignment_deg
        lines.append("misalignment C_b_m, roll pitch yaw (deg)  " + "  ".join(f"{e[i]:+8.3f} +/- {se[i]:.3f}" for i in range(3)))
        h, sh = self.h, s.h
        lines.append(f"magnetometer h ({self.mag_unit})  " + "  ".join(f"{h[i]:+.4g} +/- {sh[i]:.2g}" for i in range(3)))
        lines.append("magnetometer R diagonal  " + "  ".join(f"{self.R[i, i]:.5g} +/- {s.R[i][i]:.2g}" for i in range(3)))
        if self.accelerometer is not None:
            lines.extend(self.accelerometer.table_lines())
        hand = self.solver.details.get("hand_states")
        if hand:
            beyond = (f", more than a hand reaches ({HAND_REACH_M:g} m): the states took up a slow drift besides the "
                      "hand; the accelerometer's std counts all they took as the hand's error, so this matters only "
                      "through that std: nothing else to do" if hand["reach_m"] > HAND_REACH_M else "")
            lines.append(f"the hand's velocity solved at every node (prior std {significant(hand['sigma_v_m_s'])} m/s, "
                         f"correlation {hand['tau_s']:g} s; integrated, a position std of {significant(hand['reach_m'])} "
                         f"m{beyond}); --no-hand-states weights the hand as noise instead")
        if self.time_offset_estimated:
            lines.append(f"magnetometer lag behind the gyro (ms, negative: it leads)  {1e3 * self.time_offset_s:+.2f} +/- "
                         f"{1e3 * s.time_offset_s:.2f}")
        if self.noise is not None and self.noise.gyro_source:
            lines.append(self.noise.summary(self.mag_unit))
        disturbance = None if self.noise is None else self.noise.field_disturbance
        if disturbance is not None and self.std_white is not None:
            factor = float(np.median(s.bias_deg_s / np.maximum(self.std_white.bias_deg_s, 1e-300)))
            lines.append(f"the field wanders by {100 * disturbance.std_fraction:.2f} % along the path (correlation "
                         f"{disturbance.correlation_time_s:.1f} s); the std counts it ({factor:.1f}x the white-noise std)")
        walk = self.solver.details.get("hard_iron_walk")
        if walk:
            lines.append(f"hard iron moving (walk {walk['density_per_sqrt_s']:g} {self.mag_unit}/sqrt(s)): peak to peak "
                         + "  ".join(f"{significant(v)}" for v in walk["peak_to_peak"]) + f" {self.mag_unit}")
        if self.rests is not None:
            lines.append(f"bias from {self.rests.seconds:.1f} s of rest (deg/s)  "
                         + "  ".join(f"{v:+8.4f}" for v in self.rests.bias_deg_s))
        if self.stills is not None and self.stills.segments_s:
            lines.append(f"stills between the end rests: {len(self.stills.segments_s)}, {self.stills.seconds:.1f} s in all"
                         + ("" if self.stills.poses is None else
                            f"; {self.stills.poses} distinct poses with the end rests (gravity > {POSE_APART_DEG:g} deg apart)"))
        if self.consistency is not None and self.consistency.compared:
            c = self.consistency
            lines.append(f"split-half check: the halves differ by {c.rms_z:.1f} sigma RMS, at most {c.max_abs_z:.1f} "
                         f"({c.worst}); above {c.max_rms_z:.0f} RMS or {c.max_half_z:.0f} is a warning")
        if self.recording is not None:
            lines.append(self.recording.summary())
        ob = self.observability
        lines.append(f"observability: rank {ob.rank} of 12, condition {significant(ob.condition)}")
        sv = self.solver
        lines.append(f"solver: {solver_summary(sv)}")
        lines.extend(f"warning: {w}" for w in self.warnings)
        return "\n".join(lines)


HINT = "; pass the calibration JSON written by magyro solve"
# the type of each top-level key a calibration may hold (None: may be null); sections are checked in their reader
TOP_LEVEL = {"schema": (str,), "units": (dict, None), "gyro": (dict,), "misalignment": (dict,),
             "magnetometer": (dict,), "field_i": (list,), "time_offset_s": (int, float), "time_offset_estimated": (bool,),
             "std": (dict, None), "std_white": (dict, None), "rests": (dict, None), "warnings": (list,),
             "observability": (dict,), "solver": (dict,), "noise": (dict, None), "fit": (dict, None),
             "consistency": (dict, None), "recording": (dict, None), "accelerometer": (dict, None)}
TYPE_NAMES = {str: "a string", dict: "an object", list: "a list", bool: "true or false", int: "a number",
              float: "a number", None: "null"}


def read_json(source) -> dict:
    """The JSON object in a file (a path) or a string of JSON text: InputError for a missing, unreadable, cut-short,
    oversized or too deeply nested file, or a file of another kind (a session given in its place)."""
    from magyro.result.json_input import read_json_object

    return read_json_object(source, "calibration", HINT)


def check_top_level(data: dict) -> None:
    """Refuse a top-level key of the wrong type, naming it and what it must be (before any section is read)."""
    for key, kinds in TOP_LEVEL.items():
        if key not in data:
            continue
        value = data[key]
        ok = (value is None and None in kinds) or (
            value is not None and isinstance(value, tuple(k for k in kinds if k is not None))
            and not (isinstance(value, bool) and bool not in kinds))
        if not ok:
            must = " or ".join(dict.fromkeys(TYPE_NAMES[k] for k in kinds))
            raise InputError(f"the calibration's {key} must be {must}, not {type(value).__name__}")
    if not all(isinstance(w, str) for w in data.get("warnings", [])):
        raise InputError("the calibration's warnings must be a list of strings")
    if "time_offset_s" in data and not np.isfinite(data["time_offset_s"]):
        raise InputError(f"the calibration's time_offset_s must be a finite number, not {data['time_offset_s']}")


def check_schema(data: dict) -> None:
    """Refuse a file that is not a calibration of this schema, or whose units are not the ones it was written in."""
    schema = data.get("schema")
    if schema is not None and not isinstance(schema, str):
        raise InputError(f"not a magyro calibration: schema must be a string, not {type(schema).__name__}")
    if schema != SCHEMA:
        what = KNOWN_SCHEMAS.get(schema)
        if what:
            raise InputError(f"this is {what}{HINT}")
        found = "no schema" if schema is None else f"schema {schema[:60]!r}"
        raise InputError(f"not a magyro calibration: {found}, expected {SCHEMA!r} (written by magyro solve)")
    check_top_level(data)
    units = data.get("units")
    if units is None:
        return  # files of this schema written before `units` existed: the units are those of the key names
    expected = {**UNITS, "magnetometer": read_section(data, "magnetometer").get("unit")}
    wrong = {k: v for k, v in units.items() if k in expected and v != expected[k]}
    if wrong:
        raise InputError(f"the calibration's units {wrong} are not {expected}: this version of magyro "
                         "cannot read them")


def calibration_from_dict(data: dict) -> Calibration:
    """The Calibration a calibration JSON describes (see `Calibration.from_json`); InputError naming the key for
    anything of the wrong type, shape or value."""
    check_schema(data)
    try:
        return _calibration_from_checked(data)
    except (TypeError, ValueError, KeyError, AttributeError, IndexError, OverflowError) as exc:
        # a section of another shape than this version writes, in a key not checked one by one above
        from magyro.errors import one_line

        raise InputError(f"the calibration holds a value this version of magyro cannot read ({one_line(exc)})") from None


def _calibration_from_checked(data: dict) -> Calibration:
    gyro, mis, mag = (read_section(data, key) for key in ("gyro", "misalignment", "magnetometer"))
    K_g, C = read_array(gyro, "K_g", (3, 3), "gyro"), read_array(mis, "C_b_m", (3, 3), "misalignment")
    bias = read_array(gyro, "bias_rad_s", (3,), "gyro")
    if not np.allclose(C.T @ C, np.eye(3), atol=1e-6) or np.linalg.det(C) < 0:
        raise InputError("misalignment.C_b_m is not a proper rotation matrix")
    unit = mag.get("unit")
    if not isinstance(unit, str):
        raise InputError("magnetometer.unit must be a string")
    if unsafe_characters(unit) or len(unit) > 40:
        raise InputError(f"magnetometer.unit '{escaped(unit[:40])}' is not a unit: "
                         + (f"it holds control or bidi characters ({', '.join(unsafe_characters(unit))})"
                            if unsafe_characters(unit) else "longer than 40 characters"))
    std = data.get("std")     # a calibration from another tool may have none: its parameters taken as given
    solver = read_section(data, "solver")
    rests, noise, consistency = data.get("rests"), data.get("noise"), data.get("consistency")
    return Calibration(
        K_g=K_g, bias_rad_s=bias, K=read_array(gyro, "K", (3, 3), "gyro") if "K" in gyro else C @ K_g,
        eps_rad_s=read_array(gyro, "eps_m_rad_s", (3,), "gyro") if "eps_m_rad_s" in gyro else C @ bias, C_b_m=C,
        R=read_array(mag, "R", (3, 3), "magnetometer"), h=read_array(mag, "h", (3,), "magnetometer"), mag_unit=unit,
        field_i=read_array(data, "field_i", (3,), "the calibration"),
        std=Std.zero() if std is None else Std.from_dict(std),
        observability=Excitation.from_dict(read_section(data, "observability")),
        solver=SolverReport.from_dict(solver),
        noise=None if noise is None else NoiseReport.from_dict(noise), fit=fit_from_dict(solver["method"], data.get("fit")),
        time_offset_s=read_number(data, "time_offset_s", "the calibration", finite=True) if "time_offset_s" in data else 0.0,
        time_offset_estimated=bool(data.get("time_offset_estimated", False)),
        rests=None if rests is None else RestCheck.from_dict(rests), warnings=list(data.get("warnings", [])),
        consistency=None if consistency is None else SplitCheck.from_dict(consistency),
        recording=None if data.get("recording") is None else RecordingCheck.from_dict(data["recording"]),
        std_white=None if data.get("std_white") is None else Std.from_dict(data["std_white"], "std_white"),
        accelerometer=None if data.get("accelerometer") is None else AccelerometerCalibration.from_dict(
            data["accelerometer"], (std or {}).get("accelerometer")),
        stills=None if not isinstance(data.get("stills"), dict) else Stills.from_dict(data["stills"]),
    )
