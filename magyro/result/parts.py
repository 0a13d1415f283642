"""The typed parts of a calibration: its one-sigma, the excitation it was solved on, the solver's
report, the noise levels it used and the rests' check. Each writes and reads its own piece of
the calibration JSON (`magyro.result.calibration`), with the same keys as its fields.

The shape of every array is checked when a piece is read back, so a file
that was cut short or edited by hand is refused with the key it fails on.
"""
from __future__ import annotations

from dataclasses import dataclass, field, fields

import numpy as np

from magyro.errors import InputError
from magyro.text import significant


def as_list(a) -> list:
    """A numpy array (or number) as plain JSON lists of floats."""
    return np.asarray(a, dtype=float).tolist()


def read_array(data: dict, key: str, shape: tuple, where: str) -> np.ndarray:
    """data[key] as a finite float array of `shape`; InputError naming `where.key` otherwise."""
    if key not in data:
        raise InputError(f"{where}.{key} is missing")
    try:
        a = np.asarray(data[key], dtype=float)
    except (TypeError, ValueError):
        raise InputError(f"{where}.{key} is not an array of numbers") from None
    if a.shape != shape:
        raise InputError(f"{where}.{key} must have shape {shape}, not {a.shape}")
    if not np.isfinite(a).all():
        raise InputError(f"{where}.{key} holds a NaN or an infinity")
    return a


def read_number(data: dict, key: str, where: str, kind=float, finite: bool = False):
    """data[key] as a number of `kind` (an int kind: a whole, finite number of at most 15 digits; `finite`:
    no NaN or infinity); InputError naming `where.key` otherwise."""
    if key not in data:
        raise InputError(f"{where}.{key} is missing")
    value = data[key]
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise InputError(f"{where}.{key} must be a number, not {_shown(value)}")
    if kind is int:
        if not np.isfinite(value) or value != int(value) or abs(value) >= 1e15:
            raise InputError(f"{where}.{key} must be a whole number, not {_shown(value)}")
        return int(value)
    if (finite or kind is not float) and not np.isfinite(value):
        raise InputError(f"{where}.{key} must be a finite number, not {_shown(value)}")
    return kind(value)


def read_optional_number(data: dict, key: str, where: str, default=float("nan")) -> float:
    """data[key] as a float when present and not null (NaN allowed: magyro writes it for 'not measured'), else
    `default`; InputError naming `where.key` for anything that is not a number."""
    if data.get(key) is None:
        return default
    return read_number(data, key, where)


def read_numbers(data: dict, key: str, where: str) -> tuple:
    """data[key], a list of numbers (absent: empty), as a tuple of floats; InputError naming `where.key` otherwise."""
    value = data.get(key, ())
    if not isinstance(value, (list, tuple)) or any(isinstance(v, bool) or not isinstance(v, (int, float)) for v in value):
        raise InputError(f"{where}.{key} must be a list of numbers, not {_shown(value)}")
    return tuple(float(v) for v in value)


def read_text(data: dict, key: str, where: str, default: str | None = None) -> str:
    """data[key] as a string (absent: `default`, when given); InputError naming `where.key` otherwise."""
    value = data.get(key, default)
    if not isinstance(value, str):
        raise InputError(f"{where}.{key} must be a string, not {_shown(value)}")
    return value


def _shown(value) -> str:
    """A value as it would read in a message: short, on one line."""
    text = type(value).__name__ if isinstance(value, (dict, list)) else repr(value)
    return text if len(text) <= 40 else text[:37] + "..."


def read_section(data: dict, key: str, where: str = "the calibration") -> dict:
    """data[key] as an object; InputError naming the key otherwise."""
    value = data.get(key)
    if not isinstance(value, dict):
        path = key if where == "the calibration" else f"{where}.{key}"
        raise InputError(f"{where} has no object '{key}'" if key not in data else
                         f"{path} must be an object, not {_shown(value)}")
    return value


