"""The QR split K = C_b_m K_g and handedness (docs/spec.md section 1), unit and end to end.

Handedness, worked out: the gyro reports an angular velocity (a pseudovector), the
magnetometer a vector. If a magnetometer axis is negated (y_m' = D y_m, det D = -1),
the field seen in its frame turns with rate w' = -D w^m, and -D is a proper rotation,
so K' = (-D C_b_m) K_g: still det K > 0, the mirror is invisible and C_b_m comes out
rotated by 180 deg. If a *gyro* axis is negated (y_g' = D y_g), K' = K D has det < 0:
that is the case the QR split can and must refuse.
"""
from __future__ import annotations

import dataclasses
import json

import numpy as np
import pytest

from magyro import so3
from magyro import calibrate
from magyro.errors import InputError
from magyro.io import write_session
from magyro.result.reported import misalignment_vector, qr_split
from magyro.studies.scenario import load_problem
from magyro.result.calibration import Calibration
from magyro.result.fit import LeastSquaresFit
from magyro.result.parts import Std
from magyro.studies.simulate import simulate, truth_body_rate

MIRROR_Z = np.diag([1.0, 1.0, -1.0])
N_RANDOM = 300


def random_rotation(rng) -> np.ndarray:
    """Uniform on SO(3): QR of a Gaussian matrix with the signs fixed, det +1."""
    Q, R = np.linalg.qr(rng.standard_normal((3, 3)))
    Q = Q @ np.diag(np.sign(np.diag(R)))
    if np.linalg.det(Q) < 0:
        Q[:, 0] = -Q[:, 0]
    return Q


def random_upper(rng) -> np.ndarray:
    """Upper triangular, positive diagonal (scale 0.5..2, non-orthogonality up to +/-0.5)."""
    K = np.triu(rng.uniform(-0.5, 0.5, (3, 3)), 1)
    K[np.diag_indices(3)] = rng.uniform(0.5, 2.0, 3)
    return K


def test_qr_split_returns_rotation_and_upper_factor():
    rng = np.random.default_rng(20240601)
    for _ in range(N_RANDOM):
        C, Kg = random_rotation(rng), random_upper(rng)
        C_out, Kg_out = qr_split(C @ Kg)
        np.testing.assert_allclose(C_out, C, atol=1e-12, rtol=0)
        np.testing.assert_allclose(Kg_out, Kg, atol=1e-12, rtol=0)
        assert np.all(np.diag(Kg_out) > 0)
        assert np.linalg.det(C_out) == pytest.approx(1.0, abs=1e-12)


def test_qr_split_of_any_proper_matrix_has_positive_diagonal():
    rng = np.random.default_rng(7)
    done = 0
    while done < N_RANDOM:
        K = rng.standard_normal((3, 3))
        if np.linalg.det(K) <= 0:
            continue
        C, Kg = qr_split(K)
        assert np.all(np.diag(Kg) > 0)
        assert np.all(np.tril(Kg, -1) == 0)
        np.testing.assert_allclose(C.T @ C, np.eye(3), atol=1e-12)
        assert np.linalg.det(C) == pytest.approx(1.0, abs=1e-12)
        np.testing.assert_allclose(C @ Kg, K, atol=1e-12)
        done += 1


@pytest.mark.parametrize("where", ["left", "right"])
def test_qr_split_refuses_an_improper_matrix(where):
    rng = np.random.default_rng(3)
    for _ in range(50):
        C, Kg = random_rotation(rng), random_upper(rng)
        K = MIRROR_Z @ C @ Kg if where == "left" else C @ Kg @ MIRROR_Z
        with pytest.raises(InputError, match="mirror"):
            qr_split(K)


def test_misalignment_vector_inverts_exp():
    rng = np.random.default_rng(5)
    for _ in range(100):
        C_ref = random_rotation(rng)
        d = rng.standard_normal(3)
        d *= rng.uniform(0.0, 3.0) / np.linalg.norm(d)  # |d| < pi
        np.testing.assert_allclose(misalignment_vector(C_ref, C_ref @ so3.exp_so3(d)), d, atol=1e-10)


# --------------------------------------------------------------------------- end to end


@pytest.fixture(scope="module")
def paper_session():
    return simulate(load_problem("paper-table1"), 11)


@pytest.fixture(scope="module")
def mirrored_gyro(paper_session):
    """paper-table1 with the gyro's z column negated: a left-handed gyro against the magnetometer."""
    session, _ = paper_session
    return dataclasses.replace(session, gyro_rad_s=session.gyro_rad_s @ MIRROR_Z)


@pytest.mark.slow
def test_calibrate_refuses_a_mirrored_axis_mapping(mirrored_gyro):
    with pytest.raises(InputError, match="mirror") as info:
        calibrate(mirrored_gyro)
    assert info.value.exit_code == 2
    assert "\n" not in str(info.value)


@pytest.mark.slow
def test_cli_mirror_exits_2_with_plain_message(mirrored_gyro, tmp_path, run_magyro, assert_plain_failure):
    path = tmp_path / "mirror.parquet"
    write_session(mirrored_gyro, path)
    out = tmp_path / "calib.json"
    message = assert_plain_failure(run_magyro("solve", path, "-o", out), 2)
    assert "mirror" in message
    assert not out.exists()


