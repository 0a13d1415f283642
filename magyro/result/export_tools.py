"""Exports for other tools (issue 12): Kalibr's `scale-misalignment` IMU yaml, and a PX4 parameter file.

magyro's model (docs/spec.md section 1) maps a raw reading to the truth:

    w_b = K_g y + eps_b      (rad/s; K_g upper triangular; the bias is ADDED)
    m_m = R (y_m - h)        (unit norm; R upper triangular, h in the magnetometer's unit)

Kalibr -- repository ethz-asl/kalibr, aslam_offline_calibration/kalibr/python/kalibr_imu_camera_calibration/
IccSensors.py, class IccScaledMisalignedImu -- maps the truth to a reading:

    w_meas = M (C_gyro_i w_i) + A (C_gyro_i a_i) + b     (M lower triangular: MatrixBasicDv pattern
                                                          [[1,0,0],[1,1,0],[1,1,1]]; C_gyro_i a rotation;
                                                          A the g-sensitivity; b Kalibr's bias spline)

PX4 -- repository PX4/PX4-Autopilot, src/lib/sensor_calibration/Gyroscope.hpp and Magnetometer.hpp/.cpp:

    gyro:  corrected = rotation (y - thermal_offset - CAL_GYROx_OFF)          (rad/s; offset only)
    mag:   corrected = rotation (S ((y_m + power COMP) - CAL_MAGx_OFF))      (gauss; S symmetric:
           diag CAL_MAGx_{X,Y,Z}SCALE, CAL_MAGx_ODIAG{X,Y,Z} = S01, S02, S12)
"""
from __future__ import annotations

import json

import numpy as np

from magyro.errors import InputError
from magyro.result.applicable import GAUSS_PER_UNIT
from magyro.result.calibration import Calibration
from magyro.result.export_common import check_finite, yaml_array, yaml_number
from magyro.text import escaped

RAD2DEG = 180.0 / np.pi


def _one_line(text) -> str:
    """Text for one line of a comment: controls, line breaks and bidi characters written as visible escapes."""
    return escaped(text)


def _check_gyro(cal: Calibration) -> None:
    check_finite(cal)
    if not np.all(np.diag(cal.K_g) > 0):
        raise InputError("the gyro scale factors (diagonal of K_g) are not all positive; nothing to export")


def _rotation_angle_deg(C) -> float:
    return float(np.degrees(np.arccos(np.clip((np.trace(C) - 1.0) / 2.0, -1.0, 1.0))))


# --------------------------------------------------------------------------- Kalibr


def kalibr_parameters(cal: Calibration) -> dict:
    """Kalibr's gyro intrinsics equal to magyro's, with Kalibr's frame i = magyro's gyro frame b.

    Inverting magyro: y = K_g^-1 w_b - K_g^-1 eps_b. Kalibr wants M lower triangular, so K_g^-1 is split as
    M C_gyro_i (an LQ decomposition: the QR of K_g^-T, diag(M) > 0, det C_gyro_i = +1) -- exact, no
    approximation; C_gyro_i is then only the rotation between the two triangular conventions.
    b = -K_g^-1 eps_b (Kalibr's sign: a reading, as at rest); A = 0 (magyro has no g-sensitivity term).
    """
    _check_gyro(cal)
    K_inv = np.linalg.inv(cal.K_g)
    Q, Rr = np.linalg.qr(K_inv.T)              # K_inv^T = Q Rr  =>  K_inv = Rr^T Q^T
    D = np.diag(np.sign(np.diag(Rr)))
    M = np.tril((D @ Rr).T)                    # lower triangular, positive diagonal
    C = (Q @ D).T                              # K_inv = M C; det C = +1 as det K_inv > 0
    return {"M": M, "A": np.zeros((3, 3)), "C_gyro_i": C, "b": -K_inv @ cal.bias_rad_s}