@dataclass(frozen=True)
class Std:
    """One-sigma of every reported parameter, laid out like the parameters (JSON `std`).

    `misalignment_deg` is the std of d in C_b_m(true) = C_b_m(est) Exp(d); `K_g`
    and `R` are upper triangular like the matrices they belong to.
    """

    K_g: np.ndarray                 # (3, 3)
    bias_deg_s: np.ndarray          # (3,)
    misalignment_deg: np.ndarray    # (3,)
    R: np.ndarray                   # (3, 3), magnetometer unit^-1
    h: np.ndarray                   # (3,), magnetometer unit
    K: np.ndarray                   # (3, 3)
    field_i: np.ndarray             # (3,)
    time_offset_s: float = 0.0

    SHAPES = {"K_g": (3, 3), "bias_deg_s": (3,), "misalignment_deg": (3,), "R": (3, 3), "h": (3,), "K": (3, 3),
              "field_i": (3,)}

    def to_dict(self) -> dict:
        out = {name: as_list(getattr(self, name)) for name in self.SHAPES}
        out["time_offset_s"] = float(self.time_offset_s)
        return out

    @classmethod
    def from_dict(cls, data: dict, where: str = "std") -> "Std":
        """The std a calibration JSON holds; a key it lacks (a calibration from another tool) is zero, unknown."""
        arrays = {name: read_array(data, name, shape, where) if name in data else np.zeros(shape)
                  for name, shape in cls.SHAPES.items()}
        return cls(**arrays, time_offset_s=read_number(data, "time_offset_s", where, finite=True)
                   if "time_offset_s" in data else 0.0)

    @classmethod
    def zero(cls) -> "Std":
        """No uncertainty: parameters taken as exact (a truth, or a calibration from elsewhere)."""
        return cls(**{name: np.zeros(shape) for name, shape in cls.SHAPES.items()})


@dataclass(frozen=True)
class Excitation:
    """The observability gate's verdict on the motion the calibration was solved on (JSON `observability`)."""

    rank: int
    condition: float
    tolerance: float
    eigenvalues_normalised: tuple = ()

    @classmethod
    def of(cls, analysis) -> "Excitation":
        """From an `magyro.observability.gate.ObservabilityAnalysis`."""
        return cls(int(analysis.rank), float(analysis.condition), float(analysis.tolerance),
                   tuple(float(v) for v in analysis.eigenvalues_normalised))

    def to_dict(self) -> dict:
        return {"rank": self.rank, "condition": self.condition, "tolerance": self.tolerance,
                "eigenvalues_normalised": list(self.eigenvalues_normalised)}

    @classmethod
    def from_dict(cls, data: dict) -> "Excitation":
        where = "observability"
        return cls(read_number(data, "rank", where, int), read_optional_number(data, "condition", where),
                   read_optional_number(data, "tolerance", where), read_numbers(data, "eigenvalues_normalised", where))


SOLVER_OUTCOMES = {   # IPOPT's return status (kept as it is in the JSON) in words, for people
    "Solve_Succeeded": "converged",
    "Solved_To_Acceptable_Level": "stopped where chi^2 stopped changing (IPOPT's 'acceptable' level)",
    "Maximum_Iterations_Exceeded": "stopped at its iteration limit",
    "Maximum_CpuTime_Exceeded": "stopped at its time limit",
    "Restoration_Failed": "failed to find a better point (restoration failed)",
    "Infeasible_Problem_Detected": "found no feasible point",
    "Search_Direction_Becomes_Too_Small": "stopped: its steps became too small",
    "Invalid_Number_Detected": "stopped at a value that is not a number",
}


def solver_outcome(status: str) -> str:
    """A solver's return status in words ("converged"); an unknown status as itself, underscores as spaces."""
    return SOLVER_OUTCOMES.get(status, status.replace("_", " "))


