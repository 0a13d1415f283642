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
from magyro.front.signals import field_turning_findings, saturation, spikes
from magyro.session import Session


MIN_SAMPLES = 10                  # per sensor, to check anything at all
BURST_SHORT_PERIODS = 0.5         # bursts: intervals this far below the mean period (0.25 missed a 115200-baud
                                  #   link's 4 ms lines at 99 Hz, 0.4 period: 1366 'gaps' instead) ...
BURST_MIN_SHORT_FRACTION = 0.3    # ... make up this share of all intervals ...
BURST_LONG_PERIODS = 3.0          # ... and the waits between bursts are longer than this
BURST_MIN_LONG = 3
RESTAMP_QUANTILE = 0.1            # of the per-burst earliest arrivals: buffered samples arrive late, never early
RESTAMP_WANDER_PERIODS = 1.0      # earliest arrivals wandering more than this off one line (or RESTAMP_WANDER_S):
RESTAMP_WANDER_S = 0.005          #   drifting clocks ...
RESTAMP_WINDOW_S = 3.0            # ... followed window by window (5 s windows left a 68 ms wander 1 ms RMS off)
RESTAMP_PASSES = 2
RESTAMP_DRIFT_QUANTILE = 0.1      # within a window, once its slope is taken out: a low quantile (never early;
                                  #   robust to a short burst, whose last line comes sooner after its sample)
RESTAMP_SLOPE_POINTS = 200        # a window's slope: the median pairwise slope of at most this many bursts
RESTAMP_TRUST_PERIODS = 3.0       # still wandering this much after that: no restamp can be trusted (exit 2)
RESTAMP_MIN_BURSTS = 3            # a stretch with fewer bursts takes the period of the longest stretch, not its own
RESTAMP_LOST_PERIODS = 2.0        # a long wait after which the earliest arrivals (against the index) are this much
RESTAMP_NEIGHBOUR_BURSTS = 25     #   later than over this many bursts before it lost samples; otherwise it is a stall
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


def restamp_from_index(t: np.ndarray, long: np.ndarray | None = None,
                       period_s: float | None = None) -> tuple[np.ndarray, np.ndarray, float, float]:
    """(t_k = a(k) + b k, each burst's earliest arrival after that clock, b, how far the earliest arrivals wander
    off one line (s; 0 when they do not and a is one number)): b the least-squares slope of the
    stamps against the sample index; a from a low quantile of each burst's earliest arrival (buffered samples
    arrive late, never early). When the two clocks drift (the earliest arrivals wander along the line by more
    than RESTAMP_WANDER_PERIODS periods), a(k) follows them window by window (`drifting_offset`). `long` marks the
    intervals that end a burst (default: > 3 mean periods); `period_s`, when given, is b (a stretch too short to
    carry its own period: one burst's slope is its 2 ms spacing)."""
    n = len(t)
    if n < 3:
        return t.copy(), np.zeros(1), float(t[-1] - t[0]) if n == 2 else float("nan"), 0.0
    k = np.arange(n, dtype=float) - (n - 1) / 2
    t_mean = float(np.mean(t))
    b = index_slope_s(t) if period_s is None else float(period_s)
    line = t_mean + b * k
    residual = t - line
    if long is None:
        long = np.diff(t) > BURST_LONG_PERIODS * b
    starts = np.flatnonzero(np.concatenate([[True], long]))
    earliest = np.minimum.reduceat(residual, starts)
    a = float(np.quantile(earliest, RESTAMP_QUANTILE))
    wander = float(np.quantile(earliest, 0.9) - a)
    if wander <= max(RESTAMP_WANDER_PERIODS * b, RESTAMP_WANDER_S):
        return line + a, earliest - a, b, 0.0
    offset = np.zeros(n)
    first = earliest
    for _ in range(RESTAMP_PASSES):   # each pass flattens what the last left: a window's low quantile is then unbiased
        offset += drifting_offset(t[starts], first, k[starts], k)
        first = earliest - offset[starts]
    return line + offset, first, b, wander


