"""The solved attitude trajectory (`magyro solve --trajectory`): nodes, attitudes, their std, the calibrated field."""
from __future__ import annotations

import numpy as np

from magyro import so3
from magyro.front.ellipsoid import calibrated_field
from magyro.nls.grid import Grid
from magyro.nls.reduction import Reduced, attitude_covariance_blocks
from magyro.nls.problem import JointProblem, Linearisation
from magyro.result.trajectory import AttitudeTrajectory
from magyro.session import Session


def solved_attitudes(problem: JointProblem, lin: Linearisation, x: np.ndarray) -> np.ndarray:
    """C_m_i at every node, (N, 3, 3): the nominal attitude turned by the solved correction (node 0 the gauge, I)."""
    phi = np.vstack([np.zeros(3), x[problem.n_theta:].reshape(-1, problem.B)[:, :3]])
    return lin.C_m_i_nominal @ so3.exp_so3(phi)


def attitude_trajectory(problem: JointProblem, grid: Grid, lin: Linearisation, x: np.ndarray, reduced: Reduced,
                        session: Session, R: np.ndarray, h: np.ndarray, cov_theta: np.ndarray | None = None) -> AttitudeTrajectory:
    """C_m_i at every node (node 0 the gauge, I), the one-sigma of each, and the calibrated field there."""
    C_m_i = solved_attitudes(problem, lin, x)
    cov = attitude_covariance_blocks(reduced, cov_theta)
    std = np.vstack([np.zeros(3), np.sqrt(np.maximum(np.diagonal(cov, axis1=1, axis2=2), 0.0))])
    field = calibrated_field(R, h, session.mag[grid.node_mag_index])
    field[~grid.node_on_sample] = np.nan
    return AttitudeTrajectory(np.array(grid.t_node_s, dtype=float), C_m_i, std, field)
