"""What `magyro watch` counts, kept as the data arrives: the integral of M^T M of the gate (`observability.gate`)
against a reference vector, the field or gravity's direction, and where the gate would start counting.

The integral is kept as G = integral of z z^T dt, z = ytilde (x) q: ytilde = [y_g; 1] the gyro reading, q the
reference's 4-vector at the gyro's time (the raw magnetometer reading [y_m; 1], whose field is an affine map A q;
or gravity's direction [u; 1] weighted by stillness). `information_and_noise` projects G with A onto the integral of
M^T M and the noise matrix N, exactly, so a better ellipsoid re-projects it in O(1) (live/monitor.py).

The gate counts the session less the rests at its ends (`front.rests.moving_span`): a rest adds nothing the solve
uses. Live, the rest the recording opens with is found as the rows arrive (`leading_rest`), and the integrals start
at its end; its noise levels are observe's (`rest_noise_levels`).
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Callable

import numpy as np

from magyro.front import differences
from magyro.front.rests import MIN_REST_S, SMOOTH_S, still_prefix_s
from magyro.session import HOLE_FACTOR, Session


class RunningIntegral:
    """G = integral of z z^T dt over the gyro rows from `done` on (trapezoid over the gyro's times, holes left out:
    `matrix.information_integral`'s rule), each gyro row taken once the reference has a row after it."""

    def __init__(self, first_gyro: int = 0):
        self.G = np.zeros((16, 16))
        self.done = first_gyro       # gyro rows taken in (or left out before the reference's first row)
        self._last: tuple[float, np.ndarray] | None = None   # the last row's (t, z): the next trapezoid starts there

    def extend(self, gyro: np.ndarray, t_reference_s: np.ndarray, reference: Callable[[np.ndarray, int], np.ndarray],
               typical_dt_s: Callable[[int], float | None]) -> None:
        """Take in the gyro rows (t, x, y, z) past `done` up to the reference's last time. `reference(t, lo)`: q
        (len(t), 4) at the times t, from the reference's rows lo on; `typical_dt_s(done)`: the gyro's step (a
        longer step is a hole), or None."""
        if not len(t_reference_s) or self.done >= len(gyro):
            return
        g = gyro[self.done:]
        stop = int(np.searchsorted(g[:, 0], t_reference_s[-1], side="right"))   # wait for the reading after them
        block = g[:stop]
        block = block[block[:, 0] >= t_reference_s[0]]                           # before its first reading: left out
        self.done += stop
        if not len(block):
            return
        t = block[:, 0]
        q = reference(t, max(0, int(np.searchsorted(t_reference_s, t[0])) - 1))
        ytil = np.column_stack([block[:, 1:], np.ones(len(t))])
        z = (ytil[:, :, None] * q[:, None, :]).reshape(len(t), 16)
        if self._last is not None:
            t = np.concatenate([[self._last[0]], t])
            z = np.vstack([self._last[1], z])
        self._last = (float(t[-1]), z[-1].copy())
        if len(t) < 2:
            return
        dt = np.diff(t)
        step = typical_dt_s(self.done)
        if step is not None:
            dt = np.where(dt > HOLE_FACTOR * step, 0.0, dt)
        w = 0.5 * dt
        self.G += (z[:-1] * w[:, None]).T @ z[:-1] + (z[1:] * w[:, None]).T @ z[1:]


def field_reference(t_mag_s: np.ndarray, mag: np.ndarray):
    """q = [y_m; 1] at the gyro's times: the raw reading interpolated linearly."""
    def q(t, lo):
        return np.column_stack([np.interp(t, t_mag_s[lo:], mag[lo:, j]) for j in range(3)] + [np.ones(len(t))])
    return q


def gravity_reference(t_acc_s: np.ndarray, acc_m_s2: np.ndarray, g_m_s2: float, size=None):
    """q = sqrt(s) [u; 1] at the gyro's times (`magyro observe`'s part 2, `gravity.gyro_with_gravity`): u the
    accelerometer's direction, s its stillness (1 where |y| is the size `size` expects in that direction,
    `gravity.ExpectedSize`, else g; falling as the hand shows)."""
    from magyro.observability.stillness import ExpectedSize, stillness

    expected = size or ExpectedSize.constant(g_m_s2)

    def q(t, lo):
        a = np.column_stack([np.interp(t, t_acc_s[lo:], acc_m_s2[lo:, j]) for j in range(3)])
        norm = np.linalg.norm(a, axis=1)
        u = a / np.where(norm > 0, norm, 1.0)[:, None]
        return np.column_stack([u, np.ones(len(t))]) * np.sqrt(stillness(norm, expected.at(u), g_m_s2))[:, None]
    return q


def information_and_noise(G: np.ndarray, A: np.ndarray, gyro_std: float, reference_std: float):
    """(integral of M^T M, noise matrix N), 12 x 12, from G = integral of z z^T dt, z = ytilde (x) q (16), whose
    reference vector is A q (A 3 x 4): the field m = A [y_m; 1], or gravity's direction ([u; 1] with A = [I 0]);
    `reference_std` the per-sample noise of the unit reference."""
    G4 = G.reshape(4, 4, 4, 4)                           # [a, c, b, d]: ytilde_a q_c ytilde_b q_d
    norm2 = np.einsum("acbd,cd->ab", G4, A.T @ A)          # integral ytilde_a ytilde_b |m|^2
    mm = np.einsum("acbd,ic,jd->aibj", G4, A, A)          # integral ytilde_a ytilde_b m_i m_j
    info = (np.einsum("ab,ij->aibj", norm2, np.eye(3)) - mm).reshape(12, 12)
    Y = G4[:, 3, :, 3]                                    # integral ytilde ytilde^T
    P = Y[3, 3] * np.eye(3) - A @ G4[3, :, 3, :] @ A.T    # integral (I - m m^T)
    # |m| is 1 only up to the noise (and the fit): along the field, P can come out slightly negative where
    # the gate's unit directions make it 0; clipped, so that no direction reads as noise-free
    lam_p, V_p = np.linalg.eigh(0.5 * (P + P.T))
    P = (V_p * np.maximum(lam_p, 0.0)) @ V_p.T
    N = (np.kron(np.diag([1.0, 1.0, 1.0, 0.0]), gyro_std ** 2 * P)
         + np.kron(2.0 * reference_std ** 2 * Y, np.eye(3)))
    return 0.5 * (info + info.T), 0.5 * (N + N.T)


@dataclass(frozen=True)
class LeadingRest:
    """Where the gate would start analysing the rows so far (`start_s`), the rest the recording opens with
    (`span_s`, None without one) and whether that is settled."""

    start_s: float
    span_s: tuple[float, float] | None
    settled: bool


def leading_rest(gyro: np.ndarray, mag: np.ndarray) -> LeadingRest:
    """The rest the rows so far open with, as `front.rests.find_rests` finds it (the white noise from the rows so
    far), and where the gate starts: at its end less SMOOTH_S (`rests.moving_span`), the recording's first time
    without one. Settled once the device has moved for MIN_REST_S after it (or the recording started moving)."""
    tg, yg, tm, ym = gyro[:, 0], gyro[:, 1:], mag[:, 0], mag[:, 1:]
    head = min(still_prefix_s(tg, yg, differences.white_noise_std(yg)),
               still_prefix_s(tm, ym, differences.white_noise_std(ym)))
    t0, t_first, t_last = min(tg[0], tm[0]), max(tg[0], tm[0]), min(tg[-1], tm[-1])
    settled = (t_last - t_first) - head >= MIN_REST_S
    if head < MIN_REST_S:
        return LeadingRest(float(t0), None, settled)
    return LeadingRest(float(max(t0, t_first + head - SMOOTH_S)), (float(t_first), float(t_first + head)), settled)


def rest_noise_levels(session: Session, rest_s: tuple[float, float] | None, options=None) -> tuple[float, float] | None:
    """(gyro rad/s, magnetometer) per-sample noise std as observe's gate reads them from the leading rest `rest_s`
    (`front.noise.noise_levels`: the rest's own spread, its correlation included; given ones win), or None when
    there is no rest long enough for it (the monitor's third differences then stay)."""
    from magyro.front.noise import MIN_REST_FOR_NOISE_S, noise_levels
    from magyro.front.rests import rests_from_segments
    from magyro.options import Options

    if rest_s is None or rest_s[1] - rest_s[0] < MIN_REST_FOR_NOISE_S:
        return None
    levels = noise_levels(session, options or Options(), rests_from_segments(session, [rest_s]))
    return levels.gyro_sample_std_rad_s, levels.mag_sample_std
