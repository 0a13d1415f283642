"""The session: one recording of gyroscope and magnetometer samples (docs/spec.md section 2).

`Session` holds each sensor on its own time base, in SI units for the gyro
(rad/s) and the magnetometer's own unit. Loading and validation live in
`magyro.io`.
"""
from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np


HOLE_FACTOR = 5.0   # a step longer than this many typical sample intervals is a hole in the record


def hole_steps(t_s: np.ndarray) -> np.ndarray:
    """(N-1,) flags: the steps between consecutive samples that are holes in the record.

    A hole (a logger that stopped, samples cut out as saturated) has no data:
    nothing is integrated across it, and the attitude after it is a new segment.
    """
    dt = np.diff(np.asarray(t_s, dtype=float))
    if len(dt) == 0:
        return np.zeros(0, dtype=bool)
    return dt > HOLE_FACTOR * float(np.median(dt))


def runs_of_true(mask: np.ndarray) -> list[tuple[int, int]]:
    """(first, last) index of every run of True: holes, cut samples, plateaus, bad windows."""
    edges = np.diff(np.concatenate([[0], np.asarray(mask).astype(np.int8), [0]]))
    return list(zip(np.flatnonzero(edges == 1), np.flatnonzero(edges == -1) - 1))


def hole_spans_s(t_s: np.ndarray) -> list[tuple[float, float]]:
    """(last sample before, first sample after) of every hole."""
    k = np.flatnonzero(hole_steps(t_s))
    return [(float(t_s[i]), float(t_s[i + 1])) for i in k]


def overlaps_a_hole(t0_s, t1_s, holes_s: list[tuple[float, float]]) -> np.ndarray:
    """Flags: does [t0, t1] (arrays of equal shape) overlap one of the holes (a, b), open at both ends?"""
    t0_s, t1_s = np.asarray(t0_s, dtype=float), np.asarray(t1_s, dtype=float)
    out = np.zeros(t0_s.shape, dtype=bool)
    for a, b in holes_s:
        out |= (t0_s < b) & (t1_s > a)
    return out


@dataclass(frozen=True)
class Session:
    """One recording. Arrays are float64; times in seconds, strictly increasing."""

    t_gyro_s: np.ndarray          # (Ng,)
    gyro_rad_s: np.ndarray        # (Ng, 3)
    t_mag_s: np.ndarray           # (Nm,)
    mag: np.ndarray               # (Nm, 3), in `mag_unit`
    mag_unit: str = "unknown"
    t_acc_s: np.ndarray | None = None      # (Na,) optional
    acc_m_s2: np.ndarray | None = None     # (Na, 3) optional
    t_quat_s: np.ndarray | None = None     # (Nq,) optional optical truth times
    quat_wxyz: np.ndarray | None = None    # (Nq, 4) optional truth, NaN where lost
    source: str = ""
    metadata: dict = field(default_factory=dict)

    @property
    def duration_s(self) -> float:
        t0 = min(self.t_gyro_s[0], self.t_mag_s[0])
        t1 = max(self.t_gyro_s[-1], self.t_mag_s[-1])
        return float(t1 - t0)

    @property
    def gyro_rate_hz(self) -> float:
        return float((len(self.t_gyro_s) - 1) / (self.t_gyro_s[-1] - self.t_gyro_s[0]))

    @property
    def mag_rate_hz(self) -> float:
        return float((len(self.t_mag_s) - 1) / (self.t_mag_s[-1] - self.t_mag_s[0]))

    def within(self, t0_s: float, t1_s: float) -> "Session":
        """The session cut to t0_s <= t <= t1_s: every sensor and the truth, times unchanged.

        No checks: gyro and magnetometer may come out short or empty (callers
        that need samples check the counts); an optional stream with no sample
        left becomes None.
        """
        def cut(t, values):
            keep = (t >= t0_s) & (t <= t1_s)
            return t[keep], values[keep]

        def cut_optional(t, values):
            if t is None or values is None:
                return None, None
            t_kept, kept = cut(t, values)
            return (t_kept, kept) if len(t_kept) else (None, None)

        t_g, g = cut(self.t_gyro_s, self.gyro_rad_s)
        t_m, m = cut(self.t_mag_s, self.mag)
        t_a, a = cut_optional(self.t_acc_s, self.acc_m_s2)
        t_q, q = cut_optional(self.t_quat_s, self.quat_wxyz)
        return replace(self, t_gyro_s=t_g, gyro_rad_s=g, t_mag_s=t_m, mag=m, t_acc_s=t_a, acc_m_s2=a,
                       t_quat_s=t_q, quat_wxyz=q)
