"""The paper's own method: two-step calibration with an error-state EKF (Wu & Pei, sections II-IV).

The full derivation, with the choices made where the paper is silent, is in
docs/ekf.md; this is its summary.

Step 1, magnetometer (paper eq. 2): the algebraic ellipsoid fit
(`ellipsoid.fit_ellipsoid`) starts Gauss-Newton iterations on the constant-norm
condition r_k = |R (y_k - h)|^2 - 1 over R (upper triangular) and h
(`refine_magnetometer`). The plain least squares sum r_k^2 is biased at
O(noise^2) (the Jacobian and the residual share the noise), and when the
field covers only part of the sphere the bias is amplified: on paper-table1
it moves R33 and h_z by ~0.015, ten standard deviations. By default the
iterations solve the noise-corrected score instead (exact Gaussian moment
correction, consistent). R and h are then frozen: m^m = R (y_m - h) is the
EKF's measurement (paper eq. 3).

Step 2, gyroscope (paper eq. 9): an error-state EKF started from the least
squares of eq. (13) (`initial.linear_gyro_estimate`, its covariance inflated
as the prior), attitude C_m^i = I and m^i = the first calibrated
magnetometer sample.

Nominal state: C = C_m^i, K (3x3), eps (3), m = m^i (unit vector).
Error state, 17 entries:

    phi  [0:3]   attitude, right perturbation: C_true = C Exp(phi)  (phi in the m frame)
    dK   [3:12]  vec(K_true - K), columns stacked (vec K = [K11 K21 K31 K12 ...])
    deps [12:15] eps_true - eps
    dm   [15:17] m_true = normalise(m + B dm), B a 3x2 orthonormal basis of the plane normal to m

(m^i has 2 degrees of freedom, so its error lives in the tangent plane: no
pseudo-measurement, no singular covariance.) Optionally 9 more *consider*
states [dR upper, dh] (Schmidt-Kalman): never updated, as in the paper's two
steps, but their covariance from step 1 flows into the gain and into the
covariance of K, eps and m^i.

Propagation. With w = K y_g + eps and w_true = K_true (y_g - n_g) + eps_true
(n_g white, density sigma_g rad/s/sqrt(Hz)):

    dphi/dt = -(w x) phi + (y_g^T (x) I3) vec(dK) + deps - K n_g.

Over a gyro interval [t_a, t_b] the nominal attitude goes C <- C Exp(theta),
theta = (w_a + w_b)/2 dt + dt^2/12 (w_a x w_b) (as `so3.integrate_body_rates`),
and

    phi_b = Exp(theta)^T phi_a + dt Jr(theta) [(ybar^T (x) I3) dK + deps] + noise,
    ybar = (y_a + y_b)/2,  Jr(theta) ~ I - (theta x)/2,  cov(noise) = sigma_g^2 dt K K^T.

Measurement (paper eq. 7), at each magnetometer sample:

    z = R (y_m - h) = C_true^T m_true + n,   cov(n) = sigma_m^2 R R^T,
    z ~ C^T m + (C^T m x) phi + C^T B dm [ - dR (y_m - h) + R dh ],

H = [(zhat x), 0_{3x12}, C^T B (, consider block at the predicted reading)].
After the update the error is injected: C <- C Exp(dphi), K += dK, eps +=
deps, m <- normalise(m + B dm), and B is carried to the new m by
Gram-Schmidt (B_new^T B_old = I + O(dm^2)).

Asynchronous sensors: the filter propagates from gyro sample to gyro sample;
a magnetometer sample at t_m inside [t_a, t_b] splits the interval (gyro
reading linearly interpolated at t_m): propagate to t_m, update, propagate
on. The filter starts at the first magnetometer sample at or after the first
gyro sample, with C = I and zero attitude covariance: the paper's choice of
the inertial frame, which makes the state observable.

Output: `ekf_calibrate(session, options) -> (Calibration, EkfHistory)`, the
same Calibration as the joint least squares (solver.method = "ekf"), std from
the final covariance of [vec K, eps, R, h, m^i] through `result.reported_vector`
(central differences, like `calibrate.propagate`). `StreamingCalibrator` is
the filter itself, fed sample by sample; `plot_history` draws the paper's
Fig. 3/6/7.
"""
from __future__ import annotations

import math
import os
import tempfile
import time
from collections import deque
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from magyro.front import ellipsoid
from magyro.errors import InputError
from magyro.observability.matrix import windowed_increments
from magyro.front.initial import DEFAULT_WINDOW_S, linear_gyro_estimate
from magyro.result.calibration import UPPER, Calibration, qr_split, reported_vector, std_from_covariance
from magyro.session import Session

N_STATE = 17
IA, IK, IE, IM = slice(0, 3), slice(3, 12), slice(12, 15), slice(15, 17)
PRIOR_INFLATION = 10.0          # the eq. (13) std is multiplied by this for the filter's prior
PRIOR_FLOOR_K = 1e-3            # smallest prior std of a K entry
PRIOR_FLOOR_EPS = np.deg2rad(0.05)  # smallest prior std of an eps entry, rad/s
HISTORY_ROWS = 2000
REORTHONORMALISE_EVERY = 1000   # propagation steps between re-orthonormalisations of C
REFRESH_NOISE_EVERY = 16        # updates between recomputations of sigma_g^2 K K^T (K barely moves)
NEWTON_MAX_ITER = 50
AXES = "xyz"
K_NAMES = [f"K{i + 1}{j + 1}" for i in range(3) for j in range(3)]   # row-major, like the paper's Fig. 3
BIAS_NAMES = [f"bias_{a}_deg_s" for a in AXES]
FIELD_NAMES = [f"m_i_{a}" for a in AXES]
HISTORY_COLUMNS = ["t_s", *K_NAMES, *BIAS_NAMES, *FIELD_NAMES,
                   *(n + "_std" for n in K_NAMES + BIAS_NAMES + FIELD_NAMES)]


