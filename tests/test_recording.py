"""The recording check and its repairs (magyro.front.recording, magyro.front.repairs) on the shipped real
trials, clean and degraded the way real loggers degrade them (tests/degrade.py)."""
from __future__ import annotations

import json
import subprocess
import sys
import time
from dataclasses import replace

import numpy as np
import pytest

import degrade as D
from magyro.front.findings import SCHEMA
from magyro.front.recording import check_recording
from magyro.front.repairs import repair_recording
from magyro.options import Repairs
from magyro.session import HOLE_FACTOR
from magyro.io import write_session

CLEAN = ("broad-02", "broad-07", "simulated-phone-module")


@pytest.fixture(scope="module")
def trials():
    return {name: D.load(name) for name in CLEAN}


@pytest.fixture(scope="module")
def b02(trials):
    return trials["broad-02"]


@pytest.fixture(scope="module")
def b07(trials):
    return trials["broad-07"]


def kinds(check, severity=None):
    return sorted((f.kind, f.sensor) for f in check.findings if severity is None or f.severity == severity)


def one(check, kind, sensor=None):
    found = check.find(kind, sensor)
    assert len(found) == 1, (kind, sensor, kinds(check))
    return found[0]


def arrays(session):
    return [np.array(a, copy=True) for a in (session.t_gyro_s, session.gyro_rad_s, session.t_mag_s, session.mag)]


def assert_unchanged(session, before):
    for a, b in zip(arrays(session), before):
        assert np.array_equal(a, b)


# --------------------------------------------------------------------------- clean trials: no false alarms


@pytest.mark.parametrize("name", CLEAN)
def test_clean_trials_have_no_warning_and_no_error(trials, name):
    check = check_recording(trials[name])
    assert check.usable
    assert kinds(check, "warning") == [] and kinds(check, "error") == []
    assert check.gyro_holes_s == ()
    gyro = check.sensors["gyro"]
    assert not gyro.bursty and gyro.gaps == 0 and gyro.held_fraction < 0.001


def test_broad_magnetometer_repeats_a_third_of_its_rows_and_that_is_reported_as_info(b02, b07):
    """BROAD's magnetometer delivers ~203 Hz into a 285.7 Hz log: 29 % of its rows repeat the previous one."""
    for session in (b02, b07):
        held = one(check_recording(session), "held", "magnetometer")
        assert held.severity == "info"
        assert held.numbers["fraction"] == pytest.approx(0.291, abs=0.005)
        assert held.numbers["distinct_rate_hz"] == pytest.approx(202.6, abs=0.5)
        assert held.numbers["longest_run"] == 5


def test_phone_simulation_has_no_finding_at_all(trials):
    assert check_recording(trials["simulated-phone-module"]).findings == ()


def test_broad_lag_matches_the_solves_time_offset(b02, b07):
    """The magnetometer's lag behind the gyro, from the turning rates alone: the solve finds 11.0-11.2 ms."""
    for session in (b02, b07):
        start, end = check_recording(session).lag_s
        assert 0.008 < start < 0.015 and 0.008 < end < 0.015


# --------------------------------------------------------------------------- bursts and restamping


def test_burst_stamps_are_found_on_both_sensors(b02):
    check = check_recording(D.burst_stamps(b02))
    for sensor in ("gyro", "magnetometer"):
        bursts = one(check, "bursts", sensor)
        assert bursts.severity == "warning" and not bursts.repaired
        assert bursts.numbers["wait_s"] == pytest.approx(0.25, abs=0.01)
        assert bursts.numbers["short_fraction"] > 0.95
        assert check.sensors[sensor].bursty
    assert not check.find("gaps")


def test_restamping_puts_burst_stamps_back_within_a_few_ms(b02):
    bursty = D.burst_stamps(b02)
    late = bursty.t_gyro_s - b02.t_gyro_s
    assert np.median(late) > 0.1                     # the arrival stamps are ~130 ms late, by 5-250 ms
    before = arrays(bursty)
    repaired, check = repair_recording(bursty, Repairs(drop_held=False))
    assert_unchanged(bursty, before)
    for new, old in ((repaired.t_gyro_s, b02.t_gyro_s), (repaired.t_mag_s, b02.t_mag_s)):
        error = new - old
        assert 0.0 < np.median(error) < 0.006            # a constant few ms late: the earliest arrivals
        assert np.ptp(error) < 0.001                     # and no more than 1 ms of scatter
    assert one(check, "bursts", "gyro").repaired and one(check, "bursts", "magnetometer").repaired
    kept, _ = repair_recording(bursty, Repairs(restamp_bursts=False, drop_held=False))
    assert np.array_equal(kept.t_gyro_s, bursty.t_gyro_s)


