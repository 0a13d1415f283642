"""The accelerometer in the joint least squares (issue 26), on the real BROAD trial 2 shipped in data/.

BROAD (Laidig, Caruso, Cereatti, Seel, Data 6(7):72, 2021, CC BY 4.0): a myon aktos-t IMU turned by hand, rests at
both ends, accelerometer in m/s^2.
"""
from __future__ import annotations

import dataclasses
import json
from pathlib import Path

import numpy as np
import pytest

import degrade
from magyro import EKF, calibrate
from magyro.errors import InputError, ObservabilityError
from magyro.front.rests import find_rests
from magyro.io import write_session
from magyro.options import Options
from magyro.result.calibration import Calibration

G = 9.80665


def test_calibrated_specific_force_at_the_rests_is_g(broad02_acc_solved):
    """Still, the calibrated accelerometer reads g: within 0.05 % at both rests of trial 2 (issue 26: 0.5 %)."""
    session, cal = broad02_acc_solved
    rests = find_rests(session).segments_s
    assert len(rests) == 2
    for a, b in rests:
        keep = (session.t_acc_s >= a) & (session.t_acc_s <= b)
        f = np.linalg.norm(cal.accelerometer.apply(session.acc_m_s2[keep]), axis=1).mean()
        assert abs(f / G - 1) < 5e-4, (a, b, f)


def test_accelerometer_parameters_are_plausible_with_their_std(broad02_acc_solved):
    """A factory-calibrated MEMS accelerometer: scales within 2 %, bias under 0.3 m/s^2, axes within 1 deg of the gyro's,
    each with a finite, positive std smaller than the quantity's plausible range."""
    _, cal = broad02_acc_solved
    acc = cal.accelerometer
    assert np.all(np.abs(np.diag(acc.K_a) - 1) < 0.02)
    assert np.all(np.abs(acc.bias_m_s2) < 0.3)
    assert np.rad2deg(np.linalg.norm(_log(acc.C_b_a))) < 1.0
    for std in (np.diag(acc.std_K_a), acc.std_bias_m_s2, acc.std_misalignment_deg):
        assert np.all(np.isfinite(std)) and np.all(std > 0)
    assert np.all(np.diag(acc.std_K_a) < 0.01) and np.all(acc.std_bias_m_s2 < 0.1)


def _log(C):
    from magyro import so3
    return so3.log_so3(C)


def test_gravity_helps_the_gyro(broad02_acc_solved, broad02_solved):
    """Gravity is a second reference vector: no gyro std grows, and the bias std falls (0.51-0.86x on trial 2)."""
    _, cal = broad02_acc_solved
    _, base = broad02_solved
    assert np.all(cal.std.bias_deg_s < base.std.bias_deg_s)
    assert np.all(cal.std.K_g[np.triu_indices(3)] <= 1.02 * base.std.K_g[np.triu_indices(3)])


def test_bursty_stamps_leave_intervals_without_the_accelerometer_and_a_finite_std():
    """A logger that stamps buffered bursts on arrival (tests/degrade.py): after the restamp some intervals hold no
    accelerometer sample (weight 0), where the hand's std the weights hold was 1/0^2 - white = inf, times 0 = nan,
    and every std came out nan and refused (exit 3)."""
    bursty = degrade.burst_stamps(degrade.load("broad-02"))
    cal = calibrate(bursty, Options(accelerometer=True))
    assert np.all(np.isfinite(cal.std.K_g)) and np.all(np.isfinite(cal.accelerometer.std_K_a))
    assert np.all(cal.accelerometer.std_bias_m_s2 < 0.05)


def test_json_round_trip(broad02_acc_solved, tmp_path):
    _, cal = broad02_acc_solved
    back = Calibration.from_json(cal.to_json())
    for name in ("K_a", "bias_m_s2", "C_b_a", "std_K_a", "std_bias_m_s2", "std_misalignment_deg", "lever_arm_m",
                 "std_lever_arm_m"):
        assert np.array_equal(getattr(back.accelerometer, name), getattr(cal.accelerometer, name)), name
    d = json.loads(cal.to_json())
    assert set(d["accelerometer"]) >= {"K_a", "bias_m_s2", "C_b_a", "g_m_s2"}
    assert set(d["std"]["accelerometer"]) == {"K_a", "bias_m_s2", "misalignment_deg", "lever_arm_m"}


