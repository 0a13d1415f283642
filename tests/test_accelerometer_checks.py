"""The recording check's look at the accelerometer (magyro.front.accelerometer_checks, issue 26): an accelerometer
in g or mg labelled m/s^2 is refused (exit 2) naming its unit, one clipped at its range is a warning, and a session
without an accelerometer is checked as before. On real recordings: the shipped BROAD trials (m/s^2), and the
corpus of other devices' recordings (../shared/data/wild) when present."""
from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pytest

import magyro
from cli_clean import refusal, run_clean
from magyro.errors import InputError
from magyro.front.recording import check_recording, inspect
from magyro.front.repairs import repair_recording
from magyro.studies.scenario import load_problem
from magyro.studies.simulate import simulate

DATA = Path(__file__).resolve().parents[1] / "data"
WILD = Path(__file__).resolve().parents[2] / "shared" / "data" / "wild"   # ../shared beside the repository
G = 9.80665


def broad(name: str):
    return magyro.load_session(DATA / f"{name}.parquet")


def with_acc(session, acc):
    return dataclasses.replace(session, acc_m_s2=acc)


def accelerometer_findings(check) -> list:
    return [f for f in check.findings if f.sensor == "accelerometer"]


def wild(*parts: str) -> Path:
    path = WILD.joinpath(*parts)
    if not path.exists():
        pytest.skip(f"needs {path} (the corpus of other devices' recordings, ../shared/data/wild), absent here")
    return path


# --------------------------------------------------------------------------- sessions the check leaves alone


@pytest.mark.parametrize("name", ["broad-02", "broad-07"])
def test_real_accelerometers_in_m_s2_raise_nothing(name):
    """The BROAD trials hold their accelerometer in m/s^2 (broad-07 up to 3.2 g, unclipped): no accelerometer
    finding, and the findings are those of the same session without its accelerometer."""
    session = broad(name)
    assert session.acc_m_s2 is not None and session.metadata["acc_unit"] == "m/s^2"
    check = check_recording(session)
    assert accelerometer_findings(check) == []
    without = check_recording(dataclasses.replace(session, t_acc_s=None, acc_m_s2=None))
    assert [f.to_dict() for f in check.findings] == [f.to_dict() for f in without.findings]


def test_a_session_without_an_accelerometer_is_untouched():
    session = magyro.load_session(DATA / "simulated-phone-module.parquet")
    assert session.acc_m_s2 is None
    check, evidence = inspect(session)
    assert accelerometer_findings(check) == [] and evidence.acc_saturated is None
    repaired, _ = repair_recording(session)
    assert repaired.t_acc_s is None and repaired.acc_m_s2 is None


def test_a_simulated_accelerometer_is_clean_and_caught_in_g():
    session, _ = simulate(load_problem("phone-module-acc"), 0)
    assert accelerometer_findings(check_recording(session)) == []
    [finding] = accelerometer_findings(check_recording(with_acc(session, session.acc_m_s2 / G)))
    assert finding.kind == "acc_unit" and finding.severity == "error" and "it is in g, not m/s^2" in finding.message


def test_a_gravity_free_acceleration_reading_about_1_is_not_taken_for_g():
    """broad-07's accelerometer less gravity (up from the optical truth), scaled to a median |a| of 1: it reads
    about 0 whenever the hand pauses, which an accelerometer in g never does: no unit is named."""
    session = broad("broad-07")
    np.testing.assert_array_equal(session.t_quat_s, session.t_acc_s)
    w, x, y, z = session.quat_wxyz.T     # IMU frame to ENU: up in the IMU frame is the rotation's third row
    up = np.stack([2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)], axis=1)
    assert np.all(np.isfinite(up))
    linear = session.acc_m_s2 - G * up
    linear /= np.median(np.linalg.norm(linear, axis=1))
    assert accelerometer_findings(check_recording(with_acc(session, linear))) == []


# --------------------------------------------------------------------------- units


