"""Step 1 of the paper's method: the magnetometer calibration (Wu & Pei eq. 2).

The algebraic ellipsoid fit (`magyro.front.ellipsoid.fit_ellipsoid`) starts
Gauss-Newton iterations on the constant-norm condition
r_k = |R (y_k - h)|^2 - 1 over R (upper triangular) and h
(`refine_magnetometer`). The plain least squares sum r_k^2 is biased at
O(noise^2) (the Jacobian and the residual share the noise), and when the
field covers only part of the sphere the bias is amplified: on paper-table1
it moves R33 and h_z by ~0.015, ten standard deviations. By default the
iterations solve the noise-corrected score instead (exact Gaussian moment
correction, consistent; derivation in docs/ekf.md). R and h are then
frozen: m^m = R (y_m - h) is the EKF's measurement (paper eq. 3).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from magyro.result.reported import UPPER

NEWTON_MAX_ITER = 50


@dataclass(frozen=True)
class MagnetometerRefinement:
    """Result of the Gauss-Newton iterations on the constant-norm condition."""

    R: np.ndarray                 # 3x3 upper triangular, positive diagonal
    h: np.ndarray                 # (3,) input unit
    covariance: np.ndarray        # 9x9 of [R upper (result.UPPER order), h]
    iterations: int
    bias_corrected: bool          # the corrected score (noise_std given) or the plain least squares
    cost: float                   # sum (|R (y - h)|^2 - 1)^2 at the solution
    cost_initial: float           # the same at the starting point (the ellipsoid fit)
    rms_norm_error: float         # RMS of |R (y - h)| - 1 at the solution
    rms_norm_error_initial: float


def known_magnetometer(R, h) -> MagnetometerRefinement:
    """A magnetometer calibration taken as exact (the paper's Table I simulation assumes one)."""
    R, h = np.asarray(R, dtype=float), np.asarray(h, dtype=float)
    return MagnetometerRefinement(R, h, np.zeros((9, 9)), 0, False, float("nan"), float("nan"), float("nan"), float("nan"))


def norm_terms(y: np.ndarray, R: np.ndarray, h: np.ndarray):
    """u = R (y - h), d = y - h, r = |u|^2 - 1 and J = dr/d[R upper, h] (rows per sample)."""
    d = y - h
    u = d @ R.T
    r = np.sum(u * u, axis=1) - 1.0
    J = np.empty((len(u), 9))
    for n, (i, j) in enumerate(UPPER):
        J[:, n] = 2.0 * u[:, i] * d[:, j]
    J[:, 6:] = -2.0 * (u @ R)
    return u, d, r, J


def score_correction(u, d, r, R, sigma: float) -> np.ndarray:
    """Per-sample noise part c_k of J_k^T r_k, in the noisy data, so that E[J^T r - c] is the noise-free score.

    With y = y0 + n, n ~ N(0, s^2 I), A = R R^T, a = R n, the expectations of
    the degree-4 polynomial J_k^T r_k are exact (Gaussian moments); the
    derivation is in docs/ekf.md.
    """
    s2 = sigma * sigma
    A = R @ R.T
    trA = float(np.trace(A))
    AR = A @ R
    Ru = u @ R        # (R^T u)_j
    Au = u @ A.T      # (A u)_i
    c = np.empty((len(u), 9))
    for n, (i, j) in enumerate(UPPER):
        c[:, n] = 2.0 * s2 * (trA * u[:, i] * d[:, j] + 2.0 * u[:, i] * Ru[:, j] + 2.0 * d[:, j] * Au[:, i] + R[i, j] * r) \
            - 2.0 * s2 * s2 * (trA * R[i, j] + 2.0 * AR[i, j])
    c[:, 6:] = -2.0 * s2 * (u @ (trA * np.eye(3) + 2.0 * A)) @ R
    return c


def refine_magnetometer(y_mag, R0, h0, noise_std: float | None = None, max_iter: int = NEWTON_MAX_ITER,
                        tol: float = 1e-12) -> MagnetometerRefinement:
    """Gauss-Newton iterations on the constant-norm condition |R (y - h)| = 1, from the ellipsoid (R0, h0).

    noise_std=None: the paper's step literally, min over R (upper triangular), h of
    sum_k (|R (y_k - h)|^2 - 1)^2. Its normal equations sum_k J_k^T r_k = 0
    are biased at O(noise^2) because J_k and r_k share the noise, and when the
    field directions cover only part of the sphere the bias is amplified along
    the weakly determined direction (on paper-table1 R33 and h_z move ~0.015,
    ten standard deviations).

    noise_std given (per-axis std, input unit): the same iterations on the
    corrected score sum_k (J_k^T r_k - c_k) = 0, where c_k removes the noise
    part of J_k^T r_k exactly (`score_correction`); the root is consistent.
    Steps are Gauss-Newton steps -(J^T J)^-1 g, halved while they raise |g|
    in the J^T J metric. Covariance: the sandwich (J^T J)^-1 V (J^T J)^-1, V
    the sum of the per-sample score outer products.
    """
    y = np.asarray(y_mag, dtype=float)
    R = np.triu(np.asarray(R0, dtype=float)).copy()
    h = np.asarray(h0, dtype=float).copy()
    sigma = None if noise_std is None else float(noise_std)

    def score(R, h):
        u, d, r, J = norm_terms(y, R, h)
        s = J * r[:, None]
        if sigma is not None:
            s = s - score_correction(u, d, r, R, sigma)
        H = J.T @ J
        g = s.sum(axis=0)
        return u, r, J, s, H, g

    u, r, J, s, H, g = score(R, h)
    cost0 = float(r @ r)
    rms0 = float(np.sqrt(np.mean((np.linalg.norm(u, axis=1) - 1.0) ** 2)))
    iterations = 0
    for iterations in range(1, max_iter + 1):
        try:
            step = -np.linalg.solve(H, g)
        except np.linalg.LinAlgError:
            break
        merit = float(g @ step)  # -g^T H^-1 g
        accepted = False
        for _ in range(30):
            R_new = R.copy()
            for n, (i, j) in enumerate(UPPER):
                R_new[i, j] += step[n]
            h_new = h + step[6:]
            new = score(R_new, h_new)
            g_new, H_new = new[5], new[4]
            if float(g_new @ np.linalg.solve(H_new, g_new)) <= -merit or np.max(np.abs(step)) < 1e-15:
                accepted = True
                break
            step = 0.5 * step
        if not accepted:
            break
        R, h = R_new, h_new
        u, r, J, s, H, g = new
        if np.max(np.abs(step[:6])) <= tol * np.max(np.abs(R)) and np.max(np.abs(step[6:])) <= tol * max(np.max(np.abs(h)), 1.0 / np.max(np.abs(R))):
            break
    signs = np.sign(np.diag(R))
    signs[signs == 0] = 1.0
    if np.any(signs < 0):  # a row's sign does not change |R (y - h)|
        R = signs[:, None] * R
        u, r, J, s, H, g = score(R, h)
    try:
        Hi = np.linalg.inv(H)
        cov = Hi @ (s.T @ s) @ Hi
    except np.linalg.LinAlgError:
        cov = np.full((9, 9), np.inf)
    rms = float(np.sqrt(np.mean((np.linalg.norm(u, axis=1) - 1.0) ** 2)))
    return MagnetometerRefinement(R, h, cov, iterations, sigma is not None, float(r @ r), cost0, rms, rms0)