# --------------------------------------------------------------------------- step 1: the magnetometer


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

    @property
    def std_R(self) -> np.ndarray:
        sd = np.sqrt(np.maximum(np.diag(self.covariance), 0.0))
        out = np.zeros((3, 3))
        for n, (i, j) in enumerate(UPPER):
            out[i, j] = sd[n]
        return out

    @property
    def std_h(self) -> np.ndarray:
        return np.sqrt(np.maximum(np.diag(self.covariance)[6:], 0.0))


def _norm_terms(y: np.ndarray, R: np.ndarray, h: np.ndarray):
    """u = R (y - h), d = y - h, r = |u|^2 - 1 and J = dr/d[R upper, h] (rows per sample)."""
    d = y - h
    u = d @ R.T
    r = np.sum(u * u, axis=1) - 1.0
    J = np.empty((len(u), 9))
    for n, (i, j) in enumerate(UPPER):
        J[:, n] = 2.0 * u[:, i] * d[:, j]
    J[:, 6:] = -2.0 * (u @ R)
    return u, d, r, J


def _score_correction(u, d, r, R, sigma: float) -> np.ndarray:
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
    part of J_k^T r_k exactly (`_score_correction`); the root is consistent.
    Steps are Gauss-Newton steps -(J^T J)^-1 g, halved while they raise |g|
    in the J^T J metric. Covariance: the sandwich (J^T J)^-1 V (J^T J)^-1, V
    the sum of the per-sample score outer products.
    """
    y = np.asarray(y_mag, dtype=float)
    R = np.triu(np.asarray(R0, dtype=float)).copy()
    h = np.asarray(h0, dtype=float).copy()
    sigma = None if noise_std is None else float(noise_std)

    def score(R, h):
        u, d, r, J = _norm_terms(y, R, h)
        s = J * r[:, None]
        if sigma is not None:
            s = s - _score_correction(u, d, r, R, sigma)
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


# --------------------------------------------------------------------------- small fast helpers
# The filter runs once per sample in Python: 3-vectors and 3x3 blocks are done
# in scalar arithmetic (a numpy call costs more than the arithmetic itself).


def _rodrigues(x: float, y: float, z: float) -> tuple:
    """Exp of one rotation vector as a row-major 9-tuple."""
    th2 = x * x + y * y + z * z
    if th2 < 1e-12:
        a, b = 1.0 - th2 / 6.0, 0.5 - th2 / 24.0
    else:
        th = math.sqrt(th2)
        a, b = math.sin(th) / th, (1.0 - math.cos(th)) / th2
    bxy, bxz, byz = b * x * y, b * x * z, b * y * z
    return (1.0 - b * (y * y + z * z), bxy - a * z, bxz + a * y,
            bxy + a * z, 1.0 - b * (x * x + z * z), byz - a * x,
            bxz - a * y, byz + a * x, 1.0 - b * (x * x + y * y))


def _mul33(A, B) -> tuple:
    """Product of two row-major 9-tuples."""
    a11, a12, a13, a21, a22, a23, a31, a32, a33 = A
    b11, b12, b13, b21, b22, b23, b31, b32, b33 = B
    return (a11 * b11 + a12 * b21 + a13 * b31, a11 * b12 + a12 * b22 + a13 * b32, a11 * b13 + a12 * b23 + a13 * b33,
            a21 * b11 + a22 * b21 + a23 * b31, a21 * b12 + a22 * b22 + a23 * b32, a21 * b13 + a22 * b23 + a23 * b33,
            a31 * b11 + a32 * b21 + a33 * b31, a31 * b12 + a32 * b22 + a33 * b32, a31 * b13 + a32 * b23 + a33 * b33)


def _inv3(S: np.ndarray) -> tuple:
    """Inverse of a symmetric positive definite 3x3 (cofactors): (its 6 distinct entries, the matrix)."""
    (a, b, c), (_, e, f), (_, _, i) = S.tolist()
    A, B, C = e * i - f * f, c * f - b * i, b * f - c * e
    k = 1.0 / (a * A + b * B + c * C)
    A, B, C, E, F, I = A * k, B * k, C * k, (a * i - c * c) * k, (b * c - a * f) * k, (a * e - b * b) * k
    return (A, B, C, E, F, I), np.array([[A, B, C], [B, E, F], [C, F, I]])


def tangent_basis(m: np.ndarray) -> np.ndarray:
    """3x2 orthonormal basis of the plane normal to the unit vector m."""
    a = np.zeros(3)
    a[int(np.argmin(np.abs(m)))] = 1.0
    b1 = np.cross(m, a)
    b1 /= np.linalg.norm(b1)
    return np.column_stack([b1, np.cross(m, b1)])


def _carry_basis(B, m) -> np.ndarray:
    """The basis B moved to the plane normal to the unit vector m, staying closest to B (Gram-Schmidt).

    B_new^T B_old = I + O(|dm|^2), so the tangent coordinates need no reset to first order.
    """
    (p1, q1), (p2, q2), (p3, q3) = B.tolist()
    m1, m2, m3 = m
    k = m1 * p1 + m2 * p2 + m3 * p3
    a1, a2, a3 = p1 - k * m1, p2 - k * m2, p3 - k * m3
    n = 1.0 / math.sqrt(a1 * a1 + a2 * a2 + a3 * a3)
    a1, a2, a3 = a1 * n, a2 * n, a3 * n
    k = m1 * q1 + m2 * q2 + m3 * q3
    l = a1 * q1 + a2 * q2 + a3 * q3
    b1, b2, b3 = q1 - k * m1 - l * a1, q2 - k * m2 - l * a2, q3 - k * m3 - l * a3
    n = 1.0 / math.sqrt(b1 * b1 + b2 * b2 + b3 * b3)
    return np.array([[a1, b1 * n], [a2, b2 * n], [a3, b3 * n]])


def _orthonormalise(C: np.ndarray) -> np.ndarray:
    U, _, Vt = np.linalg.svd(C)
    return U @ Vt


# --------------------------------------------------------------------------- uncertainty of the reported parameters


def reported_covariance(K, eps, R, h, m_i, cov_in: np.ndarray, C_ref=None) -> np.ndarray:
    """Covariance of `result.reported_vector` from the covariance of x = [vec K (9), eps (3), R upper (6), h (3), m_i (3)].

    Central differences, as `calibrate.propagate` does for the joint least squares.
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


