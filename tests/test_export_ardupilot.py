"""`magyro export --format ardupilot` (issue 41): the parameters, read back as Mission Planner / MAVProxy read them
and applied by ArduPilot's own formulas (re-implemented here from its sources, not through the exporter), against
magyro's correction: exact where ArduPilot can hold the calibration, within the file's stated cost elsewhere.

Calibrations are built directly (no solve): one ArduPilot can hold (K_g = I, C_b_m^T R symmetric, K_a diagonal,
C_b_a = I) and one it cannot (every term magyro has).
"""
from __future__ import annotations

import dataclasses
import re

import numpy as np
import pytest

import magyro
from magyro import so3
from magyro.errors import InputError
from magyro.result.accelerometer import AccelerometerCalibration
from magyro.result.export import export_text

G_M_S2 = 9.80665
MG_PER_UT = 10.0          # 1 mG = 0.1 uT
RATE_DEG_S = 360.0        # the rate the file states the gyro's cost at


# --------------------------------------------------------------------------- ArduPilot, from its sources


def read_parm(text: str) -> dict:
    """NAME -> value as MAVProxy loads a file (ArduPilot/pymavlink mavparm.py, MAVParmDict.load): lines starting
    with '#' skipped, ',' read as a space, exactly two fields."""
    params = {}
    for line in text.splitlines():
        line = line.strip()
        if not line or line[0] == "#":
            continue
        fields = line.replace(",", " ").split()
        assert len(fields) == 2, line
        assert len(fields[0]) <= 16, fields[0]        # ArduPilot's parameter names: at most 16 characters
        params[fields[0]] = float(fields[1])
    return params


def ardupilot_compass_mG(raw_mG, p: dict, dtype=float) -> np.ndarray:
    """AP_Compass_Backend.cpp, correct_field (rows are samples, already in the body frame): mag += OFS; mag *= SCALE
    (within its sanity range); mag = [[DIA_X, ODI_X, ODI_Y], [ODI_X, DIA_Y, ODI_Z], [ODI_Y, ODI_Z, DIA_Z]] mag."""
    v = lambda *names: np.array([p[n] for n in names], dtype=dtype)   # noqa: E731
    mag = np.asarray(raw_mG, dtype=dtype) + v("COMPASS_OFS_X", "COMPASS_OFS_Y", "COMPASS_OFS_Z")
    if 0.85 <= p["COMPASS_SCALE"] <= 1.4:
        mag = mag * dtype(p["COMPASS_SCALE"])
    dia, odi = v("COMPASS_DIA_X", "COMPASS_DIA_Y", "COMPASS_DIA_Z"), v("COMPASS_ODI_X", "COMPASS_ODI_Y", "COMPASS_ODI_Z")
    mat = np.array([[dia[0], odi[0], odi[1]], [odi[0], dia[1], odi[2]], [odi[1], odi[2], dia[2]]], dtype=dtype)
    return mag @ mat.T


def ardupilot_gyro_rad_s(raw_rad_s, p: dict) -> np.ndarray:
    """AP_InertialSensor_Backend.cpp, _rotate_and_correct_gyro: gyro -= INS_GYROFFS (board rotation none)."""
    return np.asarray(raw_rad_s) - np.array([p[f"INS_GYROFFS_{a}"] for a in "XYZ"])


def ardupilot_accel_m_s2(raw_m_s2, p: dict) -> np.ndarray:
    """AP_InertialSensor_Backend.cpp, _rotate_and_correct_accel: accel -= INS_ACCOFFS; accel.{x,y,z} *= INS_ACCSCAL."""
    return ((np.asarray(raw_m_s2) - np.array([p[f"INS_ACCOFFS_{a}"] for a in "XYZ"]))
            * np.array([p[f"INS_ACCSCAL_{a}"] for a in "XYZ"]))


# --------------------------------------------------------------------------- calibrations and raw samples


def accelerometer(K_a, bias_m_s2, C_b_a) -> AccelerometerCalibration:
    return AccelerometerCalibration(np.asarray(K_a, float), np.asarray(bias_m_s2, float), np.asarray(C_b_a, float),
                                    G_M_S2, np.array([0.0, 0.0, 1.0]), np.zeros((3, 3)), np.zeros(3), np.zeros(3))


