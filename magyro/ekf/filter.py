"""Step 2 of the paper's method: the error-state EKF of eq. (9) (Wu & Pei, sections III-IV).

The full derivation, with the choices made where the paper is silent, is in
docs/ekf.md; this is its summary. The filter starts from the least squares of
eq. (13) (`magyro.ekf.prior`), attitude C_m^i = I and m^i = the first
calibrated magnetometer sample; R and h come from step 1
(`magyro.ekf.magnetometer`) and stay fixed.

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

This module is the filter's maths: its state, propagation, measurement,
update and injection, and its covariance read back. Feeding it samples from
two asynchronous sensors is `magyro.ekf.streaming.StreamingCalibrator`.
"""
from __future__ import annotations

import math

import numpy as np

from magyro.ekf.history import EkfHistory, history_from_rows
from magyro.ekf.scalar import carry_basis, exp9, inv_sym33, mul33
from magyro.errors import InputError
from magyro.result.reported import UPPER
from magyro.so3 import tangent_basis

N_STATE = 17
IA, IK, IE, IM = slice(0, 3), slice(3, 12), slice(12, 15), slice(15, 17)
REORTHONORMALISE_EVERY = 1000   # propagation steps between re-orthonormalisations of C
REFRESH_NOISE_EVERY = 16        # updates between recomputations of sigma_g^2 K K^T (K barely moves)


def orthonormalise(C: np.ndarray) -> np.ndarray:
    """The rotation nearest to C (polar factor U V^T of the SVD)."""
    U, _, Vt = np.linalg.svd(C)
    return U @ Vt


