"""The std that counts the room: a slowly varying field disturbance, marginalised into the covariance.

The model takes the field as homogeneous: m^i is one unit vector. In a real room
it is not (BROAD: 1-3 % across the capture volume, 7-11 %/m), so along the path
the field departs from m^i by a slow, correlated delta(t). The white-noise
weights count each magnetometer sample as independent information; correlated
model error is not, and the white std came out 2-3x too small on every
undisturbed BROAD trial (docs/real-data.md section 2).

Here delta(t) is a Gauss-Markov process in the frame i, isotropic, of std
`sigma` (a fraction of the field) and correlation time `correlation_s`:
E[delta(t) delta(s)^T] = sigma^2 exp(-|t - s| / T) I. The least-squares estimate
is kept as it is; its covariance under noise plus disturbance is the sandwich

    Cov = I^-1 + I^-1 Omega I^-1,   Omega = sum_jk u_j E[delta_j delta_k^T] u_k^T,

with I the Gauss-Newton information (attitudes eliminated) and u_j = Jt_j^T L_j
the profiled sensitivity of the estimate to delta at magnetometer sample j:
L_j = -w_j S A_j (A_j = C_i^m at the sample) is how delta enters that
residual, and Jt_j = J_theta,j - J_phi,j W_n its Jacobian with the attitude of
its node n moved along with the calibration (W = D^-1 H_phi,theta).

sigma and T are measured from the recording itself: the calibrated field's
magnitude |R (y - h)| follows the component of delta along the field. Its
autocovariance over 0.2 s window means, at lags of one window and more (where
white noise has none), minus what the calibration's own (R, h) uncertainty
explains, gives sigma^2 exp(-lag / T). A homogeneous field gives sigma ~ 0 and
the white std back (simulations: +2 % on average). The disturbance's direction
is not seen, so isotropy is an assumption: the std is right when the room's
disturbance is no larger across the field than along it.
"""
from __future__ import annotations

from dataclasses import replace

import casadi as ca
import numpy as np

from magyro import so3
from magyro.front.ellipsoid import calibrated_field
from magyro.nls.reduction import Reduced
from magyro.nls.hard_iron import hard_iron_at_samples
from magyro.nls.interval import GLOBAL_SLICES, global_number, node_size
from magyro.nls.problem import JointProblem, evaluate
from magyro.result.parts import FieldDisturbance
from magyro.session import Session

WINDOW_S = 0.2        # the field magnitude is averaged over windows this long (white noise averages out)
MAX_LAG_WINDOWS = 300  # autocovariance up to 60 s
MAGNITUDE_PARAMETERS = np.r_[GLOBAL_SLICES["U"], GLOBAL_SLICES["dh"]]   # the corrections |R (y - h)| depends on


def disturbance_covariance(problem: JointProblem, x: np.ndarray, p: np.ndarray, reduced: Reduced,
                           C_m_i_nodes: np.ndarray, session: Session) -> tuple[np.ndarray, FieldDisturbance]:
    """(the covariance of the corrections with the field disturbance marginalised, the disturbance measured).

    Serves the solve (at its solution) and the prediction before it (at the linearisation point).
    """
    theta, g = x[: problem.n_theta], problem.globals_of(p)
    S, h, K, eps, m_i, tau = (np.array(v) for v in problem.physical_function(theta, g))
    info_inv = np.linalg.inv(reduced.information)
    if problem.walk:   # the field's magnitude with the moving hard iron taken out: its walk is modelled
        session = replace(session, mag=session.mag - (hard_iron_at_samples(problem, x, p, session) - h.ravel()))
    found = measured_disturbance(problem, theta, g, info_inv, session)
    if found.std_fraction == 0.0:
        return info_inv, found
    omega = found.std_fraction**2 * disturbance_information(problem, x, p, reduced, C_m_i_nodes, session, S,
                                                             m_i.ravel(), float(tau.item()), found.correlation_time_s)
    return info_inv + info_inv @ omega @ info_inv, found


# --------------------------------------------------------------------------- measuring the disturbance


def measured_disturbance(problem: JointProblem, theta, g, info_inv: np.ndarray, session: Session,
                         window_s: float = WINDOW_S) -> FieldDisturbance:
    """sigma and T from the lag >= 1 autocovariance of the windowed field magnitude, less the part that the
    calibration's own (R, h) uncertainty explains (see the module docstring)."""
    e, G = magnitude_and_gradient(problem, theta, g, session.mag)
    cov = info_inv[np.ix_(MAGNITUDE_PARAMETERS, MAGNITUDE_PARAMETERS)]
    return disturbance_from_magnitude(session.t_mag_s, e, G, cov, window_s)


