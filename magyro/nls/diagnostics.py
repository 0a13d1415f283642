"""What the solved problem says about the recording: fit statistics, suspect windows, warnings, the result.

The model assumes a homogeneous field and a linear magnetometer; the windows
where the magnetometer fits far worse than typical, and a field magnitude that
changes along the path, are how a magnet or iron near the path shows.
"""
from __future__ import annotations

import numpy as np

from magyro.front import ellipsoid, noise, rests
from magyro.front.prepare import Prepared
from magyro.nls.grid import Grid
from magyro.nls.hard_iron import hard_iron_at_samples
from magyro.nls.information import propagate
from magyro.nls.reduction import Reduced
from magyro.nls.method import NLS
from magyro.nls.accelerometer import accelerometer_result
from magyro.nls.problem import JointProblem
from magyro.nls.variance import MIN_REDUNDANCY
from magyro.nls.solve import Solution, gyro_residuals, magnetometer_residuals, residual_matrix
from magyro.observability.gate import ObservabilityAnalysis
from magyro.result.calibration import Calibration
from magyro.result.fit import FieldChange, LeastSquaresFit, SuspectWindow
from magyro.result.parts import Excitation, FieldDisturbance, NoiseReport, RestCheck, SolverReport
from magyro.result.reported import axis_mapping_warning, qr_split, std_from_covariance
from magyro.session import Session, runs_of_true

SUSPECT_WINDOW_S = 1.0
SUSPECT_FACTOR = 5.0            # BROAD: undisturbed trials reach 3.6x, a magnet beside the path 7.5x
FIELD_WINDOW_S = 0.5
MAX_FIELD_CHANGE = 0.05         # BROAD: 1-3 % across the capture volume; a magnet beside the path 7 %


def residual_summary(problem: JointProblem, r: np.ndarray, session: Session, R: np.ndarray,
                     h: np.ndarray) -> LeastSquaresFit:
    """Fit statistics of the whitened residual matrix r (one row per interval) and of the field magnitude;
    `h` is the hard iron, or per magnetometer sample (n, 3) when it moves."""
    mag = magnetometer_residuals(r, problem.grid.stride)[problem.grid.sample_mask]
    gyro = gyro_residuals(r, problem.grid.stride)
    n_res = (mag.size + gyro.size + (3 * problem.n_int if problem.walk else 0)   # gap segments have no magnetometer residual
             + (3 * problem.n_int if problem.hand else 0))                      # the hand's velocity steps: its states' own
    dof = n_res - problem.n_x
    return LeastSquaresFit(
        mag_rms_normalised=float(np.sqrt(np.mean(mag**2))),
        gyro_rms_normalised=float(np.sqrt(np.mean(gyro**2))),
        variance_factor=float(np.sum(r**2)) / dof,
        residuals=int(n_res),
        unknowns=int(problem.n_x),
        suspect_segments=suspect_segments(problem.grid, r),
        field_change=field_magnitude_change(session, R, h),
    )


def suspect_segments(grid: Grid, residuals: np.ndarray) -> tuple[SuspectWindow, ...]:
    """Windows where the magnetometer fits far worse than typical (spikes, iron or a magnet near the path)."""
    r = residuals[:, : 3 * grid.stride]
    samples = 3 * grid.mag_weight.sum(axis=1)  # residual entries per interval with a magnetometer sample
    t = grid.t_node_s[:-1]
    window = np.floor((t - t[0]) / SUSPECT_WINDOW_S).astype(int)
    n_w = window.max() + 1
    count = np.bincount(window, weights=samples, minlength=n_w)
    rms = np.sqrt(np.bincount(window, weights=np.sum(r**2, axis=1), minlength=n_w) / np.maximum(count, 1))
    has = count > 0   # a window inside a gap in the magnetometer record has nothing to judge
    typical = np.median(rms[has])
    bad = has & (rms > SUSPECT_FACTOR * typical)
    return tuple(SuspectWindow(float(t[0] + a * SUSPECT_WINDOW_S), float(t[0] + (b + 1) * SUSPECT_WINDOW_S),
                               float(rms[a : b + 1].max() / typical)) for a, b in runs_of_true(bad))


