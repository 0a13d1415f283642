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
Hessian, its Jacobian blocks; it is `map`ped over the intervals. The
Hessian J^T J is assembled from those blocks (theta-theta by one sparse
product), so no derivative of the whole graph is ever formed.
"""
from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property

import casadi as ca
import numpy as np

from magyro import so3
from magyro.nls.grid import Grid, gyro_at_mag_midpoints
from magyro.nls.kernels import compile_kernels, load_cached_kernel

N_GLOBAL = 23          # calibration corrections without the time offset; 24 with it
GLOBAL_SLICES = {"U": slice(0, 6), "dh": slice(6, 9), "dK": slice(9, 18), "deps": slice(18, 21), "dm": slice(21, 23), "dtau": slice(23, 24)}
TIME_OFFSET_SCALE_S = 0.01
HOLE_LINK_STD_RAD = 0.1   # across a hole in the gyro record the attitudes are linked this loosely (a gauge only)
UPPER_INDEX = [(0, 0), (0, 1), (0, 2), (1, 1), (1, 2), (2, 2)]
GLOBAL_LAYOUT = [("S0", 9), ("h0", 3), ("K0", 9), ("eps0", 3), ("m0", 3), ("B", 6), ("field_scale", 1), ("Winv", 9), ("w_mag", 1), ("tau0", 1),
                 ("huber", 1)]
NO_HUBER = 1e30   # the Huber threshold (noise sigmas) of the plain least squares: no residual reaches it


# ------------------------------------------------------------- SX building blocks
def quat_exp(phi):
    """Quaternion [w, x, y, z] of Exp(phi); smooth at zero (series branch, safe argument)."""
    th2 = ca.dot(phi, phi)
    small = th2 < 1e-6
    th_safe = ca.sqrt(ca.if_else(small, 1.0, th2))
    c = ca.if_else(small, 1.0 - th2 / 8.0 + th2 * th2 / 384.0, ca.cos(th_safe / 2.0))
    s = ca.if_else(small, 0.5 - th2 / 48.0 + th2 * th2 / 3840.0, ca.sin(th_safe / 2.0) / th_safe)
    return ca.vertcat(c, s * phi)


def quat_mul(a, b):
    aw, av = a[0], a[1:]
    bw, bv = b[0], b[1:]
    return ca.vertcat(aw * bw - ca.dot(av, bv), aw * bv + bw * av + ca.cross(av, bv))


def quat_conj(q):
    return ca.vertcat(q[0], -q[1:])


def rotate_inverse(q, v):
    """R(q)^T v."""
    u = q[1:]
    c = ca.cross(u, v)
    return v - 2 * q[0] * c + 2 * ca.cross(u, c)


def unpack_globals(theta, g):
    """Physical parameters (S = R^-1, h, K, eps, m^i) from corrections and the linearisation."""
    o = 0
    parts = {}
    for name, n in GLOBAL_LAYOUT:
        parts[name] = g[o : o + n]
        o += n
    S0 = ca.reshape(parts["S0"], 3, 3)
    U = theta[GLOBAL_SLICES["U"]]
    Umat = ca.SX.zeros(3, 3) if isinstance(theta, ca.SX) else ca.MX.zeros(3, 3)
    for i, (r, c) in enumerate(UPPER_INDEX):
        Umat[r, c] = U[i]
    S = ca.mtimes(S0, ca.DM.eye(3) + Umat)
    h = parts["h0"] + parts["field_scale"] * theta[GLOBAL_SLICES["dh"]]
    K = ca.reshape(parts["K0"], 3, 3) + ca.reshape(theta[GLOBAL_SLICES["dK"]], 3, 3)
    eps = parts["eps0"] + theta[GLOBAL_SLICES["deps"]]
    m_raw = parts["m0"] + ca.mtimes(ca.reshape(parts["B"], 3, 2), theta[GLOBAL_SLICES["dm"]])
    m_i = m_raw / ca.norm_2(m_raw)
    tau = parts["tau0"] + (TIME_OFFSET_SCALE_S * theta[GLOBAL_SLICES["dtau"]] if theta.shape[0] > N_GLOBAL else 0)
    return S, h, K, eps, m_i, tau, ca.reshape(parts["Winv"], 3, 3), parts["w_mag"], parts["huber"]


def data_layout(stride: int, L: int, walk: bool = False) -> list[tuple[str, int]]:
    return [("Cbar", 9), ("qD", 4), ("w_int", 1), ("ymag", 3 * stride), ("wseg", stride), ("ymid", 3 * stride),
            ("dt", stride * L), ("ya", 3 * stride * L), ("yb", 3 * stride * L)] + ([("w_walk", 1)] if walk else [])


def global_part(g, name: str):
    """The entry `name` of the global parameter vector g (GLOBAL_LAYOUT)."""
    o = 0
    for entry, n in GLOBAL_LAYOUT:
        if entry == name:
            return g[o : o + n]
        o += n
    raise KeyError(name)


def global_number(p: np.ndarray, name: str) -> float:
    """The one-number global `name` (e.g. w_mag = 1 / sigma_mag, field_scale) of a numeric parameter vector."""
    return float(np.asarray(global_part(p, name)).item())


def huber_scaled(r, threshold):
    """r scaled so that |r|^2 / 2 becomes Huber's rho(|r|): quadratic inside `threshold`, linear outside.
    A parameter, not a constant of the kernel, so the plain least squares (threshold NO_HUBER) and Huber's
    share their compiled code."""
    n = ca.norm_2(r)
    outside = n > threshold
    n_safe = ca.if_else(outside, n, 2.0 * threshold)
    return r * ca.if_else(outside, ca.sqrt(threshold * (2.0 * n_safe - threshold)) / n_safe, 1.0)


def interval_residuals(theta, s_k, s_k1, g, d, stride: int, L: int, walk: bool = False):
    """Whitened residuals of one interval: `stride` magnetometer samples, then the gyro mismatch, then (with a
    moving hard iron, `walk`) its random-walk step. A node's state s is phi (3), then eta (3) when `walk`:
    the hard iron over the interval from the node is h + field_scale * eta_k."""
    S, h, K, eps, m_i, tau, Winv, w_mag, huber = unpack_globals(theta, g)
    phi_k, phi_k1 = s_k[:3], s_k1[:3]
    if walk:
        h = h + global_part(g, "field_scale") * s_k[3:6]
    o = 0
    parts = {}
    for name, n in data_layout(stride, L, walk):
        parts[name] = d[o : o + n]
        o += n
    Cbar = ca.reshape(parts["Cbar"], 3, 3)
    q_k = quat_exp(phi_k)
    n_k = rotate_inverse(q_k, ca.mtimes(Cbar.T, m_i))  # C_i^m(tau_k) m^i
    Q = ca.DM([1, 0, 0, 0])
    res = []
    for i in range(stride):
        v = rotate_inverse(Q, n_k)  # C_i^m(t_j) m^i at the stamp; then back by the time offset
        w_mid = ca.mtimes(K, parts["ymid"][3 * i : 3 * i + 3]) + eps
        v = rotate_inverse(quat_conj(quat_exp(tau * w_mid)), v)
        r_mag = (parts["ymag"][3 * i : 3 * i + 3] - ca.mtimes(S, v) - h) * (w_mag * parts["wseg"][i])
        res.append(huber_scaled(r_mag, huber))
        for l in range(L):
            j = i * L + l
            dt = parts["dt"][j]
            wa = ca.mtimes(K, parts["ya"][3 * j : 3 * j + 3]) + eps
            wb = ca.mtimes(K, parts["yb"][3 * j : 3 * j + 3]) + eps
            Q = quat_mul(Q, quat_exp(0.5 * (wa + wb) * dt + (dt * dt / 12.0) * ca.cross(wa, wb)))
    qE = quat_mul(quat_mul(quat_mul(quat_conj(Q), quat_conj(q_k)), parts["qD"]), quat_exp(phi_k1))
    res.append(ca.mtimes(Winv, 2.0 * qE[0] * qE[1:]) * parts["w_int"])
    if walk:
        res.append((s_k1[3:6] - s_k[3:6]) * parts["w_walk"])
    return ca.vertcat(*res)


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



# -------------------------------------------------------------------- the problem
KERNEL_NAMES = ("interval_residuals", "interval_gradient", "interval_gauss_newton")


def interval_kernels(n_theta: int, n_glob_p: int, n_data: int, stride: int, L: int, walk: bool = False):
    """The three per-interval SX kernels: residuals; sum of squares and its gradient; Gauss-Newton blocks."""
    th = ca.SX.sym("theta", n_theta)
    pk = ca.SX.sym("s_k", node_size(walk))
    pk1 = ca.SX.sym("s_k1", node_size(walk))
    g = ca.SX.sym("g", n_glob_p)
    d = ca.SX.sym("d", n_data)
    r = interval_residuals(th, pk, pk1, g, d, stride, L, walk)
    JthT = ca.jacobian(r, th).T
    Jk = ca.jacobian(r, pk)
    Jk1 = ca.jacobian(r, pk1)
    ssq = ca.sumsqr(r)
    args = [th, pk, pk1, g, d]
    return [
        ca.Function(KERNEL_NAMES[0], args, [r]),
        ca.Function(KERNEL_NAMES[1], args,
                    [ssq, 0.5 * ca.gradient(ssq, th), 0.5 * ca.gradient(ssq, pk), 0.5 * ca.gradient(ssq, pk1)]),
        ca.Function(KERNEL_NAMES[2], args,
                    [JthT, ca.mtimes(JthT, Jk), ca.mtimes(JthT, Jk1), ca.mtimes(Jk.T, Jk), ca.mtimes(Jk1.T, Jk1),
                     ca.mtimes(Jk.T, Jk1)]),
    ]


def kernel_key(stride: int, L: int, n_theta: int, walk: bool) -> str:
    """What determines the kernels completely (with the source of this module, see kernels.cache_digest)."""
    return f"stride={stride} substeps={L} theta={n_theta}" + (" walk" if walk else "")


def kernel_set(stride: int, L: int, n_theta: int, walk: bool, compiled: bool = True) -> list[ca.Function]:
    """The three interval kernels of a shape: compiled (installed with magyro, cached, or compiled now) when
    `compiled`, else the interpreted SX functions."""
    key = kernel_key(stride, L, n_theta, walk)
    cached = [load_cached_kernel(name, key) for name in KERNEL_NAMES] if compiled else [None]
    if all(k is not None for k in cached):  # compiled before: no symbolic build needed
        return cached
    n_glob_p = sum(k for _, k in GLOBAL_LAYOUT)
    n_data = sum(k for _, k in data_layout(stride, L, walk))
    kernels = interval_kernels(n_theta, n_glob_p, n_data, stride, L, walk)
    return compile_kernels(kernels, key) if compiled else kernels


def node_size(walk: bool) -> int:
    """Unknowns per node: the attitude correction phi (3), and the hard iron's walk eta (3) when it moves."""
    return 6 if walk else 3


