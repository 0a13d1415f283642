"""Exports for other tools (issue 12): Kalibr's `scale-misalignment` IMU yaml, and a PX4 parameter file; each with
an accelerometer block when the calibration has one (issue 26, `magyro solve --accelerometer`).

magyro's model (docs/spec.md section 1) maps a raw reading to the truth:

    w_b = K_g y + eps_b      (rad/s; K_g upper triangular; the bias is ADDED)
    m_m = R (y_m - h)        (unit norm; R upper triangular, h in the magnetometer's unit)

Kalibr -- repository ethz-asl/kalibr, aslam_offline_calibration/kalibr/python/kalibr_imu_camera_calibration/
IccSensors.py, class IccScaledMisalignedImu -- maps the truth to a reading:

    w_meas = M (C_gyro_i w_i) + A (C_gyro_i a_i) + b     (M lower triangular: MatrixBasicDv pattern
                                                          [[1,0,0],[1,1,0],[1,1,1]]; C_gyro_i a rotation;
                                                          A the g-sensitivity; b Kalibr's bias spline)

PX4 -- repository PX4/PX4-Autopilot, src/lib/sensor_calibration/Gyroscope.hpp, Magnetometer.hpp/.cpp and
Accelerometer.hpp/.cpp:

    gyro:  corrected = rotation (y - thermal_offset - CAL_GYROx_OFF)          (rad/s; offset only)
    mag:   corrected = rotation (S ((y_m + power COMP) - CAL_MAGx_OFF))      (gauss; S symmetric:
           diag CAL_MAGx_{X,Y,Z}SCALE, CAL_MAGx_ODIAG{X,Y,Z} = S01, S02, S12)
    acc:   corrected = rotation ((y_a - thermal_offset - CAL_ACCx_OFF) .* CAL_ACCx_SCALE)   (m/s^2; OFF and
           SCALE per axis {X,Y,Z}: a diagonal scale, no cross-axis term; the board rotation is the gyro's)

Kalibr's accelerometer (same class): y_a = M_accel (C_i_b a_b) + b, M_accel lower triangular, no rotation of its
own (frame i is the accelerometer's); see kalibr_parameters.
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


def _lq(A) -> tuple[np.ndarray, np.ndarray]:
    """(L, Q) with A = L Q, L lower triangular with a positive diagonal, Q orthogonal (a rotation when det A > 0):
    the QR of A^T."""
    Q, Rr = np.linalg.qr(np.asarray(A).T)      # A^T = Q Rr  =>  A = Rr^T Q^T
    D = np.diag(np.sign(np.diag(Rr)))
    return np.tril((D @ Rr).T), (Q @ D).T


def _check_accelerometer(cal: Calibration) -> None:
    if not np.all(np.diag(cal.accelerometer.K_a) > 0):
        raise InputError("the accelerometer scale factors (diagonal of K_a) are not all positive; nothing to export")


def kalibr_parameters(cal: Calibration) -> dict:
    """Kalibr's intrinsics equal to magyro's.

    Without an accelerometer Kalibr's frame i is magyro's gyro frame b. Inverting magyro: y = K_g^-1 w_b -
    K_g^-1 eps_b. Kalibr wants M lower triangular, so K_g^-1 is split as M C_gyro_i (an LQ decomposition: the
    QR of K_g^-T, diag(M) > 0, det C_gyro_i = +1) -- exact, no approximation; C_gyro_i is then only the
    rotation between the two triangular conventions. b = -K_g^-1 eps_b (Kalibr's sign: a reading, as at
    rest); A = 0 (magyro has no g-sensitivity term).

    With an accelerometer, Kalibr has no rotation for it: its reading is y_a = M_accel f_i + b_accel, so frame i
    is the accelerometer's. magyro: y_a = K_a^-1 C_b_a f_b - K_a^-1 eps_a; the LQ split K_a^-1 C_b_a = M_accel Q
    (exact) makes f_i = Q f_b, i.e. frame i is the accelerometer frame a turned by the rotation that makes
    M_accel lower triangular, and `i_to_b` = Q^T turns frame i into magyro's b. The gyro then splits
    K_g^-1 Q^T = M C_gyro_i (exact). b_accel = -K_a^-1 eps_a (m/s^2, Kalibr's sign).
    """
    _check_gyro(cal)
    K_inv = np.linalg.inv(cal.K_g)
    acc = cal.accelerometer
    if acc is None:
        M, C = _lq(K_inv)                      # K_inv = M C; det C = +1 as det K_inv > 0
        return {"M": M, "A": np.zeros((3, 3)), "C_gyro_i": C, "b": -K_inv @ cal.bias_rad_s}
    _check_accelerometer(cal)
    Ka_inv = np.linalg.inv(acc.K_a)
    M_accel, Q = _lq(Ka_inv @ acc.C_b_a)       # f_i = Q f_b
    M, C = _lq(K_inv @ Q.T)
    return {"M": M, "A": np.zeros((3, 3)), "C_gyro_i": C, "b": -K_inv @ cal.bias_rad_s,
            "M_accel": M_accel, "b_accel": -Ka_inv @ acc.bias_m_s2, "i_to_b": Q.T}


def kalibr_noise_lines(noise: dict | None, rostopic: str | None, indent: str) -> list[str]:
    """The keys Kalibr's ImuParameters reads besides the model (kalibr_common/ConfigReader.py: rostopic, a string;
    update_rate in Hz; the noise densities and random walks, each > 0), from `magyro.noise_allan.kalibr_values`."""
    if noise is None:
        return []
    keys = (("gyroscope_noise_density", "rad/s/sqrt(Hz)"), ("gyroscope_random_walk", "rad/s^2/sqrt(Hz)"),
            ("accelerometer_noise_density", "m/s^2/sqrt(Hz)"), ("accelerometer_random_walk", "m/s^3/sqrt(Hz)"),
            ("update_rate", "Hz"))
    return [f"{indent}rostopic: {json.dumps(str(rostopic or '/imu0'))}",
            *(f"{indent}{key}: {yaml_number(noise[key])}   # {unit}" for key, unit in keys)]


def _kalibr_noise_header(noise: dict | None, text: str) -> str:
    """With noise: its comment in place of 'no noise densities ... (add yours)', and Kalibr's --imu keys at the top
    level (its reader reads them there; the imu0 block is the layout of Kalibr's results-imu.yaml)."""
    if noise is None:
        return text
    said = ("# Noise: from magyro noise (the Allan deviation of a still recording), the largest axis of each, as Kalibr "
            "takes one\n# number per sensor; Kalibr's --imu reads the keys at the top level, repeated under imu0 as "
            "its results-imu.yaml has them.\n")
    text = text.replace("no noise densities, random walks or rostopic (add yours to use the\n# file as Kalibr input)",
                        "the noise below from magyro noise")
    text = text.replace("no noise densities, random walks or rostopic (add yours\n# to use the file as Kalibr input)",
                        "the noise below from magyro noise")
    head, imu = text.split("imu0:\n", 1)
    return head + said + "\n".join(kalibr_noise_lines(noise, noise.get("rostopic"), "")) + "\nimu0:\n" + imu


def kalibr_text(cal: Calibration, source: str = "", noise: dict | None = None, rostopic: str | None = None) -> str:
    """Kalibr's IMU yaml (model scale-misalignment), gyroscope block only, every number exact to the double; with
    `noise` (magyro.noise_allan.kalibr_values) and `rostopic` (default /imu0), every key Kalibr's reader needs."""
    p = kalibr_parameters(cal)
    noise = None if noise is None else {**noise, "rostopic": rostopic}
    if cal.accelerometer is not None:
        return _kalibr_noise_header(noise, _kalibr_text_with_accelerometer(cal, p, source, noise))
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
             *kalibr_noise_lines(noise, rostopic, "  "),
             *kalibr_gyroscope_lines(p),
             "  magyro:",
             "    # not Kalibr keys: w_m = C_b_m w_i (magnetometer frame); m_m = R (y_m - h), unit norm",
             f"    C_b_m: {yaml_array(cal.C_b_m)}",
             f"    mag_unit: {json.dumps(str(cal.mag_unit))}",
             f"    R: {yaml_array(cal.R)}",
             f"    h: {yaml_array(cal.h)}",
             ]
    return _kalibr_noise_header(noise, "\n".join(lines) + "\n")


