"""`magyro noise`: the gyro's and the accelerometer's noise from the Allan deviation of a still recording (issue 41).

What Kalibr (and most filters) need are four numbers per IMU: the white noise density and the bias random walk of
the gyro and of the accelerometer. People read them off a log-log plot by hand; this module reads them the usual way
(IEEE Std 952-1997, Annex C): the Allan variance of a still sensor is the sum of its noise terms,

    avar(tau) = N^2 / tau  +  (0.664 B)^2  +  K^2 tau / 3

the -1/2 slope of the white noise (N, the density: ARW in rad/s/sqrt(Hz), VRW in m/s^2/sqrt(Hz); the -1/2 line's
value at tau = 1 s), the flat floor of the bias instability (B, the minimum over 0.664 = sqrt(2 ln 2 / pi)) and the
+1/2 slope of the rate random walk (K, the +1/2 line's value at tau = 3 s). The three are fitted at once, a weighted
non-negative least squares of avar on (1/tau, 1, tau) over the taus from 0.1 s (FIT_FROM_S: shorter ones show the
sensor's filter, quantisation or vibration, not its -1/2 slope) with at least MIN_CLUSTERS clusters, each tau
weighted by its Allan variance's relative error 2/sqrt(2 (n/m - 1)) (n samples, m per cluster): a term read
separately from each slope is biased by the others where they bend the curve.

Each term's std is the Allan deviation's relative error ~ 1/sqrt(2 (n/m - 1)) at the tau that term is read at (where
it is the largest part of the curve): the white noise at the shortest taus, the bias instability at the minimum, the
random walk at the longest tau; or the fit's own std, widened for the overlapping taus, when larger. The bias
instability and the random walk are said only when the curve shows its minimum: the fitted one (where the -1/2 and
+1/2 terms meet) at least PAST_MINIMUM_FACTOR inside the longest tau with MIN_CLUSTERS clusters; without, the -1/2
line alone gives the white noise, and `RecordingTooShort` (exit 3: the input is good, it just does not hold the
answer, as a motion that does not excite a parameter) says how long a still recording would.

The still stretches: the rests at both ends (`magyro.front.rests.find_rests`; a still recording is one long rest),
or the whole recording with `whole=True` (`magyro noise --still`, for a recording you know is still throughout).
Each stretch's overlapping Allan variance (allantools.oadev) at a tau counts by its number of terms; the file says
which stretches were used.

The noise file (schema magyro.noise/1, unit-tagged keys) is written whole or not at all; magyro.noise_file reads it
back (refusing what it does not know) for solve --noise and export --noise.
"""
from __future__ import annotations

import json
import math
from dataclasses import dataclass, field

import numpy as np

from magyro.errors import InputError, ObservabilityError

SCHEMA = "magyro.noise/1"
NOISE_INSTALL = "pip install 'magyro[noise]', or pip install '.[noise]' in a clone of magyro"
MIN_CLUSTERS = 9                 # a tau is used only with at least this many clusters (n/m)
FLICKER_FLOOR = math.sqrt(2.0 * math.log(2.0) / math.pi)    # 0.664: adev of flicker (bias instability) over B
TAUS_PER_DECADE = 10
# overlapping Allan variances at taus closer than a factor 2 are nearly the same number: the fit's covariance,
# which counts every tau as independent, is widened by the taus per octave
TAUS_PER_OCTAVE = TAUS_PER_DECADE * math.log10(2.0)
WHITE_READ_AT_S = 1.0            # the -1/2 line read at tau = 1 s (= N)
WALK_READ_AT_S = 3.0             # the +1/2 line read at tau = 3 s (= K)
# the shortest taus are left out of the fit: there a sensor's filter, its quantisation or a vibration bends the
# curve off the -1/2 slope (BROAD's gyro at rest: a 24 Hz oscillation lifts tau = 0.02 s's deviation 4x above the
# line through 0.1-0.5 s; the least squares is weighted by the low-frequency density, which the line gives)
FIT_FROM_S = 0.1
MIN_STILL_S = 1.0                # less still time than this: not even the white noise
PAST_MINIMUM_FACTOR = 3.0       # the random walk is read when the longest usable tau is this far past the minimum
SENSORS = {"gyro": ("rad_s", "rad_s2"), "acc": ("m_s2", "m_s3")}


