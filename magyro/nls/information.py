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

from dataclasses import dataclass

import casadi as ca
import numpy as np

from magyro.front.prepare import Prepared
from magyro.nls.method import NLS
from magyro.options import Options
from magyro.nls.problem import JointProblem, Linearisation
from magyro.nls.solve import build_problem, problem_parameters
from magyro.result.reported import N_REPORTED, qr_split, reported_vector, std_from_covariance


@dataclass(frozen=True)
class Reduced:
    """J^T J with the trajectory eliminated: the marginal information of the calibration corrections."""

    information: np.ndarray   # Schur complement H_tt - H_tp D^-1 H_pt
    H_tp: np.ndarray
    D: ca.DM                  # the attitude block (sparse, block tridiagonal), full symmetric
    D_solver: ca.Linsol       # its sparse LDL factorisation
    Dinv_Hpt: np.ndarray      # D^-1 H_pt
    block: int = 3            # unknowns per node: phi (3), and the hard iron's walk (3) when it moves

    def solve_D(self, b: np.ndarray) -> np.ndarray:
        return np.array(self.D_solver.solve(self.D, ca.DM(b))).reshape(np.shape(b))


def reduce_hessian(H_triu: ca.DM, G: int, block: int = 3) -> Reduced:
    """Eliminate the attitudes (after the first G unknowns) from triu(J^T J) by a sparse LDL
    of the block-tridiagonal attitude block: no dense N x N matrix is ever formed."""
    H_tt = np.array(ca.densify(H_triu[:G, :G]))
    H_tt = H_tt + np.triu(H_tt, 1).T
    H_tp_dm = ca.densify(H_triu[:G, G:])
    H_tp = np.array(H_tp_dm)
    D_triu = H_triu[G:, G:]
    D = D_triu + ca.triu(D_triu, False).T
    solver = ca.Linsol("attitude_block", "ldl", D.sparsity())
    solver.sfact(D)
    solver.nfact(D)
    Dinv_Hpt = np.array(solver.solve(D, H_tp_dm.T))   # the right-hand side stays a DM: no numpy round trip
    return Reduced(H_tt - H_tp @ Dinv_Hpt, H_tp, D, solver, Dinv_Hpt, block)


def gauss_newton_decrement(red: Reduced, grad) -> float:
    """g^T H^-1 g: how much the objective (chi^2 units) a further Gauss-Newton step would still remove."""
    G = red.H_tp.shape[0]
    g_t, g_p = grad[:G], grad[G:]
    Dinv_gp = red.solve_D(g_p)
    x_t = np.linalg.solve(red.information, g_t - red.H_tp @ Dinv_gp)
    x_p = Dinv_gp - red.Dinv_Hpt @ x_t
    return float(g_t @ x_t + g_p @ x_p)


def propagate(problem: JointProblem, theta, g, cov_theta, C_ref) -> np.ndarray:
    """Covariance of the reported vector by central differences through R = S^-1 and the QR split."""
    def f(th):
        S, h, K, eps, m, tau = (np.array(v) for v in problem.physical_function(th, g))
        return reported_vector(K, eps.ravel(), S, h.ravel(), m.ravel(), C_ref, float(tau.item()))

    step = 1e-6
    n = problem.n_theta
    J = np.empty((len(f(theta)), n))
    for i in range(n):
        e = np.zeros(n)
        e[i] = step
        J[:, i] = (f(theta + e) - f(theta - e)) / (2 * step)
    return J @ cov_theta @ J.T


def information_covariance(problem: JointProblem, lin: Linearisation, p, session=None) -> np.ndarray:
    """Covariance of the reported vector (result.REPORTED layout) from the Gauss-Newton information
    at the linearisation point; all inf where the information is singular (a direction the data do not see).

    Given the `session`, the field disturbance it shows is counted as the solve counts it
    (`magyro.nls.disturbance`); without, the white-noise covariance (the Cramer-Rao bound of a simulation).
    """
    return covariance_and_disturbance(problem, lin, p, session)[0]


def covariance_and_disturbance(problem: JointProblem, lin: Linearisation, p, session=None):
    """(`information_covariance`, the field disturbance measured from `session`, or None without one)."""
    reduced = reduce_hessian(problem.hessian_function(np.zeros(problem.n_x), p), problem.n_theta, problem.B)
    lam = np.linalg.eigvalsh(reduced.information)
    if lam[0] <= lam[-1] * 1e-14:
        return np.full((N_REPORTED, N_REPORTED), np.inf), None
    disturbance = None
    if session is None:
        cov_theta = np.linalg.inv(reduced.information)
    else:
        from magyro.nls.disturbance import disturbance_covariance

        cov_theta, disturbance = disturbance_covariance(problem, np.zeros(problem.n_x), p, reduced,
                                                        lin.C_m_i_nominal, session)
    C0, _ = qr_split(lin.K0)
    return propagate(problem, np.zeros(problem.n_theta), p[: problem.n_glob_p], cov_theta, C0), disturbance


