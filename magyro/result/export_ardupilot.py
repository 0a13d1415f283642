"""An ArduPilot parameter file (issue 41): `magyro export CALIB.json --format ardupilot`.

ArduPilot's corrections, as its sources apply them (repository ArduPilot/ardupilot):

    compass  libraries/AP_Compass/AP_Compass_Backend.cpp, accumulate_sample -> rotate_field, then correct_field:
             the raw field (milligauss) is first turned into the body frame (rotate_field: the driver's rotation,
             then AHRS_ORIENTATION for an internal compass or COMPASS_ORIENT for an external one), then
                 mag += COMPASS_OFS                       (the offsets are ADDED)
                 mag *= COMPASS_SCALE                     (when within its sanity range; 1 changes nothing)
                 mag  = [[DIA_X, ODI_X, ODI_Y],
                         [ODI_X, DIA_Y, ODI_Z],
                         [ODI_Y, ODI_Z, DIA_Z]] mag       (symmetric)
                 mag += motor compensation                (not calibrated here)
    gyro     libraries/AP_InertialSensor/AP_InertialSensor_Backend.cpp, _rotate_and_correct_gyro:
                 gyro -= INS_GYROFFS                      (rad/s, SUBTRACTED), then the board rotation
    accel    the same file, _rotate_and_correct_accel:
                 accel -= INS_ACCOFFS; accel.{x,y,z} *= INS_ACCSCAL_{X,Y,Z}   (m/s^2; offset first, then a diagonal
                                                                               scale), then the board rotation

magyro (docs/spec.md section 1): w_b = K_g y + eps_b; m_m = R (y_m - h), unit norm; f_a = K_a y_a + eps_a,
f_b = C_b_a^T f_a. ArduPilot's compass feeds the same body frame as its gyro, so the magnetometer is exported as
the field in magyro's gyro frame b: m_b = C_b_m^T R (y_m - h) = M (y_m - h). M = V Q (polar decomposition: V a
rotation, Q symmetric positive definite): ArduPilot holds Q (scaled to the field strength in mG) as DIA/ODI and
-h as OFS; V, the rotation left, it could hold only as the compass's orientation, which is applied before the
offsets -- it is stated with its cost, not written.
"""
from __future__ import annotations

import numpy as np

from magyro.errors import InputError
from magyro.result.applicable import GAUSS_PER_UNIT
from magyro.result.calibration import Calibration
from magyro.result.export_common import yaml_array
from magyro.result.export_tools import _check_gyro, _one_line, _rotation_angle_deg, px4_accelerometer, px4_gyro_cost
from magyro.text import escaped

MILLIGAUSS_PER_GAUSS = 1000.0
# AP_Compass.cpp: COMPASS_OFFS_MAX, "the maximum allowed compass offset in calibration and arming checks", whose
# default AP_COMPASS_OFFSETS_MAX_DEFAULT is 1800 (mG)
OFFSETS_MAX_DEFAULT_MG = 1800.0
COST_RATE_DEG_S = 360.0


def milligauss_per_unit(unit: str) -> float:
    """The factor from the calibration's magnetometer unit to milligauss, ArduPilot's compass unit; InputError for a
    unit that is not a field unit."""
    key = str(unit).strip().lower()
    if key not in GAUSS_PER_UNIT:
        raise InputError(f"the magnetometer unit '{escaped(unit)}' cannot be converted to milligauss, which "
                         "ArduPilot's compass parameters are in; use a calibration solved from a magnetometer in uT, "
                         "nT, G, mG or T")
    return GAUSS_PER_UNIT[key] * MILLIGAUSS_PER_GAUSS


def polar_decomposition(M) -> tuple[np.ndarray, np.ndarray]:
    """(V, Q) with M = V Q, V a rotation (the nearest to M) and Q symmetric positive definite; InputError when M
    reflects the axes (det M < 0: no rotation and symmetric positive factor hold it)."""
    W, sing, Vt = np.linalg.svd(np.asarray(M, dtype=float))
    V = W @ Vt
    if np.linalg.det(V) < 0:
        raise InputError("the magnetometer matrix C_b_m^T R reflects the axes (det < 0); ArduPilot cannot hold it")
    Q = Vt.T @ np.diag(sing) @ Vt
    return V, (Q + Q.T) / 2.0


