"""`magyro observe`: does this recording excite every calibration parameter, and how well?

No solve. From the session alone (gyro readings and the step-1 calibrated
magnetometer) the report gives:

- the paper's observability matrix, the integral of M^T M (eq. 10-11): rank
  with the noise-floor tolerance of `magyro.observability` (the same rule as
  the gate of `magyro solve`), normalised eigenvalues, condition number;
- when, during the session, the cumulative integral first reaches rank 12 and
  when it first becomes well conditioned (condition below
  `WELL_CONDITIONED`), so a user knows how long to keep moving;
- the weakest directions in parameter names and the motion that excites them;
- coverage: per gyro axis the angle turned and the peak rate, and the fraction
  of the sphere of field directions visited (equal-area cells);
- the predicted one-sigma of every calibration parameter: the Fisher
  information of the joint problem at the initial estimate
  (`magyro.nls.solve.predicted_std`), laid out like the calibration's `std`;
- a verdict, "sufficient" | "marginal" | "insufficient", with the reason.

Times in the report are seconds from the session's first gyro sample
(`t_start_s` is that sample's `t`).
"""
from __future__ import annotations

import dataclasses
import json
import math
import re
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from magyro.front import ellipsoid
from magyro.nls.solve import Options, Prepared, moving_session, predicted_std, prepare
from magyro.errors import InputError, MagyroError, ObservabilityError
from magyro.observability.matrix import PARAMETER_NAMES, cumulative_information, trapezoid_weights
from magyro.observability.gate import FLOOR_FACTOR, ObservabilityAnalysis, cumulative_noise_matrix, directional_rank
from magyro.session import Session

SCHEMA = "magyro.observability/1"
CHECKPOINTS = 200                 # cumulative integral evaluated at this many times
WELL_CONDITIONED = 100.0          # "well conditioned": full rank and condition below this
PREDICTION_NODE_RATE_HZ = 20.0    # attitude nodes per second of the accuracy prediction (see docs)
SPHERE_BANDS = 12                 # equal-area grid: bands of equal height in z ...
SPHERE_SECTORS = 12               # ... times sectors of equal longitude
SPHERE_GRID = (f"{SPHERE_BANDS * SPHERE_SECTORS} equal-area cells: {SPHERE_BANDS} bands of equal height in z "
               f"(equal area, Archimedes) x {SPHERE_SECTORS} sectors of {360 // SPHERE_SECTORS} deg longitude, "
               "in the magnetometer frame")
AXES = "xyz"
UPPER_OFF_DIAGONAL = ((0, 1), (0, 2), (1, 2))
VERDICTS = ("sufficient", "marginal", "insufficient")


@dataclass(frozen=True)
class Targets:
    """One-sigma accuracy a calibration should reach; a predicted std above any of them is 'marginal'."""

    scale_factor_ppm: float = 1000.0        # diagonal of K_g
    non_orthogonality_deg: float = 0.1      # off-diagonal of K_g, as an angle
    bias_deg_s: float = 0.01
    misalignment_deg: float = 0.1


@dataclass
class Timeline:
    """The cumulative integral of M^T M at checkpoints through the session."""

    t_s: np.ndarray               # (C,) seconds from the first gyro sample
    eigenvalues: np.ndarray       # (C, 12) ascending, raw units
    signal_to_noise: np.ndarray   # (C, 12) ascending: each eigenvalue over what noise alone puts in its direction
    rank: np.ndarray              # (C,)
    condition: np.ndarray         # (C,) inf while singular


@dataclass
class Coverage:
    angle_turned_deg: np.ndarray    # (3,) integral of |w_i| dt per gyro axis
    peak_rate_deg_s: np.ndarray     # (3,) max |w_i|
    rate_reference: str             # how the bias was taken out of the rates
    cells_visited: int
    cells: int

    @property
    def sphere_fraction(self) -> float:
        return self.cells_visited / self.cells


