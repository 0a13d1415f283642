"""The Cramer-Rao lower bound of a simulated calibration problem.

The Fisher information of the joint least squares, linearised at the TRUE
parameters and the TRUE attitude, with the true noise levels, trajectory
marginalised out and propagated to the reported parameters exactly like the
std of a solve. No unbiased estimator can have a smaller std; the joint NLS
should come close (`magyro montecarlo` compares them).

The session is trimmed by the front end's `moving_session`, the grid and the
problem are the NLS method's (its stride and kernels), and the information is
`nls.information.information_covariance`: the functions a solve runs, only the
linearisation point is the truth. The noise is Gaussian, so the bound is that of
the plain least squares whatever the method's `loss`.
"""
from __future__ import annotations

import dataclasses

import numpy as np

from magyro import so3
from magyro.front.prepare import moving_session
from magyro.nls.grid import build_grid
from magyro.nls.information import information_covariance
from magyro.nls.method import NLS
from magyro.nls.problem import JointProblem, Linearisation
from magyro.nls.solve import default_stride
from magyro.options import Options
from magyro.result.reported import REPORTED, std_from_covariance
from magyro.session import Session
from magyro.studies.scenario import Scenario
from magyro.studies.simulate import field_i, mag_from_attitude, simulate, truth_attitude


def truth_linearisation(problem: Scenario, t_node_s: np.ndarray) -> Linearisation:
    """The true parameters and attitude at the nodes, re-based so node 0 is the inertial frame."""
    C = truth_attitude(problem, t_node_s)
    C_rebased = np.einsum("ji,njk->nik", C[0], C)
    m0 = C[0].T @ field_i(problem)
    S0 = np.linalg.inv(problem.R)
    return Linearisation(S0, np.asarray(problem.hard_iron, float), problem.K, problem.eps_m_rad_s, m0, C_rebased,
                         float(np.mean(np.diag(S0))), problem.mag_time_offset_s)


def cramer_rao_covariance(problem: Scenario, session: Session, options: Options | None = None,
                          nls: NLS | None = None) -> np.ndarray:
    """CRLB covariance of the reported vector (result.REPORTED layout), for the NLS method `nls` (default NLS())."""
    options, nls = options or Options(), nls or NLS()
    s = moving_session(session, options)[0]
    grid = build_grid(s.t_gyro_s, s.gyro_rad_s, s.t_mag_s, nls.stride or default_stride(s))
    lin = truth_linearisation(problem, grid.t_node_s)
    jp = JointProblem(grid, compiled=nls.compiled, estimate_time_offset=options.estimate_time_offset)
    p = jp.parameters(lin, s.mag, problem.mag_noise_std, problem.gyro_noise_density_rad_s_sqrt_hz,
                      s.t_gyro_s, s.gyro_rad_s, s.t_mag_s, problem.mag_time_offset_s)
    return information_covariance(jp, lin, p)


def with_start_pose(problem: Scenario, start_pose_deg) -> Scenario:
    """The problem with its motion started from another pose: C0 = [roll, pitch, yaw] deg from ENU."""
    motion = dataclasses.replace(problem.motion, initial_euler_deg=np.array(start_pose_deg, dtype=float))
    return dataclasses.replace(problem, motion=motion)


def cramer_rao_at_poses(problem: Scenario, start_poses_deg, options: Options | None = None, nls: NLS | None = None,
                        jacobians: dict | None = None) -> list[np.ndarray]:
    """`cramer_rao_covariance` of the problem's noise-seed-0 session started from each pose (`with_start_pose`),
    the same numbers at a fraction of the cost: the start pose C0 moves only the field in the device. The
    gyro readings, the attitude relative to t = 0 (C_m^i) and so the grid and the problem's graph are the
    same from every pose, and so is the noise (the same draws); per pose only the magnetometer readings
    (`simulate.mag_from_attitude`), the field m^i and the information differ. `jacobians` keeps the
    propagation's Jacobian of each pose across calls (`information.propagate`)."""
    return [information_covariance(jp, lin, p, jacobians=jacobians)
            for jp, lin, p, _ in problems_at_poses(problem, start_poses_deg, options, nls)]


def problems_at_poses(problem: Scenario, start_poses_deg, options: Options | None = None, nls: NLS | None = None):
    """Per start pose, in order: (joint problem, linearisation at the truth, its parameter vector, the moving
    session), as `cramer_rao_at_poses` describes: one simulated session, its magnetometer readings re-made per pose,
    the problem's graph built once per moving span."""
    options, nls = options or Options(), nls or NLS()
    at = [with_start_pose(problem, pose) for pose in start_poses_deg]
    session, _ = simulate(at[0], 0)
    C_m_i = truth_attitude(at[0], session.t_mag_s - problem.mag_time_offset_s)
    mag_noise = session.mag - mag_from_attitude(at[0], C_m_i)
    built: dict[tuple, tuple] = {}      # the moving span -> (joint problem, linearisation at pose 0, C_m^i at node 0)
    for pose_problem in at:
        posed = dataclasses.replace(session, mag=mag_from_attitude(pose_problem, C_m_i) + mag_noise)
        s = moving_session(posed, options)[0]
        span = (s.t_gyro_s[0], s.t_gyro_s[-1], s.t_mag_s[0], s.t_mag_s[-1])
        if span not in built:
            grid = build_grid(s.t_gyro_s, s.gyro_rad_s, s.t_mag_s, nls.stride or default_stride(s))
            jp = JointProblem(grid, compiled=nls.compiled, estimate_time_offset=options.estimate_time_offset)
            built[span] = (jp, truth_linearisation(at[0], grid.t_node_s), truth_attitude(at[0], grid.t_node_s[:1])[0])
        jp, lin, C_node0 = built[span]
        lin = dataclasses.replace(lin, m0=C_node0.T @ field_i(pose_problem))     # truth_linearisation's m0
        p = jp.parameters(lin, s.mag, problem.mag_noise_std, problem.gyro_noise_density_rad_s_sqrt_hz,
                          s.t_gyro_s, s.gyro_rad_s, s.t_mag_s, problem.mag_time_offset_s)
        yield jp, lin, p, s


def cramer_rao_std(problem: Scenario, session: Session, options: Options | None = None, nls: NLS | None = None) -> dict:
    """CRLB one-sigma of every reported parameter (laid out like Calibration.std)."""
    return std_from_covariance(cramer_rao_covariance(problem, session, options, nls))


def euler_jacobian_deg_per_rad(C: np.ndarray, step: float = 1e-6) -> np.ndarray:
    """d dcm2eul(C Exp(x)) / dx at x = 0, deg per rad (3x3, central differences)."""
    J = np.empty((3, 3))
    for k in range(3):
        e = np.zeros(3)
        e[k] = step
        J[:, k] = (so3.dcm_to_euler(C @ so3.exp_so3(e)) - so3.dcm_to_euler(C @ so3.exp_so3(-e))) / (2 * step)
    return J


def euler_std_deg(C_b_m: np.ndarray, covariance: np.ndarray) -> np.ndarray:
    """One-sigma of [roll, pitch, yaw] of C_b^m (deg) from a reported-vector covariance: J cov(d) J^T.

    d is the misalignment vector (C_true = C_est Exp(d)), in deg in the reported vector.
    """
    sl = REPORTED["misalignment_deg"]
    cov_d_rad = np.deg2rad(np.deg2rad(covariance[sl, sl]))
    J = euler_jacobian_deg_per_rad(C_b_m)
    return np.sqrt(np.maximum(np.diag(J @ cov_d_rad @ J.T), 0.0))
