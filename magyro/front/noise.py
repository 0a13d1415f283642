"""Sensor noise levels estimated from the data itself.

What weights a least squares is the noise's low-frequency density, not its
per-sample std: real sensors filter or repeat samples (docs/how-it-works.md quotes
BROAD's magnetometer's autocorrelations, computed by docs/shipped_data_numbers.py),
so consecutive samples are not independent. With per-sample std s and integrated autocorrelation time
tau = 1 + 2 sum_k rho_k (in samples), the effective white std is
s * sqrt(tau): one sample in tau carries independent information.

From rests (when the session has them) both s and tau come straight from
the still data. Otherwise the only level the data give before a solve is the
third differences' (`magyro.front.differences`): right while the motion is
slow against the sample rate, far too large at a phone's 25-40 Hz. Such a
level is a guess; the least squares then estimates both levels itself
(variance components, `magyro.nls.variance`). Users who know their sensor
pass the numbers instead.

Where each level came from is kept per sensor (`LEVEL_SOURCES`): "given",
"rest", "differences" (the gyro: the floor of the 3rd..8th differences'
levels, where they stop falling: noise, not motion, `differences.noise_floor_std`;
the magnetometer: the third's level, when the fourth's confirms it), "guess"
(still falling: the motion is too fast for the rate) here, "estimated by the solve" once the least squares has
replaced a guess.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from magyro.errors import InputError
from magyro.front import rests
from magyro.front.differences import (MAD_TO_STD, MOTION_FREE_RATIO, THIRD_DIFFERENCE_GAIN,  # noqa: F401
                                     difference_noise_std, noise_floor_std, white_noise_std)
from magyro.options import Options
from magyro.session import Session

GIVEN, REST, DIFFERENCES, GUESS, ESTIMATED = "given", "rest", "differences", "guess", "estimated by the solve"
LEVEL_SOURCES = (GIVEN, REST, DIFFERENCES, GUESS, ESTIMATED)


def mag_noise_std(y_mag: np.ndarray) -> float:
    """One magnetometer noise std (input unit), the RMS over the three axes."""
    return float(np.sqrt(np.mean(white_noise_std(y_mag) ** 2)))


def floor_level(x: np.ndarray, rate_hz: float | None = None) -> tuple[float, str]:
    """(RMS over the axes of the differences' noise floor, DIFFERENCES when it is noise else GUESS): the gyro's;
    at `rate_hz` (`differences.LOW_RATE_HZ` or below) a floor that rises with the motion is a guess."""
    std, is_noise = noise_floor_std(x, rate_hz)
    return float(np.sqrt(np.mean(std**2))), DIFFERENCES if is_noise else GUESS


def third_difference_level(x: np.ndarray) -> tuple[float, str]:
    """(RMS over the axes of the third differences' level, DIFFERENCES when the fourth's confirm it else GUESS):
    the magnetometer's. Its noise is often filtered (BROAD's, as logged: see docs/how-it-works.md), which higher
    orders see less of, so a falling level there may be the filter rather than motion: the third's level
    stays, and only its source says whether it is trusted; the solve estimates a guessed one."""
    third, fourth = difference_noise_std(x, 3), difference_noise_std(x, 4)
    level = float(np.sqrt(np.mean(third**2)))
    return level, DIFFERENCES if np.sqrt(np.mean(fourth**2)) >= MOTION_FREE_RATIO * level else GUESS


def gyro_noise_density_rad_s_sqrt_hz(gyro_rad_s: np.ndarray, rate_hz: float) -> float:
    """Gyro noise density (rad/s/sqrt(Hz)) from the per-sample std: std / sqrt(rate)."""
    std = float(np.sqrt(np.mean(white_noise_std(gyro_rad_s) ** 2)))
    return std / np.sqrt(rate_hz)


AUTOCORRELATION_CUTOFF = 0.05
MAX_LAG = 200


def integrated_autocorrelation_time(x: np.ndarray) -> float:
    """tau = 1 + 2 sum of the autocorrelations, summed until they drop below 0.05; mean over columns."""
    x = np.asarray(x, dtype=float)
    if x.ndim == 1:
        x = x[:, None]
    taus = []
    for col in (x - x.mean(axis=0)).T:
        var = float(col @ col)
        tau = 1.0
        if var > 0:
            for k in range(1, min(MAX_LAG, len(col) // 4)):
                rho = float(col[:-k] @ col[k:]) / var
                if rho < AUTOCORRELATION_CUTOFF:
                    break
                tau += 2.0 * rho
        taus.append(tau)
    return float(np.mean(taus))


CHI2_3DOF_MEDIAN = 2.3660   # median of |r|^2 for a 3-vector of unit normals


def whitened_effective_scale(r: np.ndarray) -> float:
    """The effective scale of whitened 3-vectors r (N, 3), 1 when they are unit white noise: the robust
    per-sample scale (median of |r|^2 against its chi^2 median) times the square root of their integrated
    autocorrelation time, so correlated model error (a field not quite homogeneous) counts as what it is, fewer
    independent samples. The least squares' residuals and the EKF's innovations are both re-weighted by it."""
    scale = np.sqrt(np.median(np.sum(r**2, axis=1)) / CHI2_3DOF_MEDIAN)
    return float(scale * np.sqrt(integrated_autocorrelation_time(r)))


def effective_std(x: np.ndarray) -> float:
    """RMS over axes of the per-sample std, times sqrt(tau): the white std carrying the same information."""
    per_sample = float(np.sqrt(np.mean(np.var(np.asarray(x, dtype=float), axis=0))))
    return per_sample * np.sqrt(integrated_autocorrelation_time(x))


MIN_REST_FOR_NOISE_S = 2.0
NOISE_WHOLE_S = 30.0   # a rest longer than this is measured block by block (the median of its blocks): an autopilot
NOISE_BLOCK_S = 10.0   # still on the ground for 184 s (ArduPlane TestLog2) warms up, its gyro bias creeping 0.2 deg/s,
                       # and a compass spike or a burst of vibration falls in one block; measured whole, the creep
                       # read as correlated noise (gyro 0.26 deg/s/sqrt(Hz) instead of 0.010). A rest of up to 30 s
                       # (BROAD's are 3-18 s) is measured whole, as before


def rest_blocks(segment_s: tuple[float, float]) -> list[tuple[float, float]]:
    """A rest longer than NOISE_WHOLE_S cut into equal blocks of at most NOISE_BLOCK_S; a shorter one whole."""
    a, b = segment_s
    n = 1 if b - a <= NOISE_WHOLE_S else int(np.ceil((b - a) / NOISE_BLOCK_S - 1e-9))
    edges = np.linspace(a, b, n + 1)
    return [(float(lo), float(hi)) for lo, hi in zip(edges[:-1], edges[1:])]


def rest_levels(session: Session, segment_s: tuple[float, float]) -> tuple[float, float, float, float]:
    """(magnetometer per-sample std, gyro per-sample std rad/s, magnetometer effective std, gyro effective std rad/s)
    over one still stretch: the per-sample spread, and times sqrt of the integrated autocorrelation time."""
    still = rests.rests_from_segments(session, [segment_s])
    return (float(np.sqrt(np.mean(np.var(still.mag_still, axis=0)))),
            float(np.sqrt(np.mean(np.var(still.gyro_still, axis=0)))),
            effective_std(still.mag_still), effective_std(still.gyro_still))


@dataclass(frozen=True)
class NoiseLevels:
    """Per-sample stds (what noise adds sample by sample) and effective white levels (what weights the fit)."""

    mag_sample_std: float          # magnetometer unit
    gyro_sample_std_rad_s: float
    mag_std: float                 # effective: per-sample std * sqrt(autocorrelation time)
    gyro_density_rad_s_sqrt_hz: float
    source: str                    # in words, for the table
    gyro_source: str = GUESS       # one of LEVEL_SOURCES
    mag_source: str = GUESS


def noise_levels(session: Session, options: Options, found: rests.Rests) -> NoiseLevels:
    """Noise levels: given, from the longest rest (correlation included), or from third differences (white)."""
    rate = session.gyro_rate_hz
    if found.seconds >= MIN_REST_FOR_NOISE_S:
        longest = max(found.segments_s, key=lambda ab: ab[1] - ab[0])
        blocks = rest_blocks(longest)
        levels = np.median([rest_levels(session, block) for block in blocks], axis=0)
        mag_sample, gyro_sample, mag_eff, gyro_eff = (float(v) for v in levels)
        density = gyro_eff / np.sqrt(rate)
        source = (f"the {longest[1] - longest[0]:.1f} s rest (correlation included"
                  + (f"; the median of its {len(blocks)} blocks of {NOISE_BLOCK_S:g} s)" if len(blocks) > 1 else ")"))
        gyro_source = mag_source = REST
    else:
        mag_sample, mag_source = third_difference_level(session.mag)
        gyro_sample, gyro_source = floor_level(session.gyro_rad_s, rate)
        mag_eff, density = mag_sample, gyro_sample / np.sqrt(rate)
        source = "differences (white noise assumed" + ("" if gyro_source == mag_source == DIFFERENCES else
                                                      "; the motion shows in them: a guess") + ")"
    if options.mag_noise_std:
        mag_sample = mag_eff = options.mag_noise_std
        mag_source = GIVEN
    if options.gyro_noise_density_rad_s_sqrt_hz:
        density = options.gyro_noise_density_rad_s_sqrt_hz
        gyro_sample = density * np.sqrt(rate)
        gyro_source = GIVEN
    if options.mag_noise_std or options.gyro_noise_density_rad_s_sqrt_hz:
        source = "given" if options.mag_noise_std and options.gyro_noise_density_rad_s_sqrt_hz else source + ", partly given"
    if not (mag_eff > 0 and density > 0):
        raise InputError(
            "cannot estimate the sensor noise from the data (the readings do not vary); "
            "pass --mag-noise and --gyro-noise"
        )
    return NoiseLevels(float(mag_sample), float(gyro_sample), float(mag_eff), float(density), source, gyro_source,
                       mag_source)