def holdable_calibration():
    """Every term ArduPilot holds: K_g = I (an offset only), C_b_m^T R symmetric positive definite (C_b_m itself
    a rotation: the misalignment is in R's symmetric form), K_a diagonal and C_b_a = I."""
    C_b_m = so3.euler_to_dcm([0.7, -0.4, 1.3])
    P = np.array([[0.0222, 0.0003, -0.0002], [0.0003, 0.0224, 0.0001], [-0.0002, 0.0001, 0.0221]])   # 1/uT
    cal = magyro.Calibration.from_parameters(K_g=np.eye(3), bias_rad_s=[0.01, -0.02, 0.005], C_b_m=C_b_m,
                                             R=C_b_m @ P, h=[3.5, -12.25, 40.125], mag_unit="uT")
    return dataclasses.replace(cal, accelerometer=accelerometer(np.diag([1.003, 0.998, 1.011]), [0.12, -0.3, 0.05],
                                                                np.eye(3)))


def general_calibration():
    """Every term magyro has: K_g with scale and non-orthogonality, R upper triangular, K_a above its diagonal,
    C_b_a a rotation."""
    cal = magyro.Calibration.from_parameters(
        K_g=[[1.002, 0.0012, -0.0005], [0.0, 0.9981, 0.0007], [0.0, 0.0, 1.0011]], bias_rad_s=[0.01, -0.02, 0.005],
        C_b_m=so3.euler_to_dcm([0.7, -0.4, 1.3]),      # deg
        R=[[0.0222, 0.0003, -0.0002], [0.0, 0.0224, 0.0001], [0.0, 0.0, 0.0221]],
        h=[3.5, -12.25, 40.125], mag_unit="uT")
    K_a = [[1.003, 0.004, -0.002], [0.0, 0.998, 0.003], [0.0, 0.0, 1.011]]
    return dataclasses.replace(cal, accelerometer=accelerometer(K_a, [0.12, -0.3, 0.05],
                                                                so3.euler_to_dcm([0.5, 0.3, -0.8])))


def unit_vectors(n: int, seed: int) -> np.ndarray:
    v = np.random.default_rng(seed).normal(size=(n, 3))
    return v / np.linalg.norm(v, axis=1, keepdims=True)


def raw_magnetometer_uT(cal, n=2000) -> np.ndarray:
    """Raw readings of a homogeneous field in every direction: R (y - h) a unit vector."""
    return unit_vectors(n, 1) @ np.linalg.inv(cal.R).T + cal.h


def raw_accelerometer_m_s2(cal, n=2000) -> np.ndarray:
    """Raw readings of gravity in every direction: f_a = K_a y_a + eps_a of length g."""
    acc = cal.accelerometer
    return (G_M_S2 * unit_vectors(n, 2) - acc.bias_m_s2) @ np.linalg.inv(acc.K_a).T


def stated(text: str, pattern: str) -> float:
    """A number the file states, found by the words around it."""
    found = re.search(pattern, text)
    assert found, pattern
    return float(found.group(1))


def angle_deg(a, b) -> np.ndarray:
    cos = np.sum(a * b, axis=1) / (np.linalg.norm(a, axis=1) * np.linalg.norm(b, axis=1))
    return np.degrees(np.arccos(np.clip(cos, -1.0, 1.0)))


# --------------------------------------------------------------------------- the compass


def test_compass_is_magyros_field_in_the_gyro_frame_where_ardupilot_can_hold_it():
    cal = holdable_calibration()
    params = read_parm(export_text(cal, "ardupilot", source="holdable.json"))
    raw_uT = raw_magnetometer_uT(cal)
    _, field_m = cal.apply(np.zeros_like(raw_uT), raw_uT)
    field_b = field_m @ cal.C_b_m                        # C_b_m^T m_m per row: ArduPilot's body frame is the gyro's
    strength_mG = MG_PER_UT / np.cbrt(np.linalg.det(cal.R))
    ardupilot = ardupilot_compass_mG(raw_uT * MG_PER_UT, params) / strength_mG
    assert np.max(np.abs(ardupilot - field_b)) < 1e-6
    # on the vehicle: float32 parameters and arithmetic
    ardupilot32 = ardupilot_compass_mG((raw_uT * MG_PER_UT).astype(np.float32), params, dtype=np.float32)
    assert np.max(np.abs(ardupilot32 / strength_mG - field_b)) < 1e-6
    assert params["COMPASS_SCALE"] == 1.0


