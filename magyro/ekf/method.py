"""The paper's two-step method as a method object, `EKF`: the steps in order, and the result assembled.

    magyro.calibrate(session, options, method=EKF())
    cal, history = EKF().calibrate_with_history(session, options)

    1. the shared front end (`magyro.front.prepare`): rests, noise, ellipsoid, unit check, gate
    2. step 1, the magnetometer: Gauss-Newton on the constant-norm condition,
       from the ellipsoid (`magyro.ekf.magnetometer`); one that runs to its iteration limit is refused (exit 3,
       `step1_convergence_verdict`): the filter would follow it, not the motion
    3. the filter's prior: eq. (13) on the calibrated field (`magyro.ekf.prior`)
    4. step 2, the error-state EKF fed the whole session in time order, the magnetometer stamps shifted
       by its lag and its noise re-weighted from the innovations (`magyro.ekf.streaming`,
       `magyro.ekf.filter`); the lag from eq. (13)'s search refined on the filter's own likelihood, the
       filter run at a few lags around it (`magyro.ekf.lag`)
    5. the result: the same Calibration as the joint least squares
       (solver.method = "ekf"), std from the final covariance of
       [vec K, eps, R, h, m^i] through `result.reported_vector` (central
       differences, like the least squares' `magyro.nls.information.propagate`:
       `magyro.ekf.uncertainty`), and the estimates over time
       (`magyro.ekf.history`, the paper's Fig. 3/6/7); the std counts the lag's uncertainty
       (`magyro.ekf.uncertainty.with_lag`). `magyro.calibrate` then judges it by the same result check as the
       least squares' (`magyro.result.check`: the turning misfit, the raw gyro's drift, the rests).
"""
from __future__ import annotations

import math
import time
from dataclasses import dataclass, replace
from typing import ClassVar

import numpy as np

from magyro.ekf.history import HISTORY_ROWS, EkfHistory
from magyro.ekf.lag import LAG_STEP_S, MAX_LAG_RUNS, LagEstimate, likelihood_span, search_lag
from magyro.ekf.magnetometer import NEWTON_MAX_ITER, known_magnetometer, refine_magnetometer
from magyro.ekf.prior import PRIOR_INFLATION, Initial, initial_estimate
from magyro.ekf.streaming import StreamingCalibrator, run_filter
from magyro.ekf.uncertainty import reported_covariance, with_lag
from magyro.ekf.filter import N_STATE
from magyro.ekf.room import (DisturbanceSensitivity, disturbance_covariance, measured_disturbance,
                             step1_room_covariance)
from magyro.errors import InputError, ObservabilityError, SolverError
from magyro.front import ellipsoid
from magyro.front.initial import with_time_offset
from magyro.front.noise import whitened_effective_scale
from magyro.nls.diagnostics import rest_check
from magyro.nls.run import solved_accuracy_gate
from magyro.observability.gate import unexcited_directions
from magyro.observability.prediction import excitation_gate
from magyro.front.prepare import Prepared, prepare
from magyro.options import Options
from magyro.result.calibration import Calibration
from magyro.result.fit import FilterFit
from magyro.result.parts import Excitation, FieldDisturbance, NoiseReport, SolverReport
from magyro.result.reported import axis_mapping_warning, qr_split, reported_vector, std_from_covariance
from magyro.session import Session


