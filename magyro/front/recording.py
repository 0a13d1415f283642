"""The recording check: what real loggers get wrong, found before any method runs (issue 11).

    check = check_recording(session)          # findings, per-sensor stats; nothing changed
    session, check = repair_recording(session, Repairs())   # magyro.front.repairs: the known fixes

Per sensor (gyro, magnetometer) the check measures the rate and timestamp
jitter and looks for:

- `time_unit`   stamps that are not seconds (a mean period of 3.5 "s" is 3.5 ms);
- `bursts`      host stamps of buffered data: most intervals far below the period,
                then long waits (a serial logger stamping each sample on arrival); restamped
                from the sample index through stalls (a long wait that lost nothing), or
                refused with the reason (an error) when no restamp can be trusted;
- `gaps`        intervals over GAP_PERIODS periods (dropped data), with their times;
- `held`        rows repeating the previous row exactly (a slow sensor logged on a
                faster clock by sample-and-hold);
- `saturation`  gyro plateaus at the range, per axis and sign (many samples at one
                extreme value, entered steeply);
- `spikes`      magnetometer samples far off the median of their neighbours, against
                the local spread and the noise;
- `overlap`, `clock_drift`, `time_offset`  the two sensors' clocks: spans that do not
                overlap, a lag that changes along the recording, a lag beyond the
                solve's search;
- `gyro_unit`   the gyro turning the field 57x too fast or too slow for what the
                magnetometer sees (deg/s labelled rad/s, or the reverse);
- `acc_unit`, accelerometer `saturation`  when the session has an accelerometer: gravity read
                in g or mg labelled m/s^2 (error), plateaus at its range (warning)
                (magyro.front.accelerometer_checks);
- `jitter`      (info) host-made stamps; `samples` (error) too few to check;
                `gyro_holes` (info, after repair) the spans an integration must not cross.

Each finding says what, where (times), how much it matters for the calibration and
the fix. Severity "error" means the recording is unusable as it is (exit 2). Pure
numpy, vectorised (about 20 ms on a 34k-sample session): the solve path imports
neither pandas nor scipy.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from magyro.front import accelerometer_checks, field_checks
from magyro.front.findings import GAP_PERIODS, SEVERITIES, Finding, RecordingCheck, SensorStats, repairable
from magyro.front.restamp import (BURST_LONG_PERIODS, RESTAMP_QUANTILE, RESTAMP_TRUST_PERIODS,  # noqa: F401
                                  RESTAMP_WINDOW_S, clock_period_s, early_arrival_s, increasing_or_why, lost_data_waits,
                                  restamp_from_index, restamp_segments)
from magyro.front.signals import field_turning_findings, saturation, spikes
from magyro.session import Session


MIN_SAMPLES = 10                  # per sensor, to check anything at all
BURST_SHORT_PERIODS = 0.5         # bursts: intervals this far below the mean period (0.25 missed a 115200-baud
                                  #   link's 4 ms lines at 99 Hz, 0.4 period: 1366 'gaps' instead) ...
BURST_MIN_SHORT_FRACTION = 0.3    # ... make up this share of all intervals ...
BURST_MIN_LONG = 3
JITTER_WARN_FRACTION = 0.25       # robust std of the intervals over this share of the period
HELD_MIN_ROWS, HELD_MIN_FRACTION, HELD_WARN_FRACTION = 10, 0.02, 0.5


@dataclass
class Evidence:
    """What the detectors found, by sample index, for the repairs (magyro.front.repairs)."""

    restamped: dict = field(default_factory=dict)   # sensor -> index-fitted times (bursty clocks that can be trusted)
    held: dict = field(default_factory=dict)        # sensor -> bool mask of rows repeating the previous row
    saturated: np.ndarray | None = None             # gyro rows with an axis at a saturation plateau
    spikes: np.ndarray | None = None                # magnetometer rows that are spikes
    mag_saturated: np.ndarray | None = None         # magnetometer rows with an axis pinned at its range
    anomaly: np.ndarray | None = None               # magnetometer rows in a field anomaly
    acc_saturated: np.ndarray | None = None         # accelerometer rows on a saturation plateau; None: none


def check_recording(session: Session) -> RecordingCheck:
    """Every check of this module on `session` (not modified)."""
    return inspect(session)[0]


def inspect(session: Session) -> tuple[RecordingCheck, Evidence]:
    """The check and the evidence behind it (which rows are held, saturated, spikes; restamped clocks)."""
    evidence, findings, stats = Evidence(), [], {}
    series = {"gyro": (session.t_gyro_s, session.gyro_rad_s), "magnetometer": (session.t_mag_s, session.mag)}
    few = {sensor: len(t) for sensor, (t, _) in series.items() if len(t) < MIN_SAMPLES}
    if few:
        return too_few(session, few), Evidence(held={s: np.zeros(len(t), dtype=bool) for s, (t, _) in series.items()},
                                               saturated=np.zeros(len(session.t_gyro_s), dtype=bool),
                                               spikes=np.zeros(len(session.t_mag_s), dtype=bool),
                                               mag_saturated=np.zeros(len(session.t_mag_s), dtype=bool),
                                               anomaly=np.zeros(len(session.t_mag_s), dtype=bool))
    for sensor, (t, x) in series.items():
        stat, found, restamped, held = sensor_clock_and_rows(sensor, t, x)
        stats[sensor] = stat
        findings += found
        evidence.held[sensor] = held
        if restamped is not None:
            evidence.restamped[sensor] = restamped
    findings += time_unit_findings(stats)
    evidence.saturated, found = saturation(session.t_gyro_s, session.gyro_rad_s)
    findings += found
    held_m = evidence.held["magnetometer"]   # mostly repeats: compare the fresh readings only
    evidence.spikes, found = spikes(session.t_mag_s, session.mag, session.mag_unit,
                                    held_m if held_m.mean() >= HELD_WARN_FRACTION else None)
    findings += found
    findings += magnetometer_findings(session, evidence, any(f.kind == "time_unit" for f in findings))
    findings += overlap_findings(stats)
    evidence.acc_saturated, found = accelerometer_checks.accelerometer_findings(session)
    findings += found
    t_g = evidence.restamped.get("gyro", session.t_gyro_s)
    t_m = evidence.restamped.get("magnetometer", session.t_mag_s)
    keep_m = ~evidence.held["magnetometer"] & ~evidence.spikes & ~evidence.mag_saturated & ~evidence.anomaly
    lag = ()
    if not any(f.kind == "time_unit" for f in findings):   # rates and lags mean nothing in the wrong unit
        found, lag = field_turning_findings(t_g, session.gyro_rad_s, t_m[keep_m], session.mag[keep_m])
        findings += found
    holes = gaps_of(t_g, stats["gyro"].period_s)
    order = {s: i for i, s in enumerate(reversed(SEVERITIES))}
    findings.sort(key=lambda f: order[f.severity])
    lag_s, lag_at_s = lag if lag else ((), ())
    return RecordingCheck(tuple(findings), stats, tuple(holes), lag_s, source=session.source,
                          lag_at_s=lag_at_s), evidence


def magnetometer_findings(session: Session, evidence: Evidence, unit_wrong: bool = False) -> list:
    """Units, sensor faults and the field (magyro.front.field_checks), in that order; fills the evidence's
    saturated and anomalous magnetometer rows."""
    t, mag = session.t_mag_s, session.mag
    findings = field_checks.normalised_finding(t, mag)
    findings += field_checks.stuck_findings(session.t_gyro_s, session.gyro_rad_s, t, mag)
    evidence.mag_saturated, found = field_checks.saturation(t, mag, session.mag_unit)
    findings += found
    if not any(f.kind == "stuck" and f.sensor == "magnetometer" for f in findings) and not unit_wrong:
        findings += field_checks.slow_finding(t, evidence.held["magnetometer"])
    evidence.anomaly = np.zeros(len(t), dtype=bool)
    if any(f.severity == "error" for f in findings):
        return findings
    keep = ~evidence.held["magnetometer"] & ~evidence.spikes & ~evidence.mag_saturated
    evidence.anomaly, found, fitted = field_checks.anomalies(t, mag, keep, session.mag_unit)
    return findings + found + ([] if fitted else field_checks.cloud_fault(session, keep))


def too_few(session: Session, few: dict) -> RecordingCheck:
    text = ", ".join(f"{n} {sensor} samples" for sensor, n in few.items())
    finding = Finding("samples", "both", f"only {text}: too few to check or calibrate (need {MIN_SAMPLES})", (),
                      "error", "nothing can be estimated from so few samples", "record a longer session",
                      numbers=dict(few))
    return RecordingCheck((finding,), {}, source=session.source)


# --------------------------------------------------------------------------- clocks


def sensor_clock_and_rows(sensor: str, t: np.ndarray, x: np.ndarray):
    """(SensorStats, findings, index-fitted times when bursty else None, held-row mask) of one sensor."""
    n, dt = len(t), np.diff(t)
    span = float(t[-1] - t[0])
    mean_period = span / (n - 1)
    median = float(np.median(dt))
    short, long = dt < BURST_SHORT_PERIODS * mean_period, dt > BURST_LONG_PERIODS * mean_period
    bursty = bool(short.mean() >= BURST_MIN_SHORT_FRACTION and long.sum() >= BURST_MIN_LONG)
    findings, restamped = [], None
    if bursty:
        jitter = float("nan")
        ends = ~short   # a burst ends at any interval that is not short: bursts of 2 wait under 3 periods
        waits = np.flatnonzero(dt > GAP_PERIODS * np.median(dt[ends]))   # data lost between bursts, or a stall
        period = clock_period_s(t, waits)
        gaps = lost_data_waits(t, ends, waits, period)
        stalls = np.setdiff1d(waits, gaps)
        restamped, earliest, period, wander, early = restamp_segments(t, ends, gaps, period)
        restamped, not_applied = increasing_or_why(t, restamped)
        findings.append(bursts_finding(sensor, t, dt, short, ends, earliest, period, wander, stalls, not_applied,
                                       early))
        if findings[-1].severity == "error":   # no restamp to trust: none applied (was: "ERROR bursts [repaired]")
            restamped = None
        if len(gaps):
            findings.append(gaps_finding(sensor, t, gaps, period))
    else:
        ordinary = dt[dt <= BURST_LONG_PERIODS * median]
        period = float(ordinary.mean()) if len(ordinary) else mean_period
        jitter = float(1.4826 * np.median(np.abs(dt - median)))
        gaps = np.flatnonzero(dt > GAP_PERIODS * period)
        if len(gaps):
            findings.append(gaps_finding(sensor, t, gaps, period))
        if jitter > JITTER_WARN_FRACTION * period:
            findings.append(Finding(
                "jitter", sensor, f"the {sensor} stamps jitter by {jitter * 1e3:.2f} ms (robust std), "
                f"{100 * jitter / period:.0f} % of the {period * 1e3:.2f} ms period", ((t[0], t[-1]),), "info",
                "the solve takes every stamp as exact: stamps made on the host, not by the sensor, put an "
                "attitude error of rate x jitter on each sample", "stamp the samples on the sensor or the "
                "microcontroller if you can", numbers={"jitter_s": jitter, "period_s": period}))
    held = np.zeros(n, dtype=bool)
    held[1:] = np.all(x[1:] == x[:-1], axis=1)
    n_held = int(held.sum())
    if n_held >= HELD_MIN_ROWS and n_held >= HELD_MIN_FRACTION * n:
        findings.append(held_finding(sensor, t, held, span, period))
    stat = SensorStats(sensor, n, float(t[0]), float(t[-1]), (n - 1) / span if span > 0 else float("nan"),
                       period, median, jitter, float(dt.max()), bursty, len(gaps),
                       float(np.sum(dt[gaps])), n_held / n, (n - n_held - 1) / span if span > 0 else float("nan"))
    return stat, findings, restamped, held


def stalls_text(t, dt, stalls) -> str:
    """The long waits after which no sample was missing, in words ("" when none)."""
    if not len(stalls):
        return ""
    shown = ", ".join(f"{t[j]:.3f}-{t[j + 1]:.3f} s" for j in stalls[:3]) + (" ..." if len(stalls) > 3 else "")
    return (f"; {len(stalls)} stall(s) of the link (longest {dt[stalls].max() * 1e3:.0f} ms: {shown}) lost no "
            "sample: their samples came in the next bursts, and the restamp runs through them")


def bursts_finding(sensor, t, dt, short, long, earliest, period, wander=0.0, stalls=(), not_applied="",
                   early=0.0) -> Finding:
    wait = float(np.median(dt[long]))
    drift = float(np.quantile(earliest, 0.9) - np.quantile(earliest, RESTAMP_QUANTILE))
    lost = max(drift, early) > RESTAMP_TRUST_PERIODS * period   # early: a clock that jumps (`early_arrival_s`)
    refused = lost or bool(not_applied)
    return Finding(
        "bursts", sensor,
        f"the {sensor} stamps come in bursts: {100 * short.mean():.0f} % of the intervals are under "
        f"{BURST_SHORT_PERIODS:g} period (median {np.median(dt[short]) * 1e3:.2f} ms against a mean period of "
        f"{period * 1e3:.2f} ms), then {int(long.sum())} waits of {wait * 1e3:.0f} ms: these are arrival times "
        f"of buffered data, not sample times" + (
            f"; their earliest arrivals wander by {wander * 1e3:.0f} ms off one line (the sensor's and the host's "
            f"clocks drift), so the restamp follows them {RESTAMP_WINDOW_S:g} s at a time" if wander and not lost
            else "") + (
            f"; even followed window by window ({RESTAMP_WINDOW_S:g} s), the earliest arrival per burst wanders by "
            f"{drift * 1e3:.0f} ms" + (f" and one comes {early * 1e3:.0f} ms before the clock so fitted (taken "
                                       "after it arrived)" if early > RESTAMP_TRUST_PERIODS * period else "") +
            f": the {sensor}'s clock cannot be rebuilt from its sample index (samples missing, "
            "or a clock that jumps), so no restamp can be trusted" if lost else "") + stalls_text(t, dt, stalls) + (
            f"; the restamp cannot be applied: {not_applied}" if not_applied and not lost else ""),
        ((t[0], t[-1]),), "error" if refused else "warning",
        f"each sample is stamped up to {wait * 1e3:.0f} ms late, by a varying amount: the gyro and the "
        "magnetometer no longer line up (host-stamped bursts gave a bias 0.4-0.6 deg/s off, 20-30 sigma, "
        "with exit 0)",
        **({"fix": "stamp the samples on the sensor or the microcontroller, or log the sensor's own sample counter"}
           if refused else repairable("restamp", "magyro restamps the sensor from its sample index (t = a(k) + b k: b "
                                   "fitted, a from the earliest arrivals, following drifting clocks)",
                                   "the arrival stamps", "better: stamp on the sensor side")),
        numbers={"short_fraction": float(short.mean()), "wait_s": wait, "period_s": float(period),
                 "earliest_arrival_spread_s": drift, "earliest_arrival_early_s": early,
                 "wander_off_one_line_s": wander, "stalls": len(stalls),
                 "restamp_applicable": not refused})


def gaps_of(t: np.ndarray, period: float, minimum_periods: float = GAP_PERIODS) -> list:
    """(t_before, t_after) of every interval over `minimum_periods` periods."""
    i = np.flatnonzero(np.diff(t) > minimum_periods * period)
    return [(float(t[j]), float(t[j + 1])) for j in i]


def gaps_finding(sensor, t, gaps, period) -> Finding:
    where = tuple((float(t[j]), float(t[j + 1])) for j in gaps)
    total = sum(b - a for a, b in where)
    longest = max(where, key=lambda w: w[1] - w[0])
    shown = ", ".join(f"{a:.3f}-{b:.3f} s" for a, b in where[:5]) + (" ..." if len(where) > 5 else "")
    gyro = sensor == "gyro"
    return Finding(
        "gaps", sensor, f"{len(where)} gap(s) in the {sensor} data, {total:.3f} s in all (longest "
        f"{longest[1] - longest[0]:.3f} s, over {GAP_PERIODS:g} periods of {period * 1e3:.2f} ms): {shown}",
        where, "warning" if gyro else "info",
        "integrating the gyro across a hole turns the attitude by a guess: a 30 s hole gave K_g 0.5 off "
        "with exit 0" if gyro else "the solve cuts magnetometer gaps into segments without residuals",
        "the gyro holes are reported (gyro_holes_s) and never integrated across: each starts a new attitude "
        "segment" if gyro else "nothing to do; if the logger drops data, log less or faster",
        numbers={"count": len(where), "seconds": total, "longest_s": longest[1] - longest[0]})


def held_finding(sensor, t, held, span, row_period) -> Finding:
    n, n_held = len(held), int(held.sum())
    starts = np.flatnonzero(~held)
    runs = np.diff(np.append(starts, n))
    distinct_hz = (len(starts) - 1) / span if span > 0 else float("nan")
    fraction = n_held / n
    longest = int(runs.max())
    return Finding(
        "held", sensor, f"{100 * fraction:.1f} % of the {sensor} rows repeat the previous row exactly (runs up "
        f"to {longest} rows, {longest * row_period * 1e3:.1f} ms): the sensor delivers new values at about "
        f"{distinct_hz:.1f} Hz and the logger repeats the last one at {(n - 1) / span:.1f} Hz",
        ((float(t[0]), float(t[-1])),), "warning" if fraction >= HELD_WARN_FRACTION else "info",
        f"every repeated row counts as a new measurement ({n / len(starts):.2f}x the weight a sample "
        f"deserves) and is stale by up to {(longest - 1) * row_period * 1e3:.1f} ms",
        **repairable("held", "magyro keeps the first row of each run", "the repeated rows"),
        numbers={"fraction": fraction, "held_rows": n_held, "distinct_rate_hz": distinct_hz,
                 "longest_run": longest})


def time_unit_findings(stats: dict) -> list:
    """Stamps that are not seconds, named by the loader's own rule (`magyro.io.checks.time_unit_message`)."""
    from magyro.io.checks import MAX_PLAUSIBLE_STEP_S, MIN_PLAUSIBLE_STEP_S, time_unit_message

    step_s = stats["gyro"].median_interval_s
    if MIN_PLAUSIBLE_STEP_S <= step_s <= MAX_PLAUSIBLE_STEP_S:
        return []
    where = ((min(s.start_s for s in stats.values()), max(s.end_s for s in stats.values())),)
    return [Finding("time_unit", "both", time_unit_message(step_s), where, "error",
                    "every rate, lag and integral would be off by the same factor: the calibration cannot work",
                    "", numbers={"median_step_s": step_s})]