@dataclass
class ObservabilityReport:
    """Everything `magyro observe` reports; `to_dict()` is the JSON, `table()` the terminal text."""

    source: str
    duration_s: float
    t_start_s: float
    gyro_samples: int
    mag_samples: int
    gyro_rate_hz: float
    mag_rate_hz: float
    analysis: ObservabilityAnalysis
    ellipsoid_fitted: bool
    ellipsoid_problem: str | None           # why it could not be fitted
    ellipsoid_rms_norm_error: float | None
    timeline: Timeline
    full_rank_at_s: float | None
    well_conditioned_at_s: float | None
    coverage: Coverage
    predicted_std: dict | None              # like Calibration.std (numpy, inf where unobservable), or None
    prediction: dict                        # how it was computed (stride, seconds, note)
    targets: Targets
    verdict: str
    reason: str
    weak_directions: list[str]
    advice: list[str]
    noise: dict
    analysed_span_s: list          # [start, end] the gate analyses (the rests at both ends trimmed)
    rests_s: list                  # rests found, [[start, end], ...]
    mag_unit: str
    # for the figure only (not in the JSON)
    t_mag_s: np.ndarray = field(repr=False, default=None)
    field_directions: np.ndarray = field(repr=False, default=None)   # (Nm, 3) unit
    t_gyro_s: np.ndarray = field(repr=False, default=None)
    rates_deg_s: np.ndarray = field(repr=False, default=None)        # (Ng, 3), bias taken out

    # ------------------------------------------------------------------ views
    @property
    def rank(self) -> int:
        return self.analysis.rank

    @property
    def condition(self) -> float:
        return self.analysis.condition

    @property
    def eigenvalues(self) -> np.ndarray:
        """Normalised (largest = 1), ascending."""
        return self.analysis.eigenvalues_normalised

    @property
    def exit_code(self) -> int:
        return 3 if self.verdict == "insufficient" else 0

    def to_dict(self) -> dict:
        a = self.analysis
        tl = self.timeline
        return {
            "schema": SCHEMA,
            "source": self.source,
            "verdict": self.verdict,
            "reason": self.reason,
            "rank": int(a.rank),
            "condition": _num(a.condition),
            "eigenvalues": _arr(a.eigenvalues_normalised),
            "largest_eigenvalue": _num(np.max(a.eigenvalues)),
            "parameters": list(PARAMETER_NAMES),
            "directions": directions_dict(a),
            "floor_factor": FLOOR_FACTOR,
            "full_rank_at_s": _num(self.full_rank_at_s),
            "well_conditioned_at_s": _num(self.well_conditioned_at_s),
            "well_conditioned_below": WELL_CONDITIONED,
            "weak_directions": list(self.weak_directions),
            "advice": list(self.advice),
            "coverage": {
                "axes": {AXES[i]: {"angle_turned_deg": _num(self.coverage.angle_turned_deg[i]),
                                   "peak_rate_deg_s": _num(self.coverage.peak_rate_deg_s[i])} for i in range(3)},
                "rate_reference": self.coverage.rate_reference,
                "sphere": {"fraction_visited": _num(self.coverage.sphere_fraction),
                           "cells_visited": int(self.coverage.cells_visited),
                           "cells": int(self.coverage.cells), "grid": SPHERE_GRID},
            },
            "predicted_std": _std_dict(self.predicted_std),
            "prediction": self.prediction,
            "targets": dataclasses.asdict(self.targets),
            "ellipsoid": {"fitted": self.ellipsoid_fitted, "problem": self.ellipsoid_problem,
                          "rms_norm_error": _num(self.ellipsoid_rms_norm_error)},
            "noise": self.noise,
            "session": {"duration_s": self.duration_s, "t_start_s": self.t_start_s,
                        "analysed_span_s": self.analysed_span_s, "rests_s": self.rests_s,
                        "gyro_samples": self.gyro_samples, "magnetometer_samples": self.mag_samples,
                        "gyro_rate_hz": self.gyro_rate_hz, "magnetometer_rate_hz": self.mag_rate_hz,
                        "magnetometer_unit": self.mag_unit},
            "timeline": {"t_s": _arr(tl.t_s), "rank": [int(r) for r in tl.rank], "condition": _arr(tl.condition),
                         "eigenvalues": _arr(tl.eigenvalues), "signal_to_noise": _arr(tl.signal_to_noise)},
        }

    def to_json(self) -> str:
        return json.dumps(self.to_dict(), indent=2, allow_nan=False)

    def table(self) -> str:
        """The report for people: verdict first, then why, then what to do."""
        a, c, t = self.analysis, self.coverage, self.targets
        out = [f"magyro observe: {self.source or 'session'} ({self.duration_s:.1f} s, gyro {self.gyro_rate_hz:.0f} Hz, "
               f"magnetometer {self.mag_rate_hz:.0f} Hz)",
               f"verdict: {self.verdict.upper()}: {self.reason}",
               "",
               f"observability (integral of M^T M, paper eq. 10-11): rank {a.rank} of 12, condition {_fmt(a.condition)}"]
        out.append("  eigenvalues / largest: " + " ".join(f"{v:.2g}" for v in a.eigenvalues_normalised))
        out.append(f"  full rank after:        {_when(self.full_rank_at_s)}")
        out.append(f"  well conditioned after: {_when(self.well_conditioned_at_s)} (condition < {WELL_CONDITIONED:g})")
        if self.weak_directions:
            out.append("weak directions:")
            out += [f"  - {w}" for w in self.weak_directions]
        if self.advice:
            out.append("to improve the recording:")
            out += [f"  - {w}" for w in self.advice]
        out.append("coverage (gyro axes, " + c.rate_reference + "):")
        out.append("  axis   angle turned (deg)   peak rate (deg/s)")
        for i in range(3):
            out.append(f"  {AXES[i]:>4}   {c.angle_turned_deg[i]:18.0f}   {c.peak_rate_deg_s[i]:17.1f}")
        out.append(f"  field directions: {100 * c.sphere_fraction:.0f}% of the sphere visited "
                   f"({c.cells_visited} of {c.cells} equal-area cells)")
        out.append("predicted one-sigma (Fisher information at the initial estimate) vs target:")
        if self.predicted_std is None:
            out.append("  not available: " + self.prediction.get("note", "the calibration is not determined"))
        else:
            for label, values, unit, target in accuracy_rows(self.predicted_std, t):
                cells = "  ".join(_fmt(v) for v in values)
                worst = np.max(values) if np.all(np.isfinite(values)) else np.inf
                mark = "ok" if worst <= target else "ABOVE TARGET"
                out.append(f"  {label:<32} {cells:<30} {unit:<6} target {target:g}  {mark}")
            s = self.predicted_std
            out.append(f"  {'magnetometer h (' + self.mag_unit + ')':<32} " + "  ".join(_fmt(v) for v in s["h"]))
            out.append(f"  {'magnetometer R diagonal':<32} " + "  ".join(_fmt(s['R'][i][i]) for i in range(3)))
        return "\n".join(out)