def test_accelerometer_columns_change_nothing_unless_asked(broad02_solved):
    """A session's ax ay az do not enter the default solve: without them it gives the same calibration, bit for bit."""
    session, cal = broad02_solved
    bare = calibrate(dataclasses.replace(session, t_acc_s=None, acc_m_s2=None))
    assert cal.accelerometer is None and bare.accelerometer is None
    a, b = json.loads(cal.to_json()), json.loads(bare.to_json())
    for d in (a, b):
        d["solver"].pop("seconds"), d["solver"].pop("total_seconds", None)
    assert a == b


def test_no_accelerometer_in_the_session_is_exit_2(broad02_solved, tmp_path, run_magyro, assert_plain_failure):
    session, _ = broad02_solved
    path = tmp_path / "no-acc.parquet"
    write_session(dataclasses.replace(session, t_acc_s=None, acc_m_s2=None), path)
    message = assert_plain_failure(run_magyro("solve", str(path), "--accelerometer", "-q"), 2)
    assert "no accelerometer" in message and "ax ay az" in message


def test_no_accelerometer_is_said_before_the_motion_is_judged(tmp_path):
    """A still PX4 log without its accelerometer: exit 2 for the missing accelerometer, not exit 3 for the motion
    (fixing the motion would only have led to this refusal); the Sensor Logger's left-out file is named."""
    from magyro.io import import_ulog

    still = import_ulog(Path(__file__).resolve().parents[1] / "data" / "px4-sample-appended-multiple.ulg")
    bare = dataclasses.replace(still, t_acc_s=None, acc_m_s2=None)
    with pytest.raises(ObservabilityError):
        calibrate(bare)
    with pytest.raises(InputError, match="has no accelerometer .columns ax ay az, m/s.2.; import it with its"):
        calibrate(bare, Options(accelerometer=True))
    phone = dataclasses.replace(bare, metadata={"sensor_note": "gyro from Gyroscope.csv; no accelerometer: "
                                                               "Accelerometer.csv left out, it is without gravity"})
    with pytest.raises(InputError, match=r"m/s\^2\): Accelerometer.csv left out, it is without gravity, or solve "
                                         "without --accelerometer"):
        calibrate(phone, Options(accelerometer=True))


def test_the_ekf_does_not_calibrate_the_accelerometer(broad02_solved):
    session, _ = broad02_solved
    with pytest.raises(InputError, match="least squares only"):
        calibrate(session, Options(accelerometer=True), EKF())


@pytest.mark.parametrize("seed", [1, 2])
def test_still_hand_recovers_the_simulated_accelerometer_within_its_std(seed):
    """The algebra, on paper-table1-acc without the hand's sway (only gravity and white noise): every accelerometer
    parameter within 4 reported std of the truth, and the gyro's too."""
    from magyro.studies.scenario import load_problem
    from magyro.studies.simulate import simulate
    from magyro.result.reported import misalignment_vector

    problem = load_problem("paper-table1-acc")
    still = dataclasses.replace(problem, accelerometer=dataclasses.replace(problem.accelerometer, hand_translation_m=0.0))
    session, truth = simulate(still, seed)
    cal = calibrate(session, Options(accelerometer=True))
    acc, t = cal.accelerometer, truth["accelerometer"]
    upper = np.triu_indices(3)
    z_K = (acc.K_a - np.asarray(t["K_a"]))[upper] / acc.std_K_a[upper]
    z_b = (acc.bias_m_s2 - np.asarray(t["bias_m_s2"])) / acc.std_bias_m_s2
    z_d = np.rad2deg(misalignment_vector(np.asarray(t["C_b_a"]), acc.C_b_a)) / acc.std_misalignment_deg
    assert np.all(np.abs(np.concatenate([z_K, z_b, z_d])) < 4), (z_K, z_b, z_d)
    assert np.all(np.abs(np.diag(acc.K_a) - np.diag(t["K_a"])) < 3e-3) and np.all(np.abs(z_b * acc.std_bias_m_s2) < 0.05)
    z_g = (cal.bias_deg_s - np.asarray(truth["gyro"]["bias_deg_s"])) / cal.std.bias_deg_s
    assert np.all(np.abs(z_g) < 4), z_g


