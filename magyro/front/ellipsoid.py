"""Step 1 of the paper: the magnetometer's intrinsic calibration from the ellipsoid.

    m^m = R (y_m - h),  |m^m| = 1     (paper eq. 2)

An algebraic quadric fit gives the ellipsoid; its centre is h and the Cholesky
factor of its shape matrix is R (upper triangular, positive diagonal). The
joint least squares refines both; this is only its starting point.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from magyro.errors import InputError
from magyro.text import significant


@dataclass(frozen=True)
class EllipsoidFit:
    R: np.ndarray           # 3x3 upper triangular, positive diagonal, 1/(input unit)
    h: np.ndarray           # (3,) hard iron, input unit
    rms_norm_error: float   # RMS of |R (y - h)| - 1 over the samples
    uniqueness: float       # ratio of the two smallest singular values of the fit (>> 1 when unique;
                            # below MIN_UNIQUENESS the joint solve leans on the gyro for R and h)


class DegenerateCloud(Exception):
    """The samples do not determine an ellipsoid because of the motion (static or planar)."""

    def __init__(self, kind: str, message: str):
        super().__init__(message)
        self.kind = kind  # "static" | "planar" | "sparse"


class NotAnEllipsoid(InputError):
    """The best quadric through the samples is a hyperboloid: the field or the iron changed along the path, or
    the cloud covers too little of the sphere to tell (magyro.front.causes decides which)."""


MIN_UNIQUENESS = 2.0
STATIC_SPREAD_IN_NOISE_STD = 10.0
PLANAR_THICKNESS_IN_NOISE_STD = 5.0


def quadric_design_matrix(y: np.ndarray) -> np.ndarray:
    """Rows [x^2, y^2, z^2, 2xy, 2xz, 2yz, 2x, 2y, 2z, 1] of the quadric v.row = 0."""
    x, yy, z = y[:, 0], y[:, 1], y[:, 2]
    one = np.ones_like(x)
    return np.column_stack([x * x, yy * yy, z * z, 2 * x * yy, 2 * x * z, 2 * yy * z, 2 * x, 2 * yy, 2 * z, one])


def quadric_from_vector(v: np.ndarray) -> tuple[np.ndarray, np.ndarray, float]:
    """(A, b, c) with y^T A y + 2 b^T y + c = 0."""
    A = np.array([[v[0], v[3], v[4]], [v[3], v[1], v[5]], [v[4], v[5], v[2]]])
    return A, v[6:9].copy(), float(v[9])


def classify_spread(y: np.ndarray, noise_std: float) -> None:
    """Raise DegenerateCloud when the samples sit at one point or in one plane (within the noise)."""
    lam = np.sort(np.linalg.eigvalsh(np.cov(y.T)))[::-1]
    spread, thickness = np.sqrt(np.maximum(lam[[0, 2]], 0.0))
    noise_std = max(noise_std, 1e-12)
    if spread < STATIC_SPREAD_IN_NOISE_STD * noise_std:
        raise DegenerateCloud(
            "static",
            f"the magnetometer reading barely changes (spread {significant(spread)} vs noise {significant(noise_std)}): "
            "the device was not rotated",
        )
    if thickness < PLANAR_THICKNESS_IN_NOISE_STD * noise_std:
        raise DegenerateCloud(
            "planar",
            "the magnetometer readings lie in one plane (a circle of field directions): the device turned "
            "about a single axis",
        )


def fit_ellipsoid(y_mag: np.ndarray, noise_std: float = 0.0) -> EllipsoidFit:
    """Algebraic ellipsoid fit of magnetometer samples (N, 3) in the input unit.

    Raises DegenerateCloud when the motion leaves the fit undetermined (static
    or field directions in one plane), InputError when the points lie on
    something that is not an ellipsoid.
    """
    y = np.asarray(y_mag, dtype=float)
    classify_spread(y, noise_std)
    centre = y.mean(axis=0)
    scale = np.sqrt(np.mean(np.sum((y - centre) ** 2, axis=1)))
    u = (y - centre) / scale
    # singular values and vectors of the (N x 10) design from its 10 x 10 normal matrix: the
    # data are centred and scaled, so squaring the condition costs nothing that matters here
    D = quadric_design_matrix(u)
    lam, V = np.linalg.eigh(D.T @ D)
    lam = np.maximum(lam, 0.0)
    uniqueness = float(np.sqrt(lam[1] / max(lam[0], 1e-300)))
    A, b, c = quadric_from_vector(V[:, 0])
    try:
        R_u, h_u = ellipsoid_shape(A, b, c)
    except InputError:
        # the unconstrained quadric is not an ellipsoid: the one constrained to be one may still fit well
        R_u, h_u = ellipsoid_shape(*quadric_from_vector(ellipsoid_specific_vector(D)))
        r = np.linalg.norm((u - h_u) @ R_u.T, axis=1) - 1.0
        if np.sqrt(np.mean(r**2)) > MAX_CONSTRAINED_NORM_ERROR:
            if uniqueness < MIN_UNIQUENESS:  # a family of quadrics fits: the coverage, not the data, is at fault
                raise DegenerateCloud(
                    "sparse",
                    "the magnetometer readings do not determine an ellipsoid: the field directions cover too little "
                    "of the sphere (rotation about one or two axes only?)",
                ) from None
            raise
    # back to the input unit: u = (y - centre)/scale
    R = R_u / scale
    h = centre + scale * h_u
    r = np.linalg.norm((y - h) @ R.T, axis=1) - 1.0
    return EllipsoidFit(R=R, h=h, rms_norm_error=float(np.sqrt(np.mean(r**2))), uniqueness=uniqueness)


MAX_CONSTRAINED_NORM_ERROR = 0.1
LI_GRIFFITHS_K = 4.0


def ellipsoid_specific_vector(D: np.ndarray) -> np.ndarray:
    """Quadric vector of the least-squares ellipsoid (Li & Griffiths 2004, constraint k J - I^2 = 1, k = 4).

    Always an ellipsoid; exact for near-spheres such as magnetometer clouds.
    """
    k = LI_GRIFFITHS_K
    S = D.T @ D
    S11, S12, S22 = S[:6, :6], S[:6, 6:], S[6:, 6:]
    C1 = np.zeros((6, 6))
    C1[:3, :3] = k / 2.0 - 1.0
    np.fill_diagonal(C1[:3, :3], -1.0)
    C1[3:, 3:] = -k * np.eye(3)
    M = np.linalg.solve(C1, S11 - S12 @ np.linalg.solve(S22, S12.T))
    lam, V = np.linalg.eig(M)
    v1 = np.real(V[:, int(np.argmax(np.real(lam)))])
    return np.concatenate([v1, -np.linalg.solve(S22, S12.T @ v1)])


def ellipsoid_shape(A: np.ndarray, b: np.ndarray, c: float) -> tuple[np.ndarray, np.ndarray]:
    """(R, h) with |R (y - h)| = 1 on the quadric; InputError if it is not an ellipsoid."""
    try:
        h = -np.linalg.solve(A, b)
    except np.linalg.LinAlgError:
        raise InputError("the magnetometer samples do not lie on an ellipsoid (singular quadric)") from None
    k = float(h @ A @ h - c)
    if k == 0.0:
        raise InputError("the magnetometer samples do not lie on an ellipsoid (degenerate quadric)")
    shape = A / k
    eig = np.linalg.eigvalsh(shape)
    if np.any(eig <= 0):
        raise NotAnEllipsoid(
            "the magnetometer samples do not lie on an ellipsoid (the fitted surface is a hyperboloid): "
            "check that mx, my, mz are the magnetometer and that no iron or magnet moved during the recording"
        )
    L = np.linalg.cholesky(shape)  # shape = L L^T
    return L.T.copy(), h


def calibrated_field(R: np.ndarray, h: np.ndarray, y_mag: np.ndarray) -> np.ndarray:
    """m^m = R (y_m - h) for samples (N, 3)."""
    return (np.asarray(y_mag) - h) @ R.T


def surrogate_field_directions(y_mag: np.ndarray) -> np.ndarray:
    """Raw readings normalised to unit length: a stand-in for m^m when no ellipsoid can be fitted."""
    y = np.asarray(y_mag, dtype=float)
    return y / np.linalg.norm(y, axis=1, keepdims=True)
