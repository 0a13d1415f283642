"""Gyro samples pre-filtered so the grid's trapezoid integrates the rate to fourth order.

Between two gyro samples the least squares takes the rate as linear in time (trapezoid plus a coning term).
For a smooth rate sampled every h that integral is off by -h^3 w''/12 per step, and at phone rates
(28 Hz) a hand's motion makes that a scale error of about (2 pi f h)^2 / 12: +0.6 % for 1.5 Hz. The
trapezoid of the samples w_k - (w_{k+1} - 2 w_k + w_{k-1}) / 12 removes it (Simpson-like, fourth order).
The filter is linear with unit gain at zero frequency, so it commutes with the gyro model (scale,
bias) and applies to the raw samples. It is applied only where three consecutive samples are evenly
spaced (UNIFORM_TOLERANCE); next to a hole, a cut or a jittered stamp the sample stays raw.
"""
from __future__ import annotations

import numpy as np

UNIFORM_TOLERANCE = 0.03   # the two steps around a sample may differ by this fraction of their mean


def evenly_spaced_interior(t_s: np.ndarray) -> np.ndarray:
    """Flags, one per sample: True where the steps before and after the sample differ by at most
    UNIFORM_TOLERANCE of their mean (never the first or last sample)."""
    t_s = np.asarray(t_s, dtype=float)
    flags = np.zeros(len(t_s), dtype=bool)
    if len(t_s) < 3:
        return flags
    before, after = np.diff(t_s)[:-1], np.diff(t_s)[1:]
    flags[1:-1] = np.abs(after - before) <= UNIFORM_TOLERANCE * 0.5 * (after + before)
    return flags


def fourth_order_samples(t_s: np.ndarray, rate: np.ndarray) -> np.ndarray:
    """(N, 3) samples whose trapezoid integral is fourth-order accurate: w_k - (second difference)/12
    where the sample's two neighbours are evenly spaced (`evenly_spaced_interior`), the raw sample elsewhere."""
    rate = np.asarray(rate, dtype=float)
    out = rate.copy()
    flags = evenly_spaced_interior(t_s)
    k = np.flatnonzero(flags)
    out[k] = rate[k] - (rate[k + 1] - 2.0 * rate[k] + rate[k - 1]) / 12.0
    return out
