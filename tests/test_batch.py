"""`magyro batch` (issue 15): a fleet of sessions calibrated on the local pool or a Dask cluster, each device's
row on disk as it arrives, broken sessions named with their cause, a killed batch resumed without redoing a
device, and the same numbers bit for bit on either executor.

The fleet mixes simulated production-line devices (`magyro simulate production-line --seeds`, each with its
own sensor errors) with the shipped real BROAD trial, clean and degraded the way real loggers degrade it
(tests/degrade.py), and files that are not sessions at all.
"""
from __future__ import annotations

import json
import os
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from magyro.batch.limits import Limits
from magyro.batch.run import run_batch
from magyro.errors import InputError
from magyro.io import write_session
from magyro.studies.fleet import simulate_fleet
from magyro.studies.scenario import load_problem

sys.path.insert(0, str(Path(__file__).resolve().parent))
import degrade  # noqa: E402

MAGYRO = [sys.executable, "-m", "magyro"]
NUMBERS = ("gyro", "misalignment", "magnetometer", "field_i", "time_offset_s", "std", "std_white")


@pytest.fixture(scope="module")
def fleet(tmp_path_factory) -> Path:
    """Three simulated devices of the production line, with their manifest."""
    folder = tmp_path_factory.mktemp("fleet")
    simulate_fleet(load_problem("production-line"), [0, 1, 2], folder)
    return folder


@pytest.fixture(scope="module")
def solved_fleet(fleet, tmp_path_factory):
    """(result, output folder) of the fleet batched once with the defaults; tests that go on from a solved fleet
    work on a copy of the folder (`solved_copy`), so its three solves are made once for the module."""
    out = tmp_path_factory.mktemp("solved") / "out"
    return run_batch([fleet / "manifest.csv"], out), out


def solved_copy(solved_fleet, tmp_path: Path) -> Path:
    out = tmp_path / "out"
    shutil.copytree(solved_fleet[1], out)
    return out


# the hostile inputs: real data degraded (with the exit code of the right refusal), and files that are not sessions
HOSTILE = {
    "time-in-ms": (lambda: degrade.wrong_time_unit(degrade.load("broad-02")), 2, "time"),
    "deg-labelled-rad": (lambda: degrade.gyro_in_deg_s_labelled_rad_s(degrade.load("broad-02")), 2, "rad/s"),
    "single-axis": (lambda: degrade.single_axis_window(degrade.load("broad-02")), 3, "axis"),
}


def hostile_files(folder: Path) -> dict[str, tuple[int, str]]:
    """Write the hostile sessions into `folder`; device id -> (exit code, a word its message must hold)."""
    expected = {}
    for name, (make, code, word) in HOSTILE.items():
        write_session(make(), folder / f"{name}.parquet")
        expected[name] = (code, word)
    (folder / "not-parquet.parquet").write_bytes(b"PAR1 this is not a parquet file")
    expected["not-parquet"] = (2, "parquet")
    (folder / "empty.csv").write_text("")
    expected["empty"] = (2, "empty")
    (folder / "no-magnetometer.csv").write_text("t,gx,gy,gz\n0,0,0,0\n0.01,0,0,0\n")
    expected["no-magnetometer"] = (2, "column")
    return expected


def calibration_numbers(path: Path) -> dict:
    data = json.loads(path.read_text())
    return {k: data[k] for k in NUMBERS if k in data}


# --------------------------------------------------------------------------- isolation, on real data


