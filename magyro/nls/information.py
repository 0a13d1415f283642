"""The Gauss-Newton information of the joint problem and what follows from it.

The attitudes are eliminated by a sparse LDL of the block-tridiagonal
attitude block (no dense N x N matrix), leaving the marginal information of
the calibration corrections; its inverse is propagated through R = S^-1 and
the QR split to the reported parameters. One function serves three uses:
the std of a solve (at the solution), the accuracy `magyro observe` predicts
before solving (at the initial estimate), and the Cramer-Rao bound of
`magyro montecarlo` (at the truth).
"""
from __future__ import annotations

import numpy as np

from magyro.front.prepare import Prepared
from magyro.nls.disturbance import disturbance_covariance
from magyro.nls.method import NLS
from magyro.options import Options
from magyro.nls.interval import N_ACC_THETA
from magyro.nls.problem import JointProblem, Linearisation
from magyro.nls.reduction import (  # noqa: F401  (the attitude elimination; its names kept importable from here)
    Reduced, attitude_covariance_blocks, block_tridiagonal_inverse_diagonal, gauss_newton_decrement, reduce_hessian,
    tridiagonal_blocks)
from magyro.nls.solve import build_problem, problem_parameters
from magyro.result.reported import N_REPORTED, qr_split, reported_vector, std_from_covariance


def propagate(problem: JointProblem, theta, g, cov_theta, C_ref, jacobians: dict | None = None) -> np.ndarray:
    """Covariance of the reported vector by central differences through R = S^-1 and the QR split. The Jacobian
    depends on the linearisation (g, C_ref) only, not on the data: `jacobians`, a dict, keeps it across calls
    at the same point (the start poses of `magyro plan`'s search, one a pose for every motion scored)."""
    J = cached_propagation_jacobian(problem, theta, g, C_ref, jacobians)
    return J @ cov_theta @ J.T


def cached_propagation_jacobian(problem: JointProblem, theta, g, C_ref, jacobians: dict | None) -> np.ndarray:
    """`propagation_jacobian`, kept in `jacobians` (a dict, or None: not kept) under its linearisation point."""
    if jacobians is None:
        return propagation_jacobian(problem, theta, g, C_ref)
    key = (problem.n_theta, np.asarray(theta, float).tobytes(), np.asarray(g, float).tobytes(),
           np.asarray(C_ref, float).tobytes())
    if key not in jacobians:
        jacobians[key] = propagation_jacobian(problem, theta, g, C_ref)
    return jacobians[key]


def propagation_jacobian(problem: JointProblem, theta, g, C_ref) -> np.ndarray:
    """d reported vector / d theta at theta, by central differences (`propagate`)."""
    def f(th):
        S, h, K, eps, m, tau = (np.array(v) for v in problem.physical_function(th, g))
        return reported_vector(K, eps.ravel(), S, h.ravel(), m.ravel(), C_ref, float(tau.item()))

    step = 1e-6
    n = problem.n_theta
    J = np.zeros((len(f(theta)), n))   # the accelerometer's corrections move none of it: their columns are zero
    for i in range(n - (N_ACC_THETA if problem.accelerometer else 0)):
        e = np.zeros(n)
        e[i] = step
        J[:, i] = (f(theta + e) - f(theta - e)) / (2 * step)
    return J


def information_covariance(problem: JointProblem, lin: Linearisation, p, session=None,
                           jacobians: dict | None = None) -> np.ndarray:
    """Covariance of the reported vector (result.REPORTED layout) from the Gauss-Newton information
    at the linearisation point; all inf where the information is singular (a direction the data do not see).

    Given the `session`, the field disturbance it shows is counted as the solve counts it
    (`magyro.nls.disturbance`); without, the white-noise covariance (the Cramer-Rao bound of a simulation).
    `jacobians` keeps the propagation's Jacobian across calls at the same linearisation (`propagate`).
    """
    return covariance_and_disturbance(problem, lin, p, session, jacobians)[0]


def covariance_and_disturbance(problem: JointProblem, lin: Linearisation, p, session=None,
                               jacobians: dict | None = None):
    """(`information_covariance`, the field disturbance measured from `session`, or None without one)."""
    reduced = reduce_hessian(problem.hessian_values(np.zeros(problem.n_x), np.asarray(p, dtype=float)), problem.n_theta,
                             problem.B)
    lam = np.linalg.eigvalsh(reduced.information)
    if lam[0] <= lam[-1] * 1e-14:
        return np.full((N_REPORTED, N_REPORTED), np.inf), None
    disturbance = None
    if session is None:
        cov_theta = np.linalg.inv(reduced.information)
    else:
        cov_theta, disturbance = disturbance_covariance(problem, np.zeros(problem.n_x), p, reduced,
                                                        lin.C_m_i_nominal, session)
    C0, _ = qr_split(lin.K0)
    return propagate(problem, np.zeros(problem.n_theta), problem.globals_of(p), cov_theta, C0, jacobians), disturbance


def information_std(problem: JointProblem, lin: Linearisation, p, session=None) -> dict:
    """One-sigma of every reported parameter from the Gauss-Newton information at the linearisation point
    (with the `session`'s field disturbance counted, when given: see `information_covariance`)."""
    return std_from_covariance(information_covariance(problem, lin, p, session))


def predicted_std(prep: Prepared, options: Options | None = None, method: NLS | None = None) -> dict:
    """`predicted_std_and_disturbance` without the disturbance."""
    return predicted_std_and_disturbance(prep, options, method)[0]


def predicted_std_and_disturbance(prep: Prepared, options: Options | None = None, method: NLS | None = None,
                                  room: bool = True):
    """One-sigma accuracy this recording can give, before solving.

    The Gauss-Newton (Fisher) information of the joint problem at the initial
    estimate, with the session's noise levels, trajectory marginalised out and
    propagated like the solved std. Entries are inf where the information is
    singular (unobservable). The linearisation point is the plain eq. (13)
    estimate: the lag search that the solve needs to converge changes a
    prediction by no more than the few percent it moves K. The room's field
    disturbance is measured from the recording and counted as the solve counts
    it; what cannot be predicted before solving is the magnetometer noise the
    solve re-weights to (its residuals' effective scale). `room=False`: the white-noise information alone.
    """
    options, method = options or Options(), method or NLS()
    grid, lin, problem = build_problem(prep, options, method, search_lag=False)
    p = problem_parameters(problem, prep, lin, prep.sigma_mag, lin.time_offset_s)
    cov, disturbance = covariance_and_disturbance(problem, lin, p, prep.session if room else None)
    return std_from_covariance(cov), disturbance