def window_means(t_s: np.ndarray, x: np.ndarray, window_s: float) -> np.ndarray:
    """The means of x (N,) or (N, k) over consecutive windows of `window_s` from the first sample; empty windows
    (holes) left out."""
    window = np.floor((t_s - t_s[0]) / window_s).astype(int)
    count = np.bincount(window)
    held = count > 0
    columns = np.asarray(x, dtype=float).reshape(len(t_s), -1)
    means = np.stack([np.bincount(window, columns[:, a]) for a in range(columns.shape[1])], 1)[held] / count[held, None]
    return means.reshape(-1) if np.ndim(x) == 1 else means


def disturbance_from_magnitude(t_mag_s: np.ndarray, e: np.ndarray, G: np.ndarray, cov: np.ndarray,
                               window_s: float = WINDOW_S) -> FieldDisturbance:
    """sigma and T from the calibrated field's magnitude less one, `e` per sample, its gradient `G` with respect to
    the magnetometer's corrections and their covariance `cov` (either method's parametrisation)."""
    e_w, G_w = window_means(t_mag_s, e, window_s), window_means(t_mag_s, G, window_s)
    e_w, G_w = e_w - e_w.mean(), G_w - G_w.mean(axis=0)
    n = len(e_w)
    lags = np.arange(1, max(2, min(MAX_LAG_WINDOWS, n // 4)))
    P = G_w @ cov
    excess = np.array([np.mean(e_w[k:] * e_w[: n - k]) - np.mean(np.sum(P[k:] * G_w[: n - k], axis=1)) for k in lags])
    if len(excess) == 0 or excess[0] <= 0:
        return FieldDisturbance(0.0, window_s)
    r = excess / excess[0]
    stop = int(np.argmax(r <= 0)) if np.any(r <= 0) else len(r)
    correlation_s = window_s * (0.5 + float(np.sum(r[:stop])))   # integrated correlation time
    return FieldDisturbance(float(np.sqrt(excess[0] * np.exp(window_s / correlation_s))), correlation_s)


def magnitude_and_gradient(problem: JointProblem, theta, g, mag: np.ndarray):
    """(|R (y - h)| - 1 per sample, its gradient with respect to the soft- and hard-iron corrections).

    S = R^-1 and h are linear in the corrections (S = S0 (I + U), h = h0 + field_scale dh), so a unit step of each
    gives its dS and dh exactly, and with v = R (y - h): d|v| = -(R^T v) . (dS v + dh) / |v|, one product per
    correction (central differences took 19 passes over the samples: 0.2 s at 360k)."""
    def physical(th):
        S, h = (np.array(v) for v in problem.physical_function(th, g)[:2])
        return S, h.ravel()

    S, h = physical(theta)
    R = np.linalg.inv(S)
    v = calibrated_field(R, h, mag)
    norm = np.linalg.norm(v, axis=1)
    w = (v @ R) / norm[:, None]                       # (R^T v) / |v| per sample
    dS, dh = np.empty((9, len(MAGNITUDE_PARAMETERS))), np.empty((3, len(MAGNITUDE_PARAMETERS)))
    for k, a in enumerate(MAGNITUDE_PARAMETERS):
        d = np.zeros_like(theta)
        d[a] = 1.0
        S_a, h_a = physical(theta + d)
        dS[:, k], dh[:, k] = (S_a - S).reshape(-1), h_a - h
    G = -((w[:, :, None] * v[:, None, :]).reshape(-1, 9) @ dS + w @ dh)   # w^T dS v + w^T dh, all at once
    return norm - 1.0, G


# --------------------------------------------------------------------------- its effect on the estimate


SENSITIVITY_CHUNK = 1024   # intervals per piece of the sensitivities: their memory is a piece's, not the session's
ROWS_MAP = 256             # intervals per evaluation of the rows' map


def disturbance_information(problem: JointProblem, x, p, reduced: Reduced, C_m_i_nodes: np.ndarray,
                            session: Session, S: np.ndarray, m_i: np.ndarray, tau_s: float,
                            correlation_s: float) -> np.ndarray:
    """sum_jk exp(-|t_j - t_k| / T) u_j u_k^T over the magnetometer samples that carry a residual, the
    sensitivities u_j made and summed a piece of SENSITIVITY_CHUNK intervals at a time: at 360k samples the
    whole (n, n_theta, 3) array and the n_theta x n_res J_theta^T behind it took 1.7 GB."""
    total = ExponentialDoubleSum(correlation_s)
    for U, t_s in disturbance_sensitivities(problem, x, p, reduced, C_m_i_nodes, session, S, m_i, tau_s):
        total.add(U, t_s)
    return total.result()


def disturbance_sensitivities(problem: JointProblem, x, p, reduced: Reduced, C_m_i_nodes: np.ndarray,
                              session: Session, S: np.ndarray, m_i: np.ndarray, tau_s: float,
                              chunk: int = SENSITIVITY_CHUNK):
    """Pieces, in time order, of (u_j (n, n_theta, 3) for the magnetometer samples that carry a residual, their
    times), each from `chunk` intervals."""
    grid, B, G = problem.grid, problem.B, problem.n_theta
    s = grid.stride
    W = np.concatenate([np.zeros((1, B, G)), reduced.Dinv_Hpt.reshape(problem.n_int, B, -1)[:-1]])
    w_mag = global_number(problem.globals_of(p), "w_mag")
    field_scale = global_number(problem.globals_of(p), "field_scale")
    rows_of = ThetaRows(problem, x, p)
    states = rows_of.states                                                  # node 0 (fixed) .. n_int
    for a in range(0, problem.n_int, chunk):
        n = slice(a, min(a + chunk, problem.n_int))
        m = n.stop - a
        rows = rows_of(n)                                                    # (m, 3s, n_theta)
        t_seg = session.t_mag_s[grid.mag_index[n]]                           # (m, s)
        A = np.swapaxes(so3.interpolate(grid.t_node_s, C_m_i_nodes, (t_seg - tau_s).ravel()), -1, -2)  # C_i^m
        w = grid.mag_weight[n].ravel() * w_mag
        L = -w[:, None, None] * (S @ A)                                      # d r_j / d delta_j
        start = C_m_i_nodes[n] @ so3.right_jacobian(states[n, :3])           # C_n J_r(phi_n), node n of interval n
        J_node = L.reshape(m, s, 3, 3) @ (so3.skew(m_i) @ start)[:, None]    # d r / d phi_n, (m, s, 3, 3)
        if problem.walk:   # d r / d eta_n = -w field_scale I
            J_node = np.concatenate([J_node, -(w * field_scale).reshape(m, s, 1, 1) * np.eye(3)], axis=-1)
        if problem.hand:   # the hand's velocity is not in the magnetometer's residuals
            J_node = np.concatenate([J_node, np.zeros((m, s, 3, 3))], axis=-1)
        J_profiled = rows.reshape(m, s, 3, -1) - J_node @ W[n][:, None]     # (m, s, 3, n_theta)
        U = (np.swapaxes(J_profiled, -1, -2) @ L.reshape(m, s, 3, 3)).reshape(-1, G, 3)
        carries = grid.mag_weight[n].ravel() > 0
        yield U[carries], t_seg.ravel()[carries]


class ThetaRows:
    """d r / d theta of the magnetometer residuals of a slice of intervals, (m, 3 stride, n_theta), from the
    Jacobian kernel evaluated on that slice alone: mapped over the slice (theta and g shared), evaluated through
    buffers on numpy, J's theta columns. Mapping a kernel with sparse outputs and DM arguments cost 3-4x more (0.12
    against 0.034 s for 833 intervals). With the accelerometer the kernel is the one without it
    (`JointProblem.magnetometer_jacobian_kernel`): the magnetometer rows are the same, and none of the accelerometer's
    work is done for them."""

    def __init__(self, problem: JointProblem, x, p):
        self.problem = problem
        self.rows = problem.magnetometer_jacobian_kernel   # J^T dense: its column-major values are J's rows
        B = node_size(problem.walk)                        # its states: the problem's without the hand's
        self.n_theta = self.rows.size_out(0)[0] - 2 * B    # its theta: a prefix of the problem's
        self.x_theta = np.asarray(x[: self.n_theta], dtype=float)
        self.g_values = problem.globals_of(p)[: self.rows.nnz_in(3)].astype(float)   # its globals: a prefix
        self.states = np.vstack([np.zeros(problem.B), x[problem.n_theta :].reshape(-1, problem.B)])[:, :B]   # nodes 0..n_int
        self.data = problem.data_of(p)[:, : self.rows.nnz_in(4)]   # its data: a prefix of each interval's
        self.maps = {}

    def __call__(self, n: slice) -> np.ndarray:
        """(m, 3 stride, n_theta): the magnetometer residuals' rows of each interval (zero in the accelerometer's
        columns), ROWS_MAP intervals per evaluation of the map (a map's construction grows faster than its length:
        27 ms for 833 intervals, 6 ms for 256; one map of ROWS_MAP serves every piece)."""
        problem, m = self.problem, n.stop - n.start
        width, residuals = self.rows.size_out(0)   # J's columns (its theta and 2 B), its residuals per interval
        mag = 3 * problem.grid.stride
        rows = np.zeros((m, mag, problem.n_theta))
        for a in range(n.start, n.stop, ROWS_MAP):
            b = min(a + ROWS_MAP, n.stop)
            if b - a not in self.maps:
                self.maps[b - a] = self.rows.map(b - a, [True, False, False, True, False], [False], {})
            rows[a - n.start : b - n.start, :, : self.n_theta] = evaluate(
                self.maps[b - a], self.x_theta, self.states[a:b].ravel(), self.states[a + 1 : b + 1].ravel(),
                self.g_values, self.data[a:b].ravel())[0].reshape(b - a, residuals, width)[:, :mag, : self.n_theta]
        return rows


class ExponentialDoubleSum:
    """sum_jk exp(-|t_j - t_k| / T) U_j U_k^T for U (n, a, c) given in pieces in time order, in O(n a c) by a
    recursion over the samples binned to 10 ms (the kernel is flat over that when T >= 0.2 s)."""

    BIN_S = 0.01
    BLOCK_T = 30.0   # correlation times per vectorised block: exp(30) keeps the scaled sums well inside doubles

    def __init__(self, correlation_s: float):
        self.correlation_s = correlation_s
        self.t0_s = None
        self.acc = None          # the recursion's state after the last bin run
        self.t_last_s = None
        self.cross = 0.0         # sum_k acc_k V_k^T
        self.square = 0.0        # sum_k V_k V_k^T
        self.pending = None      # (bin, its first time, V) of the last bin seen: the next piece may add to it

    def add(self, U: np.ndarray, t_s: np.ndarray) -> None:
        if len(U) == 0:
            return
        if self.t0_s is None:
            self.t0_s = float(t_s[0])
        bins = np.floor((t_s - self.t0_s) / self.BIN_S).astype(int)
        starts = np.flatnonzero(np.r_[True, np.diff(bins) > 0])
        V, b, t_b = np.add.reduceat(U, starts, axis=0), bins[starts], t_s[starts].astype(float)
        if self.pending is not None:
            bin_, t_first, V_pending = self.pending
            if b[0] == bin_:
                V[0] += V_pending
                t_b[0] = t_first
            else:
                self.run(V_pending[None], np.array([t_first]))
        self.pending = (b[-1], t_b[-1], V[-1].copy())
        self.run(V[:-1], t_b[:-1])

    def run(self, V: np.ndarray, t_b: np.ndarray) -> None:
        """The recursion acc_k = exp(-(t_k - t_k-1) / T) acc_k-1 + V_k over bins, vectorised in blocks of at
        most BLOCK_T correlation times: acc_k = exp(-s_k) (carry + sum_j<=k exp(s_j) V_j), s = (t - t_0) / T."""
        T = self.correlation_s
        k0 = 0
        while k0 < len(V):
            t0 = t_b[k0]
            k1 = max(int(np.searchsorted(t_b, t0 + self.BLOCK_T * T, side="right")), k0 + 1)
            scaled = (t_b[k0:k1] - t0) / T
            carry = 0.0 if self.acc is None else np.exp(-(t0 - self.t_last_s) / T) * self.acc
            block = V[k0:k1]
            acc = np.exp(-scaled)[:, None, None] * (carry + np.cumsum(np.exp(scaled)[:, None, None] * block, axis=0))
            self.cross = self.cross + pair_sum(acc, block)
            self.square = self.square + pair_sum(block, block)
            self.acc, self.t_last_s = acc[-1], t_b[k1 - 1]
            k0 = k1

    def result(self) -> np.ndarray:
        if self.pending is not None:
            self.run(self.pending[2][None], np.array([self.pending[1]]))
            self.pending = None
        return self.cross + np.transpose(self.cross) - self.square


def pair_sum(X: np.ndarray, Y: np.ndarray) -> np.ndarray:
    """sum_k X_k Y_k^T for X (n, a, c), Y (n, b, c), as one matrix product (einsum took 3 s at 360k samples)."""
    return np.swapaxes(X, 0, 1).reshape(X.shape[1], -1) @ np.swapaxes(Y, 0, 1).reshape(Y.shape[1], -1).T


def exponential_double_sum(U: np.ndarray, t_s: np.ndarray, correlation_s: float) -> np.ndarray:
    """sum_jk exp(-|t_j - t_k| / T) U_j U_k^T for U (n, a, c) in time order (`ExponentialDoubleSum` in one piece)."""
    total = ExponentialDoubleSum(correlation_s)
    total.add(U, t_s)
    return total.result()
