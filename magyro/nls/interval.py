"""One interval of the joint least squares as CasADi SX kernels: the code every compiled kernel is made of.

An interval runs from attitude node k to node k+1 over `stride` segments, each of `L` gyro sub-steps
(grid.py). Its residuals, whitened:

    magnetometer  (y_m - h - R^-1 C_i^m(t_j - tau) m^i) * w_mag * w_seg    raw units, one per segment start;
                  C_i^m(t - tau) = Exp(tau w(t - tau0/2)) C_i^m(t); Huber's loss through `huber_scaled`, its
                  threshold a parameter (NO_HUBER: none); w_seg 0 where a segment starts at no sample
    gyro          Winv vee(E - E^T)/2 / sqrt(T_n)     E: mismatch of the integrated gyro against the node attitudes
    walk          the moving hard iron's step, when it walks
    accelerometer (with `acc`) w_acc sum_j c_j (y_a(t_j) - M g C_i^m(t_j) u^i - c): the interval's mean reading against
                  the one gravity makes (up u^i in frame i, 2 dof; g given; y_a = M f^m + c, the model read
                  backwards, f^m = A y_a + b with A = M^-1, b = -M^-1 c), then the rests' mean at a node
                  (nls/accelerometer.py)

Each sub-step rotates by (w_a + w_b)/2 dt + dt^2/12 (w_a x w_b), w = K y_g + eps. `interval_kernels` gives the
residuals, their sum of squares with its gradient, and the Jacobian; `kernel_set` the compiled
ones. This module alone (with kernels.py) determines the compiled code: its source is in the kernels'
cache key (kernels.cache_digest), so a change anywhere else compiles nothing.
"""
from __future__ import annotations

import casadi as ca
import numpy as np

from magyro.nls.kernels import compile_kernels, load_cached_kernel

N_GLOBAL = 23          # calibration corrections without the time offset; 24 with it
GLOBAL_SLICES = {"U": slice(0, 6), "dh": slice(6, 9), "dK": slice(9, 18), "deps": slice(18, 21), "dm": slice(21, 23), "dtau": slice(23, 24)}
TIME_OFFSET_SCALE_S = 0.01
UPPER_INDEX = [(0, 0), (0, 1), (0, 2), (1, 1), (1, 2), (2, 2)]
GLOBAL_LAYOUT = [("S0", 9), ("h0", 3), ("K0", 9), ("eps0", 3), ("m0", 3), ("B", 6), ("field_scale", 1), ("Winv", 9), ("w_mag", 1), ("tau0", 1),
                 ("huber", 1)]
ACC_GLOBAL_LAYOUT = [("M0", 9), ("c0", 3), ("u0", 3), ("Bu", 6), ("g_acc", 1)]   # appended with the accelerometer
N_ACC_THETA = 17       # dM (9, column-major), dc (3, m/s^2), du (2), the lever arm r (3, m): after the time offset
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


def inverse_rotation_matrix(q):
    """R(q)^T as a matrix: I - 2 w [u]x + 2 [u]x^2 (`rotate_inverse` of the identity's columns). Summed over an
    interval's segments (weighted by their shares) before it meets gravity and the hand, whose derivatives then go
    through one product: the accelerometer's Jacobian kernel with the hand as states took 42 ms on BROAD 02 against
    49 ms with each segment's gravity turned on its own (41.9 against 49.2; the weighted one's 38 either way)."""
    S = ca.skew(q[1:])
    return ca.SX.eye(3) - 2 * q[0] * S + 2 * ca.mtimes(S, S)


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
    tau = parts["tau0"] + (TIME_OFFSET_SCALE_S * theta[GLOBAL_SLICES["dtau"]] if has_time_offset(theta.shape[0]) else 0)
    return S, h, K, eps, m_i, tau, ca.reshape(parts["Winv"], 3, 3), parts["w_mag"], parts["huber"]


def has_time_offset(n_theta: int) -> bool:
    """Whether a theta of this size holds the time offset: N_GLOBAL, + 1 with it, + N_ACC_THETA with the
    accelerometer."""
    return n_theta - N_GLOBAL - (N_ACC_THETA if has_accelerometer(n_theta) else 0) == 1


def has_accelerometer(n_theta: int) -> bool:
    return n_theta - N_GLOBAL >= N_ACC_THETA


def global_size(acc: bool = False) -> int:
    return sum(k for _, k in GLOBAL_LAYOUT + (ACC_GLOBAL_LAYOUT if acc else []))


