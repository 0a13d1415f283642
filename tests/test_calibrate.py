"""The joint calibration recovers simulated truth within its own reported uncertainty.

paper-table1 (Wu & Pei Table I) and phone-module (hard/soft iron, 200 Hz gyro, 50 Hz
magnetometer) are each solved once per seed (session fixtures in conftest.py).
"""
from __future__ import annotations

import json

import numpy as np
import pytest

from magyro.result.calibration import SCHEMA

from magyro.result.reported import misalignment_vector
from magyro.studies.scenario import load_problem

pytestmark = pytest.mark.slow  # every test here needs a solve (shared, but the first user pays)

K_SIGMA = 4.0
UPPER = [(0, 0), (0, 1), (0, 2), (1, 1), (1, 2), (2, 2)]
OFF_DIAGONAL = [(0, 1), (0, 2), (1, 2)]


def upper(M) -> np.ndarray:
    M = np.asarray(M, dtype=float)
    return np.array([M[i, j] for i, j in UPPER])


def assert_within_sigma(estimate, truth, std, what: str, k: float = K_SIGMA) -> None:
    estimate, truth, std = (np.asarray(a, dtype=float) for a in (estimate, truth, std))
    assert estimate.shape == truth.shape == std.shape, what
    assert np.all(np.isfinite(std)) and np.all(std > 0), f"{what}: reported std {std}"
    z = (estimate - truth) / std
    assert np.all(np.abs(z) <= k), f"{what}: error / reported sigma = {np.round(z, 2)} (limit {k})"


def misalignment_deg(cal, truth) -> np.ndarray:
    """d in degrees with C_b_m(true) = C_b_m(est) Exp(d) (docs/spec.md section 4)."""
    return np.rad2deg(misalignment_vector(cal.C_b_m, np.array(truth["misalignment"]["C_b_m"])))


def check_gyro_recovery(solved) -> None:
    cal, truth = solved.cal, solved.truth
    assert_within_sigma(upper(cal.K_g), upper(truth["gyro"]["K_g"]), upper(cal.std.K_g), "K_g (upper)")
    assert_within_sigma(cal.bias_deg_s, truth["gyro"]["bias_deg_s"], cal.std.bias_deg_s, "bias deg/s")
    assert_within_sigma(misalignment_deg(cal, truth), np.zeros(3), cal.std.misalignment_deg,
                        "misalignment d (deg)")


# --------------------------------------------------------------------------- paper-table1


def test_paper_gyro_parameters_within_4_sigma_of_truth(paper_solved):
    check_gyro_recovery(paper_solved)


def test_paper_field_within_4_sigma_of_truth(paper_solved):
    cal, truth = paper_solved.cal, paper_solved.truth
    assert_within_sigma(cal.field_i, truth["field_i"], cal.std.field_i, "field_i")
    assert np.linalg.norm(cal.field_i) == pytest.approx(1.0, abs=1e-9)


def test_paper_reported_sigma_within_the_papers_3_sigma_figures(paper_solved):
    """Table I text: scale 900 ppm, non-orthogonality 0.09 deg, bias 0.02 deg/s, misalignment 0.06 deg."""
    std = paper_solved.cal.std
    diag = np.diag(std.K_g)
    off = np.array([std.K_g[i, j] for i, j in OFF_DIAGONAL])
    assert np.all(diag > 0) and np.all(diag <= 900e-6), diag
    assert np.all(off > 0) and np.all(off <= np.deg2rad(0.09)), off
    assert np.all(std.bias_deg_s > 0) and np.all(std.bias_deg_s <= 0.02), std.bias_deg_s
    assert np.all(std.misalignment_deg > 0) and np.all(std.misalignment_deg <= 0.06), std.misalignment_deg


def test_paper_calibration_is_self_consistent(paper_solved):
    cal = paper_solved.cal
    np.testing.assert_allclose(cal.K, cal.C_b_m @ cal.K_g, atol=1e-12)
    np.testing.assert_allclose(cal.C_b_m.T @ cal.C_b_m, np.eye(3), atol=1e-12)
    assert np.linalg.det(cal.C_b_m) == pytest.approx(1.0, abs=1e-12)
    assert np.all(np.diag(cal.K_g) > 0) and np.all(np.tril(cal.K_g, -1) == 0)
    np.testing.assert_allclose(cal.bias_rad_s, cal.C_b_m.T @ cal.eps_rad_s, atol=1e-15)
    assert cal.observability.rank == 12
    assert cal.solver.method == "nls"
    assert cal.solver.status in ("Solve_Succeeded", "Solved_To_Acceptable_Level")
    solver_line = next(line for line in cal.table().splitlines() if line.startswith("solver:"))
    assert solver_line.startswith("solver: nls converged") and "_" not in solver_line, solver_line   # words, not IPOPT's


def test_to_dict_is_json_serialisable_and_matches_the_calibration(paper_solved):
    cal = paper_solved.cal
    text = json.dumps(cal.to_dict())
    back = json.loads(text)
    assert back["schema"] == SCHEMA == "magyro.calibration/1"
    np.testing.assert_array_equal(np.array(back["gyro"]["K_g"]), cal.K_g)
    np.testing.assert_array_equal(np.array(back["misalignment"]["C_b_m"]), cal.C_b_m)
    np.testing.assert_array_equal(np.array(back["std"]["misalignment_deg"]), cal.std.misalignment_deg)
    assert back == json.loads(cal.to_json())


# --------------------------------------------------------------------------- phone-module


def test_phone_session_is_asynchronous(phone_solved):
    problem = load_problem("phone-module")
    s = phone_solved.session
    assert len(s.t_gyro_s) != len(s.t_mag_s)
    assert s.gyro_rate_hz == pytest.approx(problem.gyro_rate_hz, rel=1e-9)
    assert s.mag_rate_hz == pytest.approx(problem.mag_rate_hz, rel=1e-9)
    assert problem.gyro_rate_hz != problem.mag_rate_hz
    # the shared table kept each sensor's own samples (the file leaves the other sensor empty)
    assert len(s.t_gyro_s) == int(problem.duration_s * problem.gyro_rate_hz) + 1
    assert len(s.t_mag_s) == int(problem.duration_s * problem.mag_rate_hz) + 1


def test_phone_magnetometer_hard_and_soft_iron_within_4_sigma(phone_solved):
    cal, truth = phone_solved.cal, phone_solved.truth
    R_true, h_true = np.array(truth["magnetometer"]["R"]), np.array(truth["magnetometer"]["h"])
    # the problem is not trivially identity/zero: soft iron off identity, hard iron tens of uT
    assert np.max(np.abs(h_true)) >= 10.0
    assert np.max(np.abs(np.triu(R_true, 1))) > 0
    assert_within_sigma(upper(cal.R), upper(R_true), upper(cal.std.R), "R (upper)")
    assert_within_sigma(cal.h, h_true, cal.std.h, "h (uT)")
    assert cal.mag_unit == truth["magnetometer"]["unit"] == "uT"


def test_phone_gyro_parameters_within_4_sigma_of_truth(phone_solved):
    check_gyro_recovery(phone_solved)


def test_phone_field_within_4_sigma_of_truth(phone_solved):
    cal, truth = phone_solved.cal, phone_solved.truth
    assert_within_sigma(cal.field_i, truth["field_i"], cal.std.field_i, "field_i")