def test_a_device_swung_too_fast_is_refused_for_its_accelerometer(run_magyro, assert_plain_failure, tmp_path):
    """BROAD trial 7 (real, turned at up to 1446 deg/s): the hand moves with the turning, and the fit takes part of
    it for scale (K_a x 0.80-0.82 where the slow trials give 1.000 +/- 0.002), which no std counts. Refused for the
    hand's size, measured as the optical position measures it (2.31 m/s^2 RMS per axis, position differentiated
    twice below 10 Hz and turned into the body): exit 3 saying so and what to do; --force reports it with the same
    words as a warning and the hand's size in the JSON."""
    from conftest import SHIPPED_BROAD_02
    from magyro.nls.accelerometer import HAND_LIMIT_OF_G

    trial_07 = SHIPPED_BROAD_02.with_name("broad-07.parquet")
    message = assert_plain_failure(run_magyro("solve", str(trial_07), "--accelerometer", "-q"), 3)
    assert "the hand accelerated the device by" in message and "more than 7 % of g (0.686 m/s^2)" in message
    assert "turn the device more slowly" in message and "--force" in message
    out = tmp_path / "calib.json"
    assert run_magyro("solve", str(trial_07), "--accelerometer", "--force", "-q", "-o", str(out)).returncode == 0
    data = json.loads(out.read_text())
    hand = data["accelerometer"]["hand_rms_m_s2"]
    assert 0.75 * 2.31 < hand < 1.25 * 2.31 and hand > HAND_LIMIT_OF_G * G
    assert any("solved with --force although the hand accelerated the device by" in w for w in data["warnings"])


def test_a_hand_that_turns_the_device_calmly_is_measured_and_accepted(broad02_acc_solved):
    """BROAD trial 2 (turned slowly by hand): the hand's acceleration the solve measures agrees with the optical
    position's (0.35 m/s^2 RMS per axis below 5 Hz, 0.45 below 10 Hz) and is under the bound, so the accelerometer
    is calibrated (its scale within 0.5 % of 1, as the optical truth has it)."""
    from magyro.nls.accelerometer import HAND_LIMIT_OF_G

    _, cal = broad02_acc_solved
    hand = cal.accelerometer.hand_rms_m_s2
    assert 0.25 < hand < 0.5 < HAND_LIMIT_OF_G * G
    assert np.all(np.abs(np.diag(cal.accelerometer.K_a) - 1.0) < 5e-3)


def test_each_rest_counts_once(broad02_solved):
    """The rests at both ends are read against gravity at a node inside each, weighted by the white noise of the
    rest's mean: the interval means wholly inside a rest are left out, or the rest counted twice (once as its mean,
    once as its intervals' means) and its std came out sqrt(2) too small where the rests rule."""
    from magyro.nls.accelerometer import accelerometer_start
    from magyro.nls.grid import build_grid
    from magyro.nls.solve import default_stride, nominal_attitudes

    session, cal = broad02_solved
    rests = find_rests(session).segments_s
    assert len(rests) == 2
    grid = build_grid(session.t_gyro_s, session.gyro_rad_s, session.t_mag_s, default_stride(session))
    C = nominal_attitudes(session, np.eye(3), np.zeros(3), grid.t_node_s)[0]
    start = accelerometer_start(session, session, grid, C, np.eye(3), rests, G)
    assert [r.span_s for r in start.rests] == [tuple(r) for r in rests]
    t = grid.t_node_s
    for r in start.rests:
        assert r.span_s[0] <= t[r.node] <= r.span_s[1] and r.samples > 500
        inside = (t[:-1] >= r.span_s[0]) & (t[1:] <= r.span_s[1])
        assert inside.sum() > 10 and np.all(start.count[inside] == 0)
    columns = start.columns()
    assert np.count_nonzero(columns["wrest0"]) + np.count_nonzero(columns["wrest1"]) == 2


