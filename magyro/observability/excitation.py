"""`magyro observe`: does this recording excite every calibration parameter, and how well?

No solve. `observe` computes, from the session alone (gyro readings and the
step-1 calibrated magnetometer):

- the paper's observability matrix, the integral of M^T M (eq. 10-11): rank
  with the noise-floor tolerance of `gate` (the same rule as the gate of
  `magyro solve`), normalised eigenvalues, condition number;
- the timeline: when, during the session, the cumulative integral first reaches
  rank 12 and when it first becomes well conditioned (condition below
  `gate.WELL_CONDITIONED`), so a user knows how long to keep moving;
- coverage: per gyro axis the angle turned and the peak rate, and the fraction
  of the sphere of field directions visited (equal-area cells);
- the prediction: the one-sigma of every calibration parameter, from the Fisher
  information of the joint problem at the initial estimate
  (`magyro.nls.information.predicted_std`), laid out like the calibration's `std`;
- the verdict, "sufficient" | "marginal" | "insufficient", with the reason;

and puts them, with the weak directions in words (`advice`), in an
`ObservabilityReport` (`report`).
"""
from __future__ import annotations

import dataclasses
import math

import numpy as np

from magyro.errors import InputError, MagyroError, ObservabilityError
from magyro.front import ellipsoid
from magyro.front.prepare import Prepared, moving_session, prepare
from magyro.nls.method import NLS
from magyro.observability.advice import weak_directions
from magyro.observability.gate import (WELL_CONDITIONED, accuracy_shortfalls, ObservabilityAnalysis, cumulative_noise_matrix,
                                       directional_rank, holes_cause, too_weak_reason)
from magyro.observability.prediction import prediction_stride, predicted_accuracy, refuse_a_field_fault  # noqa: F401  (kept importable here)
from magyro.observability.gravity import observe_accelerometer
from magyro.observability.matrix import cumulative_information, trapezoid_weights
from magyro.observability.report import (SPHERE_BANDS, SPHERE_SECTORS, sphere_cell, unit_rows, Coverage, ObservabilityReport, Targets,
                                         Timeline, accuracy_rows, fmt)
from magyro.options import Options, StdBounds
from magyro.result.parts import Std
from magyro.result.reported import plausible_gyro
from magyro.session import Session

CHECKPOINTS = 200                 # cumulative integral evaluated at this many times


def observe(session: Session, options: Options | None = None, targets: Targets | None = None,
            method: NLS | None = None, *, checkpoints: int = CHECKPOINTS) -> ObservabilityReport:
    """The excitation-sufficiency report of one session (no solve).

    `options` gives the noise levels (None: estimated from the data) and the rest
    trimming of `magyro solve`; `targets` the accuracy the verdict asks for;
    `method` the least squares whose accuracy is predicted: its `stride` is the
    node stride of the prediction (None: the solve's, `default_stride`).
    Raises InputError for unusable input.
    """
    options = options or Options()
    targets = targets or Targets()
    method = method or NLS()
    t0 = float(session.t_gyro_s[0])
    s, levels, found = gate_inputs(session, options)
    prep: Prepared | None = None
    problem = None
    try:
        prep = prepare(session, dataclasses.replace(options, force=True))
        analysis, field_m, s = prep.analysis, prep.field_m, prep.session
        mag_std_unit_field = levels.mag_sample_std * float(np.mean(np.diag(prep.fit.R)))
    except ObservabilityError as err:  # the ellipsoid cannot be fitted (static, planar, sparse cloud)
        analysis = err.report
        problem = str(err).split(";")[0]
        field_m = ellipsoid.surrogate_field_directions(s.mag)
        mag_std_unit_field = levels.mag_sample_std / float(np.mean(np.linalg.norm(s.mag, axis=1)))

    tl = timeline(s, field_m, levels.gyro_sample_std_rad_s, mag_std_unit_field, checkpoints)
    full_rank_at = first_time(tl.t_s, tl.rank == 12)
    well_at = first_time(tl.t_s, (tl.rank == 12) & (tl.condition < WELL_CONDITIONED))

    rates, reference = bias_free_rates(s, prep, analysis)
    cov = coverage(s.t_gyro_s, rates, field_m, reference)

    std, prediction = predict(prep, analysis, options, method)
    verdict, reason = judge(analysis, problem, std, targets, options.max_std, prediction.get("field_disturbance"),
                            holes_cause(s.t_gyro_s))
    weak, advice = weak_directions(analysis, verdict=verdict)
    if problem is not None and not any("all three" in a for a in advice):
        advice = ["Turn the device through large angles about all three of its axes, so that the field sweeps "
                  "the sphere (the magnetometer's soft/hard iron needs it)."] + advice
    accelerometer = None
    if session.acc_m_s2 is not None:   # gravity, a second reference vector: shown beside, the verdict unchanged
        accelerometer = observe_accelerometer(session, s, field_m, analysis, rates, found.segments_s,
                                              levels.gyro_sample_std_rad_s, mag_std_unit_field)
    return ObservabilityReport(
        source=session.source, duration_s=session.duration_s, t_start_s=t0,
        gyro_samples=len(session.t_gyro_s), mag_samples=len(session.t_mag_s),
        gyro_rate_hz=session.gyro_rate_hz, mag_rate_hz=session.mag_rate_hz,
        analysis=analysis, ellipsoid_fitted=prep is not None, ellipsoid_problem=problem,
        ellipsoid_rms_norm_error=None if prep is None else prep.fit.rms_norm_error,
        timeline=tl, full_rank_at_s=full_rank_at, well_conditioned_at_s=well_at, coverage=cov,
        predicted_std=std, prediction=prediction, targets=targets, verdict=verdict, reason=reason,
        weak_directions=weak, advice=advice,
        noise={"gyro_density_rad_s_sqrt_hz": levels.gyro_density_rad_s_sqrt_hz,
               "gyro_density_deg_s_sqrt_hz": math.degrees(levels.gyro_density_rad_s_sqrt_hz),
               "gyro_sample_std_rad_s": levels.gyro_sample_std_rad_s,
               "mag_std": levels.mag_std, "mag_sample_std": levels.mag_sample_std, "source": levels.source},
        analysed_span_s=[float(s.t_gyro_s[0]), float(s.t_gyro_s[-1])],
        rests_s=[[float(a), float(b)] for a, b in found.segments_s],
        mag_unit=session.mag_unit, t_mag_s=s.t_mag_s, field_directions=unit_rows(field_m),
        t_gyro_s=s.t_gyro_s, rates_deg_s=np.rad2deg(rates), accelerometer=accelerometer,
    )