def test_a_regular_clock_with_dropped_samples_is_not_restamped(b02):
    """Dropped samples leave intervals of 2-3 periods, none far shorter than the period: not bursts."""
    rng = np.random.default_rng(1)
    keep = rng.random(len(b02.t_gyro_s)) > 0.05
    dropped = replace(b02, t_gyro_s=b02.t_gyro_s[keep], gyro_rad_s=b02.gyro_rad_s[keep])
    repaired, check = repair_recording(dropped)
    assert not check.find("bursts") and not check.sensors["gyro"].bursty
    assert np.array_equal(repaired.t_gyro_s, dropped.t_gyro_s)


def test_a_hole_in_bursty_stamps_stays_a_hole(b02):
    bursty = D.burst_stamps(D.hole(b02, 80.0, 30.0))
    repaired, check = repair_recording(bursty)
    assert check.gyro_holes_s and check.gyro_holes_s[0][1] - check.gyro_holes_s[0][0] == pytest.approx(30.0, abs=0.3)
    step = np.diff(repaired.t_gyro_s)
    assert np.sum(step > 1.0) == 1 and np.median(step) == pytest.approx(1 / 285.714, rel=1e-3)


# --------------------------------------------------------------------------- holes


def test_a_hole_is_found_in_both_sensors_and_reported_as_a_gyro_hole(b02):
    holed = D.hole(b02, 80.0, 30.0)
    repaired, check = repair_recording(holed)
    gyro, mag = one(check, "gaps", "gyro"), one(check, "gaps", "magnetometer")
    assert gyro.severity == "warning" and mag.severity == "info"
    for gap in (gyro, mag):
        (a, b), = gap.where_s
        assert 79.99 < a < 80.0 and 110.0 < b < 110.01
    (a, b), = check.gyro_holes_s
    assert 79.99 < a < 80.0 and 110.0 < b < 110.01
    assert one(check, "gyro_holes", "gyro").where_s == check.gyro_holes_s
    assert np.sum(np.diff(repaired.t_gyro_s) > 1.0) == 1      # never filled in


# --------------------------------------------------------------------------- held samples


def test_a_held_magnetometer_is_found_and_dropped_to_its_true_rate(b02):
    held = D.held_mag(b02, mag_rate_hz=65.0)
    finding = one(check_recording(held), "held", "magnetometer")
    assert finding.severity == "warning"
    assert finding.numbers["fraction"] == pytest.approx(1 - 65.0 / 285.714, abs=0.005)
    before = arrays(held)
    repaired, check = repair_recording(held)
    assert_unchanged(held, before)
    assert repaired.mag_rate_hz == pytest.approx(65.0, abs=0.3)
    assert np.all(np.any(np.diff(repaired.mag, axis=0) != 0, axis=1))          # every kept row is new
    first = np.searchsorted(held.t_mag_s, repaired.t_mag_s)
    assert np.all(np.any(held.mag[first[1:]] != held.mag[first[1:] - 1], axis=1))  # the first row of each run
    assert one(check, "held", "magnetometer").repaired
    assert len(repair_recording(held, Repairs(drop_held=False))[0].t_mag_s) == len(held.t_mag_s)


def test_held_rows_are_found_on_a_log_clock_of_their_own(b07):
    held = D.held_mag(b07, mag_rate_hz=65.0, log_rate_hz=256.0)
    assert one(check_recording(held), "held", "magnetometer").numbers["distinct_rate_hz"] == pytest.approx(65.0, abs=0.3)
    assert check_recording(held).sensors["magnetometer"].rate_hz == pytest.approx(256.0, abs=0.1)


# --------------------------------------------------------------------------- saturation


