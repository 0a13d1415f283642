"""How well the model fitted the recording (JSON `fit`): one type for each method.

The least squares reports its whitened residuals, the windows where the
magnetometer fits far worse than typical, and how much the calibrated field's
magnitude changes along the path; the filter reports the magnetometer's norm
residual and its normalised innovations. `fit_from_dict` reads either back,
chosen by the solver's method.
"""
from __future__ import annotations

from dataclasses import asdict, dataclass

from magyro.errors import InputError
from magyro.result.parts import read_number


@dataclass(frozen=True)
class SuspectWindow:
    """A window where the magnetometer residuals are far above the typical (a spike, or iron near the path)."""

    t0_s: float
    t1_s: float
    residual_vs_typical: float


@dataclass(frozen=True)
class FieldChange:
    """The calibrated field magnitude |R (y - h)| against 1, over half-second windows: worst and typical."""

    max_fraction: float
    at_s: float
    median_fraction: float


@dataclass(frozen=True)
class LeastSquaresFit:
    """The joint least squares' residuals at the solution (whitened: 1 is the noise level)."""

    mag_rms_normalised: float
    gyro_rms_normalised: float
    variance_factor: float          # chi^2 / (residuals - unknowns); reported, never applied
    residuals: int
    unknowns: int
    suspect_segments: tuple[SuspectWindow, ...]
    field_change: FieldChange

    def to_dict(self) -> dict:
        return asdict(self) | {"suspect_segments": [asdict(w) for w in self.suspect_segments]}

    @classmethod
    def from_dict(cls, data: dict) -> "LeastSquaresFit":
        try:
            return cls(read_number(data, "mag_rms_normalised", "fit"), read_number(data, "gyro_rms_normalised", "fit"),
                       read_number(data, "variance_factor", "fit"), read_number(data, "residuals", "fit", int),
                       read_number(data, "unknowns", "fit", int),
                       tuple(SuspectWindow(**w) for w in data.get("suspect_segments", ())),
                       FieldChange(**data["field_change"]))
        except (KeyError, TypeError) as exc:
            raise InputError(f"fit is not the least squares' fit statistics ({exc})") from None


@dataclass(frozen=True)
class FilterFit:
    """The EKF's fit: step 1's norm residual before and after the Gauss-Newton refinement, and the innovations."""

    mag_norm_rms: float
    mag_norm_rms_ellipsoid: float
    normalised_innovation_squared_mean: float   # about 3 for a consistent filter
    prior_std_K_eps: tuple[float, ...]

    def to_dict(self) -> dict:
        return asdict(self) | {"prior_std_K_eps": list(self.prior_std_K_eps)}

    @classmethod
    def from_dict(cls, data: dict) -> "FilterFit":
        try:
            return cls(float(data["mag_norm_rms"]), float(data["mag_norm_rms_ellipsoid"]),
                       float(data["normalised_innovation_squared_mean"]), tuple(data["prior_std_K_eps"]))
        except (KeyError, TypeError, ValueError) as exc:
            raise InputError(f"fit is not the EKF's fit statistics ({exc})") from None


FIT_TYPES = {"nls": LeastSquaresFit, "ekf": FilterFit}


def fit_from_dict(method: str, data: dict | None):
    """The fit statistics of `method` from the JSON; None where a calibration has none (given parameters)."""
    if not data:
        return None
    kind = FIT_TYPES.get(method)
    if kind is None:
        raise InputError(f"solver.method {method!r} is not one this version of magyro knows (nls, ekf)")
    return kind.from_dict(data)