def _kalibr_text_with_accelerometer(cal: Calibration, p: dict, source: str, noise: dict | None = None) -> str:
    """Kalibr's IMU yaml with its accelerometers block: frame i is the accelerometer's (kalibr_parameters)."""
    acc = cal.accelerometer
    to_b = _rotation_angle_deg(p["i_to_b"])
    lines = ["# magyro calibration as Kalibr's IMU yaml, model scale-misalignment (magyro export --format kalibr)",
             f"# source: {_one_line(source)}",
             "# Kalibr's model (ethz-asl/kalibr, kalibr_imu_camera_calibration/IccSensors.py, IccScaledMisalignedImu),",
             "# truth -> reading, in the IMU frame i:",
             "#   accelerometer: y_a = M_accel f_i + b_accel      (f_i specific force, m/s^2; M_accel lower triangular)",
             "#   gyro:          y   = M (C_gyro_i w_i) + A (C_gyro_i f_i) + b",
             "# Kalibr gives the accelerometer no rotation, so frame i is the accelerometer's. magyro (reading -> truth):",
             "#   f_a = K_a y_a + eps_a, f_b = C_b_a^T f_a; w_b = K_g y + eps_b; so, exactly (LQ splits):",
             "#   M_accel Q = K_a^-1 C_b_a    (M_accel lower triangular, Q a rotation: f_i = Q f_b)",
             "#   M C_gyro_i = K_g^-1 Q^T     (M lower triangular, C_gyro_i a rotation)",
             "#   b_accel = -K_a^-1 eps_a (m/s^2), b = -K_g^-1 eps_b (rad/s): Kalibr's sign, the reading at zero",
             "#   A = 0                        (magyro does not model g-sensitivity: 0 means 'not estimated')",
             "# To correct readings: f_i = M_accel^-1 (y_a - b_accel); w_i = C_gyro_i^T M^-1 (y - b - A C_gyro_i f_i);",
             "#   magyro's gyro frame b: f_b = i_to_b f_i, w_b = i_to_b w_i (i_to_b = Q^T, under 'magyro').",
             f"# Frame i is magyro's gyro frame b turned by {to_b:.6f} deg (C_b_a, {_rotation_angle_deg(acc.C_b_a):.6f} deg,"
             " and the",
             "# rotation between magyro's upper-triangular K_a and Kalibr's lower-triangular M_accel).",
             "# What this file cannot hold as Kalibr keys: Kalibr estimates its biases as splines per dataset and",
             "# writes none, so b and b_accel are extra keys; no noise densities, random walks or rostopic (add yours",
             "# to use the file as Kalibr input); i_to_b, the gravity, the magnetometer (R, h) and C_b_m are under",
             "# the extra key 'magyro'.",
             "imu0:",
             '  model: "scale-misalignment"',
             f"  T_i_b: {yaml_array(np.eye(4))}",
             f"  time_offset: {yaml_number(0.0)}",
             *kalibr_noise_lines(noise, None if noise is None else noise["rostopic"], "  "),
             "  accelerometers:",
             f"    M: {yaml_array(p['M_accel'])}",
             "    # not a Kalibr key: the constant accelerometer bias in Kalibr's sign, m/s^2",
             f"    b: {yaml_array(p['b_accel'])}",
             *kalibr_gyroscope_lines(p),
             "  magyro:",
             "    # not Kalibr keys: w_b = i_to_b w_i, f_b = i_to_b f_i (magyro's gyro frame b); w_m = C_b_m w_b",
             "    # (magnetometer frame); m_m = R (y_m - h), unit norm; g_m_s2 the gravity the accelerometer was",
             "    # calibrated against",
             f"    i_to_b: {yaml_array(p['i_to_b'])}",
             f"    C_b_m: {yaml_array(cal.C_b_m)}",
             f"    g_m_s2: {yaml_number(acc.g_m_s2)}",
             f"    mag_unit: {json.dumps(str(cal.mag_unit))}",
             f"    R: {yaml_array(cal.R)}",
             f"    h: {yaml_array(cal.h)}",
             ]
    return "\n".join(lines) + "\n"