def test_clipping_at_250_deg_s_is_found_on_x_only_and_cut_out(b02):
    clipped = D.clip_gyro(b02, 250.0)
    truly = np.any(np.abs(np.degrees(b02.gyro_rad_s)) >= 250.0, axis=1)
    assert truly.sum() > 200
    repaired, check = repair_recording(clipped)
    sat = check.find("saturation", "gyro")
    assert sorted(f.numbers["limit_deg_s"] for f in sat) == pytest.approx([-250.0, 250.0])
    assert {f.numbers["axis"] for f in sat} == {"x"}
    assert all(f.repaired for f in sat) and all("250 deg/s full scale" in f.message for f in sat)
    assert sum(f.numbers["samples"] for f in sat) == truly.sum()
    cut = ~np.isin(b02.t_gyro_s, repaired.t_gyro_s)
    assert np.all(cut[truly])                                # every clipped sample is cut ...
    widened = cut & ~truly                                   # ... each plateau widened to a hole the solve sees
    assert widened.sum() < 6 * sum(f.numbers["plateaus"] for f in sat)
    gaps = np.diff(repaired.t_gyro_s) / np.median(np.diff(repaired.t_gyro_s))
    assert np.sum(gaps > HOLE_FACTOR) == sum(f.numbers["plateaus"] for f in sat)
    holes = np.array(check.gyro_holes_s)
    cut_times = b02.t_gyro_s[truly]
    inside = np.any((cut_times[:, None] > holes[:, 0]) & (cut_times[:, None] < holes[:, 1]), axis=1)
    assert inside.all()                                      # every cut sample lies in a reported hole
    assert len(holes) == sum(f.numbers["plateaus"] for f in sat)
    assert np.all(holes[:, 1] - holes[:, 0] < 0.5)
    assert one(check, "gyro_holes", "gyro").numbers["count"] == len(holes)


def test_clipping_at_1000_deg_s_is_found_on_every_axis_of_the_fast_trial(b07):
    check = check_recording(D.clip_gyro(b07, 1000.0))
    sat = check.find("saturation", "gyro")
    found = sorted((f.numbers["axis"], round(f.numbers["limit_deg_s"], 6)) for f in sat)
    assert found == [(a, s * 1000.0) for a in "xyz" for s in (-1, 1)]
    kept = repair_recording(D.clip_gyro(b07, 1000.0))[0]
    assert np.degrees(np.abs(kept.gyro_rad_s)).max() < 1000.0


def test_a_natural_peak_is_not_saturation(trials):
    """The clean trials peak at 411 and 1446 deg/s: one sample each at the extreme, no plateau."""
    for session in trials.values():
        assert not check_recording(session).find("saturation")
        assert len(repair_recording(session)[0].t_gyro_s) == len(session.t_gyro_s)


# --------------------------------------------------------------------------- spikes


@pytest.mark.parametrize("name", CLEAN)
def test_every_spike_is_found_and_no_clean_sample_is_removed(trials, name):
    clean = trials[name]
    spiked = D.mag_spikes(clean, n=20)
    where = np.flatnonzero(np.any(spiked.mag != clean.mag, axis=1))
    assert len(where) == 20
    before = arrays(spiked)
    repaired, check = repair_recording(spiked, Repairs(drop_held=False))
    assert_unchanged(spiked, before)
    finding = one(check, "spikes", "magnetometer")
    assert finding.numbers["count"] == 20 and finding.repaired
    assert [a for a, _ in finding.where_s] == pytest.approx(list(clean.t_mag_s[where]))
    assert np.array_equal(repaired.t_mag_s, np.delete(clean.t_mag_s, where))
    assert np.array_equal(repaired.mag, np.delete(clean.mag, where, axis=0))


def test_spikes_of_a_quarter_of_the_field_are_found_on_the_slow_trial(b02):
    spiked = D.mag_spikes(b02, n=20, size=10.0, seed=1)
    assert one(check_recording(spiked), "spikes").numbers["count"] == 20


def test_spikes_in_a_held_magnetometer_are_dropped_before_the_held_rows(b02):
    """A spike inside a run of repeated rows splits it; dropping the spike first joins it again."""
    spiked = D.mag_spikes(b02, n=20, seed=2)
    repaired, _ = repair_recording(spiked)
    clean, _ = repair_recording(b02)
    assert np.all(np.any(np.diff(repaired.mag, axis=0) != 0, axis=1))   # no run left split
    clean_rows = {tuple(row) for row in clean.mag}
    assert all(tuple(row) in clean_rows for row in repaired.mag)         # no spike kept
    assert len(clean.t_mag_s) - 20 <= len(repaired.t_mag_s) < len(clean.t_mag_s)