def solver_summary(solver: "SolverReport") -> str:
    """How the solve ended, in words that say whether it matters: 'nls converged: ...' (the table, the report).

    The least squares stops IPOPT where chi^2 stops changing (its 'acceptable' level: the gradient test stalls on
    rounding in chi^2 units, `magyro.nls.problem`), then checks the Gauss-Newton decrement itself and refuses a false
    stop (exit 1): a status of Solved_To_Acceptable_Level on a calibration is magyro's normal, final stop."""
    decrement = solver.details.get("gauss_newton_decrement")
    if solver.status == "Solved_To_Acceptable_Level" and decrement is not None:
        how = (f"converged: chi^2 stopped changing (magyro's stop for IPOPT) and a further Gauss-Newton step would "
               f"lower it by only {significant(decrement)}, so the result is final")
    else:
        how = solver_outcome(solver.status)
    return f"{solver.method} {how}, {solver.iterations} iterations, {solver.seconds:.2f} s"


@dataclass(frozen=True)
class SolverReport:
    """How the method got there (JSON `solver`): the common fields, then the method's own in `details`."""

    method: str
    status: str
    iterations: int
    seconds: float
    total_seconds: float = float("nan")
    details: dict = field(default_factory=dict)

    def to_dict(self) -> dict:
        return {"method": self.method, "status": self.status, "iterations": self.iterations, "seconds": self.seconds,
                "total_seconds": self.total_seconds, **self.details}

    @classmethod
    def from_dict(cls, data: dict) -> "SolverReport":
        where = "solver"
        if not isinstance(data.get("method"), str) or not isinstance(data.get("status"), str):
            raise InputError("solver.method and solver.status must be strings")
        common = {f.name for f in fields(cls)} - {"details"}
        return cls(data["method"], data["status"], read_number(data, "iterations", where, int),
                   read_number(data, "seconds", where), read_optional_number(data, "total_seconds", where),
                   {k: v for k, v in data.items() if k not in common})


@dataclass(frozen=True)
class NoiseReport:
    """The noise levels that weighted the fit (JSON `noise`); `mag_std` in the magnetometer's unit.

    `gyro_source` and `mag_source` say where each level came from: "given", "rest", "estimated by the solve"
    (variance components, when the session has no rest) or "guess" (third differences of a moving signal,
    which the solve could not replace: a warning)."""

    gyro_density_rad_s_sqrt_hz: float
    mag_std: float
    mag_std_estimated: float | None = None   # before the least squares' re-weighting
    source: str = ""
    field_disturbance: "FieldDisturbance | None" = None   # the least squares: counted in its std
    gyro_density_estimated: float | None = None   # before the least squares' re-weighting
    gyro_source: str = ""
    mag_source: str = ""
    redundancy: dict | None = None   # {"gyro": r, "mag": r}: residuals left to measure each estimated level

    def to_dict(self) -> dict:
        out = {"gyro_density_rad_s_sqrt_hz": self.gyro_density_rad_s_sqrt_hz, "mag_std": self.mag_std}
        if self.mag_std_estimated is not None:
            out["mag_std_estimated"] = self.mag_std_estimated
        if self.gyro_density_estimated is not None:
            out["gyro_density_estimated"] = self.gyro_density_estimated
        if self.source:
            out["source"] = self.source
        if self.gyro_source:
            out["gyro_source"] = self.gyro_source
        if self.mag_source:
            out["mag_source"] = self.mag_source
        if self.redundancy:
            out["redundancy"] = dict(self.redundancy)
        if self.field_disturbance is not None:
            out["field_disturbance"] = self.field_disturbance.to_dict()
        return out

    def summary(self, mag_unit: str) -> str:
        """The table's line: each level and where it came from."""
        return (f"noise: gyro {significant(np.rad2deg(self.gyro_density_rad_s_sqrt_hz))} deg/s/sqrt(Hz) "
                f"(= {significant(self.gyro_density_rad_s_sqrt_hz)} rad/s/sqrt(Hz); "
                f"{self._origin(self.gyro_source, self.gyro_density_estimated, self.gyro_density_rad_s_sqrt_hz)}), "
                f"magnetometer {significant(self.mag_std)} {mag_unit} "
                f"({self._origin(self.mag_source, self.mag_std_estimated, self.mag_std)})")

    @staticmethod
    def _origin(source: str, before, after: float) -> str:
        """Where a level came from, and the level before the fit re-weighted it when that moved it (the least squares
        re-weights a rest level too when its residuals show model error, a field not quite homogeneous)."""
        if isinstance(before, (int, float)) and not isinstance(before, bool) and before > 0 \
                and abs(after / before - 1.0) > 0.01 and source != "estimated by the solve":
            return f"{source} {significant(before)}, re-weighted by the fit's residuals"
        return source

    @classmethod
    def from_dict(cls, data: dict) -> "NoiseReport":
        where = "noise"
        disturbance = data.get("field_disturbance")
        estimated = data.get("mag_std_estimated")
        if estimated is not None and not isinstance(estimated, (bool, int, float)):
            raise InputError(f"{where}.mag_std_estimated must be a number or a boolean, not {_shown(estimated)}")
        gyro_estimated = data.get("gyro_density_estimated")
        if gyro_estimated is not None and not isinstance(gyro_estimated, (bool, int, float)):
            raise InputError(f"{where}.gyro_density_estimated must be a number or a boolean, not {_shown(gyro_estimated)}")
        redundancy = data.get("redundancy")
        if redundancy is not None and not (isinstance(redundancy, dict) and all(
                isinstance(k, str) and isinstance(v, (int, float)) and not isinstance(v, bool)
                for k, v in redundancy.items())):
            raise InputError(f"{where}.redundancy must be an object of numbers, not {_shown(redundancy)}")
        return cls(read_number(data, "gyro_density_rad_s_sqrt_hz", where), read_number(data, "mag_std", where),
                   estimated, read_text(data, "source", where, ""),
                   None if disturbance is None else FieldDisturbance.from_dict(read_section(data, "field_disturbance",
                                                                                             where)),
                   gyro_estimated, read_text(data, "gyro_source", where, ""),
                   read_text(data, "mag_source", where, ""), redundancy)