# --------------------------------------------------------------------------- PX4


def _px4_accelerometer_comments(cal: Calibration) -> list[str]:
    a = px4_accelerometer(cal)
    acc = cal.accelerometer
    per_axis = ", ".join(f"{a['per_axis_m_s2'][i]:.4f}" for i in range(3))
    g = a["g_m_s2"]
    return ["# ACC: PX4 (Accelerometer.hpp): acc = rot ((y_a - CAL_ACC0_OFF) .* CAL_ACC0_SCALE), m/s^2, the scale a",
            "#   diagonal, the same board rotation as the gyro. magyro's f_a = K_a y_a + eps_a, f_b = C_b_a^T f_a:",
            "#   SCALE = diag(K_a); OFF = -K_a^-1 eps_a (the reading at zero specific force). PX4 then reads",
            "#   diag(K_a) K_a^-1 f_a: it cannot hold K_a's non-orthogonality (above its diagonal) nor C_b_a",
            f"#   ({a['misalignment_deg']:.4f} deg, gyro to accelerometer frame). COST at 1 g ({g:g} m/s^2):",
            f"#   {a['nonorth_worst_m_s2']:.4f} m/s^2 at most from the non-orthogonality alone (accelerometer frame);",
            f"#   with C_b_a lost too, in the gyro frame: {per_axis} m/s^2 with gravity along x, y, z,",
            f"#   {a['worst_m_s2']:.4f} m/s^2 ({100 * a['worst_m_s2'] / g:.2f} % of g; at most "
            f"{np.degrees(np.arcsin(min(1.0, a['worst_m_s2'] / g))):.3f} deg of tilt) in the worst direction.",
            "# Not held (magyro's f_a = K_a y_a + eps_a):",
            *(f"#   K_a row {i}: {yaml_array(acc.K_a[i])}" for i in range(3)),
            f"#   eps_a (m/s^2): {yaml_array(acc.bias_m_s2)}",
            "#   gyro-to-accelerometer rotation C_b_a, rows:",
            *(f"#     {yaml_array(acc.C_b_a[i])}" for i in range(3)),
            "# CAL_GYRO0_ID / CAL_MAG0_ID / CAL_ACC0_ID are not written: index 0 must already be these sensors on",
            "#   the vehicle."]


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


