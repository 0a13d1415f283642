"""The reported parameters: the QR split of K, and the layout in which their covariance is propagated and unpacked.

`[C_b_m, K_g] = qr(K)` with diag(K_g) > 0; the misalignment's uncertainty is
that of d in C_b_m(true) = C_b_m(est) Exp(d).
"""
from __future__ import annotations

import numpy as np

from magyro import so3
from magyro.errors import InputError
from magyro.result.parts import Std

UPPER = [(0, 0), (0, 1), (0, 2), (1, 1), (1, 2), (2, 2)]
# layout of the reported vector (reported_vector), used to unpack its covariance
REPORTED = {
    "K_g": slice(0, 6), "bias_deg_s": slice(6, 9), "misalignment_deg": slice(9, 12), "R": slice(12, 18),
    "h": slice(18, 21), "K": slice(21, 30), "field_i": slice(30, 33), "time_offset_s": slice(33, 34),
}
N_REPORTED = 34


def qr_split(K: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(C_b_m, K_g) with K = C_b_m K_g, K_g upper triangular with positive diagonal.

    Raises InputError when C_b_m would be improper (det -1). Only the gyro's
    handedness can show up here: a mirrored magnetometer is absorbed by the
    model (y -> D y is fitted by D R^-1 D, D C D and K -> -D K, all proper), so
    it appears instead as a misalignment near 180 deg (see `axis_mapping_warning`).
    """
    Q, Rq = np.linalg.qr(K)
    D = np.diag(np.sign(np.diag(Rq)))
    C, Kg = Q @ D, D @ Rq
    if np.linalg.det(C) < 0:
        raise InputError(
            "the gyro axes are a mirror image of the magnetometer's (det C_b_m = -1): the gyro's axis mapping is "
            "wrong (one gyro axis negated, or two swapped); negate one gyro column (e.g. gz) or swap two, "
            "and solve again"
        )
    return C, Kg

MISALIGNMENT_WARNING_DEG = 90.0


def axis_mapping_warning(C_b_m: np.ndarray) -> str | None:
    """A plain warning when the gyro-to-magnetometer rotation is too large to be a mounting tolerance."""
    angle = float(np.rad2deg(np.linalg.norm(so3.log_so3(C_b_m))))
    if angle <= MISALIGNMENT_WARNING_DEG:
        return None
    return (
        f"the gyro-to-magnetometer misalignment is {angle:.0f} deg: far more than a mounting tolerance. "
        "An axis mapping is probably wrong (a magnetometer axis negated or swapped looks exactly like this); "
        "check the axis conventions of both sensors"
    )


def misalignment_vector(C_ref: np.ndarray, C: np.ndarray) -> np.ndarray:
    """d with C = C_ref Exp(d)."""
    return so3.log_so3(C_ref.T @ C)


def reported_vector(K, eps, S, h, m_i, C_ref, tau_s: float = 0.0) -> np.ndarray:
    """The reported parameters as one vector (layout REPORTED), for uncertainty propagation."""
    C, Kg = qr_split(K)
    R = np.linalg.inv(S)
    return np.concatenate([
        [Kg[i, j] for i, j in UPPER],
        np.rad2deg(C.T @ eps),
        np.rad2deg(misalignment_vector(C_ref, C)),
        [R[i, j] for i, j in UPPER],
        h,
        K.reshape(-1),
        m_i,
        [tau_s],
    ])


def std_from_covariance(cov_out: np.ndarray) -> Std:
    """Unpack the diagonal of the reported-vector covariance into one-sigma per parameter (inf where unobservable)."""
    sd = np.sqrt(np.maximum(np.diag(cov_out), 0.0))
    Kg = np.zeros((3, 3))
    R = np.zeros((3, 3))
    for n, (i, j) in enumerate(UPPER):
        Kg[i, j] = sd[REPORTED["K_g"].start + n]
        R[i, j] = sd[REPORTED["R"].start + n]
    return Std(K_g=Kg, bias_deg_s=sd[REPORTED["bias_deg_s"]], misalignment_deg=sd[REPORTED["misalignment_deg"]], R=R,
               h=sd[REPORTED["h"]], K=sd[REPORTED["K"]].reshape(3, 3), field_i=sd[REPORTED["field_i"]],
               time_offset_s=float(sd[REPORTED["time_offset_s"]][0]))


def plausible_gyro(K_g: np.ndarray) -> bool:
    """Scale factors within 0.5-2 and axes within 30 deg of orthogonal: any MEMS gyro, however poorly made."""
    scale = np.diag(K_g)
    return bool(np.all((scale > 0.5) & (scale < 2.0)) and np.all(np.abs(np.triu(K_g, 1)) < 0.5 * scale[None, :]))


def mirror_is_credible(K: np.ndarray) -> bool:
    """Is a K whose QR split is mirrored (det < 0) a plausible gyro behind a wrong axis mapping, rather than the
    noise of too little motion? Its upper-triangular factor must be a plausible gyro (`plausible_gyro`): short
    cuts of BROAD trial 02 whose linear estimate came out mirrored had scale factors of 1.5-38."""
    Q, Rq = np.linalg.qr(K)
    return plausible_gyro(np.diag(np.sign(np.diag(Rq))) @ Rq)
