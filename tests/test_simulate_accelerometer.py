"""The simulated accelerometer (a problem's [accelerometer], issue 26): the sensor model, the hand's translation
and its analytic acceleration, the truth's "accelerometer" block, and problems without the section unchanged."""
from __future__ import annotations

import dataclasses
import json

import numpy as np
import pytest

from magyro import so3
from magyro.errors import InputError
from magyro.io.toml_file import read_toml
from magyro.studies.scenario import PROBLEMS_DIR, load_problem, parse_problem
from magyro.studies.hand import acc_clean, translation_span, truth_acceleration, truth_position
from magyro.studies.motion import truth_body_attitude
from magyro.studies.simulate import simulate

ACC_PROBLEMS = ["paper-table1-acc", "phone-module-acc"]


def second_difference_agrees(p, t, acceleration, h=1e-4):
    """acceleration (N, 3) against the position's central second difference: to 1e-6 m/s^2, except within 2h of the
    window's ramp ends, where the third derivative jumps (the smoothstep is C^2, not C^3) and the difference is
    off by about h |d3p/dt3| / 6."""
    fd = (truth_position(p, t + h) - 2.0 * truth_position(p, t) + truth_position(p, t - h)) / h**2
    start, stop, ramp = translation_span(p)
    edge = np.min(np.abs(t[:, None] - np.array([start, start + ramp, stop - ramp, stop])), axis=1) < 2 * h
    np.testing.assert_allclose(acceleration[~edge], fd[~edge], atol=1e-6, rtol=0)
    np.testing.assert_allclose(acceleration[edge], fd[edge], atol=1e-4, rtol=0)


def specific_force_a(session, truth) -> np.ndarray:
    """f^a = K_a y_a + eps_a with the truth's K_a and eps_a (N, 3)."""
    acc = truth["accelerometer"]
    return session.acc_m_s2 @ np.array(acc["K_a"]).T + np.array(acc["bias_m_s2"])


@pytest.mark.parametrize("name", ACC_PROBLEMS)
def test_at_rest_the_accelerometer_reads_gravity_up_along_the_truths_direction(name):
    """In the rests |K_a y_a + eps_a| = g within the noise, and its mean points 'up': C_b^a C_m^b gravity_up_i
    (frame i is the magnetometer frame at t = 0, so the truth's gravity_up_i is the up of the first rest)."""
    p = load_problem(name)
    session, truth = simulate(p, 0)
    acc = truth["accelerometer"]
    g, std = acc["g_m_s2"], acc["sample_std_m_s2"]
    np.testing.assert_array_equal(session.t_acc_s, session.t_gyro_s)
    f_a = specific_force_a(session, truth)
    t = session.t_acc_s
    first = t < p.motion.rest_start_s
    last = t > p.duration_s - p.motion.rest_end_s
    for rest in (first, last):
        norm = np.linalg.norm(f_a[rest], axis=1)
        assert np.all(np.abs(norm - g) < 5 * std * np.sqrt(3)), (norm.min(), norm.max())
        assert abs(norm.mean() - g) < 5 * std / np.sqrt(rest.sum())
    C_b_a, C_b_m = np.array(acc["C_b_a"]), np.array(truth["misalignment"]["C_b_m"])
    up_a = C_b_a @ C_b_m.T @ np.array(acc["gravity_up_i"])
    np.testing.assert_allclose(f_a[first].mean(axis=0), g * up_a, atol=5 * std / np.sqrt(first.sum()))
    np.testing.assert_allclose(np.linalg.norm(acc["gravity_up_i"]), 1.0, rtol=1e-14)
    np.testing.assert_allclose(C_b_a, so3.euler_to_dcm(acc["euler_deg"]), atol=1e-14)


