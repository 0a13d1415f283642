"""The joint problem's kernels evaluated on numpy for IPOPT and the std, without an MX graph of the whole problem.

`MapOnNumpy` runs a kernel over every interval a piece at a time, its arguments pointers into x and the parameter
vector p; `OnNumpy` and `KeptHessian` are the callbacks nlpsol calls for the objective, its gradient and the
Gauss-Newton Hessian, with the parameters of the running `JointProblem.solve` (the NLP itself has none: no DM, no
pattern and no work copy of the 8.5M parameters of 360k samples). Every number is the one the MX graphs gave, bit
for bit: the same kernels, summed over the intervals in the same order.
"""
from __future__ import annotations

import casadi as ca
import numpy as np

MAP_CHUNK = 1024   # intervals per evaluation of a kernel's map


class MapOnNumpy:
    """A kernel over every interval (theta and g shared), evaluated on numpy through buffers, MAP_CHUNK intervals
    at a time: theta, the two nodes' states and the intervals' data are pointers into x (with a leading zero state)
    and p, the outputs land in arrays allocated once; no pattern or work vector spans the whole problem (a map over
    all 30,000 intervals of 360k samples held ~300 MB of patterns of its dense inputs and outputs). The outputs
    listed in `summed` are summed over the intervals in their order, one after another, as CasADi's map and sum2
    sum them (the same numbers bit for bit). The returned arrays are overwritten by the next call."""

    def __init__(self, problem, fn: ca.Function, summed: tuple = ()):
        self.problem, self.fn, self.summed = problem, fn, summed
        self.maps = {}
        n = problem.n_int
        self.out = [np.zeros(fn.nnz_out(i) * (1 if i in summed else n)) for i in range(fn.n_out())]
        self.rows = {i: np.zeros((min(MAP_CHUNK, n) + 1, fn.nnz_out(i))) for i in summed}

    def _map(self, m: int):
        if m not in self.maps:
            fmap = self.fn.map(m, [True, False, False, True, False], [False] * self.fn.n_out(), {})
            self.maps[m] = (fmap, *fmap.buffer())
        return self.maps[m]

    def __call__(self, x: np.ndarray, p: np.ndarray) -> list[np.ndarray]:
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
                    buffer.set_res(i, memoryview(o[a * k : b * k]))
            run()
            for i in self.summed:
                self.out[i][:] = np.cumsum(self.rows[i][: b - a + 1], axis=0)[-1]
        return self.out


def half_sum_of_squares(r: np.ndarray, block: int = 65536) -> float:
    """0.5 |r|^2 summed in r's order, one term after another, as CasADi's sumsqr sums (bit for bit)."""
    total = 0.0
    for a in range(0, r.size, block):
        total = float(np.cumsum(np.concatenate([[total], r[a : a + block] ** 2]))[-1])
    return 0.5 * total


class OnNumpy(ca.Callback):
    """A function of x alone for IPOPT (nlpsol's objective and gradient), evaluated through buffers by
    `fn(x, p)` with the parameters `p` of the running `JointProblem.solve`: no DM is made of x or of p."""

    def __init__(self, problem, name: str, out: list, fn):
        ca.Callback.__init__(self)
        self.n_x, self.out, self.fn, self.p = problem.n_x, out, fn, None
        self.construct(name, {})

    def get_n_in(self):
        return 1

    def get_n_out(self):
        return len(self.out)

    def get_sparsity_in(self, i):
        return ca.Sparsity.dense(self.n_x, 1)

    def get_sparsity_out(self, i):
        return self.out[i]

    def has_eval_buffer(self):
        return True

    def eval_buffer(self, arg, res):
        x = np.frombuffer(arg[0], dtype=float)
        for i, v in enumerate(self.fn(x, self.p)):
            np.frombuffer(res[i], dtype=float)[:] = v
        return 0


class KeptHessian(ca.Callback):
    """IPOPT's hess_lag, lam_f J^T J, keeping the last J^T J it evaluated (its nonzeros): at convergence the std is
    taken from it (the Gauss-Newton Hessian of the last iterate: one evaluation of the Gauss-Newton kernel over
    every interval saved, 1.2-1.5 s at 360k samples). The parameters are those of the running
    `JointProblem.solve`. Evaluated through buffers: no DM is made of x, of the 8.5M parameters or of H."""

    def __init__(self, problem):
        ca.Callback.__init__(self)
        self.problem, self.n_x = problem, problem.n_x
        self.p, self.last = None, None
        self.construct("kept_gauss_newton_hessian", {})

    def start(self, p: np.ndarray) -> None:
        """Before a solve: its parameters."""
        self.p, self.last = p, None

    def stop(self) -> None:
        pass

    def get_n_in(self):
        return 2

    def get_n_out(self):
        return 1

    def get_sparsity_in(self, i):
        return ca.Sparsity.dense(self.n_x, 1) if i == 0 else ca.Sparsity.dense(1, 1)

    def get_sparsity_out(self, i):
        return self.problem.hessian_pattern

    def has_eval_buffer(self):
        return True

    def eval_buffer(self, arg, res):
        x = np.frombuffer(arg[0], dtype=float).copy()
        lam_f = float(np.frombuffer(arg[1], dtype=float)[0])
        values = self.problem.hessian_values(x, self.p)
        self.last = (x, values)
        np.multiply(values, lam_f, out=np.frombuffer(res[0], dtype=float))
        return 0
