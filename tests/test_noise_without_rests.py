"""Noise levels that hold without rests (issue 22): a phone turned by hand at 28/25 Hz with no rest.

The levels come from the floor of the differences' levels (where they stop falling with the order), and
when that floor is not reached the least squares estimates them (variance components); either way the
JSON says where each level came from and a level that stays a guess is a warning.
"""
from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from magyro.front import noise
from magyro.front.differences import noise_floor_std, white_noise_std
from magyro.front.prepare import prepare
from magyro.nls.method import NLS
from magyro.nls.diagnostics import guessed_level_warnings, level_sources
from magyro.nls.run import calibrate_nls, level_estimator, not_converged_message
from magyro.nls.solve import build_problem, solve_passes
from magyro.nls.variance import MIN_REDUNDANCY, block_tridiagonal_inverse_band
from magyro.options import Options
from magyro.studies.scenario import load_problem
from magyro.studies.simulate import simulate

PROBLEM = "problems/phone-no-rest.toml"


@pytest.fixture(scope="module")
def no_rest():
    """(session, truth, calibration) of one simulated no-rest phone recording, solved once."""
    session, truth = simulate(load_problem(PROBLEM), 7)
    return session, truth, calibrate_nls(session)


def test_levels_without_rests_match_the_truth(no_rest):
    session, truth, cal = no_rest
    assert cal.rests is None or cal.rests.seconds < 2.0   # nothing still to measure the noise on
    gyro_true, mag_true = truth["noise"]["gyro_density_rad_s_sqrt_hz"], truth["noise"]["mag_std"]
    assert cal.noise.gyro_density_rad_s_sqrt_hz == pytest.approx(gyro_true, rel=0.2)
    assert cal.noise.mag_std == pytest.approx(mag_true, rel=0.2)
    assert cal.noise.gyro_source in (noise.DIFFERENCES, noise.ESTIMATED)
    assert cal.noise.mag_source in (noise.DIFFERENCES, noise.ESTIMATED)
    assert not [w for w in cal.warnings if "a guess" in w]
    out = cal.to_dict()["noise"]
    assert out["gyro_source"] == cal.noise.gyro_source and out["mag_source"] == cal.noise.mag_source
    assert "noise: gyro" in cal.table() and "(differences)" in cal.table()


def test_no_rest_solve_lands_within_its_std(no_rest):
    _, truth, cal = no_rest
    assert cal.solver.status.startswith("Solve")
    z_K = (cal.K_g - np.array(truth["gyro"]["K_g"])) / np.maximum(np.array(cal.std.K_g), 1e-12)
    z_b = (cal.bias_deg_s - np.array(truth["gyro"]["bias_deg_s"])) / np.array(cal.std.bias_deg_s)
    assert np.max(np.abs(z_K[np.triu_indices(3)])) < 4.0
    assert np.max(np.abs(z_b)) < 4.0


def test_noise_floor_separates_noise_from_fast_motion():
    rng = np.random.default_rng(0)
    t = np.arange(0, 60, 1 / 28)
    hand = np.column_stack([5 * np.sin(2 * np.pi * f * t) for f in (0.5, 0.8, 1.0)])   # a hand at 28 Hz
    shake = np.column_stack([3 * np.sin(2 * np.pi * f * t) for f in (2.5, 2.7, 3.0)])  # too fast for any floor
    white = 0.001 * rng.standard_normal(hand.shape)
    assert white_noise_std(hand + white).mean() > 3 * 0.001   # the third differences alone see the motion
    level, is_noise = noise_floor_std(hand + white)
    assert is_noise and level == pytest.approx(np.full(3, 0.001), rel=0.1)
    _, is_noise = noise_floor_std(shake + 0.1 * white)
    assert not is_noise


def test_band_inverse_is_the_inverse():
    rng = np.random.default_rng(1)
    n, b = 6, 3
    M = np.zeros((n * b, n * b))
    for k in range(n - 1):
        M[k * b:(k + 2) * b, k * b:(k + 2) * b] += (lambda a: a @ a.T)(rng.standard_normal((2 * b, 2 * b)))
    A = np.array([M[k * b:(k + 1) * b, k * b:(k + 1) * b] for k in range(n)])
    B = np.array([M[k * b:(k + 1) * b, (k + 1) * b:(k + 2) * b] for k in range(n - 1)])
    diag, upper = block_tridiagonal_inverse_band(A, B)
    inv = np.linalg.inv(M)
    for k in range(n):
        assert np.allclose(diag[k], inv[k * b:(k + 1) * b, k * b:(k + 1) * b])
    for k in range(n - 1):
        assert np.allclose(upper[k], inv[k * b:(k + 1) * b, (k + 1) * b:(k + 2) * b])


def test_the_solve_estimates_a_guessed_level(no_rest):
    """A magnetometer level 3x too large, marked a guess: the variance components bring it back to the truth.
    The gyro, marked a guess too, has too few redundant residuals at 28 Hz to be measured: it stays a guess,
    and the warning says so and names --gyro-noise."""
    session, truth, _ = no_rest
    options = Options()
    prep = prepare(session, options)
    prep = dataclasses.replace(prep, sigma_mag=3.0 * prep.sigma_mag,
                               levels=dataclasses.replace(prep.levels, mag_source=noise.GUESS,
                                                          gyro_source=noise.GUESS))
    grid, lin, problem = build_problem(prep, options, NLS())
    sol = solve_passes(problem, prep, lin, NLS(), level_estimator(problem, prep, lin))
    assert sol.levels_settled and sol.variance.mag_redundancy > 1000
    assert sol.sigma_mag == pytest.approx(truth["noise"]["mag_std"], rel=0.1)
    assert level_sources(prep, sol) == (noise.GUESS, noise.ESTIMATED)
    assert sol.variance.gyro_redundancy < MIN_REDUNDANCY
    (warning,) = guessed_level_warnings(prep, sol)
    assert "gyro noise density is a guess" in warning and "--gyro-noise" in warning
    assert f"only {sol.variance.gyro_redundancy:.0f} redundant residuals" in warning


def test_a_failed_solve_never_says_nan():
    class Stalled:
        stats = {"return_status": "Maximum_Iterations_Exceeded", "iter_count": 300}
    message = not_converged_message(Stalled(), float("nan"))
    assert "nan" not in message.lower() and "singular" in message
    assert "reduce chi^2 by 0.5" in not_converged_message(Stalled(), 0.5)