@pytest.mark.parametrize("name", ["broad-02", "broad-07"])
@pytest.mark.parametrize("unit,per_m_s2", [("g", 1 / G), ("mg", 1000 / G)])
def test_an_accelerometer_in_g_or_mg_labelled_m_s2_is_an_error_naming_the_unit(name, unit, per_m_s2):
    session = with_acc(broad(name), broad(name).acc_m_s2 * per_m_s2)
    check = check_recording(session)
    [finding] = accelerometer_findings(check)
    assert finding.kind == "acc_unit" and finding.severity == "error" and not check.usable
    assert f"it is in {unit}, not m/s^2" in finding.message and f"--acc-unit {unit}" in finding.fix
    assert finding.numbers["unit"] == unit
    with pytest.raises(InputError) as refused:   # what every solve, observe and check does with it: exit 2
        magyro.calibrate(session)
    assert refused.value.exit_code == 2 and f"it is in {unit}, not m/s^2" in str(refused.value)


def test_magyro_check_exits_2_naming_g_on_broad_divided_by_g(tmp_path):
    from magyro.io import write_session

    session = broad("broad-02")
    write_session(with_acc(session, session.acc_m_s2 / G), tmp_path / "in-g.parquet")
    message = refusal(run_clean("check", tmp_path / "in-g.parquet"), 2)
    assert "reads gravity as about 1.00" in message and "it is in g, not m/s^2" in message, message
    assert "--acc-unit g" in message, message


def test_the_x_io_csv_in_g_is_imported_in_g_by_its_header_and_m_s2_given_is_refused(tmp_path):
    """A real recording in g (x-io IMU, xioTechnologies/Fusion's sensor_data.csv, "Accelerometer X (g)"): imported
    without --acc-unit its header's g is read, and `magyro check` says nothing about it; --acc-unit m/s^2, which
    used to import it as m/s^2 for the check to refuse, now contradicts the header and the import says so (exit 2).
    The check's own refusal of g read as m/s^2 is the test above's, on BROAD 02."""
    source = wild("fusion", "sensor_data.csv")
    units = ["--gyro-unit", "deg/s", "--mag-unit", "uT"]
    message = refusal(run_clean("import", "csv", source, *units, "--acc-unit", "m/s^2", "-o", tmp_path / "x.parquet"), 2)
    assert "--acc-unit m/s^2 contradicts the header" in message and "Accelerometer X (g)" in message, message
    assert run_clean("import", "csv", source, *units, "-o", tmp_path / "g.parquet").returncode == 0
    check = run_clean("check", tmp_path / "g.parquet")
    assert "accelerometer" not in check.stdout, check.stdout


# --------------------------------------------------------------------------- saturation


def test_broad_07_clipped_at_2_g_is_a_saturation_warning_and_its_samples_are_kept():
    session = broad("broad-07")
    clipped = np.clip(session.acc_m_s2, -2 * G, 2 * G)
    pinned = np.abs(clipped) == 2 * G
    check, evidence = inspect(with_acc(session, clipped))
    found = accelerometer_findings(check)
    assert {(f.numbers["axis"], np.sign(f.numbers["limit_m_s2"])) for f in found} == \
        {(axis, sign) for k, axis in enumerate("xyz") for sign in (1.0, -1.0) if np.any(sign * clipped[:, k] == 2 * G)}
    for f in found:
        assert f.kind == "saturation" and f.severity == "warning" and "a +/-2 g full scale" in f.message, f.message
        assert abs(f.numbers["limit_m_s2"]) == 2 * G
    np.testing.assert_array_equal(evidence.acc_saturated, pinned.any(axis=1))
    assert check.usable
    repaired, after = repair_recording(with_acc(session, clipped))
    np.testing.assert_array_equal(repaired.acc_m_s2, clipped)   # reported, not cut: the samples are kept
    assert not any(f.repaired for f in accelerometer_findings(after))


def test_the_sparkfun_razors_accelerometer_saturates_at_2_g():
    """A real clipped accelerometer: the SparkFun 9DOF Razor of CCNYRoboticsLab/imu_tools' sample bag reads
    +19.60 and -19.64 m/s^2 (its +/-2 g range) on plateaus of several axes."""
    from magyro.io.rosbag import import_rosbag

    session = import_rosbag(wild("imu_tools", "imutools-2013-sparkfun_razor.bag"))
    found = accelerometer_findings(check_recording(session))
    assert found and all(f.kind == "saturation" and f.severity == "warning" for f in found)
    assert all("a +/-2 g full scale" in f.message for f in found), [f.message for f in found]
    assert {f.numbers["axis"] for f in found} == {"x", "y", "z"}
