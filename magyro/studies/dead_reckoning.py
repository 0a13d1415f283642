"""Judging a gyro calibration by dead reckoning (issue 6; the paper's Fig. 8, and optical truth).

The attitude is integrated from the gyro twice, with the same integrator
(`so3.integrate_body_rates`):

    raw          omega = y_g                       (K_g = I, bias 0)
    calibrated   omega = K_g y_g + eps_b           (the gyro frame b, docs/spec.md section 1)

**With truth quaternions** (`Session.t_quat_s`, `quat_wxyz`; for BROAD the optical
orientation, IMU frame to ENU) the error at each truth instant t is the angle of

    E(t) = (C_T(t0)^T C_T(t))^T (C_E(t0)^T C_E(t))

where C_T is the truth and C_E the dead-reckoned attitude, both body-to-reference, and
t0 is the first truth instant. Comparing rotations *since t0* removes the unknown
reference frames (ENU for the truth, the start pose for the estimate): no alignment of
the world frames is needed, and the heading of the truth never enters.

What is *not* removed is a constant rotation X between the truth's body frame and the
gyro frame: then C_T,rel = X C_E,rel X^T, and E = X C_rel^T X^T C_rel is not the
identity even for a perfect gyro (up to about 2|X| once the body has turned half a
turn). Only the rotation *angle* of a relative rotation is invariant to X, and an
angle-only comparison misses every error of the rotation axis, so it is reported only as
a lower bound (`angle_only_rms_deg`). magyro uses X = I: BROAD states that its optical
reference is "synchronized and aligned" with the IMU, i.e. `opt_quat` is the orientation
of the IMU's own frame (the authors estimated and removed the marker-to-IMU rotation),
and for a simulated session the truth is the gyro frame by construction. As a check,
the report carries the best-fitting X (a Wahba fit of the truth's and the calibrated
gyro's rotation increments over ~0.1 s), `truth_frame_offset_deg`: a few tenths of a
degree at most are expected; more means the truth is not in the gyro frame and the
error has a floor of about twice that.

**Without truth** the metric is the closure drift: the session must start and end in the
same pose (the paper's tests did), so the dead-reckoned rotation between the first and
the last sample, angle of C_E(t0)^T C_E(t_end), is pure error. The report checks the
premise where it can: the accelerometer (and magnetometer) directions averaged over the
first and last half second must agree.
"""
from __future__ import annotations

import json
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from magyro import so3
from magyro.errors import InputError
from magyro.text import PLOT_INSTALL
from magyro.front.ellipsoid import calibrated_field
from magyro.result.calibration import Calibration
from magyro.session import Session

SCHEMA = "magyro.validation/1"
POSE_WINDOW_S = 0.5          # averaged at each end for the equal-pose check
POSE_MISMATCH_WARN_DEG = 2.0
FRAME_OFFSET_WARN_DEG = 0.5
WAHBA_STEP_S = 0.1
ESTIMATES = ("raw", "calibrated")