def test_no_repair_gives_the_recording_back(b02):
    degraded = D.clip_gyro(D.mag_spikes(D.burst_stamps(b02)), 250.0)
    repaired, check = repair_recording(degraded, Repairs.none())
    for a, b in zip(arrays(repaired), arrays(degraded)):
        assert np.array_equal(a, b)
    assert not any(f.repaired for f in check.findings)
    assert {f.kind for f in check.findings} >= {"bursts", "spikes", "saturation"}


# --------------------------------------------------------------------------- units and clocks


@pytest.mark.parametrize("factor, unit", [(1e3, "ms"), (1e6, "us"), (1e9, "ns")])
def test_time_that_is_not_seconds_is_an_error_naming_the_unit(b02, factor, unit):
    check = check_recording(D.wrong_time_unit(b02, factor))
    finding = one(check, "time_unit")
    assert finding.severity == "error" and not check.usable
    word = {"ms": "milliseconds", "us": "microseconds", "ns": "nanoseconds"}[unit]
    assert f"looks like {word}" in finding.message and f"--time-unit {unit}" in finding.message, finding.message
    assert kinds(check, "error") == [("time_unit", "both")]


def test_a_gyro_unit_that_cannot_be_right_is_an_error_both_ways(b02):
    fast = one(check_recording(D.gyro_in_deg_s_labelled_rad_s(b02)), "gyro_unit")
    slow = one(check_recording(D.gyro_in_rad_s_labelled_deg_s(b02)), "gyro_unit")
    assert fast.severity == slow.severity == "error"
    assert "turns 5" in fast.message and "x faster" in fast.message and "--gyro-unit deg/s" in fast.message
    assert "x slower" in slow.message and "--gyro-unit rad/s" in slow.message


def test_a_drifting_magnetometer_clock_is_found_from_the_lag(b07):
    check = check_recording(D.mag_clock_drift(b07, 2000.0))
    drift = one(check, "clock_drift")
    expected = 2000e-6 * 0.65 * (b07.t_gyro_s[-1] - b07.t_gyro_s[0])  # the windows' centres are 0.65 span apart
    change = drift.numbers["lag_end_s"] - drift.numbers["lag_start_s"]
    assert change == pytest.approx(expected, rel=0.2)


def test_a_stretched_magnetometer_clock_is_found_from_the_spans(b07):
    drift = one(check_recording(D.mag_clock_drift(b07, 20000.0)), "clock_drift")
    assert drift.numbers["stretch"] == pytest.approx(0.02, rel=1e-3) and drift.severity == "warning"


def test_a_lag_beyond_the_solves_search_is_found(b07):
    offset = one(check_recording(D.mag_time_offset(b07, 0.3)), "time_offset")
    assert offset.numbers["lag_start_s"] == pytest.approx(0.311, abs=0.005)
    assert "-0.311 s" in offset.fix


def test_sensors_without_common_time_are_an_error(b02):
    apart = replace(b02, t_mag_s=b02.t_mag_s + 1000.0)
    assert kinds(check_recording(apart), "error") == [("overlap", "both")]


def test_too_little_motion_is_not_blamed_on_the_recording(b02, b07):
    """A window that only shakes, or turns about one axis, is the gate's business: no error here."""
    shaking, single = D.shaking_window(b07), D.single_axis_window(b02)
    assert D.max_deviation_deg(shaking.quat_wxyz) <= 22.0 and shaking.duration_s == pytest.approx(6.0, abs=0.01)
    tilt, turned = D.off_axis_and_turn_deg(single.quat_wxyz, single.gyro_rad_s)
    assert tilt <= 7.0 and turned > 180.0
    for window in (shaking, single):
        check = check_recording(window)
        assert check.usable and kinds(check, "warning") == []


# --------------------------------------------------------------------------- the report and its speed