@pytest.mark.parametrize("name", ACC_PROBLEMS)
def test_specific_force_less_gravity_is_the_position_differentiated_twice(name):
    """Noise-free: C_b^w C_a^b (K_a y_a + eps_a) + g_vec, the hand's acceleration the accelerometer saw, equals the
    simulated position differentiated twice by central differences, during the motion and across the window's
    ramps (the window's derivatives are in the analytic acceleration); it is exactly zero in the rests."""
    p = load_problem(name)
    session, truth = simulate(p, 0, noise_scale=0.0)
    t = session.t_acc_s
    f_a = specific_force_a(session, truth)
    f_w = np.einsum("nij,nj->ni", truth_body_attitude(p, t), f_a @ np.array(truth["accelerometer"]["C_b_a"]))
    a_w = f_w + np.array([0.0, 0.0, -truth["accelerometer"]["g_m_s2"]])
    second_difference_agrees(p, t, a_w)
    second_difference_agrees(p, t, truth_acceleration(p, t))
    assert np.abs(a_w).max() > 0.02   # the hand does move the device: the check is not 0 = 0
    still = (t < p.motion.rest_start_s) | (t > p.duration_s - p.motion.rest_end_s)
    assert np.all(truth_acceleration(p, t[still]) == 0.0) and np.all(truth_position(p, t[still]) == 0.0)


@pytest.mark.parametrize("name", ACC_PROBLEMS)
def test_the_hand_moves_about_hand_translation_m_another_sway_for_every_noise_seed(name):
    """To the calibration the hand's sway is noise: each noise seed draws another sway of the same size (each axis's
    peak hand_translation_m), about the same turning."""
    p = load_problem(name)
    t = np.linspace(0.0, p.duration_s, 20001)
    peak = np.abs(truth_position(p, t, 0)).max(axis=0)
    np.testing.assert_allclose(peak, p.accelerometer.hand_translation_m, rtol=2e-3)
    (s0, _), (s5, _) = simulate(p, 0), simulate(p, 5)
    assert not np.allclose(s0.acc_m_s2, s5.acc_m_s2, atol=0.05)
    clean = [acc_clean(p, simulate(p, seed)[0].t_acc_s, seed) for seed in (0, 5)]
    assert np.max(np.abs(clean[0] - clean[1])) > 0.01


@pytest.mark.parametrize("name", ACC_PROBLEMS)
def test_the_accelerometer_noise_is_its_density_times_sqrt_rate(name):
    p = load_problem(name)
    session, truth = simulate(p, 3)
    residual = session.acc_m_s2 - acc_clean(p, session.t_acc_s, 3)
    expected = 1e-6 * 9.80665 * p.accelerometer.noise_density_ug_sqrt_hz * np.sqrt(p.gyro_rate_hz)
    assert truth["accelerometer"]["sample_std_m_s2"] == pytest.approx(expected, rel=1e-12)
    np.testing.assert_allclose(residual.std(axis=0), expected, rtol=0.05)


@pytest.mark.parametrize("base", ["paper-table1", "phone-module"])
def test_without_the_section_nothing_changes(base):
    """A problem without [accelerometer] has no accelerometer, in the session, its metadata or the truth; and the
    section disturbs nothing else: the gyro and magnetometer of a problem with it are, bit for bit, those of the
    same problem without it (the accelerometer's noise is drawn last)."""
    session, truth = simulate(load_problem(base), 4)
    assert session.t_acc_s is None and session.acc_m_s2 is None
    assert "acc_unit" not in session.metadata and "accelerometer" not in truth
    with_acc = load_problem(f"{base}-acc")
    without = dataclasses.replace(with_acc, accelerometer=None)
    a, ta = simulate(with_acc, 4)
    b, tb = simulate(without, 4)
    for key in ("t_gyro_s", "gyro_rad_s", "t_mag_s", "mag"):
        np.testing.assert_array_equal(getattr(a, key), getattr(b, key))
    assert {k: v for k, v in ta.items() if k != "accelerometer"} == tb
    if base == "phone-module":   # phone-module-acc is phone-module plus the section: the same gyro and magnetometer
        for key in ("t_gyro_s", "gyro_rad_s", "t_mag_s", "mag"):
            np.testing.assert_array_equal(getattr(a, key), getattr(session, key))