def test_the_hand_states_std_counts_the_recordings_own_hand_at_every_time_it_could_have_come():
    """The hand states' std takes the recording's own hand (three axes, as measured) as the hand that could have
    come, at any time: Omega is the mean over every shift s of e_s e_s^T, e_s = sum_j U_j a_(j+s) (a zero outside
    the record), less the white noise's share. Checked against that sum done shift by shift, with a hand whose axes
    sway differently (no isotropy assumed), and the white noise's share: a hand of white noise alone adds ~nothing."""
    from magyro.nls.hand_motion import shifted_hand_information

    rng = np.random.default_rng(1)
    n, dt = 300, 0.05
    t = np.arange(n) * dt
    hand = np.stack([0.1 * np.sin(2 * np.pi * f * t + rng.uniform(0, 6.3)) for f in (0.3, 0.7, 1.1)], axis=1)
    U = rng.normal(size=(n, 4, 3))                                   # 4 parameters' sensitivities per axis
    shifted = [np.einsum("kga,ka->g", U[max(0, -s): n - max(0, s)], hand[max(0, s): n + min(0, s)])
               for s in range(-n + 1, n)]
    direct = sum(np.outer(e, e) for e in shifted) / n
    np.testing.assert_allclose(shifted_hand_information(U, hand, np.zeros(n)), direct, rtol=1e-9, atol=1e-12)
    assert np.all(np.linalg.eigvalsh(direct) > -1e-12)
    # white noise only: its share taken out, what is left is within the noise of its own periodogram
    sigma = 0.05
    noise = shifted_hand_information(U, rng.normal(scale=sigma, size=(n, 3)), np.full(n, sigma**2))
    flat = U.transpose(0, 2, 1).reshape(-1, 4)
    white = sigma**2 * flat.T @ flat
    assert np.max(np.abs(np.diag(noise))) < 0.2 * np.min(np.diag(white))


def test_the_hands_spectrum_holds_no_power_a_hand_within_reach_cannot_have():
    """A hand's acceleration is its position's second derivative: below f it has at most (2 pi f)^4 times the
    position's variance. `hand_spectrum` caps a measured autocorrelation there (zero at zero frequency) and leaves a
    sway within reach as it is."""
    from magyro.nls.accelerometer import HAND_REACH_M, hand_spectrum, tapered_autocorrelation

    dt, n = 0.05, 4096
    t = np.arange(n) * dt
    rng = np.random.default_rng(0)
    f_hz = np.fft.rfftfreq(8 * 601, dt)
    # a sway of 5 cm at 0.5-2 Hz: within reach, its spectrum is kept
    sway = sum(0.05 * (2 * np.pi * f) ** 2 * np.sin(2 * np.pi * f * t + rng.uniform(0, 6.3)) for f in (0.5, 1.2, 2.0))
    variance = float(np.mean(sway**2))
    rho = tapered_autocorrelation(np.stack([sway] * 3, axis=1), 600, 1.0)
    kept = hand_spectrum(rho, 8 * 601, variance, dt)
    raw = hand_spectrum(rho, 8 * 601, 0.0, dt)
    assert np.allclose(kept[f_hz > 0.3], raw[f_hz > 0.3])
    # a slow drift put into the same variance (what a fit's slow error leaves): capped, zero at 0 Hz
    drift = np.sqrt(variance) * np.sin(2 * np.pi * 0.01 * t)
    rho = tapered_autocorrelation(np.stack([drift] * 3, axis=1), 600, 1.0)
    capped, raw = hand_spectrum(rho, 8 * 601, variance, dt), hand_spectrum(rho, 8 * 601, 0.0, dt)
    assert capped[0] == 0.0 and raw[: 10].max() > 50 * capped[: 10].max()
    # the cap is the bound: the one-sided power below f at most (2 pi f)^4 HAND_REACH_M^2
    df = f_hz[1]
    below = np.cumsum(capped * 2 * variance * dt) * df
    assert np.all(below <= (2 * np.pi * (f_hz + df)) ** 4 * HAND_REACH_M**2 * 1.0001)
