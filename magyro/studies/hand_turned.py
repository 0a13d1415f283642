"""Phones and small boards turned fast by hand at a low, changing sample rate: sessions with an exact truth.

The recordings this mirrors (issue 38: iPhone 11s logged by Sensor Logger, a VN-100 at 40 Hz) have no rest, a gyro
at 40 Hz then 25 Hz, a magnetometer on its own clock, a hand that turns at 80 rising to 330 deg/s RMS and keeps
rolling the device over, a room whose field wanders by ~2 %, and gyro samples taken a few ms off their stamps.
`magyro.studies.simulate` draws smooth multisines about body axes at one rate; this draws the motion as the
product of a world-frame tumble T(t) (piecewise-constant world rates, a new random axis every `tumble_segment_s`)
and a hand wobble H(t) (band-limited body rates whose RMS follows `rms_profile`):

    C_b^w(t) = T(t) H(t),   w^b(t) = w_hand^b(t) + C_b^w(t)^T w_tumble^w(t)

both exact on a fine grid (`FINE_RATE_HZ`), the sensors sampled from it:

    gyro   y_g = K_g^-1 (w^b(t_k + j_k) - eps_b) + n_g,  j_k ~ N(0, sample_jitter_ms): taken off its stamp t_k
    mag    y_m = R^-1 C_w^m (m^w + d(t)) + h + n_m,      at stamp - lag; d an isotropic Gauss-Markov wander

Frames as in `magyro.studies.simulate` (C_m^w = C_b^w C_b_m^T). Every draw comes from the seed; the truth dict
carries the parameters as the replicas' truth files do (`K_g`, `bias_deg_s`, `C_b_m`, `R`, `h`).
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from magyro import so3
from magyro.session import Session
from magyro.studies.simulate import gauss_markov

FINE_RATE_HZ = 2000.0


@dataclass(frozen=True)
class HandTurned:
    """One kind of recording; the seed draws the rest (motion, parameters, noise)."""

    duration_s: float = 162.0
    gyro_schedule: tuple = ((0.0, 40.0), (32.8, 25.0))   # (from s, rate Hz): the phone's rate changes mid-recording
    mag_rate_hz: float = 24.92
    mag_lag_s: float = 0.0127
    rms_profile: tuple = ((0.0, 81.0), (20.0, 105.0), (40.0, 215.0), (80.0, 329.0), (120.0, 337.0))  # (s, deg/s)
    band_hz: tuple = (0.15, 1.5)
    components: int = 6
    tumble_deg_s: tuple = (61.0, 81.0, 105.0, 71.0, 109.0, 109.0, 38.0, 24.0, 24.0)
    tumble_segment_s: float = 20.0
    sample_jitter_ms: float = 2.3
    gyro_noise_deg_s_sqrt_hz: float = 0.01
    mag_noise_uT: float = 0.25
    field_uT: float = 43.0
    dip_deg: float = 60.0
    field_wander: float = 0.021
    field_correlation_s: float = 3.8
    parameters: dict = field(default_factory=dict)   # fixed parameters instead of drawn ones (K_g, bias_deg_s, ...)


def drawn_parameters(rng: np.random.Generator, kind: HandTurned) -> dict:
    """A phone's errors: scale within 0.5 %, non-orthogonality within 0.3 %, bias within 0.6 deg/s, misalignment
    within 2 deg, hard iron within 400 uT, soft iron within 3 % of the field."""
    K_g = np.eye(3) + np.diag(rng.uniform(-0.005, 0.005, 3))
    K_g[np.triu_indices(3, 1)] = rng.uniform(-0.003, 0.003, 3)
    drawn = {"K_g": K_g, "bias_deg_s": rng.uniform(-0.6, 0.6, 3), "misalign_euler_deg": rng.uniform(-2.0, 2.0, 3),
             "h": rng.uniform(-400.0, 400.0, 3), "soft": np.eye(3) + np.diag(rng.uniform(-0.03, 0.03, 3))}
    return {**drawn, **{k: np.asarray(v, dtype=float) for k, v in kind.parameters.items()}}


def gyro_stamps(kind: HandTurned) -> np.ndarray:
    """The gyro's stamps: each stretch of the schedule at its own rate."""
    edges = [start for start, _ in kind.gyro_schedule[1:]] + [kind.duration_s]
    parts = [start + np.arange(0.0, end - start - 1e-9, 1.0 / rate)
             for (start, rate), end in zip(kind.gyro_schedule, edges)]
    return np.concatenate(parts)


def band_process(rng: np.random.Generator, t_s: np.ndarray, kind: HandTurned) -> np.ndarray:
    """A 3-vector of sinusoids in the band, unit RMS magnitude, then scaled to the RMS profile (rad/s)."""
    f = rng.uniform(*kind.band_hz, (3, kind.components))
    phase = rng.uniform(0.0, 2 * np.pi, (3, kind.components))
    amplitude = rng.uniform(0.5, 1.0, (3, kind.components))
    x = np.einsum("ak,akn->na", amplitude, np.sin(2 * np.pi * f[..., None] * t_s + phase[..., None]))
    x /= np.sqrt(np.mean(np.sum(x**2, axis=1)))
    times, rms = np.asarray(kind.rms_profile, dtype=float).T
    return x * np.deg2rad(np.interp(t_s, times, rms))[:, None]