def data_layout(stride: int, L: int, walk: bool = False, acc: bool = False, hand: bool = False) -> list[tuple[str, int]]:
    """An interval's data, in order; with `hand` (the hand's velocity as states) its 1 / T, the velocity's decay
    over the interval and the weight of its step."""
    return ([("Cbar", 9), ("qD", 4), ("w_int", 1), ("ymag", 3 * stride), ("wseg", stride), ("ymid", 3 * stride),
             ("dt", stride * L), ("ya", 3 * stride * L), ("yb", 3 * stride * L)] + ([("w_walk", 1)] if walk else [])
            + ([("yacc", 3 * stride), ("cacc", stride), ("w_acc", 1), ("yrest0", 3), ("wrest0", 1), ("yrest1", 3),
                ("wrest1", 1)] if acc else []) + ([("hand", 3)] if hand else []))


def unpack_accelerometer(theta, g):
    """(A, b, u^i, g_m_s2, r) of the accelerometer: f^m = A y_a + b; the unit up direction in frame i; gravity; the
    lever arm from the point the device turns about (m, frame m)."""
    M, c, u_i, g_acc, lever_m = accelerometer_readout(theta, g)
    A = ca.inv(M)
    return A, -ca.mtimes(A, c), u_i, g_acc, lever_m


def accelerometer_readout(theta, g):
    """(M, c, u^i, g_m_s2, r): the reading a specific force f^m gives, y_a = M f^m + c, and the lever arm r. The
    residuals are the readings' (as the magnetometer's are): the hand's acceleration is in the readings, and a fit of
    f = A y + b with the readings as exact regressors shrinks every scale factor by the hand's share of their
    variance."""
    n = theta.shape[0]
    d = theta[n - N_ACC_THETA:]
    o = sum(k for _, k in GLOBAL_LAYOUT)
    parts = {}
    for name, k in ACC_GLOBAL_LAYOUT:
        parts[name] = g[o : o + k]
        o += k
    M = ca.reshape(parts["M0"], 3, 3) + ca.reshape(d[:9], 3, 3)
    c = parts["c0"] + d[9:12]
    u_raw = parts["u0"] + ca.mtimes(ca.reshape(parts["Bu"], 3, 2), d[12:14])
    return M, c, u_raw / ca.norm_2(u_raw), parts["g_acc"], d[14:17]


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


def lever_matrix(alpha, w):
    """[alpha]x + [w]x^2, the matrix that gives alpha x r + w x (w x r) of the lever arm r: summed over an
    interval's segments before it meets r (and M), its Jacobian is 12 % fewer operations than the sum of the segments'
    cross products, each turned by M (interval_residuals)."""
    return ca.skew(alpha) + ca.mtimes(w, w.T) - ca.dot(w, w) * ca.DM.eye(3)


def huber_scaled(r, threshold):
    """r scaled so that |r|^2 / 2 becomes Huber's rho(|r|): quadratic inside `threshold`, linear outside.
    A parameter, not a constant of the kernel, so the plain least squares (threshold NO_HUBER) and Huber's
    share their compiled code."""
    n = ca.norm_2(r)
    outside = n > threshold
    n_safe = ca.if_else(outside, n, 2.0 * threshold)
    return r * ca.if_else(outside, ca.sqrt(threshold * (2.0 * n_safe - threshold)) / n_safe, 1.0)