def test_the_session_and_truth_files_carry_the_accelerometer(tmp_path):
    from magyro.api import simulate_file
    from magyro.io import load_session

    session, truth_path = simulate_file("phone-module-acc", tmp_path / "s.parquet", seed=2)
    loaded = load_session(tmp_path / "s.parquet")
    np.testing.assert_array_equal(loaded.t_acc_s, session.t_acc_s)
    np.testing.assert_array_equal(loaded.acc_m_s2, session.acc_m_s2)
    truth = json.loads(truth_path.read_text())
    assert sorted(truth["accelerometer"]) == sorted(
        ["K_a", "bias_m_s2", "C_b_a", "euler_deg", "g_m_s2", "gravity_up_i", "hand_translation_m",
         "noise_density_ug_sqrt_hz", "sample_std_m_s2"])


def _raw(name="phone-module-acc") -> dict:
    return read_toml(PROBLEMS_DIR / f"{name}.toml")


def test_accelerometer_section_is_checked():
    raw = _raw()
    raw["accelerometer"]["rate_hz"] = 100.0
    with pytest.raises(InputError, match=r"\[accelerometer\]: unknown key\(s\) \['rate_hz'\]"):
        parse_problem(raw)
    raw = _raw()
    del raw["accelerometer"]["K_a"]
    with pytest.raises(InputError, match=r"\[accelerometer\]: missing required key\(s\) \['K_a'\]"):
        parse_problem(raw)
    raw = _raw()
    raw["accelerometer"]["K_a"][1][0] = 0.01
    with pytest.raises(InputError, match="K_a must be upper triangular"):
        parse_problem(raw)
    raw = _raw()
    raw["motion"] = {"kind": "static"}
    with pytest.raises(InputError, match="hand_translation_m must be 0"):
        parse_problem(raw)
    raw["accelerometer"]["hand_translation_m"] = 0.0   # a static device with an accelerometer: gravity alone
    p = parse_problem(raw)
    session, truth = simulate(p, 0, noise_scale=0.0)
    np.testing.assert_allclose(specific_force_a(session, truth), np.broadcast_to(
        9.80665 * np.array(truth["accelerometer"]["C_b_a"]) @ np.array(truth["misalignment"]["C_b_m"]).T
        @ truth["accelerometer"]["gravity_up_i"], session.acc_m_s2.shape), atol=1e-12)
    raw = _raw()
    del raw["accelerometer"]["g_m_s2" if "g_m_s2" in raw["accelerometer"] else "hand_translation_m"]
    assert parse_problem(raw).accelerometer.g_m_s2 == 9.80665


def test_a_turns_motion_moves_the_hand_only_between_its_first_and_last_turn():
    raw = _raw()
    raw["motion"] = {"kind": "turns", "turns": [{"rest_s": 2.0}, {"axis": [1, 0, 0], "angle_deg": 180, "seconds": 3.0},
                                                {"rest_s": 1.0}, {"axis": [0, 1, 0], "angle_deg": 90, "seconds": 3.0},
                                                {"rest_s": 2.0}]}
    raw["problem"]["duration_s"] = 12.0
    p = parse_problem(raw)
    t = np.linspace(0.0, 12.0, 12_001)
    pos, acc = truth_position(p, t), truth_acceleration(p, t)
    outside = (t <= 2.0) | (t >= 9.0)   # the turns run from 2 s to 9 s
    assert np.all(pos[outside] == 0.0) and np.all(acc[outside] == 0.0)
    np.testing.assert_allclose(np.abs(pos).max(axis=0), 0.05, rtol=0.01)
    assert translation_span(p) == (2.0, 9.0, 1.0)
    second_difference_agrees(p, t, acc)


@pytest.mark.parametrize("name", ACC_PROBLEMS)
def test_shipped_accelerometer_problems_load_and_start_and_end_at_rest_in_one_pose(name):
    from magyro.studies.simulate import truth_attitude, truth_body_rate

    p = load_problem(name)
    assert p.name == name and p.motion.rest_start_s == p.motion.rest_end_s == 2.0
    C = truth_attitude(p, [0.0, p.duration_s])
    np.testing.assert_allclose(C[0], np.eye(3), atol=1e-15)
    np.testing.assert_allclose(C[1], np.eye(3), atol=1e-12)
    np.testing.assert_allclose(truth_body_rate(p, [0.0, p.duration_s]), 0.0, atol=1e-15)
