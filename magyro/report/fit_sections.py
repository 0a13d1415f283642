"""The report's sections 4 and 5: how well the calibration explains the recording (the residuals: the
turning the calibrated gyro predicts against the field's, window by window) and agrees with itself (the
split-half check).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from magyro.report import figures
from magyro.report.section import FAIR, GOOD, POOR, Section, num, table


# --------------------------------------------------------------------------- 4. the residuals


@dataclass(frozen=True)
class Windows:
    window_s: float
    t_s: dict                  # raw | calibrated -> window centre times (s)
    misfit_deg: dict           # raw | calibrated -> per-window misfit norm (deg)
    rms_deg: dict              # raw | calibrated -> turning_residual (RMS per component, deg)


@dataclass(frozen=True)
class FieldMagnitude:
    t_s: np.ndarray
    magnitude: np.ndarray


def window_misfits(moving, field_m, K, eps, time_offset_s: float, window_s: float) -> tuple[np.ndarray, np.ndarray]:
    """(window centre times, |misfit| of eq. 13 per window in rad) for a gyro calibration K, eps."""
    from magyro.observability.matrix import field_on_gyro_times, windowed_increments
    from magyro.session import hole_spans_s, overlaps_a_hole

    t_mag = np.asarray(moving.t_mag_s) - time_offset_s
    dm, int_M = windowed_increments(moving.t_gyro_s, moving.gyro_rad_s, t_mag, field_m, window_s)
    theta = np.concatenate([np.asarray(K, dtype=float).reshape(-1, order="F"), np.asarray(eps, dtype=float)])
    misfit = np.linalg.norm(int_M @ theta - dm, axis=1)
    # the windows' times, as windowed_increments chooses them
    inside, _ = field_on_gyro_times(moving.t_gyro_s, t_mag, field_m)
    t = moving.t_gyro_s[inside]
    step = max(1, int(round(window_s * (len(t_mag) - 1) / (t_mag[-1] - t_mag[0]))))
    ends = np.arange(0, len(t_mag), step)
    ends = ends[(t_mag[ends] >= t[0]) & (t_mag[ends] <= t[-1])]
    t_end = t_mag[ends]
    whole = ~overlaps_a_hole(t_end[:-1], t_end[1:], hole_spans_s(t) + hole_spans_s(t_mag))
    centres = (0.5 * (t_end[:-1] + t_end[1:]))[whole]
    if len(centres) != len(misfit):  # should not happen; keep the figure honest about order at least
        centres = np.linspace(moving.t_mag_s[0], moving.t_mag_s[-1], len(misfit))
    return centres, misfit


PLOT_WINDOW_S = 1.0   # the figure's windows: over 0.1 s the magnetometer's noise hides the gyro's errors


def residual_section(moving, cal) -> Section:
    from magyro.api import MAX_TURNING_MISFIT
    from magyro.front.ellipsoid import calibrated_field
    from magyro.front.initial import DEFAULT_WINDOW_S, linear_gyro_estimate, turning_residual
    from magyro.nls.diagnostics import FIELD_WINDOW_S, MAX_FIELD_CHANGE, field_magnitude_change

    field_m = calibrated_field(cal.R, cal.h, moving.mag)
    args = (moving.t_gyro_s, moving.gyro_rad_s, moving.t_mag_s, field_m)
    gyros = {"raw": (np.eye(3), np.zeros(3), 0.0), "calibrated": (cal.K, cal.eps_rad_s, cal.time_offset_s)}

    def misfits(window_s):
        rms = {name: float(np.rad2deg(turning_residual(*args, K, eps, offset, window_s)))
               for name, (K, eps, offset) in gyros.items()}
        best = float(np.rad2deg(linear_gyro_estimate(*args, window_s=window_s,
                                                     time_offset_s=cal.time_offset_s).residual))
        return rms, best

    solve_rms, solve_best = misfits(DEFAULT_WINDOW_S)
    plot_rms, plot_best = misfits(PLOT_WINDOW_S)
    times, misfit = {}, {}
    for name, (K, eps, offset) in gyros.items():   # the lag moves the windows: each gyro has its own times
        times[name], m = window_misfits(moving, field_m, K, eps, offset, PLOT_WINDOW_S)
        misfit[name] = np.rad2deg(m)
    windows = Windows(PLOT_WINDOW_S, times, misfit, plot_rms)
    magnitude = np.linalg.norm(field_m, axis=1)
    change = field_magnitude_change(moving, cal.R, cal.h)
    ratio = solve_rms["calibrated"] / solve_best if solve_best > 0 else 1.0
    reduction = 1.0 - plot_rms["calibrated"] / plot_rms["raw"] if plot_rms["raw"] > 0 else float("nan")
    field_ok = change.max_fraction <= MAX_FIELD_CHANGE
    fits = ratio <= MAX_TURNING_MISFIT
    status = GOOD if field_ok and fits else POOR if not fits else FAIR
    sentence = (f"Over {PLOT_WINDOW_S:g} s windows the calibrated gyro predicts the field's turning with an RMS "
                f"misfit of {num(plot_rms['calibrated'], 2)} deg against {num(plot_rms['raw'], 2)} deg raw "
                f"({100 * reduction:.0f} % less; the best linear fit reaches {num(plot_best, 2)} deg, the rest is "
                f"magnetometer noise), and the calibrated field magnitude, averaged over "
                f"{FIELD_WINDOW_S:g} s, stays within {100 * change.max_fraction:.1f} % of 1 (worst at "
                f"{change.at_s:.1f} s), "
                + ("inside the 5 % a homogeneous field allows: the model fits the recording."
                   if field_ok and fits else
                   f"beyond the {100 * MAX_FIELD_CHANGE:.0f} % a homogeneous field allows: iron or a magnet near the "
                   "path, or a magnetometer that is not linear." if not field_ok else
                   f"but the calibrated gyro fits {ratio:.1f}x worse than the best linear fit: the result does not "
                   "explain the recording."))
    deviation = np.abs(magnitude - 1.0)
    worst = int(np.argmax(deviation))
    rows = [[f"turning misfit over {1e3 * DEFAULT_WINDOW_S:.0f} ms windows (the solve's): raw, calibrated, best "
             "linear fit", f"{solve_rms['raw']:.3f}, {solve_rms['calibrated']:.3f}, {solve_best:.3f} deg RMS"],
            [f"turning misfit over {PLOT_WINDOW_S:g} s windows: raw, calibrated, best linear fit",
             f"{plot_rms['raw']:.3f}, {plot_rms['calibrated']:.3f}, {plot_best:.3f} deg RMS"],
            ["calibrated misfit over the best linear fit's (a converged solve stays within 1.12)", f"{ratio:.3f}"],
            [f"field magnitude |R (y − h)| over {FIELD_WINDOW_S:g} s: median, largest deviation from 1",
             f"{100 * change.median_fraction:.2f} %, {100 * change.max_fraction:.2f} % at {change.at_s:.1f} s"],
            ["field magnitude, largest single-sample deviation from 1",
             f"{100 * deviation[worst]:.2f} % at {moving.t_mag_s[worst]:.2f} s"]]
    fit = cal.fit
    if fit is not None and hasattr(fit, "mag_rms_normalised"):
        rows.append(["whitened residual RMS: magnetometer, gyro (1 = the noise level assumed)",
                     f"{fit.mag_rms_normalised:.3f}, {fit.gyro_rms_normalised:.3f}"])
        if fit.suspect_segments:
            rows.append(["suspect windows (magnetometer fits far worse than typical)",
                         "; ".join(f"{w.t0_s:.1f}–{w.t1_s:.1f} s ({w.residual_vs_typical:.1f}×)"
                                   for w in fit.suspect_segments)])
    details = table(["", ""], rows, "keyvalue")
    details += (f"<p class='small'>Computed on the moving part of the session ({moving.t_gyro_s[0]:.1f}–"
                f"{moving.t_gyro_s[-1]:.1f} s), as the solve sees it, on the calibrated field R (y − h). A window's "
                "misfit is the norm of the field's change the gyro predicts (paper eq. 13) minus the change "
                "measured; the raw gyro is K = I, ε = 0 with no magnetometer lag.</p>")
    fig = figures.residual_figure(windows, FieldMagnitude(moving.t_mag_s, magnitude), MAX_FIELD_CHANGE,
                                  FIELD_WINDOW_S)
    return Section("residuals", "4. The fit's residuals over time", status,
                   f"misfit −{100 * reduction:.0f} % vs raw, field within {100 * change.max_fraction:.1f} %",
                   sentence, figures.embedded(fig), "turning misfit and field magnitude over time", details)


# --------------------------------------------------------------------------- 5. the split-half check


SPLIT_LABELS = {"K_g[0,0]": "scale x", "K_g[1,1]": "scale y", "K_g[2,2]": "scale z", "K_g[0,1]": "non-orth xy",
                "K_g[0,2]": "non-orth xz", "K_g[1,2]": "non-orth yz", "bias_x_deg_s": "bias x",
                "bias_y_deg_s": "bias y", "bias_z_deg_s": "bias z", "misalignment_dx_deg": "misalign. x",
                "misalignment_dy_deg": "misalign. y", "misalignment_dz_deg": "misalign. z"}


def split_section(check, computed_here: bool, why_not: str | None = None) -> Section:
    title = "5. The split-half check"
    if check is None:
        return Section("split", title, "", "not run", f"The split-half check was not run: {why_not}.")
    spans = "; ".join(f"{a:.1f}–{b:.1f} s" for a, b in check.spans_s)
    if not check.compared:
        return Section("split", title, FAIR, "a half failed",
                       f"The split-half check could not compare the halves ({spans}): "
                       f"{'; '.join(map(str, check.failed))}.")
    label = SPLIT_LABELS.get(check.worst, check.worst)
    ok = check.agrees          # the judgement of `magyro solve --split-check`, from the same numbers
    if ok:
        sentence = (f"The two halves of the recording ({spans}) agree within their std: the RMS z is "
                    f"{check.rms_z:.2f} (within {check.max_rms_z:g}) and the largest |z| {check.max_abs_z:.1f} on "
                    f"{label} (within {check.max_half_z:g}), so the calibration's one-sigma holds on this recording.")
        caveat = ""
    else:
        sentence = (f"The two halves of the recording ({spans}) disagree by {check.rms_z:.1f} σ RMS, at most "
                    f"{check.max_abs_z:.1f} σ on {label} (a warning above {check.max_rms_z:g} RMS or "
                    f"{check.max_half_z:g}): the model does not hold throughout, so the calibration's std "
                    f"understates the error by about {max(check.rms_z, 1.0):.1f}×.")
        caveat = (f"the two halves of the recording disagree by {check.rms_z:.1f} σ RMS, so the calibration's "
                  f"std understates the error by about {max(check.rms_z, 1.0):.1f}×")
    rows = []
    for name, p in check.parameters.items():
        scale = 1e6 if name in ("K_g[0,0]", "K_g[1,1]", "K_g[2,2]") else float(np.rad2deg(1.0)) \
            if name.startswith("K_g") else 1.0
        unit = "ppm" if scale == 1e6 else "deg" if name.startswith(("K_g", "misalignment")) else "deg/s"
        offset = 1e6 if scale == 1e6 else 0.0
        d = 0 if unit == "ppm" else 4

        def f(v, sign=True):
            return f"{v:+.{d}f}" if sign else f"{v:.{d}f}"

        rows.append([SPLIT_LABELS.get(name, name), f(p["first"] * scale - offset), f(p["second"] * scale - offset),
                     f(p["difference"] * scale), f(p["reported_std"] * scale, False), f(p["split_std"] * scale, False),
                     f"{p['z']:+.2f}", unit])
    details = table(["parameter", "first half", "second half", "difference", "calibration's σ",
                     "half the difference", "z", "unit"], rows, "numbers")
    details += ("<p class='small'>z is the halves' difference over the std of that difference (the halves' own std "
                "combined); when the model holds it is about unit normal, and the check is judged on z alone, as "
                "<code>magyro solve --split-check</code> judges it. Half the difference is one draw of the error, "
                "not a std: shown beside the calibration's one-sigma, never in its place. Misalignment here is the "
                "rotation vector of each half's C_b_m against the full session's."
                + (" This check was computed for this report (it solves the least squares twice, once per half)."
                   if computed_here else " This check was carried in the calibration file.") + "</p>")
    fig = figures.split_figure(check, SPLIT_LABELS)
    return Section("split", title, GOOD if ok else FAIR, f"RMS z {check.rms_z:.2f}, max {check.max_abs_z:.1f}",
                   sentence, figures.embedded(fig), "each gyro parameter's split-half z", details, caveat)