def information_std(problem: JointProblem, lin: Linearisation, p, session=None) -> dict:
    """One-sigma of every reported parameter from the Gauss-Newton information at the linearisation point
    (with the `session`'s field disturbance counted, when given: see `information_covariance`)."""
    return std_from_covariance(information_covariance(problem, lin, p, session))


def predicted_std(prep: Prepared, options: Options | None = None, method: NLS | None = None) -> dict:
    """`predicted_std_and_disturbance` without the disturbance."""
    return predicted_std_and_disturbance(prep, options, method)[0]


def predicted_std_and_disturbance(prep: Prepared, options: Options | None = None, method: NLS | None = None):
    """One-sigma accuracy this recording can give, before solving.

    The Gauss-Newton (Fisher) information of the joint problem at the initial
    estimate, with the session's noise levels, trajectory marginalised out and
    propagated like the solved std. Entries are inf where the information is
    singular (unobservable). The linearisation point is the plain eq. (13)
    estimate: the lag search that the solve needs to converge changes a
    prediction by no more than the few percent it moves K. The room's field
    disturbance is measured from the recording and counted as the solve counts
    it; what cannot be predicted before solving is the magnetometer noise the
    solve re-weights to (its residuals' effective scale).
    """
    options, method = options or Options(), method or NLS()
    grid, lin, problem = build_problem(prep, options, method, search_lag=False)
    p = problem_parameters(problem, prep, lin, prep.sigma_mag, lin.time_offset_s)
    cov, disturbance = covariance_and_disturbance(problem, lin, p, prep.session)
    return std_from_covariance(cov), disturbance


def attitude_covariance_blocks(red: Reduced, cov_theta: np.ndarray | None = None) -> np.ndarray:
    """(N-1, 3, 3): the marginal covariance of each node's attitude correction phi_n, the calibration's
    uncertainty (`cov_theta`, default the inverse information) included: the diagonal blocks of
    D^-1 + (D^-1 H_pt) cov_theta (D^-1 H_pt)^T."""
    A, B = tridiagonal_blocks(red.D, red.block)
    inner = block_tridiagonal_inverse_diagonal(A, B)[:, :3, :3]
    W = red.Dinv_Hpt.reshape(len(A), red.block, -1)[:, :3]
    cov_theta = np.linalg.inv(red.information) if cov_theta is None else cov_theta
    return inner + np.einsum("nia,ab,njb->nij", W, cov_theta, W)


def tridiagonal_blocks(D: ca.DM, b: int = 3) -> tuple[np.ndarray, np.ndarray]:
    """(diagonal b x b blocks (n, b, b), upper off-diagonal blocks D[k, k+1] (n-1, b, b)) of a sparse
    block-tridiagonal matrix, read from its nonzeros (no dense matrix)."""
    rows, cols = (np.asarray(v) for v in D.sparsity().get_triplet())
    values = np.array(D.nonzeros())
    n = D.size1() // b
    A, B = np.zeros((n, b, b)), np.zeros((max(n - 1, 0), b, b))
    on = rows // b == cols // b
    A[rows[on] // b, rows[on] % b, cols[on] % b] = values[on]
    up = cols // b == rows // b + 1
    B[rows[up] // b, rows[up] % b, cols[up] % b] = values[up]
    return A, B


def block_tridiagonal_inverse_diagonal(A: np.ndarray, B: np.ndarray) -> np.ndarray:
    """The diagonal blocks of the inverse of a symmetric positive definite block-tridiagonal matrix
    (diagonal blocks A, upper blocks B), in O(n): Schur complements forward, then the inverse backward
    (G_k = S_k^-1 + S_k^-1 B_k G_k+1 B_k^T S_k^-1)."""
    n = len(A)
    S_inv = np.empty_like(A)
    S = A[0]
    for k in range(n):
        if k:
            S = A[k] - B[k - 1].T @ S_inv[k - 1] @ B[k - 1]
        S_inv[k] = np.linalg.inv(S)
    G = np.empty_like(A)
    G[-1] = S_inv[-1]
    for k in range(n - 2, -1, -1):
        F = S_inv[k] @ B[k]
        G[k] = S_inv[k] + F @ G[k + 1] @ F.T
    return 0.5 * (G + G.transpose(0, 2, 1))