@dataclass(frozen=True)
class EKF:
    """The paper's method: magnetometer first (ellipsoid + Gauss-Newton), then the gyro by an error-state EKF.

    Noise levels, rest trimming and the observability gate are those of the
    shared front end (`magyro.front.prepare`: `Options.force`, the noise
    options and `trim_rests` apply; ObservabilityError when the motion does
    not excite every parameter). The magnetometer's lag is searched as the
    least squares' start searches it (eq. 13), then refined on the filter's
    own likelihood, whose curvature gives its std; it shifts the magnetometer
    stamps and its uncertainty counts in every std (`magyro.ekf.lag`).
    `Options.estimate_time_offset=False` fixes it at `Options.time_offset_s`. The magnetometer noise is re-weighted from the
    filter's innovations, and the std counts the room's field disturbance
    (`magyro.ekf.room`; `count_room=False`: the filter's own covariance).

    magnetometer=(R, h): take this magnetometer calibration as exact and skip
    step 1 (the paper's Table I simulation assumes a calibrated magnetometer).
    mag_bias_correction: step 1 on the noise-corrected score (default) or the
    paper's plain least squares (see `refine_magnetometer`).
    consider_magnetometer: carry step 1's uncertainty into the std of the gyro
    parameters (Schmidt-Kalman consider states); off, the std is the filter's
    alone, as in the paper, which treats the calibrated magnetometer as exact.
    estimate_magnetometer: R and h become states of the filter, started at step 1's with its covariance (the gyro
    then constrains them, as in the least squares); off (the default), the paper's two steps, R and h as consider
    states. Measured in docs/ekf.md ("Why the EKF's halves disagree").
    history_rows: about how many instants the history keeps.
    prior_inflation: the eq. (13) std is multiplied by this for the filter's prior.
    """

    name: ClassVar[str] = "ekf"
    magnetometer: tuple | None = None      # (R, h) taken as exact: skip step 1
    mag_bias_correction: bool = True
    consider_magnetometer: bool = True
    history_rows: int = HISTORY_ROWS
    prior_inflation: float = PRIOR_INFLATION
    count_room: bool = True                # the std counts the room's field disturbance (magyro.ekf.room)
    estimate_magnetometer: bool = False    # R and h as states of the filter (from step 1's), not consider states

    def calibrate(self, session: Session, options: Options | None = None) -> Calibration:
        """Calibrate gyro and magnetometer from one session (returns a `magyro.Calibration`)."""
        return self.calibrate_with_history(session, options)[0]

    def calibrate_with_history(self, session: Session, options: Options | None = None) -> tuple[Calibration, EkfHistory]:
        """(Calibration, EkfHistory): the calibration and the filter's estimates over time."""
        options = options or Options()
        t_start = time.perf_counter()
        prep = prepare(session, options)
        # the gate of the least squares and the verdict of observe, from the same prediction (the x-IMU example's
        # quarter sphere, unchecked, had the filter return a 27 deg misalignment at exit 0)
        gate_warnings = excitation_gate(prep, options, self)
        s = prep.session
        if self.magnetometer is not None:
            ref = known_magnetometer(*self.magnetometer)
        else:
            ref = magnetometer_step(s, prep, self.mag_bias_correction)
            gate_warnings += step1_convergence_verdict(ref, prep, options)
        lag0 = magnetometer_lag(s, ref, prep, options)
        searched = lag_is_searched(prep, options)
        room = (measured_disturbance(s.t_mag_s, s.mag, ref) if self.magnetometer is None and self.count_room
                else FieldDisturbance(0.0, 0.0))
        if room.std_fraction > 0.0:   # step 1's std counts the room too, and reaches the gyro through the consider states
            ref = replace(ref, covariance=ref.covariance + step1_room_covariance(s.t_mag_s, s.mag, ref, room))
        init = initial_estimate(lagged(s, lag0), ref, self.prior_inflation, unexcited_directions(prep.analysis))
        stride = max(1, int(math.ceil(len(s.t_mag_s) / max(self.history_rows - 2, 1))))
        cov_Rh = ref.covariance if (self.consider_magnetometer and self.magnetometer is None) else None
        span = likelihood_span(s.t_gyro_s)
        filter_runs: list[float] = []

        def run_at(lag_s: float, sigma_mag: float, final: bool, innovations: bool = False) -> StreamingCalibrator:
            """The filter over the session with the magnetometer stamps shifted by lag_s; the final run records
            the history and, when the room is counted, the sensitivities to it; the noise passes the innovations."""
            filt = StreamingCalibrator(ref.R, ref.h, init.K0, init.eps0, None, prep.gyro_density, sigma_mag,
                                       P0=init.P0, cov_Rh=cov_Rh, history_stride=stride if final else None)
            if final and room.std_fraction > 0.0:
                filt.room = DisturbanceSensitivity(N_STATE)
            filt.innovations = [] if innovations else None
            filt.estimate_magnetometer = self.estimate_magnetometer
            filt.likelihood_from_s, filt.likelihood_to_s = span[0] - lag_s, span[1] - lag_s
            run_filter(lagged(s, lag_s), filt)
            filter_runs.append(lag_s)
            if not filt.started or filt.mag_updates == 0:
                raise InputError("the EKF got no magnetometer sample inside the gyro's time span")
            return filt

        t_filter = time.perf_counter()
        filt, sigma_mag, _ = reweighted(lambda sigma: run_at(lag0, sigma, final=not searched, innovations=True),
                                        prep.sigma_mag, options)
        lag, warnings = None, []
        if searched:
            lag, sigma_mag = likelihood_lag(run_at, lag0, filt, sigma_mag, options)
            if lag is None:
                warnings.append(LAG_NOT_BRACKETED)
            filt = run_at(lag0 if lag is None else lag.lag_s, sigma_mag, final=True)
        tau = lag0 if lag is None else lag.lag_s
        filter_s = time.perf_counter() - t_filter
        history = filt.history()
        omega = disturbance_covariance(filt.room, room) if filt.room is not None else None
        filt.room = filt.innovations = None   # the recorded entries are large; the covariance is all that is kept
        cal = assemble(filt, prep, init, filter_s, time.perf_counter() - t_start, tau, room, omega, sigma_mag, lag,
                       len(filter_runs), lag0)
        cal.warnings.extend(gate_warnings + warnings)
        # the bounds on the solved std, as the least squares applies them: a std that counts a wandering room can
        # be too large for the result to be worth having although the motion excites every parameter well
        cal.warnings.extend(solved_accuracy_gate(cal, options))
        return cal, history


