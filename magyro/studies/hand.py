"""The hand's translation of a simulated session and what the accelerometer reads (see magyro.studies.simulate).

The device's position p^w(t) is, on each world axis, the rotation's window times a few sinusoids in the motion's
band, drawn from ``default_rng([motion.seed, TRANSLATION_STREAM, seed])``; its acceleration is analytic. With
``[accelerometer] hand_while_turning`` (a "turns" motion), the window is 1 while the device turns and 0 over the
poses held between the turns, ramped in and out inside each run of turns (`turning_spans`): a person's hand that
holds a pose still, as the static-pose method assumes (issue 39).
"""
from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

import numpy as np

from magyro import so3
from magyro.studies.motion import inertial_from_world, smoothstep, truth_body_attitude, turn_steps
from magyro.studies.scenario import Scenario

TRANSLATION_STREAM = 3          # the hand's translation: default_rng([motion.seed, 3, seed]) (fleet devices use [seed, 1])
TRANSLATION_PEAK_GRID = 50      # the peak of the position is taken on this many points per period of the band's top


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
    spans_s: tuple = ()          # with hand_while_turning: (start, stop, ramp) of each run of turns, the window's


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


TURNING_RAMP_S = 1.0   # hand_while_turning: the window ramps in (and out) over this much of each run of turns at most


def turning_spans(problem: Scenario) -> tuple:
    """((start, stop, ramp), ...) of every run of back-to-back turns of a "turns" motion: the hand moves the device
    there only (hand_while_turning), ramping in over its first and out over its last TURNING_RAMP_S (at most half
    the run: a hand that starts and stops with the turn), so the window is C^2 and 0 over every held pose."""
    st = turn_steps(problem)
    turning = st.angle_rad != 0.0
    edges = np.flatnonzero(np.diff(np.concatenate([[0], turning.astype(np.int8), [0]])))
    spans = []
    for a, b in zip(edges[::2], edges[1::2]):
        start, stop = float(st.start_s[a]), float(st.start_s[b - 1] + st.seconds[b - 1])
        spans.append((start, stop, min(TURNING_RAMP_S, 0.5 * (stop - start))))
    return tuple(spans)


def translation_window(tr: Translation, t: np.ndarray):
    """The translation's window and its first and second time derivatives: the rotation's, or with `spans_s` the
    sum of each run of turns' own (the runs do not overlap)."""
    if not tr.spans_s:
        return window_derivatives(t, tr.start_s, tr.stop_s, tr.ramp_s)
    w, wdot, wddot = np.zeros(len(t)), np.zeros(len(t)), np.zeros(len(t))
    for start, stop, ramp in tr.spans_s:
        inside = (t >= start) & (t <= stop)
        parts = window_derivatives(t[inside], start, stop, ramp)
        w[inside], wdot[inside], wddot[inside] = parts
    return w, wdot, wddot


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
    spans = turning_spans(problem) if acc.hand_while_turning and m.kind == "turns" else ()
    unit = Translation(weights, freqs, phases, start, stop, ramp, spans)
    lo, hi = (start, stop) if ramp > 0 else (0.0, problem.duration_s)
    grid = np.linspace(lo, hi, int(math.ceil((hi - lo) * m.band_hz[1] * TRANSLATION_PEAK_GRID)) + 2)
    peak = np.max(np.abs(translation_derivatives(unit, grid)[0]), axis=0)
    scale = acc.hand_translation_m / np.where(peak > 0.0, peak, 1.0)
    return dataclasses.replace(unit, amplitudes_m=weights * scale[:, None])


def translation_derivatives(tr: Translation, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(position p^w (N, 3) in m, acceleration p''^w (N, 3) in m/s^2) at the times t, analytic."""
    p, a = np.empty((len(t), 3)), np.empty((len(t), 3))
    if tr.ramp_s > 0:
        w, wdot, wddot = translation_window(tr, t)
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


def acc_clean(problem: Scenario, t_s: np.ndarray, hand_seed: int | None = None) -> np.ndarray:
    """Noise-free y_a = K_a^-1 (C_b^a f^b - eps_a), m/s^2 (N, 3)."""
    acc = problem.accelerometer
    f_a = truth_specific_force_b(problem, t_s, hand_seed) @ acc.C_b_a.T
    return np.linalg.solve(acc.K_a, (f_a - acc.bias_m_s2).T).T


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
