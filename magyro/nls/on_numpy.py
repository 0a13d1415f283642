"""The joint problem's kernels evaluated on numpy for IPOPT and the std, without an MX graph of the whole problem.

`MapOnNumpy` runs a kernel over every interval a piece at a time, its arguments pointers into x and the parameter
vector p; `OnNumpy` and `KeptHessian` are the callbacks nlpsol calls for the objective, its gradient and the
Gauss-Newton Hessian, with the parameters of the running `JointProblem.solve` (the NLP itself has none: no DM, no
pattern and no work copy of the 5.5M parameters (42 MB) of 360k samples). Every number is the one the MX graphs gave, bit
for bit: the same kernels, summed over the intervals in the same order.
"""
from __future__ import annotations

import ctypes

import casadi as ca
import numpy as np

MAP_CHUNK = 256   # intervals per evaluation of a kernel's map: as fast as 1024 per interval, and building a map
                  # grows faster than its length (the three of 833 intervals took 10-20 ms more than of 256)


class MapOnNumpy:
    """A kernel over every interval (theta and g shared), evaluated on numpy through buffers, MAP_CHUNK intervals
    at a time: theta, the two nodes' states and the intervals' data are pointers into x (with a leading zero state)
    and p; no pattern or work vector spans the whole problem (a map over all 30,000 intervals of 360k samples held
    ~300 MB of patterns of its dense inputs and outputs). The outputs listed in `summed` are summed over the
    intervals in their order, one after another, as CasADi's map and sum2 sum them (the same numbers bit for bit).
    The others land in arrays over every interval allocated once, or, with `pieces`, in arrays of one piece handed
    to `consume(a, b, outputs)` for intervals a..b-1 (nothing over every interval is held). The returned arrays are
    overwritten by the next call."""

    def __init__(self, problem, fn: ca.Function, summed: tuple = (), pieces: bool = False):
        self.problem, self.fn, self.summed, self.pieces = problem, fn, summed, pieces
        self.maps = {}
        n = problem.n_int
        per = min(MAP_CHUNK, n) if pieces else n
        self.out = [np.zeros(fn.nnz_out(i) * (1 if i in summed else per)) for i in range(fn.n_out())]
        self.rows = {i: np.zeros((min(MAP_CHUNK, n) + 1, fn.nnz_out(i))) for i in summed}

    def _map(self, m: int):
        if m not in self.maps:
            fmap = self.fn.map(m, [True, False, False, True, False], [False] * self.fn.n_out(), {})
            self.maps[m] = (fmap, *fmap.buffer())
        return self.maps[m]

    def __call__(self, x: np.ndarray, p: np.ndarray, consume=None) -> list[np.ndarray]:
        problem, B, G, nd = self.problem, self.problem.B, self.problem.n_theta, self.problem.n_data
        x = np.asarray(x, dtype=float).reshape(-1)
        p = np.asarray(p, dtype=float).reshape(-1)
        states = np.zeros(B + x.size - G)   # node 0's state (zero) and then every unknown node's
        states[B:] = x[G:]
        theta, g, D = np.array(x[:G]), np.array(problem.globals_of(p)), p[problem.n_lead * nd :]
        for i in self.summed:
            self.out[i][:] = 0.0
        for a in range(0, problem.n_int, MAP_CHUNK):
            b = min(a + MAP_CHUNK, problem.n_int)
            fmap, buffer, run = self._map(b - a)
            args = [theta, states[a * B : b * B], states[(a + 1) * B : (b + 1) * B], g, D[a * nd : b * nd]]
            for i, v in enumerate(args):
                assert v.flags.c_contiguous and v.size == fmap.nnz_in(i), (fmap.name(), i, v.size, fmap.nnz_in(i))
                buffer.set_arg(i, memoryview(v))
            for i, o in enumerate(self.out):
                k = self.fn.nnz_out(i)
                if i in self.summed:
                    rows = self.rows[i]
                    rows[0] = o
                    buffer.set_res(i, memoryview(rows[1 : b - a + 1].reshape(-1)))
                else:
                    buffer.set_res(i, memoryview(o[: (b - a) * k] if self.pieces else o[a * k : b * k]))
            run()
            for i in self.summed:
                self.out[i][:] = np.cumsum(self.rows[i][: b - a + 1], axis=0)[-1]
            if consume is not None:
                consume(a, b, [o if i in self.summed else o[: (b - a) * self.fn.nnz_out(i)]
                               for i, o in enumerate(self.out)])
        return self.out


