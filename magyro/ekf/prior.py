"""The filter's starting point: the least squares of paper eq. (13) on the step-1 calibrated field, and its prior."""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from magyro.ekf.magnetometer import MagnetometerRefinement
from magyro.front import ellipsoid
from magyro.front.initial import DEFAULT_WINDOW_S, linear_gyro_estimate
from magyro.observability.matrix import windowed_increments
from magyro.session import Session

PRIOR_INFLATION = 10.0          # the eq. (13) std is multiplied by this for the filter's prior
PRIOR_FLOOR_K = 1e-3            # smallest prior std of a K entry
PRIOR_FLOOR_EPS = np.deg2rad(0.05)  # smallest prior std of an eps entry, rad/s


@dataclass
class Initial:
    """Step 1 and eq. (13): the filter's starting point."""

    refinement: MagnetometerRefinement
    K0: np.ndarray
    eps0: np.ndarray
    P0: np.ndarray                # 12x12 prior covariance of [vec K, eps]
    ls_std: np.ndarray = field(default_factory=lambda: np.zeros(12))


def initial_estimate(session: Session, refinement: MagnetometerRefinement, inflation: float = PRIOR_INFLATION,
                     unexcited: np.ndarray | None = None) -> Initial:
    """Eq. (13) on the step-1 calibrated field, with its least-squares covariance inflated as the filter's prior.

    The least squares ignores the noise in its regressors and reuses the data
    the filter will see, so its covariance is too small to be a prior: it is
    multiplied by `inflation` (in std) and floored at PRIOR_FLOOR_K / PRIOR_FLOOR_EPS.
    `unexcited`: the directions a forced, rank-deficient motion leaves out (see `linear_gyro_estimate`).
    """
    field_m = ellipsoid.calibrated_field(refinement.R, refinement.h, session.mag)
    lin = linear_gyro_estimate(session.t_gyro_s, session.gyro_rad_s, session.t_mag_s, field_m, unexcited=unexcited)
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
