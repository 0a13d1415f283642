"""The rows of the Monte Carlo table, and what one run yields for each of them.

Parameters, named after the calibration JSON (indices 0-based, as in its lists):

    K_g[i,j]              upper triangle (6)
    bias_deg_s[i]         eps_b in deg/s (3)
    misalignment_deg[i]   d = Log(C_est^T C_true) in deg, i.e. C_true = C_est Exp(d)
                          (`misalignment_vector(C_est, C_true)`, the definition of
                          std.misalignment_deg in docs/spec.md); truth 0 (3)
    euler_deg[i]          [roll, pitch, yaw] of C_est (the paper's dcm2eul column), for
                          the comparison with the paper's misalignment std; solvers do
                          not report an Euler std, so rep/act is empty there (3)
    R[i,j], h[i]          magnetometer soft iron (upper triangle, 6) and hard iron (3)
    time_offset_s         magnetometer lag, when the method estimates it
    K_a[i,j], bias_m_s2[i], acc_misalignment_deg[i]
                          the accelerometer's 12 (a problem with an [accelerometer], solved with it): K_a's upper
                          triangle, eps_a in m/s^2, and d with C_b_a(true) = C_b_a(est) Exp(d) in deg, truth 0

Every value is a plain float keyed by its row name: the truth, one run's
estimates and reported stds (`Outcome`), the CRLB.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from magyro import so3
from magyro.errors import one_line
from magyro.result.parts import Std
from magyro.result.reported import UPPER, misalignment_vector
from magyro.studies.scenario import Scenario


@dataclass(frozen=True)
class Parameter:
    """One row of the table."""

    name: str     # e.g. "K_g[0,1]"
    group: str    # "K_g", "bias_deg_s", "misalignment_deg", "euler_deg", "R", "h", "time_offset_s"
    unit: str


def parameters(mag_unit: str, with_time_offset: bool, accelerometer: bool = False) -> list[Parameter]:
    """The table's rows in order (the accelerometer's 12 last, when it is calibrated)."""
    rows = [Parameter(f"K_g[{i},{j}]", "K_g", "-") for i, j in UPPER]
    rows += [Parameter(f"bias_deg_s[{i}]", "bias_deg_s", "deg/s") for i in range(3)]
    rows += [Parameter(f"misalignment_deg[{i}]", "misalignment_deg", "deg") for i in range(3)]
    rows += [Parameter(f"euler_deg[{i}]", "euler_deg", "deg") for i in range(3)]
    rows += [Parameter(f"R[{i},{j}]", "R", f"1/{mag_unit}") for i, j in UPPER]
    rows += [Parameter(f"h[{i}]", "h", mag_unit) for i in range(3)]
    if with_time_offset:
        rows.append(Parameter("time_offset_s", "time_offset_s", "s"))
    if accelerometer:
        rows += [Parameter(f"K_a[{i},{j}]", "K_a", "-") for i, j in UPPER]
        rows += [Parameter(f"bias_m_s2[{i}]", "bias_m_s2", "m/s^2") for i in range(3)]
        rows += [Parameter(f"acc_misalignment_deg[{i}]", "acc_misalignment_deg", "deg") for i in range(3)]
    return rows


def accelerometer_rows(K_a, bias_m_s2, misalignment_deg) -> dict[str, float]:
    """The accelerometer's 12 rows (K_a upper triangle, bias in m/s^2, misalignment d in deg)."""
    out = {f"K_a[{i},{j}]": float(np.asarray(K_a)[i, j]) for i, j in UPPER}
    out.update({f"bias_m_s2[{i}]": float(v) for i, v in enumerate(bias_m_s2)})
    out.update({f"acc_misalignment_deg[{i}]": float(v) for i, v in enumerate(misalignment_deg)})
    return out


def _flatten(K_g, bias_deg_s, misalignment_deg, euler_deg, R, h, time_offset_s=None) -> dict[str, float]:
    out: dict[str, float] = {}
    if K_g is not None:
        out.update({f"K_g[{i},{j}]": float(np.asarray(K_g)[i, j]) for i, j in UPPER})
    if bias_deg_s is not None:
        out.update({f"bias_deg_s[{i}]": float(v) for i, v in enumerate(bias_deg_s)})
    if misalignment_deg is not None:
        out.update({f"misalignment_deg[{i}]": float(v) for i, v in enumerate(misalignment_deg)})
    if euler_deg is not None:
        out.update({f"euler_deg[{i}]": float(v) for i, v in enumerate(euler_deg)})
    if R is not None:
        out.update({f"R[{i},{j}]": float(np.asarray(R)[i, j]) for i, j in UPPER})
    if h is not None:
        out.update({f"h[{i}]": float(v) for i, v in enumerate(h)})
    if time_offset_s is not None:
        out["time_offset_s"] = float(time_offset_s)
    return out