# --------------------------------------------------------------------------- the report


def observe(session: Session, options: Options | None = None, targets: Targets | None = None,
            checkpoints: int = CHECKPOINTS) -> ObservabilityReport:
    """The excitation-sufficiency report of one session (no solve).

    `options` gives the noise levels (None: estimated from the data), the rest
    trimming of `magyro solve`, and, as `stride`, the node stride of the
    accuracy prediction (None: nodes at `PREDICTION_NODE_RATE_HZ`). Raises
    InputError for unusable input.
    """
    options = options or Options()
    targets = targets or Targets()
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
        cloud = err.__context__ if isinstance(err.__context__, ellipsoid.DegenerateCloud) else None
        problem = str(cloud) if cloud is not None else str(err).split(";")[0]
        field_m = ellipsoid.surrogate_field_directions(s.mag)
        mag_std_unit_field = levels.mag_sample_std / float(np.mean(np.linalg.norm(s.mag, axis=1)))

    tl = timeline(s, field_m, levels.gyro_sample_std_rad_s, mag_std_unit_field, checkpoints, t0)
    full_rank_at = first_time(tl.t_s, tl.rank == 12)
    well_at = first_time(tl.t_s, (tl.rank == 12) & (tl.condition < WELL_CONDITIONED))

    rates, reference = bias_free_rates(s, prep, analysis)
    cov = coverage(s.t_gyro_s, rates, field_m, reference)

    std, prediction = predict(prep, analysis, options)
    verdict, reason = judge(analysis, problem, std, targets)
    weak, advice = weak_directions(analysis, verdict=verdict)
    if problem is not None and not any("all three" in a for a in advice):
        advice = ["Turn the device through large angles about all three of its axes, so that the field sweeps "
                  "the sphere (the magnetometer's soft/hard iron needs it)."] + advice
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
        analysed_span_s=[float(s.t_gyro_s[0] - t0), float(s.t_gyro_s[-1] - t0)],
        rests_s=[[float(a - t0), float(b - t0)] for a, b in found.segments_s],
        mag_unit=session.mag_unit, t_mag_s=s.t_mag_s - t0, field_directions=_unit(field_m),
        t_gyro_s=s.t_gyro_s - t0, rates_deg_s=np.rad2deg(rates),
    )


