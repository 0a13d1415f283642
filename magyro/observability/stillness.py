"""How still the device was at each accelerometer sample: the weight gravity's direction counts with.

A still device reads gravity alone; a hand's acceleration shows in the reading's size. So each sample counts by
w = exp(-((|y| - s(u)) / (STILL_SCALE g))^2 / 2), s(u) the size the accelerometer reads still in the reading's
direction u (`expected_size`). Against g alone, an uncalibrated accelerometer's scale and bias errors, a few % of g
in some poses, made a pose held still count a fraction of its seconds. Used by `magyro observe`
(observability/gravity.py), `magyro watch` (live/integral.py) and `magyro plan` (studies/plan_accelerometer.py).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

STILL_SCALE = 0.05        # |y| off g by 5 % of g counts exp(-1/2) = 0.61, by 10 % 0.14, by 15 % 0.011
SIZE_PRIOR_OF_G = 0.1     # the expected size's prior: scale and bias errors within a tenth of g (std), isotropic
SIZE_FIT_SCALE = 3.0      # the samples its first fit reads: |y| within 3 STILL_SCALE of g (shaking left out)
SIZE_FIT_ROUNDS = 2       # its fits: the second weighs each sample by its stillness against the first


def stillness(norm: np.ndarray, expected, g: float) -> np.ndarray:
    """The weight of each sample: 1 where |y| is the `expected` size (a number, or one per sample), falling as the
    hand's acceleration shows in the size, on the scale STILL_SCALE of g."""
    return np.exp(-0.5 * ((norm - expected) / (STILL_SCALE * g)) ** 2)


@dataclass(frozen=True)
class ExpectedSize:
    """The size an accelerometer reads still, by the direction u of its reading: s(u) = c . u + d . (u * u). A
    reading y = S f + b of a specific force of size g has, to first order in the scale errors S - I and the bias b,
    |y| = g + b . u + g u^T (S - I) u: c is the bias, d g times the scale factors (their sum is g's at the isotropic
    start, as u . u = 1). The non-orthogonality's share is second order and left out."""

    c: np.ndarray
    d: np.ndarray

    @classmethod
    def constant(cls, g: float) -> "ExpectedSize":
        return cls(np.zeros(3), np.full(3, float(g)))

    def at(self, u: np.ndarray) -> np.ndarray:
        return u @ self.c + (u * u) @ self.d


def expected_size(acc: np.ndarray, g: float) -> ExpectedSize:
    """`ExpectedSize` fitted to the readings: least squares of |y| on [u, u * u] over the samples within
    SIZE_FIT_SCALE x STILL_SCALE of g, with a prior that the accelerometer is within SIZE_PRIOR_OF_G of g in every
    direction (a pose never visited keeps g); then again, each sample weighted by its stillness against the first
    fit (SIZE_FIT_ROUNDS). Weighted by stillness against g from the start, the fit leaned towards g exactly in the
    poses furthest from it. The hand's acceleration averages out of the size over a pose's seconds; the scale and
    bias errors do not. BROAD 02 read through paper-table1-acc's accelerometer errors (scale 1.2-1.8 %, bias
    0.15-0.25 m/s^2) reads 9.46-10.24 m/s^2 still, depending on the pose; the fit gives each pose's within 0.15."""
    norm = np.linalg.norm(acc, axis=1)
    ok = np.isfinite(norm) & (norm > 0)
    u, norm = acc[ok] / norm[ok, None], norm[ok]
    X = np.column_stack([u, u * u])
    noise = STILL_SCALE * g                                  # the size's spread with the hand in it, per sample
    prior = np.concatenate([np.zeros(3), np.full(3, float(g))])
    size = ExpectedSize.constant(g)
    w = (np.abs(norm - g) < SIZE_FIT_SCALE * noise).astype(float)
    for _ in range(SIZE_FIT_ROUNDS):
        A = (X * w[:, None]).T @ X / noise**2 + np.eye(6) / (SIZE_PRIOR_OF_G * g) ** 2
        rhs = (X * w[:, None]).T @ norm / noise**2 + prior / (SIZE_PRIOR_OF_G * g) ** 2
        theta = np.linalg.solve(A, rhs)
        size = ExpectedSize(theta[:3], theta[3:])
        w = stillness(norm, size.at(u), g)
    return size


def still_weights(acc: np.ndarray, g: float, size: ExpectedSize | None = None) -> np.ndarray:
    """(n,) each sample's stillness against the size expected in its direction (`expected_size`, fitted here when not
    given), its scale STILL_SCALE of g."""
    norm = np.linalg.norm(acc, axis=1)
    u = acc / np.where(norm > 0, norm, 1.0)[:, None]
    return stillness(norm, (size or expected_size(acc, g)).at(u), g)
