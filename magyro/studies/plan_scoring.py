"""How a plan (`magyro plan`) is scored: the predicted one-sigma of the 12 gyro parameters from the Fisher
information the solve uses (the Cramer-Rao bound on the motion's noise-seed-0 session), its ratios to a
reference motion's, and the reference motions brought to the same duration and peak rate (`rescaled`; see
magyro/studies/plan.py's module doc). Also the sampling interval a Monte Carlo's std ratio falls in.
"""
from __future__ import annotations

import dataclasses
import math

import numpy as np

from magyro.errors import InputError
from magyro.result.reported import REPORTED
from magyro.studies.scenario import Scenario

# the gyro parameters lead the reported vector, in GYRO_ROWS order
assert (REPORTED["K_g"], REPORTED["bias_deg_s"], REPORTED["misalignment_deg"]) == (slice(0, 6), slice(6, 9),
                                                                                   slice(9, 12))
GYRO_ROWS = ([f"K_g[{i},{j}]" for i, j in ((0, 0), (0, 1), (0, 2), (1, 1), (1, 2), (2, 2))]
             + [f"bias_deg_s[{i}]" for i in range(3)] + [f"misalignment_deg[{i}]" for i in range(3)])
GROUPS = {  # the table's groups of gyro parameters
    "scale factors (K_g diagonal)": ["K_g[0,0]", "K_g[1,1]", "K_g[2,2]"],
    "non-orthogonality (K_g above)": ["K_g[0,1]", "K_g[0,2]", "K_g[1,2]"],
    "bias": ["bias_deg_s[0]", "bias_deg_s[1]", "bias_deg_s[2]"],
    "misalignment": ["misalignment_deg[0]", "misalignment_deg[1]", "misalignment_deg[2]"],
}


def gyro_covariance(problem: Scenario) -> np.ndarray:
    """The 12x12 Cramer-Rao covariance of the gyro parameters (GYRO_ROWS order) on the problem's noise-seed-0
    session (`crlb.cramer_rao_covariance` with default options: the information a default solve uses); all inf
    when the motion does not make every parameter observable."""
    from magyro.nls.method import NLS
    from magyro.options import Options
    from magyro.studies.crlb import cramer_rao_covariance
    from magyro.studies.simulate import simulate

    session, _ = simulate(problem, 0)
    return cramer_rao_covariance(problem, session, Options(), NLS())[:12, :12]


def gyro_std(problem: Scenario) -> dict[str, float]:
    """Predicted one-sigma of the 12 gyro parameters (the square roots of `gyro_covariance`'s diagonal; the
    layout of the reported vector, magyro.result.reported.REPORTED, starts with them in this order)."""
    sd = np.sqrt(np.maximum(np.diag(gyro_covariance(problem)), 0.0))
    return {name: float(v) for name, v in zip(GYRO_ROWS, sd)}


# The start poses a plan is scored from (C0 = [roll, pitch, yaw] deg from ENU; x east, y north, z up at
# identity): the base pose, a quarter turn about each world axis, two oblique poses. Only where the field
# lies in the device matters (the attitude relative to the start is the same from every pose: crlb.
# cramer_rao_at_poses), and these put it (the unit field of dip 60 deg, in device axes: `field_in_device`)
# at [0, 0.5, -0.87], [0, -0.87, -0.5], [0.87, 0.5, 0], [0.5, 0, -0.87], and, off every axis, near the
# diagonals: [0.53, 0.62, 0.57] and [-0.53, 0.57, -0.62].
START_POSES: tuple[tuple[str, tuple[float, float, float]], ...] = (
    ("identity", (0.0, 0.0, 0.0)), ("roll 90", (90.0, 0.0, 0.0)), ("pitch 90", (0.0, 90.0, 0.0)),
    ("yaw 90", (0.0, 0.0, 90.0)), ("oblique 1", (-150.0, 60.0, -120.0)), ("oblique 2", (-60.0, -60.0, 120.0)))

# The paper's motion the plan is compared with (docs/spec.md, `magyro plan`): roll, pitch and yaw (the body's z,
# y, x factors) each a sum of 4 sinusoids of 0.04-0.2 Hz, amplitudes 120, 54 and 120 deg, no rests, each angle
# relative to its value at t = 0 (no ramp: it starts at the start pose already turning). Draw 7 of magyro's
# motion generator: its own peak body rate at 60 s is 120.8 deg/s, the paper's 121.
PAPER_MOTION = {"kind": "euler", "axes": ("z", "y", "x"), "amplitude_deg": (120.0, 54.0, 120.0),
                "band_hz": (0.04, 0.2), "components": 4, "seed": 7, "ramp_s": 0.0}


