"""Gyro samples pre-filtered so the grid's trapezoid integrates the rate to high order.

Between two gyro samples the least squares takes the rate as linear in time (trapezoid plus a coning term).
For a smooth rate sampled every h that integral is off by -h^3 w''/12 per step, and at phone rates
(28 Hz) a hand's motion makes that a scale error of about (2 pi f h)^2 / 12: +0.6 % for 1.5 Hz.
The trapezoid of filtered samples is exact for a rate e^(i w t) when the filter's gain is
(2 / wh) tan(wh / 2) = 1 + (wh)^2/12 + (wh)^4/120 + ...; a symmetric filter matches it:
- five taps (SIXTH_ORDER) to (wh)^4, leaving about 0.003 (wh)^6 (1e-5 at 1.5 Hz / 28 Hz);
- three taps, w_k - (w_{k+1} - 2 w_k + w_{k-1}) / 12, to (wh)^2, leaving 0.015 (wh)^4 (2e-4 there:
  a +1e-4 scale bias in simulation);
The filters are linear with unit gain at zero frequency, so they commute with the gyro model (scale,
bias) and apply to the raw samples. Each sample takes the widest filter whose samples are evenly
spaced (UNIFORM_TOLERANCE); next to a hole, a cut or a jittered stamp it stays raw.
"""
from __future__ import annotations

import numpy as np

UNIFORM_TOLERANCE = 0.03   # the two steps around a sample may differ by this fraction of their mean
FOURTH_ORDER = np.array([-1.0, 14.0, -1.0]) / 12.0                    # taps k-1 .. k+1
SIXTH_ORDER = np.array([11.0, -104.0, 906.0, -104.0, 11.0]) / 720.0  # taps k-2 .. k+2


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


def filter_widths(t_s: np.ndarray) -> np.ndarray:
    """Per sample, the filter's taps: 5 where the four steps around it are evenly spaced, 3 where the two
    are, 1 (raw) elsewhere."""
    even = evenly_spaced_interior(t_s)
    wide = np.zeros_like(even)
    wide[1:-1] = even[:-2] & even[1:-1] & even[2:]
    return np.where(wide, 5, np.where(even, 3, 1))


def high_order_samples(t_s: np.ndarray, rate: np.ndarray) -> np.ndarray:
    """(N, 3) samples whose trapezoid integrates a smooth rate to high order: the widest filter of
    `filter_widths` at each sample (SIXTH_ORDER, FOURTH_ORDER), the raw sample elsewhere."""
    rate = np.asarray(rate, dtype=float)
    out = rate.copy()
    widths = filter_widths(t_s)
    for taps in (FOURTH_ORDER, SIXTH_ORDER):
        half = len(taps) // 2
        k = np.flatnonzero(widths == len(taps))
        out[k] = sum(c * rate[k + j - half] for j, c in enumerate(taps))
    return out