def gate_inputs(session: Session, options: Options):
    """(session as the gate analyses it, per-sample noise levels, rests), exactly as prepare() makes them,
    for the cumulative integral to follow the gate."""
    return moving_session(session, options)


def timeline(session: Session, field_m, gyro_sample_std: float, mag_std_unit_field: float,
             checkpoints: int = CHECKPOINTS, t0_s: float | None = None) -> Timeline:
    """Rank and condition of the cumulative integral at `checkpoints` times, by the gate's rule.

    Each checkpoint is judged like `observability.analyse` judges a whole session: an
    eigen-direction v of the integral so far counts when its eigenvalue exceeds
    FLOOR_FACTOR times v^T N v, N the noise matrix of the same stretch of session (it grows
    with the integral). The last checkpoint therefore reproduces the gate's rank.
    Times are seconds from `t0_s` (default: the first gyro sample).
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
    return Timeline(tc - (t[0] if t0_s is None else t0_s), lam, snr, rank, cond)


def first_time(t_s: np.ndarray, reached: np.ndarray) -> float | None:
    hit = np.flatnonzero(reached)
    return float(t_s[hit[0]]) if hit.size else None


def bias_free_rates(session: Session, prep: Prepared | None, analysis: ObservabilityAnalysis):
    """Gyro rates (rad/s, per gyro axis) with the bias taken out, and how.

    Full rank: corrected by the linear initial estimate (paper eq. 13), w_b = K_g0 y + eps_b0.
    Otherwise the per-axis median reading is taken as the bias (right for still axes,
    which is what matters when axes are missing).
    """
    y = session.gyro_rad_s
    if prep is not None and analysis.full_rank:
        from magyro.front.initial import linear_gyro_estimate
        from magyro.result.calibration import qr_split

        lin = linear_gyro_estimate(session.t_gyro_s, y, session.t_mag_s, prep.field_m)
        try:
            C, Kg = qr_split(lin.K)
        except InputError:
            pass
        else:
            return y @ Kg.T + C.T @ lin.eps, "corrected by the initial estimate of K_g and bias"
    return y - np.median(y, axis=0), "readings minus their median (taken as the bias)"


def sphere_cell(directions: np.ndarray, bands: int = SPHERE_BANDS, sectors: int = SPHERE_SECTORS) -> np.ndarray:
    """Index of the equal-area cell of each unit vector (N, 3): band of equal height in z, sector of longitude."""
    u = _unit(directions)
    band = np.clip(np.floor((u[:, 2] + 1.0) / 2.0 * bands), 0, bands - 1).astype(int)
    lon = np.arctan2(u[:, 1], u[:, 0])
    sector = np.clip(np.floor((lon + np.pi) / (2 * np.pi) * sectors), 0, sectors - 1).astype(int)
    return band * sectors + sector


def coverage(t_gyro_s, rates_rad_s, field_m, rate_reference: str) -> Coverage:
    w = trapezoid_weights(t_gyro_s)
    angle = np.rad2deg(np.abs(rates_rad_s).T @ w)
    peak = np.rad2deg(np.max(np.abs(rates_rad_s), axis=0))
    cells = np.unique(sphere_cell(field_m))
    return Coverage(angle, peak, rate_reference, int(cells.size), SPHERE_BANDS * SPHERE_SECTORS)


def prediction_stride(session: Session, options: Options) -> int:
    return int(options.stride or max(1, round(session.mag_rate_hz / PREDICTION_NODE_RATE_HZ)))


def predict(prep: Prepared | None, analysis: ObservabilityAnalysis, options: Options) -> tuple[dict | None, dict]:
    """`calibrate.predicted_std` on a coarser node grid (see docs/observability.md), or None."""
    if prep is None:
        return None, {"note": "the magnetometer's soft/hard iron cannot be fitted, so no calibration is determined"}
    stride = prediction_stride(prep.session, options)
    start = time.perf_counter()
    try:
        std = predicted_std(prep, dataclasses.replace(options, stride=stride))
    except (MagyroError, np.linalg.LinAlgError) as e:
        if analysis.full_rank:
            raise
        return None, {"stride": stride, "note": f"no prediction for a rank-deficient session ({e})"}
    info = {"stride": stride, "seconds": time.perf_counter() - start,
            "method": "Gauss-Newton information of the joint problem at the initial estimate, trajectory "
                      "marginalised, noise levels of the session"}
    if not all(np.all(np.isfinite(v)) for v in std.values()):
        info["note"] = "the information is singular: null marks what this recording cannot determine"
    return std, info


def accuracy_rows(std: dict, targets: Targets) -> list[tuple[str, np.ndarray, str, float]]:
    """(label, predicted one-sigma values, unit, target) for each target of the verdict."""
    K = np.asarray(std["K_g"], dtype=float)
    return [
        ("scale factor (K_g diagonal)", 1e6 * np.diag(K), "ppm", targets.scale_factor_ppm),
        ("non-orthogonality (K_g upper)", np.rad2deg([K[i, j] for i, j in UPPER_OFF_DIAGONAL]), "deg",
         targets.non_orthogonality_deg),
        ("gyro bias", np.asarray(std["bias_deg_s"], dtype=float), "deg/s", targets.bias_deg_s),
        ("misalignment (roll pitch yaw)", np.asarray(std["misalignment_deg"], dtype=float), "deg",
         targets.misalignment_deg),
    ]


def judge(analysis: ObservabilityAnalysis, ellipsoid_problem: str | None, std: dict | None,
          targets: Targets) -> tuple[str, str]:
    """The verdict and its reason in plain words."""
    if ellipsoid_problem is not None:
        return "insufficient", (f"{ellipsoid_problem}, so the magnetometer's soft/hard iron cannot be fitted; "
                                f"the motion excites {analysis.rank} of the 12 gyro parameters")
    if not analysis.full_rank:
        return "insufficient", (f"the motion excites only {analysis.rank} of the 12 gyro parameters "
                                f"(rank of the integral of M^T M above the noise floor)")
    if std is None:
        return "marginal", "all 12 gyro parameters are excited, but their accuracy could not be predicted"
    above, worst = [], []
    for label, values, unit, target in accuracy_rows(std, targets):
        v = float(np.max(values)) if np.all(np.isfinite(values)) else math.inf
        worst.append((v / target, label, v, unit, target))
        if not v <= target:
            above.append(f"{label} {_fmt(v)} {unit} (target {target:g})")
    if above:
        return "marginal", ("all 12 gyro parameters are excited, but the predicted one-sigma is above target for "
                            + "; ".join(above) + ": record longer or with larger, faster turns")
    ratio, label, v, unit, target = max(worst)
    return "sufficient", (f"all 12 gyro parameters are excited and every predicted one-sigma is within its "
                          f"target (closest: {label} {_fmt(v)} {unit} of {target:g})")


# --------------------------------------------------------------------------- weak directions in words


def describe_direction(v: np.ndarray, at_least: float = 0.05, most: int = 4) -> str:
    """A unit 12-vector over [vec K; eps] as its largest components, e.g. '0.71 K13 - 0.52 eps_z'."""
    v = np.asarray(v, dtype=float)
    order = np.argsort(-np.abs(v))
    v = v * np.sign(v[order[0]])
    keep = [i for i in order[:most] if v[i] ** 2 >= at_least] or [order[0]]
    text = ""
    for n, i in enumerate(keep):
        sign = "-" if v[i] < 0 else ("+" if n else "")
        text += (f" {sign} " if n else sign) + f"{abs(v[i]):.2f} {PARAMETER_NAMES[i]}"
    return text.strip()


def direction_advice(v: np.ndarray) -> str:
    """The motion that excites a direction of [vec K; eps]: turn about the gyro axes whose column of K it holds."""
    share = np.array([np.sum(v[3 * j: 3 * j + 3] ** 2) for j in range(3)] + [np.sum(v[9:] ** 2)])
    parts = []
    axes = [AXES[j] for j in range(3) if share[j] >= 0.2]
    if axes:
        one = len(axes) == 1
        parts.append("turn more about the gyro " + " and ".join(axes) + (" axis" if one else " axes")
                     + " (larger angles, varied rates), with the field not along " + ("it" if one else "them"))
    if share[3] >= 0.2:
        parts.append("vary the rotation rate (turn back and forth, start and stop) so the bias separates "
                     "from the scale factors")
    return "; ".join(parts) or "turn about all three axes with varied rates"


def weak_directions(analysis: ObservabilityAnalysis, most: int = 3, verdict: str = "") -> tuple[list[str], list[str]]:
    """(weak directions, advice) in plain words.

    Rank deficient: the share of each gyro axis's response and of the bias that is
    unobservable, the unobservable direction itself when there is just one, and the
    gate's motion advice. Full rank: the `most` weakest eigen-directions of the integral (by
    signal to noise, as the gate ranks them) in parameter names, with the motion that
    excites the weakest when it is poorly excited or the verdict is marginal.
    """
    a = analysis
    snr = _snr(a)
    order = np.argsort(snr, kind="stable")   # weakest first (the analysis already keeps them so)
    V, lam, snr = a.eigenvectors[:, order], a.eigenvalues[order], snr[order]
    top = float(np.max(a.eigenvalues))
    if not a.full_rank:
        weak = [f"unobservable: {w}" for w in a.weak_directions]
        if 12 - a.rank == 1:  # a single null direction is unique (up to sign): name it
            weak.append(f"unobservable direction: {describe_direction(V[:, 0])}")
        return weak, list(a.advice)
    weak, advice = [], []
    for k in range(min(most, 12)):
        weak.append(f"{describe_direction(V[:, k])} (eigenvalue {lam[k] / top:.2g} of the largest, "
                    f"{snr[k]:.3g} x its noise floor)")
    if lam[0] / top < 1.0 / WELL_CONDITIONED or snr[0] < 10 * FLOOR_FACTOR:
        advice.append(f"The weakest direction is poorly excited: {direction_advice(V[:, 0])}.")
    elif verdict == "marginal":
        advice.append(f"To sharpen the weakest direction ({describe_direction(V[:, 0])}): {direction_advice(V[:, 0])}; "
                      "recording longer with the same motion also helps (the std falls as 1/sqrt(duration)).")
    return weak, advice


def directions_dict(a: ObservabilityAnalysis) -> list[dict]:
    """Every eigen-direction of the integral, weakest (signal to noise) first: what the gate counts."""
    snr = _snr(a)
    order = np.argsort(snr, kind="stable")
    top = float(np.max(a.eigenvalues))
    return [{"eigenvalue": _num(a.eigenvalues[k] / top), "signal_to_noise": _num(snr[k]),
             "excited": bool(i >= 12 - a.rank), "vector": _arr(a.eigenvectors[:, k]),
             "in_words": describe_direction(a.eigenvectors[:, k])} for i, k in enumerate(order)]


def _snr(a: ObservabilityAnalysis) -> np.ndarray:
    """Signal to noise per eigen-direction of the analysis (eigenvalue over its noise floor), analysis order."""
    snr = getattr(a, "signal_to_noise", None)
    if snr is None:
        return np.asarray(a.eigenvalues, dtype=float) / max(a.noise_floor, 1e-300)
    return np.asarray(snr, dtype=float)


# --------------------------------------------------------------------------- the figure


def require_matplotlib():
    try:
        import matplotlib  # noqa: F401
        from matplotlib.figure import Figure
    except ImportError:
        raise InputError("--plot needs matplotlib, which is not installed: pip install 'magyro[plot]'") from None
    return Figure


def plot_report(report: ObservabilityReport, path) -> None:
    """The figure: field-direction coverage, eigenvalue growth, signal to noise, rates per axis. Written atomically."""
    Figure = require_matplotlib()
    from magyro.io.sessions import write_atomically

    path = Path(path)
    fmt = path.suffix.lstrip(".").lower() or "png"
    fig = Figure(figsize=(13, 9.5), layout="constrained")
    grid = fig.add_gridspec(3, 2, height_ratios=[1.1, 1.0, 0.9])
    ax_sphere = fig.add_subplot(grid[0, 0])
    ax_eig = fig.add_subplot(grid[0, 1])
    ax_snr = fig.add_subplot(grid[1, 1], sharex=ax_eig)
    ax_text = fig.add_subplot(grid[1, 0])
    ax_rate = fig.add_subplot(grid[2, :])
    fig.suptitle(f"magyro observe: {Path(report.source).name or 'session'}: {report.verdict.upper()} "
                 f"(rank {report.rank} of 12, condition {_fmt(report.condition)})")
    c = report.coverage

    # field directions, Lambert cylindrical equal-area projection: the grid cells are equal rectangles
    u = report.field_directions
    lon = np.rad2deg(np.arctan2(u[:, 1], u[:, 0]))
    cells = np.zeros(SPHERE_BANDS * SPHERE_SECTORS)
    np.add.at(cells, sphere_cell(u), 1.0)
    visited = (cells > 0).reshape(SPHERE_BANDS, SPHERE_SECTORS).astype(float)
    ax_sphere.imshow(visited, origin="lower", extent=(-180, 180, -1, 1), aspect="auto", cmap="Greens",
                     vmin=0, vmax=2.5, interpolation="nearest")
    points = ax_sphere.scatter(lon, u[:, 2], s=1, c=report.t_mag_s, cmap="viridis")
    fig.colorbar(points, ax=ax_sphere, label="time (s)", fraction=0.04, pad=0.01)
    for z in np.linspace(-1, 1, SPHERE_BANDS + 1):
        ax_sphere.axhline(z, color="0.8", lw=0.5)
    for x in np.linspace(-180, 180, SPHERE_SECTORS + 1):
        ax_sphere.axvline(x, color="0.8", lw=0.5)
    ax_sphere.set_xlim(-180, 180)
    ax_sphere.set_ylim(-1, 1)
    ax_sphere.set_xlabel("longitude of the field direction, magnetometer frame (deg)")
    ax_sphere.set_ylabel("z of the unit field (= sin latitude)")
    ax_sphere.set_title(f"field directions: {100 * c.sphere_fraction:.0f}% of the sphere "
                        f"({c.cells_visited}/{c.cells} equal-area cells)", fontsize=10)

    # eigenvalue growth of the cumulative integral, and each eigenvalue against its noise floor
    tl = report.timeline
    lam = np.where(tl.eigenvalues > 0, tl.eigenvalues, np.nan)
    snr = np.where(tl.signal_to_noise > 0, tl.signal_to_noise, np.nan)
    for k in range(12):
        ax_eig.plot(tl.t_s, lam[:, k], lw=1, color=_palette(k))
        ax_snr.plot(tl.t_s, snr[:, k], lw=1, color=_palette(k))
    ax_snr.axhline(FLOOR_FACTOR, color="k", ls="--", lw=1.2, label=f"counted above {FLOOR_FACTOR:g} x noise")
    for ax in (ax_eig, ax_snr):
        for t_mark, label, style in ((report.full_rank_at_s, "full rank", "-"),
                                     (report.well_conditioned_at_s, "well conditioned", ":")):
            if t_mark is not None:
                ax.axvline(t_mark, color="tab:red", ls=style, lw=1, label=f"{label} at {t_mark:.1f} s")
        ax.set_yscale("log")
    ax_eig.set_ylabel("eigenvalues")
    ax_eig.set_title("eigenvalue growth of the integral of M^T M", fontsize=10)
    if ax_eig.get_legend_handles_labels()[0]:
        ax_eig.legend(loc="lower right", fontsize=8)
    ax_snr.set_xlabel("time (s)")
    ax_snr.set_ylabel("eigenvalue / noise floor")
    ax_snr.set_title("eigenvalue / its noise floor (counted in the rank above the line)", fontsize=10)
    ax_snr.legend(loc="lower right", fontsize=8)

    ax_text.axis("off")
    lines = [f"verdict: {report.verdict}", *_wrap(report.reason, 80), ""]
    lines += ["weakest directions:"] + [f"  {w}" for d in report.weak_directions[:4] for w in _wrap(d, 78)]
    if report.advice:
        lines += ["", "advice:"] + [f"  {w}" for a in report.advice[:3] for w in _wrap(a, 78)]
    ax_text.text(0.0, 1.0, "\n".join(lines), va="top", ha="left", family="monospace", fontsize=7.5,
                 transform=ax_text.transAxes)

    for i in range(3):
        ax_rate.plot(report.t_gyro_s, report.rates_deg_s[:, i], lw=0.7,
                     label=f"gyro {AXES[i]}: turned {c.angle_turned_deg[i]:.0f} deg, peak {c.peak_rate_deg_s[i]:.0f} deg/s")
    ax_rate.set_xlabel("time (s)")
    ax_rate.set_ylabel("rate (deg/s)")
    ax_rate.set_title(f"rates per gyro axis ({c.rate_reference})", fontsize=10)
    ax_rate.legend(loc="upper right", fontsize=8)
    write_atomically(path, lambda tmp: fig.savefig(tmp, format=fmt, dpi=100))


def _wrap(text: str, width: int) -> list[str]:
    import textwrap

    return textwrap.wrap(text, width) or [""]


def _palette(k: int):
    import matplotlib

    return matplotlib.colormaps["viridis"](k / 11.0)


# --------------------------------------------------------------------------- the canonical table (docs)

CANONICAL = (  # problem, motion, rank the theorem predicts (docs/observability.md derives it)
    ("static", "none", 2),
    ("axis-x", "about gyro x only", 6),
    ("axis-y", "about gyro y only", 6),
    ("axis-z", "about gyro z only", 6),
    ("two-axes", "x, then y", 9),
    ("three-axes", "x, then y, then z", 12),
    ("paper-table1", "x, y, z at once (Table I)", 12),
)
TABLE_START = "<!-- table:canonical:start -->"
TABLE_END = "<!-- table:canonical:end -->"


def canonical_reports(seed: int = 0) -> dict[str, ObservabilityReport]:
    """observe() on every canonical problem of problems/, simulated with `seed`."""
    from magyro.studies.simulate import load_problem, simulate

    return {name: observe(simulate(load_problem(name), seed)[0]) for name, _, _ in CANONICAL}


def canonical_table(seed: int = 0, reports: dict | None = None) -> str:
    """The rank/condition table of the canonical problems as the tool reports them (3 significant digits)."""
    reports = reports or canonical_reports(seed)
    lines = ["| problem | motion | rank (theorem) | rank (magyro) | condition | full rank at (s) | sphere visited | verdict |",
             "|---|---|---:|---:|---:|---:|---:|---|"]
    for name, motion, theorem in CANONICAL:
        r = reports[name]
        lines.append(f"| {name} | {motion} | {theorem} | {r.rank} | {_fmt(r.condition)} | "
                     f"{'never' if r.full_rank_at_s is None else _fmt(r.full_rank_at_s)} | "
                     f"{100 * r.coverage.sphere_fraction:.0f}% | {r.verdict} |")
    return "\n".join(lines)


def table_in_page(text: str) -> str:
    """The text between the canonical-table markers of a page."""
    m = re.search(re.escape(TABLE_START) + r"\n(.*?)\n" + re.escape(TABLE_END), text, flags=re.S)
    if not m:
        raise ValueError(f"no {TABLE_START} ... {TABLE_END} block in the page")
    return m.group(1)


def update_page(path, table: str) -> None:
    """Replace the canonical table of a page (docs/observability.md) with `table`."""
    path = Path(path)
    text = path.read_text(encoding="utf-8")
    old = table_in_page(text)
    path.write_text(text.replace(f"{TABLE_START}\n{old}\n{TABLE_END}", f"{TABLE_START}\n{table}\n{TABLE_END}"),
                    encoding="utf-8")


# --------------------------------------------------------------------------- formatting


def _num(x):
    """A JSON number, or None for missing / inf / NaN."""
    if x is None:
        return None
    x = float(x)
    return x if math.isfinite(x) else None


def _arr(a):
    a = np.asarray(a, dtype=float)
    if a.ndim == 0:
        return _num(a)
    return [_arr(v) for v in a]


def _std_dict(std: dict | None) -> dict:
    """The predicted std as JSON, laid out like the calibration file's `std`; null where not finite."""
    keys = ("K_g", "bias_deg_s", "misalignment_deg", "R", "h", "K", "field_i")
    if std is None:
        shapes = {"K_g": (3, 3), "R": (3, 3), "K": (3, 3)}
        return {k: _arr(np.full(shapes.get(k, (3,)), np.nan)) for k in keys}
    return {k: _arr(std[k]) for k in (*keys, *(k for k in std if k not in keys))}


def _fmt(x) -> str:
    if x is None:
        return "-"
    x = float(x)
    if not math.isfinite(x):
        return "inf"
    return f"{x:.3g}"


def _when(t) -> str:
    return "never (within this session)" if t is None else f"{t:.1f} s"


def _unit(v: np.ndarray) -> np.ndarray:
    v = np.asarray(v, dtype=float)
    n = np.linalg.norm(v, axis=1, keepdims=True)
    return v / np.where(n > 0, n, 1.0)


if __name__ == "__main__":  # python -m magyro.observe [docs/observability.md]: regenerate the docs table
    import sys

    page = Path(sys.argv[1]) if len(sys.argv) > 1 else Path(__file__).resolve().parent.parent / "docs" / "observability.md"
    new = canonical_table()
    print(new)
    if page.exists():
        update_page(page, new)
        print(f"updated {page}")
