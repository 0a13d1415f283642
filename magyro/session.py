"""The session: one recording of gyroscope and magnetometer samples (SPEC section 2).

`Session` holds each sensor on its own time base, in SI units for the gyro
(rad/s) and the magnetometer's own unit. Loading and validation live in
`magyro.io`.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np


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
