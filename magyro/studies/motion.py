"""The truth's motion of a simulated session: the body's attitude and rate, analytic (see magyro.studies.simulate).

Frames: w = ENU world, b = gyro, m = magnetometer, i = the magnetometer frame at t = 0.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from magyro import so3
from magyro.studies.scenario import AXES, Scenario


# --------------------------------------------------------------------------- motion


@dataclass(frozen=True, eq=False)
class Factor:
    """One elementary rotation Exp(a(t) u): a(t) = window(t) * sum_k A_k sin(2 pi f_k t + phi_k)."""

    axis: np.ndarray            # (3,) unit, body frame
    amplitudes_rad: np.ndarray  # (K,)
    freqs_hz: np.ndarray        # (K,)
    phases_rad: np.ndarray      # (K,)
    start_s: float              # window is 0 before start_s and after stop_s
    stop_s: float
    ramp_s: float


def motion_factors(problem: Scenario) -> list[Factor]:
    """The rotation factors of the problem's motion, drawn from motion.seed (not the noise seed)."""
    m = problem.motion
    if m.kind == "static":
        return []
    if m.kind == "turns":
        raise ValueError("a \"turns\" motion has no factors: see turn_steps")
    rng = np.random.default_rng(m.seed)
    t0, t1 = m.rest_start_s, problem.duration_s - m.rest_end_s
    n = len(m.axes)
    if m.kind == "sequential":
        edges = np.linspace(t0, t1, n + 1)
        slots = [(float(edges[j]), float(edges[j + 1])) for j in range(n)]
    else:  # euler: all factors at once
        slots = [(t0, t1)] * n
    factors = []
    for axis, amp_deg, (start, stop) in zip(m.axes, m.amplitude_deg, slots):
        freqs = rng.uniform(m.band_hz[0], m.band_hz[1], m.components)
        phases = rng.uniform(0.0, 2.0 * np.pi, m.components)
        weights = rng.uniform(0.5, 1.0, m.components)
        amps = math.radians(amp_deg) * weights / weights.sum()
        factors.append(Factor(AXES[axis], amps, freqs, phases, start, stop, m.ramp_s))
    return factors