def test_compass_elsewhere_is_turned_by_the_stated_angle_and_no_more():
    cal = general_calibration()
    text = export_text(cal, "ardupilot", source="general.json")
    params = read_parm(text)
    raw_uT = raw_magnetometer_uT(cal)
    _, field_m = cal.apply(np.zeros_like(raw_uT), raw_uT)
    field_b = field_m @ cal.C_b_m
    ardupilot = ardupilot_compass_mG(raw_uT * MG_PER_UT, params)
    turned_deg = stated(text, r"the field is turned by ([0-9.]+) deg from the gyro frame")
    assert turned_deg > 0.1                               # a calibration ArduPilot cannot hold
    angles = angle_deg(ardupilot, field_b)
    assert np.max(angles) <= turned_deg + 1e-4            # the file's 4 decimals
    assert np.max(angles) > 0.99 * turned_deg             # reached for a field square to the rotation's axis
    strength_mG = stated(text, r"ArduPilot's field is then ([0-9.]+) mG")
    np.testing.assert_allclose(np.linalg.norm(ardupilot, axis=1), strength_mG, rtol=1e-5)   # the true strength


def test_a_unit_that_is_not_a_field_is_refused_with_one_message(tmp_path, run_magyro, assert_plain_failure):
    cal = dataclasses.replace(general_calibration(), mag_unit="counts")
    with pytest.raises(InputError, match="'counts' cannot be converted to milligauss"):
        export_text(cal, "ardupilot")
    path, out = tmp_path / "counts.json", tmp_path / "counts.parm"
    cal.to_json(path)
    message = assert_plain_failure(run_magyro("export", path, "--format", "ardupilot", "-o", out), 2)
    assert "cannot be converted to milligauss" in message and not out.exists()


# --------------------------------------------------------------------------- the gyro


def test_gyro_offsets_are_magyros_rates_where_ardupilot_can_hold_them():
    cal = holdable_calibration()
    params = read_parm(export_text(cal, "ardupilot"))
    raw = np.radians(RATE_DEG_S) * unit_vectors(500, 3)
    assert np.max(np.abs(ardupilot_gyro_rad_s(raw, params) - cal.apply(raw)[0])) < 1e-12   # rad/s


def test_gyro_elsewhere_is_exact_at_rest_and_off_by_the_stated_cost_at_360_deg_s():
    cal = general_calibration()
    text = export_text(cal, "ardupilot")
    params = read_parm(text)
    at_rest = -np.linalg.solve(cal.K_g, cal.bias_rad_s)           # magyro's rate there is 0
    assert np.max(np.abs(ardupilot_gyro_rad_s(at_rest[None, :], params))) < 1e-15
    per_axis = [float(v) for v in re.search(r"about x, y, z that is ([0-9.]+), ([0-9.]+), ([0-9.]+) deg/s",
                                            text).groups()]
    worst = stated(text, r"([0-9.]+) deg/s about the worst direction")
    for axis in range(3):                                          # a true rate of 360 deg/s about b's axis
        w_true = np.radians(RATE_DEG_S) * np.eye(3)[axis]
        raw = np.linalg.solve(cal.K_g, w_true - cal.bias_rad_s)
        error_deg_s = np.degrees(np.linalg.norm(ardupilot_gyro_rad_s(raw[None, :], params)[0] - w_true))
        assert abs(error_deg_s - per_axis[axis]) <= 1e-4            # the file's 4 decimals
    w_true = np.radians(RATE_DEG_S) * unit_vectors(2000, 4)
    raw = np.linalg.solve(cal.K_g, (w_true - cal.bias_rad_s).T).T
    errors = np.degrees(np.linalg.norm(ardupilot_gyro_rad_s(raw, params) - w_true, axis=1))
    assert np.max(errors) <= worst + 1e-4 and np.max(errors) > 0.9 * worst
    assert "INS_GYR_CAL = 0" in text                                # ArduPilot re-learns the offsets at boot