MAX_NOISE_PASSES = 4          # the filter runs again at most 3 times with the magnetometer noise re-weighted
NOISE_RESCALE_TOLERANCE = 0.2   # ... when the innovations' effective scale is off by more than this (the NLS's)


def likelihood_lag(run_at, lag0_s: float, first: StreamingCalibrator, sigma_mag: float,
                   options: Options) -> tuple[LagEstimate | None, float]:
    """(the lag from the filter's likelihood, the magnetometer noise std it was found with), from eq. (13)'s lag
    lag0_s, where `first` ran (`magyro.ekf.lag.search_lag`). The noise was re-weighted at lag0_s; a lag far from
    it had inflated the innovations there (paper-table1 at a lag of 7.3 ms that eq. 13 put at 0: a lag std of
    0.22 ms instead of 0.14), so where the lag moved by more than LAG_STEP_S the noise is re-weighted at the new
    lag, and the lag searched again from there if that moved the noise."""
    def likelihood(sigma: float):
        def at(lag_s: float) -> tuple[float, StreamingCalibrator]:
            run = run_at(lag_s, sigma, final=False)
            return run.nll_sum, run
        return at

    lag = search_lag(likelihood(sigma_mag), lag0_s, (first.nll_sum, first))
    if lag is None or abs(lag.lag_s - lag0_s) <= LAG_STEP_S:
        return lag, sigma_mag
    filt, sigma_there, moved = reweighted(lambda sigma: run_at(lag.lag_s, sigma, final=False, innovations=True),
                                          sigma_mag, options)
    again = search_lag(likelihood(sigma_there), lag.lag_s, (filt.nll_sum, filt)) if moved else None
    return (again, sigma_there) if again is not None else (lag, sigma_mag)


