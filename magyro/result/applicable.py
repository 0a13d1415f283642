"""Whether a calibration may be applied to a session (issues 22, 25): `apply`, `validate` and `report` ask the
same questions before any work, so none of them applies a calibration twice, to a magnetometer in another unit,
or with matrices that would turn finite readings into infinities.
"""
from __future__ import annotations

import numpy as np

from magyro.errors import InputError
from magyro.io.csv_units import MAG_UNITS
from magyro.text import escaped, significant

MAX_CONDITION = 1e12          # K_g or R beyond this is singular to double precision
MAX_GAIN = 1e6                # no sensor's scale factor is a million: such a K_g is not a calibration
GAUSS_PER_LABEL = {"uT": 1e-2, "nT": 1e-5, "mT": 10.0, "T": 1e4, "G": 1.0, "mG": 1e-3}
# every spelling the importers accept for a physical magnetometer unit (magyro.io.csv_units.MAG_UNITS), in gauss
GAUSS_PER_UNIT = {key: GAUSS_PER_LABEL[label] for key, label in MAG_UNITS.items() if label in GAUSS_PER_LABEL}
UNKNOWN_UNITS = ("", "unknown")


def already_calibrated(session, name: str) -> None:
    """InputError when the session's metadata says a calibration was already applied to it."""
    md = session.metadata or {}
    if str(md.get("calibrated", "")).lower() == "true":
        raise InputError(f"{name}: already calibrated (by {escaped(md.get('calibration', 'a calibration'))}, "
                         f"frame {escaped(md.get('calibration_frame', '?'))}); applying a calibration twice "
                         "corrupts the rates: use the raw session")


def same_unit(a: str, b: str) -> bool:
    """True when two magnetometer unit labels name the same unit (uT, µT and microtesla alike)."""
    ka, kb = str(a).strip().lower(), str(b).strip().lower()
    if ka in GAUSS_PER_UNIT and kb in GAUSS_PER_UNIT:
        return GAUSS_PER_UNIT[ka] == GAUSS_PER_UNIT[kb]
    return ka == kb


def singular_matrix(cal) -> str | None:
    """Which of K_g and R (and the accelerometer's K_a, when the calibration has one) is singular or nearly so
    (condition number above MAX_CONDITION), said in words; None when none is."""
    accelerometer = getattr(cal, "accelerometer", None)
    matrices = (("gyro K_g", cal.K_g), ("magnetometer R", cal.R)) + (
        (("accelerometer K_a", accelerometer.K_a),) if accelerometer is not None else ())
    for name, M in matrices:
        M = np.asarray(M, dtype=float)
        with np.errstate(all="ignore"):
            condition = np.linalg.cond(M) if np.all(np.isfinite(M)) else np.inf
        if not np.isfinite(condition) or condition > MAX_CONDITION:
            return (f"the calibration's {name} is singular or nearly so (condition number {significant(condition)}, at most "
                    f"{MAX_CONDITION:g})")
    return None


def check_matrices(cal) -> None:
    """InputError when K_g or R is singular, or K_g scales rates by more than MAX_GAIN (results would overflow)."""
    singular = singular_matrix(cal)
    if singular is not None:
        raise InputError(f"{singular}: not a calibration that can be applied")
    gain = float(np.max(np.abs(cal.K_g)))
    if gain > MAX_GAIN:
        raise InputError(f"the calibration's gyro K_g scales rates by {significant(gain)} (at most {MAX_GAIN:g}): not a "
                         "calibration that can be applied")


def check_applicable(cal, session, name: str, *, magnetometer: bool = True) -> None:
    """InputError, before any work, when `cal` must not be applied to `session` (named `name` in the message):
    the session is already calibrated, a matrix is singular or absurd, or (`magnetometer`: the field is used)
    the calibration's magnetometer unit is not the session's."""
    already_calibrated(session, name)
    check_matrices(cal)
    if not magnetometer:
        return
    cal_unit, session_unit = str(cal.mag_unit), str(session.mag_unit)
    if cal_unit.strip().lower() in UNKNOWN_UNITS or session_unit.strip().lower() in UNKNOWN_UNITS:
        return   # one side does not say: nothing to compare
    if not same_unit(cal_unit, session_unit):
        raise InputError(f"{name}: the magnetometer is in {escaped(session_unit)}, the calibration was made in "
                         f"{escaped(cal_unit)}; its hard iron h and soft iron R hold only in that unit: use a "
                         f"calibration made in {escaped(session_unit)}")


def check_finite_result(rates, field=None, specific_force=None) -> None:
    """InputError when applying the calibration gave a rate, field or specific force that is not finite (nothing is
    written)."""
    if not np.all(np.isfinite(rates)) or (field is not None and not np.all(np.isfinite(field))):
        raise InputError("applying the calibration gives values that are not finite (the readings times K_g or R "
                         "overflow); nothing written")
    if specific_force is not None and not np.all(np.isfinite(specific_force)):
        raise InputError("applying the calibration gives accelerometer values that are not finite (the readings "
                         "times K_a overflow, or an ax ay az is not finite); nothing written")
