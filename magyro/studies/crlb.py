"""The Cramer-Rao lower bound of a simulated calibration problem.

The Fisher information of the joint least squares, linearised at the TRUE
parameters and the TRUE attitude, with the true noise levels, trajectory
marginalised out and propagated to the reported parameters exactly like the
std of a solve. No unbiased estimator can have a smaller std; the joint NLS
should come close (`magyro montecarlo` compares them).
"""
from __future__ import annotations

import numpy as np

from magyro.nls.solve import Options, default_stride, information_covariance, moving_session
from magyro.result.calibration import std_from_covariance
from magyro.nls.problem import JointProblem, Linearisation, build_grid
from magyro.session import Session
from magyro.studies.simulate import Problem, field_i, truth_attitude


def truth_linearisation(problem: Problem, t_node_s: np.ndarray) -> Linearisation:
    """The true parameters and attitude at the nodes, re-based so node 0 is the inertial frame."""
    C = truth_attitude(problem, t_node_s)
    C_rebased = np.einsum("ji,njk->nik", C[0], C)
    m0 = C[0].T @ field_i(problem)
    S0 = np.linalg.inv(problem.R)
    return Linearisation(S0, np.asarray(problem.hard_iron, float), problem.K, problem.eps_m_rad_s, m0, C_rebased,
                         float(np.mean(np.diag(S0))), problem.mag_time_offset_s)


def moving_part(problem: Problem, session: Session, options: Options) -> Session:
    """The session as the solver sees it (rests at both ends trimmed, as calibrate does)."""
    return moving_session(session, options)[0]


def cramer_rao_std(problem: Problem, session: Session, options: Options | None = None) -> dict:
    """CRLB one-sigma of every reported parameter (laid out like Calibration.std)."""
    return std_from_covariance(cramer_rao_covariance(problem, session, options))


def cramer_rao_covariance(problem: Problem, session: Session, options: Options | None = None) -> np.ndarray:
    """CRLB covariance of the reported vector (result.REPORTED layout)."""
    options = options or Options()
    s = moving_part(problem, session, options)
    grid = build_grid(s.t_gyro_s, s.gyro_rad_s, s.t_mag_s, options.stride or default_stride(s))
    lin = truth_linearisation(problem, grid.t_node_s)
    jp = JointProblem(grid, compiled=options.compiled, estimate_time_offset=options.estimate_time_offset)
    p = jp.parameters(lin, s.mag, problem.mag_noise_std, problem.gyro_noise_density_rad_s_sqrt_hz,
                      s.t_gyro_s, s.gyro_rad_s, s.t_mag_s, problem.mag_time_offset_s)
    return information_covariance(jp, lin, p)