def reweighted(run_at, sigma_mag: float, options: Options) -> tuple[StreamingCalibrator, float, bool]:
    """(the last run, the magnetometer noise std it ran with, whether that moved from sigma_mag): the filter
    `run_at(sigma)` run again while its innovations say the noise is off (`noise_factor`)."""
    start = sigma_mag
    for n_pass in range(1, MAX_NOISE_PASSES + 1):
        filt = run_at(sigma_mag)
        factor = noise_factor(filt, options) if n_pass < MAX_NOISE_PASSES else None
        if factor is None:
            break
        sigma_mag *= factor if n_pass == 1 else math.sqrt(factor)   # damped: the filter moves with its noise
    return filt, sigma_mag, sigma_mag != start


def noise_factor(filt: StreamingCalibrator, options: Options) -> float | None:
    """The factor on the magnetometer noise std when the filter's innovations say it is off, else None.

    The front end's level, from third differences when there is no rest, can be several times off (BROAD's
    magnetometer at 286 Hz: 0.20 uT against 1.03 from its rests), and a field that wanders along the path adds
    correlated model error. As the least squares re-weights its magnetometer noise from its residuals
    (`magyro.nls.solve.magnetometer_noise_factor`), the factor is the robust scale of the whitened innovations
    S^-1/2 nu (median of |e|^2 against its chi^2 median) times the square root of their integrated
    autocorrelation time, so correlated error counts as fewer independent samples. Passes after the first
    move half-way (the square root of the factor): a filter given noisier readings leans on its gyro, and its
    innovations then correlate by its own dynamics, so the factor overshoots (BROAD trial 09: 1.08 uT from
    its rests, 4.96 after one pass, 13 after three). A level the user gave (--mag-noise) is kept.
    """
    if options.mag_noise_std is not None or not filt.innovations:
        return None
    nu = np.array([v for v, _ in filt.innovations])
    lam, V = np.linalg.eigh(np.array([S for _, S in filt.innovations]))     # S^-1/2 nu, S symmetric
    e = np.einsum("kji,kj->ki", V, nu) / np.sqrt(np.maximum(lam, 1e-300))
    factor = whitened_effective_scale(e)
    return factor if abs(factor - 1.0) > NOISE_RESCALE_TOLERANCE else None


def magnetometer_step(s: Session, prep: Prepared, bias_correction: bool):
    """Step 1 from the ellipsoid; a cloud that pins no unique magnetometer calibration is too little motion
    (exit 3), never a crash."""
    try:
        ref = refine_magnetometer(s.mag, prep.fit.R, prep.fit.h, prep.sigma_mag if bias_correction else None)
    except np.linalg.LinAlgError:
        ref = None
    if ref is None or not (np.all(np.isfinite(ref.R)) and np.all(np.isfinite(ref.covariance))):
        raise ObservabilityError(
            "the magnetometer's field directions do not pin down its soft/hard iron (step 1's normal equations are "
            "singular: the readings cover too little of the sphere); turn the device through large angles about "
            "all three of its axes so that the field sweeps much of the sphere", prep.analysis)
    return ref


def step1_convergence_verdict(ref, prep: Prepared, options: Options) -> list[str]:
    """Step 1's Gauss-Newton that runs to its iteration limit has walked off along a direction the field's norm
    alone does not pin (a cap of the sphere fitted by ever larger spheres): ObservabilityError (exit 3), or with
    --force the warning. The filter then follows step 1, not the motion, and agrees with its own field, so no check
    of the result against the data sees it: the second half of BROAD trial 07 (ellipsoid uniqueness 2.6, its field
    wandering) ran 50 iterations to an R 20-45 % small and a hard iron 28 field units away, the filter's scale 17 %
    low (the split check read 14 sigma); a simulated 40/25 Hz hand with an ideal gyro on part of the sphere
    (uniqueness 1.3; 50 iterations on seeds 0-5, R 4-60 % off) had the scale 10 % low at 8.7 of its std and
    dead-reckoned 16.5 deg RMS against the raw gyro's 0.9. The least squares, which fits R and h with the gyro,
    was right on both."""
    if ref.iterations < NEWTON_MAX_ITER:
        return []
    why = (f"the magnetometer's step 1 (Gauss-Newton on the field's norm, without the gyro) did not converge in "
           f"{NEWTON_MAX_ITER} iterations: the field directions do not pin its soft/hard iron (ellipsoid uniqueness "
           f"{prep.fit.uniqueness:.1f})")
    if not options.force:
        raise ObservabilityError(f"{why}; turn the device through more orientations so that the field sweeps much of "
                                 "the sphere, or solve with the least squares (--method nls), which fits them with "
                                 "the gyro", prep.analysis)
    return [f"solved with --force although {why}"]


