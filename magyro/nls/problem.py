"""The joint calibration as one nonlinear least squares in CasADi.

Decision variables, all small corrections about a linearisation point so
that IPOPT sees numbers of order one:

    U    (6)   R^-1 = S0 (I + U), U upper triangular    soft iron and field strength
    dh   (3)   h = h0 + field_scale * dh                 hard iron
    dK   (9)   K = K0 + dK   (column-major)              gyro, in the m frame
    deps (3)   eps = eps0 + deps                         rad/s
    dm   (2)   m^i = normalise(m0 + B dm)                unit field, 2 dof
    dtau (1)   time offset tau = tau0 + 0.01 s * dtau    optional: the magnetometer sample
               stamped t measures the field at t - tau (it lags the gyro)
    phi  (3 x (N-1))  attitude at nodes 1..N-1: C_m^i(tau_n) = Cbar_n Exp(phi_n)

Node 0 sits on the first magnetometer sample with C_i^m = I (the gauge of
docs/spec.md section 1, paper eq. 12). Nodes sit on every `stride`-th segment
boundary (every magnetometer and gyro time, grid.py); between them the gyro is integrated in
sub-steps ending on every gyro and magnetometer time, each a rotation by
(w_a + w_b)/2 dt + dt^2/12 (w_a x w_b), w = K y_g + eps (third-order local
error for rates linear in time). Residuals, whitened:

    magnetometer  (y_m - h - R^-1 C_i^m(t_j - tau) m^i) * w_mag        raw units, with
                  C_i^m(t - tau) = Exp(tau w(t - tau0/2)) C_i^m(t) and, optionally, a Huber
                  loss (the residual scaled to sqrt(2 rho(|r|)) / |r|); weight 0 on the
                  segments that bridge a gap in the magnetometer record (Grid)
    gyro          Winv vee(E - E^T)/2 / sqrt(T_n)                      E: mismatch of
                  the integrated gyro against the two node attitudes, Winv = L^-1 / sigma_g
                  with L L^T = K0 K0^T (the gyro noise enters through K)

One SX kernel computes an interval's residuals and, for the Gauss-Newton
Hessian, its Jacobian blocks; it is `map`ped over the intervals, a piece at a
time, on numpy (`magyro.nls.on_numpy`): IPOPT's objective, gradient and Hessian
are callbacks, so no MX graph of the whole problem and no derivative of one is
ever formed (`residual_function` builds the residuals' graph for symbolic use).
The Hessian J^T J is assembled from those blocks.
"""
from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property

import casadi as ca
import numpy as np

from magyro import so3
from magyro.memory import give_back
from magyro.nls.grid import Grid, gyro_at_mag_midpoints
from magyro.nls.on_numpy import GaussNewtonProducts, KeptHessian, MapOnNumpy, OnNumpy, node_columns_in, sum_of_squares
from magyro.nls.interval import (ACC_GLOBAL_LAYOUT, GLOBAL_LAYOUT, N_ACC_THETA, N_GLOBAL, NO_HUBER,
                                 accelerometer_jacobian, data_layout, global_size, kernel_key, kernel_set, node_size,
                                 unpack_accelerometer, unpack_globals)

SAFE_SLOTS = ("ymag", "yacc", "yrest0", "yrest1")   # data whose every use is weighted by a weight of the data
HOLE_LINK_STD_RAD = 0.1   # across a hole in the gyro record the attitudes are linked this loosely (a gauge only)


# ------------------------------------------------------------------ linearisation
@dataclass(frozen=True)
class Linearisation:
    """The point the corrections are taken about, and the noise weights."""

    S0: np.ndarray             # R0^-1
    h0: np.ndarray
    K0: np.ndarray
    eps0: np.ndarray
    m0: np.ndarray             # unit vector
    C_m_i_nominal: np.ndarray  # (N, 3, 3), node 0 = I
    field_scale: float         # typical |R^-1|, scales dh
    time_offset_s: float = 0.0  # magnetometer lag to start from
    accelerometer: object = None   # `magyro.nls.accelerometer.AccelerometerStart` when the accelerometer joins


# -------------------------------------------------------------------- the problem