# --------------------------------------------------------------------------- history


@dataclass
class EkfHistory:
    """Estimates and their 1-sigma over time (the paper's Fig. 3, 6, 7), subsampled.

    Arrays, one row per recorded instant: t_s (N,), K (N,3,3), eps_m_rad_s (N,3),
    m_i (N,3), cov_theta (N,12,12) of [vec K, eps], m_i_std (N,3).
    """

    t_s: np.ndarray
    K: np.ndarray
    eps_m_rad_s: np.ndarray
    m_i: np.ndarray
    cov_theta: np.ndarray
    m_i_std: np.ndarray

    def __len__(self) -> int:
        return len(self.t_s)

    @property
    def K_std(self) -> np.ndarray:
        """(N,3,3) one-sigma of K's entries."""
        sd = np.sqrt(np.maximum(np.diagonal(self.cov_theta, axis1=1, axis2=2)[:, :9], 0.0))
        return sd.reshape(-1, 3, 3).transpose(0, 2, 1)  # vec is column-major

    def bias(self) -> tuple[np.ndarray, np.ndarray]:
        """(eps_b deg/s (N,3), its one-sigma (N,3)), eps_b = C_b_m^T eps through the QR split of K.

        The std uses the QR differential: with K = Q U, X = Q^T dK U^-1, the
        rotation change is dQ = Q (w x), w = (X32, -X31, X21) (strict lower
        part of X), and d eps_b = Q^T d eps + eps_b x w.
        """
        Q, U = np.linalg.qr(self.K)
        D = np.sign(np.diagonal(U, axis1=1, axis2=2))
        D[D == 0] = 1.0
        Q = Q * D[:, None, :]
        U = D[:, :, None] * U
        Ui = np.linalg.inv(U)
        eps_b = np.einsum("nji,nj->ni", Q, self.eps_m_rad_s)
        J = np.empty((len(self.t_s), 3, 12))
        for j in range(3):
            for i in range(3):
                w = np.stack([Q[:, i, 2] * Ui[:, j, 1], -Q[:, i, 2] * Ui[:, j, 0], Q[:, i, 1] * Ui[:, j, 0]], axis=1)
                J[:, :, 3 * j + i] = np.cross(eps_b, w)
        J[:, :, 9:] = Q.transpose(0, 2, 1)
        cov = np.einsum("nak,nkl,nbl->nab", J, self.cov_theta, J)
        sd = np.sqrt(np.maximum(np.diagonal(cov, axis1=1, axis2=2), 0.0))
        return np.rad2deg(eps_b), np.rad2deg(sd)

    def to_frame(self):
        """pandas DataFrame: t_s, K11..K33 (row-major), bias_{x,y,z}_deg_s, m_i_{x,y,z} and each `_std`."""
        import pandas as pd

        bias, bias_sd = self.bias()
        cols = {"t_s": self.t_s}
        K, Ks = self.K.reshape(-1, 9), self.K_std.reshape(-1, 9)
        for n, name in enumerate(K_NAMES):
            cols[name] = K[:, n]
        for n, name in enumerate(BIAS_NAMES):
            cols[name] = bias[:, n]
        for n, name in enumerate(FIELD_NAMES):
            cols[name] = self.m_i[:, n]
        for n, name in enumerate(K_NAMES):
            cols[name + "_std"] = Ks[:, n]
        for n, name in enumerate(BIAS_NAMES):
            cols[name + "_std"] = bias_sd[:, n]
        for n, name in enumerate(FIELD_NAMES):
            cols[name + "_std"] = self.m_i_std[:, n]
        return pd.DataFrame(cols, columns=HISTORY_COLUMNS)

    def write_parquet(self, path) -> None:
        """Write to_frame() as Parquet, whole or not at all."""
        frame = self.to_frame()
        _write_atomically(path, lambda tmp: frame.to_parquet(tmp, index=False))


def plot_history(history: EkfHistory, path, title: str | None = None) -> None:
    """Figure like the paper's Fig. 3/6/7: K entries, gyro bias and m^i over time, +/- 3 sigma bands."""
    try:
        from matplotlib.figure import Figure
    except ImportError:
        raise InputError("plotting needs matplotlib: pip install 'magyro[plot]'") from None
    df = history.to_frame()
    t = df["t_s"].to_numpy()
    fig = Figure(figsize=(15, 4.5), constrained_layout=True)
    axes = fig.subplots(1, 3)
    panels = [
        (axes[0], K_NAMES, "matrix K"),
        (axes[1], BIAS_NAMES, "gyro bias eps_b (deg/s)"),
        (axes[2], FIELD_NAMES, "local magnetic vector m^i"),
    ]
    for ax, names, label in panels:
        for n, name in enumerate(names):
            v, s = df[name].to_numpy(), df[name + "_std"].to_numpy()
            line, = ax.plot(t, v, lw=1.0, label=name.replace("_deg_s", ""))
            ax.fill_between(t, v - 3 * s, v + 3 * s, color=line.get_color(), alpha=0.2, lw=0)
        ax.set_title(label)
        ax.set_xlabel("time (s)")
        ax.grid(True, alpha=0.3)
        ax.legend(fontsize=7, ncol=3 if len(names) > 3 else 1, loc="best")
    # +/-3 sigma of a barely excited parameter can dwarf the estimates: zoom to the settled part
    for ax, names, _ in panels:
        v = df[list(names)].to_numpy()
        s = df[[n + "_std" for n in names]].to_numpy()
        settled = len(t) // 10  # the first tenth may hold the wide prior bands
        lo = np.min(v[settled:] - 3 * s[settled:])
        hi = np.max(v[settled:] + 3 * s[settled:])
        pad = 0.15 * max(hi - lo, 1e-9)
        ax.set_ylim(lo - pad, hi + pad)
    fig.suptitle(title or "EKF estimates with +/- 3 sigma bands")
    _write_atomically(path, lambda tmp: fig.savefig(tmp, dpi=120, format=Path(path).suffix.lstrip(".") or "png"))


