"""The linear initial estimate of the gyro parameters (paper eq. 13).

Over each window [t_k, t_k+1] the change of the calibrated field equals the
integral of M times [vec K; eps]; stacking the windows gives an ordinary
least squares for the 12 parameters. It ignores the noise in M (errors in
variables), which is why the joint least squares refines it.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .excitation import windowed_increments

DEFAULT_WINDOW_S = 0.1


@dataclass(frozen=True)
class LinearGyroEstimate:
    K: np.ndarray      # 3x3, C_b^m K_g
    eps: np.ndarray    # (3,) rad/s, in the m frame
    rank: int          # rank of the stacked system
    windows: int


def linear_gyro_estimate(t_gyro_s, gyro_rad_s, t_mag_s, field_m, window_s: float = DEFAULT_WINDOW_S) -> LinearGyroEstimate:
    """Least-squares [vec K; eps] from eq. (13); minimum-norm when rank deficient."""
    dm, int_M = windowed_increments(t_gyro_s, gyro_rad_s, t_mag_s, field_m, window_s)
    A = int_M.reshape(-1, 12)
    b = dm.reshape(-1)
    theta, *_ , sv = np.linalg.lstsq(A, b, rcond=None)
    rank = int(np.sum(sv > sv[0] * 1e-9)) if sv.size else 0
    K = theta[:9].reshape(3, 3, order="F")
    return LinearGyroEstimate(K=K, eps=theta[9:].copy(), rank=rank, windows=len(dm))
