"""Still segments of a session: found, trimmed from the ends, and used as an independent bias check.

A sample is still when, over a window around it, both the gyro and the
magnetometer vary no more than their noise (rolling std below
`STILL_IN_NOISE_STD` times the white-noise std on every axis). Still runs
of at least `MIN_REST_S` are rests. The paper excludes the rests at both
ends from the calibration; a rest in the middle costs nothing and stays.

At rest the true rate is zero (the Earth's 0.004 deg/s is far below a MEMS
gyro's bias), so K_g y_rest + eps_b = 0 and eps_b = -K_g mean(y_rest): a
bias estimate that owes nothing to the magnetometer.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .session import Session

WINDOW_S = 0.5
MIN_REST_S = 1.0
STILL_IN_NOISE_STD = 3.0


@dataclass(frozen=True)
class Rests:
    segments_s: list[tuple[float, float]]  # (start, end) of each rest
    seconds: float
    gyro_mean_rad_s: np.ndarray | None     # mean raw gyro over all rests, None without rests

    def to_dict(self) -> dict:
        return {
            "segments_s": [list(map(float, s)) for s in self.segments_s],
            "seconds": self.seconds,
            "gyro_mean_rad_s": None if self.gyro_mean_rad_s is None else self.gyro_mean_rad_s.tolist(),
        }


def rolling_std(t_s: np.ndarray, x: np.ndarray, window_s: float) -> np.ndarray:
    """Std of each column of x over a centred window of `window_s` (cumulative sums, any sampling)."""
    c1 = np.concatenate([np.zeros((1, x.shape[1])), np.cumsum(x, axis=0)])
    c2 = np.concatenate([np.zeros((1, x.shape[1])), np.cumsum(x * x, axis=0)])
    lo = np.searchsorted(t_s, t_s - window_s / 2, side="left")
    hi = np.searchsorted(t_s, t_s + window_s / 2, side="right")
    n = np.maximum(hi - lo, 1)[:, None]
    mean = (c1[hi] - c1[lo]) / n
    return np.sqrt(np.maximum((c2[hi] - c2[lo]) / n - mean**2, 0.0))


def still_runs(t_s: np.ndarray, still: np.ndarray, min_s: float) -> list[tuple[float, float]]:
    edges = np.diff(np.concatenate([[0], still.astype(int), [0]]))
    starts, ends = np.flatnonzero(edges == 1), np.flatnonzero(edges == -1) - 1
    return [(float(t_s[a]), float(t_s[b])) for a, b in zip(starts, ends) if t_s[b] - t_s[a] >= min_s]


def find_rests(session: Session, gyro_std_rad_s: float, mag_std: float) -> Rests:
    """Rests of the session, on the gyro time base."""
    t = session.t_gyro_s
    gyro_still = np.all(rolling_std(t, session.gyro_rad_s, WINDOW_S) < STILL_IN_NOISE_STD * gyro_std_rad_s, axis=1)
    mag_still_m = np.all(rolling_std(session.t_mag_s, session.mag, WINDOW_S) < STILL_IN_NOISE_STD * mag_std, axis=1)
    mag_still = np.interp(t, session.t_mag_s, mag_still_m.astype(float)) > 0.99
    segments = still_runs(t, gyro_still & mag_still, MIN_REST_S)
    inside = np.zeros(len(t), dtype=bool)
    for a, b in segments:
        inside |= (t >= a) & (t <= b)
    mean = session.gyro_rad_s[inside].mean(axis=0) if inside.any() else None
    return Rests(segments, float(sum(b - a for a, b in segments)), mean)


def moving_span(session: Session, rests: Rests) -> tuple[float, float]:
    """Session time without the rests at the very start and the very end."""
    t0 = min(session.t_gyro_s[0], session.t_mag_s[0])
    t1 = max(session.t_gyro_s[-1], session.t_mag_s[-1])
    start, end = t0, t1
    margin = 0.5 * WINDOW_S
    for a, b in rests.segments_s:
        if a <= session.t_gyro_s[0] + margin:
            start = max(start, b - margin)
        if b >= session.t_gyro_s[-1] - margin:
            end = min(end, a + margin)
    return start, end


def trimmed(session: Session, t0_s: float, t1_s: float) -> Session:
    """The session restricted to [t0_s, t1_s] (gyro and magnetometer)."""
    from dataclasses import replace

    g = (session.t_gyro_s >= t0_s) & (session.t_gyro_s <= t1_s)
    m = (session.t_mag_s >= t0_s) & (session.t_mag_s <= t1_s)
    return replace(session, t_gyro_s=session.t_gyro_s[g], gyro_rad_s=session.gyro_rad_s[g],
                   t_mag_s=session.t_mag_s[m], mag=session.mag[m])
