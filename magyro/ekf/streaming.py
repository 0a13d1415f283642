"""Feeding the error-state EKF (`magyro.ekf.filter`) one sample at a time, from two asynchronous sensors.

Asynchronous sensors: the filter propagates from gyro sample to gyro sample;
a magnetometer sample at t_m inside [t_a, t_b] splits the interval (gyro
reading linearly interpolated at t_m): propagate to t_m, update, propagate
on. The filter starts at the first magnetometer sample at or after the first
gyro sample, with C = I and zero attitude covariance: the paper's choice of
the inertial frame, which makes the state observable.

`StreamingCalibrator` is the filter fed sample by sample (a live stream, with
an optional latency buffer for late magnetometer samples); `run_filter` feeds
it a whole recorded session in time order.
"""
from __future__ import annotations

from collections import deque

import numpy as np

from magyro.ekf.filter import ErrorStateEKF
from magyro.ekf.uncertainty import reported_covariance
from magyro.errors import InputError
from magyro.result.reported import qr_split, std_from_covariance
from magyro.session import Session
from magyro.so3 import dcm_to_euler


class StreamingCalibrator(ErrorStateEKF):
    """The error-state EKF of paper eq. (9), fed one sample at a time.

    Each sensor's samples must come in increasing time. The filter
    propagates with every gyro sample and updates with every magnetometer
    sample; a magnetometer sample later than the last gyro sample processed
    waits until the next gyro sample brackets it, so `estimate()` reflects the
    samples up to the last gyro sample processed. Magnetometer samples older
    than that (or before the first gyro sample) are skipped (counted in
    `skipped_mag`): feed the two sensors merged by timestamp, or set
    latency_s to hold gyro samples back by that much so that magnetometer
    samples arriving up to latency_s late still count (call `flush()` at the
    end of the stream).

    The other arguments are the filter's (`ErrorStateEKF`): R, h from step 1,
    K0, eps0 and their covariance P0, m0 (None: from the first magnetometer
    sample), the noise levels, cov_Rh for the consider states, history_stride.
    """

    def __init__(self, R, h, K0, eps0, m0=None, gyro_noise_density_rad_s_sqrt_hz: float = 0.0,
                 mag_noise_std: float = 0.0, *, P0=None, cov_Rh=None, m0_std: float = 0.1,
                 history_stride: int | None = None, latency_s: float = 0.0):
        super().__init__(R, h, K0, eps0, m0, gyro_noise_density_rad_s_sqrt_hz, mag_noise_std, P0=P0,
                         cov_Rh=cov_Rh, m0_std=m0_std, history_stride=history_stride)
        self.t_gyro = None         # last gyro sample processed
        self.y_gyro = None
        self.t_gyro_fed = None     # last gyro sample fed (processed or buffered)
        self.latency_s = float(latency_s)
        self._gyro_buffer: deque = deque()
        self.t_last_mag = None
        self.pending: list[tuple[float, np.ndarray, list]] = []
        self.gyro_samples = 0
        self.skipped_mag = 0

    # ---- feeding

    def add_gyro(self, t_s: float, y_rad_s) -> None:
        """One raw gyro sample (rad/s) stamped t_s.

        With latency_s > 0 the sample waits in a buffer until a gyro sample
        latency_s newer arrives (or `flush()`), so magnetometer samples that
        arrive up to latency_s late still land in their place.
        """
        t = float(t_s)
        y = tuple(np.asarray(y_rad_s, dtype=float).tolist())
        if self.t_gyro_fed is not None and not t > self.t_gyro_fed:
            raise InputError(f"gyro samples must come in increasing time: {t} after {self.t_gyro_fed}")
        self.t_gyro_fed = t
        if self.latency_s <= 0.0:
            self._process_gyro(t, y)
            return
        buf = self._gyro_buffer
        buf.append((t, y))
        limit = t - self.latency_s
        while buf and buf[0][0] <= limit:
            self._process_gyro(*buf.popleft())

    def flush(self) -> None:
        """Process every buffered gyro sample (the end of a stream with latency_s > 0)."""
        buf = self._gyro_buffer
        while buf:
            self._process_gyro(*buf.popleft())

    def _process_gyro(self, t: float, y: tuple) -> None:
        """Update with the waiting magnetometer samples up to t (gyro interpolated), then propagate to t."""
        if self.pending:
            ta, ya = self.t_gyro, self.y_gyro
            keep = []
            for item in self.pending:
                tm = item[0]
                if tm > t:
                    keep.append(item)
                elif ta is None:                   # before the first gyro sample: nothing to propagate with
                    if tm == t:
                        self._measure(tm, y, item[1], item[2])
                    else:
                        self.skipped_mag += 1
                else:
                    if tm == t:
                        ym = y
                    else:
                        f = (tm - ta) / (t - ta)
                        ym = (ya[0] + (y[0] - ya[0]) * f, ya[1] + (y[1] - ya[1]) * f, ya[2] + (y[2] - ya[2]) * f)
                    if self.started:
                        self._propagate(tm, ym)
                    self._measure(tm, ym, item[1], item[2])
            self.pending = keep
        if self.started:
            self._propagate(t, y)
            self.gyro_samples += 1
        self.t_gyro, self.y_gyro = t, y

    def add_mag(self, t_s: float, y_mag) -> None:
        """One raw magnetometer sample (input unit) stamped t_s."""
        t = float(t_s)
        if self.t_last_mag is not None and not t > self.t_last_mag:
            raise InputError(f"magnetometer samples must come in increasing time: {t} after {self.t_last_mag}")
        self.t_last_mag = t
        if self.t_gyro is not None and t < self.t_gyro:
            self.skipped_mag += 1              # older than the filter's time: too late
            return
        d = np.asarray(y_mag, dtype=float) - self.h
        z = self.R @ d
        if t == self.t_gyro:
            self._measure(t, self.y_gyro, z, d.tolist())
        else:
            self.pending.append((t, z, d.tolist()))

    def _measure(self, t: float, y, z: np.ndarray, d: list) -> None:
        """One calibrated magnetometer sample z = R d, d = y_m - h, at t (gyro reading y there)."""
        if self.started:
            self._update(z, d)
        else:
            self._start(t, y, z, d)

    # ---- reading

    def estimate(self) -> dict:
        """The current estimate: K, K_g, bias, C_b_m, Euler angles, m^i, and one-sigma of each."""
        C, Kg = qr_split(self.K)
        cov = reported_covariance(self.K, self.eps, self.R, self.h, self.m, self.input_covariance(), C)
        std = std_from_covariance(cov)
        return {
            "t_s": self.t,
            "started": self.started,
            "gyro_samples": self.gyro_samples,
            "mag_updates": self.mag_updates,
            "K": self.K.copy(),
            "K_g": Kg,
            "eps_m_rad_s": self.eps.copy(),
            "bias_rad_s": C.T @ self.eps,
            "bias_deg_s": np.rad2deg(C.T @ self.eps),
            "C_b_m": C,
            "euler_deg": dcm_to_euler(C),
            "field_i": self.m.copy(),
            "C_m_i": self.C.copy(),
            "std": {k: getattr(std, k) for k in ("K", "K_g", "bias_deg_s", "misalignment_deg", "field_i")},
        }


def time_ordered(t_gyro_s: np.ndarray, t_mag_s: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(is_gyro, index) of all samples in time order, gyro first on equal stamps."""
    t = np.concatenate([t_gyro_s, t_mag_s])
    kind = np.concatenate([np.zeros(len(t_gyro_s), dtype=np.int8), np.ones(len(t_mag_s), dtype=np.int8)])
    idx = np.concatenate([np.arange(len(t_gyro_s)), np.arange(len(t_mag_s))])
    order = np.lexsort((kind, t))
    return kind[order] == 0, idx[order]


def run_filter(session: Session, filt: StreamingCalibrator) -> StreamingCalibrator:
    """Feed a whole session through a StreamingCalibrator, one sample at a time, in time order."""
    is_gyro, index = time_ordered(session.t_gyro_s, session.t_mag_s)
    tg, tm = session.t_gyro_s.tolist(), session.t_mag_s.tolist()
    yg, ym = session.gyro_rad_s, session.mag
    add_gyro, add_mag = filt.add_gyro, filt.add_mag
    for g, i in zip(is_gyro.tolist(), index.tolist()):
        if g:
            add_gyro(tg[i], yg[i])
        else:
            add_mag(tm[i], ym[i])
    return filt
