"""A hard iron that moves (`NLS(hard_iron_walk=...)`): its Gauss-Newton blocks, and a drifting hard iron recovered."""
from __future__ import annotations

import dataclasses

import casadi as ca
import numpy as np

import magyro
from magyro.front.prepare import prepare
from magyro.nls.hard_iron import hard_iron_at_samples
from magyro.nls.solve import build_problem, problem_parameters
from magyro.studies.scenario import load_problem
from magyro.studies.simulate import simulate

PROBLEM = load_problem("phone-module")


def drifting_hard_iron(session, amplitude: float, period_s: float = 40.0):
    """The magnetometer with a hard iron that drifts by +/- `amplitude` (its unit) on every axis."""
    drift = amplitude * np.sin(2 * np.pi * session.t_mag_s[:, None] / period_s + np.array([0.3, 1.7, 4.1]))
    return dataclasses.replace(session, mag=session.mag + drift), drift


def test_the_assembled_hessian_is_j_transpose_j_with_the_walk():
    """The block pattern with 6 unknowns a node (attitude and walk) places every Gauss-Newton block where
    J^T J has it: checked against CasADi's own Jacobian of the residuals on a 6 s session."""
    session, _ = simulate(PROBLEM, 0)
    session = drifting_hard_iron(session.within(10.0, 16.0), 2.0)[0]
    options, method = magyro.Options(trim_rests=False), magyro.NLS(compiled=False, stride=4, hard_iron_walk=1.0)
    prep = prepare(session, options)
    _, lin, problem = build_problem(prep, options, method)
    p = problem_parameters(problem, prep, lin, prep.sigma_mag, lin.time_offset_s)
    x = np.random.default_rng(0).normal(scale=1e-3, size=problem.n_x)
    xs = ca.MX.sym("x", problem.n_x)
    J = np.array(ca.Function("J", [xs], [ca.jacobian(problem.residual_function(xs, p), xs)])(x))
    H = np.array(ca.densify(problem.hessian_function(x, p)))
    np.testing.assert_allclose(np.triu(H), np.triu(J.T @ J), rtol=1e-8, atol=1e-8 * np.abs(J.T @ J).max())


def test_a_drifting_hard_iron_is_followed_and_the_gyro_recovered():
    """+/- 5 uT of drift on a 50 uT field: the constant model's scale factors come out percent off (its std,
    which counts the wander, covers that), the walk's within 3 std and 0.3 % of the truth, its h(t) follows the drift."""
    session, _ = simulate(PROBLEM, 0)
    drifted, drift = drifting_hard_iron(session, 5.0)
    constant = magyro.calibrate(drifted, magyro.Options(force=True))
    walking = magyro.calibrate(drifted, method=magyro.NLS(hard_iron_walk=1.0))
    scale_truth = np.diag(PROBLEM.K_g)
    err_constant = np.diag(constant.K_g) - scale_truth
    err_walk = np.diag(walking.K_g) - scale_truth
    assert np.max(np.abs(err_constant)) > 0.01, err_constant
    assert np.all(np.abs(err_walk) < 3 * np.diag(walking.std.K_g)) and np.max(np.abs(err_walk)) < 0.003, err_walk
    bias_err = walking.bias_deg_s - PROBLEM.gyro_bias_deg_s
    assert np.all(np.abs(bias_err) < 3 * walking.std.bias_deg_s), (bias_err, walking.std.bias_deg_s)
    track = walking.solver.details["hard_iron_walk"]
    assert 0.7 * 10.0 < min(track["peak_to_peak"]) and max(track["peak_to_peak"]) < 1.3 * 10.0, track
