"""Every example in examples/ runs as a test, as a user would run it (a fresh process, another folder)."""
from __future__ import annotations

import re
import subprocess
import sys
from pathlib import Path

import pytest

EXAMPLES = Path(__file__).resolve().parent.parent / "examples"


def run_example(name: str, cwd: Path, *args) -> str:
    done = subprocess.run([sys.executable, str(EXAMPLES / name), *map(str, args)], cwd=cwd, capture_output=True,
                          text=True, timeout=600)
    assert done.returncode == 0, done.stderr
    return done.stdout


def test_every_example_has_a_test():
    tested = set(re.findall(r'run_example\("(\w+\.py)"', Path(__file__).read_text()))
    assert {p.name for p in EXAMPLES.glob("*.py")} == tested


@pytest.mark.slow
def test_calibrate_a_recording(tmp_path):
    out = run_example("calibrate_a_recording.py", tmp_path)
    assert (tmp_path / "calib.json").exists()
    norm, spread = (float(x) for x in re.search(r"field norm ([\d.]+) \+/- ([\d.]+)", out).groups())
    assert abs(norm - 1.0) < 0.01 and spread < 0.05, out


def test_is_my_motion_enough(tmp_path):
    out = run_example("is_my_motion_enough.py", tmp_path)
    ranks = [int(r) for r in re.findall(r"rank +(\d+) of 12", out)]
    assert ranks == [6, 9, 12], out
    assert "insufficient" in out.splitlines()[0] and "sufficient" in out.splitlines()[2]


@pytest.mark.slow
def test_two_methods(tmp_path):
    out = run_example("two_methods.py", tmp_path)
    ratios = [float(r) for r in re.findall(r"\|error\|/std max ([\d.]+)", out)]
    assert len(ratios) == 2 and max(ratios) < 4.0, out


@pytest.mark.slow
def test_dead_reckoning(tmp_path):
    out = run_example("dead_reckoning.py", tmp_path)
    raw, calibrated = (float(re.search(rf"{name} gyro +([\d.]+)", out).group(1)) for name in ("raw", "calibrated"))
    assert calibrated < 0.2 * raw, out


def test_calibrate_a_fleet(tmp_path):
    out = run_example("calibrate_a_fleet.py", tmp_path, tmp_path / "fleet")
    counts = re.search(r"4 devices: (\d+) accepted, (\d+) rejected, (\d+) failed", out)
    assert counts and int(counts.group(3)) == 0, out
    assert int(counts.group(1)) + int(counts.group(2)) == 4
    rejected = [line for line in out.splitlines() if ": rejected: " in line]
    assert len(rejected) == int(counts.group(2)) and all("deg/s" in line for line in rejected), out
    assert (tmp_path / "fleet" / "batch" / "summary.html").exists()
