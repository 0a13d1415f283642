"""Sensor noise levels estimated from the data itself.

A third difference of a smooth signal sampled fast is nearly zero, while for
white noise of std s it has std s * sqrt(20). A robust (MAD) scale of the
third differences therefore estimates the white-noise std per axis, even
while the device moves. Good enough to weight the least squares; users who
know their sensor pass the numbers instead.
"""
from __future__ import annotations

import numpy as np

THIRD_DIFFERENCE_GAIN = np.sqrt(20.0)  # sqrt(1 + 9 + 9 + 1)
MAD_TO_STD = 1.4826


def white_noise_std(x: np.ndarray) -> np.ndarray:
    """Per-column white-noise std of samples x (N, d) from robust third differences."""
    d3 = np.diff(np.asarray(x, dtype=float), n=3, axis=0)
    med = np.median(d3, axis=0)
    mad = np.median(np.abs(d3 - med), axis=0)
    return MAD_TO_STD * mad / THIRD_DIFFERENCE_GAIN


def mag_noise_std(y_mag: np.ndarray) -> float:
    """One magnetometer noise std (input unit), the RMS over the three axes."""
    return float(np.sqrt(np.mean(white_noise_std(y_mag) ** 2)))


def gyro_noise_density_rad_s_sqrt_hz(gyro_rad_s: np.ndarray, rate_hz: float) -> float:
    """Gyro noise density (rad/s/sqrt(Hz)) from the per-sample std: std / sqrt(rate)."""
    std = float(np.sqrt(np.mean(white_noise_std(gyro_rad_s) ** 2)))
    return std / np.sqrt(rate_hz)
