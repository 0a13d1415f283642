"""The paper's matrix M and its integrals, shared by the linear initial estimate
(eq. 13) and the observability check (eq. 10-11).

    d m^m / dt = m^m x (K y_g + eps) = M [vec K; eps],
    M = [y_g^T (x) (m^m x),  m^m x]          (3 x 12, vec stacks columns)

Everything is evaluated on the gyro's time base, with the calibrated field m^m
linearly interpolated there.
"""
from __future__ import annotations

import numpy as np

from magyro.session import hole_spans_s, hole_steps, overlaps_a_hole
from magyro.so3 import skew

PARAMETER_NAMES = (
    "K11", "K21", "K31", "K12", "K22", "K32", "K13", "K23", "K33", "eps_x", "eps_y", "eps_z",
)


def interpolate_rows(t_new: np.ndarray, t: np.ndarray, x: np.ndarray) -> np.ndarray:
    """Linear interpolation of each column of x (N, d) from times t onto t_new (clamped at the ends)."""
    return np.column_stack([np.interp(t_new, t, x[:, j]) for j in range(x.shape[1])])


def m_matrices(gyro: np.ndarray, field_m: np.ndarray) -> np.ndarray:
    """M at each sample: (N, 3, 12) from gyro y_g (N, 3) and field m^m (N, 3)."""
    S = skew(field_m)                                     # (N, 3, 3)
    blocks = [gyro[:, j, None, None] * S for j in range(3)]  # y_j (m x): column block j of vec K
    return np.concatenate(blocks + [S], axis=2)


def trapezoid_weights(t_s: np.ndarray) -> np.ndarray:
    """Weights w_k with sum_k w_k f(t_k) the trapezoid integral of f over [t_0, t_N-1], holes left out."""
    dt = np.where(hole_steps(t_s), 0.0, np.diff(t_s))
    w = np.zeros_like(t_s)
    w[:-1] += 0.5 * dt
    w[1:] += 0.5 * dt
    return w


def field_on_gyro_times(t_gyro_s: np.ndarray, t_mag_s: np.ndarray, field_m: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(mask, field) for the gyro samples inside the magnetometer's time span."""
    inside = (t_gyro_s >= t_mag_s[0]) & (t_gyro_s <= t_mag_s[-1])
    return inside, interpolate_rows(t_gyro_s[inside], t_mag_s, field_m)


PIECE = 65536   # samples per piece of the sums over the session: their temporaries are a piece's, not the session's


def information_integral(t_gyro_s, gyro_rad_s, t_mag_s, field_m) -> np.ndarray:
    """The 12 x 12 integral of M^T M over the session (paper eq. 11).

    M = [u_1 (m x), u_2 (m x), u_3 (m x), u_4 (m x)] with u = (y, 1), so M^T M = (u u^T) kron ((m x)^T (m x)) and
    (m x)^T (m x) = |m|^2 I - m m^T: the integral is one (16 x 9) matrix product of the weighted u_j u_l against
    those 9 numbers per sample, in pieces (no (N, 3, 12) M)."""
    inside, f = field_on_gyro_times(t_gyro_s, t_mag_s, field_m)
    y = gyro_rad_s[inside]
    w = trapezoid_weights(t_gyro_s[inside])
    T = np.zeros((16, 9))
    for a in range(0, len(w), PIECE):
        fk, yk, wk = f[a : a + PIECE], y[a : a + PIECE], w[a : a + PIECE]
        u = np.column_stack([yk, np.ones(len(yk))])
        P = (np.sum(fk * fk, axis=1)[:, None, None] * np.eye(3) - fk[:, :, None] * fk[:, None, :]).reshape(-1, 9)
        T += ((wk[:, None] * u)[:, :, None] * u[:, None, :]).reshape(-1, 16).T @ P
    return T.reshape(4, 4, 3, 3).transpose(0, 2, 1, 3).reshape(12, 12)


def cumulative_information(t_gyro_s, gyro_rad_s, t_mag_s, field_m, t_checkpoints_s) -> np.ndarray:
    """Integral of M^T M from the start up to each checkpoint time: (C, 12, 12)."""
    inside, f = field_on_gyro_times(t_gyro_s, t_mag_s, field_m)
    t = t_gyro_s[inside]
    M = m_matrices(gyro_rad_s[inside], f)
    MtM = np.einsum("kia,kib->kab", M, M)
    dt = np.where(hole_steps(t), 0.0, np.diff(t))[:, None, None]
    cum = np.concatenate([np.zeros((1, 12, 12)), np.cumsum(0.5 * (MtM[1:] + MtM[:-1]) * dt, axis=0)])
    idx = np.clip(np.searchsorted(t, t_checkpoints_s, side="right") - 1, 0, len(t) - 1)
    return cum[idx]


def windowed_increments(t_gyro_s, gyro_rad_s, t_mag_s, field_m, window_s: float):
    """Rows of eq. (13): field change over each window and the integral of M over it.

    Windows run between magnetometer samples about `window_s` apart; a window
    that overlaps a hole in either record is left out (nothing is known of the
    motion there). Returns (dm (W, 3), int_M (W, 3, 12)).

    M's blocks are y_j (m x) = (y_j m) x, so only the 12 numbers y_j m and m are integrated per sample and
    turned into skew blocks per window: the same sums, sign for sign, as integrating M itself. The running
    integral is made PIECE samples at a time, each piece's sum started from the last one's (the same additions in
    the same order as one cumulative sum) and read at the window ends that fall in it: its temporaries are a
    piece's, not the session's (~400 bytes a sample).
    """
    inside = np.flatnonzero((t_gyro_s >= t_mag_s[0]) & (t_gyro_s <= t_mag_s[-1]))
    t = t_gyro_s[inside]
    step = max(1, int(round(window_s * (len(t_mag_s) - 1) / (t_mag_s[-1] - t_mag_s[0]))))
    ends = np.arange(0, len(t_mag_s), step)
    ends = ends[(t_mag_s[ends] >= t[0]) & (t_mag_s[ends] <= t[-1])]
    t_end = t_mag_s[ends]
    cum_at = np.empty((len(ends), 12))
    carry = np.zeros((1, 12))
    for a in range(0, max(len(t) - 1, 1), PIECE):
        b = min(a + PIECE, len(t) - 1)                  # samples a..b: the running integral at each of them
        rows = inside[a : b + 1]
        f = interpolate_rows(t[a : b + 1], t_mag_s, field_m)
        y = gyro_rad_s[rows]
        q = np.concatenate([y[:, j, None] * f for j in range(3)] + [f], axis=1)   # y_1 m, y_2 m, y_3 m, m
        q = 0.5 * (q[1:] + q[:-1])
        q *= np.diff(t[a : b + 1])[:, None]
        cum = np.cumsum(np.concatenate([carry, q]), axis=0)
        carry = cum[-1:]
        last = b == len(t) - 1
        here = (t_end >= t[a]) & ((t_end <= t[b]) if last else (t_end < t[b]))
        for i in range(12):
            cum_at[here, i] = np.interp(t_end[here], t[a : b + 1], cum[:, i])
    dm = np.diff(field_m[ends], axis=0)
    whole = ~overlaps_a_hole(t_end[:-1], t_end[1:], hole_spans_s(t) + hole_spans_s(t_mag_s))
    inc = np.diff(cum_at, axis=0)[whole]
    return dm[whole], np.concatenate([skew(inc[:, 3 * j : 3 * j + 3]) for j in range(4)], axis=2)
