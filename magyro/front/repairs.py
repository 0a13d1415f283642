"""The repairs of the recording check where the fix is known, each on by default and each with its switch.

    session, check = repair_recording(session, Repairs())            # all four
    session, check = repair_recording(session, Repairs(drop_held=False))   # --no-repair held

- `restamp_bursts`  a sensor whose stamps come in bursts (buffered data stamped on arrival)
                    gets t_k = a(k) + b k from its sample index, stretch by stretch between gaps
                    (lost data; a stall that lost nothing is run through); a regular clock with dropped
                    samples is never restamped (holes stay holes); when the fitted times cannot be used
                    the check's `bursts` finding says why (an error) and the stamps are kept;
- `drop_held`       rows repeating the previous row are dropped, the first of each run kept
                    (only on a sensor the check found holding values);
- `cut_saturation`  gyro rows on a saturation plateau are removed; the spans they leave are
                    gyro holes, whatever their length (the true rate there is unknown);
- `drop_spikes`     magnetometer spikes are removed.

The input session and its arrays are never modified. The returned check has
`repaired=True` on what was fixed, a `gyro_holes` finding and `gyro_holes_s`: the
spans without gyro data (over GAP_PERIODS periods, or cut for saturation) that an
integration must not cross.
"""
from __future__ import annotations

from dataclasses import replace

import numpy as np

from magyro.front.findings import GAP_PERIODS, Finding, RecordingCheck
from magyro.front.recording import inspect
from magyro.front.signals import SOLVE_LAG_SEARCH_S
from magyro.options import Repairs
from magyro.session import HOLE_FACTOR, Session, runs_of_true


def kept(array: np.ndarray, keep: np.ndarray) -> np.ndarray:
    """The rows of `array` that `keep` keeps: the array itself when it keeps every row (a session is never changed in
    place, and a copy of an untouched recording held it twice through the solve: 22 MB at 360k samples)."""
    return array if keep.all() else array[keep]


def repair_recording(session: Session, repairs: Repairs | None = None) -> tuple[Session, RecordingCheck]:
    """(the repaired session, the check of the recording as given, with `repaired` set on what was fixed)."""
    repairs = repairs or Repairs()
    check, evidence = inspect(session)
    fixed = set()
    times = {"gyro": session.t_gyro_s, "magnetometer": session.t_mag_s}
    values = {"gyro": session.gyro_rad_s, "magnetometer": session.mag}
    keep = {sensor: np.ones(len(t), dtype=bool) for sensor, t in times.items()}
    if repairs.restamp_bursts:
        for sensor, t in evidence.restamped.items():   # increasing: the check names why when it cannot restamp
            times[sensor] = t
            fixed.add(("bursts", sensor))
    if repairs.drop_spikes and evidence.spikes.any():
        keep["magnetometer"] &= ~evidence.spikes
        fixed.add(("spikes", "magnetometer"))
    if repairs.drop_spikes and evidence.anomaly.any():
        keep["magnetometer"] &= ~evidence.anomaly
        fixed.add(("field_anomaly", "magnetometer"))
    if repairs.cut_saturation and evidence.mag_saturated.any():
        keep["magnetometer"] &= ~evidence.mag_saturated
        fixed.add(("saturation", "magnetometer"))
    if repairs.cut_saturation and evidence.saturated.any():
        evidence.saturated = widened_to_holes(evidence.saturated)
        keep["gyro"] &= ~evidence.saturated
        fixed.add(("saturation", "gyro"))
    if repairs.drop_held:
        for sensor in ("gyro", "magnetometer"):
            if check.find("held", sensor):
                keep[sensor] &= ~held_after(values[sensor], keep[sensor])
                fixed.add(("held", sensor))
    stretched = [f.numbers["stretch"] for f in check.find("clock_drift") if "stretch" in f.numbers]
    if repairs.align_clocks and stretched:   # one clock runs fast over the whole span: shrink it back
        t_m = times["magnetometer"]
        times["magnetometer"] = t_m[0] + (t_m - t_m[0]) / (1.0 + stretched[0])
        fixed.add(("clock_drift", "both"))
    elif repairs.align_clocks and check.lag_s and (check.find("clock_drift") or check.find("time_offset")):
        times["magnetometer"] = aligned_magnetometer_times(times["magnetometer"], check.lag_s, check.lag_at_s)
        fixed |= {("clock_drift", "both"), ("time_offset", "both")}
    repaired = replace(session, **{name: kept(array, keep[sensor]) for name, array, sensor in (
        ("t_gyro_s", times["gyro"], "gyro"), ("gyro_rad_s", values["gyro"], "gyro"),
        ("t_mag_s", times["magnetometer"], "magnetometer"), ("mag", values["magnetometer"], "magnetometer"))},
                       t_acc_s=accelerometer_times(session, times["gyro"], ("bursts", "gyro") in fixed))
    cut = evidence.saturated if ("saturation", "gyro") in fixed else np.zeros(len(keep["gyro"]), dtype=bool)
    holes = gyro_holes(times["gyro"], keep["gyro"], cut)
    findings = [replace(f, repaired=True) if (f.kind, f.sensor) in fixed else truthful(f, repairs) for f in check.findings]
    if holes:
        findings.append(holes_finding(holes))
    return repaired, replace(check, findings=tuple(findings), gyro_holes_s=tuple(holes),
                             repairs={name: bool(on) for name, on in repairs.__dict__.items()})


