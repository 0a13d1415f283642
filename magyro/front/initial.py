"""The linear initial estimate of the gyro parameters (paper eq. 13).

Over each window [t_k, t_k+1] the change of the calibrated field equals the
integral of M times [vec K; eps]; stacking the windows gives an ordinary
least squares for the 12 parameters. It ignores the noise in M (errors in
variables), which is why the joint least squares refines it.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from magyro.front.ellipsoid import calibrated_field
from magyro.observability.matrix import windowed_increments

DEFAULT_WINDOW_S = 0.1
MAX_TIME_OFFSET_S = 0.1
GOLDEN = (np.sqrt(5.0) - 1.0) / 2.0
SEARCH_RATE_HZ = 100.0
SEARCH_SPAN_S = 300.0   # the lag is searched on the most turning 300 s of a longer recording (the final fit uses it all)


@dataclass(frozen=True)
class LinearGyroEstimate:
    K: np.ndarray      # 3x3, C_b^m K_g
    eps: np.ndarray    # (3,) rad/s, in the m frame
    rank: int          # rank of the stacked system
    windows: int       # windows used: those that cross a hole in either record are left out (0: an ideal gyro)
    time_offset_s: float = 0.0   # magnetometer lag used (searched by `with_time_offset`)
    residual: float = 0.0        # RMS of the stacked residual (nan without windows)


def linear_gyro_estimate(t_gyro_s, gyro_rad_s, t_mag_s, field_m, window_s: float = DEFAULT_WINDOW_S,
                         time_offset_s: float = 0.0, unexcited: np.ndarray | None = None) -> LinearGyroEstimate:
    """Least-squares [vec K; eps] from eq. (13); nearest to an ideal gyro when rank deficient.

    A magnetometer that lags by `time_offset_s` measured, at stamp t, the field of t - offset.
    `unexcited` (12 x k, columns in [vec K; eps]): directions the motion does not excite (the
    gate's, when forced); there the estimate is set to an ideal gyro's instead of the noise's.
    """
    dm, int_M = windowed_increments(t_gyro_s, gyro_rad_s, np.asarray(t_mag_s) - time_offset_s, field_m, window_s)
    return estimate_from_increments(dm, int_M, time_offset_s, unexcited)


def estimate_from_increments(dm: np.ndarray, int_M: np.ndarray, time_offset_s: float = 0.0,
                             unexcited: np.ndarray | None = None) -> LinearGyroEstimate:
    """`linear_gyro_estimate` from the rows of eq. (13) (`windowed_increments`). Without rows (every window crosses
    a hole: host stamps in bursts left unrepaired) an ideal gyro, rank 0, residual nan."""
    if len(dm) == 0:
        return LinearGyroEstimate(K=np.eye(3), eps=np.zeros(3), rank=0, windows=0, time_offset_s=time_offset_s,
                                  residual=float("nan"))
    A = int_M.reshape(-1, 12)
    b = dm.reshape(-1)
    # normal equations (12 x 12): a tall lstsq cost 40 ms a call in the lag search
    N, rhs = A.T @ A, A.T @ b
    lam, V = np.linalg.eigh(N)
    keep = lam > lam[-1] * 1e-18  # singular values above 1e-9 of the largest
    if keep.all():
        theta = V @ ((V.T @ rhs) / lam)
    else:  # where the data say nothing, an ideal gyro (K = I, eps = 0) rather than zero, which looks mirrored
        ideal = np.concatenate([np.eye(3).reshape(-1), np.zeros(3)])
        theta = ideal + V[:, keep] @ ((V[:, keep].T @ (rhs - N @ ideal)) / lam[keep])
    if unexcited is not None and np.size(unexcited):
        basis, _ = np.linalg.qr(np.asarray(unexcited, dtype=float))
        ideal = np.concatenate([np.eye(3).reshape(-1), np.zeros(3)])
        theta = theta + basis @ (basis.T @ (ideal - theta))
    rank = int(np.sum(keep))
    K = theta[:9].reshape(3, 3, order="F")
    rms = float(np.sqrt(np.mean((A @ theta - b) ** 2)))
    return LinearGyroEstimate(K=K, eps=theta[9:].copy(), rank=rank, windows=len(dm), time_offset_s=time_offset_s, residual=rms)


def with_time_offset(t_gyro_s, gyro_rad_s, t_mag_s, field_m, window_s: float = DEFAULT_WINDOW_S,
                     tolerance_s: float = 5e-4) -> LinearGyroEstimate:
    """Eq. (13) at the magnetometer lag that fits it best (golden-section search over +/-0.1 s).

    A lag of 10 ms at 7 rad/s turns the field 4 deg out of step with the gyro and biases
    the linear estimate by several deg/s; searching it first gives the joint problem a
    start it converges from.
    """
    rate_hz = (len(t_gyro_s) - 1) / (t_gyro_s[-1] - t_gyro_s[0])
    step = max(1, int(rate_hz // SEARCH_RATE_HZ))  # the search integrates at ~100 Hz; the final fit at full rate
    g, m = search_span(t_gyro_s, gyro_rad_s, t_mag_s)
    tg, yg, tm, fm = t_gyro_s[g][::step], gyro_rad_s[g][::step], np.asarray(t_mag_s)[m], np.asarray(field_m)[m]

    def fit(offset):
        return linear_gyro_estimate(tg, yg, tm, fm, window_s, offset)

    at_zero = fit(0.0)
    if at_zero.windows == 0:   # every window crosses a hole: no residual to search a lag on
        return linear_gyro_estimate(t_gyro_s, gyro_rad_s, t_mag_s, field_m, window_s, 0.0)
    a, b = -MAX_TIME_OFFSET_S, MAX_TIME_OFFSET_S
    c, d = b - GOLDEN * (b - a), a + GOLDEN * (b - a)
    fc, fd = fit(c), fit(d)
    while b - a > tolerance_s:
        if fc.residual < fd.residual:
            b, d, fd = d, c, fc
            c = b - GOLDEN * (b - a)
            fc = fit(c)
        else:
            a, c, fc = c, d, fd
            d = a + GOLDEN * (b - a)
            fd = fit(d)
    best = min((fc, fd, at_zero), key=lambda e: e.residual)
    return linear_gyro_estimate(t_gyro_s, gyro_rad_s, t_mag_s, field_m, window_s, best.time_offset_s)


def search_span(t_gyro_s, gyro_rad_s, t_mag_s, span_s: float = SEARCH_SPAN_S) -> tuple[slice, slice]:
    """(gyro, magnetometer) slices of the `span_s` seconds in which the gyro turns most (all of a shorter
    recording): the lag search's cost then stops growing with the recording (1 h at 100 Hz: 4.9 s -> ~0.5 s)."""
    t_gyro_s, t_mag_s = np.asarray(t_gyro_s), np.asarray(t_mag_s)
    if t_gyro_s[-1] - t_gyro_s[0] <= span_s:
        return slice(None), slice(None)
    turned = np.concatenate([[0.0], np.cumsum(np.linalg.norm(gyro_rad_s[1:], axis=1) * np.diff(t_gyro_s))])
    ends = np.searchsorted(t_gyro_s, t_gyro_s + span_s)
    valid = ends < len(t_gyro_s)
    starts = np.flatnonzero(valid)
    best = int(starts[np.argmax(turned[ends[valid]] - turned[starts])])
    t0, t1 = t_gyro_s[best], t_gyro_s[best] + span_s
    g = slice(best, int(np.searchsorted(t_gyro_s, t1, side="right")))
    m = slice(int(np.searchsorted(t_mag_s, t0)), int(np.searchsorted(t_mag_s, t1, side="right")))
    return g, m


def turning_residual(t_gyro_s, gyro_rad_s, t_mag_s, field_m, K, eps, time_offset_s: float = 0.0,
                     window_s: float = DEFAULT_WINDOW_S) -> float:
    """RMS misfit of eq. (13) for given K, eps: how well that gyro calibration predicts the calibrated
    field's turning over the windows (the linear estimate is the K, eps that minimise it)."""
    dm, int_M = windowed_increments(t_gyro_s, gyro_rad_s, np.asarray(t_mag_s) - time_offset_s, field_m, window_s)
    return residual_of_increments(dm, int_M, K, eps)


def residual_of_increments(dm: np.ndarray, int_M: np.ndarray, K, eps) -> float:
    """`turning_residual` from the rows of eq. (13); nan without rows."""
    if len(dm) == 0:
        return float("nan")
    theta = np.concatenate([np.asarray(K, dtype=float).reshape(-1, order="F"), np.asarray(eps, dtype=float)])
    return float(np.sqrt(np.mean((int_M.reshape(-1, 12) @ theta - dm.reshape(-1)) ** 2)))


def turning_misfit_ratio(session, K, eps, R, h, time_offset_s: float = 0.0, window_s: float = DEFAULT_WINDOW_S) -> float:
    """How much worse a calibration predicts the field's turning than the best linear fit (1 = as well).

    On BROAD trials 02 and 07 and simulated sessions every converged solve
    (both methods) stays within 1.12; a result that does not explain the
    recording (an EKF that lost track: 3.6 on fast shaking) is far above.
    Longer windows (`window_s`) let a wrong scale or bias grow above the
    magnetometer's noise (`magyro.result.check`).
    """
    field_m = calibrated_field(np.asarray(R), h, session.mag)
    rows = windowed_increments(session.t_gyro_s, session.gyro_rad_s, np.asarray(session.t_mag_s) - time_offset_s,
                               field_m, window_s)   # once: the best fit and the calibration's misfit on the same rows
    if len(rows[0]) == 0:   # every window crosses a hole: nothing to compare (the recording check names the holes)
        return 1.0
    best = estimate_from_increments(*rows, time_offset_s).residual
    return residual_of_increments(*rows, K, eps) / best if best > 0 else 1.0
