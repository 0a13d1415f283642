"""White-noise stds from robust third differences: the one noise measure that needs no rest.

A third difference of a smooth signal sampled fast is nearly zero, while for
white noise of std s it has std s * sqrt(20). A robust (MAD) scale of the
third differences therefore estimates the white-noise std per axis while the
device moves, as long as the motion is slow against the sample rate. At a
phone's 25-40 Hz a hand's motion is not slow: the level is then far too large,
a guess that the least squares replaces by its own estimate (`magyro.nls.variance`).
Its own module so that the rests (which need it to judge stillness) and the
noise levels (which need the rests) import it without importing each other.
"""
from __future__ import annotations

from math import comb

import numpy as np

THIRD_DIFFERENCE_GAIN = np.sqrt(20.0)  # sqrt(1 + 9 + 9 + 1)
MAD_TO_STD = 1.4826


MOTION_FREE_RATIO = 0.9   # the next order's level at least this share of the previous: the noise floor


def difference_noise_std(x: np.ndarray, order: int) -> np.ndarray:
    """Per-column white-noise std of samples x (N, d) from robust differences of the given order
    (white noise of std s gives a k-th difference of std s * sqrt(binomial(2k, k)))."""
    dk = np.diff(np.asarray(x, dtype=float), n=order, axis=0)
    med = np.median(dk, axis=0)
    mad = np.median(np.abs(dk - med), axis=0)
    return MAD_TO_STD * mad / np.sqrt(comb(2 * order, order))


def white_noise_std(x: np.ndarray) -> np.ndarray:
    """Per-column white-noise std of samples x (N, d) from robust third differences."""
    return difference_noise_std(x, 3)


MAX_ORDER = 8


def noise_floor_std(x: np.ndarray, rate_hz: float | None = None) -> tuple[np.ndarray, bool]:
    """(per-column white-noise std, whether it is noise): the levels of the 3rd, 4th, ... differences.

    For white noise every order gives the same level; a motion that leaks in shrinks by about (omega dt)^2
    per order while the noise's gain only grows, so the levels fall with the order until only the noise is
    left. The first order whose level no longer falls (by more than 1 - MOTION_FREE_RATIO from the previous
    order's, RMS over the columns) gives the level, and it is noise; when they still fall at MAX_ORDER, the last level is an upper
    bound only (motion too fast for the sample rate: a guess)."""
    levels = [difference_noise_std(x, k) for k in range(3, MAX_ORDER + 1)]
    rms = [float(np.sqrt(np.mean(v**2))) for v in levels]
    for k in range(len(levels) - 1):
        if rms[k] > 0 and rms[k + 1] >= MOTION_FREE_RATIO * rms[k]:
            return levels[k + 1], not (low_rate(rate_hz) and floor_follows_motion(x, k + 4))
    return levels[-1], False


LOW_RATE_HZ = 100.0          # the floor is compared with the motion at this rate or below: there a hand's turning
                             # (to ~5 Hz) leaks into every order; above it (BROAD at 285 Hz, whose floor is 1.9x
                             # higher where it turns fast) what rises with the turning is the sensor's own, which the
                             # least squares' variance components read as the room's wander and the gyro level 6.6x
                             # too large on BROAD 02 without its rests


def low_rate(rate_hz: float | None) -> bool:
    """Is the gyro sampled slowly enough for a hand's motion to show in the differences' floor?"""
    return rate_hz is not None and rate_hz <= LOW_RATE_HZ


FLOOR_WINDOW = 64            # samples a window: a robust level to ~15 % each
MIN_FLOOR_WINDOWS = 9        # fewer windows cannot compare thirds
MOTION_SPREAD = 1.5          # the fastest third of the windows turns at least this much faster than the slowest ...
FLOOR_FOLLOWS_MOTION = 1.3   # ... and its floor is this much higher: the floor is the motion, not the sensor


def floor_follows_motion(x: np.ndarray, order: int) -> bool:
    """Whether the differences' floor of `order` rises with the motion: a sensor's white noise is the same
    whether the device turns slowly or fast, what the motion leaks into high orders is not. A floor that no
    longer falls with the order can still be the motion: at 25 Hz a hand turning a phone at 200-340 deg/s (its
    stamps a few ms off the true sample times) leaves a white-looking floor 150x a phone gyro's noise, which falls
    no further with the order (issue 38). Windows of FLOOR_WINDOW samples are sorted by their RMS magnitude; the
    floor of the fastest third against the slowest third's (medians) tells. A white-noise floor compares at
    1.0 +/- 0.1 over nine windows or more; the iPhone's at 1.5-1.8."""
    x = np.asarray(x, dtype=float)
    n = len(x) // FLOOR_WINDOW
    if n < MIN_FLOOR_WINDOWS:
        return False
    windows = x[: n * FLOOR_WINDOW].reshape(n, FLOOR_WINDOW, -1)
    motion = np.sqrt(np.mean(np.sum(windows**2, axis=2), axis=1))
    floor = np.array([np.sqrt(np.mean(difference_noise_std(w, order) ** 2)) for w in windows])
    order_by_motion = np.argsort(motion, kind="stable")
    third = n // 3
    slow, fast = order_by_motion[:third], order_by_motion[-third:]
    slow_floor = float(np.median(floor[slow]))
    if not np.median(motion[fast]) >= MOTION_SPREAD * np.median(motion[slow]) or not slow_floor > 0:
        return False
    return bool(np.median(floor[fast]) >= FLOOR_FOLLOWS_MOTION * slow_floor)
