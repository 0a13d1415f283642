"""The simulator: analytic truth, the sensor model, noise levels, problem files."""
from __future__ import annotations

import dataclasses
import json
from pathlib import Path

import numpy as np
import pytest

from magyro import so3
from magyro.errors import InputError
from magyro.studies.scenario import PROBLEMS_DIR, load_problem
from magyro.studies.simulate import (
    field_i,
    simulate,
    truth_attitude,
    truth_body_attitude,
    truth_body_rate,
    truth_rate_m,
    write_truth,
)

SHIPPED = ["paper-table1", "phone-module", "short-30s", "static", "axis-x", "axis-y", "axis-z",
           "two-axes", "three-axes"]


def _fd_rate(attitude, t, dt):
    """log(C(t)^T C(t+dt)) / dt, the mean rate over [t, t+dt]."""
    C0, C1 = attitude(t), attitude(t + dt)
    return so3.log_so3(np.swapaxes(C0, -1, -2) @ C1) / dt


@pytest.mark.parametrize("name", ["paper-table1", "phone-module", "static", "axis-y", "three-axes"])
def test_rates_match_finite_differences_of_attitude(name):
    p = load_problem(name)
    t = np.random.default_rng(0).uniform(-1.0, p.duration_s + 1.0, 400)
    dt = 1e-4
    fd_b = _fd_rate(lambda s: truth_body_attitude(p, s), t, dt)
    np.testing.assert_allclose(fd_b, truth_body_rate(p, t + dt / 2), atol=1e-6, rtol=0)
    fd_m = _fd_rate(lambda s: truth_attitude(p, s), t, dt)
    np.testing.assert_allclose(fd_m, truth_rate_m(p, t + dt / 2), atol=1e-6, rtol=0)


@pytest.mark.parametrize("name", SHIPPED)
def test_shipped_problems_load_and_start_and_end_at_rest_in_one_pose(name):
    p = load_problem(name)
    assert p.name == name
    C = truth_attitude(p, [0.0, p.duration_s])
    np.testing.assert_allclose(C[0], np.eye(3), atol=1e-15)
    np.testing.assert_allclose(C[1], np.eye(3), atol=1e-12)
    np.testing.assert_allclose(truth_body_rate(p, [0.0, p.duration_s]), 0.0, atol=1e-15)


def _with_offset(p, offset):
    return dataclasses.replace(p, mag_time_offset_s=offset)


@pytest.mark.parametrize("name,offset", [("paper-table1", 0.0), ("phone-module", 0.0), ("phone-module", 0.013)])
def test_noise_free_session_satisfies_the_model(name, offset):
    p = _with_offset(load_problem(name), offset)
    session, truth = simulate(p, seed=5, noise_scale=0.0)
    R, h = np.array(truth["magnetometer"]["R"]), np.array(truth["magnetometer"]["h"])
    m_m = (session.mag - h) @ R.T
    np.testing.assert_allclose(np.linalg.norm(m_m, axis=1), 1.0, atol=1e-12)
    C_m_i = truth_attitude(p, session.t_mag_s - offset)
    expected = np.einsum("nji,j->ni", C_m_i, np.array(truth["field_i"]))
    np.testing.assert_allclose(m_m, expected, atol=1e-12)
    K_g, eps_b = np.array(truth["gyro"]["K_g"]), np.array(truth["gyro"]["bias_rad_s"])
    w_b = session.gyro_rad_s @ K_g.T + eps_b
    np.testing.assert_allclose(w_b, truth_body_rate(p, session.t_gyro_s), atol=1e-13)
    # and in the magnetometer frame: w^m = K y_g + eps
    K, eps = np.array(truth["gyro"]["K"]), np.array(truth["gyro"]["eps_rad_s"])
    np.testing.assert_allclose(session.gyro_rad_s @ K.T + eps, truth_rate_m(p, session.t_gyro_s), atol=1e-13)