def kalibr_text(cal: Calibration, source: str = "") -> str:
    """Kalibr's IMU yaml (model scale-misalignment), gyroscope block only, every number exact to the double."""
    p = kalibr_parameters(cal)
    angle = _rotation_angle_deg(p["C_gyro_i"])
    lines = ["# magyro calibration as Kalibr's IMU yaml, model scale-misalignment (magyro export --format kalibr)",
             f"# source: {_one_line(source)}",
             "# Kalibr's gyro model (ethz-asl/kalibr, kalibr_imu_camera_calibration/IccSensors.py,",
             "# IccScaledMisalignedImu): w_meas = M (C_gyro_i w_i) + A (C_gyro_i a_i) + b, truth -> reading.",
             "# Frame i here is magyro's gyro frame b. magyro: w_b = K_g y + eps_b (reading -> truth), so",
             "#   M C_gyro_i = K_g^-1   (exact LQ split: M lower triangular as Kalibr has it, C_gyro_i a rotation)",
             "#   b = -K_g^-1 eps_b      (rad/s, Kalibr's sign: the reading at rest)",
             "#   A = 0                  (magyro does not model g-sensitivity: 0 means 'not estimated')",
             "# To correct a reading y:  w_i = C_gyro_i^T M^-1 (y - b - A C_gyro_i a_i)  (= magyro's w_b exactly).",
             f"# C_gyro_i only turns magyro's upper-triangular convention into Kalibr's lower one: {angle:.6f} deg.",
             "# What this file cannot hold as Kalibr keys: Kalibr estimates its bias b as a spline per dataset and",
             "# writes none, so b is an extra key; magyro calibrates no accelerometer, so there is no",
             "# 'accelerometers' block, and no noise densities, random walks or rostopic (add yours to use the",
             "# file as Kalibr input); the magnetometer (R, h) and C_b_m are under the extra key 'magyro'.",
             "imu0:",
             '  model: "scale-misalignment"',
             f"  T_i_b: {yaml_array(np.eye(4))}",
             f"  time_offset: {yaml_number(0.0)}",
             "  gyroscopes:",
             f"    M: {yaml_array(p['M'])}",
             f"    A: {yaml_array(p['A'])}",
             f"    C_gyro_i: {yaml_array(p['C_gyro_i'])}",
             "    # not a Kalibr key: the constant gyro bias in Kalibr's sign, rad/s",
             f"    b: {yaml_array(p['b'])}",
             "  magyro:",
             "    # not Kalibr keys: w_m = C_b_m w_i (magnetometer frame); m_m = R (y_m - h), unit norm",
             f"    C_b_m: {yaml_array(cal.C_b_m)}",
             f"    mag_unit: {json.dumps(str(cal.mag_unit))}",
             f"    R: {yaml_array(cal.R)}",
             f"    h: {yaml_array(cal.h)}",
             ]
    return "\n".join(lines) + "\n"


# --------------------------------------------------------------------------- PX4


def gauss_per_unit(unit: str) -> float:
    """The factor from the calibration's magnetometer unit to gauss; InputError for a unit with none."""
    key = str(unit).strip().lower()
    if key not in GAUSS_PER_UNIT:
        raise InputError(f"the magnetometer unit '{escaped(unit)}' cannot be converted to gauss, which PX4 expects; "
                         "use a calibration solved from a magnetometer in uT, nT, G, mG or T")
    return GAUSS_PER_UNIT[key]


def px4_parameters(cal: Calibration) -> dict:
    """PX4's values and what they imply.

    gyro: PX4 computes y - OFF. OFF = -K_g^-1 eps_b, the reading at rest, makes it exact at zero rate;
    at a true rate w it then gives K_g^-1 w, an error of (K_g^-1 - I) w (see px4_gyro_cost).
    mag: R = U P (polar decomposition, U a rotation, P symmetric positive definite). PX4's S must be
    symmetric, so S = P k with k = det(P)^-1/3 (the field strength in the magnetometer's unit, making
    det S = 1) and OFF = h, both in gauss: PX4's field = k_gauss U^T m_m. The scale k_gauss is PX4's
    convention (a field in gauss, not unit norm); the rotation U cannot be held (CAL_MAGx_ROT is only
    an enum of coarse rotations).
    """
    _check_gyro(cal)
    to_gauss = gauss_per_unit(cal.mag_unit)
    W, sing, Vt = np.linalg.svd(cal.R)
    U, P = W @ Vt, Vt.T @ np.diag(sing) @ Vt
    if np.linalg.det(U) < 0:
        raise InputError("the magnetometer matrix R reflects the axes (det R < 0); PX4 cannot hold it")
    P = (P + P.T) / 2.0
    k_unit = float(np.prod(sing) ** (-1.0 / 3.0))
    return {"gyro_offset_rad_s": -np.linalg.solve(cal.K_g, cal.bias_rad_s),
            "mag_offset_gauss": cal.h * to_gauss, "mag_scale": P * k_unit,
            "mag_field_gauss": k_unit * to_gauss, "mag_rotation_U": U, "gauss_per_unit": to_gauss}