def interval_residuals(theta, s_k, s_k1, g, d, stride: int, L: int, walk: bool = False, acc: bool = False,
                       hand: bool = False):
    """Whitened residuals of one interval: `stride` magnetometer samples, then the gyro mismatch, then (with a
    moving hard iron, `walk`) its random-walk step. A node's state s is phi (3), then eta (3) when `walk`:
    the hard iron over the interval from the node is h + field_scale * eta_k; then (with `hand`, the accelerometer's
    hand as states) the hand's velocity v (3, m/s, frame i): the interval's mean acceleration is (v_k1 - v_k) / T,
    read with gravity, and the velocity's Ornstein-Uhlenbeck step is the interval's last residuals."""
    S, h, K, eps, m_i, tau, Winv, w_mag, huber = unpack_globals(theta, g)
    phi_k, phi_k1 = s_k[:3], s_k1[:3]
    if walk:
        h = h + global_part(g, "field_scale") * s_k[3:6]
    o = 0
    parts = {}
    for name, n in data_layout(stride, L, walk, acc, hand):
        parts[name] = d[o : o + n]
        o += n
    Cbar = ca.reshape(parts["Cbar"], 3, 3)
    q_k = quat_exp(phi_k)
    n_k = rotate_inverse(q_k, ca.mtimes(Cbar.T, m_i))  # C_i^m(tau_k) m^i
    if acc:   # the interval's mean reading: sum_j c_j (y_j - M (g C_i^m(t_j) u^i + lever_j) - c), M and c taken out
        M, c, u_i, g_acc, lever_m = accelerometer_readout(theta, g)
        up_k = rotate_inverse(q_k, ca.mtimes(Cbar.T, u_i))   # C_i^m(t_k) u^i
        if hand:   # gravity and the hand's mean acceleration, read together: C_i^m(t_j) (g u^i + (v_k1 - v_k) / T)
            v = hand_slice(walk)
            hand_i = (s_k1[v] - s_k[v]) * parts["hand"][0]
            felt_k = rotate_inverse(q_k, ca.mtimes(Cbar.T, g_acc * u_i + hand_i))
        y_sum, turn_sum, lever_sum, share_sum = ca.SX.zeros(3), ca.SX.zeros(3, 3), ca.SX.zeros(3, 3), 0
    Q = ca.DM([1, 0, 0, 0])
    res = []
    for i in range(stride):
        if acc:   # the reading and gravity's up at the segment start, weighted into the interval's sums
            share = parts["cacc"][i]
            y_sum += share * parts["yacc"][3 * i : 3 * i + 3]
            turn_sum += share * inverse_rotation_matrix(Q)   # the segments' turns, summed before they meet gravity
            share_sum += share
        v = rotate_inverse(Q, n_k)  # C_i^m(t_j) m^i at the stamp; then back by the time offset
        w_mid = ca.mtimes(K, parts["ymid"][3 * i : 3 * i + 3]) + eps
        v = rotate_inverse(quat_conj(quat_exp(tau * w_mid)), v)
        r_mag = (parts["ymag"][3 * i : 3 * i + 3] - ca.mtimes(S, v) - h) * (w_mag * parts["wseg"][i])
        res.append(huber_scaled(r_mag, huber))
        turned, seg_dt = 0, 0
        for l in range(L):
            j = i * L + l
            dt = parts["dt"][j]
            wa = ca.mtimes(K, parts["ya"][3 * j : 3 * j + 3]) + eps
            wb = ca.mtimes(K, parts["yb"][3 * j : 3 * j + 3]) + eps
            Q = quat_mul(Q, quat_exp(0.5 * (wa + wb) * dt + (dt * dt / 12.0) * ca.cross(wa, wb)))
            if l == 0:
                w_start = wa
            turned, seg_dt = turned + (wb - wa), seg_dt + dt   # padded sub-steps add nothing (wa = wb)
        if acc:   # turning about a point r away: alpha x r + w x (w x r) at the segment start, as a matrix on r
            alpha = turned / ca.if_else(seg_dt > 0, seg_dt, 1.0)   # no segment (the globals' columns): no 0/0
            lever_sum += share * lever_matrix(alpha, w_start)
    qE = quat_mul(quat_mul(quat_mul(quat_conj(Q), quat_conj(q_k)), parts["qD"]), quat_exp(phi_k1))
    res.append(ca.mtimes(Winv, 2.0 * qE[0] * qE[1:]) * parts["w_int"])
    if walk:
        res.append((s_k1[3:6] - s_k[3:6]) * parts["w_walk"])
    if acc:
        felt_sum = ca.mtimes(turn_sum, felt_k) if hand else g_acc * ca.mtimes(turn_sum, up_k)
        acc_mean = y_sum - ca.mtimes(M, felt_sum + ca.mtimes(lever_sum, lever_m)) - share_sum * c
        res.append(acc_mean * parts["w_acc"])
        up_k1 = rotate_inverse(quat_exp(phi_k1), rotate_inverse(parts["qD"], ca.mtimes(Cbar.T, u_i)))   # at node k+1
        rest = lambda y, up: y - ca.mtimes(M, g_acc * up) - c
        res.append(rest(parts["yrest0"], up_k) * parts["wrest0"] + rest(parts["yrest1"], up_k1) * parts["wrest1"])
    if hand:   # the hand's velocity: v_k1 = decay v_k + a white step of std 1 / w
        v = hand_slice(walk)
        res.append((s_k1[v] - parts["hand"][1] * s_k[v]) * parts["hand"][2])
    return ca.vertcat(*res)


def hand_slice(walk: bool) -> slice:
    """Where the hand's velocity sits in a node's states (after phi, and eta when the hard iron walks)."""
    return slice(6, 9) if walk else slice(3, 6)


KERNEL_NAMES = ("interval_residuals", "interval_gradient", "interval_jacobian")


