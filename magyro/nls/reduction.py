"""The attitudes eliminated from the joint problem's Gauss-Newton information (`Reduced`, `reduce_hessian`):
the marginal information of the calibration corrections by a sparse LDL of the block-tridiagonal attitude block,
the Gauss-Newton decrement, and the marginal covariance of each node's attitude. magyro.nls.information turns
the reduced information into the std; magyro.nls.disturbance adds the room's field to it.
"""
from __future__ import annotations

from dataclasses import dataclass

import casadi as ca
import numpy as np

from magyro.nls.banded import cho_solve_banded, cholesky_banded


@dataclass(frozen=True)
class Reduced:
    """J^T J with the trajectory eliminated: the marginal information of the calibration corrections."""

    information: np.ndarray   # Schur complement H_tt - H_tp D^-1 H_pt
    H_tp: np.ndarray
    diagonal: np.ndarray      # the attitude block D's diagonal blocks (n, b, b), full symmetric
    upper: np.ndarray         # its upper off-diagonal blocks D[k, k+1] (n-1, b, b)
    factor: object            # D's factorisation: the banded Cholesky (scipy's upper form), or (Linsol, D) where
                              # D is not positive definite (the sparse LDL of CasADi)
    Dinv_Hpt: np.ndarray      # D^-1 H_pt
    block: int = 3            # unknowns per node: phi (3), and the hard iron's walk (3) when it moves

    def solve_D(self, b: np.ndarray) -> np.ndarray:
        if isinstance(self.factor, tuple):
            solver, D = self.factor
            return np.array(solver.solve(D, ca.DM(b))).reshape(np.shape(b))
        return cho_solve_banded((self.factor, False), b)


def reduce_hessian(H_triu, G: int, block: int = 3) -> Reduced:
    """Eliminate the attitudes (after the first G unknowns) from triu(J^T J): the attitude block is block
    tridiagonal, so a banded Cholesky (bandwidth 2 block - 1) factorises it in O(N); no dense N x N matrix is ever
    formed. The blocks are read off the nonzeros in the order of `problem.hessian_sparsity` (no sparse slicing of
    the 2.7M nonzeros at 360k samples); another pattern is read through its triplets."""
    H_tt, H_tp, A, U = hessian_blocks(H_triu, G, block)
    try:
        factor = cholesky_banded(banded_upper(A, U))
        Dinv_Hpt = cho_solve_banded((factor, False), H_tp.T)
    except np.linalg.LinAlgError:   # not positive definite (a forced solve of a motion that excites too little)
        if isinstance(H_triu, np.ndarray):
            from magyro.nls.problem import hessian_sparsity
            H_triu = ca.DM(hessian_sparsity(len(A), G, block), H_triu)
        D_triu = H_triu[G:, G:]
        D = D_triu + ca.triu(D_triu, False).T
        solver = ca.Linsol("attitude_block", "ldl", D.sparsity())
        solver.sfact(D)
        solver.nfact(D)
        factor = (solver, D)
        Dinv_Hpt = np.array(solver.solve(D, ca.DM(H_tp.T)))
    return Reduced(H_tt - H_tp @ Dinv_Hpt, H_tp, A, U, factor, Dinv_Hpt, block)


def hessian_blocks(H_triu, G: int, b: int) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """(H_tt (G, G) full, H_tp (G, b n), D's diagonal blocks (n, b, b) full, its upper blocks (n-1, b, b)) of triu(H):
    a DM, or the nonzeros (numpy) of a Hessian in the order of `problem.hessian_sparsity`."""
    sizes = [G + b + c + 1 for c in range(b)]
    n_tt = G * (G + 1) // 2
    if isinstance(H_triu, np.ndarray):
        values = H_triu
        n = (len(values) - n_tt + b * b) // sum(sizes)
    else:
        n = (H_triu.size1() - G) // b
        expected = n_tt + n * sum(sizes) - b * b
        if H_triu.nnz() != expected or n < 1:   # not the joint problem's own pattern: the general reading
            return hessian_blocks_from_triplets(H_triu, G, b)
        values = np.array(H_triu.nonzeros())
    H_tt = np.zeros((G, G))
    rows, cols = np.triu_indices(G)
    order = np.lexsort((rows, cols))      # column-major order of the upper triangle
    H_tt[rows[order], cols[order]] = values[:n_tt]
    H_tt = H_tt + np.triu(H_tt, 1).T
    per_node = np.zeros((n, sum(sizes)))
    starts = np.cumsum([0] + sizes[:-1])
    first = np.concatenate([np.arange(o, o + G) for o in starts] + [np.arange(o + G + b, o + s) for o, s in zip(starts, sizes)])
    first.sort()
    per_node[0, first] = values[n_tt : n_tt + len(first)]
    per_node[1:] = values[n_tt + len(first):].reshape(n - 1, sum(sizes))
    H_tp = np.empty((G, n, b))
    A = np.zeros((n, b, b))
    U = np.zeros((n, b, b))     # U[k] = D[k-1, k]; U[0] unused
    for c, o in enumerate(starts):
        H_tp[:, :, c] = per_node[:, o : o + G].T
        U[:, :, c] = per_node[:, o + G : o + G + b]
        A[:, : c + 1, c] = per_node[:, o + G + b : o + G + b + c + 1]
    A = A + np.triu(A, 1).transpose(0, 2, 1)
    return H_tt, H_tp.reshape(G, n * b), A, U[1:]


def hessian_blocks_from_triplets(H_triu: ca.DM, G: int, b: int):
    """`hessian_blocks` of any upper-triangular pattern (block tridiagonal past the first G unknowns)."""
    H_tt = np.array(ca.densify(H_triu[:G, :G]))
    H_tt = H_tt + np.triu(H_tt, 1).T
    H_tp = np.array(ca.densify(H_triu[:G, G:]))
    D_triu = H_triu[G:, G:]
    A, U = tridiagonal_blocks(D_triu + ca.triu(D_triu, False).T, b)
    return H_tt, H_tp, A, U


def banded_upper(A: np.ndarray, U: np.ndarray) -> np.ndarray:
    """The symmetric block-tridiagonal matrix (diagonal blocks A, upper blocks U) in LAPACK's upper banded form
    (bandwidth 2 b - 1): ab[u + i - j, j] = D[i, j] for i <= j."""
    n, b = A.shape[0], A.shape[1]
    m, u = n * b, 2 * b - 1
    ab = np.zeros((u + 1, m))
    for r in range(b):                       # row r of every diagonal block, columns r..b-1
        for c in range(r, b):
            ab[u + r - c, np.arange(n) * b + c] = A[:, r, c]
    for r in range(b):                       # the upper blocks: row k b + r, column (k + 1) b + c
        for c in range(b):
            ab[u + r - (b + c), np.arange(1, n) * b + c] = U[:, r, c]
    return ab


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
    A, B = red.diagonal, red.upper
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
