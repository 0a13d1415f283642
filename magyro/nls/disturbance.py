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
from magyro.nls.information import Reduced
from magyro.nls.hard_iron import hard_iron_at_samples
from magyro.nls.interval import GLOBAL_SLICES, global_number
from magyro.nls.problem import JointProblem
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
    theta, g = x[: problem.n_theta], p[: problem.n_glob_p]
    S, h, K, eps, m_i, tau = (np.array(v) for v in problem.physical_function(theta, g))
    info_inv = np.linalg.inv(reduced.information)
    if problem.walk:   # the field's magnitude with the moving hard iron taken out: its walk is modelled
        session = replace(session, mag=session.mag - (hard_iron_at_samples(problem, x, p, session) - h.ravel()))
    found = measured_disturbance(problem, theta, g, info_inv, session)
    if found.std_fraction == 0.0:
        return info_inv, found
    U, t_s = disturbance_sensitivities(problem, x, p, reduced, C_m_i_nodes, session, S, m_i.ravel(), float(tau.item()))
    omega = found.std_fraction**2 * exponential_double_sum(U, t_s, found.correlation_time_s)
    return info_inv + info_inv @ omega @ info_inv, found


# --------------------------------------------------------------------------- measuring the disturbance


def measured_disturbance(problem: JointProblem, theta, g, info_inv: np.ndarray, session: Session,
                         window_s: float = WINDOW_S) -> FieldDisturbance:
    """sigma and T from the lag >= 1 autocovariance of the windowed field magnitude, less the part that the
    calibration's own (R, h) uncertainty explains (see the module docstring)."""
    e, G = magnitude_and_gradient(problem, theta, g, session.mag)
    window = np.floor((session.t_mag_s - session.t_mag_s[0]) / window_s).astype(int)
    count = np.bincount(window)
    held = count > 0
    e_w = (np.bincount(window, e) / np.maximum(count, 1))[held]
    G_w = np.stack([np.bincount(window, G[:, a]) for a in range(G.shape[1])], 1)[held] / count[held, None]
    e_w, G_w = e_w - e_w.mean(), G_w - G_w.mean(axis=0)
    n = len(e_w)
    lags = np.arange(1, max(2, min(MAX_LAG_WINDOWS, n // 4)))
    P = G_w @ info_inv[np.ix_(MAGNITUDE_PARAMETERS, MAGNITUDE_PARAMETERS)]
    excess = np.array([np.mean(e_w[k:] * e_w[: n - k]) - np.mean(np.sum(P[k:] * G_w[: n - k], axis=1)) for k in lags])
    if len(excess) == 0 or excess[0] <= 0:
        return FieldDisturbance(0.0, window_s)
    r = excess / excess[0]
    stop = int(np.argmax(r <= 0)) if np.any(r <= 0) else len(r)
    correlation_s = window_s * (0.5 + float(np.sum(r[:stop])))   # integrated correlation time
    return FieldDisturbance(float(np.sqrt(excess[0] * np.exp(window_s / correlation_s))), correlation_s)


def magnitude_and_gradient(problem: JointProblem, theta, g, mag: np.ndarray, step: float = 1e-6):
    """(|R (y - h)| - 1 per sample, its gradient with respect to the soft- and hard-iron corrections)."""
    def magnitude(th):
        S, h = (np.array(v) for v in problem.physical_function(th, g)[:2])
        return np.linalg.norm(calibrated_field(np.linalg.inv(S), h.ravel(), mag), axis=1)

    G = np.empty((len(mag), len(MAGNITUDE_PARAMETERS)))
    for k, a in enumerate(MAGNITUDE_PARAMETERS):
        d = np.zeros_like(theta)
        d[a] = step
        G[:, k] = (magnitude(theta + d) - magnitude(theta - d)) / (2 * step)
    return magnitude(theta) - 1.0, G


# --------------------------------------------------------------------------- its effect on the estimate


def disturbance_sensitivities(problem: JointProblem, x, p, reduced: Reduced, C_m_i_nodes: np.ndarray,
                              session: Session, S: np.ndarray, m_i: np.ndarray, tau_s: float):
    """(u_j (n, n_theta, 3) for the magnetometer samples that carry a residual, their times)."""
    grid = problem.grid
    s = grid.stride
    rows = magnetometer_rows(problem, x, p)                                   # (n_int, 3s, n_theta)
    t_seg = session.t_mag_s[grid.mag_index]                                   # (n_int, s)
    A = np.swapaxes(so3.interpolate(grid.t_node_s, C_m_i_nodes, (t_seg - tau_s).ravel()), -1, -2)   # C_i^m per sample
    w = grid.mag_weight.ravel() * global_number(p, "w_mag")
    L = -w[:, None, None] * (S @ A)                                           # d r_j / d delta_j
    B = problem.B
    phi = np.vstack([np.zeros(3), x[problem.n_theta :].reshape(-1, B)[:, :3]])
    start = C_m_i_nodes[:-1] @ so3.right_jacobian(phi[:-1])                   # C_n J_r(phi_n), node n of interval n
    J_node = L.reshape(problem.n_int, s, 3, 3) @ (so3.skew(m_i) @ start)[:, None]   # d r / d phi_n, (n_int, s, 3, 3)
    if problem.walk:   # d r / d eta_n = -w field_scale I
        field_scale = global_number(p, "field_scale")
        J_eta = -(w * field_scale).reshape(problem.n_int, s, 1, 1) * np.eye(3)
        J_node = np.concatenate([J_node, J_eta], axis=-1)                     # (n_int, s, 3, 6)
    W = np.concatenate([np.zeros((1, B, problem.n_theta)), reduced.Dinv_Hpt.reshape(problem.n_int, B, -1)[:-1]])
    J_profiled = rows.reshape(problem.n_int, s, 3, -1) - J_node @ W[:, None]  # (n_int, s, 3, n_theta)
    U = np.einsum("nsra,nsrc->nsac", J_profiled, L.reshape(problem.n_int, s, 3, 3)).reshape(-1, problem.n_theta, 3)
    carries = grid.mag_weight.ravel() > 0
    return U[carries], t_seg.ravel()[carries]


def magnetometer_rows(problem: JointProblem, x, p) -> np.ndarray:
    """d r / d theta of every magnetometer residual, (n_int, 3 stride, n_theta), from the Gauss-Newton kernel."""
    xs, ps, args = problem._symbols
    JthT = problem.gn_kernel.map(problem.n_int)(*args)[0]      # n_theta x (n_res_per_interval n_int)
    rows = np.array(ca.Function("theta_rows", [xs, ps], [JthT])(x, p))
    rows = rows.reshape(problem.n_theta, problem.n_int, problem.n_res_per_interval)   # interval-major columns
    return np.transpose(rows[:, :, : 3 * problem.grid.stride], (1, 2, 0))


def exponential_double_sum(U: np.ndarray, t_s: np.ndarray, correlation_s: float) -> np.ndarray:
    """sum_jk exp(-|t_j - t_k| / T) U_j U_k^T for U (n, a, c) in time order, in O(n a c) by a recursion
    over the samples binned to 10 ms (the kernel is flat over that when T >= 0.2 s)."""
    bins = np.floor((t_s - t_s[0]) / 0.01).astype(int)
    starts = np.flatnonzero(np.r_[True, np.diff(bins) > 0])
    V = np.add.reduceat(U, starts, axis=0)
    t_b = t_s[starts]
    decay = np.exp(-np.diff(t_b) / correlation_s)
    acc = np.empty_like(V)
    acc[0] = V[0]
    for k in range(1, len(V)):
        acc[k] = decay[k - 1] * acc[k - 1] + V[k]
    cross = np.einsum("kac,kbc->ab", acc, V)
    return cross + cross.T - np.einsum("kac,kbc->ab", V, V)
