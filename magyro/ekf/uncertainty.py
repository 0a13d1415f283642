"""From the filter's covariance to the one-sigma of the reported parameters (K_g, bias, misalignment, R, h, m^i, the lag)."""
from __future__ import annotations

import numpy as np

from magyro.result.reported import UPPER, qr_split, reported_vector


def reported_covariance(K, eps, R, h, m_i, cov_in: np.ndarray, C_ref=None) -> np.ndarray:
    """Covariance of `result.reported_vector` from the covariance of x = [vec K (9), eps (3), R upper (6), h (3), m_i (3)].

    Central differences, as `magyro.nls.information.propagate` does for the joint least squares.
    """
    K, eps, R, h, m_i = (np.asarray(a, dtype=float) for a in (K, eps, R, h, m_i))
    if C_ref is None:
        C_ref, _ = qr_split(K)
    x0 = np.concatenate([K.reshape(-1, order="F"), eps, [R[i, j] for i, j in UPPER], h, m_i])

    def f(x):
        Rx = np.zeros((3, 3))
        for n, (i, j) in enumerate(UPPER):
            Rx[i, j] = x[12 + n]
        return reported_vector(x[:9].reshape(3, 3, order="F"), x[9:12], np.linalg.inv(Rx), x[18:21], x[21:24], C_ref)

    step = 1e-6
    n = len(x0)
    J = np.empty((len(f(x0)), n))
    for i in range(n):
        e = np.zeros(n)
        e[i] = step * max(1.0, abs(x0[i]))
        J[:, i] = (f(x0 + e) - f(x0 - e)) / (2 * e[i])
    return J @ cov_in @ J.T


def with_lag(cov_out: np.ndarray, lag_std_s: float, sensitivity: np.ndarray) -> np.ndarray:
    """The covariance of the reported vector given the lag, plus what the lag's own uncertainty adds (law of total
    covariance): var(lag) g g^T, g = d(reported vector)/d(lag) per second (its time_offset_s entry is 1)."""
    g = np.asarray(sensitivity, dtype=float)
    return cov_out + lag_std_s**2 * np.outer(g, g)