def _write_atomically(path, write) -> None:
    """write(tmp) then rename over path: the file is written whole or not at all."""
    path = Path(path)
    fd, tmp = tempfile.mkstemp(prefix=path.name + ".", suffix=".tmp", dir=path.parent)
    os.close(fd)
    try:
        write(tmp)
        os.replace(tmp, path)
    except BaseException:
        if os.path.exists(tmp):
            os.unlink(tmp)
        raise


# --------------------------------------------------------------------------- the filter


class StreamingCalibrator:
    """The error-state EKF of paper eq. (9), fed one sample at a time.

    Each sensor's samples must come in increasing time. The filter
    propagates with every gyro sample and updates with every magnetometer
    sample; a magnetometer sample later than the last gyro sample processed
    waits until the next gyro sample brackets it, so `estimate()` reflects the
    samples up to the last gyro sample processed. Magnetometer samples older
    than that (or before the first gyro sample) are skipped (counted in
    `skipped_mag`): feed the two sensors merged by timestamp, or set
    latency_s to hold gyro samples back by that much so that magnetometer
    samples arriving up to latency_s late still count (call `flush()` at the
    end of the stream).

    The inertial frame is the magnetometer frame at the first magnetometer
    sample used (C_m^i = I there). With m0=None that sample also gives m^i;
    otherwise m0 (with std m0_std, rad) is the prior and the sample is an
    ordinary update.

    R, h: the step-1 magnetometer calibration; K0 (3x3) and eps0 (3,) rad/s
    in the m frame: the starting gyro parameters; P0: 12x12 covariance of
    [vec K (columns stacked), eps] (default: 0.05 on K entries, 1 deg/s on
    eps). cov_Rh: 9x9 covariance of [R upper, h] from step 1; when given, R
    and h are *consider* states (Schmidt-Kalman): never updated (the paper's
    two steps), but their uncertainty flows into the covariance of K, eps and
    m^i, so the reported std includes step 1's error.
    """

    def __init__(self, R, h, K0, eps0, m0=None, gyro_noise_density_rad_s_sqrt_hz: float = 0.0,
                 mag_noise_std: float = 0.0, *, P0=None, cov_Rh=None, m0_std: float = 0.1,
                 history_stride: int | None = None, latency_s: float = 0.0):
        if not (gyro_noise_density_rad_s_sqrt_hz > 0 and mag_noise_std > 0):
            raise InputError("the EKF needs a positive gyro noise density and magnetometer noise std")
        self.R = np.array(R, dtype=float)
        self.h = np.array(h, dtype=float)
        # the nominal state lives in Python floats (row-major tuples/lists): see "small fast helpers"
        self._K = np.asarray(K0, dtype=float).reshape(-1).tolist()
        self._eps = np.asarray(eps0, dtype=float).reshape(-1).tolist()
        self._C = (1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0)
        self._m = [0.0, 0.0, 0.0]
        self._B = np.zeros((3, 2))
        self.sigma_g2 = float(gyro_noise_density_rad_s_sqrt_hz) ** 2
        self.mag_noise_std = float(mag_noise_std)
        self.Rn = self.mag_noise_std**2 * (self.R @ self.R.T)
        self.consider = cov_Rh is not None
        n = N_STATE + (9 if self.consider else 0)
        self.n = n
        self.P = np.zeros((n, n))
        if P0 is None:
            P0 = np.diag(np.concatenate([np.full(9, 0.05**2), np.full(3, np.deg2rad(1.0) ** 2)]))
        self.P[3:15, 3:15] = np.asarray(P0, dtype=float)
        if self.consider:
            self.P[N_STATE:, N_STATE:] = np.asarray(cov_Rh, dtype=float)
        self._Hc_h = self.R.tolist()   # dz/dh rows
        self._Sinv = np.linalg.inv(self.R).reshape(-1).tolist()   # R^-1, upper triangular, row-major
        self._zeros12 = [0.0] * 12
        self._refresh_noise()
        self.m_prior = None if m0 is None else np.asarray(m0, dtype=float) / np.linalg.norm(m0)
        self.m0_std = float(m0_std)
        self.started = False
        self.t = None              # the filter's time (the last gyro time once started)
        self.y = None              # gyro reading at the filter's time, tuple
        self.t_gyro = None         # last gyro sample processed
        self.y_gyro = None
        self.t_gyro_fed = None     # last gyro sample fed (processed or buffered)
        self.latency_s = float(latency_s)
        self._gyro_buffer: deque = deque()
        self.t_last_mag = None
        self.pending: list[tuple[float, np.ndarray, list]] = []
        self.t0 = None
        self.gyro_samples = 0
        self.mag_updates = 0
        self.skipped_mag = 0
        self.nis_sum = 0.0
        self._steps = 0
        self.history_stride = history_stride
        self._rows: list[tuple] = []

    # ---- the nominal state as arrays

    @property
    def K(self) -> np.ndarray:
        return np.array(self._K).reshape(3, 3)

    @property
    def eps(self) -> np.ndarray:
        return np.array(self._eps)

    @property
    def C(self) -> np.ndarray:
        """C_m^i, the attitude of the magnetometer frame in the inertial frame."""
        return np.array(self._C).reshape(3, 3)

    @property
    def m(self) -> np.ndarray:
        return np.array(self._m)

    @property
    def B(self) -> np.ndarray:
        return self._B.copy()

    def _refresh_noise(self) -> None:
        """sigma_g^2 K K^T, the gyro noise on the attitude rate (recomputed when K changes)."""
        K = np.array(self._K).reshape(3, 3)
        self._Qc = self.sigma_g2 * (K @ K.T)

    # ---- feeding

    def add_gyro(self, t_s: float, y_rad_s) -> None:
        """One raw gyro sample (rad/s) stamped t_s.

        With latency_s > 0 the sample waits in a buffer until a gyro sample
        latency_s newer arrives (or `flush()`), so magnetometer samples that
        arrive up to latency_s late still land in their place.
        """
        t = float(t_s)
        y = tuple(np.asarray(y_rad_s, dtype=float).tolist())
        if self.t_gyro_fed is not None and not t > self.t_gyro_fed:
            raise InputError(f"gyro samples must come in increasing time: {t} after {self.t_gyro_fed}")
        self.t_gyro_fed = t
        if self.latency_s <= 0.0:
            self._process_gyro(t, y)
            return
        buf = self._gyro_buffer
        buf.append((t, y))
        limit = t - self.latency_s
        while buf and buf[0][0] <= limit:
            self._process_gyro(*buf.popleft())

    def flush(self) -> None:
        """Process every buffered gyro sample (the end of a stream with latency_s > 0)."""
        buf = self._gyro_buffer
        while buf:
            self._process_gyro(*buf.popleft())

    def _process_gyro(self, t: float, y: tuple) -> None:
        if self.pending:
            ta, ya = self.t_gyro, self.y_gyro
            keep = []
            for item in self.pending:
                tm = item[0]
                if tm > t:
                    keep.append(item)
                elif ta is None:                   # before the first gyro sample: nothing to propagate with
                    if tm == t:
                        self._measure(tm, y, item[1], item[2])
                    else:
                        self.skipped_mag += 1
                else:
                    if tm == t:
                        ym = y
                    else:
                        f = (tm - ta) / (t - ta)
                        ym = (ya[0] + (y[0] - ya[0]) * f, ya[1] + (y[1] - ya[1]) * f, ya[2] + (y[2] - ya[2]) * f)
                    if self.started:
                        self._propagate(tm, ym)
                    self._measure(tm, ym, item[1], item[2])
            self.pending = keep
        if self.started:
            self._propagate(t, y)
            self.gyro_samples += 1
        self.t_gyro, self.y_gyro = t, y

    def add_mag(self, t_s: float, y_mag) -> None:
        """One raw magnetometer sample (input unit) stamped t_s."""
        t = float(t_s)
        if self.t_last_mag is not None and not t > self.t_last_mag:
            raise InputError(f"magnetometer samples must come in increasing time: {t} after {self.t_last_mag}")
        self.t_last_mag = t
        if self.t_gyro is not None and t < self.t_gyro:
            self.skipped_mag += 1              # older than the filter's time: too late
            return
        d = np.asarray(y_mag, dtype=float) - self.h
        z = self.R @ d
        if t == self.t_gyro:
            self._measure(t, self.y_gyro, z, d.tolist())
        else:
            self.pending.append((t, z, d.tolist()))

    def _measure(self, t: float, y, z: np.ndarray, d: list) -> None:
        if self.started:
            self._update(z, d)
        else:
            self._start(t, y, z, d)

    def _consider_jacobian(self, d) -> np.ndarray:
        """dz/d[R upper, h] for z = R (y - h): -e_i d_j for R_ij and R for h (errors are true - nominal)."""
        Hc = np.zeros((3, 9))
        for n, (i, j) in enumerate(UPPER):
            Hc[i, n] = -d[j]
        Hc[:, 6:] = self.R
        return Hc

    def _start(self, t: float, y, z: np.ndarray, d: list) -> None:
        self.started = True
        self.t = self.t0 = t
        self.y = y
        if self.m_prior is None:
            nz = float(np.linalg.norm(z))
            m = z / nz
            self._m = m.tolist()
            self._B = tangent_basis(m)
            B = self._B
            self.P[IM, IM] = B.T @ self.Rn @ B / nz**2
            if self.consider:
                # m = z / |z| with z = R (y - h): the field prior shares step 1's error
                cross = -(B.T @ self._consider_jacobian(d) @ self.P[N_STATE:, N_STATE:]) / nz
                self.P[IM, N_STATE:] = cross
                self.P[N_STATE:, IM] = cross.T
            self._record()
        else:
            self._m = self.m_prior.tolist()
            self._B = tangent_basis(self.m_prior)
            self.P[IM, IM] = np.eye(2) * self.m0_std**2
            self._record()
            self._update(z, d)

    # ---- the filter

    def _propagate(self, t_b: float, y_b) -> None:
        """Nominal attitude and covariance from the filter's time to t_b (gyro reading y_b there)."""
        dt = t_b - self.t
        if dt <= 0.0:
            return
        k11, k12, k13, k21, k22, k23, k31, k32, k33 = self._K
        e1, e2, e3 = self._eps
        p1, p2, p3 = self.y
        q1, q2, q3 = y_b
        a1 = k11 * p1 + k12 * p2 + k13 * p3 + e1
        a2 = k21 * p1 + k22 * p2 + k23 * p3 + e2
        a3 = k31 * p1 + k32 * p2 + k33 * p3 + e3
        b1 = k11 * q1 + k12 * q2 + k13 * q3 + e1
        b2 = k21 * q1 + k22 * q2 + k23 * q3 + e2
        b3 = k31 * q1 + k32 * q2 + k33 * q3 + e3
        c = dt * dt / 12.0
        h = 0.5 * dt
        x = (a1 + b1) * h + c * (a2 * b3 - a3 * b2)
        y = (a2 + b2) * h + c * (a3 * b1 - a1 * b3)
        z = (a3 + b3) * h + c * (a1 * b2 - a2 * b1)
        E = _rodrigues(x, y, z)
        self._C = _mul33(self._C, E)
        # F rows 0:3 = [Exp(theta)^T, ybar_1 Gamma, ybar_2 Gamma, ybar_3 Gamma, Gamma], Gamma = dt I - (dt/2) (theta x)
        g = (dt, h * z, -h * y, -h * z, dt, h * x, h * y, -h * x, dt)
        u1, u2, u3 = 0.5 * (p1 + q1), 0.5 * (p2 + q2), 0.5 * (p3 + q3)
        Fa = np.array([
            [E[0], E[3], E[6], u1 * g[0], u1 * g[1], u1 * g[2], u2 * g[0], u2 * g[1], u2 * g[2], u3 * g[0], u3 * g[1], u3 * g[2], g[0], g[1], g[2]],
            [E[1], E[4], E[7], u1 * g[3], u1 * g[4], u1 * g[5], u2 * g[3], u2 * g[4], u2 * g[5], u3 * g[3], u3 * g[4], u3 * g[5], g[3], g[4], g[5]],
            [E[2], E[5], E[8], u1 * g[6], u1 * g[7], u1 * g[8], u2 * g[6], u2 * g[7], u2 * g[8], u3 * g[6], u3 * g[7], u3 * g[8], g[6], g[7], g[8]],
        ])
        P = self.P
        X = Fa @ P[:15]                              # rows 0:3 of F P (F is I below row 3; m, consider columns of F are 0)
        P[0:3, 3:] = X[:, 3:]
        P[3:, 0:3] = X[:, 3:].T
        P[0:3, 0:3] = X[:, :15] @ Fa.T + dt * self._Qc
        self.t, self.y = t_b, y_b
        self._steps += 1
        if self._steps % REORTHONORMALISE_EVERY == 0:
            self._C = tuple(_orthonormalise(np.array(self._C).reshape(3, 3)).reshape(-1).tolist())
            self.P = 0.5 * (P + P.T)

    def measurement_jacobian(self) -> tuple[tuple, np.ndarray]:
        """(zhat = C^T m as a 3-tuple, H (3 x n)) at the current state."""
        c11, c12, c13, c21, c22, c23, c31, c32, c33 = self._C
        m1, m2, m3 = self._m
        B = self._B
        (r1, s1), (r2, s2), (r3, s3) = B.tolist()
        # zhat = C^T m, H_m = C^T B
        z1 = c11 * m1 + c21 * m2 + c31 * m3
        z2 = c12 * m1 + c22 * m2 + c32 * m3
        z3 = c13 * m1 + c23 * m2 + c33 * m3
        hb11, hb12 = c11 * r1 + c21 * r2 + c31 * r3, c11 * s1 + c21 * s2 + c31 * s3
        hb21, hb22 = c12 * r1 + c22 * r2 + c32 * r3, c12 * s1 + c22 * s2 + c32 * s3
        hb31, hb32 = c13 * r1 + c23 * r2 + c33 * r3, c13 * s1 + c23 * s2 + c33 * s3
        o = self._zeros12
        if self.consider:
            # dz/dR at the *predicted* raw reading R^-1 zhat: the measured y_m - h carries the
            # noise that is also in the innovation, and a gain built from it would be biased
            S_ = self._Sinv
            d1 = S_[0] * z1 + S_[1] * z2 + S_[2] * z3
            d2 = S_[4] * z2 + S_[5] * z3
            d3 = S_[8] * z3
            hh = self._Hc_h
            # consider columns: R upper in UPPER order (00, 01, 02, 11, 12, 22), then h
            H = np.array([
                [0.0, -z3, z2, *o, hb11, hb12, -d1, -d2, -d3, 0.0, 0.0, 0.0, *hh[0]],
                [z3, 0.0, -z1, *o, hb21, hb22, 0.0, 0.0, 0.0, -d2, -d3, 0.0, *hh[1]],
                [-z2, z1, 0.0, *o, hb31, hb32, 0.0, 0.0, 0.0, 0.0, 0.0, -d3, *hh[2]],
            ])
        else:
            H = np.array([
                [0.0, -z3, z2, *o, hb11, hb12],
                [z3, 0.0, -z1, *o, hb21, hb22],
                [-z2, z1, 0.0, *o, hb31, hb32],
            ])
        return (z1, z2, z3), H

    def _update(self, z: np.ndarray, d: list) -> None:
        """EKF update with one calibrated magnetometer sample z = R (y_m - h); inject the correction."""
        (z1, z2, z3), H = self.measurement_jacobian()
        m1, m2, m3 = self._m
        B = self._B
        (r1, s1), (r2, s2), (r3, s3) = B.tolist()
        P = self.P
        PHt = P @ H.T                                      # (n, 3)
        S = H @ PHt + self.Rn
        (A, Bs, Cs, E, F, I), Si = _inv3(S)
        Wa = PHt[:N_STATE] @ Si                            # gain of the estimated states (consider states get none)
        zz = z.tolist()
        v1, v2, v3 = zz[0] - z1, zz[1] - z2, zz[2] - z3
        nu = (v1, v2, v3)
        self.nis_sum += A * v1 * v1 + E * v2 * v2 + I * v3 * v3 + 2.0 * (Bs * v1 * v2 + Cs * v1 * v3 + F * v2 * v3)
        dx = (Wa @ nu).tolist()
        P[:N_STATE] -= Wa @ PHt.T
        if self.consider:
            P[N_STATE:, :N_STATE] = P[:N_STATE, N_STATE:].T
        # inject. The reset Jacobians differ from I by O(|dx|) for the attitude (I - (dphi x)/2,
        # |dphi| ~ 1e-3 rad) and by O(|dm|^2) for the field basis: both are left out.
        self._C = _mul33(self._C, _rodrigues(dx[0], dx[1], dx[2]))
        K = self._K
        # dK is vec (column-major): dx[3 + 3j + i] is K[i][j]; K is stored row-major (K[3i + j])
        for j in range(3):
            for i in range(3):
                K[3 * i + j] += dx[3 + 3 * j + i]
        e = self._eps
        e[0] += dx[12]
        e[1] += dx[13]
        e[2] += dx[14]
        u, v = dx[15], dx[16]
        n1, n2, n3 = m1 + r1 * u + s1 * v, m2 + r2 * u + s2 * v, m3 + r3 * u + s3 * v
        k = 1.0 / math.sqrt(n1 * n1 + n2 * n2 + n3 * n3)
        self._m = [n1 * k, n2 * k, n3 * k]
        self._B = _carry_basis(B, self._m)
        self.mag_updates += 1
        if self.mag_updates % REFRESH_NOISE_EVERY == 0:
            self._refresh_noise()
        if self.history_stride and self.mag_updates % self.history_stride == 0:
            self._record()

    # ---- reading

    def _record(self) -> None:
        if self.history_stride is None:
            return
        if self._rows and self._rows[-1][0] == self.t:
            self._rows.pop()
        P = 0.5 * (self.P + self.P.T)
        cov_m = self.B @ P[IM, IM] @ self.B.T
        self._rows.append((self.t, self.K.copy(), self.eps.copy(), self.m.copy(), P[3:15, 3:15].copy(),
                           np.sqrt(np.maximum(np.diag(cov_m), 0.0))))

    def history(self) -> EkfHistory:
        """The recorded estimates (needs history_stride), with the current state as the last row."""
        if self.history_stride is None:
            raise ValueError("history was not recorded: pass history_stride")
        if self.started:
            self._record()
        rows = self._rows
        if not rows:
            return EkfHistory(np.zeros(0), np.zeros((0, 3, 3)), np.zeros((0, 3)), np.zeros((0, 3)),
                              np.zeros((0, 12, 12)), np.zeros((0, 3)))
        return EkfHistory(
            t_s=np.array([r[0] for r in rows]), K=np.stack([r[1] for r in rows]),
            eps_m_rad_s=np.stack([r[2] for r in rows]), m_i=np.stack([r[3] for r in rows]),
            cov_theta=np.stack([r[4] for r in rows]), m_i_std=np.stack([r[5] for r in rows]),
        )

    @property
    def covariance(self) -> np.ndarray:
        """The full error-state covariance (17x17, or 26x26 with the consider states), symmetrised."""
        return 0.5 * (self.P + self.P.T)

    @property
    def covariance_theta(self) -> np.ndarray:
        """12x12 covariance of [vec K (columns stacked), eps]."""
        return self.covariance[3:15, 3:15]

    @property
    def field_covariance(self) -> np.ndarray:
        """3x3 covariance of m^i (rank 2, in the plane normal to m^i)."""
        return self.B @ self.covariance[IM, IM] @ self.B.T

    def input_covariance(self, cov_Rh: np.ndarray | None = None) -> np.ndarray:
        """24x24 covariance of [vec K, eps, R upper, h, m_i].

        The R, h block and its cross terms come from the consider states when
        the filter carries them, else from cov_Rh (uncorrelated), else zero.
        """
        P = self.covariance
        T = np.zeros((24, self.n))        # x = T (error state)
        T[:12, 3:15] = np.eye(12)
        T[21:, IM] = self.B
        if self.consider:
            T[12:21, N_STATE:] = np.eye(9)
        cov = T @ P @ T.T
        if not self.consider and cov_Rh is not None:
            cov[12:21, 12:21] = cov_Rh
        return cov

    def estimate(self) -> dict:
        """The current estimate: K, K_g, bias, C_b_m, Euler angles, m^i, and one-sigma of each."""
        from magyro.so3 import dcm_to_euler

        C, Kg = qr_split(self.K)
        cov = reported_covariance(self.K, self.eps, self.R, self.h, self.m, self.input_covariance(), C)
        std = std_from_covariance(cov)
        return {
            "t_s": self.t,
            "started": self.started,
            "gyro_samples": self.gyro_samples,
            "mag_updates": self.mag_updates,
            "K": self.K.copy(),
            "K_g": Kg,
            "eps_m_rad_s": self.eps.copy(),
            "bias_rad_s": C.T @ self.eps,
            "bias_deg_s": np.rad2deg(C.T @ self.eps),
            "C_b_m": C,
            "euler_deg": dcm_to_euler(C),
            "field_i": self.m.copy(),
            "C_m_i": self.C.copy(),
            "std": {k: std[k] for k in ("K", "K_g", "bias_deg_s", "misalignment_deg", "field_i")},
        }


