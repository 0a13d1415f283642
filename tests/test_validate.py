"""Tests for magyro.validate: dead reckoning against truth, closure drift, the figure."""
from __future__ import annotations

import dataclasses
import json
from pathlib import Path

import numpy as np
import pytest

from magyro import so3
from magyro.errors import InputError
from magyro.result.calibration import Calibration
from magyro.io import trim
from magyro.io import load_session
from magyro.studies.scenario import load_problem
from magyro.studies.simulate import simulate, truth_body_attitude
from magyro.studies.dead_reckoning import attitude_at, plot_validation, validate

DATA = Path(__file__).resolve().parents[1] / "data"


def with_truth(session, problem, offset=None):
    """The simulated session plus its true body attitude as truth quaternions (gyro frame to world).

    `offset`: a rotation X (truth body from gyro frame) to put the truth in a rotated body frame.
    """
    C = truth_body_attitude(problem, session.t_gyro_s)
    if offset is not None:
        C = C @ offset.T
    return dataclasses.replace(session, t_quat_s=session.t_gyro_s.copy(), quat_wxyz=so3.dcm_to_quat(C))


def true_calibration(truth: dict) -> Calibration:
    """The simulated sensor's true gyro and magnetometer parameters as a Calibration."""
    return Calibration.from_parameters(truth["gyro"]["K_g"], truth["gyro"]["bias_rad_s"],
                                       R=truth["magnetometer"]["R"], h=truth["magnetometer"]["h"], method="truth")


@pytest.fixture(scope="module")
def paper():
    problem = load_problem("paper-table1")
    session, truth = simulate(problem, 5)
    return problem, session, true_calibration(truth)


@pytest.fixture(scope="module")
def phone():
    problem = load_problem("phone-module")
    session, truth = simulate(problem, 5)
    return problem, session, true_calibration(truth)


def test_truth_mode_true_calibration_beats_raw(paper):
    problem, session, truth = paper
    report = validate(with_truth(session, problem), truth)
    assert report.mode == "truth"
    raw, cal = report.summary["raw"], report.summary["calibrated"]
    assert raw["rms_deg"] > 20.0                    # 10-30 % scale errors and deg/s biases
    assert cal["rms_deg"] < 0.5 and cal["max_deg"] < 1.0
    assert cal["rms_deg"] < 0.02 * raw["rms_deg"]
    assert report.ratio == pytest.approx(cal["rms_deg"] / raw["rms_deg"])
    assert cal["angle_only_rms_deg"] <= cal["rms_deg"] + 1e-9   # a lower bound
    assert report.diagnostics["truth_frame_offset_deg"] < 0.05
    assert len(report.error_deg["raw"]) == len(report.t_s) == len(session.t_gyro_s)
    assert report.error_deg["calibrated"][0] == pytest.approx(0.0, abs=1e-9)
    text = report.table()
    assert "raw gyro" in text and "calibrated gyro" in text and "RMS" in text


def test_truth_mode_error_is_free_of_the_world_frames(paper):
    """A different reference frame for the truth (e.g. ENU vs the start pose) changes nothing."""
    problem, session, truth = paper
    s = with_truth(session, problem)
    C = so3.quat_to_dcm(s.quat_wxyz)
    rotated = dataclasses.replace(s, quat_wxyz=so3.dcm_to_quat(so3.euler_to_dcm([30, -50, 170]) @ C))
    a, b = validate(s, truth), validate(rotated, truth)
    for name in ("raw", "calibrated"):
        assert b.summary[name]["rms_deg"] == pytest.approx(a.summary[name]["rms_deg"], abs=1e-6)


def test_truth_in_a_rotated_body_frame_is_flagged(paper):
    problem, session, truth = paper
    X = so3.euler_to_dcm([1.5, -1.0, 2.0])
    report = validate(with_truth(session, problem, offset=X), truth)
    expected = np.rad2deg(np.linalg.norm(so3.log_so3(X)))
    assert report.diagnostics["truth_frame_offset_deg"] == pytest.approx(expected, abs=0.05)
    assert any("rotated" in n for n in report.notes)
    assert report.summary["calibrated"]["rms_deg"] > 1.0   # the floor the offset causes


def test_truth_with_gaps_and_other_times_is_interpolated(paper):
    """Truth at its own instants (between gyro samples) with a marker gap still gives the same errors."""
    problem, session, truth = paper
    t_q = np.arange(0.0025, session.t_gyro_s[-1], 1 / 120.0)
    t_q = t_q[(t_q < 30.0) | (t_q > 32.0)]
    q = so3.dcm_to_quat(truth_body_attitude(problem, t_q))
    s = dataclasses.replace(session, t_quat_s=t_q, quat_wxyz=q)
    report = validate(s, truth)
    assert report.diagnostics["longest_truth_gap_s"] == pytest.approx(2.0, abs=0.01)
    reference = validate(with_truth(session, problem), truth)
    assert report.summary["calibrated"]["rms_deg"] < 0.5
    assert report.summary["raw"]["rms_deg"] == pytest.approx(reference.summary["raw"]["rms_deg"], rel=0.02)


def test_attitude_at_interpolates_on_the_geodesic():
    t = np.array([0.0, 1.0, 2.0])
    C = so3.exp_so3(np.array([[0, 0, 0], [0, 0, 0.4], [0, 0, 0.8]]))
    got = attitude_at(t, C, np.array([0.0, 0.25, 1.5, 2.0]))
    np.testing.assert_allclose(so3.log_so3(got)[:, 2], [0.0, 0.1, 0.6, 0.8], atol=1e-12)