def test_session_layout_and_sample_times():
    p = load_problem("phone-module")
    session, truth = simulate(p, seed=3)
    assert session.source == "simulated:phone-module:seed=3"
    assert session.mag_unit == "uT" and truth["magnetometer"]["unit"] == "uT"
    assert len(session.t_gyro_s) == 60 * 200 + 1 and len(session.t_mag_s) == 60 * 50 + 1
    np.testing.assert_allclose(session.t_gyro_s[:3], [0.0, 0.005, 0.010])
    assert session.t_mag_s[-1] == pytest.approx(60.0)
    assert session.gyro_rad_s.shape == (len(session.t_gyro_s), 3)
    assert session.mag.shape == (len(session.t_mag_s), 3)
    # readings carry the field strength (50 uT, soft iron a few %) plus the hard iron
    norms = np.linalg.norm(session.mag - truth["magnetometer"]["h"], axis=1)
    assert 47.0 < norms.min() and norms.max() < 53.0


@pytest.mark.parametrize("name,axis", [("axis-x", 0), ("axis-y", 1), ("axis-z", 2)])
def test_single_axis_motion_has_exactly_zero_off_axis_rate(name, axis):
    p = load_problem(name)
    w = truth_body_rate(p, np.linspace(0.0, p.duration_s, 20001))
    off = [k for k in range(3) if k != axis]
    assert np.all(w[:, off] == 0.0)
    assert np.abs(w[:, axis]).max() > np.deg2rad(30.0)


def test_sequential_two_axes_turns_one_axis_at_a_time():
    p = load_problem("two-axes")
    t = np.linspace(0.0, p.duration_s, 20001)
    w = truth_body_rate(p, t)
    assert np.all(w[:, 2] == 0.0)
    assert np.all(w[t <= 30.0, 1] == 0.0) and np.all(w[t >= 30.0, 0] == 0.0)


def test_static_motion_gives_bias_only():
    p = load_problem("static")
    session, truth = simulate(p, seed=0, noise_scale=0.0)
    expected = np.linalg.solve(p.K_g, -p.gyro_bias_rad_s)
    np.testing.assert_allclose(session.gyro_rad_s, np.broadcast_to(expected, session.gyro_rad_s.shape), atol=1e-15)


@pytest.mark.parametrize("name", ["paper-table1", "phone-module"])
def test_noise_statistics(name):
    p = load_problem(name)
    clean, _ = simulate(p, seed=11, noise_scale=0.0)
    noisy, truth = simulate(p, seed=11)
    dg = noisy.gyro_rad_s - clean.gyro_rad_s
    expected_g = np.deg2rad(p.gyro_noise_density_deg_s_sqrt_hz) * np.sqrt(p.gyro_rate_hz)
    np.testing.assert_allclose(dg.std(axis=0), expected_g, rtol=0.05)
    np.testing.assert_allclose(dg.mean(axis=0), 0.0, atol=5 * expected_g / np.sqrt(len(dg)))
    dm = noisy.mag - clean.mag
    np.testing.assert_allclose(dm.std(axis=0), p.mag_noise_std, rtol=0.05)
    # the truth file states the noise the samples actually carry
    np.testing.assert_allclose(dg.std(axis=0), truth["noise"]["gyro_sample_std_rad_s"], rtol=0.05)
    np.testing.assert_allclose(dm.std(axis=0), truth["noise"]["mag_std"], rtol=0.05)


def test_motion_is_fixed_by_the_problem_and_noise_by_the_seed():
    p = load_problem("short-30s")
    a, _ = simulate(p, seed=1)
    b, _ = simulate(p, seed=1)
    c, _ = simulate(p, seed=2)
    np.testing.assert_array_equal(a.gyro_rad_s, b.gyro_rad_s)
    assert not np.array_equal(a.gyro_rad_s, c.gyro_rad_s)
    clean_a, _ = simulate(p, seed=1, noise_scale=0.0)
    clean_c, _ = simulate(p, seed=2, noise_scale=0.0)
    np.testing.assert_array_equal(clean_a.gyro_rad_s, clean_c.gyro_rad_s)


