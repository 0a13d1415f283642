"""Simulated sessions with an analytic truth (docs/spec.md section 1 model).

`simulate(problem, seed)` turns a `Scenario` (`magyro.studies.scenario`) into a
`Session` plus a truth dict laid out like the calibration JSON.

Truth is analytic. The body (gyro frame) attitude is a product of elementary
rotations about fixed body axes,

    C_b^w(t) = C0 Exp(a_1(t) u_1) Exp(a_2(t) u_2) ... Exp(a_n(t) u_n),

with each angle a_j(t) = window_j(t) * sum_k A_k sin(2 pi f_k t + phi_k) (with ramp_s 0, no
window: the multisine minus its value at t = 0, so the body starts at C0 already turning, as the
paper's motion does; `magyro plan` compares with it), so the body rate is exact:

    w^b(t) = sum_j (prod_{l>j} Exp(a_l u_l))^T adot_j u_j.

A "turns" motion (a list of turns and rests, `scenario.Turn`) is instead

    C_b^w(t) = C0 Exp(theta_1 u_1) ... Exp(theta_{k-1} u_{k-1}) Exp(a_k(t) u_k)

during step k (the completed turns, then the current partial one; a rest is the
identity), with a_k(t) = theta_k s((t - start_k) / T_k), s the quintic smoothstep
(the minimum-jerk profile of a hand movement: rate and acceleration continuous, zero
at both ends of the turn), so w^b(t) = theta_k s'((t - start_k) / T_k) / T_k u_k.

Frames: w = ENU world, b = gyro, m = magnetometer (equivalent) frame, i = the
magnetometer frame at t = 0. C_m^w = C_b^w C_m^b, C_w^i = C_m^w(0)^T.

Sensors:

    gyro   y_g = K_g^-1 (w^b - eps_b) + n_g,  std(n_g) = density * sqrt(rate)
    mag    y_m = field_strength * T C_w^m (m^w / |m^w|) + h + n_m
               = R^-1 C_i^m m^i + h + n_m,  R = inv(field_strength * T)

    acc    y_a = K_a^-1 (C_b^a C_w^b (a^w - g_vec) - eps_a) + n_a,  g_vec = (0, 0, -g),
                                                    std(n_a) = density * sqrt(rate)

The magnetometer sample stamped t measures the field at t - time_offset_s;
gyro samples are stamped at their true time. The motion is drawn from
``motion.seed`` (fixed in the problem), the noise from ``seed``, so every noise
seed sees the same motion.

The accelerometer (a problem's optional ``[accelerometer]``, issue 26) is sampled at the
gyro's times. The device's position p^w(t) (the accelerometer's) is, on each world axis,
window(t) * sum_k B_k sin(2 pi f_k t + phi_k): the rotation's window (zero in the rests at both
ends, C^2, so the acceleration is continuous) and the rotation's band and number of sinusoids,
drawn from ``default_rng([motion.seed, TRANSLATION_STREAM, seed])`` (another sway for every noise seed:
to the calibration the hand is noise; the rotation's draw untouched), scaled so each axis's peak is ``hand_translation_m``. Its acceleration
a^w = p'' = window'' s + 2 window' s' + window s'' is analytic. The accelerometer's noise is drawn
after the gyro's and the magnetometer's, so a problem without the section samples as before.
"""
from __future__ import annotations

import dataclasses
import json
import math
import os
from dataclasses import dataclass

import numpy as np

from magyro import so3
from magyro.session import Session
from magyro.studies.scenario import AXES, Scenario

TRUTH_SCHEMA = "magyro.truth/1"
TRANSLATION_STREAM = 3          # the hand's translation: default_rng([motion.seed, 3, seed]) (fleet devices use [seed, 1])
TRANSLATION_PEAK_GRID = 50      # the peak of the position is taken on this many points per period of the band's top


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


# --------------------------------------------------------------------------- the hand's translation


def smoothstep_curvature(x: np.ndarray) -> np.ndarray:
    """d^2 s/dx^2 of `smoothstep` on [0, 1] (0 outside): 60x - 180x^2 + 120x^3, zero at both ends."""
    x = np.clip(x, 0.0, 1.0)
    return 60.0 * x * (1.0 - x) * (1.0 - 2.0 * x)


def window_derivatives(t: np.ndarray, start: float, stop: float, ramp: float):
    """`window` and its first and second time derivatives (continuous: the smoothstep is C^2)."""
    up, dup = smoothstep((t - start) / ramp)
    down, ddown = smoothstep((stop - t) / ramp)
    d2up, d2down = smoothstep_curvature((t - start) / ramp), smoothstep_curvature((stop - t) / ramp)
    return (up * down, (dup * down - up * ddown) / ramp,
            (d2up * down - 2.0 * dup * ddown + up * d2down) / ramp ** 2)


