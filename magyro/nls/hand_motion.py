"""The std that counts the hand: its acceleration is correlated from one interval to the next.

The accelerometer's interval means carry the hand's acceleration a(t), tenths of m/s^2 while a hand turns the
device. Its variance is in their weights (nls/accelerometer.py), which count every interval as independent (with
the hand's variance scaled by the peak of its spectrum); it is not: a hand sways at the frequencies it turns at. As
for the room's field (nls/disturbance.py), the estimate is kept and its covariance is the sandwich

    Cov = I^-1 (I + Omega) I^-1,   Omega = sum_{j, k} U_j rho(j - k) U_k^T - sum_j V_j V_j^T,

U_j = Jt_j^T L_j, Jt_j the profiled Jacobian of interval j's accelerometer residual (its start node moved along
with the calibration), L_j = w_j s_h(t_j) M C_i^m(t_j) how a unit of the hand's acceleration in frame i enters it
(the readings are y = M f + c), and
rho the hand's measured autocorrelation over intervals (`accelerometer.tapered_autocorrelation`), isotropic in
frame i, of the local std s_h(t) measured (nls/accelerometer.py `hand_motion`); V_j is U_j with the std the
weights hold, which I counts as independent already. At rest s_h is zero. The
double sum is one product per frequency: Omega = Re sum_f S(f) F(f) F(f)^H / N, F the Fourier transform of U
over the intervals and S that of rho, with N >= n + max lag so that no lag wraps around. I + Omega is
J^T W (white + hand) W J, positive semi-definite; where the weights hold more hand than measured the std comes out
below I^-1.
"""
from __future__ import annotations

import numpy as np

from magyro import so3
from magyro.nls.accelerometer import HAND_REACH_M, hand_spectrum
from magyro.nls.interval import data_layout
from magyro.nls.on_numpy import MapOnNumpy
from magyro.nls.problem import JointProblem
from magyro.nls.reduction import Reduced



def hand_covariance_term(problem: JointProblem, x: np.ndarray, p: np.ndarray, reduced: Reduced, information: np.ndarray,
                         hand_std_m_s2: np.ndarray, weights_hand_std_m_s2: np.ndarray,
                         correlation: np.ndarray, variance_m2_s4: float, reach_m: float = HAND_REACH_M) -> np.ndarray:
    """I^-1 Omega I^-1: what the hand's correlated acceleration adds to the corrections' covariance.
    `hand_std_m_s2` (n_int,) is s_h per interval as measured, `weights_hand_std_m_s2` the one the weights hold (I
    counts it: it is taken out again), `correlation` rho at lags 0, 1, ... intervals, its spectrum capped where no
    hand held within reach could put it (`accelerometer.hand_spectrum`, with the hand's variance `variance_m2_s4`)."""
    if not np.any(hand_std_m_s2 > 0) and not np.any(weights_hand_std_m_s2 > 0):
        return np.zeros_like(information)
    sensitivities = hand_sensitivities(problem, x, p, reduced, np.ones(problem.n_int))
    U = sensitivities * hand_std_m_s2[:, None, None]                                       # (n_int, n_theta, 3)
    counted = sensitivities * weights_hand_std_m_s2[:, None, None]
    n, L = len(U), len(correlation) - 1
    size = 1 << int(np.ceil(np.log2(n + L + 1)))
    S = hand_spectrum(correlation, size, variance_m2_s4, float(np.median(problem.grid.interval_s)), reach_m)
    F = np.fft.rfft(U, size, axis=0)                              # (size/2 + 1, n_theta, 3)
    weights = np.full(len(S), 2.0)
    weights[0] = 1.0
    if size % 2 == 0:
        weights[-1] = 1.0
    G = (F * np.sqrt(np.maximum(S * weights, 0.0) / size)[:, None, None]).transpose(0, 2, 1).reshape(-1, F.shape[1])
    omega = (G.T @ G.conj()).real                                 # sum over f and axes of S F F^H / N: one product
    held = counted.transpose(0, 2, 1).reshape(-1, counted.shape[1])
    omega -= held.T @ held                                        # what I counts as independent
    return sandwich_term(information, omega)


def shifted_hand_covariance_term(problem: JointProblem, x: np.ndarray, p: np.ndarray, reduced: Reduced,
                                 information: np.ndarray, hand_i_m_s2: np.ndarray, white_m2_s4: np.ndarray) -> np.ndarray:
    """I^-1 Omega I^-1: what the hand adds to the corrections' covariance, the hand that could have come being the
    recording's own (`hand_i_m_s2` (n_int, 3), frame i, as measured with its white noise, zero where unused) at any
    time (`shifted_hand_information`)."""
    U = hand_sensitivities(problem, x, p, reduced, np.ones(problem.n_int))
    return sandwich_term(information, shifted_hand_information(U, hand_i_m_s2, white_m2_s4))


