"""Restamping a logger's bursts (`magyro.front.recording`'s `bursts` finding): host stamps of buffered data turned
back into the sensor's own clock, t_k = a(k) + b k from the sample index, through stalls (a long wait that lost
nothing) and drifting board clocks (window by window), or the reason no restamp can be trusted."""
from __future__ import annotations

import numpy as np

BURST_LONG_PERIODS = 3.0          # the waits between bursts are longer than this (`magyro.front.recording`'s too)
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
