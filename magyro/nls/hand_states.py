"""The hand as states: its velocity at the nodes, an Ornstein-Uhlenbeck process (`NLS(hand_states=True)`, the default).

The accelerometer's interval means read gravity and the hand's acceleration together. Weighted as independent
noise (nls/accelerometer.py) the hand's sway, which lasts seconds, counts as dozens of independent intervals, and
the calibration follows it: on the simulated phone module its scale factors spread 8-13x their Cramer-Rao bound,
and on BROAD's fast trials they came out 4-30 % from 1, many std. Here the hand's velocity v (frame i, m/s) is a
state at every node, the interval's mean acceleration is (v_k1 - v_k) / T and the velocity is an
Ornstein-Uhlenbeck process

    v_k1 = exp(-T / tau) v_k + w_k,     w_k ~ N(0, sigma_v^2 (1 - exp(-2 T / tau)) I),

v_0 = 0 (the device still at the start). The interval means are then weighted by their white noise alone, and the
hand is what the states take. The process's two numbers come from the first pass's hand
(`accelerometer.hand_motion`): sigma_v = the hand's acceleration std per axis over 2 pi HAND_SWAY_HZ (a sway of
that frequency), tau = HAND_TAU_S (benchmarks/accelerometer_hand_models.py measured the family against the
simulator's hand; docs/accelerometer.md, "The hand as states", what the solves give).

The std is the sandwich of that estimator under the hand it measured (`hand_in_frame_i`, shifted to every time it
could have come: nls/hand_motion.py `shifted_hand_covariance_term`): the states' prior is no data, so its share of
the information is taken out (`prior_information`).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from magyro.nls.hand_motion import attitude_i_to_m, node_states
from magyro.nls.interval import hand_slice

HAND_SWAY_HZ = 0.1     # the hand's velocity std is its acceleration's over 2 pi times this
HAND_TAU_S = 0.3       # the velocity's correlation time


@dataclass(frozen=True)
class HandPrior:
    """The hand's velocity process: its std per axis (m/s) and correlation time (s)."""

    sigma_v_m_s: float
    tau_s: float = HAND_TAU_S

    def columns(self, interval_s: np.ndarray) -> np.ndarray:
        """(n_int, 3): each interval's 1 / T, the velocity's decay over it, the weight of its step."""
        T = np.maximum(np.asarray(interval_s, dtype=float), 1e-9)
        decay = np.exp(-T / self.tau_s)
        step_std = self.sigma_v_m_s * np.sqrt(1.0 - decay**2)
        return np.column_stack([1.0 / T, decay, 1.0 / step_std])


def hand_prior(variance_m2_s4: float) -> HandPrior | None:
    """The prior of a hand whose acceleration has this variance per axis; None for a still hand."""
    if not variance_m2_s4 > 0:
        return None
    return HandPrior(float(np.sqrt(variance_m2_s4)) / (2.0 * np.pi * HAND_SWAY_HZ))


def interleave_hand(problem_from, problem_to, x: np.ndarray) -> np.ndarray:
    """A solution of `problem_from` (no hand states) as a start of `problem_to` (the same, with them): the hand's
    velocity zero at every node."""
    G, B0, B1 = problem_from.n_theta, problem_from.B, problem_to.B
    out = np.zeros(problem_to.n_x)
    out[:G] = x[:G]
    out[G:].reshape(-1, B1)[:, :B0] = x[G:].reshape(-1, B0)
    return out


def prior_information(problem, reduced) -> np.ndarray:
    """P (n_theta, n_theta): the profiled information the velocity's prior rows hold, sum_k w_k^2 D_k^T D_k with
    D_k = W_k1 - decay_k W_k on the velocity, W_n node n's response to the corrections (reduced.Dinv_Hpt; node 0
    fixed)."""
    B, G = problem.B, problem.n_theta
    W = np.concatenate([np.zeros((1, B, G)), reduced.Dinv_Hpt.reshape(problem.n_int, B, G)])   # nodes 0..n_int
    v = hand_slice(problem.walk)
    cols = problem.hand_prior.columns(problem.grid.interval_s)
    D = (W[1:, v] - cols[:, 1, None, None] * W[:-1, v]) * cols[:, 2, None, None]               # (n_int, 3, G)
    flat = D.reshape(-1, G)
    return flat.T @ flat


def hand_velocity(problem, x: np.ndarray) -> np.ndarray:
    """(n_int + 1, 3) the hand's velocity at the nodes (frame i, m/s), node 0's zero."""
    return node_states(problem, x)[:, hand_slice(problem.walk)]


def hand_reach_m(problem, x: np.ndarray) -> float:
    """The std (m, RMS over the axes) of the device's position, the hand's velocity states integrated: how far the
    hand took it from where it was turned, as the states say (they may take up more than the hand)."""
    v = hand_velocity(problem, x)
    position = np.cumsum(0.5 * (v[1:] + v[:-1]) * problem.grid.interval_s[:, None], axis=0)
    return float(np.sqrt(np.mean(position.var(axis=0))))


def hand_in_frame_i(problem, x: np.ndarray, p: np.ndarray, residuals: np.ndarray) -> np.ndarray:
    """(n_int, 3) the hand's mean acceleration in each interval, frame i (m/s^2): the states' (v_k1 - v_k) / T plus
    what the accelerometer's unweighted residuals (n_int, 3; y = M C_i^m a + ...) leave, C_m^i A r. The hand and the
    white noise, whatever the states took of it."""
    states = node_states(problem, x)
    v = states[:, hand_slice(problem.walk)]
    A = np.array(problem.accelerometer_function(x[: problem.n_theta], problem.globals_of(p))[0])
    C_i_m = attitude_i_to_m(problem.data_of(p), states[:-1])
    return (v[1:] - v[:-1]) / problem.grid.interval_s[:, None] + np.einsum("kji,kj->ki", C_i_m, residuals @ A.T)
