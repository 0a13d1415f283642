"""The attitudes eliminated from the joint problem's Gauss-Newton information (`Reduced`, `reduce_hessian`):
the marginal information of the calibration corrections by a sparse LDL of the block-tridiagonal attitude block,
the Gauss-Newton decrement, and the marginal covariance of each node's attitude. magyro.nls.information turns
the reduced information into the std; magyro.nls.disturbance adds the room's field to it.
"""
from __future__ import annotations

from dataclasses import dataclass

import casadi as ca
import numpy as np


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


def block_tridiagonal_inverse_band(A: np.ndarray, B: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(diagonal blocks, upper off-diagonal blocks) of the inverse of a symmetric positive definite
    block-tridiagonal matrix (diagonal blocks A, upper blocks B), in O(n): Schur complements forward, then
    backward G_k = S_k^-1 + F_k G_k+1 F_k^T and G_k,k+1 = -F_k G_k+1 with F_k = S_k^-1 B_k."""
    n = len(A)
    S_inv = np.empty_like(A)
    S = A[0]
    for k in range(n):
        if k:
            S = A[k] - B[k - 1].T @ S_inv[k - 1] @ B[k - 1]
        S_inv[k] = np.linalg.inv(S)
    G, U = np.empty_like(A), np.empty_like(B)
    G[-1] = S_inv[-1]
    for k in range(n - 2, -1, -1):
        F = S_inv[k] @ B[k]
        U[k] = -F @ G[k + 1]
        G[k] = S_inv[k] - U[k] @ F.T
    return G, U


def block_tridiagonal_inverse_diagonal(A: np.ndarray, B: np.ndarray) -> np.ndarray:
    """The diagonal blocks of that inverse (`block_tridiagonal_inverse_band`), symmetrised."""
    G = block_tridiagonal_inverse_band(A, B)[0]
    return 0.5 * (G + G.transpose(0, 2, 1))