LAG_NOT_BRACKETED = ("the filter's likelihood gave no magnetometer lag (it did not bracket one within +/-0.1 s and "
                     f"{MAX_LAG_RUNS} runs, or the filter's innovation covariance lost positive definiteness), so the "
                     "lag of the linear fit (eq. 13) is used and the std does not count its uncertainty; solve with the "
                     "least squares (--method nls), which estimates the lag with the rest")


def lag_is_searched(prep: Prepared, options: Options) -> bool:
    """The lag is estimated unless fixed (--no-time-offset) or the motion does not excite every parameter."""
    return bool(options.estimate_time_offset and prep.analysis.full_rank)


def lagged(s: Session, lag_s: float) -> Session:
    """The session with the magnetometer stamps moved to the instants its readings measured (stamp - lag)."""
    return replace(s, t_mag_s=s.t_mag_s - lag_s) if lag_s else s


def magnetometer_lag(s: Session, ref, prep: Prepared, options: Options) -> float:
    """The start of the magnetometer's lag behind the gyro, s: searched on eq. (13) as the least squares starts from
    (`magyro.front.initial.with_time_offset`; 10-33 ms on real devices, where 3-10 deg of attitude per update at
    300 deg/s biased the filter by degrees per second); the filter's likelihood then refines it
    (`magyro.ekf.lag`). `Options.time_offset_s` when fixed (--no-time-offset) or when the motion does not
    excite every parameter."""
    if not lag_is_searched(prep, options):
        return float(options.time_offset_s or 0.0)
    field_m = ellipsoid.calibrated_field(ref.R, ref.h, s.mag)
    return float(with_time_offset(s.t_gyro_s, s.gyro_rad_s, s.t_mag_s, field_m).time_offset_s)


