"""Known distortions of a session and the calibration they must give: a test of the solve on real data.

A real recording has no truth, but a known change of it has a known answer: distort the
gyro (y' = A y + b) and the magnetometer (y_m' = Q T y_m + c) of a recording, and the
calibration of the distorted recording must equal `predicted_distorted` of the
undistorted one (the algebra is in its docstring). `distortion_z_scores` measures the
difference in units of a std (the distorted solve's own by default, or its white-noise std).
Used by tests/test_real_data.py and benchmarks/std_on_real_data.py.
"""
from __future__ import annotations

import dataclasses

import numpy as np
import scipy.linalg

from magyro import so3
from magyro.result.reported import misalignment_vector

UPPER = np.triu_indices(3)

# gyro y' = A y + b: scale errors of a few %, non-orthogonality ~0.5 deg, bias ~0.5 deg/s
A_GYRO = np.array([[1.05, 0.010, -0.008],
                   [0.00, 0.970, 0.012],
                   [0.00, 0.000, 1.020]])
B_GYRO = np.deg2rad([0.5, -0.3, 0.2])
# magnetometer y_m' = Q T y_m + c: soft iron T (a few %), hard iron c (uT), rotation Q (a few deg)
T_MAG = np.array([[1.04, 0.020, -0.010],
                  [0.00, 0.970, 0.015],
                  [0.00, 0.000, 1.020]])
C_MAG = np.array([30.0, -20.0, 15.0])
Q_MAG = so3.euler_to_dcm([2.0, -3.0, 4.0])


def distorted(session):
    return dataclasses.replace(session, gyro_rad_s=session.gyro_rad_s @ A_GYRO.T + B_GYRO,
                               mag=session.mag @ (Q_MAG @ T_MAG).T + C_MAG)


def rq_positive(M: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """M = U P with U upper triangular, positive diagonal, and P a proper rotation (det M > 0)."""
    U, P = scipy.linalg.rq(M)
    D = np.diag(np.sign(np.diag(U)))
    U, P = U @ D, D @ P
    if np.linalg.det(P) <= 0:
        raise ValueError("the distortion mirrors the magnetometer")
    return U, P


def predicted_distorted(cal) -> dict:
    """What the calibration of the distorted session must be, from the undistorted one.

    Undistorted model (docs/spec.md section 1): y_m = R^-1 C_i^m m^i + h,  w^m = K y_g + eps,
    K = C_b^m K_g, eps = C_b^m eps_b, i = the m frame at the first sample.

    Gyro, y' = A y + b:  y = A^-1 (y' - b), so in the *same* m frame
        w^m = K A^-1 y' + (eps - K A^-1 b).
    Magnetometer, y_m' = Q T y_m + c:
        y_m' = Q T R^-1 C_i^m m^i + (Q T h + c).
    Q T R^-1 is not upper triangular; factor it RQ-wise, Q T R^-1 = U P (U upper
    triangular with positive diagonal, P a rotation; det > 0 so P is proper). The
    distorted magnetometer then is the model with R'^-1 = U in a new equivalent
    magnetometer frame m' = P m (C_m^m' = P):
        y_m' = U (P C_i^m P^T) (P m^i) + h'.
    The new inertial frame is m' at the first sample, so C_i'^m' = P C_i^m P^T and
    m^i' = P m^i. The gyro seen in m' is w^m' = P w^m, hence
        R' = U^-1,  h' = Q T h + c,  field_i' = P field_i,
        K' = P K A^-1,  eps' = P (eps - K A^-1 b),  tau' = tau.
    QR split of K' = (P C_b^m)(K_g A^-1): K_g A^-1 is upper triangular with positive
    diagonal (A is), so by uniqueness of the split
        C_b^m' = P C_b^m,  K_g' = K_g A^-1,  eps_b' = C_b^m'^T eps' = eps_b - K_g A^-1 b.
    (The gyro frame b does not move because A is upper triangular; only m turns, by P.)
    """
    A_inv = np.linalg.inv(A_GYRO)
    U, P = rq_positive(Q_MAG @ T_MAG @ np.linalg.inv(cal.R))
    return {
        "K_g": cal.K_g @ A_inv,
        "bias_deg_s": np.rad2deg(cal.bias_rad_s - cal.K_g @ A_inv @ B_GYRO),
        "C_b_m": P @ cal.C_b_m,
        "K": P @ cal.K @ A_inv,
        "eps_deg_s": np.rad2deg(P @ (cal.eps_rad_s - cal.K @ A_inv @ B_GYRO)),
        "R": np.linalg.inv(U),
        "h": Q_MAG @ T_MAG @ cal.h + C_MAG,
        "field_i": P @ cal.field_i,
        "time_offset_s": cal.time_offset_s,
        "P": P,
    }


def z_scores(estimate, predicted, std) -> np.ndarray:
    """(estimate - predicted) / std, elementwise."""
    estimate, predicted, std = (np.asarray(a, dtype=float) for a in (estimate, predicted, std))
    return (estimate - predicted) / std


def distortion_z_scores(cal_d, pred, std=None) -> dict[str, np.ndarray]:
    """Distorted solve minus prediction, in units of `std` (default: the distorted solve's own std)."""
    s = std if std is not None else cal_d.std
    return {
        "K_g": z_scores(cal_d.K_g[UPPER], pred["K_g"][UPPER], s.K_g[UPPER]),
        "bias_deg_s": z_scores(cal_d.bias_deg_s, pred["bias_deg_s"], s.bias_deg_s),
        "misalignment_deg": np.rad2deg(misalignment_vector(pred["C_b_m"], cal_d.C_b_m)) / s.misalignment_deg,
        "K": z_scores(cal_d.K, pred["K"], s.K).ravel(),
        # eps' = C_b^m' eps_b': its per-axis std is the bias std turned by a few degrees
        "eps_deg_s": z_scores(np.rad2deg(cal_d.eps_rad_s), pred["eps_deg_s"], s.bias_deg_s),
        "R": z_scores(cal_d.R[UPPER], pred["R"][UPPER], s.R[UPPER]),
        "h": z_scores(cal_d.h, pred["h"], s.h),
        "field_i": z_scores(cal_d.field_i, pred["field_i"], s.field_i),
        "time_offset_s": np.atleast_1d(z_scores(cal_d.time_offset_s, pred["time_offset_s"], s.time_offset_s)),
    }