# --------------------------------------------------------------------------- batch


@dataclass
class Initial:
    """Step 1 and eq. (13): the filter's starting point."""

    refinement: MagnetometerRefinement
    K0: np.ndarray
    eps0: np.ndarray
    P0: np.ndarray                # 12x12 prior covariance of [vec K, eps]
    ls_std: np.ndarray = field(default_factory=lambda: np.zeros(12))


def known_magnetometer(R, h) -> MagnetometerRefinement:
    """A magnetometer calibration taken as exact (the paper's Table I simulation assumes one)."""
    R, h = np.asarray(R, dtype=float), np.asarray(h, dtype=float)
    return MagnetometerRefinement(R, h, np.zeros((9, 9)), 0, False, float("nan"), float("nan"), float("nan"), float("nan"))


def initial_estimate(session: Session, refinement: MagnetometerRefinement, inflation: float = PRIOR_INFLATION) -> Initial:
    """Eq. (13) on the step-1 calibrated field, with its least-squares covariance inflated as the filter's prior.

    The least squares ignores the noise in its regressors and reuses the data
    the filter will see, so its covariance is too small to be a prior: it is
    multiplied by `inflation` (in std) and floored at PRIOR_FLOOR_K / PRIOR_FLOOR_EPS.
    """
    field_m = ellipsoid.calibrated_field(refinement.R, refinement.h, session.mag)
    lin = linear_gyro_estimate(session.t_gyro_s, session.gyro_rad_s, session.t_mag_s, field_m)
    dm, int_M = windowed_increments(session.t_gyro_s, session.gyro_rad_s, session.t_mag_s, field_m, DEFAULT_WINDOW_S)
    A, b = int_M.reshape(-1, 12), dm.reshape(-1)
    theta = np.concatenate([lin.K.reshape(-1, order="F"), lin.eps])
    res = b - A @ theta
    s2 = float(res @ res) / max(len(b) - 12, 1)
    try:
        ls_std = np.sqrt(np.maximum(np.diag(s2 * np.linalg.inv(A.T @ A)), 0.0))
    except np.linalg.LinAlgError:
        ls_std = np.full(12, np.inf)
    floor = np.concatenate([np.full(9, PRIOR_FLOOR_K), np.full(3, PRIOR_FLOOR_EPS)])
    prior_std = np.clip(inflation * np.nan_to_num(ls_std, nan=1.0, posinf=1.0), floor, 1.0)
    return Initial(refinement, lin.K, lin.eps, np.diag(prior_std**2), ls_std)