# --------------------------------------------------------------------------- the accelerometer


def test_accelerometer_is_magyros_where_ardupilot_can_hold_it():
    cal = holdable_calibration()
    params = read_parm(export_text(cal, "ardupilot"))
    raw = raw_accelerometer_m_s2(cal)
    assert np.max(np.abs(ardupilot_accel_m_s2(raw, params) - cal.apply_accelerometer(raw))) < 1e-9   # m/s^2


def test_accelerometer_elsewhere_is_off_by_no_more_than_the_stated_cost_at_1_g():
    cal = general_calibration()
    text = export_text(cal, "ardupilot")
    params = read_parm(text)
    raw = raw_accelerometer_m_s2(cal)
    errors = np.linalg.norm(ardupilot_accel_m_s2(raw, params) - cal.apply_accelerometer(raw), axis=1)   # frame b
    worst = stated(text, r"([0-9.]+) m/s\^2 with C_b_a in the worst direction")
    assert np.max(errors) <= worst + 1e-4 and np.max(errors) > 0.9 * worst
    at_zero = -np.linalg.solve(cal.accelerometer.K_a, cal.accelerometer.bias_m_s2)   # magyro's f there is 0
    assert np.max(np.abs(ardupilot_accel_m_s2(at_zero[None, :], params))) < 1e-15


def test_without_an_accelerometer_no_ins_acc_parameters():
    params = read_parm(export_text(dataclasses.replace(general_calibration(), accelerometer=None), "ardupilot"))
    assert not [name for name in params if name.startswith("INS_ACC")]
    assert {"COMPASS_OFS_X", "COMPASS_ODI_Z", "INS_GYROFFS_Z"} <= set(params)


# --------------------------------------------------------------------------- the command


def test_cli_writes_the_file_and_states_what_ardupilot_cannot_hold_on_stderr(tmp_path, run_magyro):
    path, out = tmp_path / "general.json", tmp_path / "general.parm"
    general_calibration().to_json(path)
    written = run_magyro("export", path, "--format", "ardupilot", "-o", out)
    assert written.returncode == 0, written.stderr
    assert read_parm(out.read_text(encoding="utf-8")) == read_parm(export_text(general_calibration(), "ardupilot",
                                                                               source=str(path)))
    said = written.stderr.splitlines()
    assert len(said) == 3 and all(line.startswith("ardupilot cannot hold: ") for line in said), written.stderr
    assert "GYRO" in said[0] and "COMPASS" in said[1] and "ACCEL" in said[2]


def test_an_offset_above_ardupilots_arming_limit_is_stated():
    cal = general_calibration()
    assert "COMPASS_OFFS_MAX" not in export_text(cal, "ardupilot")       # 401 mG: within the 1800 mG default
    far = dataclasses.replace(cal, h=np.array([3.5, -12.25, 240.0]))     # 2400 mG
    assert "COMPASS_OFS up to 2400.0 mG: above COMPASS_OFFS_MAX's default" in export_text(far, "ardupilot")


def test_on_broad_02_s_own_samples_ardupilot_is_within_what_the_file_states(broad02_acc_solved):
    """The shipped trial, solved once per run (conftest): its raw samples through ArduPilot's formulas."""
    session, cal = broad02_acc_solved
    text = export_text(cal, "ardupilot", source="broad-02")
    params = read_parm(text)
    assert cal.mag_unit == "uT"
    _, field_m = cal.apply(np.zeros_like(session.mag), session.mag)
    ardupilot = ardupilot_compass_mG(session.mag * MG_PER_UT, params)
    turned_deg = stated(text, r"the field is turned by ([0-9.]+) deg from the gyro frame")
    assert np.max(angle_deg(ardupilot, field_m @ cal.C_b_m)) <= turned_deg + 1e-4
    rates = cal.apply(session.gyro_rad_s)[0]
    error_deg_s = np.degrees(np.linalg.norm(ardupilot_gyro_rad_s(session.gyro_rad_s, params) - rates, axis=1))
    worst_per_deg_s = stated(text, r"([0-9.]+) deg/s about the worst direction") / RATE_DEG_S
    assert np.all(error_deg_s <= worst_per_deg_s * np.degrees(np.linalg.norm(rates, axis=1)) + 1e-9)