class RecordingTooShort(ObservabilityError):
    """The still recording holds too few clusters to read a term (exit 3): the message says how long is needed."""


def require_allantools():
    """allantools, or InputError naming the extra (call before any work)."""
    try:
        import allantools
    except ImportError:
        raise InputError(f"magyro noise needs allantools, which is not installed: {NOISE_INSTALL}") from None
    return allantools


# --------------------------------------------------------------------------- the Allan deviation


@dataclass(frozen=True)
class AllanCurve:
    """The overlapping Allan variance over the still stretches, per axis: taus, avar (n_tau, 3), clusters (n/m)."""

    taus_s: np.ndarray
    avar: np.ndarray
    clusters: np.ndarray

    @property
    def adev(self) -> np.ndarray:
        return np.sqrt(self.avar)


def cluster_taus_s(rate_hz: float, longest_n: int) -> np.ndarray:
    """Log-spaced cluster lengths (whole samples) from 1 sample to the longest with MIN_CLUSTERS clusters."""
    max_m = longest_n // MIN_CLUSTERS
    if max_m < 1:
        return np.zeros(0)
    m = np.unique(np.round(np.logspace(0, math.log10(max_m), int(TAUS_PER_DECADE * math.log10(max_m)) + 2)))
    return m.astype(int) / rate_hz


def allan_curve(stretches: list[np.ndarray], rate_hz: float, name: str = "signal") -> AllanCurve:
    """The overlapping Allan variance of (n, 3) still stretches sampled at rate_hz, combined by their terms."""
    from magyro.progress import step

    allantools = require_allantools()
    n_total = sum(len(s) for s in stretches)
    m_all = np.round(cluster_taus_s(rate_hz, n_total) * rate_hz).astype(int)
    weighted = np.zeros((len(m_all), 3))
    terms = np.zeros(len(m_all))
    clusters = np.zeros(len(m_all))
    for k, x in enumerate(stretches):
        n = len(x)
        usable = (m_all >= 1) & (n >= 2 * m_all + 1)
        if not usable.any():
            continue
        ms = m_all[usable]
        for axis in range(3):
            step(f"Allan deviation of the {name}, stretch {k + 1} of {len(stretches)}, axis {'xyz'[axis]}")
            taus, ad, _, ns = allantools.oadev(np.asarray(x[:, axis], dtype=float), rate=rate_hz,
                                               data_type="freq", taus=ms / rate_hz)
            got = np.round(np.asarray(taus) * rate_hz).astype(int)
            rows = np.searchsorted(m_all, got)
            weighted[rows, axis] += np.asarray(ns) * np.asarray(ad) ** 2
            if axis == 0:
                terms[rows] += np.asarray(ns)
                clusters[rows] += n // got
    kept = clusters >= MIN_CLUSTERS
    return AllanCurve(m_all[kept] / rate_hz, weighted[kept] / terms[kept, None], clusters[kept])


def relative_adev_error(clusters) -> np.ndarray:
    """The Allan deviation's relative error with n/m clusters: 1/sqrt(2 (n/m - 1))."""
    return 1.0 / np.sqrt(2.0 * (np.asarray(clusters, dtype=float) - 1.0))


# --------------------------------------------------------------------------- the usual reading


@dataclass(frozen=True)
class AxisReading:
    """The three terms of one axis (None: the curve does not show it), each with its std, and why not."""

    white: float                  # N, unit/sqrt(Hz)  (rad/s/sqrt(Hz) = rad/sqrt(s), m/s^2/sqrt(Hz))
    white_std: float
    bias_instability: float | None
    bias_instability_std: float | None
    random_walk: float | None     # K, unit/s/sqrt(Hz)
    random_walk_std: float | None
    minimum_tau_s: float
    longest_tau_s: float
    why_not: dict = field(default_factory=dict)