class JointProblem:
    """The least squares on one grid shape; data and linearisation enter as parameters.

    With a `walk_density` (magnetometer unit / sqrt(s)) the hard iron moves: h(t) = h + field_scale * eta_n over
    the interval from node n, eta a random walk from eta_0 = 0 whose steps are weighted by the parameters'
    `w_walk` (1 / (density sqrt(dt))). The kernels depend only on whether it walks, not on the density.
    """

    def __init__(self, grid: Grid, compiled: bool = True, estimate_time_offset: bool = True, huber: float | None = None,
                 walk_density: float | None = None):
        self.grid = grid
        self.walk_density = walk_density
        self.huber = huber
        self.walk = walk = walk_density is not None
        self.B = node_size(walk)
        self.n_theta = N_GLOBAL + (1 if estimate_time_offset else 0)
        n, s, L = grid.nodes, grid.stride, grid.substeps
        self.n_int = n - 1
        self.n_glob_p = sum(k for _, k in GLOBAL_LAYOUT)
        self.n_data = sum(k for _, k in data_layout(s, L, walk))
        self.n_x = self.n_theta + self.B * self.n_int
        self.n_res_per_interval = 3 * s + 3 + (3 if walk else 0)

        self.kernel_key = kernel_key(s, L, self.n_theta, walk)
        self.residual_kernel, self.gradient_kernel, self.gn_kernel = kernel_set(s, L, self.n_theta, walk, compiled)
        th = ca.SX.sym("theta", self.n_theta)
        g = ca.SX.sym("g", self.n_glob_p)
        S, h, K, eps, m_i, tau, _, _, _ = unpack_globals(th, g)
        self.physical_function = ca.Function(
            "physical", [th, g], [S, h, K, eps, m_i, tau], ["theta", "g"], ["S", "h", "K", "eps", "m_i", "tau"]
        )
        self._solver = None

    # ------------------------------------------------------------------ MX graph
    def _split(self, x, p):
        theta = x[: self.n_theta]
        phi = ca.reshape(x[self.n_theta :], self.B, self.n_int)
        phi_k = ca.horzcat(ca.MX.zeros(self.B, 1), phi[:, : self.n_int - 1])
        g = p[: self.n_glob_p]
        D = ca.reshape(p[self.n_glob_p :], self.n_data, self.n_int)
        return theta, phi_k, phi, g, D

    # The three MX graphs are built on first use: the accuracy prediction and the CRLB need only
    # the Hessian, which saves two thirds of the graph-building time of `magyro observe`.
    @cached_property
    def _symbols(self):
        x = ca.MX.sym("x", self.n_x)
        p = ca.MX.sym("p", self.n_glob_p + self.n_data * self.n_int)
        return x, p, self._split(x, p)

    @cached_property
    def _residual_graph(self):
        x, p, args = self._symbols
        r = ca.vec(self.residual_kernel.map(self.n_int)(*args))
        return ca.Function("residuals", [x, p], [r]), 0.5 * ca.sumsqr(r)

    @property
    def residual_function(self) -> ca.Function:
        return self._residual_graph[0]

    @cached_property
    def _gradient_graph(self):
        x, p, args = self._symbols
        ssq, g_t, g_l, g_r = self.gradient_kernel.map(self.n_int)(*args)
        grad_phi = ca.horzcat(g_l[:, 1:], ca.MX.zeros(self.B, 1)) + g_r
        grad = ca.vertcat(ca.sum2(g_t), ca.vec(grad_phi))
        grad_f = ca.Function("nlp_grad_f", [x, p], [0.5 * ca.sum2(ssq), grad], ["x", "p"], ["f", "grad_f_x"])
        return ca.Function("gradient", [x, p], [grad]), grad_f

    @property
    def gradient_function(self) -> ca.Function:
        return self._gradient_graph[0]

    @cached_property
    def _hessian_graph(self):
        x, p, args = self._symbols
        JthT, CL, CR, DL, DR, O = self.gn_kernel.map(self.n_int)(*args)
        H_tt = ca.mtimes(JthT, JthT.T)
        B = self.B
        H_tp = ca.horzcat(CL[:, B:], ca.MX.zeros(self.n_theta, B)) + CR
        H_pp = ca.horzcat(DL[:, B:], ca.MX.zeros(B, B)) + DR
        assert H_tp.shape[1] == B * self.n_int
        values = ca.vertcat(ca.vec(ca.densify(H_tt)), ca.vec(ca.densify(H_tp)), ca.vec(ca.densify(H_pp)), ca.vec(ca.densify(O)))
        sp, perm = hessian_pattern(self.n_int, self.n_theta, self.B)
        H = ca.MX(sp, values[perm])
        lam_f = ca.MX.sym("lam_f")
        lam_g = ca.MX.sym("lam_g", 0)
        hess_lag = ca.Function(
            "nlp_hess_l", [x, p, lam_f, lam_g], [lam_f * H], ["x", "p", "lam_f", "lam_g"], ["triu_hess_gamma_x_x"]
        )
        return ca.Function("gauss_newton_hessian", [x, p], [H]), hess_lag

    @property
    def hessian_function(self) -> ca.Function:
        return self._hessian_graph[0]

    # ---------------------------------------------------------------- numbers in
    def parameters(self, lin: Linearisation, y_mag, sigma_mag: float, sigma_gyro_density: float,
                   t_gyro_s=None, gyro_rad_s=None, t_mag_s=None, tau0_s: float = 0.0) -> np.ndarray:
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
        gvec = np.concatenate([np.asarray(glob[k], float).reshape(-1, order="F") for k, _ in GLOBAL_LAYOUT])
        C = lin.C_m_i_nominal
        D = np.einsum("kji,kjl->kil", C[:-1], C[1:])
        n_int, s, L = self.n_int, g_.stride, g_.substeps
        cols = {
            "Cbar": C[:-1].transpose(0, 2, 1).reshape(n_int, 9),  # column-major vec of each C
            "qD": so3.dcm_to_quat(D),
            "w_int": np.where(g_.gyro_linked, 1.0 / np.sqrt(g_.interval_s), sigma_gyro_density / HOLE_LINK_STD_RAD)[:, None],
            "ymag": np.asarray(y_mag)[g_.mag_index].reshape(n_int, 3 * s),
            "wseg": g_.mag_weight.reshape(n_int, s),
            "ymid": gyro_at_mag_midpoints(g_, t_gyro_s, gyro_rad_s, t_mag_s, tau0_s).reshape(n_int, 3 * s),
            "dt": g_.dt_s.reshape(n_int, s * L),
            "ya": g_.gyro_a.reshape(n_int, 3 * s * L),
            "yb": g_.gyro_b.reshape(n_int, 3 * s * L),
        }
        if self.walk:   # eta is in field_scale units
            cols["w_walk"] = (lin.field_scale / (self.walk_density * np.sqrt(g_.interval_s)))[:, None]
        data = np.concatenate([cols[k] for k, _ in data_layout(s, L, self.walk)], axis=1)  # n_int x n_data
        return np.concatenate([gvec, data.reshape(-1)])

    # ----------------------------------------------------------------- the solve
    def solver(self, ipopt_options: dict | None = None):
        if self._solver is None:
            opts = {
                "hess_lag": self._hessian_graph[1],
                "grad_f": self._gradient_graph[1],
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
            }
            opts.update(ipopt_options or {})
            x, p, _ = self._symbols
            self._solver = ca.nlpsol("joint", "ipopt", {"x": x, "p": p, "f": self._residual_graph[1]}, opts)
        return self._solver