def tumble_rates(rng: np.random.Generator, t_s: np.ndarray, kind: HandTurned) -> np.ndarray:
    """World-frame rates (rad/s): a random axis and the listed speed a segment, blended over a second."""
    n = int(np.ceil(kind.duration_s / kind.tumble_segment_s)) + 1
    axes = rng.standard_normal((n, 3))
    axes /= np.linalg.norm(axes, axis=1)[:, None]
    speeds = np.deg2rad(np.resize(np.asarray(kind.tumble_deg_s, dtype=float), n))
    segment = np.minimum((t_s / kind.tumble_segment_s).astype(int), n - 1)
    raw = axes[segment] * speeds[segment][:, None]
    width = int(FINE_RATE_HZ)   # a second's moving average: the hand changes its roll smoothly
    kernel = np.ones(width) / width
    return np.stack([np.convolve(np.pad(raw[:, a], (width // 2, width - 1 - width // 2), mode="edge"), kernel,
                                 mode="valid") for a in range(3)], axis=1)


def body_attitude_and_rate(rng: np.random.Generator, t_s: np.ndarray, kind: HandTurned):
    """(C_b^w, w^b) on the fine grid t_s: C = T H, T the world tumble, H the hand wobble."""
    dt = np.diff(t_s)[:, None]
    w_hand = band_process(rng, t_s, kind)
    w_world = tumble_rates(rng, t_s, kind)
    H = so3.quat_to_dcm(so3.cumulative_quat_product(np.concatenate(
        [[[1.0, 0.0, 0.0, 0.0]], so3.exp_quat(0.5 * (w_hand[:-1] + w_hand[1:]) * dt)])))
    # T_{k+1} = Exp(w dt) T_k: T_k^T is the right-multiplied product of the inverse steps
    Tt = so3.quat_to_dcm(so3.cumulative_quat_product(np.concatenate(
        [[[1.0, 0.0, 0.0, 0.0]], so3.exp_quat(-0.5 * (w_world[:-1] + w_world[1:]) * dt)])))
    C = np.einsum("nji,njk->nik", Tt, H)
    w_body = w_hand + np.einsum("nji,nj->ni", C, w_world)
    return C, w_body


def field_wander(rng: np.random.Generator, t_s: np.ndarray, kind: HandTurned) -> np.ndarray:
    """An isotropic Gauss-Markov wander of the world field (uT), std `field_wander` of it per axis."""
    return gauss_markov(t_s, kind.field_wander * kind.field_uT, kind.field_correlation_s, rng)


def simulate_hand_turned(seed: int, kind: HandTurned = HandTurned()) -> tuple[Session, dict]:
    """A session (gyro rad/s, magnetometer uT) and its truth."""
    rng = np.random.default_rng([seed, 38])
    p = drawn_parameters(rng, kind)
    t_fine = np.arange(0.0, kind.duration_s + 0.5, 1.0 / FINE_RATE_HZ)
    C_b_w, w_body = body_attitude_and_rate(rng, t_fine, kind)
    t_g = gyro_stamps(kind)
    t_taken = t_g + 1e-3 * kind.sample_jitter_ms * rng.standard_normal(len(t_g))
    w = np.stack([np.interp(t_taken, t_fine, w_body[:, a]) for a in range(3)], axis=1)
    bias_rad_s = np.deg2rad(p["bias_deg_s"])
    gyro = np.linalg.solve(p["K_g"], (w - bias_rad_s).T).T
    rate_hz = 1.0 / np.gradient(t_g)
    gyro += (np.deg2rad(kind.gyro_noise_deg_s_sqrt_hz) * np.sqrt(rate_hz))[:, None] * rng.standard_normal(gyro.shape)
    t_m = np.arange(0.0, kind.duration_s - kind.mag_lag_s, 1.0 / kind.mag_rate_hz) + kind.mag_lag_s
    C_at = so3.interpolate(t_fine, C_b_w, t_m - kind.mag_lag_s)
    C_b_m = so3.euler_to_dcm(p["misalign_euler_deg"])
    dip = np.deg2rad(kind.dip_deg)
    m_w = kind.field_uT * np.array([0.0, np.cos(dip), -np.sin(dip)]) + field_wander(rng, t_m, kind)
    m_b = np.einsum("nji,nj->ni", C_at, m_w)
    R = np.linalg.inv(p["soft"]) / kind.field_uT   # y = R^-1 (unit field) + h: R^-1 = field * soft
    mag = (m_b @ C_b_m.T) @ p["soft"].T + p["h"] + kind.mag_noise_uT * rng.standard_normal(m_b.shape)
    session = Session(t_gyro_s=t_g, gyro_rad_s=gyro, t_mag_s=t_m, mag=mag, mag_unit="uT",
                      source=f"simulated:hand-turned:seed={seed}",
                      metadata={"problem": "hand-turned", "seed": seed, "gyro_unit": "rad/s", "mag_unit": "uT"})
    truth = {"K_g": p["K_g"].tolist(), "bias_deg_s": p["bias_deg_s"].tolist(), "bias_rad_s": bias_rad_s.tolist(),
             "C_b_m": C_b_m.tolist(), "R": R.tolist(), "h": p["h"].tolist(), "seed": seed,
             "true_rate_rms_deg_s": float(np.rad2deg(np.sqrt(np.mean(np.sum(w_body**2, axis=1)))))}
    return session, truth