def overlap_findings(stats: dict) -> list:
    """The two sensors' spans: no common time (error), one clock stretched (both start together, one
    ends over 1 % of the span later), or only a partly common span."""
    g, m = stats["gyro"], stats["magnetometer"]
    overlap = min(g.end_s, m.end_s) - max(g.start_s, m.start_s)
    union = max(g.end_s, m.end_s) - min(g.start_s, m.start_s)
    share = max(overlap, 0.0) / union if union > 0 else 0.0
    starts, ends = m.start_s - g.start_s, m.end_s - g.end_s
    numbers = {"overlap_fraction": share, "start_offset_s": starts, "end_offset_s": ends}
    where = ((min(g.start_s, m.start_s), max(g.end_s, m.end_s)),)
    text = (f"the gyro spans {g.start_s:.3f}-{g.end_s:.3f} s and the magnetometer {m.start_s:.3f}-{m.end_s:.3f} s "
            f"(overlap {100 * share:.1f} %)")
    together = abs(starts) <= max(GAP_PERIODS * max(g.period_s, m.period_s), 0.002 * union)
    if share < 0.5:
        return [Finding("overlap", "both", text + ": their clocks do not share a zero (or a unit)", where, "error",
                        "without common time the gyro cannot be compared with the magnetometer",
                        "stamp both sensors on one clock, in seconds", numbers=numbers)]
    if together and abs(ends) > 0.01 * union:
        stretch = (m.end_s - m.start_s) / (g.end_s - g.start_s) - 1
        return [Finding("clock_drift", "both", text + f": they start together but the magnetometer's span is "
                        f"{100 * stretch:+.2f} % of the gyro's, as when one sensor is stamped at a nominal rate "
                        "that is not its real one (or one stopped early)", where, "warning",
                        f"a {100 * abs(stretch):.1f} % clock error slides the sensors {abs(ends):.2f} s apart by the "
                        "end; the solve fits one constant lag",
                        **repairable("clocks", "magyro rescales the magnetometer's times to the gyro's span",
                                     "the magnetometer's times", "better: stamp both sensors on one clock (or cut "
                                     "the session to the common span if one stopped early)"),
                        numbers={**numbers, "stretch": stretch})]
    if share < 0.95:
        return [Finding("overlap", "both", text + "; only the common span can be calibrated", where, "info",
                        "the samples outside the common span carry no information for the calibration", "none needed",
                        numbers=numbers)]
    return []


# --------------------------------------------------------------------------- values


# --------------------------------------------------------------------------- the field's turning


