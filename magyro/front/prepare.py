"""The front end every method shares: from a loaded session to what a solver starts from.

    1. rests found at both ends, noise levels from them (`magyro.front.noise`),
       the session trimmed to its moving span (the paper excludes the rests);
       the stills between them found (`magyro.front.stills`: the accelerometer's rests too, not trimmed)
    2. the magnetometer ellipsoid (paper step 1, `magyro.front.ellipsoid`)
    3. the gyro unit check: the gyro must turn the field as fast as the
       magnetometer sees it turn
    4. the observability gate on the integral of M^T M (`magyro.observability`)
       -> ObservabilityError (exit 3) when rank < 12, unless forced
"""
from __future__ import annotations

import weakref
from dataclasses import dataclass

import numpy as np

from magyro import so3
from magyro.errors import InputError, MagyroError, ObservabilityError
from magyro.front import causes, ellipsoid, rests
from magyro.front.stills import Stills, find_stills
from magyro.front.noise import NoiseLevels, noise_levels
from magyro.observability.gate import ObservabilityAnalysis, analyse
from magyro.options import Options
from magyro.session import Session, hole_steps

MIN_MOVING_SAMPLES = 100
MIN_RATE_RATIO = 0.1


@dataclass
class Prepared:
    """Everything before the solve: noise, step-1 fit, gate, initial estimates."""

    session: Session                # trimmed to the moving span when Options.trim_rests
    sigma_mag: float
    gyro_density: float
    fit: ellipsoid.EllipsoidFit
    analysis: ObservabilityAnalysis
    rests: rests.Rests | None = None
    noise_source: str = ""
    levels: NoiseLevels | None = None   # where each level came from (given, rest, guess)
    untrimmed: Session | None = None    # the session before its end rests were trimmed (the accelerometer's rests)
    stills: Stills | None = None        # poses held still between the end rests (None with Options.stills off)

    @property
    def accelerometer_rests_s(self) -> list[tuple[float, float]]:
        """The spans the accelerometer reads as rests: the end rests and the stills between them, in time order."""
        ends = list(self.rests.segments_s) if self.rests is not None else []
        return sorted(ends + list(self.stills.segments_s)) if self.stills is not None else ends

    @property
    def field_m(self) -> np.ndarray:
        """The calibrated field R (y - h) of every magnetometer sample of `session`, made when asked: not kept, so
        the linearisation's use of it does not last through the solve (8 MB at 360k samples, all of it resident at
        IPOPT's high-water mark)."""
        return ellipsoid.calibrated_field(self.fit.R, self.fit.h, self.session.mag)


def attitude_span_deg(session: Session, bias_rad_s: np.ndarray | None = None) -> float:
    """How far the raw gyro (less a rest bias, when known) says the device ever turned from its first attitude.

    Unlike the path integral of |w| dt, shaking back and forth does not add up.
    Holes in the record start again from the attitude before them.
    """
    return causes.turning(session, bias_rad_s).span_deg


def cloud_error(session: Session, kind: str, message: str, found: rests.Rests, gyro_std: float,
                mag_sample: float) -> MagyroError:
    """What a magnetometer cloud that fits no ellipsoid means, judged against how the gyro says the device turned
    (`magyro.front.causes`: too little motion or one axis, exit 3; a magnetometer that does not follow or a
    field that is not homogeneous, exit 2; else too little of the sphere, exit 3)."""
    def analysis_of():
        field = ellipsoid.surrogate_field_directions(session.mag)
        return analyse(session.t_gyro_s, session.gyro_rad_s, session.t_mag_s, field, gyro_std,
                       mag_sample / np.mean(np.linalg.norm(session.mag, axis=1)))

    return causes.cloud_error(session, kind, message, found.gyro_mean_rad_s, analysis_of)


UNIT_CHECK_BLOCK_S = 0.1       # the field's turning, too slow side: steps between means over 0.1 s blocks
UNIT_CHECK_NOISE_STDS = 2.0     # ... each step counted only beyond this many noise stds of a step
MAX_SLOW_RATE_RATIO = 0.25      # the gyro turned < 1/4 of the field's turning: rad/s labelled deg/s (57x)
MIN_SEEN_TURN_DEG = 180.0       # ... judged only when the field turned this much beyond noise