def test_broken_sessions_are_named_with_their_cause_and_the_good_ones_calibrated(fleet, tmp_path):
    sessions = tmp_path / "sessions"
    sessions.mkdir()
    expected = hostile_files(sessions)
    write_session(degrade.burst_stamps(degrade.load("broad-02")), sessions / "broad-02-bursty.parquet")
    result = run_batch([fleet / "manifest.csv", sessions], tmp_path / "out", jobs=2)

    rows = {r["device_id"]: r for r in result.rows}
    assert len(rows) == 3 + 1 + len(expected)
    good = [d for d in rows if d not in expected]
    for device in good:
        assert rows[device]["exit_code"] == 0, rows[device]["message"]
        assert rows[device]["verdict"] == "accepted"
        assert (tmp_path / "out" / rows[device]["calibration"]).is_file()
    assert "restamp" in rows["broad-02-bursty"]["repaired"] or rows["broad-02-bursty"]["repaired"]
    for device, (code, word) in expected.items():
        row = rows[device]
        assert (row["exit_code"], row["verdict"]) == (code, "failed"), (device, row["message"])
        assert word in row["message"].lower(), (device, row["message"])
        assert row["exit_class"] != "crashed" and not row["calibration"]
        assert not (tmp_path / "out" / "calibrations" / f"{device}.json").exists()

    summary = pd.read_parquet(tmp_path / "out" / "summary.parquet")
    assert sorted(summary["device_id"]) == sorted(rows)
    html = (tmp_path / "out" / "summary.html").read_text()
    assert all(device in html for device in expected)


def test_devices_recover_their_own_truth_within_their_std(fleet, solved_fleet):
    result, _ = solved_fleet
    for row in result.rows:
        truth = json.loads((fleet / f"{Path(row['session']).stem}.truth.json").read_text())
        K_g, bias = np.array(truth["gyro"]["K_g"]), np.array(truth["gyro"]["bias_deg_s"])
        for i, a in enumerate("xyz"):
            assert abs(row[f"scale_ppm_{a}"] - 1e6 * (K_g[i, i] - 1)) < 4 * row[f"std_scale_ppm_{a}"]
            assert abs(row[f"bias_deg_s_{a}"] - bias[i]) < 4 * row[f"std_bias_deg_s_{a}"]


def test_limits_rejudge_the_fleet_without_solving_again(fleet, solved_fleet, tmp_path):
    first, _ = solved_fleet
    assert (first.solved, first.reused) == (3, 0)
    biggest = max(abs(r["bias_deg_s_x"]) for r in first.rows)
    strict = Limits(max_abs_bias_deg_s=0.999 * biggest)
    second = run_batch([fleet / "manifest.csv"], solved_copy(solved_fleet, tmp_path), limits=strict)
    assert (second.solved, second.reused) == (0, 3)
    rejected = [r for r in second.rows if r["verdict"] == "rejected"]
    assert len(rejected) >= 1 and all("bias_deg_s" in r["verdict_reason"] for r in rejected)


def test_a_changed_session_or_option_is_solved_again(fleet, solved_fleet, tmp_path):
    out = solved_copy(solved_fleet, tmp_path)
    again = run_batch([fleet / "manifest.csv"], out, redo=True)
    assert (again.solved, again.reused) == (3, 0)
    from magyro.options import Options
    other = run_batch([fleet / "manifest.csv"], out, Options(estimate_time_offset=False))
    assert (other.solved, other.reused) == (3, 0)


# --------------------------------------------------------------------------- resume after a kill