def time_ordered(t_gyro_s: np.ndarray, t_mag_s: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(is_gyro, index) of all samples in time order, gyro first on equal stamps."""
    t = np.concatenate([t_gyro_s, t_mag_s])
    kind = np.concatenate([np.zeros(len(t_gyro_s), dtype=np.int8), np.ones(len(t_mag_s), dtype=np.int8)])
    idx = np.concatenate([np.arange(len(t_gyro_s)), np.arange(len(t_mag_s))])
    order = np.lexsort((kind, t))
    return kind[order] == 0, idx[order]


def run_filter(session: Session, filt: StreamingCalibrator) -> StreamingCalibrator:
    """Feed a whole session through a StreamingCalibrator, one sample at a time, in time order."""
    is_gyro, index = time_ordered(session.t_gyro_s, session.t_mag_s)
    tg, tm = session.t_gyro_s.tolist(), session.t_mag_s.tolist()
    yg, ym = session.gyro_rad_s, session.mag
    add_gyro, add_mag = filt.add_gyro, filt.add_mag
    for g, i in zip(is_gyro.tolist(), index.tolist()):
        if g:
            add_gyro(tg[i], yg[i])
        else:
            add_mag(tm[i], ym[i])
    return filt


def ekf_calibrate(session: Session, options=None, *, magnetometer=None, mag_bias_correction: bool = True,
                  consider_magnetometer: bool = True, history_rows: int = HISTORY_ROWS,
                  prior_inflation: float = PRIOR_INFLATION) -> tuple[Calibration, EkfHistory]:
    """The paper's two-step calibration: magnetometer (ellipsoid + Gauss-Newton), then the error-state EKF.

    Noise levels, rest trimming and the observability gate are those of
    `calibrate.prepare` (`Options.force`, the noise options and `trim_rests`
    apply; ObservabilityError when the motion does not excite every
    parameter). A fixed `Options.time_offset_s` (magnetometer lag) shifts the
    magnetometer stamps; the EKF does not estimate the lag. The options only
    the joint least squares uses (stride, loss, estimate_time_offset,
    max_iter, ...) are ignored.

    magnetometer=(R, h): take this magnetometer calibration as exact and skip
    step 1 (the paper's Table I simulation assumes a calibrated magnetometer).
    mag_bias_correction: step 1 on the noise-corrected score (default) or the
    paper's plain least squares (see `refine_magnetometer`).
    consider_magnetometer: carry step 1's uncertainty into the std of the gyro
    parameters (Schmidt-Kalman consider states); off, the std is the filter's
    alone, as in the paper, which treats the calibrated magnetometer as exact.

    Returns (Calibration, EkfHistory).
    """
    from magyro.nls.solve import Options, prepare

    options = options or Options()
    t_start = time.perf_counter()
    prep = prepare(session, options)
    s = prep.session
    tau = float(getattr(options, "time_offset_s", 0.0) or 0.0)
    if tau:
        from dataclasses import replace

        s = replace(s, t_mag_s=s.t_mag_s - tau)
    if magnetometer is not None:
        ref = known_magnetometer(*magnetometer)
    else:
        ref = refine_magnetometer(s.mag, prep.fit.R, prep.fit.h, prep.sigma_mag if mag_bias_correction else None)
    init = initial_estimate(s, ref, prior_inflation)
    stride = max(1, int(math.ceil(len(s.t_mag_s) / max(history_rows - 2, 1))))
    cov_Rh = ref.covariance if (consider_magnetometer and magnetometer is None) else None
    filt = StreamingCalibrator(ref.R, ref.h, init.K0, init.eps0, None, prep.gyro_density, prep.sigma_mag,
                               P0=init.P0, cov_Rh=cov_Rh, history_stride=stride)
    t_filter = time.perf_counter()
    run_filter(s, filt)
    filter_s = time.perf_counter() - t_filter
    if not filt.started or filt.mag_updates == 0:
        raise InputError("the EKF got no magnetometer sample inside the gyro's time span")
    history = filt.history()
    cal = assemble(filt, prep, init, filter_s, time.perf_counter() - t_start, tau)
    return cal, history


def assemble(filt: StreamingCalibrator, prep, init: Initial, filter_s: float, total_s: float, tau: float) -> Calibration:
    """The Calibration of the filter's final state, with the same fields as the joint least squares'."""
    import dataclasses

    K, eps, m = filt.K.copy(), filt.eps.copy(), filt.m.copy()
    C, Kg = qr_split(K)
    ref = init.refinement
    std = std_from_covariance(reported_covariance(K, eps, ref.R, ref.h, m, filt.input_covariance(ref.covariance), C))
    a = prep.analysis
    n_samples = filt.gyro_samples + filt.mag_updates
    kwargs = dict(
        K_g=Kg, bias_rad_s=C.T @ eps, K=K, eps_rad_s=eps, C_b_m=C, R=ref.R, h=ref.h,
        mag_unit=prep.session.mag_unit, field_i=m, std=std,
        observability={"rank": a.rank, "condition": a.condition, "tolerance": a.tolerance,
                       "eigenvalues_normalised": a.eigenvalues_normalised.tolist()},
        solver={"method": "ekf", "status": "done", "iterations": int(n_samples), "seconds": float(filter_s),
                "total_seconds": float(total_s), "gyro_samples": int(filt.gyro_samples),
                "mag_updates": int(filt.mag_updates), "skipped_mag": int(filt.skipped_mag),
                "samples_per_second": float(n_samples / filter_s) if filter_s > 0 else None,
                "state_dimension": int(filt.n), "consider_magnetometer": bool(filt.consider),
                "magnetometer_newton_iterations": int(ref.iterations),
                "magnetometer_bias_corrected": bool(ref.bias_corrected)},
        noise={"gyro_density_rad_s_sqrt_hz": prep.gyro_density, "mag_std": prep.sigma_mag},
        fit={"mag_norm_rms": ref.rms_norm_error, "mag_norm_rms_ellipsoid": ref.rms_norm_error_initial,
             "normalised_innovation_squared_mean": float(filt.nis_sum / max(filt.mag_updates, 1)),
             "prior_std_K_eps": np.sqrt(np.diag(init.P0)).tolist()},
    )
    if "time_offset_s" in {f.name for f in dataclasses.fields(Calibration)}:
        kwargs["time_offset_s"] = tau
    return Calibration(**kwargs)