def check_gyro_unit(session: Session, field_m: np.ndarray) -> None:
    """The gyro must turn the field as fast as the magnetometer sees it turn, both ways.

    deg/s labelled rad/s turns it 57x too fast: the turning predicted from the gyro,
    integral |f x w| dt, against the field's path sampled every 0.1 s (noise only
    lengthens that path, so a right unit never looks too fast). rad/s labelled deg/s
    turns it 57x too slowly: the angle the gyro turned, integral |w| dt (free of the
    misalignment; noise and bias only add to it), against the field's path between
    0.1 s block means, each step counted beyond 2 noise stds (so a noisy or barely
    turning field never looks fast; the noise comes from the field's norm, which turning
    leaves alone, so fast motion is not mistaken for noise), and only when that path
    exceeds 180 deg (a device that barely turns is too little motion, for the gate to
    report). On BROAD trials 02 and 07 and the simulated sessions (also with 1-4 Hz
    shaking, or 10 min of noisy rest) the gyro turns 1.1-2.1x that path; with rad/s
    labelled deg/s, 0.020-0.037x. A time column that is not in seconds is named first.
    """
    from magyro.front.noise import MAD_TO_STD
    from magyro.io.checks import check_time_unit

    check_time_unit(session.t_gyro_s)  # stamps in ms would look like a gyro 1000x too fast
    t, y = session.t_gyro_s, session.gyro_rad_s
    step = max(1, int(round(0.1 * session.mag_rate_hz)))
    tm = session.t_mag_s[::step]
    fm = field_m[::step]
    seen = np.sum(np.linalg.norm(np.diff(fm, axis=0), axis=1))
    inside = (t >= tm[0]) & (t <= tm[-1])
    f_on_g = np.column_stack([np.interp(t[inside], session.t_mag_s, field_m[:, i]) for i in range(3)])
    w = np.gradient(t[inside])
    predicted = np.sum(np.linalg.norm(np.cross(f_on_g, y[inside]), axis=1) * w)
    if predicted > np.deg2rad(90) and seen / predicted < MIN_RATE_RATIO:
        raise InputError(
            f"the gyro turns {predicted / seen:.0f}x faster than the magnetometer sees the field turn: "
            "the gyro looks like deg/s labelled rad/s; pass --gyro-unit deg/s"
        )

    block = np.floor((session.t_mag_s - session.t_mag_s[0]) / UNIT_CHECK_BLOCK_S).astype(np.int64)
    count = np.bincount(block)
    used = count > 0
    if used.sum() < 8:
        return
    means = np.column_stack([np.bincount(block, field_m[:, i])[used] for i in range(3)]) / count[used, None]
    # noise of a block mean, per axis: from the field's norm (turning moves it across, never along it)
    radial_step = np.diff(np.bincount(block, np.linalg.norm(field_m, axis=1) - 1.0)[used] / count[used])
    block_noise = MAD_TO_STD * np.median(np.abs(radial_step - np.median(radial_step))) / np.sqrt(2.0)
    step_noise = 2.0 * block_noise  # two blocks, two directions across the field
    path = np.sum(np.maximum(0.0, np.linalg.norm(np.diff(means, axis=0), axis=1) - UNIT_CHECK_NOISE_STDS * step_noise))
    turned = np.sum(np.linalg.norm(y[inside], axis=1) * w)
    if path > np.deg2rad(MIN_SEEN_TURN_DEG) and turned < MAX_SLOW_RATE_RATIO * path:
        raise InputError(
            f"the gyro turns {path / max(turned, 1e-12):.0f}x slower than the magnetometer sees the field turn "
            f"(the gyro {np.rad2deg(turned):.0f} deg, the field {np.rad2deg(path):.0f} deg): the gyro looks like "
            "rad/s labelled deg/s; pass --gyro-unit rad/s"
        )


_last_moving: list = []   # [(weak reference to the session, options, result)] of the last call


def moving_session(session: Session, options: Options) -> tuple[Session, NoiseLevels, rests.Rests]:
    """(the session as the calibration sees it, noise levels, rests): rests found, noise levels
    from them, and the session trimmed to its moving span when Options.trim_rests. A session
    that is one long rest stays whole: the gate then calls it static.

    The last call's answer is kept for the same (frozen) session object and equal options: the front end and
    the result check of one calibration ask the same question (0.4 s at 360k samples)."""
    if _last_moving:
        ref, opts, found = _last_moving[0]
        if ref() is session and opts == options:
            return found
    result = find_moving_session(session, options)
    _last_moving[:] = [(weakref.ref(session), options, result)]
    return result


def find_moving_session(session: Session, options: Options) -> tuple[Session, NoiseLevels, rests.Rests]:
    found = rests.find_rests(session)
    levels = noise_levels(session, options, found)
    if options.trim_rests and found.segments_s:
        moving = session.within(*rests.moving_span(session, found))
        if min(len(moving.t_mag_s), len(moving.t_gyro_s)) >= MIN_MOVING_SAMPLES:
            session = moving
    return session, levels, found


def prepare(session: Session, options: Options) -> Prepared:
    """Steps 1-3: noise, rests, ellipsoid, observability. Raises ObservabilityError unless forced."""
    untrimmed = session
    session, levels, found = moving_session(session, options)
    sigma_mag, density = levels.mag_std, levels.gyro_density_rad_s_sqrt_hz
    gyro_std, mag_sample = levels.gyro_sample_std_rad_s, levels.mag_sample_std
    try:
        fit = ellipsoid.fit_ellipsoid(session.mag, mag_sample)
    except ellipsoid.DegenerateCloud as cloud:
        raise cloud_error(session, cloud.kind, str(cloud), found, gyro_std, mag_sample) from None
    except ellipsoid.NotAnEllipsoid as shape:
        raise cloud_error(session, "hyperboloid", str(shape), found, gyro_std, mag_sample) from None
    field = ellipsoid.calibrated_field(fit.R, fit.h, session.mag)
    check_gyro_unit(session, field)
    analysis = analyse(session.t_gyro_s, session.gyro_rad_s, session.t_mag_s, field, gyro_std, mag_sample * float(np.mean(np.diag(fit.R))))
    motion = causes.motion_error(causes.turning(session, found.gyro_mean_rad_s), "" if analysis.full_rank else
                                 f" Gyro parameters: {analysis.summary().rstrip('.')}.", analysis)
    if motion is not None:   # a device that barely turned, or about one axis, even with --force: said so, not
        raise motion         # "rotate about y" nor a linear estimate that comes out mirrored
    if not analysis.full_rank and not options.force:
        raise ObservabilityError(
            f"the motion does not excite every gyro parameter: {analysis.summary()} (--force solves anyway)", analysis
        )
    stills = find_stills(untrimmed, found) if options.stills else None
    return Prepared(session, sigma_mag, density, fit, analysis, found, levels.source, levels, untrimmed, stills)