class JointProblem:
    """The least squares on one grid shape; data and linearisation enter as parameters.

    With a `walk_density` (magnetometer unit / sqrt(s)) the hard iron moves: h(t) = h + field_scale * eta_n over
    the interval from node n, eta a random walk from eta_0 = 0 whose steps are weighted by the parameters'
    `w_walk` (1 / (density sqrt(dt))). The kernels depend only on whether it walks, not on the density.
    """

    def __init__(self, grid: Grid, compiled: bool = True, estimate_time_offset: bool = True, huber: float | None = None,
                 walk_density: float | None = None, accelerometer: bool = False, hand_prior=None):
        self.grid = grid
        self.compiled = compiled
        self.walk_density = walk_density
        self.huber = huber
        self.walk = walk = walk_density is not None
        self.accelerometer = acc = accelerometer
        self.hand_prior = hand_prior          # `hand_states.HandPrior`: the hand's velocity as states (with acc)
        self.hand = hand = hand_prior is not None and acc
        self.estimate_time_offset = estimate_time_offset
        self.B = node_size(walk, hand)
        self.n_theta = N_GLOBAL + (1 if estimate_time_offset else 0) + (N_ACC_THETA if acc else 0)
        n, s, L = grid.nodes, grid.stride, grid.substeps
        self.n_int = n - 1
        self.n_glob_p = global_size(acc)
        self.n_data = sum(k for _, k in data_layout(s, L, walk, acc, hand))
        self.n_x = self.n_theta + self.B * self.n_int
        # The globals ride in leading columns of the data matrix, in slots whose every use is weighted by a weight
        # that is 0 there (the magnetometer and accelerometer samples), so those columns add nothing but zeros: then
        # the kernels' map reads the parameters reshaped whole, with no slice of them (a copy of every parameter in
        # every evaluation and 136 MB of index list and pattern at 360k samples)
        offsets, o = {}, 0
        for name, k in data_layout(s, L, walk, acc, hand):
            offsets[name], o = (o, k), o + k
        safe = [a + i for name in SAFE_SLOTS if name in offsets for a, k in [offsets[name]] for i in range(k)]
        self.n_lead = -(-self.n_glob_p // len(safe))
        self.global_positions = np.array([c * self.n_data + f for c in range(self.n_lead) for f in safe][: self.n_glob_p])
        self.n_p = self.n_data * (self.n_lead + self.n_int)
        self.n_res_per_interval = 3 * s + 3 + (3 if walk else 0) + (6 if acc else 0) + (3 if hand else 0)

        self.kernel_key = kernel_key(s, L, self.n_theta, walk, hand)
        self.residual_kernel, self.gradient_kernel, self.jacobian_kernel = kernel_set(s, L, self.n_theta, walk, compiled, hand)
        th = ca.SX.sym("theta", self.n_theta)
        g = ca.SX.sym("g", self.n_glob_p)
        S, h, K, eps, m_i, tau, _, _, _ = unpack_globals(th, g)
        self.physical_function = ca.Function(
            "physical", [th, g], [S, h, K, eps, m_i, tau], ["theta", "g"], ["S", "h", "K", "eps", "m_i", "tau"]
        )
        self.accelerometer_function = ca.Function("accelerometer", [th, g], list(unpack_accelerometer(th, g)),
                                                  ["theta", "g"], ["A", "b", "u_i", "g_m_s2", "lever_m"]) if acc else None
        self._solvers, self._objective, self._gradient = {}, None, None   # IPOPT, one per set of options (`solver`)

    # ------------------------------------------------------------------ MX graph
    def _split(self, x, p):
        """The kernels' map arguments over the n_lead leading columns (zero states) and the intervals."""
        theta = x[: self.n_theta]
        phi = ca.reshape(x[self.n_theta :], self.B, self.n_int)
        lead = ca.MX.zeros(self.B, self.n_lead)
        phi_k = ca.horzcat(lead, ca.MX.zeros(self.B, 1), but_last_column(phi))   # a split: a column slice costs 7x more
        g = p[self.global_positions.tolist()]
        D = ca.reshape(p, self.n_data, self.n_lead + self.n_int)
        return theta, phi_k, ca.horzcat(lead, phi), g, D

    def _intervals(self, M):
        """M without its n_lead leading columns (those of the globals)."""
        return ca.horzsplit(M, [0, self.n_lead, M.shape[1]])[1]

    @property
    def n_map(self) -> int:
        return self.n_lead + self.n_int

    def globals_of(self, p: np.ndarray) -> np.ndarray:
        """The global parameters (`interval.GLOBAL_LAYOUT`) of a parameter vector."""
        return np.asarray(p)[self.global_positions]

    def data_of(self, p: np.ndarray) -> np.ndarray:
        """The intervals' data of a parameter vector, (n_int, n_data)."""
        return np.asarray(p)[self.n_lead * self.n_data :].reshape(self.n_int, self.n_data)

    # The residuals' MX graph, for symbolic use (derivatives in tests): the numbers come from `_maps`.
    @cached_property
    def _symbols(self):
        x = ca.MX.sym("x", self.n_x)
        p = ca.MX.sym("p", self.n_p)
        return x, p, self._split(x, p)

    @cached_property
    def _residual_graph(self):
        x, p, args = self._symbols
        r = ca.vec(self._intervals(self.residual_kernel.map(self.n_map)(*args)))
        return ca.Function("residuals", [x, p], [r]), 0.5 * ca.sumsqr(r)

    @cached_property
    def accelerometer_jacobian(self) -> ca.Function:
        """d r / d theta and d r / d s_k of each interval's accelerometer mean (interval.accelerometer_jacobian)."""
        g = self.grid
        return accelerometer_jacobian(g.stride, g.substeps, self.n_theta, self.walk, self.compiled, self.hand)

    @cached_property
    def magnetometer_jacobian_kernel(self) -> ca.Function:
        """The Jacobian kernel of this shape without the accelerometer (this problem's own without it): its theta, its
        globals and each interval's data are prefixes of this problem's (interval.data_layout and GLOBAL_LAYOUT append
        the accelerometer's), so its magnetometer and gyro rows are this problem's, without the accelerometer's work
        (the room's sandwich needs the magnetometer's rows alone: nls/disturbance.py)."""
        if not self.accelerometer:
            return self.jacobian_kernel
        g = self.grid
        return kernel_set(g.stride, g.substeps, self.n_theta - N_ACC_THETA, self.walk, self.compiled)[2]

    @property
    def residual_function(self) -> ca.Function:
        return self._residual_graph[0]

    @cached_property
    def _products(self) -> GaussNewtonProducts:
        """The Gauss-Newton parts from the intervals' Jacobians, batched on numpy (`on_numpy.GaussNewtonProducts`)."""
        return GaussNewtonProducts(self.n_theta, self.B, self.compiled)

    @cached_property
    def _node_1(self) -> np.ndarray:
        """Node 1's values among a node's column values: no previous node's rows."""
        G, B = self.n_theta, self.B
        return np.sort(np.concatenate(
            [np.arange(o, o + G) for o in column_starts(G, B)]
            + [np.arange(o + G + B, o + G + B + c + 1) for c, o in enumerate(column_starts(G, B))]))

    @cached_property
    def _maps(self) -> dict:
        """The three kernels over the intervals alone, each evaluated on numpy in pieces (`MapOnNumpy`): the states
        and the data go in by pointer, so no MX graph over the whole problem is built (at 360k samples the three
        graphs, their nlpsol and the patterns of the 5.5M parameters took ~300 MB and 1.4 s) and no evaluation
        copies the parameters into a work vector (42 MB each)."""
        return {"residuals": MapOnNumpy(self, self.residual_kernel, pieces=True),
                "gradient": MapOnNumpy(self, self.gradient_kernel, summed=(0, 1)),
                "jacobian": MapOnNumpy(self, self.jacobian_kernel, pieces=True)}

    @cached_property
    def hessian_pattern(self) -> ca.Sparsity:
        return hessian_sparsity(self.n_int, self.n_theta, self.B)

    @property
    def hessian_function(self):
        """(x, p) -> triu(J^T J) as a sparse DM (`hessian_values` gives its nonzeros without the DM)."""
        def hessian(x, p):
            x, p = (np.asarray(ca.DM(v) if not isinstance(v, np.ndarray) else v, dtype=float).ravel() for v in (x, p))
            return ca.DM(self.hessian_pattern, self.hessian_values(x, p))
        return hessian

    def solve(self, solver, x0: np.ndarray, p: np.ndarray) -> tuple[np.ndarray, dict]:
        """(the solution, IPOPT's stats): IPOPT from x0 with the parameters p, which the callbacks of the NLP read
        from numpy (the NLP has no parameter: no DM or work copy of p); the point of the last Gauss-Newton Hessian
        IPOPT evaluated is kept (`last_hessian_point`)."""
        self.callbacks()
        p = np.ascontiguousarray(p, dtype=float)
        self._kept.start(p)
        self._objective.p = self._gradient.p = p
        give_back()   # the set-up's freed temporaries, before IPOPT's matrices come on top
        buffer, run = solver.buffer()
        free = np.full(self.n_x, np.inf)
        held = {"x0": np.array(x0, dtype=float), "lbx": -free, "ubx": free}
        for name, value in held.items():
            buffer.set_arg(solver.index_in(name), memoryview(value))
        x = np.zeros(self.n_x)
        buffer.set_res(solver.index_out("x"), memoryview(x))
        try:
            run()
        finally:
            self._objective.p = self._gradient.p = None
        return x, dict(buffer.stats())

    def release_solver(self) -> None:
        """Give IPOPT's memory back (its matrices and MUMPS's factors stay with each solver until it goes: 120 MB at
        360k samples); the last Hessian's point stays (`last_hessian_point`); `solver` builds anew when asked."""
        self._solvers, self._objective, self._gradient = {}, None, None
        give_back()

    def last_hessian_point(self, p: np.ndarray) -> np.ndarray | None:
        """The x of the last Gauss-Newton Hessian IPOPT evaluated in the last `solve` with these parameters p, or
        None (no iteration)."""
        kept = getattr(self, "_kept", None)
        return kept.last if kept is not None and kept.p is p else None

    def hessian_values(self, x: np.ndarray, p: np.ndarray, out: np.ndarray | None = None) -> np.ndarray:
        """The nonzeros of triu(J^T J) at (x, p), in the order of `hessian_sparsity` (in `out` when given): the
        intervals' Jacobians a piece at a time, their products batched (`on_numpy.GaussNewtonProducts`), the parts
        assembled piece by piece (`on_numpy.node_columns_in`)."""
        products = self._products
        out = np.empty(products.n_tt + len(self._node_1) + (self.n_int - 1) * products.size) if out is None else out
        consume, finish = node_columns_in(out, products.n_tt, self._node_1, self.n_int, products.size)
        H_tt = np.zeros((self.n_theta, self.n_theta))
        shape = self.jacobian_kernel.size_out(0)[::-1]   # J^T's columns are J's rows

        def parts(a: int, b: int, outputs) -> None:
            first, second = products(outputs[0].reshape(b - a, *shape), H_tt)
            consume(a, b, [None, first, second])
        self._maps["jacobian"](x, p, parts)
        return finish(products.theta_block(H_tt))

    def residual_values(self, x: np.ndarray, p: np.ndarray) -> np.ndarray:
        """The whitened residuals at (x, p), interval by interval (`residual_function`'s output)."""
        k = self.n_res_per_interval
        r = np.empty(k * self.n_int)

        def put(a, b, out):
            r[a * k : b * k] = out[0]
        self._maps["residuals"](x, p, put)
        return r

    def objective_value(self, x: np.ndarray, p: np.ndarray) -> float:
        """0.5 |r|^2 at (x, p), summed piece by piece (no array of every residual)."""
        total = [0.0]

        def add(a, b, out):
            total[0] = sum_of_squares(out[0], total[0])
        self._maps["residuals"](x, p, add)
        return 0.5 * total[0]

    def objective_and_gradient(self, x: np.ndarray, p: np.ndarray) -> tuple[float, np.ndarray]:
        """(0.5 |r|^2, its gradient) at (x, p), from the gradient kernel: the theta rows summed over the
        intervals, node n's columns interval n-1's right part plus interval n's left part."""
        ssq, g_t, g_l, g_r = self._maps["gradient"](x, p)
        B = self.B
        grad = np.empty(self.n_x)
        grad[: self.n_theta] = g_t
        grad[self.n_theta :] = g_r
        grad[self.n_theta : self.n_x - B] += g_l[B:]
        return 0.5 * float(ssq[0]), grad

    def gradient_values(self, x: np.ndarray, p: np.ndarray) -> np.ndarray:
        return self.objective_and_gradient(x, p)[1]

    # ---------------------------------------------------------------- numbers in
    def parameters(self, lin: Linearisation, y_mag, sigma_mag: float, sigma_gyro_density: float,
                   t_gyro_s=None, gyro_rad_s=None, t_mag_s=None, tau0_s: float = 0.0, acc_weight=None) -> np.ndarray:
        """Flat parameter vector: the linearisation, the weights and the data on the grid.

        With a time offset tau0 the raw gyro at each magnetometer stamp minus
        tau0/2 is needed (t_gyro_s, gyro_rad_s, t_mag_s); without them it is
        taken as zero rate.
        """
        g_ = self.grid
        Lchol = np.linalg.cholesky(lin.K0 @ lin.K0.T)
        glob = {
            "S0": lin.S0, "h0": lin.h0, "K0": lin.K0, "eps0": lin.eps0, "m0": lin.m0,
            "B": so3.tangent_basis(lin.m0), "field_scale": np.array([lin.field_scale]),
            "Winv": np.linalg.inv(Lchol) / sigma_gyro_density, "w_mag": np.array([1.0 / sigma_mag]),
            "tau0": np.array([tau0_s]), "huber": np.array([NO_HUBER if self.huber is None else self.huber]),
        }
        layout = GLOBAL_LAYOUT
        if self.accelerometer:   # the accelerometer's start and its weights (nls/accelerometer.py)
            start = lin.accelerometer
            glob.update(start.globals())
            layout = GLOBAL_LAYOUT + ACC_GLOBAL_LAYOUT
        gvec = np.concatenate([np.asarray(glob[k], float).reshape(-1, order="F") for k, _ in layout])
        C = lin.C_m_i_nominal
        n_int, s, L = self.n_int, g_.stride, g_.substeps
        # every column block written straight into the vector (no whole-session array of the data beside it, and
        # no second one for the leading columns joined on: 2 x 42 MB at 360k samples)
        out = np.zeros(self.n_p)
        out[self.global_positions] = gvec
        data = out[self.n_lead * self.n_data :].reshape(n_int, self.n_data)
        dt, ya, yb = g_.sub_steps()
        columns = {
            "Cbar": lambda: C[:-1].transpose(0, 2, 1).reshape(n_int, 9),  # column-major vec of each C
            "qD": lambda: so3.dcm_to_quat(np.einsum("kji,kjl->kil", C[:-1], C[1:])),
            "w_int": lambda: np.where(g_.gyro_linked, 1.0 / np.sqrt(g_.interval_s),
                                      sigma_gyro_density / HOLE_LINK_STD_RAD)[:, None],
            "ymag": lambda: np.asarray(y_mag)[g_.mag_index].reshape(n_int, 3 * s),
            "wseg": lambda: g_.mag_weight.reshape(n_int, s),
            "ymid": lambda: gyro_at_mag_midpoints(g_, t_gyro_s, gyro_rad_s, t_mag_s, tau0_s).reshape(n_int, 3 * s),
            "dt": lambda: dt.reshape(n_int, s * L),
            "ya": lambda: ya.reshape(n_int, 3 * s * L),
            "yb": lambda: yb.reshape(n_int, 3 * s * L),
        }
        if self.walk:   # eta is in field_scale units
            columns["w_walk"] = lambda: (lin.field_scale / (self.walk_density * np.sqrt(g_.interval_s)))[:, None]
        if self.accelerometer:
            columns.update({k: (lambda v=v: v) for k, v in start.columns(acc_weight).items()})
        if self.hand:
            columns["hand"] = lambda: self.hand_prior.columns(g_.interval_s)
        o = 0
        for name, k in data_layout(s, L, self.walk, self.accelerometer, self.hand):
            data[:, o : o + k] = columns[name]()
            o += k
        return out

    # ----------------------------------------------------------------- the solve
    def solver(self, ipopt_options: dict | None = None):
        """IPOPT on the NLP in x alone: objective, gradient and Gauss-Newton Hessian are callbacks that evaluate the
        kernels' maps on numpy with the parameters of the running `solve` (no MX graph of the whole problem)."""
        key = tuple(sorted((ipopt_options or {}).items()))
        if self._solvers.get(key) is None:
            x, p = ca.MX.sym("x", self.n_x), ca.MX.sym("p", 0)
            self.callbacks()
            opts = {
                "hess_lag": self._kept,   # the callbacks themselves: no MX function around them (its work copies)
                "grad_f": self._gradient,
                "calc_lam_p": False,
                "no_nlp_grad": True,  # grad_f and hess_lag are given: nothing needs to differentiate f
                "calc_lam_x": False,
                "print_time": False,
                "ipopt.print_level": 0,
                "ipopt.sb": "yes",
                # The objective is already whitened (chi^2 units), so no scaling. Rounding
                # alone leaves gradients of 1e-6..1e-4 (curvatures reach 1e7+), so a gradient
                # test can stall in line searches on noise. Stop instead when chi^2 stops
                # changing (relative 1e-10 on two iterations in a row); calibrate() then
                # checks the Gauss-Newton decrement itself and refuses a false stop.
                "ipopt.nlp_scaling_method": "none",
                "ipopt.tol": 1e-6,
                "ipopt.acceptable_tol": 1e10,
                "ipopt.acceptable_dual_inf_tol": 1e10,
                "ipopt.acceptable_obj_change_tol": 1e-10,
                "ipopt.acceptable_iter": 2,
                "ipopt.max_iter": 200,
                "ipopt.linear_solver": "mumps",
                # QAMD: the approximate minimum degree ordering that detects the quasi-dense theta rows of the KKT
                # matrix. The automatic choice (METIS here) spends 2 s of MUMPS's analysis on them at 360k samples
                # (0.03 s at 36k); QAMD 0.2 s.
                "ipopt.mumps_pivot_order": 6,
            }
            if self.accelerometer:
                # AMF: with the accelerometer's 17 more quasi-dense rows QAMD's factorisations took 0.59 s of
                # IPOPT's time on BROAD 02 (9 iterations, one thread), AMF's 0.18 s (METIS 0.23 s, AMD 0.61 s).
                # Without it QAMD stays: that problem's numbers stay bit for bit.
                opts["ipopt.mumps_pivot_order"] = 2
            opts.update(ipopt_options or {})
            self._solvers[key] = ca.nlpsol("joint", "ipopt", {"x": x, "p": p, "f": self._objective(x)}, opts)
        return self._solvers[key]

    def callbacks(self) -> None:
        """The objective, gradient and Hessian callbacks every solver of this problem shares (until released)."""
        if self._objective is None:
            one = ca.Sparsity.dense(1, 1)
            self._objective = OnNumpy(self, "joint_objective", ["x"], {"f": one}, lambda x_, p_: [self.objective_value(x_, p_)])
            self._gradient = OnNumpy(self, "nlp_grad_f", ["x", "p"], {"f": one, "grad_f_x": ca.Sparsity.dense(self.n_x, 1)},
                                     lambda x_, p_: list(self.objective_and_gradient(x_, p_)))
            self._kept = KeptHessian(self)


def evaluate(fn: ca.Function, *args) -> list[np.ndarray]:
    """fn at numpy arguments (each its nonzeros, in order), its outputs' nonzeros as numpy arrays: through CasADi's
    buffers, so no DM is made of an argument (a DM of the 8.5M parameters at 360k samples costs 0.6-1 s and 68 MB)
    or of an output."""
    buffer, run = fn.buffer()
    held = [np.ascontiguousarray(a, dtype=float).reshape(-1) for a in args]
    for i, a in enumerate(held):
        assert a.size == fn.nnz_in(i), (fn.name(), i, a.size, fn.nnz_in(i))
        buffer.set_arg(i, memoryview(a))
    out = [np.zeros(fn.nnz_out(i)) for i in range(fn.n_out())]
    for i, o in enumerate(out):
        buffer.set_res(i, memoryview(o))
    run()
    return out


def but_last_column(M):
    """M without its last column, by a split (no index list)."""
    n = M.shape[1]
    return ca.horzsplit(M, [0, n - 1, n])[0] if n > 1 else ca.MX(M.shape[0], 0)


def column_starts(G: int, B: int) -> list[int]:
    """Where each of a node's B columns starts in `node_columns`' stacking (G theta rows, B previous, c+1 own)."""
    sizes = [G + B + c + 1 for c in range(B)]
    return [int(v) for v in np.cumsum([0] + sizes[:-1])]


def hessian_sparsity(n_int: int, G: int = N_GLOBAL, B: int = 3) -> ca.Sparsity:
    """Sparsity of triu(J^T J): the G x G theta block, theta rows over every node column, each node's own
    upper triangle, and the block coupling node k to k+1 (node 1, the first unknown one, has no previous node).
    Built from CasADi's sparsity algebra: no list of every nonzero is made in Python."""
    ones = lambda sp: ca.DM(sp, 1)
    own = ca.kron(ones(ca.Sparsity.diag(n_int)), ones(ca.Sparsity.upper(B))).sparsity()
    coupling = ca.kron(ones(ca.Sparsity.band(n_int, -1)), ones(ca.Sparsity.dense(B, B))).sparsity()
    top = ca.horzcat(ca.Sparsity.upper(G), ca.Sparsity.dense(G, B * n_int))
    return ca.vertcat(top, ca.horzcat(ca.Sparsity(B * n_int, G), own.unite(coupling)))
