"""The hand as states (magyro/nls/hand_states.py): its velocity at the nodes, an Ornstein-Uhlenbeck process."""
from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pytest

import magyro
from magyro.nls.hand_states import HandPrior, interleave_hand
from magyro.nls.method import NLS
from magyro.options import Options

DATA = Path(__file__).resolve().parent.parent / "data"


def test_the_velocity_keeps_its_variance_from_one_node_to_the_next():
    """v_k1 = decay v_k + w: decay^2 sigma^2 + std(w)^2 = sigma^2 for any interval, and 1 / T reads the mean
    acceleration."""
    prior = HandPrior(0.04, 0.3)
    T = np.array([0.01, 0.06, 0.3, 2.0])
    inv_T, decay, weight = prior.columns(T).T
    assert inv_T == pytest.approx(1.0 / T)
    assert decay == pytest.approx(np.exp(-T / 0.3))
    assert decay**2 * 0.04**2 + 1.0 / weight**2 == pytest.approx(np.full(4, 0.04**2))


@pytest.fixture(scope="module")
def phone_session():
    from magyro.studies.scenario import load_problem
    from magyro.studies.simulate import simulate

    problem = load_problem("phone-module-acc")
    return problem, *simulate(problem, 3)


def test_still_states_leave_every_other_residual_as_it_was(phone_session):
    """With the hand's velocity zero at every node the problem with the states gives the residuals of the one
    without them, and zero velocity steps; a velocity at one node reads in its two intervals' means only."""
    from magyro.front.prepare import prepare
    from magyro.nls.problem import JointProblem
    from magyro.nls.solve import build_problem, problem_parameters, residual_matrix

    _, session, _ = phone_session
    options = Options(accelerometer=True)
    prep = prepare(session, options)
    grid, lin, plain = build_problem(prep, options, NLS())
    states = JointProblem(grid, estimate_time_offset=options.estimate_time_offset, accelerometer=True,
                          hand_prior=HandPrior(0.03))
    x = np.random.default_rng(0).normal(0.0, 1e-3, plain.n_x)
    p0 = problem_parameters(plain, prep, lin, prep.sigma_mag, lin.time_offset_s)
    p1 = problem_parameters(states, prep, lin, prep.sigma_mag, lin.time_offset_s)
    x1 = interleave_hand(plain, states, x)
    r0, r1 = residual_matrix(plain, x, p0), residual_matrix(states, x1, p1)
    assert states.B == plain.B + 3 and r1.shape[1] == r0.shape[1] + 3
    np.testing.assert_allclose(r1[:, : r0.shape[1]], r0, rtol=0, atol=1e-12)
    assert np.all(r1[:, r0.shape[1]:] == 0.0)
    k = grid.nodes // 2
    x1.reshape(-1)[states.n_theta + states.B * (k - 1) + 3] = 0.05       # v_x at node k (node 0 is fixed)
    moved = np.any(residual_matrix(states, x1, p1) != r1, axis=1)
    assert np.flatnonzero(moved).tolist() == [k - 1, k]


def test_a_hand_swaying_the_phone_module_is_told_from_gravity(phone_session):
    """Simulated phone module, its hand swaying it by 5 cm: with the hand as states the accelerometer's scale
    factors lie within 4 of their std of the truth and that std is below the weighting's; the states' integrated
    velocity says how far the hand took the device, within 2x of the simulated position's std."""
    from magyro.studies.hand import truth_position

    problem, session, truth = phone_session
    states = magyro.calibrate(session, Options(accelerometer=True))
    weighted = magyro.calibrate(session, Options(accelerometer=True), NLS(hand_states=False))
    K_true = np.diag(np.asarray(truth["accelerometer"]["K_a"]))
    acc = states.accelerometer
    z = (np.diag(acc.K_a) - K_true) / np.diag(acc.std_K_a)
    assert np.all(np.abs(z) < 4), z
    assert np.all(np.diag(acc.std_K_a) < np.diag(weighted.accelerometer.std_K_a)), (
        np.diag(acc.std_K_a), np.diag(weighted.accelerometer.std_K_a))
    details = states.solver.details["hand_states"]
    moved = float(np.sqrt(np.mean(truth_position(problem, session.t_gyro_s, 3).var(axis=0))))
    assert 0.5 * moved < details["reach_m"] < 2.0 * moved, (details, moved)
    assert "hand_states" not in weighted.solver.details
    assert "the hand's velocity solved at every node" in states.table()
    assert "the hand's velocity solved at every node" not in weighted.table()


def test_a_device_turned_about_itself_keeps_its_white_weights(phone_session):
    """No hand (the phone module turned about itself): nothing to take, so no states, and the calibration is the
    weighting's bit for bit."""
    from magyro.studies.simulate import simulate

    problem, _, _ = phone_session
    still = dataclasses.replace(problem, accelerometer=dataclasses.replace(problem.accelerometer, hand_translation_m=0.0))
    session, _ = simulate(still, 3)
    default = magyro.calibrate(session, Options(accelerometer=True))
    weighted = magyro.calibrate(session, Options(accelerometer=True), NLS(hand_states=False))
    assert "hand_states" not in default.solver.details
    assert default.to_dict()["accelerometer"] == weighted.to_dict()["accelerometer"]
    assert default.to_dict()["std"] == weighted.to_dict()["std"]


def test_a_fast_turned_accelerometer_comes_out_within_its_std(run_magyro, tmp_path):
    """BROAD trial 07 (shipped; fast, the hand 2.1 m/s^2 RMS), forced past the hand's refusal: weighted by its
    hand, K_a[0,0] came out 0.855, 9.7 std from 1 (the same sensor's slow trials give 1 within 0.35 %); with the
    hand as states every scale factor lies within 3 std of 1. `--no-hand-states` is the weighting."""
    out_states, out_weighted = tmp_path / "states.json", tmp_path / "weighted.json"
    for out, extra in ((out_states, []), (out_weighted, ["--no-hand-states"])):
        result = run_magyro("solve", DATA / "broad-07.parquet", "--accelerometer", "--force", "-o", out, "-q", *extra)
        assert result.returncode == 0, result.stderr
    states, weighted = (magyro.Calibration.from_json(p) for p in (out_states, out_weighted))
    z_states = (np.diag(states.accelerometer.K_a) - 1.0) / np.diag(states.accelerometer.std_K_a)
    z_weighted = (np.diag(weighted.accelerometer.K_a) - 1.0) / np.diag(weighted.accelerometer.std_K_a)
    assert np.all(np.abs(z_states) < 3), z_states
    assert np.max(np.abs(z_weighted)) > 5, z_weighted
    assert states.solver.details["hand_states"]["sigma_v_m_s"] > 0
    from magyro.text import significant

    worst = significant(100 * np.max(np.diag(states.accelerometer.std_K_a)))   # the refusal says this session's own
    assert any(f"scale factors come out uncertain by up to {worst} % one-sigma" in w for w in states.warnings), (
        states.warnings)
    assert any("biases the accelerometer's scale factors" in w for w in weighted.warnings), weighted.warnings