def ardupilot_compass(cal: Calibration) -> dict:
    """COMPASS_OFS (mG), COMPASS_DIA / COMPASS_ODI and COMPASS_SCALE, and what they leave.

    ArduPilot (AP_Compass_Backend.cpp, correct_field): field = S (COMPASS_SCALE (y_mG + OFS)), S symmetric. magyro's
    field in the gyro frame: m_b = M (y - h), M = C_b_m^T R = V Q. With OFS = -h (in mG), COMPASS_SCALE = 1 and
    S = k Q, k = det(M)^-1/3 (the field strength in the magnetometer's unit, so det S = 1), ArduPilot's field is
    strength_mG V^T m_b: the length of the true field in mG, its direction turned by V^T from magyro's gyro frame.
    rotation_left_deg, the angle of V, is then the largest angle between the two (for a field square to V's axis).
    """
    _check_gyro(cal)     # every number finite, K_g and R not singular
    to_mG = milligauss_per_unit(cal.mag_unit)
    M = cal.C_b_m.T @ cal.R
    V, Q = polar_decomposition(M)
    strength_unit = float(np.linalg.det(M) ** (-1.0 / 3.0))
    S = strength_unit * Q
    return {"offsets_mG": -cal.h * to_mG, "diagonals": np.diag(S).copy(),
            "offdiagonals": np.array([S[0, 1], S[0, 2], S[1, 2]]), "scale": 1.0, "soft_iron": S,
            "field_strength_mG": strength_unit * to_mG, "milligauss_per_unit": to_mG,
            "rotation_left": V, "rotation_left_deg": _rotation_angle_deg(V)}


def ardupilot_gyro(cal: Calibration, rate_deg_s: float = COST_RATE_DEG_S) -> dict:
    """INS_GYROFFS (rad/s) and what ArduPilot's offset-only gyro costs at `rate_deg_s`.

    ArduPilot (AP_InertialSensor_Backend.cpp, _rotate_and_correct_gyro): w = y - INS_GYROFFS. INS_GYROFFS =
    -K_g^-1 eps_b, the reading at rest, is exact at zero rate; at a true rate w ArduPilot reads K_g^-1 w, an error of
    (K_g^-1 - I) w -- the same as PX4's (export_tools.px4_gyro_cost computes it)."""
    _check_gyro(cal)
    return {"offsets_rad_s": -np.linalg.solve(cal.K_g, cal.bias_rad_s), **px4_gyro_cost(cal, rate_deg_s)}


def ardupilot_accelerometer(cal: Calibration) -> dict:
    """INS_ACCOFFS (m/s^2), INS_ACCSCAL and their cost at 1 g.

    ArduPilot (AP_InertialSensor_Backend.cpp, _rotate_and_correct_accel): f = (y_a - INS_ACCOFFS) .* INS_ACCSCAL, then
    the board rotation the gyro has too: PX4's formula (export_tools.px4_accelerometer), so the same values and cost:
    INS_ACCSCAL = diag(K_a), INS_ACCOFFS = -K_a^-1 eps_a; the error (diag(K_a) K_a^-1 C_b_a - I) f_b in the gyro frame
    (the non-orthogonality of K_a and the rotation C_b_a, which ArduPilot cannot hold)."""
    a = px4_accelerometer(cal)
    return {**a, "offsets_m_s2": a["offset_m_s2"]}