def paper_motion(base: Scenario) -> Scenario:
    """The base sensors and start pose with the paper's motion (PAPER_MOTION)."""
    motion = dataclasses.replace(base.motion, **{k: (np.array(v, float) if k == "amplitude_deg" else v)
                                                for k, v in PAPER_MOTION.items()},
                                 rest_start_s=0.0, rest_end_s=0.0, turns=())
    return dataclasses.replace(base, name="paper", motion=motion, source_path="",
                               description="the paper's motion (magyro.studies.plan_scoring.PAPER_MOTION)")


def field_in_device(problem: Scenario, start_pose_deg) -> np.ndarray:
    """The problem's unit field in the device's axes at the start pose (C0^T m^w / |m^w|)."""
    from magyro import so3

    field = np.asarray(problem.field_w, float)
    return so3.euler_to_dcm(np.array(start_pose_deg, float)).T @ (field / np.linalg.norm(field))


def pose_std(problem: Scenario, start_poses_deg, jacobians: dict | None = None) -> list[dict[str, float]]:
    """`gyro_std` of the problem started from each pose (crlb.cramer_rao_at_poses: one session for all)."""
    from magyro.studies.crlb import cramer_rao_at_poses

    out = []
    for cov in cramer_rao_at_poses(problem, start_poses_deg, jacobians=jacobians):
        sd = np.sqrt(np.maximum(np.diag(cov[:12, :12]), 0.0))
        out.append({name: float(v) for name, v in zip(GYRO_ROWS, sd)})
    return out


def pose_score(stds: list[dict], references: list[dict]) -> tuple[float, float]:
    """(the largest std / reference over the poses and the 12 gyro parameters, the geometric mean of all the
    ratios): the plan's score from several start poses, lower is better."""
    r = np.array([list(ratios(s, ref).values()) for s, ref in zip(stds, references)])
    if not np.all(np.isfinite(r)):
        return math.inf, math.inf
    return float(r.max()), float(np.exp(np.mean(np.log(r))))


def ratios(std: dict[str, float], reference: dict[str, float]) -> dict[str, float]:
    return {k: std[k] / reference[k] if reference[k] > 0 else math.inf for k in GYRO_ROWS}


def peak_rate_deg_s(problem: Scenario) -> float:
    """The largest |w^b| over the gyro sample times, deg/s."""
    from magyro.studies.simulate import sample_times, truth_body_rate

    w = truth_body_rate(problem, sample_times(problem.gyro_rate_hz, problem.duration_s))
    return float(np.rad2deg(np.linalg.norm(w, axis=1).max()))


def rescaled(base: Scenario, motion_source: Scenario, duration_s: float, max_rate_deg_s: float
             ) -> tuple[Scenario, float]:
    """The base sensors with `motion_source`'s motion at `duration_s`, its band scaled by k so its peak body
    rate is max_rate (magyro.studies.plan's module doc); (scenario, k). Raises InputError when it cannot be."""
    from magyro.studies.scenario import _check_consistency

    m = motion_source.motion
    if m.kind not in ("euler", "sequential"):
        raise InputError(f"a '{m.kind}' motion has no frequency band to rescale")

    def at(k: float) -> Scenario:
        motion = dataclasses.replace(m, band_hz=(m.band_hz[0] * k, m.band_hz[1] * k))
        s = dataclasses.replace(base, name=motion_source.name, duration_s=duration_s, motion=motion,
                                description=motion_source.description)
        _check_consistency(s, motion_source.name)
        return s

    k = 1.0
    for _ in range(8):
        peak = peak_rate_deg_s(at(k))
        if peak <= 0:
            raise InputError("the motion does not move")
        if abs(peak - max_rate_deg_s) <= 1e-4 * max_rate_deg_s:
            break
        k *= max_rate_deg_s / peak
    return at(k), k


def std_ratio_interval(cov: np.ndarray, runs: int, level: float = 0.99, draws: int = 20000) -> tuple[float, float]:
    """The `level` interval of mean_i(s_i / sigma_i) over the parameters of `cov`, s_i the sample std (ddof 1) of
    `runs` draws from N(0, cov): where a Monte Carlo's mean actual / predicted std falls by its sampling error
    alone when the prediction is exact (by simulation, seed 1; the parameters are correlated, so the mean's
    spread is wider than 1/sqrt(n) of one parameter's, about 1/sqrt(2 (runs - 1)))."""
    rng = np.random.default_rng(1)
    sigma = np.sqrt(np.diag(cov))
    L = np.linalg.cholesky(cov / np.outer(sigma, sigma) + 1e-12 * np.eye(len(sigma)))
    z = rng.standard_normal((draws, runs, len(sigma))) @ L.T
    m = np.mean(np.std(z, axis=1, ddof=1), axis=1)
    low, high = np.quantile(m, [(1 - level) / 2, (1 + level) / 2])
    return float(low), float(high)