def px4_gyro_cost(cal: Calibration, rate_deg_s: float = 360.0) -> dict:
    """What PX4's offset-only gyro costs at a true rate of `rate_deg_s`: the error (K_g^-1 - I) w, in deg/s.

    per_axis_deg_s: |error| for a rotation about b's x, y, z axes; worst_deg_s: the largest over all directions
    (spectral norm of K_g^-1 - I times the rate), reached about `worst_axis` (a unit vector in frame b);
    misalignment_deg: the gyro-to-magnetometer rotation C_b_m, which PX4 cannot hold either.
    """
    E = np.linalg.inv(cal.K_g) - np.eye(3)
    _, sing, Vt = np.linalg.svd(E)
    return {"rate_deg_s": float(rate_deg_s),
            "per_axis_deg_s": np.linalg.norm(E, axis=0) * float(rate_deg_s),
            "worst_deg_s": float(sing[0] * rate_deg_s), "worst_axis": Vt[0],
            "misalignment_deg": _rotation_angle_deg(cal.C_b_m)}


def px4_text(cal: Calibration, source: str = "", rate_deg_s: float = 360.0) -> str:
    """A QGroundControl .params file: tab-separated vehicle id, component id, name, value, type (9 = REAL32)."""
    p, cost = px4_parameters(cal), px4_gyro_cost(cal, rate_deg_s)
    per_axis = ", ".join(f"{cost['per_axis_deg_s'][i]:.4f}" for i in range(3))
    U_angle = _rotation_angle_deg(p["mag_rotation_U"])
    header = ["# Onboard parameters for Vehicle 1",
              "#",
              "# Stack: PX4 Pro",
              f"# magyro calibration (magyro export --format px4), source: {_one_line(source)}",
              "# PX4 (PX4-Autopilot src/lib/sensor_calibration): gyro = rot (y - CAL_GYRO0_OFF), rad/s, offset only;",
              "#   mag = rot (S (y_m - CAL_MAG0_OFF)), gauss, S symmetric (SCALE diagonal, ODIAG = S01, S02, S12).",
              "# GYRO: OFF = -K_g^-1 eps_b, the reading at rest: exact at zero rate. PX4's Gyroscope.cpp reads no gyro",
              "#   scale, non-orthogonality or misalignment (older PX4 had CAL_GYRO0_{X,Y,Z}SCALE, a diagonal only;",
              "#   current PX4 reads only OFF), so at a true rate w it gives K_g^-1 w, an error of (K_g^-1 - I) w:",
              f"#   COST at {cost['rate_deg_s']:g} deg/s about the x, y, z axes: {per_axis} deg/s;",
              f"#   {cost['worst_deg_s']:.4f} deg/s about the worst direction.",
              "# Not held (magyro's w_b = K_g y + eps_b):",
              *(f"#   K_g row {i}: {yaml_array(cal.K_g[i])}" for i in range(3)),
              f"#   gyro-to-magnetometer rotation C_b_m ({cost['misalignment_deg']:.4f} deg), rows:",
              *(f"#     {yaml_array(cal.C_b_m[i])}" for i in range(3)),
              "# MAG: magyro's R = U P (U a rotation, P symmetric); PX4 holds S = P k, OFF = h, in gauss",
              f"#   (unit '{_one_line(cal.mag_unit)}' x {p['gauss_per_unit']:g}); k = {p['mag_field_gauss']:.6g} gauss,"
              " the field strength R normalises, so PX4's field = k U^T m_m:",
              f"#   its length is k, not 1, and its frame is turned by U ({U_angle:.4f} deg), which PX4 cannot hold.",
              "# CAL_GYRO0_ID / CAL_MAG0_ID are not written: index 0 must already be these sensors on the vehicle.",
              "# PX4 stores REAL32: values round to about 7 significant digits on the vehicle.",
              "#",
              "# Vehicle-Id Component-Id Name Value Type"]
    rows = []
    for i, ax in enumerate("XYZ"):
        rows.append((f"CAL_GYRO0_{ax}OFF", p["gyro_offset_rad_s"][i]))
    for i, ax in enumerate("XYZ"):
        rows.append((f"CAL_MAG0_{ax}OFF", p["mag_offset_gauss"][i]))
    for i, ax in enumerate("XYZ"):
        rows.append((f"CAL_MAG0_{ax}SCALE", p["mag_scale"][i, i]))
    S = p["mag_scale"]
    rows += [("CAL_MAG0_XODIAG", S[0, 1]), ("CAL_MAG0_YODIAG", S[0, 2]), ("CAL_MAG0_ZODIAG", S[1, 2])]
    return "\n".join(header + [f"1\t1\t{name}\t{yaml_number(value)}\t9" for name, value in rows]) + "\n"