# --------------------------------------------------------------------------- the timeline


def gate_inputs(session: Session, options: Options):
    """(session as the gate analyses it, per-sample noise levels, rests), exactly as prepare() makes them,
    for the cumulative integral to follow the gate."""
    return moving_session(session, options)


def timeline(session: Session, field_m, gyro_sample_std: float, mag_std_unit_field: float,
             checkpoints: int = CHECKPOINTS) -> Timeline:
    """Rank and condition of the cumulative integral at `checkpoints` times, by the gate's rule.

    Each checkpoint is judged like `gate.analyse` judges a whole session: an
    eigen-direction v of the integral so far counts when its eigenvalue exceeds
    FLOOR_FACTOR times v^T N v, N the noise matrix of the same stretch of session (it grows
    with the integral). The last checkpoint therefore reproduces the gate's rank.
    Times are session time: the `t` of the session's samples (the session file's t_s).
    """
    t, y = session.t_gyro_s, session.gyro_rad_s
    tc = np.linspace(t[0], t[-1], max(2, int(checkpoints)))
    info = cumulative_information(t, y, session.t_mag_s, field_m, tc)
    N = cumulative_noise_matrix(t, y, session.t_mag_s, field_m, gyro_sample_std, mag_std_unit_field, tc)
    lam, V = np.linalg.eigh(info)
    rank = np.zeros(len(tc), dtype=int)
    snr = np.zeros((len(tc), 12))
    for c in range(len(tc)):
        if lam[c, -1] > 0:
            rank[c], snr_c = directional_rank(lam[c], V[c], N[c])
            snr[c] = np.sort(snr_c)
    with np.errstate(divide="ignore", invalid="ignore"):
        cond = np.where(lam[:, 0] > 0, lam[:, -1] / np.where(lam[:, 0] > 0, lam[:, 0], 1.0), np.inf)
    return Timeline(tc, lam, snr, rank, cond)


def first_time(t_s: np.ndarray, reached: np.ndarray) -> float | None:
    hit = np.flatnonzero(reached)
    return float(t_s[hit[0]]) if hit.size else None


# --------------------------------------------------------------------------- coverage


def bias_free_rates(session: Session, prep: Prepared | None, analysis: ObservabilityAnalysis):
    """Gyro rates (rad/s, per gyro axis) with the bias taken out, and how.

    Full rank: corrected by the linear initial estimate (paper eq. 13), w_b = K_g0 y + eps_b0,
    when that estimate is a plausible gyro (scale factors within 0.5-2, axes within 30 deg of
    orthogonal); a weakly excited motion can give one that turns 970 deg where the raw gyro
    says 89. Otherwise the per-axis median reading is taken as the bias (right for still
    axes, which is what matters when axes are missing).
    """
    y = session.gyro_rad_s
    if prep is not None and analysis.full_rank:
        from magyro.front.initial import linear_gyro_estimate
        from magyro.result.reported import qr_split

        lin = linear_gyro_estimate(session.t_gyro_s, y, session.t_mag_s, prep.field_m)
        try:
            C, Kg = qr_split(lin.K)
        except InputError:
            pass
        else:
            if plausible_gyro(Kg):
                return y @ Kg.T + C.T @ lin.eps, "corrected by the initial estimate of K_g and bias"
    return y - np.median(y, axis=0), "readings minus their median (taken as the bias)"


