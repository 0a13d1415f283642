"""The report's six sections: for each, the numbers, one sentence saying what they mean and whether that is
good (computed from the numbers), a status (good, fair, poor), a figure and the details.

Each `*_section` function takes what it judges and returns a `Section` (magyro.report.section);
`magyro.report.build` calls them in order and `magyro.report.html` lays them out. Sections 1-3 and 6 are here;
4 (the residuals) and 5 (the split-half check), how well the calibration explains the recording and agrees
with itself, are in magyro.report.fit_sections.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from magyro.front.findings import lag_line
from magyro.report import figures
from magyro.report.fit_sections import residual_section, split_section  # noqa: F401  (sections 4 and 5)
from magyro.report.section import FAIR, GOOD, POOR, Section, esc, num, table  # noqa: F401  (esc: public)
from magyro.result.parts import solver_outcome, solver_summary
from magyro.text import significant

# the calibration section judges each one-sigma against the accuracy targets (magyro.targets), as observe does
DEAD_RECKONING_GOOD_RATIO = 0.5   # calibrated / raw error at most this: the calibration clearly pays


@dataclass(frozen=True)
class ParameterRow:
    group: str                 # scale | nonorth | bias | misalignment
    axis: str                  # x, y, xy, roll, ...
    label: str
    value: float               # in `unit`
    std: float
    unit: str
    split_std: float | None = None
    rest: float | None = None  # the bias the rests imply


# --------------------------------------------------------------------------- 1. the recording check


def recording_section(raw, repaired, check) -> Section:
    repaired_findings = [f for f in check.findings if f.repaired]
    open_warnings = [f for f in check.warnings if not f.repaired]
    rates = ", ".join(f"{name} {s.rate_hz:.1f} Hz" for name, s in check.sensors.items())
    gaps = sum(s.gaps for s in check.sensors.values())
    holes = len(check.gyro_holes_s)
    facts = (f"{rates}, {gaps} gap{'s' * (gaps != 1)}, {holes} gyro hole{'s' * (holes != 1)}; magyro repaired "
             f"{len(repaired_findings)} finding{'s' * (len(repaired_findings) != 1)}"
             + (f" ({', '.join(sorted({f'{f.kind} {f.sensor}' for f in repaired_findings}))})"
                if repaired_findings else ""))
    if check.errors:
        status, headline = POOR, f"unusable: {len(check.errors)} error(s)"
        sentence = (f"The recording is not usable as it is ({check.errors[0].message}): {facts}.")
    elif open_warnings:
        status, headline = FAIR, f"usable, {len(open_warnings)} warning(s)"
        sentence = (f"The recording is usable but {len(open_warnings)} problem{'s' * (len(open_warnings) != 1)} "
                    f"remain{'s' * (len(open_warnings) == 1)} unrepaired ({', '.join(f.kind for f in open_warnings)}): "
                    f"{facts}.")
    else:
        status, headline = GOOD, "clean" if not repaired_findings else f"clean after {len(repaired_findings)} repair(s)"
        sentence = f"The recording is clean{' after the repairs' if repaired_findings else ''}: {facts}."
    rows = [[s.sensor, f"{s.samples:,}", f"{s.rate_hz:.2f}", f"{s.distinct_rate_hz:.2f}", f"{s.jitter_s * 1e3:.3f}",
             f"{s.start_s:.3f} – {s.end_s:.3f}", f"{100 * s.held_fraction:.1f}", s.gaps,
             "bursty" if s.bursty else "regular"] for s in check.sensors.values()]
    details = table(["sensor", "samples", "rate (Hz)", "distinct (Hz)", "jitter (ms)", "span (s)", "held (%)",
                     "gaps", "clock"], rows, "numbers")
    if len(check.lag_s) == 2:
        details += f"<p>{esc(lag_line(check.lag_s).capitalize())}.</p>"
    if check.findings:
        items = []
        for f in check.findings:
            tag = "repaired" if f.repaired else f.severity
            extra = "".join(f"<div class='sub'><b>{label}:</b> {esc(text)}</div>"
                            for label, text in (("matters", f.matters), ("fix", f.fix)) if text)
            items.append(f"<li><span class='tag {esc(tag)}'>{esc(tag)}</span> <b>{esc(f.kind)}</b> "
                         f"({esc(f.sensor)}): {esc(f.message)}{extra}</li>")
        details += "<ul class='findings'>" + "".join(items) + "</ul>"
    else:
        details += "<p>No findings.</p>"
    fig = figures.recording_figure(raw, repaired, check)
    return Section("recording", "1. The recording", status, headline, sentence, figures.embedded(fig),
                   "sample intervals of the gyro and the magnetometer over time", details)


# --------------------------------------------------------------------------- 2. excitation and coverage


def excitation_section(report) -> Section:
    from magyro.observability.plot import report_figure

    c = report.coverage
    status = {"sufficient": GOOD, "marginal": FAIR}.get(report.verdict, POOR)
    sentence = (f"The motion excites {report.rank} of the 12 gyro parameters (condition {num(report.condition)}) "
                f"and sweeps the field over {100 * c.sphere_fraction:.0f} % of the sphere, so the excitation is "
                f"{report.verdict}: {report.reason.rstrip('.')}.")
    rows = [["rank", f"{report.rank} of 12"], ["condition number", num(report.condition)],
            ["field directions covered", f"{100 * c.sphere_fraction:.0f} % ({c.cells_visited}/{c.cells} cells)"],
            ["angle turned per gyro axis (deg)", ", ".join(f"{a:.0f}" for a in c.angle_turned_deg)],
            ["peak rate per gyro axis (deg/s)", ", ".join(f"{a:.0f}" for a in c.peak_rate_deg_s)],
            ["full rank reached at (session time)",
             "never" if report.full_rank_at_s is None else f"{report.full_rank_at_s:.1f} s"],
            ["well conditioned at (session time)", "never" if report.well_conditioned_at_s is None
             else f"{report.well_conditioned_at_s:.1f} s"]]
    details = table(["", ""], rows, "keyvalue")
    if report.weak_directions:
        details += ("<p><b>Weakest directions:</b></p><ul>"
                    + "".join(f"<li>{esc(w)}</li>" for w in report.weak_directions[:4]) + "</ul>")
    if report.advice:
        details += "<p><b>Advice:</b></p><ul>" + "".join(f"<li>{esc(a)}</li>" for a in report.advice[:3]) + "</ul>"
    return Section("excitation", "2. Excitation and coverage", status,
                   f"{report.verdict}, rank {report.rank}/12", sentence,
                   figures.embedded(report_figure(report)),
                   "field-direction coverage, eigenvalue growth and rates (magyro observe's figure)", details)


# --------------------------------------------------------------------------- 3. the calibration


SPLIT_NAMES = {"scale": "K_g[{i},{i}]", "bias": "bias_{a}_deg_s", "misalignment": "misalignment_d{a}_deg"}


def parameter_rows(cal, check=None) -> list[ParameterRow]:
    """The gyro parameters in readable units, each with its std (and split-half std, rest bias when known)."""
    s = cal.std
    split = check.parameters if check is not None and check.compared else {}

    def split_std(name, scale=1.0):
        return split[name]["split_std"] * scale if name in split else None

    rows = []
    for i, a in enumerate("xyz"):
        rows.append(ParameterRow("scale", a, f"scale factor {a}", 1e6 * (cal.K_g[i, i] - 1.0), 1e6 * s.K_g[i][i],
                                 "ppm", split_std(f"K_g[{i},{i}]", 1e6)))
    for i, j in ((0, 1), (0, 2), (1, 2)):
        axis = "xyz"[i] + "xyz"[j]
        rows.append(ParameterRow("nonorth", axis, f"non-orthogonality {axis} (K_g[{i},{j}])",
                                 float(np.rad2deg(cal.K_g[i, j])), float(np.rad2deg(s.K_g[i][j])), "deg",
                                 split_std(f"K_g[{i},{j}]", float(np.rad2deg(1.0)))))
    rest = cal.rests.bias_deg_s if cal.rests is not None else None
    for k, a in enumerate("xyz"):
        rows.append(ParameterRow("bias", a, f"bias {a}", float(cal.bias_deg_s[k]), float(s.bias_deg_s[k]), "deg/s",
                                 split_std(f"bias_{a}_deg_s"), None if rest is None else float(rest[k])))
    for k, (a, name) in enumerate(zip("xyz", ("roll", "pitch", "yaw"))):
        rows.append(ParameterRow("misalignment", name, f"misalignment {name} (C_b_m)", float(cal.euler_deg[k]),
                                 float(s.misalignment_deg[k]), "deg", split_std(f"misalignment_d{a}_deg")))
    return rows


def accelerometer_rows(acc) -> list[ParameterRow]:
    """The accelerometer's parameters (solved with the gyro, by default when the session has one) in readable units, each with its std: scale
    factors (K_a's diagonal - 1, ppm), non-orthogonality (above it, as angles), bias (m/s^2) and C_b_a's Euler
    angles. Judged against the accelerometer's own targets (`Targets.acc_*`)."""
    rows = []
    for i, a in enumerate("xyz"):
        rows.append(ParameterRow("acc_scale", a, f"scale factor {a}", 1e6 * (acc.K_a[i, i] - 1.0),
                                 1e6 * acc.std_K_a[i, i], "ppm"))
    for i, j in ((0, 1), (0, 2), (1, 2)):
        axis = "xyz"[i] + "xyz"[j]
        rows.append(ParameterRow("acc_nonorth", axis, f"non-orthogonality {axis} (K_a[{i},{j}])",
                                 float(np.rad2deg(acc.K_a[i, j])), float(np.rad2deg(acc.std_K_a[i, j])), "deg"))
    for k, a in enumerate("xyz"):
        rows.append(ParameterRow("acc_bias", a, f"bias {a}", float(acc.bias_m_s2[k]), float(acc.std_bias_m_s2[k]),
                                 "m/s²"))
    for k, name in enumerate(("roll", "pitch", "yaw")):
        rows.append(ParameterRow("acc_misalignment", name, f"misalignment {name} (C_b_a)", float(acc.euler_deg[k]),
                                 float(acc.std_misalignment_deg[k]), "deg"))
    return rows


def accelerometer_details(acc, targets=None) -> str:
    """The accelerometer's table for the calibration section's details (HTML), each one-sigma against its target."""
    from magyro.targets import Targets

    targets = targets or Targets()
    digits = {"ppm": 0, "deg": 3, "m/s²": 4}
    body = [[r.label, f"{r.value:+.{digits[r.unit]}f}", f"{r.std:.{digits[r.unit]}f}", f"{target_of(r, targets):g}",
             r.unit] for r in accelerometer_rows(acc)]
    body.append([f"gravity it was calibrated against ({acc.gravity_source})", f"{acc.g_m_s2:.5f}", "", "", "m/s²"])
    return ("<h3>Accelerometer</h3>" + table(["parameter", "estimate", "± 1σ", "target (1σ)", "unit"], body,
                                             "numbers params")
            + "<p class='small'>Solved in the same least squares as the gyro (<code>magyro solve</code> calibrates it by "
            "default when the session has one) against gravity: f_a = K_a y_a + ε_a in the accelerometer's frame a, f_b = C_b_aᵀ f_a in the gyro's. Scale "
            "factors are K_a's diagonal minus 1 in ppm; non-orthogonality is K_a's off-diagonal as an angle; the "
            "misalignment is C_b_a (gyro to accelerometer frame) as roll, pitch, yaw. Each one-sigma is judged "
            "against the accelerometer's own targets (<code>acc_*</code> in the <code>[targets]</code> table): "
            "by default a bias of 0.02 m/s², which tilts gravity's direction by 0.12 deg; 2000 ppm of scale and 0.1 deg of "
            "non-orthogonality put as much error on an axis at 1 g; 0.1 deg of misalignment is the gyro's own "
            "target.</p>")


def sigma(r: ParameterRow) -> float:
    """The calibration's one-sigma of a parameter, the one judged against the targets. Half the split-half
    difference (`split_std`) is one difference, one draw of the error: shown beside it, never in its place."""
    return r.std


def target_of(r: ParameterRow, targets) -> float:
    """The target of a parameter's one-sigma: the gyro's, or the accelerometer's own (`acc_*` groups)."""
    return {"scale": targets.scale_factor_ppm, "nonorth": targets.non_orthogonality_deg,
            "bias": targets.bias_deg_s, "misalignment": targets.misalignment_deg,
            "acc_scale": targets.acc_scale_factor_ppm, "acc_nonorth": targets.acc_non_orthogonality_deg,
            "acc_bias": targets.acc_bias_m_s2, "acc_misalignment": targets.acc_misalignment_deg}[r.group]


def above_targets(rows, targets) -> list[ParameterRow]:
    """The parameters whose one-sigma (the calibration's) is above its target, worst (largest ratio) first."""
    return sorted((r for r in rows if not sigma(r) <= target_of(r, targets)),
                  key=lambda r: -sigma(r) / target_of(r, targets))


def known_to(r: ParameterRow) -> str:
    """'scale x is known only to ±3038 ppm' (the calibration's one-sigma)."""
    name = {"scale": "scale", "nonorth": "non-orthogonality", "bias": "bias", "misalignment": "misalignment"}[
        r.group.removeprefix("acc_")]
    whose = "the accelerometer's " if r.group.startswith("acc_") else ""
    return f"{whose}{name} {r.axis} is known only to ±{num(sigma(r), 2)} {r.unit}"


def calibration_section(cal, check=None, targets=None) -> Section:
    from magyro.targets import Targets

    targets = targets or Targets()
    rows = parameter_rows(cal, check)
    by = {g: [r for r in rows if r.group == g] for g in ("scale", "nonorth", "bias", "misalignment")}
    worst_scale = max(by["scale"], key=sigma)
    worst_bias = max(by["bias"], key=sigma)
    worst_mis = max(by["misalignment"], key=sigma)
    solved = "succeeded" in cal.solver.status.lower() or "acceptable" in cal.solver.status.lower() \
        or cal.solver.status.lower() in ("converged", "ok", "given")
    acc = cal.accelerometer
    acc_rows = accelerometer_rows(acc) if acc is not None else []
    above = above_targets(rows, targets)
    acc_above = above_targets(acc_rows, targets)   # the accelerometer against its own targets
    determined = not above and not acc_above
    status = GOOD if (solved and determined and cal.observability.rank == 12) else FAIR if solved else POOR
    scales = ", ".join(f"{r.value:+.0f}" for r in by["scale"])
    biases = ", ".join(f"{r.value:+.3f}" for r in by["bias"])
    judged = ("every one-sigma within the targets" if not above else
              f"{len(above)} of the 12 one-sigma above the targets ({targets.text()})")
    sentence = (f"The gyro's scale factors are off by {scales} ppm and its bias is {biases} deg/s, {judged}: "
                f"the largest one-sigma is {num(sigma(worst_scale), 2)} ppm on scale {worst_scale.axis}, "
                f"{num(sigma(worst_bias), 2)} deg/s on bias {worst_bias.axis} and {num(sigma(worst_mis), 2)} deg on "
                f"misalignment {worst_mis.axis}")
    if cal.rests is not None and cal.rests.seconds > 0:
        sentence += (f", and the {cal.rests.seconds:.1f} s of rest imply a bias within "
                     f"{num(float(np.max(np.abs(cal.rests.estimate_minus_rest_deg_s))), 2)} deg/s of the estimate")
    if acc is not None:
        acc_judged = ("every one-sigma within its own targets" if not acc_above else
                      f"{len(acc_above)} of its 12 one-sigma above its own targets ({targets.accelerometer_text()})")
        acc_scale = [r for r in acc_rows if r.group == "acc_scale"]
        acc_bias = [r for r in acc_rows if r.group == "acc_bias"]
        sentence += (f"; the accelerometer's scale factors are off by {', '.join(f'{r.value:+.0f}' for r in acc_scale)}"
                     f" ppm and its bias is {', '.join(f'{r.value:+.4f}' for r in acc_bias)} m/s², known to "
                     f"±{num(max(r.std for r in acc_scale), 2)} ppm and ±{num(max(r.std for r in acc_bias), 2)} m/s² "
                     f"at most, {acc_judged}")
    sentence += (f" ({cal.solver.method} {'converged' if solved else solver_outcome(cal.solver.status)}, "
                 f"{cal.solver.iterations} iterations).")
    has_split = any(r.split_std is not None for r in rows)
    has_rest = any(r.rest is not None for r in rows)
    header = ["parameter", "estimate", "± 1σ", *(["half the split-half difference (one draw, not a σ)"] if has_split else []),
              *(["from the rests"] if has_rest else []), "unit"]
    digits = {"ppm": 0, "deg": 3, "deg/s": 4}
    body = []
    for r in rows:
        d = digits[r.unit]
        line = [r.label, f"{r.value:+.{d}f}", f"{r.std:.{d}f}"]
        if has_split:
            line.append("" if r.split_std is None else f"{r.split_std:.{d}f}")
        if has_rest:
            line.append("" if r.rest is None else f"{r.rest:+.{d}f}")
        body.append(line + [r.unit])
    details = table(header, body, "numbers params")
    mag = [["hard iron h (" + cal.mag_unit + ")", ", ".join(f"{v:+.4g} ± {e:.2g}" for v, e in zip(cal.h, cal.std.h))],
           ["field strength (" + cal.mag_unit + ")", f"{1.0 / np.cbrt(np.prod(np.diag(cal.R))):.4g}"],
           ["R diagonal", ", ".join(f"{cal.R[i, i]:.5g} ± {cal.std.R[i][i]:.2g}" for i in range(3))]]
    if cal.time_offset_estimated:
        mag.append(["magnetometer lag behind the gyro",
                    f"{1e3 * cal.time_offset_s:+.2f} ± {1e3 * cal.std.time_offset_s:.2f} ms"])
    if cal.noise is not None:
        mag.append(["gyro noise density", f"{significant(np.rad2deg(cal.noise.gyro_density_rad_s_sqrt_hz))} deg/s/√Hz"])
        mag.append(["magnetometer noise (" + cal.mag_unit + ")", f"{significant(cal.noise.mag_std)}"])
    mag.append(["observability", f"rank {cal.observability.rank} of 12, condition {num(cal.observability.condition)}"])
    mag.append(["solver", solver_summary(cal.solver)])
    details += "<h3>Magnetometer and solve</h3>" + table(["", ""], mag, "keyvalue")
    details += ("<p class='small'>Scale factors are K_g's diagonal minus 1 in parts per million; non-orthogonality "
                "is K_g's off-diagonal as an angle; the misalignment is C_b_m (gyro to magnetometer frame) as roll, "
                "pitch, yaw. Model: ω = K_g y + ε_b.</p>")
    if acc is not None:
        details += accelerometer_details(acc, targets)
    fig = figures.calibration_figure(rows)
    first = (above or acc_above or [None])[0]
    caveat = ("" if status == GOOD else
              f"{known_to(first)}, above its {target_of(first, targets):g} {first.unit} target"
              if not determined else f"the solver {solver_outcome(cal.solver.status)}" if not solved
              else f"the motion excites only {cal.observability.rank} of the 12 parameters")
    return Section("calibration", "3. The calibration", status,
                   f"scale σ ≤ {num(sigma(worst_scale), 2)} ppm, bias σ ≤ {num(sigma(worst_bias), 2)} deg/s",
                   sentence, figures.embedded(fig), "each gyro parameter with its one-sigma", details, caveat)


# --------------------------------------------------------------------------- 6. dead reckoning


def dead_reckoning_section(report) -> Section:
    from magyro.studies.dead_reckoning import validation_figure

    raw, cal = report.summary["raw"], report.summary["calibrated"]
    ratio = report.ratio
    removed = 100 * (1.0 - ratio)
    if report.mode == "truth":
        what = (f"Against the optical truth the calibrated gyro dead-reckons with {num(cal['rms_deg'], 2)} deg RMS "
                f"error ({num(cal['final_deg'], 2)} deg at the end) against {num(raw['rms_deg'], 2)} deg raw "
                f"({num(raw['final_deg'], 2)} deg at the end)")
        rows = [[f"{name} gyro", f"{s['rms_deg']:.3f}", f"{s['max_deg']:.3f}", f"{s['final_deg']:.3f}"]
                for name, s in report.summary.items()]
        details = table(["", "RMS (deg)", "max (deg)", "final (deg)"], rows, "numbers")
    else:
        what = (f"The calibrated gyro closes the loop with {num(cal['closure_deg'], 2)} deg of drift at the end "
                f"against {num(raw['closure_deg'], 2)} deg raw")
        rows = [[f"{name} gyro", f"{s['closure_deg']:.3f}", f"{s['closure_deg_per_min']:.3f}"]
                for name, s in report.summary.items()]
        details = table(["", "closure drift (deg)", "per minute (deg)"], rows, "numbers")
    if not np.isfinite(ratio):
        status, verdict = "", "there is no drift to compare"
    elif ratio <= DEAD_RECKONING_GOOD_RATIO:
        status, verdict = GOOD, f"the calibration removes {removed:.0f} % of the error"
    elif ratio < 1.0:
        status, verdict = FAIR, f"the calibration removes only {removed:.0f} % of the error"
    else:
        status, verdict = POOR, f"the calibration makes it {ratio:.1f}× worse"
    sentence = f"{what}: {verdict}."
    if report.notes:
        details += "<ul>" + "".join(f"<li>{esc(n)}</li>" for n in report.notes) + "</ul>"
    headline = f"{'−' if removed >= 0 else '+'}{abs(removed):.0f} % error" if np.isfinite(ratio) else "n/a"
    return Section("dead-reckoning", "6. Dead reckoning, raw against calibrated", status, headline, sentence,
                   figures.embedded(validation_figure(report)),
                   "dead-reckoning error of the raw and the calibrated gyro", details)