def px4_accelerometer(cal: Calibration) -> dict:
    """PX4's accelerometer values, what they imply and what they cost at 1 g (the calibration's gravity).

    PX4 (Accelerometer.hpp, Correct): f = rotation ((y_a - thermal_offset - CAL_ACCx_OFF) .* CAL_ACCx_SCALE), in
    m/s^2, the scale a diagonal. SCALE = diag(K_a), each axis's scale factor; OFF = -K_a^-1 eps_a, the reading at
    zero specific force. PX4 then gives diag(K_a) K_a^-1 f_a: an error (diag(K_a) K_a^-1 - I) f_a, linear in the
    true f_a (that OFF makes it so, the smallest worst case over a sphere |f| = g for that SCALE), from K_a's
    non-orthogonality, which PX4 cannot hold. PX4 also turns the accelerometer by the same board rotation as the
    gyro, so C_b_a is lost too: in the gyro frame b the error is (diag(K_a) K_a^-1 C_b_a - I) f_b.

    scale, offset_m_s2: the values; nonorth_worst_m_s2: the largest error at |f| = g in frame a (non-orthogonality
    alone); per_axis_m_s2: |error| for f = g along b's x, y, z axes (non-orthogonality and C_b_a); worst_m_s2:
    the largest over all directions, about `worst_axis` (a unit vector in frame b); misalignment_deg: the angle
    of C_b_a.
    """
    acc = cal.accelerometer
    check_finite(cal)
    _check_accelerometer(cal)
    g = float(acc.g_m_s2)
    D = np.diag(np.diag(acc.K_a))
    Ka_inv = np.linalg.inv(acc.K_a)
    E_a = D @ Ka_inv - np.eye(3)
    E_b = D @ Ka_inv @ acc.C_b_a - np.eye(3)
    _, sing, Vt = np.linalg.svd(E_b)
    return {"scale": np.diag(acc.K_a).copy(), "offset_m_s2": -Ka_inv @ acc.bias_m_s2, "g_m_s2": g,
            "nonorth_worst_m_s2": float(np.linalg.svd(E_a, compute_uv=False)[0] * g),
            "per_axis_m_s2": np.linalg.norm(E_b, axis=0) * g, "worst_m_s2": float(sing[0] * g),
            "worst_axis": Vt[0], "misalignment_deg": _rotation_angle_deg(acc.C_b_a)}


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
              *(_px4_accelerometer_comments(cal) if cal.accelerometer is not None else
                ["# CAL_GYRO0_ID / CAL_MAG0_ID are not written: index 0 must already be these sensors on the vehicle."]),
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
    if cal.accelerometer is not None:
        a = px4_accelerometer(cal)
        rows += [(f"CAL_ACC0_{ax}OFF", a["offset_m_s2"][i]) for i, ax in enumerate("XYZ")]
        rows += [(f"CAL_ACC0_{ax}SCALE", a["scale"][i]) for i, ax in enumerate("XYZ")]
    return "\n".join(header + [f"1\t1\t{name}\t{yaml_number(value)}\t9" for name, value in rows]) + "\n"


def kalibr_gyroscope_lines(p: dict) -> list[str]:
    """Kalibr's gyroscopes block of a split (M, A, C_gyro_i and the bias under the extra key b), with or without an
    accelerometer."""
    return ["  gyroscopes:",
            f"    M: {yaml_array(p['M'])}",
            f"    A: {yaml_array(p['A'])}",
            f"    C_gyro_i: {yaml_array(p['C_gyro_i'])}",
            "    # not a Kalibr key: the constant gyro bias in Kalibr's sign, rad/s",
            f"    b: {yaml_array(p['b'])}"]