def field_magnitude_change(session: Session, R: np.ndarray, h: np.ndarray) -> FieldChange:
    """Largest departure of the calibrated field magnitude |R (y - h)| from 1, over FIELD_WINDOW_S windows.

    The method assumes a homogeneous field: its magnitude must not change along
    the path. A magnet or iron near the path shows as a local change.
    """
    norm = np.linalg.norm(ellipsoid.calibrated_field(R, h, session.mag), axis=1)
    window = np.floor((session.t_mag_s - session.t_mag_s[0]) / FIELD_WINDOW_S).astype(int)
    count = np.bincount(window)
    mean = np.bincount(window, weights=norm) / np.maximum(count, 1)
    dev = np.where(count > 0, np.abs(mean - 1.0), 0.0)   # a window inside a hole has nothing to judge
    worst = int(np.argmax(dev))
    return FieldChange(float(dev[worst]), float(session.t_mag_s[0] + (worst + 0.5) * FIELD_WINDOW_S),
                       float(np.median(dev[count > 0])))


def rest_check(found: rests.Rests | None, K_g: np.ndarray, bias_rad_s: np.ndarray) -> RestCheck | None:
    """The bias the rests imply (eps_b = -K_g mean(y_rest)) against the estimate."""
    if found is None or found.gyro_mean_rad_s is None:
        return None
    at_rest = -K_g @ found.gyro_mean_rad_s
    return RestCheck(tuple(tuple(map(float, s)) for s in found.segments_s), float(found.seconds),
                     found.gyro_mean_rad_s, np.rad2deg(at_rest), np.rad2deg(bias_rad_s - at_rest))


def warnings_for(fit: LeastSquaresFit, analysis: ObservabilityAnalysis, C_b_m: np.ndarray,
                 ellipsoid_fit: ellipsoid.EllipsoidFit) -> list[str]:
    """The plain-language warnings of a solve (docs/how-it-works.md, step 9)."""
    out = []
    change = fit.field_change
    if change.max_fraction > MAX_FIELD_CHANGE:
        out.append(
            f"the field magnitude changes by {100 * change.max_fraction:.1f}% around "
            f"{change.at_s:.1f} s (typically {100 * change.median_fraction:.1f}%): the field is not "
            "homogeneous there (a magnet or iron near the path) or the magnetometer is not linear; this calibration "
            "assumes a homogeneous field, so re-record away from iron, or try --loss huber"
        )
    if ellipsoid_fit.uniqueness < ellipsoid.MIN_UNIQUENESS:
        out.append(
            f"the field directions cover little of the sphere (ellipsoid uniqueness {ellipsoid_fit.uniqueness:.2f}): "
            "the magnetometer's R and h rest on the gyro as much as on the ellipsoid; turn through more orientations"
        )
    mapping = axis_mapping_warning(C_b_m)
    if mapping:
        out.append(mapping)
    for seg in fit.suspect_segments:
        out.append(
            f"the magnetometer does not fit the model during {seg.t0_s:.1f}-{seg.t1_s:.1f} s "
            f"(residual {seg.residual_vs_typical:.1f}x the typical): a magnet or iron near the path, or a spike; "
            "check the recording, or use --loss huber to weigh those samples down"
        )
    if not analysis.full_rank:
        out.append(f"solved with --force although the motion is insufficient: {analysis.summary()}")
    return out


def level_sources(prep: Prepared, sol: Solution) -> tuple[str, str]:
    """(gyro, magnetometer): where each level that weighted the fit came from. A guess the solve re-weighted
    until it settled, with enough redundant residuals to measure it, is "estimated by the solve"."""
    levels = prep.levels
    if levels is None:
        return "", ""
    step = sol.variance

    def source(given: str, factor_redundancy: float) -> str:
        if given != noise.GUESS or step is None or not sol.levels_settled:
            return given
        return noise.ESTIMATED if factor_redundancy >= MIN_REDUNDANCY else noise.GUESS
    return (source(levels.gyro_source, step.gyro_redundancy if step else 0.0),
            source(levels.mag_source, step.mag_redundancy if step else 0.0))


def noise_report(prep: Prepared, sol: Solution, disturbance: FieldDisturbance) -> NoiseReport:
    """The levels that weighted the fit, those before the solve, and where each came from."""
    gyro_source, mag_source = level_sources(prep, sol)
    density = prep.gyro_density if sol.gyro_density is None else sol.gyro_density
    step = sol.variance
    redundancy = None if step is None else {k: float(v) for k, v in (("gyro", step.gyro_redundancy),
                                                                      ("mag", step.mag_redundancy)) if np.isfinite(v)}
    return NoiseReport(float(density), float(sol.sigma_mag), float(prep.sigma_mag), prep.noise_source, disturbance,
                       float(prep.gyro_density), gyro_source, mag_source, redundancy or None)


