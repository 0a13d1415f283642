"""Every still of a recording, not only the rests at its ends (issue 39): poses held in the middle.

A pose held still in the middle of a recording says, as an end rest does, where gravity is at one attitude with no
hand in it. The static-pose method (imu_tk) is built on exactly those holds; magyro's accelerometer uses each
still as it uses an end rest (`magyro.nls.accelerometer.rests_at_nodes`: its mean against gravity at its first
node, the intervals inside it left out). The stills are not trimmed from the solve: only the end rests are.

A sample is still when, on every axis,
  * the gyro, smoothed over `SMOOTH_S`, stays within `STILL_IN_NOISE_STD` stds of that smoothed noise (the
    gyro's white noise, measured as the end rests judge it) plus `BIAS_ALLOWANCE_RAD_S` of the gyro's bias at the
    end rests (its creep as it warms; a still's mean is read at its first node's attitude, so a still must not
    turn: 0.1 deg/s over a 4 s still is 0.2 deg at most, 0.03 m/s^2 of gravity);
  * the accelerometer, when the session has one, smoothed over `SMOOTH_S`, stays within as many stds of its mean
    over `LOCAL_S` around it (a hand that sways or shakes the device is not still).
A run of still samples lasting `MIN_STILL_S`, `EDGE_S` taken off each end (the smoothing reaches that far into
the motion), outside the end rests, is a still.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from magyro.front.differences import white_noise_std
from magyro.front.rests import SMOOTH_S, Rests, moving_average, smoothed_noise_band
from magyro.session import Session

MIN_STILL_S = 2.0         # a still lasts at least this long (after its edges are taken off)
EDGE_S = SMOOTH_S         # taken off each end of a still run: the smoothing reaches this far into the motion
LOCAL_S = 1.0             # the accelerometer's smoothed value against its mean over this long
BIAS_ALLOWANCE_RAD_S = np.radians(0.1)   # the gyro's bias may creep this far from the end rests'
POSE_APART_DEG = 20.0     # two stills whose gravity directions are this far apart are distinct poses


@dataclass(frozen=True)
class Stills:
    """The stills between the end rests: their spans, their total length, how many distinct poses they and the end
    rests hold (gravity directions POSE_APART_DEG apart; None without an accelerometer)."""

    segments_s: list[tuple[float, float]]
    seconds: float
    poses: int | None

    def to_dict(self) -> dict:
        return {"count": len(self.segments_s), "segments_s": [list(map(float, s)) for s in self.segments_s],
                "seconds": float(self.seconds), "poses": self.poses, "pose_apart_deg": POSE_APART_DEG}

    @classmethod
    def from_dict(cls, data: dict) -> "Stills":
        """Read back from a calibration JSON's `stills`; InputError (exit 2) naming it when it is no such entry."""
        try:
            segments = [(float(a), float(b)) for a, b in data.get("segments_s", [])]
            poses = data.get("poses")
            if isinstance(poses, bool) or not (poses is None or isinstance(poses, int)):
                raise TypeError(poses)
            seconds = data.get("seconds", 0.0)
            if isinstance(seconds, (bool, str)):
                raise TypeError(seconds)
            return cls(segments, float(seconds), poses)
        except (TypeError, ValueError):
            from magyro.errors import InputError

            raise InputError("stills must be {count, segments_s: [[start, end], ...], seconds, poses}") from None


def gyro_still(session: Session, bias_rad_s: np.ndarray) -> np.ndarray:
    """(n_gyro,) True where the smoothed gyro is within its noise band (plus the drift allowance) of the bias."""
    t, y = session.t_gyro_s, session.gyro_rad_s
    band = smoothed_noise_band(t, np.maximum(white_noise_std(y), 1e-12)) + BIAS_ALLOWANCE_RAD_S
    return np.all(np.abs(moving_average(t, y, SMOOTH_S) - bias_rad_s) <= band, axis=1)


def accelerometer_still(session: Session) -> np.ndarray:
    """(n_acc,) True where the smoothed accelerometer is within its noise band of its mean over LOCAL_S."""
    t, a = session.t_acc_s, session.acc_m_s2
    band = smoothed_noise_band(t, np.maximum(white_noise_std(a), 1e-12))
    return np.all(np.abs(moving_average(t, a, SMOOTH_S) - moving_average(t, a, LOCAL_S)) <= band, axis=1)


def still_runs(t_s: np.ndarray, still: np.ndarray) -> list[tuple[float, float]]:
    """(start, end) of every run of still samples, EDGE_S off each end, at least MIN_STILL_S long."""
    edges = np.flatnonzero(np.diff(np.concatenate([[0], still.astype(np.int8), [0]])))
    runs = [(float(t_s[a]) + EDGE_S, float(t_s[b - 1]) - EDGE_S) for a, b in zip(edges[::2], edges[1::2])]
    return [(a, b) for a, b in runs if b - a >= MIN_STILL_S]


def outside_rests(runs, rest_segments) -> list[tuple[float, float]]:
    """The runs that overlap no end rest (an end rest is judged, and trimmed, on its own)."""
    return [(a, b) for a, b in runs if not any(a <= r1 and b >= r0 for r0, r1 in rest_segments)]


def gravity_directions(session: Session, segments) -> np.ndarray:
    """(n, 3) the unit mean raw accelerometer of every segment with samples."""
    t, a = session.t_acc_s, session.acc_m_s2
    means = [a[(t >= s0) & (t <= s1)].mean(axis=0) for s0, s1 in segments if np.any((t >= s0) & (t <= s1))]
    means = np.array(means).reshape(-1, 3)
    return means / np.maximum(np.linalg.norm(means, axis=1), 1e-12)[:, None]


def distinct_poses(directions: np.ndarray, apart_deg: float = POSE_APART_DEG) -> int:
    """How many of the unit `directions` are more than `apart_deg` from every direction counted before them."""
    kept: list[np.ndarray] = []
    cos_apart = np.cos(np.radians(apart_deg))
    for d in directions:
        if all(d @ k < cos_apart for k in kept):
            kept.append(d)
    return len(kept)


def find_stills(session: Session, rests: Rests) -> Stills:
    """The stills of `session` (untrimmed) outside its end rests `rests`."""
    t = session.t_gyro_s
    if len(t) < 10:
        return Stills([], 0.0, None)
    bias = rests.gyro_mean_rad_s if rests.gyro_mean_rad_s is not None else np.median(session.gyro_rad_s, axis=0)
    still = gyro_still(session, bias)
    has_acc = session.acc_m_s2 is not None and len(session.acc_m_s2) >= 10
    if has_acc:
        acc_on_gyro = np.interp(t, session.t_acc_s, accelerometer_still(session).astype(float)) > 0.5
        still &= acc_on_gyro
    segments = outside_rests(still_runs(t, still), rests.segments_s)
    poses = distinct_poses(gravity_directions(session, sorted(list(rests.segments_s) + segments))) if has_acc else None
    return Stills(segments, float(sum(b - a for a, b in segments)), poses)