@dataclass(frozen=True)
class FieldDisturbance:
    """How far the room's field departs from homogeneity along the path (JSON `noise.field_disturbance`):
    std as a fraction of the field and correlation time, measured from the calibrated field's magnitude
    (`magyro.nls.disturbance`); the std of the calibration counts it."""

    std_fraction: float
    correlation_time_s: float

    def to_dict(self) -> dict:
        return {"std_fraction": self.std_fraction, "correlation_time_s": self.correlation_time_s}

    @classmethod
    def from_dict(cls, data: dict) -> "FieldDisturbance":
        where = "noise.field_disturbance"
        return cls(read_number(data, "std_fraction", where), read_number(data, "correlation_time_s", where))


@dataclass(frozen=True)
class RestCheck:
    """The rests at both ends and the bias they imply, eps_b = -K_g mean(y_rest), against the estimate (JSON `rests`)."""

    segments_s: tuple
    seconds: float
    gyro_mean_rad_s: np.ndarray
    bias_deg_s: np.ndarray
    estimate_minus_rest_deg_s: np.ndarray

    def to_dict(self) -> dict:
        return {"segments_s": [list(map(float, s)) for s in self.segments_s], "seconds": float(self.seconds),
                "gyro_mean_rad_s": as_list(self.gyro_mean_rad_s), "bias_deg_s": as_list(self.bias_deg_s),
                "estimate_minus_rest_deg_s": as_list(self.estimate_minus_rest_deg_s)}

    @classmethod
    def from_dict(cls, data: dict) -> "RestCheck":
        where = "rests"
        segments = data.get("segments_s", ())
        if not isinstance(segments, list) or not all(isinstance(x, list) for x in segments):
            raise InputError(f"{where}.segments_s must be a list of [start, end] pairs, not {_shown(segments)}")
        return cls(tuple(read_numbers({"s": x}, "s", f"{where}.segments_s") for x in segments),
                   read_number(data, "seconds", where),
                   read_array(data, "gyro_mean_rad_s", (3,), where), read_array(data, "bias_deg_s", (3,), where),
                   read_array(data, "estimate_minus_rest_deg_s", (3,), where))