@dataclass(frozen=True, eq=False)
class Translation:
    """The device's position on the world axes: p_i(t) = window(t) sum_k B_ik sin(2 pi f_ik t + phi_ik) (with
    ramp_s 0, no window: the multisine minus its value at t = 0)."""

    amplitudes_m: np.ndarray     # (3, K)
    freqs_hz: np.ndarray         # (3, K)
    phases_rad: np.ndarray       # (3, K)
    start_s: float
    stop_s: float
    ramp_s: float


def translation_span(problem: Scenario) -> tuple[float, float, float]:
    """(start, stop, ramp) of the translation's window: the rotation's (the motion between the rests, its ramp); for
    a "turns" motion from the first turn's start to the last turn's end, ramping over at most half of that."""
    m = problem.motion
    if m.kind != "turns":
        return m.rest_start_s, problem.duration_s - m.rest_end_s, m.ramp_s
    st = turn_steps(problem)
    turning = np.flatnonzero(st.angle_rad != 0.0)
    start, stop = float(st.start_s[turning[0]]), float(st.start_s[turning[-1]] + st.seconds[turning[-1]])
    return start, stop, min(m.ramp_s, 0.5 * (stop - start))


def hand_translation(problem: Scenario, hand_seed: int | None = None) -> Translation | None:
    """The problem's translation, drawn from motion.seed and the noise seed `hand_seed` (a simulated session's
    `seed`): to the calibration the hand's sway is noise, so every noise seed sees another sway of the same size in
    the same band, about the same turning; None when the device does not move (no accelerometer,
    hand_translation_m 0 or a static motion)."""
    acc, m = problem.accelerometer, problem.motion
    if acc is None or acc.hand_translation_m == 0.0 or m.kind == "static":
        return None
    rng = np.random.default_rng([m.seed, TRANSLATION_STREAM] + ([] if hand_seed is None else [hand_seed]))
    freqs, phases, weights = (np.empty((3, m.components)) for _ in range(3))
    for i in range(3):
        freqs[i] = rng.uniform(m.band_hz[0], m.band_hz[1], m.components)
        phases[i] = rng.uniform(0.0, 2.0 * np.pi, m.components)
        weights[i] = rng.uniform(0.5, 1.0, m.components)
    start, stop, ramp = translation_span(problem)
    unit = Translation(weights, freqs, phases, start, stop, ramp)
    lo, hi = (start, stop) if ramp > 0 else (0.0, problem.duration_s)
    grid = np.linspace(lo, hi, int(math.ceil((hi - lo) * m.band_hz[1] * TRANSLATION_PEAK_GRID)) + 2)
    peak = np.max(np.abs(translation_derivatives(unit, grid)[0]), axis=0)
    scale = acc.hand_translation_m / np.where(peak > 0.0, peak, 1.0)
    return dataclasses.replace(unit, amplitudes_m=weights * scale[:, None])