@dataclass
class ValidationReport:
    """Dead-reckoning errors of the raw and the calibrated gyro.

    mode "truth": `t_s` are the truth instants used and `error_deg[name]` the angle of
    E(t) for name in ("raw", "calibrated"). mode "closure": `t_s` are the gyro times and
    `euler_deg[name]` the dead-reckoned attitude since the start, [roll, pitch, yaw]
    (the paper's Fig. 8); `summary[name]["closure_deg"]` is the drift at the end.
    """

    mode: str
    source: str
    calibration: dict                  # K_g, bias_rad_s actually used, and where from
    t_s: np.ndarray
    summary: dict                      # name -> metric -> value
    error_deg: dict = field(default_factory=dict)
    euler_deg: dict = field(default_factory=dict)
    truth_angle_deg: np.ndarray | None = None  # rotation angle of the truth since t0
    diagnostics: dict = field(default_factory=dict)
    notes: list = field(default_factory=list)

    @property
    def ratio(self) -> float:
        """Calibrated over raw: RMS error (truth) or closure drift (closure)."""
        key = "rms_deg" if self.mode == "truth" else "closure_deg"
        raw = self.summary["raw"][key]
        return float(self.summary["calibrated"][key] / raw) if raw > 0 else float("nan")

    def to_dict(self, include_series: bool = False, max_points: int = 2000) -> dict:
        out = {
            "schema": SCHEMA,
            "mode": self.mode,
            "source": self.source,
            "calibration": {k: (np.asarray(v).tolist() if isinstance(v, np.ndarray) else v)
                            for k, v in self.calibration.items()},
            "summary": self.summary,
            "calibrated_over_raw": self.ratio,
            "diagnostics": self.diagnostics,
            "notes": list(self.notes),
        }
        if include_series:
            step = max(1, int(np.ceil(len(self.t_s) / max_points)))
            series = {"t_s": self.t_s[::step].tolist()}
            for name, values in (self.error_deg if self.mode == "truth" else self.euler_deg).items():
                series[name] = np.asarray(values)[::step].tolist()
            out["series"] = series
        return out

    def to_json(self, include_series: bool = False) -> str:
        return json.dumps(self.to_dict(include_series), indent=2)

    def table(self) -> str:
        lines = []
        span = f"{self.t_s[0]:.2f} to {self.t_s[-1]:.2f} s"
        if self.mode == "truth":
            n = self.diagnostics.get("truth_samples", len(self.t_s))
            lines.append(f"dead reckoning against truth, rotations since t = {self.t_s[0]:.2f} s "
                         f"({n} truth samples, {span})")
            lines.append(f"{'':18s}{'RMS (deg)':>12s}{'max (deg)':>12s}{'final (deg)':>13s}")
            for name in ESTIMATES:
                s = self.summary[name]
                lines.append(f"{name + ' gyro':18s}{s['rms_deg']:12.3f}{s['max_deg']:12.3f}{s['final_deg']:13.3f}")
            lines.append(f"calibrated / raw RMS error: {self.ratio:.3f}")
            if "truth_frame_offset_deg" in self.diagnostics:
                lines.append(f"truth-to-gyro frame offset (diagnostic, assumed 0): "
                             f"{self.diagnostics['truth_frame_offset_deg']:.3f} deg")
        else:
            lines.append(f"closure drift: dead-reckoned rotation between the first and the last sample "
                         f"({span}); valid when the session starts and ends in the same pose")
            for name in ESTIMATES:
                s = self.summary[name]
                lines.append(f"{name + ' gyro':18s}{s['closure_deg']:10.3f} deg")
            lines.append(f"calibrated / raw closure drift: {self.ratio:.3f}")
            for key, label in (("pose_mismatch_acc_deg", "accelerometer"), ("pose_mismatch_mag_deg", "magnetometer")):
                if key in self.diagnostics:
                    lines.append(f"start/end pose check ({label} direction): {self.diagnostics[key]:.2f} deg apart")
        for note in self.notes:
            lines.append(f"note: {note}")
        return "\n".join(lines)


# --------------------------------------------------------------------------- calibration input


def as_calibration(calibration) -> tuple[Calibration, str]:
    """(the calibration, where it came from): a `Calibration`, a calibration JSON file (read by
    `Calibration.from_json`, which refuses anything else), or None (identity: the raw gyro)."""
    if calibration is None:
        return Calibration.from_parameters(np.eye(3), np.zeros(3), method="identity"), "identity (no calibration)"
    if isinstance(calibration, Calibration):
        return calibration, "Calibration object"
    if isinstance(calibration, (str, Path)):
        return Calibration.from_json(calibration), str(calibration)
    raise InputError(f"a calibration must be a Calibration or the path of a calibration JSON, "
                     f"not {type(calibration).__name__}")


# --------------------------------------------------------------------------- validation