def smoothstep(x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Quintic ramp s(x) = 10x^3 - 15x^4 + 6x^5 on [0, 1] (clamped outside) and ds/dx; C^2."""
    x = np.clip(x, 0.0, 1.0)
    return x**3 * (10.0 - 15.0 * x + 6.0 * x**2), 30.0 * x**2 * (1.0 - x) ** 2


def window(t: np.ndarray, start: float, stop: float, ramp: float) -> tuple[np.ndarray, np.ndarray]:
    """0 outside [start, stop], ramping up/down over `ramp` seconds, 1 in between; and d/dt."""
    up, dup = smoothstep((t - start) / ramp)
    down, ddown = smoothstep((stop - t) / ramp)
    return up * down, (dup * down - up * ddown) / ramp


def multisine(t: np.ndarray, amps: np.ndarray, freqs: np.ndarray, phases: np.ndarray):
    """sum_k A_k sin(2 pi f_k t + phi_k) and its time derivative, for t of shape (N,)."""
    arg = 2.0 * np.pi * np.outer(t, freqs) + phases
    return np.sin(arg) @ amps, np.cos(arg) @ (2.0 * np.pi * freqs * amps)


def factor_angles(factor: Factor, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """a(t) and adot(t), exactly zero outside the factor's window; with no ramp (ramp_s 0) no window, the angle
    taken relative to its value at t = 0 (the motion starts at C0, already turning)."""
    s, sdot = multisine(t, factor.amplitudes_rad, factor.freqs_hz, factor.phases_rad)
    if factor.ramp_s == 0:
        return s - multisine(np.zeros(1), factor.amplitudes_rad, factor.freqs_hz, factor.phases_rad)[0], sdot
    w, wdot = window(t, factor.start_s, factor.stop_s, factor.ramp_s)
    return w * s, wdot * s + w * sdot


def _factor_rotations(factors: list[Factor], t: np.ndarray):
    """Per factor: (Exp(a_j u_j) stack (N,3,3), adot_j u_j (N,3))."""
    out = []
    for f in factors:
        a, adot = factor_angles(f, t)
        out.append((so3.exp_so3(a[:, None] * f.axis), adot[:, None] * f.axis))
    return out


@dataclass(frozen=True, eq=False)
class TurnSteps:
    """A "turns" motion laid out in time: step j runs from start_s[j] for seconds[j], turning by angle_rad[j]
    about axis[j] (a rest: angle 0), and before[j] is the product of the steps before it (identity for j = 0)."""

    start_s: np.ndarray      # (n,)
    seconds: np.ndarray      # (n,)
    axis: np.ndarray         # (n, 3) unit (rests: zero)
    angle_rad: np.ndarray    # (n,)
    before: np.ndarray       # (n, 3, 3)


def turn_steps(problem: Scenario) -> TurnSteps:
    """The layout of the problem's "turns" motion: the steps back to back from t = 0."""
    steps = problem.motion.turns
    seconds = np.array([st.seconds for st in steps], dtype=float)
    start = np.concatenate([[0.0], np.cumsum(seconds)[:-1]])
    axis = np.array([np.zeros(3) if st.is_rest else np.asarray(st.axis, float) for st in steps])
    angle = np.array([math.radians(st.angle_deg) for st in steps])
    step_rotation = so3.exp_so3(angle[:, None] * axis)      # all steps at once: one call, not one a step
    before = np.empty((len(steps), 3, 3))
    P = np.eye(3)
    for j in range(len(steps)):
        before[j] = P
        P = P @ step_rotation[j]
    return TurnSteps(start, seconds, axis, angle, before)


def _turn_angles(problem: Scenario, t: np.ndarray):
    """Per time: the step index, its angle a(t) and rate adot(t) (clamped: 0 before, the full angle after)."""
    st = turn_steps(problem)
    j = np.clip(np.searchsorted(st.start_s, t, side="right") - 1, 0, len(st.start_s) - 1)
    s, ds = smoothstep((t - st.start_s[j]) / st.seconds[j])
    return st, j, st.angle_rad[j] * s, st.angle_rad[j] * ds / st.seconds[j]


def turns_body_attitude(problem: Scenario, t: np.ndarray) -> np.ndarray:
    """C_b^w(t) of a "turns" motion: C0, the completed turns, the current partial one."""
    st, j, a, _ = _turn_angles(problem, t)
    return problem.C0 @ st.before[j] @ so3.exp_so3(a[:, None] * st.axis[j])


def turns_body_rate(problem: Scenario, t: np.ndarray) -> np.ndarray:
    """w^b(t) of a "turns" motion: adot(t) u of the current step (0 in rests, before and after)."""
    st, j, _, adot = _turn_angles(problem, t)
    return adot[:, None] * st.axis[j]


def truth_body_attitude(problem: Scenario, t_s) -> np.ndarray:
    """C_b^w(t) = C0 prod_j Exp(a_j(t) u_j), shape (N, 3, 3)."""
    t = np.atleast_1d(np.asarray(t_s, dtype=float))
    if problem.motion.kind == "turns":
        return turns_body_attitude(problem, t)
    C = np.broadcast_to(problem.C0, (len(t), 3, 3)).copy()
    for E, _ in _factor_rotations(motion_factors(problem), t):
        C = C @ E
    return C


def truth_body_rate(problem: Scenario, t_s) -> np.ndarray:
    """w_ib^b(t) in rad/s, gyro frame, (N, 3): sum_j (prod_{l>j} Exp(a_l u_l))^T adot_j u_j."""
    t = np.atleast_1d(np.asarray(t_s, dtype=float))
    if problem.motion.kind == "turns":
        return turns_body_rate(problem, t)
    w = np.zeros((len(t), 3))
    P = np.broadcast_to(np.eye(3), (len(t), 3, 3))
    for E, rate in reversed(_factor_rotations(motion_factors(problem), t)):
        w = w + np.einsum("nji,nj->ni", P, rate)
        P = E @ P
    return w


def inertial_from_world(problem: Scenario) -> np.ndarray:
    """C_w^i = C_m^w(0)^T = C_b^m C_b^w(0)^T."""
    return problem.C_b_m @ truth_body_attitude(problem, [0.0])[0].T


def field_i(problem: Scenario) -> np.ndarray:
    """m^i, the unit field in the inertial frame."""
    mw = problem.field_w
    return inertial_from_world(problem) @ (mw / np.linalg.norm(mw))


def truth_attitude(problem: Scenario, t_s) -> np.ndarray:
    """C_m^i(t) = C_w^i C_b^w(t) C_m^b, (N, 3, 3); identity at t = 0."""
    C_b_w = truth_body_attitude(problem, t_s)
    return inertial_from_world(problem) @ C_b_w @ problem.C_b_m.T


def truth_rate_m(problem: Scenario, t_s) -> np.ndarray:
    """w^m = C_b^m w^b, rad/s (N, 3), so that dC_m^i/dt = C_m^i (w^m x)."""
    return truth_body_rate(problem, t_s) @ problem.C_b_m.T