def truth_values(problem: Scenario) -> dict[str, float]:
    """The true value of every row; the misalignment error d is 0 at truth."""
    out = _flatten(problem.K_g, problem.gyro_bias_deg_s, np.zeros(3), so3.dcm_to_euler(problem.C_b_m),
                   problem.R, problem.hard_iron, problem.mag_time_offset_s)
    if problem.accelerometer is not None:
        out.update(accelerometer_rows(problem.accelerometer.K_a, problem.accelerometer.bias_m_s2, np.zeros(3)))
    return out


def estimate_values(cal, problem: Scenario) -> dict[str, float]:
    """A calibration's estimate of every row.

    misalignment_deg = d with C_true = C_est Exp(d) (misalignment_vector(C_est, C_true));
    Euler angles are unwrapped to within 180 deg of the truth so a mean makes sense.
    """
    C_true = problem.C_b_m
    d_deg = np.rad2deg(misalignment_vector(np.asarray(cal.C_b_m), C_true))
    e_true = so3.dcm_to_euler(C_true)
    e = e_true + (so3.dcm_to_euler(np.asarray(cal.C_b_m)) - e_true + 180.0) % 360.0 - 180.0
    tau = cal.time_offset_s if getattr(cal, "time_offset_estimated", False) else None
    out = _flatten(cal.K_g, np.rad2deg(np.asarray(cal.bias_rad_s)), d_deg, e, cal.R, cal.h, tau)
    acc = getattr(cal, "accelerometer", None)
    if acc is not None and problem.accelerometer is not None:
        d_acc = np.rad2deg(misalignment_vector(np.asarray(acc.C_b_a), problem.accelerometer.C_b_a))
        out.update(accelerometer_rows(acc.K_a, acc.bias_m_s2, d_acc))
    return out


def accelerometer_std_values(acc) -> dict[str, float]:
    """A calibration's accelerometer std as rows (none without an accelerometer)."""
    return {} if acc is None else accelerometer_rows(acc.std_K_a, acc.std_bias_m_s2, acc.std_misalignment_deg)


def std_values(std: Std, time_offset: bool) -> dict[str, float]:
    """A `Std` (a calibration's, or crlb.cramer_rao_std) as rows (no Euler rows; the lag's only if `time_offset`)."""
    return _flatten(std.K_g, std.bias_deg_s, std.misalignment_deg, None, std.R, std.h,
                    float(std.time_offset_s) if time_offset else None)


# --------------------------------------------------------------------------- one run


@dataclass
class Outcome:
    """One method on one seed: the estimates, or why there are none."""

    seed: int
    method: str
    ok: bool
    seconds: float = 0.0                               # wall time of the solve
    estimate: dict = field(default_factory=dict)       # row name -> value
    reported_std: dict = field(default_factory=dict)   # row name -> the solver's one-sigma
    solver: dict = field(default_factory=dict)         # status, iterations, ...
    error: str | None = None
    error_type: str | None = None
    exit_code: int | None = None                       # the CLI exit code this error has
    cpu_seconds: float = 0.0                           # CPU time of the solve (its process only)

    @classmethod
    def failure(cls, seed: int, method: str, exc: BaseException, seconds: float) -> "Outcome":
        return cls(seed, method, False, seconds, error=one_line(exc, limit=None), error_type=type(exc).__name__,
                   exit_code=int(getattr(exc, "exit_code", 1)))

    def to_dict(self) -> dict:
        d = {"seed": self.seed, "method": self.method, "ok": self.ok, "seconds": self.seconds,
             "cpu_seconds": self.cpu_seconds}
        if self.ok:
            d.update(estimate=json_dict(self.estimate), reported_std=json_dict(self.reported_std),
                     solver=json_dict(self.solver))
        else:
            d.update(error=self.error, error_type=self.error_type, exit_code=self.exit_code)
        return d


# --------------------------------------------------------------------------- plain values for JSON


def is_missing(v) -> bool:
    """None or a non-finite float: shown as "-", written as null (JSON) or empty (CSV)."""
    return v is None or (isinstance(v, float) and not np.isfinite(v))


def json_number(v):
    if isinstance(v, (float, np.floating)):
        return float(v) if np.isfinite(v) else None
    if isinstance(v, np.integer):
        return int(v)
    return v


def json_dict(d: dict) -> dict:
    return {k: json_number(v) for k, v in d.items()}
