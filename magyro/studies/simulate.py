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

import numpy as np

from magyro import so3
from magyro.session import Session
from magyro.studies.scenario import Scenario

from magyro.studies.hand import acc_clean, accelerometer_truth
from magyro.studies.motion import (field_i, motion_factors, truth_attitude, truth_body_attitude,  # noqa: F401
                                   truth_body_rate, truth_rate_m)   # the truth's motion, importable from here too

TRUTH_SCHEMA = "magyro.truth/1"


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


def write_truth(truth: dict, path: str | os.PathLike) -> None:
    """Write the truth JSON atomically (whole or not at all)."""
    from magyro.io.atomic import write_text_atomically

    write_text_atomically(path, json.dumps(truth, indent=2) + "\n")


def gauss_markov(t_s: np.ndarray, std: float, correlation_s: float, rng: np.random.Generator) -> np.ndarray:
    """(N, 3) an isotropic first-order Gauss-Markov process at the times t_s: stationary std `std` per axis,
    correlation time `correlation_s`, started in its stationary distribution."""
    decay = np.exp(-np.diff(t_s) / correlation_s)
    kicks = rng.standard_normal((len(t_s), 3))
    delta = np.empty((len(t_s), 3))
    delta[0] = std * kicks[0]
    for k in range(1, len(t_s)):
        delta[k] = decay[k - 1] * delta[k - 1] + std * np.sqrt(1.0 - decay[k - 1] ** 2) * kicks[k]
    return delta


def with_field_disturbance(session: Session, problem: Scenario, std_fraction: float, correlation_s: float,
                           seed: int) -> Session:
    """The session in a field that is not homogeneous: m^i + delta(t), delta an isotropic Gauss-Markov process
    in the frame i (std `std_fraction` of the field per axis, correlation time `correlation_s`), as a room's
    iron makes it along a hand-held path. Only the magnetometer changes; the truth stays that of the problem."""
    t = session.t_mag_s
    delta = gauss_markov(t, std_fraction, correlation_s, np.random.default_rng([seed, 7]))
    C_m_i = truth_attitude(problem, t - problem.mag_time_offset_s)
    extra = np.einsum("nji,nj->ni", C_m_i, delta) @ np.linalg.inv(problem.R).T
    return dataclasses.replace(session, mag=session.mag + extra,
                               source=f"{session.source}:field_disturbance={std_fraction},{correlation_s}s")