def test_paper_problem_is_table_one():
    p = load_problem("paper-table1")
    _, truth = simulate(p, seed=0)
    np.testing.assert_array_equal(truth["gyro"]["K_g"], [[1.1, 0.1, 0.15], [0, 1.2, 0.2], [0, 0, 1.3]])
    np.testing.assert_allclose(truth["gyro"]["bias_deg_s"], [1.0, 3.0, 2.0])
    np.testing.assert_allclose(truth["misalignment"]["euler_deg"], [10.0, 20.0, 15.0], atol=1e-12)
    np.testing.assert_allclose(truth["magnetometer"]["R"], np.eye(3))
    np.testing.assert_allclose(truth["magnetometer"]["h"], 0.0)
    assert truth["noise"]["mag_std"] == 0.01
    assert truth["noise"]["gyro_density_rad_s_sqrt_hz"] == pytest.approx(np.deg2rad(0.02))
    assert p.duration_s == 100.0 and p.gyro_rate_hz == 100.0 and p.mag_rate_hz == 100.0
    assert p.motion.rest_start_s == 0.0 and p.motion.rest_end_s == 0.0
    np.testing.assert_allclose(np.linalg.norm(truth["field_i"]), 1.0)
    # realistic hand motion about all three axes
    w = np.rad2deg(truth_body_rate(p, np.arange(0.0, 100.0, 0.01)))
    assert np.linalg.norm(w, axis=1).max() < 200.0
    assert np.all(np.abs(w).max(axis=0) > 50.0)


def test_field_i_is_the_first_magnetometer_reading():
    p = load_problem("phone-module")
    session, truth = simulate(p, seed=0, noise_scale=0.0)
    R, h = np.array(truth["magnetometer"]["R"]), np.array(truth["magnetometer"]["h"])
    np.testing.assert_allclose(R @ (session.mag[0] - h), field_i(p), atol=1e-12)


def test_write_truth_is_json_and_atomic(tmp_path):
    _, truth = simulate(load_problem("static"), seed=4)
    out = tmp_path / "truth.json"
    write_truth(truth, out)
    assert json.loads(out.read_text()) == json.loads(json.dumps(truth))
    assert [f.name for f in tmp_path.iterdir()] == ["truth.json"]
    assert truth["schema"] == "magyro.truth/1" and truth["seed"] == 4 and truth["problem"] == "static"


def _write(tmp_path: Path, text: str) -> Path:
    path = tmp_path / "p.toml"
    path.write_text(text)
    return path


def _paper_text() -> str:
    return (PROBLEMS_DIR / "paper-table1.toml").read_text()


@pytest.mark.parametrize(
    "edit,needle",
    [
        (lambda s: s + "\n[gyro\n", "not valid TOML"),
        (lambda s: s.replace("rate_hz = 100.0\nnoise_density", "rate_hz = -100.0\nnoise_density"), "positive"),
        (lambda s: s.replace("[0.0, 1.2, 0.2]", "[0.1, 1.2, 0.2]"), "upper triangular"),
        (lambda s: s.replace("[0.0, 0.0, 1.3]", "[0.0, 0.0, -1.3]"), "positive diagonal"),
        (lambda s: s.replace("bias_deg_s = [1.0, 3.0, 2.0]", "bias_deg_s = [1.0, 3.0]"), "bias_deg_s"),
        (lambda s: s.replace("dip_deg = 60.0", "dip_deg = 60.0\ndeclination = 3.0"), "unknown key"),
        (lambda s: s + "\n[extra]\na = 1\n", "unknown section"),
        (lambda s: s.replace('kind = "euler"', 'kind = "wobble"'), "kind"),
        (lambda s: s.replace("duration_s = 100.0\n", ""), "missing"),
        (lambda s: s.replace('axes = ["z", "y", "x"]', 'axes = ["z", "y"]'), "amplitude_deg"),
        (lambda s: s.replace("band_hz = [0.02, 0.2]", "band_hz = [0.02, 80.0]"), "Nyquist"),
        (lambda s: s.replace('unit = "unitless"', "unit = 3"), "unit"),
    ],
)
def test_load_problem_rejects_bad_files(tmp_path, edit, needle):
    text = _paper_text()
    bad = edit(text)
    assert bad != text
    with pytest.raises(InputError, match=needle):
        load_problem(_write(tmp_path, bad))


def test_load_problem_missing_file_and_name(tmp_path):
    with pytest.raises(InputError, match="not found"):
        load_problem(tmp_path / "nope.toml")
    with pytest.raises(InputError, match="paper-table1"):  # lists the shipped problems
        load_problem("no-such-problem")


def test_load_problem_by_path_and_by_name_agree(tmp_path):
    by_name = load_problem("paper-table1")
    by_path = load_problem(_write(tmp_path, _paper_text()))
    np.testing.assert_array_equal(by_name.K_g, by_path.K_g)
    assert load_problem("paper-table1.toml").name == "paper-table1"
