"""The QR split K = C_b_m K_g and handedness (SPEC section 1), unit and end to end.

Handedness, worked out: the gyro reports an angular velocity (a pseudovector), the
magnetometer a vector. If a magnetometer axis is negated (y_m' = D y_m, det D = -1),
the field seen in its frame turns with rate w' = -D w^m, and -D is a proper rotation,
so K' = (-D C_b_m) K_g: still det K > 0, the mirror is invisible and C_b_m comes out
rotated by 180 deg. If a *gyro* axis is negated (y_g' = D y_g), K' = K D has det < 0:
that is the case the QR split can and must refuse.
"""
from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from magyro import so3
from magyro.nls.solve import calibrate
from magyro.errors import InputError
from magyro.io.sessions import write_session
from magyro.result.calibration import misalignment_vector, qr_split
from magyro.studies.simulate import load_problem, simulate

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
    assert np.all(np.abs(mirrored.K_g - straight.K_g) <= tol * straight.std["K_g"] + 1e-15)
    assert np.all(np.abs(mirrored.bias_deg_s - straight.bias_deg_s) <= tol * straight.std["bias_deg_s"])
    d = np.rad2deg(misalignment_vector(mirrored.C_b_m, -MIRROR_Z @ straight.C_b_m))
    assert np.all(np.abs(d) <= tol * straight.std["misalignment_deg"]), d
    assert np.all(np.abs(mirrored.R - MIRROR_Z @ straight.R @ MIRROR_Z) <= tol * straight.std["R"] + 1e-15)
    assert np.linalg.det(mirrored.C_b_m) == pytest.approx(1.0, abs=1e-12)
    # what the user is told instead: a misalignment far beyond any mounting tolerance
    assert any("axis mapping is probably wrong" in w for w in mirrored.warnings)
    assert not any("axis mapping" in w for w in straight.warnings)
