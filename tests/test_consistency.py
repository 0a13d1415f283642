"""The split-half check: quiet when the model holds, loud when the recording changes half way."""
from __future__ import annotations

import dataclasses
import json

import numpy as np
import pytest

from magyro.result import consistency

from magyro import so3
from magyro.options import Options
from magyro import calibrate
from magyro.front.prepare import moving_session
from magyro.errors import ObservabilityError
from magyro.io import write_session
from magyro.studies.scenario import load_problem
from magyro.studies.simulate import simulate

pytestmark = pytest.mark.slow  # three solves per session


@pytest.fixture(scope="module")
def paper():
    return simulate(load_problem("paper-table1"), 5)


@pytest.fixture(scope="module")
def paper_checked(paper):
    return calibrate(paper[0], Options(split_check=True))


def turned_second_half(session, truth, angle_deg: float):
    """The magnetometer turned on the board by `angle_deg` about its z axis half way through the motion."""
    R, h = np.array(truth["magnetometer"]["R"]), np.array(truth["magnetometer"]["h"])
    A = np.linalg.inv(R)                                 # y = A C m + h
    turn = A @ so3.rot_z(np.deg2rad(angle_deg)) @ R      # y - h -> A Q A^-1 (y - h)
    first_half, _ = consistency.half_spans_s(moving_session(session, Options())[0])
    late = session.t_mag_s > first_half[1]
    mag = session.mag.copy()
    mag[late] = h + (mag[late] - h) @ turn.T
    return dataclasses.replace(session, mag=mag)


def test_halves_agree_within_their_std_when_the_model_holds(paper_checked):
    cal = paper_checked
    report = cal.consistency
    rows = report.parameters
    assert len(rows) == 12 and report.compared
    assert report.rms_z < consistency.MAX_RMS_Z, report.rms_z
    assert report.max_abs_z < consistency.MAX_HALF_Z, (report.worst, report.max_abs_z)
    assert not [w for w in cal.warnings if "halves" in w], cal.warnings
    # the halves are real calibrations of half the data: each sits near the full estimate
    assert abs(rows["K_g[0,0]"]["first"] - cal.K_g[0, 0]) < 5e-3


def test_a_magnetometer_turned_half_way_is_caught(paper, paper_checked):
    session, truth = paper
    cal = calibrate(turned_second_half(session, truth, 0.5), Options(split_check=True))
    report = cal.consistency
    assert report.rms_z > consistency.MAX_RMS_Z, report.rms_z
    assert report.worst.startswith("misalignment_d"), report.worst
    # C_b_m -> Rz(0.5 deg) C_b_m in the second half: the halves' difference in d turns by 0.5 deg about
    # the m frame's z axis, which is C_b_m^T e_z in the gyro frame; the first half is the same data
    names = [f"misalignment_d{a}_deg" for a in "xyz"]
    before = paper_checked.consistency.parameters
    shift = np.array([before[n]["difference"] - report.parameters[n]["difference"] for n in names])
    axis = paper_checked.C_b_m.T @ np.array([0.0, 0.0, 1.0])
    np.testing.assert_allclose(shift, 0.5 * axis, atol=0.01)
    assert report.parameters["K_g[0,0]"]["first"] == pytest.approx(before["K_g[0,0]"]["first"], abs=1e-9)
    warning = [w for w in cal.warnings if "halves" in w]
    assert len(warning) == 1 and "understates the error" in warning[0] and report.worst in warning[0]


def test_a_half_that_cannot_be_solved_is_reported(paper):
    session, _ = paper
    full = calibrate(session)

    def refuse(half, options):
        raise ObservabilityError("the motion does not excite every gyro parameter: rank 9 of 12", None)

    report = consistency.split_check(session, full, Options(), refuse)
    assert len(report.failed) == 2 and "rank 9 of 12" in report.failed[0]
    assert report.failed[0].startswith("first half (")
    warning = consistency.split_warning(report)
    assert "could not calibrate each half" in warning and "record longer" in warning


def test_solve_split_check_writes_the_report(paper, run_magyro, tmp_path):
    session, _ = paper
    path = tmp_path / "s.parquet"
    write_session(session, path)
    out = tmp_path / "c.json"
    result = run_magyro("solve", path, "--split-check", "-o", out)
    assert result.returncode == 0, result.stderr
    assert "split-half check: the halves differ by" in result.stdout
    doc = json.loads(out.read_text())
    assert set(doc["consistency"]["parameters"]) == {name for name, _, _ in consistency.QUANTITIES}
    assert doc["consistency"]["rms_z"] < consistency.MAX_RMS_Z
    plain = tmp_path / "plain.json"
    assert run_magyro("solve", path, "-o", plain, "-q").returncode == 0
    assert "consistency" not in json.loads(plain.read_text())