class ErrorStateEKF:
    """The error-state EKF of paper eq. (9): nominal state, covariance, propagation and update.

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
    m^i, so the reported std includes step 1's error. history_stride: record
    the estimate every that many updates (`history()`).
    """

    def __init__(self, R, h, K0, eps0, m0=None, gyro_noise_density_rad_s_sqrt_hz: float = 0.0,
                 mag_noise_std: float = 0.0, *, P0=None, cov_Rh=None, m0_std: float = 0.1,
                 history_stride: int | None = None):
        if not (gyro_noise_density_rad_s_sqrt_hz > 0 and mag_noise_std > 0):
            raise InputError("the EKF needs a positive gyro noise density and magnetometer noise std")
        self.R = np.array(R, dtype=float)
        self.h = np.array(h, dtype=float)
        # the nominal state lives in Python floats (row-major tuples/lists): see magyro.ekf.scalar
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
        self.t0 = None
        self.mag_updates = 0
        self.nis_sum = 0.0
        # -log of the readings' likelihood, (nu^T S^-1 nu + log det S) / 2 summed over the updates at filter times in
        # [likelihood_from_s, likelihood_to_s] (magyro.ekf.lag compares it between lags over the same readings)
        self.nll_sum = 0.0
        self.likelihood_from_s, self.likelihood_to_s = -math.inf, math.inf
        self._steps = 0
        self.history_stride = history_stride
        self._rows: list[tuple] = []
        self.room = None           # a DisturbanceSensitivity (magyro.ekf.room) to record, when the room is counted
        self.innovations = None    # a list to append (innovation, S) of every update to, when asked
        # with consider states: estimate R and h too (their gain is not zero, the correction is injected); off, the
        # paper's two steps
        self.estimate_magnetometer = False

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

    # ---- the first magnetometer sample

    def _consider_jacobian(self, d) -> np.ndarray:
        """dz/d[R upper, h] for z = R (y - h): -e_i d_j for R_ij and R for h (errors are true - nominal)."""
        Hc = np.zeros((3, 9))
        for n, (i, j) in enumerate(UPPER):
            Hc[i, n] = -d[j]
        Hc[:, 6:] = self.R
        return Hc

    def _start(self, t: float, y, z: np.ndarray, d: list) -> None:
        """Start at the first magnetometer sample: C_m^i = I, and m^i from it unless m0 was given."""
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
        E = exp9(x, y, z)
        self._C = mul33(self._C, E)
        # F rows 0:3 = [Exp(theta)^T, ybar_1 Gamma, ybar_2 Gamma, ybar_3 Gamma, Gamma], Gamma = dt I - (dt/2) (theta x)
        g = (dt, h * z, -h * y, -h * z, dt, h * x, h * y, -h * x, dt)
        u1, u2, u3 = 0.5 * (p1 + q1), 0.5 * (p2 + q2), 0.5 * (p3 + q3)
        Fa = np.array([
            [E[0], E[3], E[6], u1 * g[0], u1 * g[1], u1 * g[2], u2 * g[0], u2 * g[1], u2 * g[2], u3 * g[0], u3 * g[1], u3 * g[2], g[0], g[1], g[2]],
            [E[1], E[4], E[7], u1 * g[3], u1 * g[4], u1 * g[5], u2 * g[3], u2 * g[4], u2 * g[5], u3 * g[3], u3 * g[4], u3 * g[5], g[3], g[4], g[5]],
            [E[2], E[5], E[8], u1 * g[6], u1 * g[7], u1 * g[8], u2 * g[6], u2 * g[7], u2 * g[8], u3 * g[6], u3 * g[7], u3 * g[8], g[6], g[7], g[8]],
        ])
        P = self.P
        if self.room is not None:
            self.room.propagate(Fa)
        X = Fa @ P[:15]                              # rows 0:3 of F P (F is I below row 3; m, consider columns of F are 0)
        P[0:3, 3:] = X[:, 3:]
        P[3:, 0:3] = X[:, 3:].T
        P[0:3, 0:3] = X[:, :15] @ Fa.T + dt * self._Qc
        self.t, self.y = t_b, y_b
        self._steps += 1
        if self._steps % REORTHONORMALISE_EVERY == 0:
            self._C = tuple(orthonormalise(np.array(self._C).reshape(3, 3)).reshape(-1).tolist())
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
        (A, Bs, Cs, E, F, I), Si, det_S = inv_sym33(S)
        joint = self.consider and self.estimate_magnetometer
        W = PHt @ Si if joint else None
        Wa = W[:N_STATE] if joint else PHt[:N_STATE] @ Si   # gain of the estimated states (consider states get none)
        zz = z.tolist()
        v1, v2, v3 = zz[0] - z1, zz[1] - z2, zz[2] - z3
        nu = (v1, v2, v3)
        nis = A * v1 * v1 + E * v2 * v2 + I * v3 * v3 + 2.0 * (Bs * v1 * v2 + Cs * v1 * v3 + F * v2 * v3)
        self.nis_sum += nis
        if self.likelihood_from_s <= self.t <= self.likelihood_to_s:
            # an S that is not positive definite (a filter whose covariance broke down) has no likelihood
            self.nll_sum += 0.5 * (nis + math.log(det_S)) if det_S > 0.0 else math.inf
        dx = ((W if joint else Wa) @ nu).tolist()
        if self.innovations is not None:
            self.innovations.append((nu, S))
        if self.room is not None:
            self.room.update(self.t, Wa, H, np.array(self._C).reshape(3, 3))
        if joint:
            P -= W @ PHt.T
            self._inject_magnetometer(dx[N_STATE:])
        else:
            P[:N_STATE] -= Wa @ PHt.T
            if self.consider:
                P[N_STATE:, :N_STATE] = P[:N_STATE, N_STATE:].T
        # inject. The reset Jacobians differ from I by O(|dx|) for the attitude (I - (dphi x)/2,
        # |dphi| ~ 1e-3 rad) and by O(|dm|^2) for the field basis: both are left out.
        self._C = mul33(self._C, exp9(dx[0], dx[1], dx[2]))
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
        self._B = carry_basis(B, self._m)
        self.mag_updates += 1
        if self.mag_updates % REFRESH_NOISE_EVERY == 0:
            self._refresh_noise()
        if self.history_stride and self.mag_updates % self.history_stride == 0:
            self._record()

    def _inject_magnetometer(self, d_Rh: list) -> None:
        """R (upper, UPPER order) and h corrected by the update, and what is derived from them."""
        for n, (i, j) in enumerate(UPPER):
            self.R[i, j] += d_Rh[n]
        self.h = self.h + np.asarray(d_Rh[6:9])
        self.Rn = self.mag_noise_std**2 * (self.R @ self.R.T)
        self._Hc_h = self.R.tolist()
        self._Sinv = np.linalg.inv(self.R).reshape(-1).tolist()

    # ---- reading

    def _record(self) -> None:
        """Append the current estimate to the history (replacing a row at the same time)."""
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
        return history_from_rows(self._rows)

    @property
    def covariance(self) -> np.ndarray:
        """The full error-state covariance (17x17, or 26x26 with the consider states), symmetrised."""
        return 0.5 * (self.P + self.P.T)

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

