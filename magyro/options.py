"""What is true of the sensors and the recording, whatever the method (`magyro.calibrate(session, options, method)`).

Each method's own knobs live in its method object (`magyro.NLS`, `magyro.EKF`),
as rockit separates a problem from its discretisation: the same `Options`
calibrate with either.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

STANDARD_GRAVITY_M_S2 = 9.80665   # 1 g: the unit g and mg are read in, and the default local gravity


@dataclass(frozen=True)
class StdBounds:
    """The refusal bound: the largest one-sigma, predicted before the solve, at which a calibration is still worth
    having. Not the accuracy targets (magyro.targets, 10-50x stricter: what a user asks for); docs/spec.md
    section 6 sets the two side by side.

    A motion that excites every parameter, but too weakly, is refused with the
    numbers (exit 3) instead of failing later or reporting a meaningless result;
    the defaults are the size of the errors a low-cost MEMS gyro is calibrated
    for (scale factors off by a few percent, biases of a few deg/s).
    """

    scale_ppm: float = 20000.0          # K_g diagonal
    nonorthogonality_deg: float = 1.0   # K_g above the diagonal, as angles
    bias_deg_s: float = 0.5
    misalignment_deg: float = 2.0
    acc_scale_ppm: float = 20000.0      # the accelerometer's (--accelerometer), on the solved std: K_a diagonal
    acc_nonorthogonality_deg: float = 1.0
    acc_bias_m_s2: float = 0.2
    acc_misalignment_deg: float = 2.0


@dataclass(frozen=True)
class Repairs:
    """Which repairs of the recording `magyro.front.repairs.repair_recording` makes before any method (all by
    default; each is reported in the calibration's `recording` section)."""

    restamp_bursts: bool = True
    drop_held: bool = True
    cut_saturation: bool = True
    drop_spikes: bool = True
    align_clocks: bool = True       # take a drifting lag, or one beyond the solve's search, off the magnetometer's stamps

    @classmethod
    def none(cls) -> "Repairs":
        return cls(**dict.fromkeys(cls.NAMES.values(), False))

    NAMES = {"restamp": "restamp_bursts", "held": "drop_held", "saturation": "cut_saturation", "spikes": "drop_spikes",
             "clocks": "align_clocks"}

    @classmethod
    def without(cls, names) -> "Repairs":
        """All repairs but the ones named (NAMES' keys, alone or comma-separated; all turns every one off)."""
        names = [n.strip() for item in names for n in item.split(",") if n.strip()]
        unknown = [n for n in names if n not in cls.NAMES and n != "all"]
        if unknown:
            from magyro.errors import InputError

            raise InputError(f"unknown repair {unknown[0]!r}; use {', '.join(cls.NAMES)} or all")
        if "all" in names:
            return cls.none()
        return cls(**{field: name not in names for name, field in cls.NAMES.items()})


@dataclass(frozen=True)
class Options:
    """Physics settings; None means 'estimate from the data'."""

    gyro_noise_density_rad_s_sqrt_hz: float | None = None
    mag_noise_std: float | None = None      # in the magnetometer's unit
    force: bool = False                     # solve even when the observability check fails
    trim_rests: bool = True                 # drop the rests at both ends (the paper does)
    estimate_time_offset: bool = True       # the magnetometer's lag behind the gyro, estimated (NLS) ...
    time_offset_s: float = 0.0              # ... from this start, or fixed at it (the EKF shifts the stamps by it)
    split_check: bool = False               # also calibrate each half alone and compare (magyro.result.consistency)
    max_std: StdBounds = StdBounds()        # the refusal bound: the gate refuses above it (force: solve anyway)
    repairs: Repairs = Repairs()            # what the recording check may repair (restamps, held, saturation, spikes)
    accelerometer: bool | None = None       # the accelerometer in the least squares (issue 26): None when the session
                                            # has ax ay az (left out, saying why, if it cannot be calibrated); True
                                            # required (exit 2 without ax ay az, exit 3 past its bound); False never
    gravity_m_s2: float = STANDARD_GRAVITY_M_S2   # the local gravity the accelerometer is calibrated against
    stills: bool = True                     # poses held still mid-recording count as rests for the accelerometer
                                            # (magyro.front.stills, issue 39); False: only the end rests do

    @classmethod
    def in_user_units(cls, gyro_noise_deg_s_sqrt_hz: float | None = None, mag_noise_std: float | None = None,
                      **settings) -> "Options":
        """Options from the units people quote: the gyro noise density in deg/s/sqrt(Hz)."""
        from magyro.errors import InputError

        for name, value in (("--gyro-noise", gyro_noise_deg_s_sqrt_hz), ("--mag-noise", mag_noise_std)):
            if value is not None and not (math.isfinite(value) and value > 0):
                raise InputError(f"{name} must be a positive number, not {value:g}")
        density = None if gyro_noise_deg_s_sqrt_hz is None else math.radians(gyro_noise_deg_s_sqrt_hz)
        return cls(gyro_noise_density_rad_s_sqrt_hz=density, mag_noise_std=mag_noise_std, **settings)