def assemble(filt: StreamingCalibrator, prep: Prepared, init: Initial, filter_s: float, total_s: float,
             tau: float, room: FieldDisturbance, omega: np.ndarray | None, sigma_mag: float,
             lag: LagEstimate | None = None, filter_runs: int = 1, lag_start_s: float | None = None) -> Calibration:
    """The Calibration of the filter's final state, with the same fields as the joint least squares'; its std
    counts the room's field disturbance (`magyro.ekf.room`), the filter's own beside it as `std_white`, and both
    the uncertainty of the lag when the likelihood estimated it (`magyro.ekf.lag`)."""
    K, eps, m = filt.K.copy(), filt.eps.copy(), filt.m.copy()
    C, Kg = proper_split(K)
    ref = init.refinement

    def reported(cov_in: np.ndarray) -> np.ndarray:
        cov = reported_covariance(K, eps, filt.R, filt.h, m, cov_in, C)
        if lag is None:
            return cov
        g = lag.sensitivity(lambda lag_s, run: reported_vector(run.K, run.eps, np.linalg.inv(run.R), run.h, run.m, C,
                                                               lag_s))
        return with_lag(cov, lag.std_s, g)

    cov_white = filt.input_covariance(ref.covariance)
    std_white = std_from_covariance(reported(cov_white))
    std = std_white if omega is None else std_from_covariance(reported(cov_white + room_input_covariance(omega, filt.B)))
    n_samples = filt.gyro_samples + filt.mag_updates
    return Calibration(
        K_g=Kg, bias_rad_s=C.T @ eps, K=K, eps_rad_s=eps, C_b_m=C, R=filt.R.copy(), h=filt.h.copy(),
        mag_unit=prep.session.mag_unit, field_i=m, std=std, std_white=None if omega is None else std_white,
        observability=Excitation.of(prep.analysis),
        solver=SolverReport("ekf", "done", int(n_samples), float(filter_s), float(total_s), {
            "gyro_samples": int(filt.gyro_samples), "mag_updates": int(filt.mag_updates),
            "skipped_mag": int(filt.skipped_mag),
            "samples_per_second": float(n_samples * filter_runs / filter_s) if filter_s > 0 else None,
            "state_dimension": int(filt.n), "consider_magnetometer": bool(filt.consider),
            "magnetometer_newton_iterations": int(ref.iterations),
            "magnetometer_bias_corrected": bool(ref.bias_corrected),
            "filter_runs": int(filter_runs),
            "lag_start_s": float(tau if lag_start_s is None else lag_start_s)}),
        noise=NoiseReport(prep.gyro_density, sigma_mag, prep.sigma_mag if sigma_mag != prep.sigma_mag else None,
                          prep.noise_source,
                          room if ref.covariance is not None and room.correlation_time_s > 0 else None,
                          None, *level_sources(prep, sigma_mag)),
        fit=FilterFit(float(ref.rms_norm_error), float(ref.rms_norm_error_initial),
                      float(filt.nis_sum / max(filt.mag_updates, 1)), tuple(np.sqrt(np.diag(init.P0)).tolist())),
        time_offset_s=tau, time_offset_estimated=lag is not None,
        rests=rest_check(prep.rests, Kg, C.T @ eps),
        warnings=[w for w in (axis_mapping_warning(C), guessed_gyro_level_warning(prep)) if w],
    )


def proper_split(K: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """`qr_split`, except that a K of negative determinant is the filter's failure to report (exit 1), not a
    diagnosis: the filter cannot tell a mirrored gyro from having lost its way; the least squares can."""
    if np.linalg.det(K) < 0:
        raise SolverError(
            "the EKF ended with a gyro matrix K of negative determinant (its C_b_m would be a mirror image), so "
            "its result is not reported: the filter cannot tell a mirrored gyro axis from having lost its way; "
            "solve with the least squares (--method nls), which can")
    return qr_split(K)


def room_input_covariance(omega: np.ndarray, B: np.ndarray) -> np.ndarray:
    """The disturbance's Omega over the error state's [vec K, eps, m^i tangent] as a 24x24 covariance of
    [vec K, eps, R upper, h, m_i] (`StreamingCalibrator.input_covariance`'s layout)."""
    T = np.zeros((24, 14))
    T[:12, :12] = np.eye(12)
    T[21:, 12:] = B
    return T @ omega @ T.T


def level_sources(prep: Prepared, sigma_mag: float) -> tuple[str, str]:
    """(gyro, magnetometer): where each level came from; the magnetometer's, re-weighted from the filter's
    innovations, is estimated by the solve."""
    from magyro.front import noise

    levels = prep.levels
    if levels is None:
        return "", ""
    return levels.gyro_source, noise.ESTIMATED if sigma_mag != prep.sigma_mag else levels.mag_source


def guessed_gyro_level_warning(prep: Prepared) -> str | None:
    """The filter cannot measure a gyro level it was given as a guess (no rest, differences still falling)."""
    from magyro.front import noise

    if prep.levels is None or prep.levels.gyro_source != noise.GUESS:
        return None
    return ("the gyro noise density is a guess: the recording has no rest at either end and the EKF cannot measure "
            "it; the std rests on it. Start and end the recording with 2 s of rest, or pass --gyro-noise "
            "(--method nls estimates it)")