def drifting_offset(t_start: np.ndarray, earliest: np.ndarray, k_start: np.ndarray, k: np.ndarray) -> np.ndarray:
    """The offset a(k) under the earliest arrivals, window by window (RESTAMP_WINDOW_S): in each, the arrivals less
    their own line against k, their RESTAMP_DRIFT_QUANTILE put back on that line at the window's middle; joined by
    straight lines, continued beyond the first and the last window with their own slopes. Before (issue 38), the
    lowest arrival of 5 s windows taken as is: it sat a slope x half a window low where the clock turned, one short
    last burst (its line comes sooner after its sample) pulled a window 4-6 ms down, and the slope between the
    last two windows lagged a turning clock; on a board wandering 68 ms (magyro.studies.logger_stamps) the times
    came out 4-7 ms off at the end and the gyro bias 5 std. A last window under half as long joins the one before."""
    window = np.floor((t_start - t_start[0]) / RESTAMP_WINDOW_S).astype(int)
    if t_start[-1] - t_start[0] - window[-1] * RESTAMP_WINDOW_S < RESTAMP_WINDOW_S / 2:
        window = np.minimum(window, max(window[-1] - 1, 0))   # a short last window joins the one before it
    anchors_k, anchors_a, slopes = [], [], []
    for w in np.unique(window):
        inside = window == w
        if inside.sum() >= 3:
            middle = float(np.median(k_start[inside]))
            slope = slope_within(k_start, earliest, inside)
            line = earliest[inside] - slope * (k_start[inside] - middle)
            anchors_k.append(middle)
            anchors_a.append(float(np.quantile(line, RESTAMP_DRIFT_QUANTILE)))
            slopes.append(slope)
    if len(anchors_k) < 2:
        return np.full(len(k), float(np.quantile(earliest, RESTAMP_QUANTILE)))
    anchors_a = [anchors_a[0] + slopes[0] * (k[0] - anchors_k[0])] + anchors_a + \
                [anchors_a[-1] + slopes[-1] * (k[-1] - anchors_k[-1])]
    return np.interp(k, [k[0]] + anchors_k + [k[-1]], anchors_a)


def slope_within(k: np.ndarray, y: np.ndarray, inside: np.ndarray) -> float:
    """The slope of y against k over the rows `inside`, robustly: the median of the slopes between every two of
    them (Theil-Sen; at most RESTAMP_SLOPE_POINTS rows, evenly spread; 0 with fewer than 3). A burst off the others,
    late (a stale one) or early (a partial last burst: fewer lines, its last one comes sooner after its sample),
    tipped a least-squares slope, and the line continued from the last window put the last second 8-70 ms off."""
    kk, yy = k[inside], y[inside]
    if len(kk) < 3:
        return 0.0
    if len(kk) > RESTAMP_SLOPE_POINTS:
        pick = np.linspace(0, len(kk) - 1, RESTAMP_SLOPE_POINTS).round().astype(int)
        kk, yy = kk[pick], yy[pick]
    i, j = np.triu_indices(len(kk), 1)
    return float(np.median((yy[j] - yy[i]) / (kk[j] - kk[i])))


def index_slope_s(t: np.ndarray) -> float:
    """The least-squares slope of the stamps `t` against their index (s per sample)."""
    k = np.arange(len(t), dtype=float) - (len(t) - 1) / 2
    return float(np.dot(k, t - float(np.mean(t))) / np.dot(k, k))


def clock_period_s(t: np.ndarray, waits: np.ndarray) -> float:
    """The sample period of a bursty clock: `index_slope_s` of the longest stretch between the long `waits`."""
    bounds = np.concatenate([[0], waits + 1, [len(t)]])
    a, b = max(zip(bounds[:-1], bounds[1:]), key=lambda ab: ab[1] - ab[0])
    return index_slope_s(t[a:b]) if b - a >= 3 else float(t[-1] - t[0]) / max(len(t) - 1, 1)


