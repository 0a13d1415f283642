"""Split-half consistency: does the session agree with itself?

The std assumes the model holds: a field whose departure from homogeneity is
the Gauss-Markov disturbance the solve measures (`magyro.nls.disturbance`), a
linear magnetometer, a constant gyro. Each half of the moving span is
calibrated on its own (with the full solve's gyro noise level), and each gyro
parameter's half-difference is compared with the std of that difference (z).
The misalignment is compared as the rotation vector d of each half's C_b_m
against the full session's, C_b_m(half) = C_b_m(full) Exp(d), whose components
are what its std is of. When the model holds, z is about unit normal: on
simulated sessions (paper-table1, 20 seeds; phone-module, 10) the RMS of the
twelve z stayed within 0.4-1.4 and the largest |z| below 3.1. On BROAD's
undisturbed trials (02, 03, 05, 07, 09, 21) the RMS z is 0.89-1.17 with the std
that counts the room, 1.86-3.12 with the white-noise std alone
(benchmarks/std_on_real_data.py: the .mat trials cut to their movement +/- 10 s,
without the accelerometer; docs/numbers/std-on-real-data.json). The check warns at an RMS z above `MAX_RMS_Z`
or one |z| above `MAX_HALF_Z`. Half a parameter's half-difference is its
split-half error estimate (one degree of freedom).
"""
from __future__ import annotations

from dataclasses import fields, replace

import numpy as np

from magyro.errors import MagyroError
from magyro.result.calibration import Calibration
from magyro.result.consistency_record import MAX_HALF_Z, MAX_RMS_Z, SplitCheck  # noqa: F401  (kept importable here)
from magyro.result.reported import misalignment_vector
from magyro.session import Session
from magyro.text import significant

QUANTITIES = (
    [(f"K_g[{i},{j}]", "K_g", (i, j)) for i, j in ((0, 0), (1, 1), (2, 2), (0, 1), (0, 2), (1, 2))]
    + [(f"bias_{a}_deg_s", "bias_deg_s", (k,)) for k, a in enumerate("xyz")]
    + [(f"misalignment_d{a}_deg", "misalignment_deg", (k,)) for k, a in enumerate("xyz")]
)


def gyro_values(cal: Calibration, C_b_m_ref: np.ndarray) -> dict[str, float]:
    """The compared gyro parameters of one calibration, by name; the misalignment as d (deg) with
    C_b_m = C_b_m_ref Exp(d)."""
    d_deg = np.rad2deg(misalignment_vector(C_b_m_ref, cal.C_b_m))
    source = {"K_g": cal.K_g, "bias_deg_s": cal.bias_deg_s, "misalignment_deg": d_deg}
    return {name: float(np.asarray(source[key])[idx]) for name, key, idx in QUANTITIES}


def gyro_stds(cal: Calibration) -> dict[str, float]:
    """Their reported one-sigma, by name."""
    return {name: float(np.asarray(getattr(cal.std, key))[idx]) for name, key, idx in QUANTITIES}


def half_spans_s(session: Session) -> list[tuple[float, float]]:
    """The two halves of the session's time span."""
    t0 = max(session.t_gyro_s[0], session.t_mag_s[0])
    t1 = min(session.t_gyro_s[-1], session.t_mag_s[-1])
    mid = 0.5 * (t0 + t1)
    return [(float(t0), float(mid)), (float(mid), float(t1))]


def half_options(options, cal: Calibration):
    """The full solve's options with its gyro noise fixed, no rest trimming (the halves have no rests) and no
    bounds on the std (`Options.max_std`): a half is a diagnostic, and its std, however large, is what its
    difference is compared with. A half that does not excite every parameter is still refused.

    The magnetometer noise is left to each half: its per-sample level (for the
    ellipsoid's degeneracy checks) comes from third differences, and the
    solve's re-weighting finds its effective level from the residuals.
    """
    from magyro.options import StdBounds

    unbounded = StdBounds(**{f.name: float("inf") for f in fields(StdBounds)})   # the accelerometer's bounds too
    return replace(options, gyro_noise_density_rad_s_sqrt_hz=cal.noise.gyro_density_rad_s_sqrt_hz, trim_rests=False,
                   max_std=unbounded)


def compare_halves(full: Calibration, halves: list[Calibration]) -> dict:
    """Per-parameter half-difference, its sigma, and the worst one."""
    a, b = (gyro_values(h, full.C_b_m) for h in halves)
    sa, sb = (gyro_stds(h) for h in halves)
    reported = gyro_stds(full)
    rows = {}
    for name in a:
        diff = a[name] - b[name]
        sigma = float(np.hypot(sa[name], sb[name]))
        rows[name] = {
            "first": a[name], "second": b[name], "difference": diff,
            "z": diff / sigma if sigma > 0 else float("inf"),
            "reported_std": reported[name], "split_std": abs(diff) / 2.0,
        }
    worst = max(rows, key=lambda n: abs(rows[n]["z"]))
    rms_z = float(np.sqrt(np.mean([row["z"] ** 2 for row in rows.values()])))
    return {"parameters": rows, "worst": worst, "max_abs_z": abs(rows[worst]["z"]), "rms_z": rms_z}


def split_check(moving: Session, full: Calibration, options, calibrate) -> SplitCheck:
    """Calibrate both halves of the moving session and compare them (see the module docstring).

    `calibrate(session, options)` is passed in so this module does not import the solver.
    A half that cannot be calibrated on its own is reported with its message.
    """
    spans = half_spans_s(moving)
    opts = half_options(options, full)
    halves, failures = [], []
    from magyro.progress import step

    for k, (t0, t1) in enumerate(spans):
        step(f"split-half check: the {('first', 'second')[k]} half alone ({t0:.0f}-{t1:.0f} s)")
        try:
            halves.append(calibrate(moving.within(t0, t1), opts))
        except MagyroError as exc:
            failures.append(f"{('first', 'second')[k]} half ({t0:.1f}-{t1:.1f} s): {exc}")
    spans_s = tuple(tuple(s) for s in spans)
    if failures:
        return SplitCheck(spans_s, failed=tuple(failures))
    return SplitCheck(spans_s, **compare_halves(full, halves))


def split_warning(report: SplitCheck) -> str | None:
    """A warning when the halves disagree beyond their std, or could not be compared."""
    if report.failed:
        return ("the split-half check could not calibrate each half on its own (" + "; ".join(report.failed)
                + "): record longer so that each half excites every parameter")
    if report.agrees:
        return None
    row = report.parameters[report.worst]
    return (
        f"the two halves of the recording disagree by {report.rms_z:.1f} sigma RMS over the gyro parameters "
        f"(most on {report.worst}: {row['difference']:.4g}, {report.max_abs_z:.1f} sigma): the model does not "
        f"hold throughout (field not homogeneous along the path, magnetometer not linear, or the sensor changed), "
        f"so the reported std understates the error by about {report.rms_z:.1f}x (half the halves' difference, "
        f"split_std in the JSON, is {significant(row['split_std'])} for {report.worst}: one difference, not a std)"
    )