def dead_reckon(session: Session, calibration: Calibration) -> np.ndarray:
    """C(t_k) body-to-start from the calibrated rates omega = K_g y_g + eps_b at the gyro times; C(t_0) = I."""
    omega_rad_s, _ = calibration.apply(session.gyro_rad_s)
    return so3.integrate_body_rates(session.t_gyro_s, omega_rad_s)


def validate(session: Session, calibration=None) -> ValidationReport:
    """Dead-reckon with the raw and the calibrated gyro; errors against truth, or closure drift."""
    cal = as_calibration(calibration)
    if calibration is not None:   # the identity is the raw gyro: it applies to any session
        from magyro.result.applicable import check_applicable

        check_applicable(cal[0], session, session.source or "the session", magnetometer=False)
    if len(session.t_gyro_s) < 2:
        raise InputError("the session has fewer than 2 gyro samples; nothing to integrate")
    attitudes = {
        "raw": dead_reckon(session, as_calibration(None)[0]),
        "calibrated": dead_reckon(session, cal[0]),
    }
    notes = []
    if calibration is None:
        notes.append("no calibration given: the calibrated gyro is the raw gyro")
    t_q, q = _truth_in_span(session)
    if t_q is not None and len(t_q) >= 2:
        return _truth_report(session, cal, attitudes, t_q, q, notes)
    if session.t_quat_s is not None and len(session.t_quat_s) > 0:
        notes.append("the truth quaternions do not overlap the gyro samples; fell back to closure drift")
    return _closure_report(session, cal, attitudes, notes)


def _truth_in_span(session: Session):
    if session.t_quat_s is None or session.quat_wxyz is None:
        return None, None
    t_q = np.asarray(session.t_quat_s, dtype=float)
    q = np.asarray(session.quat_wxyz, dtype=float)
    norm = np.linalg.norm(q, axis=1)
    keep = ((t_q >= session.t_gyro_s[0]) & (t_q <= session.t_gyro_s[-1]) & np.isfinite(q).all(axis=1)
            & (norm > 0.5) & (norm < 1.5))
    return t_q[keep], q[keep]


def attitude_at(t_gyro_s: np.ndarray, C: np.ndarray, t_s: np.ndarray) -> np.ndarray:
    """Attitudes at `t_s` by geodesic interpolation between the neighbouring gyro instants (`so3.interpolate`)."""
    return so3.interpolate(t_gyro_s, C, t_s)


def _angle_deg(C: np.ndarray) -> np.ndarray:
    return np.rad2deg(np.linalg.norm(so3.log_so3(C), axis=-1))


def _relative(C: np.ndarray) -> np.ndarray:
    """C(t0)^T C(t): the rotation since the first instant."""
    return C[0].T @ C


def _truth_report(session, cal, attitudes, t_q, q, notes) -> ValidationReport:
    C_truth = _relative(so3.quat_to_dcm(q))
    truth_angle = _angle_deg(C_truth)
    errors, summary, estimated = {}, {}, {}
    for name, C in attitudes.items():
        C_est = _relative(attitude_at(session.t_gyro_s, C, t_q))
        estimated[name] = C_est
        err = _angle_deg(np.swapaxes(C_truth, -1, -2) @ C_est)
        angle_only = np.abs(truth_angle - _angle_deg(C_est))
        errors[name] = err
        summary[name] = {
            "rms_deg": float(np.sqrt(np.mean(err**2))),
            "max_deg": float(np.max(err)),
            "final_deg": float(err[-1]),
            "angle_only_rms_deg": float(np.sqrt(np.mean(angle_only**2))),
        }
    diagnostics = {
        "truth_samples": int(len(t_q)),
        "truth_span_s": [float(t_q[0]), float(t_q[-1])],
        "longest_truth_gap_s": float(np.max(np.diff(t_q))) if len(t_q) > 1 else 0.0,
        "max_truth_rotation_deg": float(np.max(truth_angle)),
    }
    offset = _frame_offset(t_q, C_truth, estimated["calibrated"])
    if offset is not None:
        diagnostics["truth_frame_offset_deg"] = float(np.rad2deg(np.linalg.norm(so3.log_so3(offset))))
        diagnostics["truth_frame_offset_euler_deg"] = so3.dcm_to_euler(offset).tolist()
        if diagnostics["truth_frame_offset_deg"] > FRAME_OFFSET_WARN_DEG:
            notes.append(f"the truth's body frame seems rotated by {diagnostics['truth_frame_offset_deg']:.2f} deg "
                         f"from the gyro frame; the error then has a floor of up to about twice that")
    gyro_span = session.t_gyro_s[-1] - session.t_gyro_s[0]
    if t_q[-1] - t_q[0] < 0.8 * gyro_span:
        notes.append(f"truth covers only {t_q[-1] - t_q[0]:.1f} s of the {gyro_span:.1f} s gyro record")
    return ValidationReport(mode="truth", source=session.source, calibration=_cal_public(cal), t_s=t_q,
                            summary=summary, error_deg=errors, truth_angle_deg=truth_angle,
                            diagnostics=diagnostics, notes=notes)