def translation_derivatives(tr: Translation, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(position p^w (N, 3) in m, acceleration p''^w (N, 3) in m/s^2) at the times t, analytic."""
    p, a = np.empty((len(t), 3)), np.empty((len(t), 3))
    if tr.ramp_s > 0:
        w, wdot, wddot = window_derivatives(t, tr.start_s, tr.stop_s, tr.ramp_s)
    for i in range(3):
        omega = 2.0 * np.pi * tr.freqs_hz[i]
        arg = np.outer(t, omega) + tr.phases_rad[i]
        sin_, cos_ = np.sin(arg), np.cos(arg)
        s, sdot, sddot = sin_ @ tr.amplitudes_m[i], cos_ @ (omega * tr.amplitudes_m[i]), \
            -(sin_ @ (omega ** 2 * tr.amplitudes_m[i]))
        if tr.ramp_s > 0:
            p[:, i], a[:, i] = w * s, wddot * s + 2.0 * wdot * sdot + w * sddot
        else:
            p[:, i], a[:, i] = s - np.sin(tr.phases_rad[i]) @ tr.amplitudes_m[i], sddot
    return p, a


def truth_position(problem: Scenario, t_s, hand_seed: int | None = None) -> np.ndarray:
    """p^w(t), the device's (the accelerometer's) position in the world frame relative to where it rests, m (N, 3)."""
    t = np.atleast_1d(np.asarray(t_s, dtype=float))
    tr = hand_translation(problem, hand_seed)
    return np.zeros((len(t), 3)) if tr is None else translation_derivatives(tr, t)[0]


def truth_acceleration(problem: Scenario, t_s, hand_seed: int | None = None) -> np.ndarray:
    """a^w(t) = p''(t), m/s^2 (N, 3), analytic (the window's derivatives included)."""
    t = np.atleast_1d(np.asarray(t_s, dtype=float))
    tr = hand_translation(problem, hand_seed)
    return np.zeros((len(t), 3)) if tr is None else translation_derivatives(tr, t)[1]


def gravity_w(problem: Scenario) -> np.ndarray:
    """g_vec in ENU: (0, 0, -g), g the problem's [accelerometer] g_m_s2."""
    return np.array([0.0, 0.0, -problem.accelerometer.g_m_s2])


def truth_specific_force_b(problem: Scenario, t_s, hand_seed: int | None = None) -> np.ndarray:
    """f^b = C_w^b (a^w - g_vec), m/s^2 (N, 3), in the gyro frame."""
    f_w = truth_acceleration(problem, t_s, hand_seed) - gravity_w(problem)
    return np.einsum("nji,nj->ni", truth_body_attitude(problem, t_s), f_w)


def gravity_up_i(problem: Scenario) -> np.ndarray:
    """The 'up' direction (0, 0, 1)^w, the unit specific force at rest, in the frame i: C_w^i (0, 0, 1)."""
    return inertial_from_world(problem)[:, 2].copy()


# --------------------------------------------------------------------------- sensors


def sample_times(rate_hz: float, duration_s: float) -> np.ndarray:
    """t = k / rate for k = 0, 1, ... while t <= duration."""
    n = int(math.floor(duration_s * rate_hz + 1e-9)) + 1
    return np.arange(n) / rate_hz


def gyro_clean(problem: Scenario, t_s: np.ndarray) -> np.ndarray:
    """Noise-free y_g = K_g^-1 (w^b - eps_b), rad/s (N, 3)."""
    w = truth_body_rate(problem, t_s)
    return np.linalg.solve(problem.K_g, (w - problem.gyro_bias_rad_s).T).T


def mag_clean(problem: Scenario, t_stamp_s: np.ndarray) -> np.ndarray:
    """Noise-free y_m = R^-1 C_i^m m^i + h at the stamps (field taken at stamp - time_offset)."""
    return mag_from_attitude(problem, truth_attitude(problem, t_stamp_s - problem.mag_time_offset_s))


def mag_from_attitude(problem: Scenario, C_m_i: np.ndarray) -> np.ndarray:
    """Noise-free y_m = R^-1 C_i^m m^i + h at the attitudes C_m^i (N, 3, 3). C_m^i does not depend on the start
    pose C0 (it is relative to t = 0), m^i does: one attitude serves every start pose (crlb.cramer_rao_at_poses)."""
    m_m = np.einsum("nji,j->ni", C_m_i, field_i(problem))  # C_i^m m^i
    return m_m @ np.linalg.inv(problem.R).T + problem.hard_iron


def acc_clean(problem: Scenario, t_s: np.ndarray, hand_seed: int | None = None) -> np.ndarray:
    """Noise-free y_a = K_a^-1 (C_b^a f^b - eps_a), m/s^2 (N, 3)."""
    acc = problem.accelerometer
    f_a = truth_specific_force_b(problem, t_s, hand_seed) @ acc.C_b_a.T
    return np.linalg.solve(acc.K_a, (f_a - acc.bias_m_s2).T).T


def simulate(problem: Scenario, seed: int, noise_scale: float = 1.0) -> tuple[Session, dict]:
    """A session and its truth. `noise_scale` multiplies every noise level (0 for noise-free)."""
    rng = np.random.default_rng(seed)
    t_g = sample_times(problem.gyro_rate_hz, problem.duration_s)
    t_m = sample_times(problem.mag_rate_hz, problem.duration_s)
    gyro = gyro_clean(problem, t_g)
    mag = mag_clean(problem, t_m)
    gyro = gyro + noise_scale * problem.gyro_sample_std_rad_s * rng.standard_normal(gyro.shape)
    mag = mag + noise_scale * problem.mag_noise_std * rng.standard_normal(mag.shape)
    metadata = {"problem": problem.name, "seed": seed, "gyro_unit": "rad/s", "mag_unit": problem.mag_unit}
    accelerometer = {}
    if problem.accelerometer is not None:   # drawn last: the gyro's and magnetometer's noise are as without it
        acc = acc_clean(problem, t_g, seed)
        acc = acc + noise_scale * problem.accelerometer.sample_std_m_s2(problem.gyro_rate_hz) * \
            rng.standard_normal(acc.shape)
        accelerometer = {"t_acc_s": t_g.copy(), "acc_m_s2": acc}
        metadata["acc_unit"] = "m/s^2"
    session = Session(
        t_gyro_s=t_g,
        gyro_rad_s=gyro,
        t_mag_s=t_m,
        mag=mag,
        mag_unit=problem.mag_unit,
        source=f"simulated:{problem.name}:seed={seed}",
        metadata=metadata,
        **accelerometer,
    )
    return session, truth_dict(problem, seed, noise_scale)


def truth_dict(problem: Scenario, seed: int, noise_scale: float = 1.0) -> dict:
    """The true parameters, laid out like the calibration JSON (plain lists)."""
    return {
        "schema": TRUTH_SCHEMA,
        "problem": problem.name,
        "seed": seed,
        "gyro": {
            "K_g": problem.K_g.tolist(),
            "bias_rad_s": problem.gyro_bias_rad_s.tolist(),
            "bias_deg_s": problem.gyro_bias_deg_s.tolist(),
            "K": problem.K.tolist(),
            "eps_rad_s": problem.eps_m_rad_s.tolist(),
        },
        "misalignment": {
            "C_b_m": problem.C_b_m.tolist(),
            "euler_deg": so3.dcm_to_euler(problem.C_b_m).tolist(),
        },
        "magnetometer": {
            "R": problem.R.tolist(),
            "h": problem.hard_iron.tolist(),
            "unit": problem.mag_unit,
        },
        "field_i": field_i(problem).tolist(),
        "time_offset_s": problem.mag_time_offset_s,
        "noise": {
            "gyro_density_rad_s_sqrt_hz": noise_scale * problem.gyro_noise_density_rad_s_sqrt_hz,
            "gyro_sample_std_rad_s": noise_scale * problem.gyro_sample_std_rad_s,
            "mag_std": noise_scale * problem.mag_noise_std,
        },
        "motion": {"kind": problem.motion.kind, "seed": problem.motion.seed},
    } | ({} if problem.accelerometer is None else accelerometer_truth(problem, noise_scale))


def accelerometer_truth(problem: Scenario, noise_scale: float = 1.0) -> dict:
    """The truth's "accelerometer" block (and its noise), for a problem with an [accelerometer]."""
    acc = problem.accelerometer
    return {"accelerometer": {
        "K_a": acc.K_a.tolist(),
        "bias_m_s2": acc.bias_m_s2.tolist(),
        "C_b_a": acc.C_b_a.tolist(),
        "euler_deg": so3.dcm_to_euler(acc.C_b_a).tolist(),
        "g_m_s2": acc.g_m_s2,
        "gravity_up_i": gravity_up_i(problem).tolist(),
        "hand_translation_m": acc.hand_translation_m,
        "noise_density_ug_sqrt_hz": noise_scale * acc.noise_density_ug_sqrt_hz,
        "sample_std_m_s2": noise_scale * acc.sample_std_m_s2(problem.gyro_rate_hz),
    }}


def write_truth(truth: dict, path: str | os.PathLike) -> None:
    """Write the truth JSON atomically (whole or not at all)."""
    from magyro.io.atomic import write_text_atomically

    write_text_atomically(path, json.dumps(truth, indent=2) + "\n")


def with_field_disturbance(session: Session, problem: Scenario, std_fraction: float, correlation_s: float,
                           seed: int) -> Session:
    """The session in a field that is not homogeneous: m^i + delta(t), delta an isotropic Gauss-Markov process
    in the frame i (std `std_fraction` of the field per axis, correlation time `correlation_s`), as a room's
    iron makes it along a hand-held path. Only the magnetometer changes; the truth stays that of the problem."""
    rng = np.random.default_rng([seed, 7])
    t = session.t_mag_s
    decay = np.exp(-np.diff(t) / correlation_s)
    kicks = rng.standard_normal((len(t), 3))
    delta = np.empty((len(t), 3))
    delta[0] = std_fraction * kicks[0]
    for k in range(1, len(t)):
        delta[k] = decay[k - 1] * delta[k - 1] + std_fraction * np.sqrt(1.0 - decay[k - 1] ** 2) * kicks[k]
    C_m_i = truth_attitude(problem, t - problem.mag_time_offset_s)
    extra = np.einsum("nji,nj->ni", C_m_i, delta) @ np.linalg.inv(problem.R).T
    return dataclasses.replace(session, mag=session.mag + extra,
                               source=f"{session.source}:field_disturbance={std_fraction},{correlation_s}s")