def test_the_report_is_plain_json_with_its_schema(b02):
    _, check = repair_recording(D.clip_gyro(D.hole(b02, 80.0, 30.0), 250.0))
    data = json.loads(check.to_json())
    assert data["schema"] == SCHEMA == "magyro.recording/1" and data["usable"] is True
    assert set(data["sensors"]) == {"gyro", "magnetometer"}
    assert data["repairs"] == {"restamp_bursts": True, "drop_held": True, "cut_saturation": True, "drop_spikes": True,
                               "align_clocks": True}
    assert {f["kind"] for f in data["findings"]} == {"gaps", "saturation", "held", "gyro_holes"}
    for f in data["findings"]:
        assert set(f) == {"kind", "sensor", "severity", "message", "where_s", "matters", "fix", "repaired", "numbers"}
        assert f["matters"] and f["fix"] and f["where_s"]
    assert len(data["gyro_holes_s"]) == len(check.gyro_holes_s) > 1
    table = check.table()
    assert "saturation (gyro) [repaired]" in table and "gaps (gyro)" in table


def test_check_and_repair_take_a_small_share_of_a_solve(b02):
    repair_recording(b02)
    best = min(_timed(lambda: repair_recording(b02)) for _ in range(5))
    # typically 40-220 ms, the best of 5 (a solve of this trial takes 2.5-25 s, idle to loaded); this guards against an
    # order of magnitude, the 10 % share is measured by benchmarks/bench_recording_check.py on a quiet machine
    assert best < 1.0, best


def _timed(job) -> float:
    t = time.perf_counter()
    job()
    return time.perf_counter() - t


def test_the_check_imports_neither_pandas_nor_scipy():
    code = ("import sys, magyro.front.repairs, magyro.front.recording; "
            "print(sorted(m for m in ('pandas', 'scipy') if m in sys.modules))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "[]"


# --------------------------------------------------------------------------- magyro check


def test_magyro_check_prints_the_table_and_writes_the_json(run_magyro, tmp_path):
    out = tmp_path / "check.json"
    r = run_magyro("check", D.DATA / "broad-02.parquet", "-o", out)
    assert r.returncode == 0, r.stderr
    assert "held (magnetometer) [repaired]" in r.stdout and "no findings" not in r.stdout
    data = json.loads(out.read_text())
    assert data["schema"] == "magyro.recording/1" and data["usable"]
    assert data["sensors"]["magnetometer"]["held_fraction"] == pytest.approx(0.291, abs=0.005)


def test_magyro_check_exits_2_on_a_gyro_unit_that_cannot_be_right(run_magyro, assert_plain_failure, tmp_path):
    """rad/s data read as deg/s: the loader accepts it (the rates are small), the check refuses it."""
    out = tmp_path / "check.json"
    r = run_magyro("check", D.DATA / "broad-02.parquet", "--gyro-unit", "deg/s", "-o", out)
    message = assert_plain_failure(r, 2)
    assert "unusable" in message and "rad/s labelled deg/s" in message and "--gyro-unit rad/s" in message
    assert "gyro_unit (gyro)" in r.stdout                  # the table is printed before the refusal
    data = json.loads(out.read_text())
    assert data["usable"] is False and [f["kind"] for f in data["findings"] if f["severity"] == "error"] == ["gyro_unit"]


def test_magyro_check_exits_2_on_millisecond_stamps(run_magyro, assert_plain_failure, b02, tmp_path):
    """The loader or the check (a session built in memory) names the unit; either way exit 2."""
    path = tmp_path / "ms.parquet"
    write_session(D.wrong_time_unit(b02.within(40.0, 60.0), 1e3), path)
    message = assert_plain_failure(run_magyro("check", path), 2)
    assert "milliseconds" in message or "looks like ms" in message


def test_a_session_with_almost_no_samples_is_an_error_not_a_crash(b02):
    check = check_recording(b02.within(40.0, 40.02))
    assert kinds(check, "error") == [("samples", "both")] and not check.usable
    repaired, again = repair_recording(b02.within(40.0, 40.02))
    assert len(repaired.t_gyro_s) == 6 and not again.usable


def test_a_finding_of_an_unknown_kind_is_refused_when_read_back():
    """A recording check written by another magyro, with a finding kind this one does not know, is refused with
    the kind named (exit 2), not read half-understood."""
    from magyro.errors import InputError
    from magyro.front.findings import RecordingCheck

    finding = {"kind": "martian", "sensor": "gyro", "severity": "warning", "message": "?", "where_s": []}
    with pytest.raises(InputError, match="unknown finding kind 'martian'"):
        RecordingCheck.from_dict({"findings": [finding]})