def _frame_offset(t_q: np.ndarray, C_truth: np.ndarray, C_est: np.ndarray) -> np.ndarray | None:
    """X with truth increment ~= X est increment X^T (Wahba fit on ~0.1 s rotation increments)."""
    if len(t_q) < 10:
        return None
    grid = np.searchsorted(t_q, np.arange(t_q[0], t_q[-1], WAHBA_STEP_S))
    grid = np.unique(grid[grid < len(t_q)])
    if len(grid) < 3:
        return None
    a, b = grid[:-1], grid[1:]
    ok = (t_q[b] - t_q[a]) < 2.5 * WAHBA_STEP_S
    a, b = a[ok], b[ok]
    if len(a) < 3:
        return None
    phi_t = so3.log_so3(np.swapaxes(C_truth[a], -1, -2) @ C_truth[b])
    phi_e = so3.log_so3(np.swapaxes(C_est[a], -1, -2) @ C_est[b])
    B = phi_t.T @ phi_e
    s = np.linalg.svd(B, compute_uv=False)
    if s[1] < 1e-3 * max(s[0], 1e-12):  # rotation about one axis only: X not determined
        return None
    U, _, Vt = np.linalg.svd(B)
    D = np.diag([1.0, 1.0, np.sign(np.linalg.det(U @ Vt))])
    return U @ D @ Vt