@pytest.mark.slow
def test_mirrored_magnetometer_axis_is_indistinguishable_from_a_rotation(paper_session, solve_cache):
    """Negating mz cannot be detected: the solve is the unmirrored one with C_b_m -> diag(-1,-1,1) C_b_m.

    K_g and the bias are unchanged, R -> D R D; so a mirrored magnetometer is not what the
    det(C_b_m) = -1 check can catch (see the module doc); it shows as a 180 deg misalignment.
    """
    session, _ = paper_session
    mirrored = calibrate(dataclasses.replace(session, mag=session.mag @ MIRROR_Z))
    straight = solve_cache("paper-table1", 11).cal
    tol = 0.01  # of the straight solve's one sigma: the two problems are the same up to the rotation
    assert np.all(np.abs(mirrored.K_g - straight.K_g) <= tol * straight.std.K_g + 1e-15)
    assert np.all(np.abs(mirrored.bias_deg_s - straight.bias_deg_s) <= tol * straight.std.bias_deg_s)
    d = np.rad2deg(misalignment_vector(mirrored.C_b_m, -MIRROR_Z @ straight.C_b_m))
    assert np.all(np.abs(d) <= tol * straight.std.misalignment_deg), d
    assert np.all(np.abs(mirrored.R - MIRROR_Z @ straight.R @ MIRROR_Z) <= tol * straight.std.R + 1e-15)
    assert np.linalg.det(mirrored.C_b_m) == pytest.approx(1.0, abs=1e-12)
    # what the user is told instead: a misalignment far beyond any mounting tolerance
    assert any("axis mapping is probably wrong" in w for w in mirrored.warnings)
    assert not any("axis mapping" in w for w in straight.warnings)


# --------------------------------------------------------------------------- the calibration file


@pytest.fixture(scope="module")
def solved_phone(phone_solved):
    return phone_solved.cal


def test_from_json_reads_back_what_to_json_wrote(solved_phone, tmp_path):
    path = tmp_path / "calib.json"
    solved_phone.to_json(path)
    back = Calibration.from_json(path)
    assert back.to_dict() == solved_phone.to_dict()
    assert isinstance(back.std, Std) and back.std.K_g.shape == (3, 3)
    assert back.observability.rank == 12 and back.solver.method == "nls"
    assert back.solver.details["stride"] == solved_phone.solver.details["stride"]
    assert Calibration.from_json(path.read_text()).to_dict() == back.to_dict()   # the text itself


def test_apply_is_the_model_in_both_frames(solved_phone, phone_solved):
    """omega_b = K_g y + eps_b, omega_m = C_b_m omega_b, and the field R (y_m - h) has unit norm."""
    cal, session = solved_phone, phone_solved.session
    y, y_m = session.gyro_rad_s[:500], session.mag[:500]
    kept_y, kept_m = y.copy(), y_m.copy()
    omega_b, field = cal.apply(y, y_m)
    omega_m, _ = cal.apply(y, frame="m")
    for k in (0, 137, 499):
        np.testing.assert_allclose(omega_b[k], cal.K_g @ y[k] + cal.bias_rad_s, rtol=0, atol=1e-15)
        np.testing.assert_allclose(field[k], cal.R @ (y_m[k] - cal.h), rtol=1e-14)
    np.testing.assert_allclose(omega_m, omega_b @ cal.C_b_m.T, atol=1e-14)
    norm = np.linalg.norm(field, axis=1)
    assert abs(np.mean(norm) - 1.0) < 0.01 and np.std(norm) < 0.05   # the simulated field is homogeneous
    np.testing.assert_array_equal(y, kept_y)
    np.testing.assert_array_equal(y_m, kept_m)
    with pytest.raises(InputError, match="unknown frame"):
        cal.apply(y, frame="i")


def test_apply_turns_the_raw_gyro_into_the_true_rate(phone_solved):
    """Applied to the raw simulated gyro, the calibration gives the true body rate within a few sigma of noise."""
    cal, session, problem = phone_solved.cal, phone_solved.session, load_problem(phone_solved.name)
    true_rate = truth_body_rate(problem, session.t_gyro_s)
    raw_error = np.sqrt(np.mean((session.gyro_rad_s - true_rate) ** 2))
    calibrated_error = np.sqrt(np.mean((cal.apply(session.gyro_rad_s)[0] - true_rate) ** 2))
    noise_rad_s = problem.gyro_noise_density_rad_s_sqrt_hz * np.sqrt(problem.gyro_rate_hz)
    assert calibrated_error < 1.2 * noise_rad_s < raw_error, (calibrated_error, noise_rad_s, raw_error)


def test_fit_statistics_read_back_by_method(solved_phone, tmp_path):
    """The fit section is the method's own type, written and read back whole."""
    fit = solved_phone.fit
    assert isinstance(fit, LeastSquaresFit) and fit.residuals > fit.unknowns > 0
    assert 0.5 < fit.mag_rms_normalised < 1.5 and fit.field_change.max_fraction < 0.05
    doc = solved_phone.to_dict()
    doc["solver"]["method"] = "ekf"      # least-squares statistics under the filter's name
    with pytest.raises(InputError, match="not the EKF's fit statistics"):
        Calibration.from_json(json.dumps(doc))
    doc["solver"]["method"] = "kalibr"
    with pytest.raises(InputError, match="not one this version of magyro knows"):
        Calibration.from_json(json.dumps(doc))