def test_calibration_inputs_agree(paper, tmp_path):
    """A Calibration and the JSON it writes dead-reckon alike; no calibration is the raw gyro."""
    problem, session, truth = paper
    s = with_truth(session, problem)
    path = tmp_path / "cal.json"
    truth.to_json(path)
    numbers = [validate(s, c).summary["calibrated"]["rms_deg"] for c in (truth, str(path), path)]
    assert numbers == pytest.approx([numbers[0]] * 3, rel=1e-12)
    assert numbers[0] < 0.05 * validate(s, None).summary["raw"]["rms_deg"]
    identity = validate(s, None)
    assert identity.summary["calibrated"] == identity.summary["raw"]
    assert any("no calibration" in n for n in identity.notes)


def test_bad_calibrations_are_input_errors(paper, tmp_path):
    """What is not a calibration JSON of this schema is refused, naming the cause."""
    problem, session, truth = paper
    good = truth.to_dict()
    cases = {
        "truth.json": (json.dumps({"schema": "magyro.truth/1", "gyro": good["gyro"]}), "simulated session"),
        "other.json": (json.dumps({**good, "schema": "magyro.calibration/2"}), "expected 'magyro.calibration/1'"),
        "shape.json": (json.dumps({**good, "gyro": {**good["gyro"], "K_g": [[1, 0], [0, 1]]}}), r"gyro.K_g must have shape \(3, 3\)"),
        "nan.json": (json.dumps({**good, "gyro": {**good["gyro"], "bias_rad_s": [0, float("nan"), 0]}}), "NaN"),
        "units.json": (json.dumps({**good, "units": {**good["units"], "angular_rate": "deg/s"}}), "units"),
        "cut.json": (json.dumps(good)[:500], "cut short"),
        "list.json": ("[1, 2, 3]", "JSON object"),
    }
    for name, (text, message) in cases.items():
        (tmp_path / name).write_text(text)
        with pytest.raises(InputError, match=message):
            validate(session, tmp_path / name)
    with pytest.raises(InputError, match="no such file"):
        validate(session, tmp_path / "missing.json")
    with pytest.raises(InputError, match="must be a Calibration"):
        validate(session, {"gyro": good["gyro"]})


def test_closure_mode_without_truth(phone):
    problem, session, truth = phone
    assert session.t_quat_s is None
    report = validate(session, truth)
    assert report.mode == "closure"
    raw, cal = report.summary["raw"]["closure_deg"], report.summary["calibrated"]["closure_deg"]
    assert raw > 10.0                                  # deg/s-level biases over 60 s
    assert cal < 0.5 and cal < 0.05 * raw
    # the simulated motion ends in its start pose, and the magnetometer agrees
    assert report.diagnostics["pose_mismatch_mag_deg"] < 1.0
    assert not any("differ" in n for n in report.notes)
    assert report.euler_deg["raw"].shape == (len(report.t_s), 3)
    assert "closure drift" in report.table()


def test_closure_warns_when_start_and_end_poses_differ(phone):
    problem, session, truth = phone
    report = validate(trim(session, 0.0, 25.0), truth)
    assert report.mode == "closure"
    assert any("poses differ" in n for n in report.notes)


def test_report_json_and_figures(paper, phone, tmp_path):
    pytest.importorskip("matplotlib")
    problem, session, truth = paper
    truth_report = validate(with_truth(session, problem), truth)
    closure_report = validate(phone[1], phone[2])
    for report in (truth_report, closure_report):
        d = json.loads(json.dumps(report.to_dict(include_series=True)))
        assert d["schema"] == "magyro.validation/1" and d["mode"] == report.mode
        assert len(d["series"]["t_s"]) <= 2000
        assert set(d["summary"]) == {"raw", "calibrated"}
        out = tmp_path / f"{report.mode}.png"
        plot_validation(report, out)
        assert out.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert "series" not in truth_report.to_dict()
    with pytest.raises(InputError, match="figure"):
        plot_validation(truth_report, tmp_path / "figure.nonsense")
    assert not [p for p in tmp_path.iterdir() if p.name.endswith(".tmp")]


def test_shipped_broad_session_raw_dead_reckoning():
    """The real trial: the raw gyro drifts by tens of degrees; the truth frame is the IMU frame."""
    s = load_session(DATA / "broad-02.parquet")
    report = validate(s, None)
    assert report.mode == "truth"
    raw = report.summary["raw"]
    assert 5.0 < raw["rms_deg"] < 60.0 and raw["final_deg"] > 10.0
    assert report.diagnostics["truth_frame_offset_deg"] < 0.5
    assert report.diagnostics["max_truth_rotation_deg"] > 150.0
    # removing the rest-period gyro mean (a bias-only calibration) already cuts the error by > 3x
    t0, t1 = (float(x) for x in s.metadata["movement_span_s"].split())
    rest = (s.t_gyro_s < t0 - 0.5) | (s.t_gyro_s > t1 + 0.5)
    bias_only = Calibration.from_parameters(np.eye(3), -s.gyro_rad_s[rest].mean(axis=0))
    assert validate(s, bias_only).summary["calibrated"]["rms_deg"] < raw["rms_deg"] / 3
