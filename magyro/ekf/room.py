"""The EKF's std that counts the room: the same field-disturbance model as the least squares', as a sandwich.

The filter takes the field as homogeneous, as the least squares does; in a real
room it departs from m^i by a slow, correlated delta(t) (`magyro.nls.disturbance`:
a Gauss-Markov process in the frame i, isotropic, std sigma as a fraction of the
field and correlation time T). Its covariance alone counts every magnetometer
sample as independent information, and came out 3-5x smaller than the least
squares' on BROAD.

sigma and T are measured the same way as for the least squares
(`disturbance_from_magnitude`): from the autocovariance of the step-1 calibrated
field's magnitude, less what step 1's own (R, h) uncertainty explains.

The filter's final estimate is, to first order, linear in its innovations:
x_k = (I - W_k H_k) F_k x_k-1 + W_k z_k, with F_k the propagation since the
previous update. So the final parameters move by S_j = Lambda_j W_j C_j^T delta_j
for a disturbance delta_j at update j (z = C^T (m + delta)), with
Lambda_j = prod_{k > j} (I - W_k H_k) F_k, built backwards from the last update.
The disturbance then adds

    Omega = sigma^2 sum_jk exp(-|t_j - t_k| / T) S_j S_k^T

to the covariance of [vec K, eps, m^i] (the estimate itself is left as it is),
summed as the least squares sums it (`ExponentialDoubleSum`). A homogeneous field
gives sigma ~ 0 and the filter's own covariance back.
"""
from __future__ import annotations

import numpy as np

from magyro.ekf.magnetometer import MagnetometerRefinement
from magyro.nls.disturbance import ExponentialDoubleSum, disturbance_from_magnitude
from magyro.result.parts import FieldDisturbance
from magyro.result.reported import UPPER

ROWS = slice(3, 17)   # the error state's K, eps and m^i: what the reported parameters come from


def measured_disturbance(t_mag_s: np.ndarray, mag: np.ndarray, ref: MagnetometerRefinement) -> FieldDisturbance:
    """sigma and T of the room's field disturbance from the step-1 calibrated field's magnitude."""
    d = np.asarray(mag, dtype=float) - ref.h
    u = d @ ref.R.T
    norm = np.linalg.norm(u, axis=1)
    G = np.empty((len(d), 9))
    for n, (i, j) in enumerate(UPPER):
        G[:, n] = u[:, i] * d[:, j] / norm
    G[:, 6:] = -(u @ ref.R) / norm[:, None]
    return disturbance_from_magnitude(np.asarray(t_mag_s, dtype=float), norm - 1.0, G, ref.covariance)


class DisturbanceSensitivity:
    """Records what the backward pass needs, one entry per update: the propagation since the previous update
    (rows 0:3 of F over the attitude, K and eps errors), the gain, H over the estimated states, C^T and t."""

    def __init__(self, n_state: int):
        self.n_state = n_state
        self.acc = self.fresh()
        self.entries: list[tuple] = []

    @staticmethod
    def fresh() -> np.ndarray:
        acc = np.zeros((3, 15))
        acc[:, :3] = np.eye(3)
        return acc

    def propagate(self, Fa: np.ndarray) -> None:
        """One propagation step, F rows 0:3 = Fa (3 x 15), after those recorded since the last update."""
        acc = Fa[:, :3] @ self.acc
        acc[:, 3:] += Fa[:, 3:15]
        self.acc = acc

    def update(self, t_s: float, W: np.ndarray, H: np.ndarray, C_m_i: np.ndarray) -> None:
        self.entries.append((t_s, self.acc, W.copy(), H[:, : self.n_state].copy(), C_m_i.T.copy()))
        self.acc = self.fresh()

    def sensitivities(self) -> tuple[np.ndarray, np.ndarray]:
        """(S_j (n, 14, 3): how the final K, eps, m^i move with a disturbance at update j, t_j), backwards."""
        n = self.n_state
        lam = np.zeros((ROWS.stop - ROWS.start, n))
        lam[:, ROWS] = np.eye(ROWS.stop - ROWS.start)
        out = np.empty((len(self.entries), lam.shape[0], 3))
        times = np.empty(len(self.entries))
        for k in range(len(self.entries) - 1, -1, -1):
            t_s, acc, W, H, Ct = self.entries[k]
            lw = lam @ W
            out[k] = lw @ Ct
            times[k] = t_s
            lam = lam - lw @ H                          # Lambda (I - W H)
            moved = lam[:, :3] @ acc                    # ... F: the attitude columns carry into K and eps
            lam[:, 3:15] += moved[:, 3:]
            lam[:, :3] = moved[:, :3]
        return out, times


def disturbance_covariance(recorder: DisturbanceSensitivity, found: FieldDisturbance) -> np.ndarray:
    """Omega (14 x 14) over the error state's K, eps and m^i entries (zero when the field is homogeneous)."""
    size = ROWS.stop - ROWS.start
    if found.std_fraction <= 0.0 or not recorder.entries:
        return np.zeros((size, size))
    S, t_s = recorder.sensitivities()
    total = ExponentialDoubleSum(found.correlation_time_s)
    total.add(S, t_s)
    omega = found.std_fraction**2 * total.result()
    return 0.5 * (omega + omega.T)


def step1_room_covariance(t_mag_s: np.ndarray, mag: np.ndarray, ref: MagnetometerRefinement,
                          found: FieldDisturbance) -> np.ndarray:
    """What the room's disturbance adds to step 1's covariance of [R upper, h] (9 x 9).

    Step 1 fits |R (y - h)|^2 = 1; a disturbance delta moves each residual by 2 delta along the field, and
    its correlation over seconds makes the sandwich over independent samples too small. With J the step's
    Jacobian rows: (J^T J)^-1 [4 sigma^2 sum_jk exp(-|t_j - t_k| / T) J_j J_k^T] (J^T J)^-1. It enters the
    filter through the consider states, so the gyro parameters' std counts it too.
    """
    if found.std_fraction <= 0.0:
        return np.zeros((9, 9))
    from magyro.ekf.magnetometer import norm_terms

    J = norm_terms(np.asarray(mag, dtype=float), ref.R, ref.h)[3]
    total = ExponentialDoubleSum(found.correlation_time_s)
    total.add(J[:, :, None], np.asarray(t_mag_s, dtype=float))
    Hi = np.linalg.inv(J.T @ J)
    out = Hi @ (4.0 * found.std_fraction**2 * total.result()) @ Hi
    return 0.5 * (out + out.T)