def fit_terms(taus_s: np.ndarray, avar: np.ndarray, clusters: np.ndarray, terms=(True, True, True)
              ) -> tuple[np.ndarray, np.ndarray]:
    """((N^2, (0.664 B)^2, K^2/3), their stds): non-negative least squares of avar on (1/tau, 1, tau) (the `terms`
    kept; the others 0), each row over its std (the avar's relative error, 2/sqrt(2 (n/m - 1)), times the fitted
    avar: a second pass). The stds are the fit's, widened by TAUS_PER_OCTAVE (`read_axis` takes the larger of
    these and the clusters' error at the tau a term is read at)."""
    from scipy.optimize import nnls

    rel_var_error = 2.0 * relative_adev_error(clusters)          # avar's relative error is twice adev's
    kept = np.flatnonzero(terms)
    design = np.column_stack([1.0 / taus_s, np.ones_like(taus_s), taus_s])[:, kept]
    level = avar
    for _ in range(2):
        A = design / (level * rel_var_error)[:, None]
        scale = np.abs(A).max(axis=0)
        coef, _ = nnls(A / scale, avar / (level * rel_var_error))
        coef = coef / scale
        level = np.maximum(design @ coef, 1e-300)
    A = design / (level * rel_var_error)[:, None]
    scale = np.abs(A).max(axis=0)
    cov = np.linalg.pinv((A / scale).T @ (A / scale)) / np.outer(scale, scale)
    full, full_std = np.zeros(3), np.zeros(3)
    full[kept], full_std[kept] = coef, np.sqrt(np.maximum(np.diag(cov), 0.0) * TAUS_PER_OCTAVE)
    return full, full_std


def root_std(c: float, c_std: float) -> float:
    """The std of sqrt(c) from c's: c_std / (2 sqrt(c))."""
    return c_std / (2.0 * math.sqrt(c)) if c > 0 else math.inf


def fitted_from_s(taus_s: np.ndarray) -> float:
    """The shortest tau fitted: FIT_FROM_S, or a fifth of the longest tau when that is shorter (a short rest)."""
    return min(FIT_FROM_S, float(taus_s[-1]) / 5.0)


def read_axis(curve: AllanCurve, axis: int) -> AxisReading:
    """The usual reading of one axis's curve (module docstring), from tau = fitted_from_s on."""
    kept = curve.taus_s >= fitted_from_s(curve.taus_s) * (1.0 - 1e-9)
    taus, avar, clusters = curve.taus_s[kept], curve.avar[kept, axis], curve.clusters[kept]
    (white_c, flat_c, walk_c), (white_c_std, flat_c_std, walk_c_std) = fit_terms(taus, avar, clusters)
    rel = relative_adev_error(clusters)
    i_min = int(np.argmin(avar))
    why = {}
    bias = bias_std = walk = walk_std = None
    # the fitted curve's minimum (the -1/2 and +1/2 terms equal) at least PAST_MINIMUM_FACTOR inside the longest tau
    past_minimum = walk_c > 0 and white_c > 0 and PAST_MINIMUM_FACTOR * math.sqrt(white_c / walk_c) <= taus[-1]
    if not past_minimum:      # the curve shows no minimum: the -1/2 line alone (a short rest)
        (white_c, _, _), (white_c_std, _, _) = fit_terms(taus, avar, clusters, (True, False, False))
    # the -1/2 line N^2/tau read at tau = 1 s is N (without a white term: the first point's level)
    white = math.sqrt((white_c if white_c > 0 else avar[0] * taus[0]) / WHITE_READ_AT_S)
    white_std = max(white * float(rel[0]), root_std(white_c, white_c_std))
    if past_minimum and flat_c > 0:
        bias = math.sqrt(flat_c) / FLICKER_FLOOR
        bias_std = max(bias * float(rel[i_min]), root_std(flat_c, flat_c_std) / FLICKER_FLOOR)
    else:
        why["bias_instability"] = "the curve has no minimum inside the taus with enough clusters"
    walk_term_last = walk_c * taus[-1]
    if past_minimum and walk_c > 0 and walk_term_last > white_c / taus[-1] + flat_c:
        walk = math.sqrt(walk_c * WALK_READ_AT_S)      # the +1/2 line K^2 tau / 3 read at tau = 3 s is K
        walk_std = max(walk * float(rel[-1]), math.sqrt(WALK_READ_AT_S) * root_std(walk_c, walk_c_std))
    else:
        why["random_walk"] = "the curve does not rise on the +1/2 slope at the longest taus"
    return AxisReading(white, white_std, bias, bias_std, walk, walk_std, float(taus[i_min]), float(taus[-1]), why)