def interval_kernels(stride: int, L: int, n_theta: int, walk: bool = False, hand: bool = False):
    """The three per-interval SX kernels of a shape (`kernel_key`'s arguments): residuals; sum of squares and its
    gradient; the Jacobian J = d r / d (theta, s_k, s_k1), given as J^T densified (n_theta + 2 B rows, one column
    per residual) so that its column-major nonzeros are J's rows, each interval's J a C-ordered (residuals,
    n_theta + 2 B) block. The Gauss-Newton products J^T J are formed from it on numpy, batched over a piece of
    intervals (on_numpy.GaussNewtonProducts, GAUSS_NEWTON_C: in the order the kernel summed them, so the same
    Hessian bit for bit): a Hessian at 360k samples took 0.86 s CPU with the products inside the kernel, 0.44 s
    so."""
    th = ca.SX.sym("theta", n_theta)
    pk = ca.SX.sym("s_k", node_size(walk, hand))
    pk1 = ca.SX.sym("s_k1", node_size(walk, hand))
    acc = has_accelerometer(n_theta)
    g = ca.SX.sym("g", global_size(acc))
    d = ca.SX.sym("d", sum(k for _, k in data_layout(stride, L, walk, acc, hand)))
    r = interval_residuals(th, pk, pk1, g, d, stride, L, walk, acc, hand)
    ssq = ca.sumsqr(r)
    args = [th, pk, pk1, g, d]
    opts = kernel_options(acc)
    return [
        ca.Function(KERNEL_NAMES[0], args, [r], opts),
        ca.Function(KERNEL_NAMES[1], args,
                    [ssq, 0.5 * ca.gradient(ssq, th), 0.5 * ca.gradient(ssq, pk), 0.5 * ca.gradient(ssq, pk1)], opts),
        ca.Function(KERNEL_NAMES[2], args, [ca.densify(ca.jacobian(r, ca.vertcat(th, pk, pk1)).T)], opts),
    ]


def kernel_options(acc: bool) -> dict:
    """The SX Functions' options: with the accelerometer, CasADi's common subexpression elimination (the Jacobian's
    derivatives of the accelerometer's rows repeat the magnetometer's: 75.4k -> 71.1k operations at stride 12).
    Without it none, so that the kernels without the accelerometer stay the code they were."""
    return {"cse": True} if acc else {}


# The Gauss-Newton products of the intervals' Jacobians (on_numpy.GaussNewtonProducts), in the order the SX kernel
# with the products inside summed them (casadi_mtimes over J^T J: each entry a sum over the residuals in their order
# from zero, each interval's triu(J_theta^T J_theta) then added to the running total interval after interval), so
# the Hessian is the same bit for bit; an exact zero of J is skipped (as a structural zero was: adding +-0 changes no
# sum, which starts at +0 and so is never -0), and so are a row's theta columns past its last nonzero one (the
# accelerometer's 17 columns of every magnetometer row), and the work block is zeroed as it is added, not whole per
# interval: with the accelerometer (41 theta columns) the products of a BROAD 02 Hessian took 12.7 ms against 16.5 ms,
# without it 9.0 against 9.2 ms (the same H and P bit for bit). Plain C built with the kernels' flags (-O2, no
# -march), this function at O3 (its loops vectorised across the entries, each entry's sum in the same order: 0.15 ->
# 0.11 s of a 360k Hessian): no BLAS, whose order and FMA depend on the CPU it runs on.
GAUSS_NEWTON_PRODUCTS = "gauss_newton_parts"
GAUSS_NEWTON_C = """
#pragma GCC optimize ("O3")
void gauss_newton_parts(long m, long R, long N, long G, const double* restrict J, double* restrict H_tt,
                        double* restrict P, double* restrict tmp) {
  /* J (m, R, N) row-major, each interval's Jacobian [J_theta, J_k, J_k1]; H_tt (G, G): the running total of
     triu(J_theta^T J_theta) (upper triangle, row-major); P (m, N, W = N - G): each interval's J^T [J_k, J_k1];
     tmp (G, G): work */
  long W = N - G, i, r, a, b;
  for (a = 0; a < G * G; ++a) tmp[a] = 0.0;   /* then zeroed again where it is added to H_tt */
  for (i = 0; i < m; ++i) {
    const double* restrict Ji = J + i * R * N;
    double* restrict Pi = P + i * N * W;
    for (a = 0; a < N * W; ++a) Pi[a] = 0.0;
    for (r = 0; r < R; ++r) {
      const double* restrict row = Ji + r * N;
      long end = G;   /* past the row's last nonzero theta column: the zeros after it add nothing to any sum */
      while (end > 0 && row[end - 1] == 0.0) --end;
      for (a = 0; a < N; ++a) {
        double ja = row[a];
        if (ja == 0.0) continue;
        if (a < end)
          for (b = a; b < end; ++b) tmp[a * G + b] += ja * row[b];
        for (b = 0; b < W; ++b) Pi[a * W + b] += ja * row[G + b];
      }
    }
    for (a = 0; a < G; ++a)
      for (b = a; b < G; ++b) {
        H_tt[a * G + b] += tmp[a * G + b];
        tmp[a * G + b] = 0.0;
      }
  }
}
"""