def ardupilot_parameters(cal: Calibration) -> list[tuple[str, float]]:
    """(name, value) of every parameter the file sets, in the order written."""
    c, g = ardupilot_compass(cal), ardupilot_gyro(cal)
    rows = [(f"COMPASS_OFS_{ax}", c["offsets_mG"][i]) for i, ax in enumerate("XYZ")]
    rows += [(f"COMPASS_DIA_{ax}", c["diagonals"][i]) for i, ax in enumerate("XYZ")]
    rows += [(f"COMPASS_ODI_{ax}", c["offdiagonals"][i]) for i, ax in enumerate("XYZ")]
    rows.append(("COMPASS_SCALE", c["scale"]))
    rows += [(f"INS_GYROFFS_{ax}", g["offsets_rad_s"][i]) for i, ax in enumerate("XYZ")]
    if cal.accelerometer is not None:
        a = ardupilot_accelerometer(cal)
        rows += [(f"INS_ACCOFFS_{ax}", a["offsets_m_s2"][i]) for i, ax in enumerate("XYZ")]
        rows += [(f"INS_ACCSCAL_{ax}", a["scale"][i]) for i, ax in enumerate("XYZ")]
    return rows


def cannot_hold_lines(cal: Calibration, rate_deg_s: float = COST_RATE_DEG_S) -> list[str]:
    """What ArduPilot cannot hold of the calibration, each with its cost at a named rate or field (the file's
    comments, and what `magyro export` says on stderr)."""
    c, g = ardupilot_compass(cal), ardupilot_gyro(cal, rate_deg_s)
    per_axis = ", ".join(f"{v:.4f}" for v in g["per_axis_deg_s"])
    lines = [f"GYRO scale and non-orthogonality (K_g): ArduPilot only subtracts INS_GYROFFS; at {g['rate_deg_s']:g} deg/s"
             f" about x, y, z that is {per_axis} deg/s wrong, {g['worst_deg_s']:.4f} deg/s about the worst direction.",
             f"COMPASS rotation left: the field is turned by {c['rotation_left_deg']:.4f} deg from the gyro frame (the"
             f" gyro-magnetometer misalignment, {_rotation_angle_deg(cal.C_b_m):.4f} deg, with the soft iron's rotation);"
             f" up to {c['rotation_left_deg']:.4f} deg of heading. Only a compass orientation could hold it"
             " (COMPASS_ORIENT, a custom rotation), applied before the offsets: not written."]
    largest_mG = float(np.max(np.abs(c["offsets_mG"])))
    if largest_mG > OFFSETS_MAX_DEFAULT_MG:
        lines.append(f"COMPASS_OFS up to {largest_mG:.1f} mG: above COMPASS_OFFS_MAX's default "
                     f"({OFFSETS_MAX_DEFAULT_MG:g} mG), so ArduPilot's arming check refuses the compass unless "
                     "COMPASS_OFFS_MAX is raised (its documented range: 500 to 3000 mG).")
    if cal.accelerometer is not None:
        a = ardupilot_accelerometer(cal)
        grav = a["g_m_s2"]
        lines.append(f"ACCEL non-orthogonality (K_a above its diagonal) and the gyro-accelerometer rotation C_b_a "
                     f"({a['misalignment_deg']:.4f} deg): ArduPilot's INS_ACCSCAL is a diagonal; at 1 g ({grav:g} m/s^2)"
                     f" {a['nonorth_worst_m_s2']:.4f} m/s^2 from the non-orthogonality alone, "
                     f"{a['worst_m_s2']:.4f} m/s^2 with C_b_a in the worst direction (at most "
                     f"{np.degrees(np.arcsin(min(1.0, a['worst_m_s2'] / grav))):.3f} deg of tilt).")
    return lines