def shifted_hand_information(U: np.ndarray, hand: np.ndarray, white: np.ndarray) -> np.ndarray:
    """Omega (n_theta, n_theta): the mean over every shift s in time of e_s e_s^T, e_s = sum_j U_j a_(j+s) what the
    hand a (n, 3; zero outside the record) moved by s puts into the gradient (U (n, n_theta, 3) per unit of it in
    each interval), less what the white noise in a puts there (`white` (n,), its variance per axis in each
    interval). Its spectrum is the hand's periodogram, each axis's own and their cross-spectra: no taper, no
    isotropy, no stationary size. One recording's hand is a few sways, each at a frequency of its own; the
    autocorrelation tapered over 30 s and averaged over the axes (`hand_covariance_term`'s) smeared each over 1/30 Hz,
    and fed the simulator's true hand its share of the std was 1.0-1.8x the error that hand makes; shifted, 0.8-1.2x
    (benchmarks/hand_states_std.py, 64 seeds of each simulated problem)."""
    n = len(U)
    size = 1 << int(np.ceil(np.log2(2 * n)))                   # no shift wraps around
    spectrum = np.einsum("fga,fa->fg", np.fft.rfft(U, size, axis=0), np.fft.rfft(hand[::-1], size, axis=0))
    errors = np.fft.irfft(spectrum, size, axis=0)              # e_s at every shift (and zeros)
    flat = U.transpose(0, 2, 1).reshape(-1, U.shape[1])
    return errors.T @ errors / n - float(np.sum(white)) / n * (flat.T @ flat)


def sandwich_term(information: np.ndarray, omega: np.ndarray) -> np.ndarray:
    """I^-1 (I + Omega) I^-1 - I^-1, I + Omega (J^T W (white + hand) W J) made positive semi-definite: where the
    hand measured is smaller than what the information already counts, the std comes out below I^-1."""
    info_inv = np.linalg.inv(information)
    value, vector = np.linalg.eigh(information + omega)
    return info_inv @ ((vector * np.maximum(value, 0.0)) @ vector.T) @ info_inv - info_inv


def hand_sensitivities(problem: JointProblem, x, p, reduced: Reduced, hand_std_m_s2: np.ndarray) -> np.ndarray:
    """U_j (n_int, n_theta, 3) for every interval (zero where it carries no accelerometer mean or the hand is still),
    from the accelerometer's own Jacobian kernel evaluated over every interval as the solve's kernels are
    (`on_numpy.MapOnNumpy`: through buffers, MAP_CHUNK intervals a piece), its sparse outputs put in place."""
    B, G = problem.B, problem.n_theta
    W_all = reduced.Dinv_Hpt.reshape(problem.n_int, B, -1)                  # nodes 1..n_int
    W = np.concatenate([np.zeros((1, B, G)), W_all[:-1]])                    # each interval's first node
    theta, g = np.asarray(x[:G], dtype=float), problem.globals_of(p).astype(float)
    states = node_states(problem, x)                                         # nodes 0..n_int
    data = problem.data_of(p)
    weight = data[:, data_offset(problem, "w_acc")]
    readout = np.linalg.inv(np.array(problem.accelerometer_function(theta, g)[0]))   # M: the hand reads as M C_i^m a
    kernel = problem.accelerometer_jacobian
    places = [kernel.sparsity_out(i).get_triplet() for i in range(kernel.n_out())]   # (rows, columns) of each nonzero
    U = np.zeros((problem.n_int, G, 3))

    def piece(a: int, b: int, values) -> None:
        dense = [np.zeros((b - a, 3, G))] + [np.zeros((b - a, 3, B)) for _ in range(kernel.n_out() - 1)]
        for out, v, (rows, columns) in zip(dense, values, places):
            out[:, rows, columns] = v.reshape(b - a, len(rows))                # each interval's nonzeros, in order
        n = slice(a, b)
        J_profiled = dense[0] - dense[1] @ W[n]
        if problem.hand:   # the hand's states: the mean reads the next node's velocity too
            J_profiled = J_profiled - dense[2] @ W_all[n]
        L = (weight[n] * hand_std_m_s2[n])[:, None, None] * (readout @ attitude_i_to_m(data[n], states[n]))  # (m, 3, 3)
        U[n] = np.swapaxes(J_profiled, -1, -2) @ L
    MapOnNumpy(problem, kernel, pieces=True)(x, p, piece)
    return U


def data_offset(problem: JointProblem, name: str) -> int:
    """Where the per-interval datum `name` starts in an interval's data (interval.data_layout)."""
    o = 0
    for entry, k in data_layout(problem.grid.stride, problem.grid.substeps, problem.walk, problem.accelerometer):
        if entry == name:
            return o
        o += k
    raise KeyError(name)


def node_states(problem: JointProblem, x: np.ndarray) -> np.ndarray:
    """(n_int + 1, B) every node's states, node 0's (fixed) zero."""
    return np.vstack([np.zeros(problem.B), x[problem.n_theta :].reshape(-1, problem.B)])


def attitude_i_to_m(data: np.ndarray, states: np.ndarray) -> np.ndarray:
    """C_i^m at each interval's start node, (m, 3, 3): (Cbar Exp(phi))^T, from the intervals' data and start states."""
    Cbar = data[:, :9].reshape(-1, 3, 3).transpose(0, 2, 1)   # column-major vec of each Cbar
    return np.swapaxes(Cbar @ so3.exp_so3(states[:, :3]), -1, -2)
