"""The rests at both ends of a session: found, trimmed, and used for noise levels and a bias check.

A recording starts and ends with the device lying still (the paper's, and
BROAD's, do). The first and last `WINDOW_S` tell what still looks like on
this sensor: their mean and std. The rest lasts while the smoothed gyro and
magnetometer stay within `STILL_IN_NOISE_STD` smoothed-noise stds of that
mean on every axis; a run of at least `MIN_REST_S` is a rest. No assumed
noise level enters, so filtered or quantised sensors are handled alike. The
paper excludes these rests from the calibration.

That test alone ends a long rest too soon on an autopilot on the ground (issue 38: ArduPlane's TestLog2
was found still for 2.1 s of its ~180 s before take-off). Its 50 Hz gyro has bursts of x-axis noise
(sample-to-sample swings of +-1.3 deg/s, alternating in sign: no turning, the accelerometer stays within
0.03 m/s^2), its bias creeps as it warms (0.16-0.24 deg/s over three minutes), and its 10 Hz magnetometer
has single-sample spikes of 3 uT: each crosses a band set by the first half second. So a rest that lasts
past `BLOCK_S` is also followed block by block (`block_still_prefix_s`): each second's mean must stay within
`STEP_IN_NOISE_STD` stds of the previous second's, the std of a mean taken from that second's own
sample-to-sample noise or the session's, the larger (vibration widens it, a turn does not), and within a drift cap of the first second's
(`MAX_GYRO_DRIFT_RAD_S`; `MAX_FIELD_DRIFT_FRACTION` of the field). Where that finds the rest longer than the
first test by more than a block, the first test is run again from the last still block, which places the
end to within `SMOOTH_S`; otherwise the first test's rest stands unchanged.

At rest the true rate is zero (the Earth's 0.004 deg/s is far below a MEMS
gyro's bias), so K_g y_rest + eps_b = 0 and eps_b = -K_g mean(y_rest): a
bias estimate that owes nothing to the magnetometer.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from magyro.front.differences import white_noise_std
from magyro.session import Session

WINDOW_S = 0.5
SMOOTH_S = 0.1
MIN_REST_S = 1.0
STILL_IN_NOISE_STD = 8.0
MOVING_IF_STD_OVER_WHITE = 10.0   # a first window this much noisier than white noise is already moving
BLOCK_S = 1.0                     # a long rest is followed by the means of its seconds
MIN_BLOCK_SAMPLES = 5             # fewer in a block (a hole, a slow sensor): the block-by-block test stops
STEP_IN_NOISE_STD = 8.0           # a block's mean within this many stds of the previous block's
MAX_GYRO_DRIFT_RAD_S = np.radians(0.5)   # a warming gyro's bias creeps; a turn this fast is no rest
MAX_FIELD_DRIFT_FRACTION = 0.05   # the field's mean moves less than 5 % of |field| (about 3 deg of turn)


@dataclass(frozen=True)
class Rests:
    segments_s: list[tuple[float, float]]  # (start, end) of each rest
    seconds: float
    gyro_mean_rad_s: np.ndarray | None     # mean raw gyro over all rests, None without rests
    gyro_still: np.ndarray | None = None   # the raw gyro samples at rest (for noise levels)
    mag_still: np.ndarray | None = None    # the magnetometer samples at rest

    def to_dict(self) -> dict:
        return {
            "segments_s": [list(map(float, s)) for s in self.segments_s],
            "seconds": self.seconds,
            "gyro_mean_rad_s": None if self.gyro_mean_rad_s is None else self.gyro_mean_rad_s.tolist(),
        }


def moving_average(t_s: np.ndarray, x: np.ndarray, width_s: float) -> np.ndarray:
    c = np.concatenate([np.zeros((1, x.shape[1])), np.cumsum(x, axis=0)])
    lo = np.searchsorted(t_s, t_s - width_s / 2, side="left")
    hi = np.searchsorted(t_s, t_s + width_s / 2, side="right")
    return (c[hi] - c[lo]) / np.maximum(hi - lo, 1)[:, None]


def smoothed_noise_band(t_s: np.ndarray, std: np.ndarray) -> np.ndarray:
    """STILL_IN_NOISE_STD stds of a SMOOTH_S moving average of white noise of per-sample `std` (per axis): how far
    the smoothed signal of a still sensor strays."""
    n_smooth = max(1.0, SMOOTH_S * (len(t_s) - 1) / max(t_s[-1] - t_s[0], 1e-12))
    return STILL_IN_NOISE_STD * std / np.sqrt(n_smooth)


def still_prefix_s(t_s: np.ndarray, x: np.ndarray, white_std: np.ndarray) -> float:
    """How long x stays like its first WINDOW_S (0 when it is moving from the start)."""
    first = t_s <= t_s[0] + WINDOW_S
    mean0, std0 = x[first].mean(axis=0), x[first].std(axis=0)
    if first.sum() < 5 or np.any(std0 > MOVING_IF_STD_OVER_WHITE * np.maximum(white_std, 1e-12)):
        return 0.0
    band = smoothed_noise_band(t_s, np.maximum(std0, white_std))
    away = np.any(np.abs(moving_average(t_s, x, SMOOTH_S) - mean0) > band, axis=1)
    return float((t_s[np.argmax(away)] if away.any() else t_s[-1]) - t_s[0])


def block_still_prefix_s(t_s: np.ndarray, x: np.ndarray, white_std: np.ndarray, drift_allowed) -> float:
    """How long x stays still block by block: the mean of each BLOCK_S within STEP_IN_NOISE_STD stds of the
    previous block's (each mean's std: the larger of the block's own white noise and the session's,
    `white_std`, over sqrt(samples): a few samples alone say little) and `drift_allowed(first_mean, mean)`
    of the first block's. A multiple of BLOCK_S; 0 for less than two."""
    n_blocks = int((t_s[-1] - t_s[0]) // BLOCK_S)
    edges = np.searchsorted(t_s, t_s[0] + BLOCK_S * np.arange(n_blocks + 1))
    previous = first = None
    for k in range(n_blocks):
        block = x[edges[k]:edges[k + 1]]
        if len(block) < MIN_BLOCK_SAMPLES:
            return k * BLOCK_S
        mean = block.mean(axis=0)
        mean_std = np.maximum(white_noise_std(block), white_std) / np.sqrt(len(block))
        if previous is not None:
            step_std = np.sqrt(mean_std**2 + previous[1]**2)
            if np.any(np.abs(mean - previous[0]) > STEP_IN_NOISE_STD * step_std) or not drift_allowed(first, mean):
                return k * BLOCK_S
        else:
            first = mean
        previous = (mean, mean_std)
    return n_blocks * BLOCK_S


def gyro_drift_allowed(first: np.ndarray, mean: np.ndarray) -> bool:
    return bool(np.all(np.abs(mean - first) <= MAX_GYRO_DRIFT_RAD_S))


def field_drift_allowed(first: np.ndarray, mean: np.ndarray) -> bool:
    return bool(np.linalg.norm(mean - first) <= MAX_FIELD_DRIFT_FRACTION * np.linalg.norm(first))


def rest_prefix_s(t_s: np.ndarray, x: np.ndarray, white_std: np.ndarray, drift_allowed) -> float:
    """`still_prefix_s`, unless the block-by-block test finds the rest longer by more than a block: then the
    first test again from the last still block (see the module docstring)."""
    fine = still_prefix_s(t_s, x, white_std)
    if fine <= 0.0:
        return fine
    coarse = block_still_prefix_s(t_s, x, white_std, drift_allowed)
    if coarse <= fine + BLOCK_S:
        return fine
    i = int(np.searchsorted(t_s, t_s[0] + coarse - BLOCK_S))
    return float(t_s[i] - t_s[0]) + still_prefix_s(t_s[i:], x[i:], white_std)


def end_rest_lengths(session: Session, gyro_white: np.ndarray, mag_white: np.ndarray, reverse: bool) -> float:
    def flip(t, x):
        return (t[-1] - t[::-1], x[::-1]) if reverse else (t, x)

    g = rest_prefix_s(*flip(session.t_gyro_s, session.gyro_rad_s), gyro_white, gyro_drift_allowed)
    m = rest_prefix_s(*flip(session.t_mag_s, session.mag), mag_white, field_drift_allowed)
    return min(g, m)


def find_rests(session: Session) -> Rests:
    """The rests at the start and at the end of the session."""
    gw, mw = white_noise_std(session.gyro_rad_s), white_noise_std(session.mag)
    t_first = max(session.t_gyro_s[0], session.t_mag_s[0])
    t_last = min(session.t_gyro_s[-1], session.t_mag_s[-1])
    head = end_rest_lengths(session, gw, mw, reverse=False)
    tail = end_rest_lengths(session, gw, mw, reverse=True)
    segments = []
    if head >= MIN_REST_S:
        segments.append((float(t_first), float(t_first + head)))
    if tail >= MIN_REST_S and t_last - tail > t_first + head:
        segments.append((float(t_last - tail), float(t_last)))
    return rests_from_segments(session, segments)


def rests_from_segments(session: Session, segments) -> Rests:
    def inside(t):
        m = np.zeros(len(t), dtype=bool)
        for a, b in segments:
            m |= (t >= a) & (t <= b)
        return m

    g, m = inside(session.t_gyro_s), inside(session.t_mag_s)
    if not g.any():
        return Rests([], 0.0, None)
    return Rests(list(segments), float(sum(b - a for a, b in segments)), session.gyro_rad_s[g].mean(axis=0),
                 session.gyro_rad_s[g], session.mag[m])


def moving_span(session: Session, rests: Rests) -> tuple[float, float]:
    """Session time without the rests at the very start and the very end."""
    t0 = min(session.t_gyro_s[0], session.t_mag_s[0])
    t1 = max(session.t_gyro_s[-1], session.t_mag_s[-1])
    start, end = t0, t1
    margin = SMOOTH_S
    for a, b in rests.segments_s:
        if a <= session.t_gyro_s[0] + margin:
            start = max(start, b - margin)
        if b >= session.t_gyro_s[-1] - margin:
            end = min(end, a + margin)
    return start, end