def accelerometer_times(session: Session, t_gyro_s: np.ndarray, gyro_restamped: bool) -> np.ndarray | None:
    """The accelerometer's stamps: the gyro's restamped ones when it shares the gyro's rows (one IMU read and
    stamped together, as the gyro's bursts were), else its own as recorded. Left on the bursts, a restamped gyro's
    accelerometer lagged it by up to a burst (0.25 s on BROAD 02 stamped in bursts) and its calibration came out
    past the refusal bound."""
    t_a = session.t_acc_s
    if gyro_restamped and t_a is not None and np.array_equal(t_a, session.t_gyro_s):
        return t_gyro_s
    return t_a


def truthful(finding: Finding, repairs: Repairs) -> Finding:
    """The finding with the fix that is true when its repair was turned off (`--no-repair`)."""
    if finding.repair and not getattr(repairs, Repairs.NAMES[finding.repair]):
        return replace(finding, fix=finding.fix_off)
    return finding


def aligned_magnetometer_times(t_m: np.ndarray, lag_s: tuple, lag_at_s: tuple) -> np.ndarray:
    """The magnetometer's stamps less the lag the check measured, as a line through its two measurements; a lag
    the solve can find itself (within its search) is left for it, with its std."""
    (l0, l1), (c0, c1) = lag_s, lag_at_s
    lag = l0 + (l1 - l0) * (t_m - c0) / (c1 - c0)
    mean = 0.5 * (l0 + l1)
    return t_m - (lag - (mean if abs(mean) <= SOLVE_LAG_SEARCH_S else 0.0))


def widened_to_holes(cut: np.ndarray) -> np.ndarray:
    """The cut widened so that each run of it leaves a hole (`magyro.session.HOLE_FACTOR` periods or more) that
    every integration sees and never crosses: a plateau of 2 samples cut alone would be bridged by
    interpolating rates the gyro could not measure."""
    need = int(np.ceil(HOLE_FACTOR)) + 1
    wide = cut.copy()
    for a, last in runs_of_true(cut):
        short = need - (last + 1 - a)
        if short > 0:
            wide[max(a - short // 2, 0): min(last + 1 + short - short // 2, len(cut))] = True
    return wide


def held_after(x: np.ndarray, keep: np.ndarray) -> np.ndarray:
    """Rows (of all of x) that repeat the previous kept row exactly; only kept rows are marked."""
    kept = np.flatnonzero(keep)
    repeat = np.zeros(len(x), dtype=bool)
    repeat[kept[1:]] = np.all(x[kept[1:]] == x[kept[:-1]], axis=1)
    return repeat


def gyro_holes(t: np.ndarray, keep: np.ndarray, cut: np.ndarray) -> list:
    """Spans with no gyro data that an integration must not cross: intervals of the kept samples over
    GAP_PERIODS typical periods, and every span left by samples cut for saturation; merged, in order."""
    kept = np.flatnonzero(keep)
    if len(kept) < 2:
        return []
    tk = t[kept]
    dt = np.diff(tk)
    median = float(np.median(dt))
    ordinary = dt[dt <= 3 * median]
    period = float(ordinary.mean()) if len(ordinary) else median
    crosses_cut = np.zeros(len(dt), dtype=bool)
    if cut.any():
        n_cut = np.concatenate([[0], np.cumsum(cut)])
        crosses_cut = n_cut[kept[1:]] - n_cut[kept[:-1] + 1] > 0   # a cut sample between two kept ones
    i = np.flatnonzero((dt > GAP_PERIODS * period) | crosses_cut)
    return [(float(tk[j]), float(tk[j + 1])) for j in i]


def holes_finding(holes: list) -> Finding:
    total = sum(b - a for a, b in holes)
    longest = max(b - a for a, b in holes)
    return Finding(
        "gyro_holes", "gyro", f"after repair the gyro has {len(holes)} hole(s), {total:.3f} s in all (longest "
        f"{longest:.3f} s): spans with no gyro data over {GAP_PERIODS:g} periods, or cut for saturation",
        tuple(holes), "info",
        "the attitude cannot be carried across a hole by the gyro; each hole starts a new attitude segment "
        "that the magnetometer alone ties to the rest", "nothing: the solve never integrates across them",
        numbers={"count": len(holes), "seconds": total, "longest_s": longest})