def gauss_newton_products(compiled: bool = True):
    """`GAUSS_NEWTON_C` compiled (installed with magyro, cached, or compiled now) and loaded by ctypes, or None
    (no compiler, MAGYRO_JIT=0, or not `compiled`): then numpy sums in the same order, slower."""
    import ctypes

    from magyro.nls.kernels import build_libraries, existing_library, jit_enabled, library_path

    if not compiled or not jit_enabled():
        return None
    lib = existing_library(GAUSS_NEWTON_PRODUCTS, GAUSS_NEWTON_PRODUCTS)
    if lib is None:
        lib = library_path(GAUSS_NEWTON_PRODUCTS, GAUSS_NEWTON_PRODUCTS)
        build_libraries([(GAUSS_NEWTON_C.encode(), lib)])
        if not lib.exists():
            return None
    fn = ctypes.CDLL(str(lib)).gauss_newton_parts
    pointer = ctypes.POINTER(ctypes.c_double)
    fn.argtypes = [ctypes.c_long] * 4 + [pointer] * 4
    fn.restype = None
    return fn


def accelerometer_jacobian_kernel(stride: int, L: int, n_theta: int, walk: bool = False, hand: bool = False) -> ca.Function:
    """d r / d theta (3 x n_theta) and d r / d s_k (3 x B) of an interval's accelerometer mean residual (the hand's
    sandwich, nls/hand_motion.py), and d r / d s_k1 with the hand's states: its own small kernel, not the
    Gauss-Newton one's rows."""
    th = ca.SX.sym("theta", n_theta)
    pk, pk1 = ca.SX.sym("s_k", node_size(walk, hand)), ca.SX.sym("s_k1", node_size(walk, hand))
    g = ca.SX.sym("g", global_size(True))
    d = ca.SX.sym("d", sum(k for _, k in data_layout(stride, L, walk, True, hand)))
    r = interval_residuals(th, pk, pk1, g, d, stride, L, walk, True, hand)
    first = 3 * stride + 3 + (3 if walk else 0)
    mean = r[first : first + 3]
    outputs = [ca.jacobian(mean, th), ca.jacobian(mean, pk)] + ([ca.jacobian(mean, pk1)] if hand else [])
    return ca.Function("interval_accelerometer_jacobian", [th, pk, pk1, g, d], outputs, kernel_options(True))


def accelerometer_jacobian(stride: int, L: int, n_theta: int, walk: bool, compiled: bool = True,
                           hand: bool = False) -> ca.Function:
    """`accelerometer_jacobian_kernel`, compiled (installed, cached or compiled now) when `compiled`."""
    key = kernel_key(stride, L, n_theta, walk, hand)
    cached = load_cached_kernel("interval_accelerometer_jacobian", key) if compiled else None
    if cached is not None:
        return cached
    fn = accelerometer_jacobian_kernel(stride, L, n_theta, walk, hand)
    return compile_kernels([fn], key)[0] if compiled else fn


def kernel_key(stride: int, L: int, n_theta: int, walk: bool, hand: bool = False) -> str:
    """What determines the kernels completely (with the source of this module, see kernels.cache_digest)."""
    return f"stride={stride} substeps={L} theta={n_theta}" + (" walk" if walk else "") + (" hand" if hand else "")


def kernel_set(stride: int, L: int, n_theta: int, walk: bool, compiled: bool = True, hand: bool = False) -> list[ca.Function]:
    """The three interval kernels of a shape: compiled (installed with magyro, cached, or compiled now) when
    `compiled`, else the interpreted SX functions."""
    key = kernel_key(stride, L, n_theta, walk, hand)
    cached = [load_cached_kernel(name, key) for name in KERNEL_NAMES] if compiled else [None]
    if all(k is not None for k in cached):  # compiled before: no symbolic build needed
        return cached
    kernels = interval_kernels(stride, L, n_theta, walk, hand)
    return compile_kernels(kernels, key) if compiled else kernels


def node_size(walk: bool, hand: bool = False) -> int:
    """Unknowns per node: the attitude correction phi (3), the hard iron's walk eta (3) when it moves, the hand's
    velocity (3) when it is a state."""
    return 3 + (3 if walk else 0) + (3 if hand else 0)