def needed_still_s(curve: AllanCurve, duration_s: float) -> float:
    """How long a still recording must be for the random walk: its +1/2 slope needs tau well past the minimum (10x)
    with MIN_CLUSTERS clusters, and at least an hour (the usual advice: 2 h)."""
    tau_min = float(curve.taus_s[np.argmin(curve.avar.mean(axis=1))]) if len(curve.taus_s) else duration_s
    return max(3600.0, 10.0 * tau_min * MIN_CLUSTERS, 2.0 * duration_s)


# --------------------------------------------------------------------------- a session's noise


@dataclass(frozen=True)
class NoiseReport:
    rate_hz: float
    duration_s: float
    stretches_how: str
    stretches_s: list
    sensors: dict                 # "gyro"/"acc" -> [AxisReading] * 3
    curves: dict                  # "gyro"/"acc" -> AllanCurve

    def to_dict(self) -> dict:
        out = {"schema": SCHEMA, "rate_hz": self.rate_hz, "duration_s": self.duration_s,
               "still_s": float(sum(b - a for a, b in self.stretches_s)),
               "stretches": {"how": self.stretches_how, "segments_s": [[float(a), float(b)] for a, b in self.stretches_s]}}
        for name, readings in self.sensors.items():
            unit, walk_unit = SENSORS[name]
            for term, key_unit, attr in (("white", f"{unit}_sqrt_hz", "white"),
                                         ("bias_instability", unit, "bias_instability"),
                                         ("random_walk", f"{walk_unit}_sqrt_hz", "random_walk")):
                values = [getattr(r, attr) for r in readings]
                stds = [getattr(r, attr + "_std") for r in readings]
                key = f"{name}_{term}_{key_unit}"
                out[key] = None if any(v is None for v in values) else [float(v) for v in values]
                out[key + "_std"] = None if any(v is None for v in stds) else [float(v) for v in stds]
            out[f"{name}_minimum_tau_s"] = [r.minimum_tau_s for r in readings]
            out[f"{name}_longest_tau_s"] = readings[0].longest_tau_s
        return out

    def table(self) -> str:
        """Per sensor and axis: each term +/- its std (\"-\" where the curve does not show it)."""
        lines = [f"still: {sum(b - a for a, b in self.stretches_s):.1f} s of {self.duration_s:.1f} s "
                 f"({self.stretches_how}), {self.rate_hz:.4g} Hz"]
        for name, readings in self.sensors.items():
            unit = "rad/s" if name == "gyro" else "m/s^2"
            lines.append(f"{name}  white ({unit}/sqrt(Hz))  bias instability ({unit})  random walk ({unit}/s/sqrt(Hz))")
            for axis, r in zip("xyz", readings):
                cells = [_pm(r.white, r.white_std), _pm(r.bias_instability, r.bias_instability_std),
                         _pm(r.random_walk, r.random_walk_std)]
                lines.append(f"  {axis}  " + "  ".join(f"{c:>24}" for c in cells))
        return "\n".join(lines)

    def to_json(self, path=None) -> str:
        text = json.dumps(self.to_dict(), indent=2) + "\n"
        if path is not None:
            from magyro.io import write_text_atomically

            write_text_atomically(path, text)
        return text


def _pm(value, std) -> str:
    return "-" if value is None else f"{value:.4g} +/- {std:.2g}"


def write_plot(report: NoiseReport, path) -> None:
    """The Allan deviation of each axis and the three fitted terms, log-log; written whole or not at all."""
    from pathlib import Path

    from magyro.io import write_atomically
    from magyro.observability.plot import require_matplotlib

    Figure = require_matplotlib()
    fig = Figure(figsize=(10.0, 4.5 * len(report.curves)))
    for row, (name, curve) in enumerate(report.curves.items()):
        ax = fig.add_subplot(len(report.curves), 1, row + 1)
        for axis, r in enumerate(report.sensors[name]):
            line, = ax.loglog(curve.taus_s, curve.adev[:, axis], ".", label=f"{'xyz'[axis]}")
            fit = r.white ** 2 / curve.taus_s
            fit = fit + ((FLICKER_FLOOR * r.bias_instability) ** 2 if r.bias_instability else 0.0)
            fit = fit + ((r.random_walk ** 2) * curve.taus_s / 3.0 if r.random_walk else 0.0)
            ax.loglog(curve.taus_s, np.sqrt(fit), "-", color=line.get_color(), lw=0.8)
        ax.set_xlabel("tau (s)")
        ax.set_ylabel(f"Allan deviation ({'rad/s' if name == 'gyro' else 'm/s^2'})")
        ax.set_title(f"{name}: points measured, lines the fitted -1/2, 0 and +1/2 terms")
        ax.grid(True, which="both", lw=0.3)
        ax.legend()
    fig.tight_layout()
    path = Path(path)
    write_atomically(path, lambda tmp: fig.savefig(tmp, format=path.suffix.lstrip(".").lower() or "png", dpi=100))