def test_a_killed_batch_finishes_the_rest_without_redoing_a_device(tmp_path):
    folder = tmp_path / "fleet"
    folder.mkdir()
    simulate_fleet(load_problem("production-line"), list(range(6)), folder)
    out = tmp_path / "out"
    command = MAGYRO + ["batch", str(folder / "manifest.csv"), "-o", str(out), "-q"]
    process = subprocess.Popen(command, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, start_new_session=True)
    deadline = time.monotonic() + 120
    while time.monotonic() < deadline and len(list((out / "rows").glob("*.json"))) < 2:
        time.sleep(0.05)
    os.killpg(process.pid, signal.SIGKILL)
    process.wait()
    done_before = {p.name: p.stat().st_mtime_ns for p in (out / "rows").glob("*.json")}
    assert 2 <= len(done_before) < 6, "the batch was not stopped mid-way"
    assert not (out / "summary.parquet").exists()
    assert not list(out.rglob("*.tmp")) and not [p for p in out.rglob(".*") if p.is_file()]

    r = subprocess.run(command[:-1], capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, r.stderr
    assert f"{6 - len(done_before)} solved now, {len(done_before)} kept from an earlier run" in r.stdout
    assert {p.name: p.stat().st_mtime_ns for p in (out / "rows").glob("*.json") if p.name in done_before} == done_before
    assert len(pd.read_csv(out / "summary.csv")) == 6


# --------------------------------------------------------------------------- the command line


def test_cli_exit_codes_and_messages(fleet, solved_fleet, tmp_path):
    limits = tmp_path / "limits.toml"
    limits.write_text("[limits]\nmax_abs_bias_deg_s = 1e-6\n")
    solved_copy(solved_fleet, tmp_path)      # the solves are kept: this is about the command's exits and messages
    r = subprocess.run(MAGYRO + ["batch", str(fleet / "manifest.csv"), "-o", str(tmp_path / "out"), "--limits",
                                 str(limits)], capture_output=True, text=True, timeout=300)
    assert r.returncode == 1 and "3 of 3 devices not accepted (3 rejected, 0 failed)" in r.stderr, r.stderr
    r = subprocess.run(MAGYRO + ["batch", str(fleet / "manifest.csv"), "-o", str(tmp_path / "out"), "-q"],
                       capture_output=True, text=True, timeout=300)
    assert r.returncode == 0 and r.stderr == "", r.stderr
    for bad, word in ((str(tmp_path / "missing.parquet"), "no such file"), (str(tmp_path / "*.nothing"), "no file matches")):
        r = subprocess.run(MAGYRO + ["batch", bad, "-o", str(tmp_path / "out2")], capture_output=True, text=True)
        assert r.returncode == 2 and word in r.stderr and "Traceback" not in r.stderr, r.stderr
        assert not (tmp_path / "out2").exists()
    limits.write_text("[limits]\nmax_bias = 1\n")
    r = subprocess.run(MAGYRO + ["batch", str(fleet), "-o", str(tmp_path / "out3"), "--limits", str(limits)],
                       capture_output=True, text=True)
    assert r.returncode == 2 and "max_bias" in r.stderr and not (tmp_path / "out3").exists(), r.stderr


def test_inputs_are_checked_before_any_work(fleet, tmp_path):
    from magyro.batch.inputs import devices_from_inputs

    devices = devices_from_inputs([str(fleet)])
    assert [d.device_id for d in devices] == ["production-line-0000", "production-line-0001", "production-line-0002"]
    assert [d.device_id for d in devices_from_inputs([str(fleet / "manifest.csv")])] == [d.device_id for d in devices]
    with pytest.raises(InputError, match="two sessions have the device id production-line-0000"):
        devices_from_inputs([str(fleet), str(fleet / "production-line-0000.parquet")])
    bad = tmp_path / "m.csv"
    bad.write_text("device_id,session\nA/1,x.parquet\n")
    with pytest.raises(InputError, match="line 2"):
        devices_from_inputs([str(bad)])
    bad.write_text(f"device_id,session\nA1,{tmp_path / 'missing.parquet'}\n")
    with pytest.raises(InputError, match="is not a file"):
        devices_from_inputs([str(bad)])
    inside = tmp_path / "out" / "calibrations" / "a.parquet"   # a session where the batch writes its own files
    inside.parent.mkdir(parents=True)
    inside.write_bytes((fleet / "production-line-0000.parquet").read_bytes())
    with pytest.raises(InputError, match="inside"):
        run_batch([str(inside)], tmp_path / "out")
    assert inside.read_bytes() == (fleet / "production-line-0000.parquet").read_bytes()
    assert not (tmp_path / "out" / "rows").exists()


def test_reports_are_written_per_device(fleet, tmp_path):
    pytest.importorskip("matplotlib", reason="the device reports need magyro[plot]")
    result = run_batch([fleet / "production-line-0000.parquet"], tmp_path / "out", reports=True)
    page = (tmp_path / "out" / "reports" / "production-line-0000.html").read_text()
    assert result.rows[0]["exit_code"] == 0 and page.startswith("<!DOCTYPE html>") and "production-line-0000" in page
