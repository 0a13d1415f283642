"""The command line beyond the default solve: `python -m magyro`, `--method ekf`, `--loss huber`, `validate`.

Run as a user runs them (subprocesses), on the shipped real recording (BROAD trial 02) or
on a simulated session with its truth, and read back through `Calibration.from_json`.
"""
from __future__ import annotations

import dataclasses
import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from magyro.io import load_session, write_session
from magyro.result.calibration import Calibration

DATA = Path(__file__).resolve().parent.parent / "data"
BROAD_02 = DATA / "broad-02.parquet"


def test_python_dash_m_is_the_magyro_command():
    done = subprocess.run([sys.executable, "-m", "magyro", "--version"], capture_output=True, text=True, timeout=60)
    assert done.returncode == 0, done.stderr
    assert done.stdout.split()[0] == "magyro"


@pytest.fixture(scope="module")
def phone(tmp_path_factory, run_magyro):
    """A simulated phone module (200 Hz gyro, 50 Hz magnetometer, hard and soft iron) and its truth."""
    d = tmp_path_factory.mktemp("phone")
    done = run_magyro("simulate", "phone-module", "-o", "s.parquet", "--seed", 4, cwd=d)
    assert done.returncode == 0, done.stderr
    return d, json.loads((d / "s.truth.json").read_text())


@pytest.mark.slow
def test_solve_method_ekf_writes_a_calibration_and_its_history(phone, run_magyro):
    d, truth = phone
    done = run_magyro("solve", "s.parquet", "--method", "ekf", "-o", "ekf.json", "--history", "h.parquet", cwd=d)
    assert done.returncode == 0, done.stderr
    assert "solver: ekf done" in done.stdout
    cal = Calibration.from_json(d / "ekf.json")
    assert cal.solver.method == "ekf" and cal.observability.rank == 12
    z = (cal.bias_deg_s - np.array(truth["gyro"]["bias_deg_s"])) / cal.std.bias_deg_s
    scale = (np.diag(cal.K_g) - np.diag(truth["gyro"]["K_g"])) / np.diag(cal.std.K_g)
    assert np.all(np.abs(z) < 4) and np.all(np.abs(scale) < 4), (z, scale)
    history = pd.read_parquet(d / "h.parquet")
    assert len(history) > 100 and history["t_s"].is_monotonic_increasing
    assert history["K11"].iloc[-1] == pytest.approx(cal.K[0, 0], rel=1e-9)


def spiky(session, fraction: float, size: float, seed: int = 0):
    """Magnetometer spikes of +/- `size` on every axis of a `fraction` of the samples, as a glitching logger gives."""
    rng = np.random.default_rng(seed)
    mag = session.mag.copy()
    hit = rng.choice(len(mag), int(fraction * len(mag)), replace=False)
    mag[hit] += rng.choice([-1.0, 1.0], size=(len(hit), 3)) * size
    return dataclasses.replace(session, mag=mag)


@pytest.mark.heavy
@pytest.mark.slow
def test_loss_huber_resists_magnetometer_spikes_on_a_real_recording(tmp_path, run_magyro):
    """1 % of BROAD trial 02's magnetometer samples spiked by 40 uT (55 sigma), the spike repair turned off: the
    plain least squares moves the gyro scale and bias by up to 3.5 of the clean solve's white-noise std (the
    precision the noise allows; `std`, which also counts the room's field, is about 2x that), the Huber loss
    by less than half of that. With the repair on (the default) the spikes are dropped before any solve."""
    session = load_session(BROAD_02)
    write_session(spiky(session, 0.01, 40.0), tmp_path / "spiky.parquet")
    spiky_file = tmp_path / "spiky.parquet"
    runs = {"clean": (BROAD_02,), "l2": (spiky_file, "--no-repair", "spikes"),
            "huber": (spiky_file, "--loss", "huber", "--no-repair", "spikes"), "repaired": (spiky_file,)}
    cals = {}
    for name, args in runs.items():
        done = run_magyro("solve", *args, "-o", tmp_path / f"{name}.json", "-q")
        assert done.returncode == 0, done.stderr
        cals[name] = Calibration.from_json(tmp_path / f"{name}.json")
    clean = cals["clean"]

    def worst_z(cal) -> float:
        z_bias = (cal.bias_deg_s - clean.bias_deg_s) / clean.std_white.bias_deg_s
        z_scale = (np.diag(cal.K_g) - np.diag(clean.K_g)) / np.diag(clean.std_white.K_g)
        return float(np.max(np.abs(np.concatenate([z_bias, z_scale]))))

    assert cals["huber"].solver.details["loss"] == "huber" and cals["l2"].solver.details["loss"] == "l2"
    assert worst_z(cals["l2"]) > 2.5, worst_z(cals["l2"])
    assert worst_z(cals["huber"]) < 0.5 * worst_z(cals["l2"]), (worst_z(cals["huber"]), worst_z(cals["l2"]))
    assert worst_z(cals["repaired"]) < 0.5, worst_z(cals["repaired"])
    spikes = [f for f in cals["repaired"].recording.findings if f.kind == "spikes"]
    assert len(spikes) == 1 and spikes[0].repaired and spikes[0].numbers["count"] >= 0.95 * 0.01 * len(session.mag)


@pytest.mark.slow
def test_validate_command_on_the_shipped_recording(tmp_path, run_magyro):
    done = run_magyro("solve", BROAD_02, "-o", tmp_path / "calib.json", "-q")
    assert done.returncode == 0, done.stderr
    done = run_magyro("validate", BROAD_02, tmp_path / "calib.json", "-o", tmp_path / "report.json")
    assert done.returncode == 0, done.stderr
    report = json.loads((tmp_path / "report.json").read_text())
    assert report["mode"] == "truth"
    raw, calibrated = (report["summary"][name]["rms_deg"] for name in ("raw", "calibrated"))
    assert calibrated < 0.2 * raw, (calibrated, raw)     # docs/results.md: 0.705 deg against 15.9 deg
    assert report["calibrated_over_raw"] == pytest.approx(calibrated / raw)


def test_validate_refuses_a_truth_file_as_the_calibration(phone, run_magyro, assert_plain_failure):
    d, _ = phone
    done = run_magyro("validate", "s.parquet", "s.truth.json", "-o", "never.json", cwd=d)
    assert "true parameters of a simulated session" in assert_plain_failure(done, 2)
    assert not (d / "never.json").exists()