def burst_earliest(t: np.ndarray, long: np.ndarray, period_s: float) -> tuple[np.ndarray, np.ndarray]:
    """(first index of each burst, its earliest arrival against the index line t = period_s k, s)."""
    starts = np.flatnonzero(np.concatenate([[True], long]))
    return starts, np.minimum.reduceat(t - period_s * np.arange(len(t)), starts)


def lost_data_waits(t: np.ndarray, long: np.ndarray, waits: np.ndarray, period_s: float) -> np.ndarray:
    """The long `waits` (interval indices) after which samples are missing. Samples never arrive early, so the
    earliest arrivals against the index trace the sensor's clock: after lost samples they are later by the time
    lost, and stay so; after a stall (the host or the link paused, the sensor went on sampling into its buffer)
    the samples of the wait come in the next bursts and the earliest arrivals go on as before. A wait is data
    lost when the earliest arrivals of the RESTAMP_NEIGHBOUR_BURSTS bursts after it are over RESTAMP_LOST_PERIODS
    periods later than those of the bursts before it (back to the last wait)."""
    if not len(waits):
        return waits
    starts, earliest = burst_earliest(t, long, period_s)
    after = np.searchsorted(starts, waits + 1)          # the burst that each wait ends
    lost = []
    for i, j in enumerate(after):
        first = max(j - RESTAMP_NEIGHBOUR_BURSTS, after[i - 1] if i else 0)
        last = min(j + RESTAMP_NEIGHBOUR_BURSTS, after[i + 1] if i + 1 < len(after) else len(starts))
        if earliest[j:last].min() - earliest[first:j].min() > RESTAMP_LOST_PERIODS * period_s:
            lost.append(waits[i])
    return np.asarray(lost, dtype=int)


def increasing_or_why(t: np.ndarray, restamped: np.ndarray) -> tuple[np.ndarray | None, str]:
    """(the restamped times, "") when they increase step by step, else (None, why they cannot be used)."""
    step = np.diff(restamped)
    if np.all(step > 0):
        return restamped, ""
    i = int(np.argmin(step))
    return None, (f"the index-fitted times do not increase: from the sample stamped {t[i]:.3f} s to the next they "
                  f"step {step[i] * 1e3:+.2f} ms (the clocks fitted on either side of a gap overlap)")


def restamp_segments(t: np.ndarray, long: np.ndarray, gaps: np.ndarray,
                     period_s: float | None = None) -> tuple[np.ndarray, np.ndarray, float, float, float]:
    """`restamp_from_index` on each stretch between gaps (the index says nothing across lost data):
    (times, earliest arrivals, the period of the longest stretch, the largest wander off one line, the most any
    burst but a stretch's first and last arrives before its fitted clock: `early_arrival_s`). A stretch of fewer
    than RESTAMP_MIN_BURSTS bursts (a stale burst between two gaps) takes `period_s`."""
    bounds = np.concatenate([[0], gaps + 1, [len(t)]])
    times, earliest, periods, wander, early = [], [], [], 0.0, 0.0
    for a, b in zip(bounds[:-1], bounds[1:]):
        short = period_s is not None and np.sum(long[a:b - 1]) + 1 < RESTAMP_MIN_BURSTS
        fitted, first, period, off_line = restamp_from_index(t[a:b], long[a:b - 1], period_s if short else None)
        times.append(fitted)
        earliest.append(first)
        periods.append((b - a, period))
        wander = max(wander, off_line)
        early = max(early, early_arrival_s(first))
    return np.concatenate(times), np.concatenate(earliest), float(max(periods)[1]), wander, early


def early_arrival_s(earliest: np.ndarray) -> float:
    """How far the earliest arrival of any burst but the first and the last comes before the low quantile of them
    all (0 with fewer than 3 bursts). A clock that jumps does it: one window follows the jump and the bursts
    beside it come 95 ms early (19 periods); legitimate bursts 0.4 period at most. The first and the last burst
    are left out: a partial one (fewer lines on the link) comes up to (lines missing) x (line spacing) sooner."""
    if len(earliest) < 3:
        return 0.0
    return max(float(np.quantile(earliest, RESTAMP_QUANTILE) - np.min(earliest[1:-1])), 0.0)


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