def guessed_level_warnings(prep: Prepared, sol: Solution) -> list[str]:
    """A level that is still a guess after the solve (no rest, not given, not measurable by the solve)."""
    out = []
    step = sol.variance
    for name, src, option, redundancy in zip(("gyro noise density", "magnetometer noise"), level_sources(prep, sol),
                                              ("--gyro-noise", "--mag-noise"),
                                              (None if step is None else step.gyro_redundancy,
                                               None if step is None else step.mag_redundancy)):
        if src != noise.GUESS:
            continue
        why = ("its re-weighting had not settled" if not sol.levels_settled else
               f"the fit leaves only {redundancy:.0f} redundant residuals to measure it" if redundancy is not None
               and np.isfinite(redundancy) else "it could not be measured")
        out.append(f"the {name} is a guess: the recording has no rest at either end and {why}; the std rests on it. "
                   f"Start and end the recording with 2 s of rest, or pass {option}")
    return out


def walk_details(problem: JointProblem, method: NLS, h_samples: np.ndarray) -> dict:
    """The moving hard iron's density and how far it walked (peak to peak per axis, magnetometer unit)."""
    if not problem.walk:
        return {}
    return {"hard_iron_walk": {"density_per_sqrt_s": float(method.hard_iron_walk),
                               "peak_to_peak": [float(v) for v in np.ptp(h_samples, axis=0)]}}


def assemble(problem: JointProblem, prep: Prepared, grid: Grid, sol: Solution, reduced: Reduced,
             method: NLS, total_s: float, cov_theta: np.ndarray, disturbance: FieldDisturbance) -> Calibration:
    """The Calibration of a converged solve: parameters, QR split, std (from `cov_theta`, the covariance of the
    corrections with the field disturbance counted; the white std beside it), fit statistics and warnings."""
    g = problem.globals_of(sol.p)
    theta = sol.x[: problem.n_theta]
    S, h, K, eps, m_i, tau = (np.array(v) for v in problem.physical_function(theta, g))
    h, eps, m_i, tau = h.ravel(), eps.ravel(), m_i.ravel(), float(tau.item())
    C, Kg = qr_split(K)
    R = np.linalg.inv(S)
    h_samples = hard_iron_at_samples(problem, sol.x, sol.p, prep.session) if problem.walk else h
    r = residual_matrix(problem, sol.x, sol.p) if sol.residuals is None else sol.residuals
    fit = residual_summary(problem, r, prep.session, R, h_samples)
    # No a-posteriori variance-factor scaling: the noise levels are already calibrated (given, from
    # rests with their correlation, or re-weighted from the residuals' effective scale); the plain
    # factor counts correlated samples as independent and would undo that. It is reported in `fit`.
    std_white = std_from_covariance(propagate(problem, theta, g, np.linalg.inv(reduced.information), C))
    std = std_from_covariance(propagate(problem, theta, g, cov_theta, C))
    a = prep.analysis
    stats = sol.stats
    return Calibration(
        K_g=Kg, bias_rad_s=C.T @ eps, K=K, eps_rad_s=eps, C_b_m=C, R=R, h=h,
        mag_unit=prep.session.mag_unit, field_i=m_i, std=std, std_white=std_white,
        observability=Excitation.of(a),
        solver=SolverReport("nls", stats["return_status"], int(stats["iter_count"]), float(sol.seconds), float(total_s),
                            {"gauss_newton_decrement": stats["gauss_newton_decrement"], "passes": sol.passes,
                             "nodes": int(grid.nodes), "stride": int(grid.stride), "loss": method.loss,
                             **walk_details(problem, method, h_samples)}),
        noise=noise_report(prep, sol, disturbance),
        fit=fit,
        time_offset_s=tau,
        time_offset_estimated=problem.estimate_time_offset,
        rests=rest_check(prep.rests, Kg, C.T @ eps), stills=prep.stills if problem.accelerometer else None,
        warnings=warnings_for(fit, a, C, prep.fit) + guessed_level_warnings(prep, sol),
        accelerometer=accelerometer_result(problem, theta, g, cov_theta) if problem.accelerometer else None,
    )