def coverage(t_gyro_s, rates_rad_s, field_m, rate_reference: str) -> Coverage:
    w = trapezoid_weights(t_gyro_s)
    angle = np.rad2deg(np.abs(rates_rad_s).T @ w)
    peak = np.rad2deg(np.max(np.abs(rates_rad_s), axis=0))
    cells = np.unique(sphere_cell(field_m))
    return Coverage(angle, peak, rate_reference, int(cells.size), SPHERE_BANDS * SPHERE_SECTORS)


# --------------------------------------------------------------------------- the prediction and the verdict


def predict(prep: Prepared | None, analysis: ObservabilityAnalysis, options: Options,
            method: NLS) -> tuple[Std | None, dict]:
    """The solve's gate's prediction (`magyro.observability.prediction.predicted_accuracy`: one computation for
    both), or None."""
    if prep is None:
        return None, {"note": "the magnetometer's soft/hard iron cannot be fitted, so no calibration is determined"}
    try:
        predicted = predicted_accuracy(prep, options, method)
    except (MagyroError, np.linalg.LinAlgError) as e:
        if analysis.full_rank:
            raise
        return None, {"stride": prediction_stride(prep.session, method),
                      "note": f"no prediction for a rank-deficient session ({e})"}
    refuse_a_field_fault(prep, options, method, predicted)   # the field's fault, not the motion's: as the solve says
    std, disturbance = predicted.std, predicted.disturbance
    info = {"stride": predicted.stride, "seconds": predicted.seconds,
            "method": "Gauss-Newton information of the joint problem at the initial estimate, trajectory "
                      "marginalised, noise levels of the session, the field's wander measured and counted"}
    if disturbance is not None:
        info["field_disturbance"] = disturbance.to_dict()
    if not all(np.all(np.isfinite(getattr(std, f.name))) for f in dataclasses.fields(std)):
        info["note"] = "the information is singular: null marks what this recording cannot determine"
    return std, info


ROOM_LIMITS_ABOVE = 0.005   # a field that wanders by more than 0.5 % along the path is named as a limit


def judge(analysis: ObservabilityAnalysis, ellipsoid_problem: str | None, std: Std | None,
          targets: Targets, bounds: StdBounds = StdBounds(), disturbance: dict | None = None,
          holes: str = "") -> tuple[str, str]:
    """The verdict and its reason in plain words: insufficient exactly when the solve would refuse the session."""
    if ellipsoid_problem is not None:
        return "insufficient", (f"{ellipsoid_problem}, so the magnetometer's soft/hard iron cannot be fitted; "
                                f"the motion excites {analysis.rank} of the 12 gyro parameters")
    if not analysis.full_rank:
        return "insufficient", (f"the motion excites only {analysis.rank} of the 12 gyro parameters "
                                f"(rank of the integral of M^T M above the noise floor)")
    if std is None:
        return "marginal", "all 12 gyro parameters are excited, but their accuracy could not be predicted"
    shortfalls = accuracy_shortfalls(std, bounds)
    if shortfalls:
        wander = (disturbance or {}).get("std_fraction")
        return "insufficient", f"{too_weak_reason(shortfalls, wander, holes)} (magyro solve refuses it too)"
    above, worst = [], []
    for label, values, unit, target in accuracy_rows(std, targets):
        v = float(np.max(values)) if np.all(np.isfinite(values)) else math.inf
        worst.append((v / target, label, v, unit, target))
        if not v <= target:
            above.append(f"{label} {fmt(v)} {unit} (target {target:g})")
    if above:
        room = (disturbance or {}).get("std_fraction", 0.0)
        fix = ("record longer or with larger, faster turns" if room <= ROOM_LIMITS_ABOVE else
               f"the field wanders by {100 * room:.1f} % along the path, which the std counts: record away from iron "
               "and magnets (or in a smaller volume), longer, or with larger, faster turns")
        return "marginal", ("all 12 gyro parameters are excited, but the predicted one-sigma is above target for "
                            + "; ".join(above) + ": " + fix)
    ratio, label, v, unit, target = max(worst)
    return "sufficient", (f"all 12 gyro parameters are excited and every predicted one-sigma is within its "
                          f"target (closest: {label} {fmt(v)} {unit} of {target:g})")


# --------------------------------------------------------------------------- helpers