def sum_of_squares(r: np.ndarray, total: float = 0.0, block: int = 65536) -> float:
    """total + |r|^2 summed in r's order, one term after another, as CasADi's sumsqr sums (bit for bit): a sum over
    pieces, each continuing the last one's total, is the same sum."""
    for a in range(0, r.size, block):
        total = float(np.cumsum(np.concatenate([[total], r[a : a + block] ** 2]))[-1])
    return total


class GaussNewtonProducts:
    """The Gauss-Newton parts of a piece of intervals from their Jacobians J = [J_theta, J_k, J_k1] (the Jacobian
    kernel's output, each interval's J a C-ordered (residuals, G + 2B) block): each interval's triu(J_theta^T
    J_theta) added to the running H_tt, and P = J^T [J_k, J_k1], whose entries are each interval's first- and
    second-node columns of triu(J^T J) in compressed-column order (problem.hessian_sparsity: per column c of a node
    the G theta rows, the previous node's B rows, the node's own rows 0..c; the first node's previous rows are zero,
    interval k-1 holds them). Summed in the order of the SX kernel that had the products inside (interval.
    GAUSS_NEWTON_C, compiled; numpy in the same order without a compiler), so the Hessian is that kernel's bit for
    bit; at 360k samples a Hessian takes 0.44 s CPU so against 0.86 s with the products inside the kernel (0.42 s
    with BLAS's products, whose summation order changed estimates by up to 9e-7 of their std and Table I's text)."""

    def __init__(self, G: int, B: int, compiled: bool = True):
        from magyro.nls.interval import gauss_newton_products

        self.G, self.B = G, B
        W = 2 * B   # P's columns: J_k's then J_k1's
        first, second = [], []
        for c in range(B):
            first += [i * W + c for i in range(G)] + [-1] * B + [(G + i) * W + c for i in range(c + 1)]
            second += ([i * W + B + c for i in range(G)] + [(G + i) * W + B + c for i in range(B)]
                       + [(G + B + i) * W + B + c for i in range(c + 1)])
        self.first, self.second = np.array(first), np.array(second)
        self.zero = self.first < 0      # the first node's previous-node rows
        self.first[self.zero] = 0
        self.size = len(second)
        self.n_tt = G * (G + 1) // 2
        self.triu = np.array([i * G + j for j in range(G) for i in range(j + 1)])   # triu's compressed-column order
        self.c_parts = gauss_newton_products(compiled)
        self.tmp = np.zeros((G, G))

    def __call__(self, J: np.ndarray, H_tt: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """J (m, residuals, G + 2B), C-contiguous: adds the m intervals' triu(J_theta^T J_theta) to H_tt (G, G, its
        upper triangle) one after another and returns their (first-node, second-node) parts, (m, size) each."""
        m, R, N = J.shape
        G = self.G
        if self.c_parts is not None:
            P = np.empty((m, N, N - G))
            assert J.flags.c_contiguous and H_tt.flags.c_contiguous and H_tt.shape == (G, G)
            pointer = ctypes.POINTER(ctypes.c_double)
            self.c_parts(m, R, N, G, *(v.ctypes.data_as(pointer) for v in (J, H_tt, P, self.tmp)))
        else:   # the same sums in the same order: over the residuals from zero, then interval after interval
            each = np.zeros((m, G, G))
            P = np.zeros((m, N, N - G))
            for r in range(R):
                row = J[:, r, :]
                each += row[:, :G, None] * row[:, None, :G]
                P += row[:, :, None] * row[:, None, G:]
            H_tt[:] = np.cumsum(np.concatenate([H_tt[None], each]), axis=0)[-1]
        P = P.reshape(m, -1)
        F = P[:, self.first]
        F[:, self.zero] = 0.0
        return F, P[:, self.second]

    def theta_block(self, H_tt: np.ndarray) -> np.ndarray:
        """triu(H_tt)'s nonzeros in compressed-column order."""
        return H_tt.reshape(-1)[self.triu]


def node_columns_in(out: np.ndarray, n_tt: int, node_1: np.ndarray, n_int: int, size: int):
    """`consume` for the Gauss-Newton parts (triu(J_theta^T J_theta) summed, each interval's first- and second-node
    columns): node k's columns, interval k's second-node part plus interval k+1's first-node part (the last
    interval's alone), written piece by piece into triu(J^T J)'s nonzeros `out` after its n_tt theta values, node 1
    (k = 0) without a previous node's rows (`node_1`). Returns (consume, finish(H_tt))."""
    n_1 = len(node_1)
    cols = out[n_tt + n_1 :].reshape(n_int - 1, size)   # nodes k = 1 .. n_int - 1
    pending = [None]   # interval a-1's second-node part, waiting for interval a's first-node part

    def put(k: int, values: np.ndarray) -> None:
        if k == 0:
            out[n_tt : n_tt + n_1] = values[node_1]
        else:
            cols[k - 1] = values

    def consume(a: int, b: int, outputs) -> None:
        F, S = outputs[1].reshape(b - a, size), outputs[2].reshape(b - a, size)
        if pending[0] is not None:
            put(a - 1, pending[0] + F[0])
        first = a
        if a == 0 and b - a > 1:
            put(0, S[0] + F[1])
            first = 1
        if b - 1 > first:   # nodes first .. b-2 whole within this piece
            np.add(S[first - a : b - 1 - a], F[first - a + 1 : b - a], out=cols[first - 1 : b - 2])
        pending[0] = S[b - 1 - a].copy()

    def finish(H_tt: np.ndarray) -> np.ndarray:
        put(n_int - 1, pending[0])
        out[:n_tt] = H_tt
        return out
    return consume, finish


class OnNumpy(ca.Callback):
    """A function for nlpsol (its objective of x, or grad_f of (x, p) with an empty p), evaluated through buffers by
    `fn(x, p)` with the parameters `p` of the running `JointProblem.solve`: no DM is made of x or of p."""

    def __init__(self, problem, name: str, names_in: list, out: dict, fn):
        ca.Callback.__init__(self)
        self.n_x, self.names_in, self.names_out, self.out = problem.n_x, names_in, list(out), list(out.values())
        self.fn, self.p = fn, None
        self.construct(name, {})

    def get_n_in(self):
        return len(self.names_in)

    def get_n_out(self):
        return len(self.out)

    def get_name_in(self, i):
        return self.names_in[i]

    def get_name_out(self, i):
        return self.names_out[i]

    def get_sparsity_in(self, i):
        return ca.Sparsity.dense(self.n_x if i == 0 else 0, 1)

    def get_sparsity_out(self, i):
        return self.out[i]

    def has_eval_buffer(self):
        return True

    def eval_buffer(self, arg, res):
        x = np.frombuffer(arg[0], dtype=float)
        for i, v in enumerate(self.fn(x, self.p)):
            if res[i] is not None:   # an output nobody asked for
                np.frombuffer(res[i], dtype=float)[:] = v
        return 0


class KeptHessian(ca.Callback):
    """IPOPT's hess_lag (x, p, lam_f, lam_g) -> lam_f J^T J (p and lam_g empty), evaluated straight into IPOPT's
    array with the parameters of the running `JointProblem.solve`, keeping the point of the last evaluation: at
    convergence the std is taken from J^T J there (`JointProblem.last_hessian_point`), evaluated again once IPOPT
    has given its memory back. A copy of every Hessian kept for that (21 MB at 360k samples) sat on top of IPOPT's
    and MUMPS's matrices at the solve's high-water mark; the evaluation again costs one Hessian per calibration
    (0.45 s CPU at 360k samples). No DM is made of x, of the parameters or of H, and no MX function wraps it (its
    work copy of H)."""

    def __init__(self, problem):
        ca.Callback.__init__(self)
        self.problem, self.n_x = problem, problem.n_x
        self.p, self.last = None, None
        self.construct("nlp_hess_l", {})

    def start(self, p: np.ndarray) -> None:
        """Before a solve: its parameters."""
        self.p, self.last = p, None

    def get_n_in(self):
        return 4

    def get_n_out(self):
        return 1

    def get_name_in(self, i):
        return ["x", "p", "lam_f", "lam_g"][i]

    def get_name_out(self, i):
        return "triu_hess_gamma_x_x"

    def get_sparsity_in(self, i):
        return [ca.Sparsity.dense(self.n_x, 1), ca.Sparsity.dense(0, 1), ca.Sparsity.dense(1, 1),
                ca.Sparsity.dense(0, 1)][i]

    def get_sparsity_out(self, i):
        return self.problem.hessian_pattern

    def has_eval_buffer(self):
        return True

    def eval_buffer(self, arg, res):
        x = np.frombuffer(arg[0], dtype=float).copy()
        lam_f = float(np.frombuffer(arg[2], dtype=float)[0])
        values = self.problem.hessian_values(x, self.p, out=np.frombuffer(res[0], dtype=float))
        np.multiply(values, lam_f, out=values)
        self.last = x
        return 0