def _closure_report(session, cal, attitudes, notes) -> ValidationReport:
    summary, euler = {}, {}
    duration = float(session.t_gyro_s[-1] - session.t_gyro_s[0])
    for name, C in attitudes.items():
        closure = float(_angle_deg(C[-1]))
        summary[name] = {"closure_deg": closure,
                         "closure_deg_per_min": closure / duration * 60.0 if duration > 0 else float("nan")}
        euler[name] = np.array([so3.dcm_to_euler(Ck) for Ck in C[:: max(1, len(C) // 5000)]])
    diagnostics = {"duration_s": duration}
    mismatch = _pose_mismatch(session, cal)
    diagnostics.update(mismatch)
    worst = max(mismatch.values(), default=None)
    if worst is None:
        notes.append("no accelerometer or magnetometer at both ends to check that the start and end poses are equal")
    elif worst > POSE_MISMATCH_WARN_DEG:
        notes.append(f"the start and end poses differ by about {worst:.1f} deg (sensor directions over the first "
                     f"and last {POSE_WINDOW_S} s); the closure drift then is not an error measure")
    step = max(1, len(session.t_gyro_s) // 5000)
    return ValidationReport(mode="closure", source=session.source, calibration=_cal_public(cal),
                            t_s=session.t_gyro_s[::step].copy(), summary=summary, euler_deg=euler,
                            diagnostics=diagnostics, notes=notes)


def _pose_mismatch(session: Session, cal: tuple[Calibration, str]) -> dict:
    """Angle between the mean sensor directions over the first and last POSE_WINDOW_S."""
    out = {}
    if session.t_acc_s is not None and session.acc_m_s2 is not None and len(session.t_acc_s) > 1:
        angle = _end_direction_angle(session.t_acc_s, session.acc_m_s2)
        if angle is not None:
            out["pose_mismatch_acc_deg"] = angle
    mag = calibrated_field(cal[0].R, cal[0].h, session.mag)
    angle = _end_direction_angle(session.t_mag_s, mag)
    if angle is not None:
        out["pose_mismatch_mag_deg"] = angle
    return out


def _end_direction_angle(t: np.ndarray, v: np.ndarray) -> float | None:
    first = t <= t[0] + POSE_WINDOW_S
    last = t >= t[-1] - POSE_WINDOW_S
    if first.sum() < 2 or last.sum() < 2:
        return None
    a, b = v[first].mean(axis=0), v[last].mean(axis=0)
    na, nb = np.linalg.norm(a), np.linalg.norm(b)
    if na == 0 or nb == 0:
        return None
    return float(np.rad2deg(np.arccos(np.clip(a @ b / (na * nb), -1.0, 1.0))))


def _cal_public(cal: tuple[Calibration, str]) -> dict:
    calibration, source = cal
    return {"K_g": calibration.K_g, "bias_rad_s": calibration.bias_rad_s, "bias_deg_s": calibration.bias_deg_s,
            "from": source}


# --------------------------------------------------------------------------- figure


def plot_validation(report: ValidationReport, path) -> None:
    """The figure (PNG, PDF or SVG by suffix), written atomically; needs matplotlib."""
    from magyro.io import write_atomically

    fig = validation_figure(report)
    path = Path(path)
    fmt = path.suffix.lower().lstrip(".") or "png"
    try:
        write_atomically(path, lambda tmp: fig.savefig(tmp, format=fmt, dpi=120))
    except ValueError as exc:  # unknown format
        raise InputError(f"{path}: cannot write a figure of this type ({exc}); use .png, .pdf or .svg") from None


def validation_figure(report: ValidationReport):
    """The matplotlib Figure of `plot_validation` (not written): errors against truth, or the attitudes."""
    try:
        from matplotlib.figure import Figure
    except ImportError:
        raise InputError(f"plotting needs matplotlib, which is not installed: {PLOT_INSTALL}") from None

    colors = {"raw": "tab:red", "calibrated": "tab:blue"}
    if report.mode == "truth":
        fig = Figure(figsize=(9, 6))
        ax1, ax2 = fig.subplots(2, 1, sharex=True, height_ratios=[2, 1])
        for name in ESTIMATES:
            s = report.summary[name]
            ax1.plot(report.t_s, report.error_deg[name], color=colors[name], lw=1,
                     label=f"{name} gyro (RMS {s['rms_deg']:.2f} deg, final {s['final_deg']:.2f} deg)")
        ax1.set_ylabel("attitude error (deg)")
        ax1.set_title("dead reckoning vs truth, relative rotations since the first instant")
        ax1.grid(alpha=0.3)
        ax1.legend()
        ax2.plot(report.t_s, report.truth_angle_deg, color="0.4", lw=1)
        ax2.set_ylabel("truth rotation\nsince start (deg)")
        ax2.set_xlabel("session time (s)")
        ax2.grid(alpha=0.3)
    else:
        fig = Figure(figsize=(9, 7))
        axes = fig.subplots(3, 1, sharex=True)
        for i, label in enumerate(("roll", "pitch", "yaw")):
            for name in ESTIMATES:
                axes[i].plot(report.t_s, report.euler_deg[name][:, i], color=colors[name], lw=1,
                             label=f"{name} gyro (closure {report.summary[name]['closure_deg']:.2f} deg)")
            axes[i].set_ylabel(f"{label} (deg)")
            axes[i].grid(alpha=0.3)
        axes[0].set_title("dead-reckoned attitude since the start (equal start and end poses)")
        axes[0].legend()
        axes[-1].set_xlabel("session time (s)")
    fig.tight_layout()
    return fig