def still_stretches_s(session, whole: bool) -> tuple[str, list]:
    """(how, segments): the whole recording, or the rests at both ends (find_rests)."""
    if whole:
        return "the whole recording (--still)", [(float(session.t_gyro_s[0]), float(session.t_gyro_s[-1]))]
    from magyro.front.rests import find_rests

    return "the rests at both ends (magyro.front.rests.find_rests)", list(find_rests(session).segments_s)


def too_short_message(name: str, missing: list, readings: list, curve: AllanCurve, still_s: float) -> str:
    """Why the terms in `missing` cannot be read, and how long a still recording would do."""
    lowest_s, longest_s = max(r.minimum_tau_s for r in readings), readings[0].longest_tau_s
    where = (f"the curve still falls at its longest tau with {MIN_CLUSTERS} clusters, {longest_s:.3g} s"
             if lowest_s >= longest_s * (1.0 - 1e-9) else
             f"its lowest point at {lowest_s:.3g} s, not far enough inside its longest tau, {longest_s:.3g} s")
    return (f"{still_s:.0f} s still is too short to read the {name}'s "
            f"{' and '.join(term.replace('_', ' ') for term in missing)} ({where}): the +1/2 slope needs tau well past "
            f"the curve's minimum with at least {MIN_CLUSTERS} clusters: record at least "
            f"{needed_still_s(curve, still_s) / 3600:.1f} h still (the usual advice: 2 h or more); --white-only "
            "measures the white noise alone")


def samples_within(t_s: np.ndarray, x: np.ndarray, segments_s: list) -> list[np.ndarray]:
    return [x[(t_s >= a) & (t_s <= b)] for a, b in segments_s]


def session_noise(session, whole: bool = False, white_only: bool = False) -> NoiseReport:
    """The noise of a session's gyro (and accelerometer when it has one) over its still stretches.

    RecordingTooShort (exit 3) when the stretches cannot say a term asked for (all three, or the white noise only
    with white_only), naming how long a still recording is needed."""
    require_allantools()
    how, segments = still_stretches_s(session, whole)
    still_s = float(sum(b - a for a, b in segments))
    if still_s < MIN_STILL_S:
        raise RecordingTooShort(f"the recording has {still_s:.1f} s still (rests at its ends); the white noise needs "
                                f"at least {MIN_STILL_S:g} s still, the random walk about 2 h (record the device lying "
                                "still, or pass --still if the whole recording is)")
    rate = float(session.gyro_rate_hz)
    sensors, curves = {}, {}
    signals = {"gyro": (session.t_gyro_s, session.gyro_rad_s)}
    if session.acc_m_s2 is not None:
        signals["acc"] = (session.t_acc_s, session.acc_m_s2)
    for name, (t, x) in signals.items():
        sensor_rate = rate if name == "gyro" else float((len(t) - 1) / (t[-1] - t[0]))
        curve = allan_curve(samples_within(t, x, segments), sensor_rate, name)
        if len(curve.taus_s) < 3:
            raise RecordingTooShort(f"the {still_s:.1f} s still hold too few samples of the {name} for its Allan "
                                    f"deviation (at least {MIN_CLUSTERS} clusters at 3 cluster lengths)")
        readings = [read_axis(curve, axis) for axis in range(3)]
        if not white_only:
            missing = sorted({term for r in readings for term in r.why_not})
            if missing:
                raise RecordingTooShort(too_short_message(name, missing, readings, curve, still_s))
        sensors[name], curves[name] = readings, curve
    return NoiseReport(rate, float(session.duration_s), how, segments, sensors, curves)