def ardupilot_text(cal: Calibration, source: str = "", rate_deg_s: float = COST_RATE_DEG_S) -> str:
    """A parameter file Mission Planner and MAVProxy load: '#' comment lines, then NAME,VALUE lines (Mission
    Planner's own .param format; MAVProxy's `param load`, ArduPilot/pymavlink mavparm.py MAVParmDict.load, skips
    lines that start with '#' and replaces ',' by a space before splitting NAME and VALUE)."""
    c, g = ardupilot_compass(cal), ardupilot_gyro(cal, rate_deg_s)
    header = ["# ArduPilot parameters: magyro calibration (magyro export --format ardupilot)",
              f"# source: {_one_line(source)}",
              "# NAME,VALUE per line: Mission Planner's .param format; MAVProxy's 'param load' (ArduPilot/pymavlink",
              "#   mavparm.py, MAVParmDict.load) skips '#' lines and reads ',' as a space.",
              "# ArduPilot (ArduPilot/ardupilot) corrects, in its own units:",
              "#   compass (AP_Compass_Backend.cpp correct_field, after rotate_field turned it into the body frame),",
              "#     mG: field = [DIA ODI; symmetric] (COMPASS_SCALE (y + COMPASS_OFS)); the offsets are ADDED",
              "#   gyro  (AP_InertialSensor_Backend.cpp _rotate_and_correct_gyro), rad/s: w = y - INS_GYROFFS",
              "#   accel (same file, _rotate_and_correct_accel), m/s^2: f = (y - INS_ACCOFFS) .* INS_ACCSCAL",
              "# The readings magyro calibrated are taken as those ArduPilot corrects, with AHRS_ORIENTATION = 0: the",
              "#   compass's after its COMPASS_ORIENT, the IMU's after the driver's own rotation. With another board",
              "#   orientation ArduPilot turns the compass BEFORE its correction and the IMU AFTER: calibrate in that frame.",
              "# COMPASS: magyro's field in the gyro frame m_b = C_b_m^T R (y_m - h) = V Q (y_m - h) (polar",
              "#   decomposition: V a rotation, Q symmetric). OFS = -h in mG (unit "
              f"'{_one_line(cal.mag_unit)}' x {c['milligauss_per_unit']:g}); DIA/ODI = k Q,",
              f"#   k = {c['field_strength_mG'] / c['milligauss_per_unit']:.6g} {_one_line(cal.mag_unit)}, the field"
              " strength (det = 1); COMPASS_SCALE = 1 (replaces any the",
              "#   calibrator set). ArduPilot's field is then "
              f"{c['field_strength_mG']:.6g} mG x V^T m_b: the true strength, exact where V = I.",
              "# GYRO: INS_GYROFFS = -K_g^-1 eps_b, the reading at rest (rad/s): exact at zero rate. ArduPilot RE-LEARNS",
              "#   INS_GYROFFS at every boot while INS_GYR_CAL = 1 (its default) and overwrites these: set INS_GYR_CAL = 0",
              "#   (never) to keep them; the bias's change from one turn-on to the next is then not learned.",
              ]
    if cal.accelerometer is not None:
        header += ["# ACCEL: INS_ACCSCAL = diag(K_a), INS_ACCOFFS = -K_a^-1 eps_a (the reading at zero specific force)."]
    header += ["# A calibration solved from an ArduPilot log (magyro import of a .bin) saw the gyro and accelerometer",
               "#   after the vehicle's own INS offsets and scales and its board rotation: for it these are what",
               "#   remains on top of them, not a replacement.",
               "# WHAT ARDUPILOT CANNOT HOLD, and its cost:",
               *(f"#   {line}" for line in cannot_hold_lines(cal, rate_deg_s)),
               "# Not held (magyro's w_b = K_g y + eps_b; m_b = C_b_m^T R (y_m - h)):",
               *(f"#   K_g row {i}: {yaml_array(cal.K_g[i])}" for i in range(3)),
               *(f"#   rotation left V row {i}: {yaml_array(c['rotation_left'][i])}" for i in range(3))]
    if cal.accelerometer is not None:
        header += [f"#   K_a row {i}: {yaml_array(cal.accelerometer.K_a[i])}" for i in range(3)]
        header += [f"#   C_b_a row {i}: {yaml_array(cal.accelerometer.C_b_a[i])}" for i in range(3)]
    header += ["# Instance 1 only (COMPASS_OFS_, INS_GYROFFS_, INS_ACCOFFS_): the sensors must be the vehicle's first.",
               "# ArduPilot stores float32: values round to about 7 significant digits on the vehicle."]
    return "\n".join(header + [f"{name},{_value(value)}" for name, value in ardupilot_parameters(cal)]) + "\n"


def _value(x: float) -> str:
    """The shortest decimal that reads back to the same double."""
    x = float(x)
    if not np.isfinite(x):
        raise InputError("the export would hold a number that is not finite; nothing exported")
    return repr(x)
