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

import numpy as np

THIRD_DIFFERENCE_GAIN = np.sqrt(20.0)  # sqrt(1 + 9 + 9 + 1)
MAD_TO_STD = 1.4826


def white_noise_std(x: np.ndarray) -> np.ndarray:
    """Per-column white-noise std of samples x (N, d) from robust third differences."""
    d3 = np.diff(np.asarray(x, dtype=float), n=3, axis=0)
    med = np.median(d3, axis=0)
    mad = np.median(np.abs(d3 - med), axis=0)
    return MAD_TO_STD * mad / THIRD_DIFFERENCE_GAIN