def hessian_pattern(n_int: int, G: int = N_GLOBAL, B: int = 3):
    """Sparsity of triu(J^T J) and, per nonzero, its index in the stacked block values.

    Stacked values: vec(H_tt) (G x G), vec(H_tp) (G x Bn), vec(H_pp) (B x Bn,
    diagonal blocks side by side), vec(O) (B x Bn, block k couples node k to k+1).
    Column of node n (1..n_int), component c: the G theta rows, then node n-1's
    B rows (n >= 2), then node n's rows 0..c. B is the node's size (3, or 6 with a moving hard iron).
    """
    o_tp, o_pp = G * G, G * G + G * B * n_int
    o_o = o_pp + B * B * n_int
    jt, it = np.triu_indices(G)[::-1]  # column-major upper triangle: for each column j, rows 0..j
    order = np.lexsort((it, jt))
    rows_t, perm_t = it[order], it[order] + G * jt[order]
    node = np.repeat(np.arange(1, n_int + 1), B)
    comp = np.tile(np.arange(B), n_int)
    col = B * (node - 1) + comp                              # column within the node block
    slots = np.arange(G + 2 * B)                             # theta rows, off-diagonal, diagonal
    r = np.empty((len(col), G + 2 * B), dtype=np.int64)
    q = np.empty_like(r)
    r[:, :G] = slots[:G]
    q[:, :G] = o_tp + slots[:G] + G * col[:, None]
    a = np.arange(B)
    r[:, G:G + B] = G + B * (node[:, None] - 2) + a
    q[:, G:G + B] = o_o + a + B * col[:, None]
    r[:, G + B:] = G + B * (node[:, None] - 1) + a
    q[:, G + B:] = o_pp + a + B * col[:, None]
    valid = np.ones_like(r, dtype=bool)
    valid[:, G:G + B] = (node >= 2)[:, None]
    valid[:, G + B:] = a[None, :] <= comp[:, None]
    counts = valid.sum(axis=1)
    rows = np.concatenate([rows_t, r[valid]])
    perm = np.concatenate([perm_t, q[valid]])
    colptr = np.concatenate([[0], np.cumsum(np.arange(1, G + 1)), G * (G + 1) // 2 + np.cumsum(counts)])
    n_x = G + B * n_int
    return ca.Sparsity(n_x, n_x, colptr.tolist(), rows.tolist()), perm.tolist()
