"""Input safety everywhere (issue 11): outputs that would destroy an input or cannot be written,
time stamps that are not in seconds, and gyro units wrong either way.

Each refusal is exit 2 with one plain message naming the real cause. Output problems are
found before any work: the command returns at once, no output and no temp file appears,
and the input's bytes are unchanged. The unit checks are tested on the shipped real trials
degraded both ways, through the Python API and the command line.
"""
from __future__ import annotations

import dataclasses
import errno
import hashlib
import os
import shutil
import tempfile
from pathlib import Path

import numpy as np
import pytest

import magyro
from magyro.api import solve_file
from magyro.errors import InputError
from magyro.front import ellipsoid
from magyro.front.prepare import check_gyro_unit, moving_session, prepare
from magyro.io import atomic, check_outputs, load_session, write_session, write_text_atomically
from magyro.options import Options
from magyro.studies.scenario import load_problem
from magyro.studies.simulate import simulate

DATA = Path(__file__).resolve().parents[1] / "data"
BROAD_02 = DATA / "broad-02.parquet"
BROAD_07 = DATA / "broad-07.parquet"
PROBLEMS = Path(__file__).resolve().parents[1] / "problems"
DEG_PER_RAD = 57.2958


def sha256(path: Path) -> str:
    return hashlib.sha256(Path(path).read_bytes()).hexdigest()


def listing(folder: Path) -> list[str]:
    return sorted(str(p.relative_to(folder)) for p in folder.rglob("*"))


# --------------------------------------------------------------------------- outputs, from the command line


@pytest.fixture
def work(tmp_path):
    """A folder with a real session, a calibration, a problem file, a CSV export and a BROAD-like .mat."""
    import scipy.io

    shutil.copy(BROAD_02, tmp_path / "in.parquet")
    (tmp_path / "calib.json").write_text('{"schema": "magyro.calibration/1"}\n')
    shutil.copy(PROBLEMS / "short-30s.toml", tmp_path / "p.toml")
    shutil.copy(PROBLEMS / "short-30s.toml", tmp_path / "s.truth.json")  # a problem file that simulate's truth would hit
    (tmp_path / "src.csv").write_text("t,gx,gy,gz,mx,my,mz\n0,0,0,0,1,0,0\n")
    t = np.arange(300) / 100.0
    scipy.io.savemat(tmp_path / "trial.mat", {"imu_gyr": np.zeros((300, 3)), "imu_mag": np.c_[np.cos(t), np.sin(t), 0 * t],
                                              "sampling_rate": np.array([[100.0]])})
    (tmp_path / "existing_dir").mkdir()
    return tmp_path


INPUT_IS_OUTPUT = [  # (command line, the input named, the output named)
    (["solve", "in.parquet", "-o", "in.parquet"], "in.parquet", "in.parquet"),
    (["solve", "in.parquet", "-o", "./existing_dir/../in.parquet"], "in.parquet", "existing_dir/../in.parquet"),
    (["solve", "in.parquet", "-o", "link.parquet"], "in.parquet", "link.parquet"),      # a symlink to the input
    (["solve", "in.parquet", "-o", "hard.parquet"], "in.parquet", "hard.parquet"),      # a hard link to it
    (["solve", "in.parquet", "--method", "ekf", "--history", "in.parquet"], "in.parquet", "in.parquet"),
    (["solve", "in.parquet", "--method", "ekf", "--history-plot", "in.parquet"], "in.parquet", "in.parquet"),
    (["observe", "in.parquet", "-o", "in.parquet"], "in.parquet", "in.parquet"),
    (["observe", "in.parquet", "--plot", "in.parquet"], "in.parquet", "in.parquet"),
    (["validate", "in.parquet", "calib.json", "-o", "calib.json"], "calib.json", "calib.json"),
    (["validate", "in.parquet", "calib.json", "--plot", "in.parquet"], "in.parquet", "in.parquet"),
    (["simulate", "p.toml", "-o", "p.toml"], "p.toml", "p.toml"),
    (["simulate", "s.truth.json", "-o", "s.parquet"], "s.truth.json", "s.truth.json"),  # its truth file
    (["montecarlo", "p.toml", "--runs", "2", "-o", "p.toml"], "p.toml", "p.toml"),
    (["montecarlo", "p.toml", "--runs", "2", "--csv", "p.toml"], "p.toml", "p.toml"),
    (["import", "broad", "trial.mat", "-o", "trial.mat"], "trial.mat", "trial.mat"),
    (["import", "csv", "src.csv", "-o", "src.csv", "--gyro-unit", "rad/s", "--mag-unit", "uT"], "src.csv", "src.csv"),
]


def run_refused(run_magyro, assert_plain_failure, folder: Path, args) -> str:
    """Run a command that must be refused before any work; return its message."""
    hashes = {p.name: sha256(p) for p in folder.iterdir() if p.is_file()}
    before = listing(folder)
    r = run_magyro(*args, cwd=folder, env={"MAGYRO_PROGRESS": "lines"})   # every step of work a stderr line
    message = assert_plain_failure(r, 2)    # one line: the refusal, and no step of work before it
    assert listing(folder) == before, "an output or temp file appeared"
    assert {p.name: sha256(p) for p in folder.iterdir() if p.is_file()} == hashes, "an input changed"
    return message


@pytest.mark.parametrize("args, inp, out", INPUT_IS_OUTPUT, ids=lambda v: " ".join(v) if isinstance(v, list) else None)
def test_an_output_that_is_an_input_is_refused_before_any_work(args, inp, out, work, run_magyro, assert_plain_failure):
    (work / "link.parquet").symlink_to(work / "in.parquet")
    os.link(work / "in.parquet", work / "hard.parquet")
    message = run_refused(run_magyro, assert_plain_failure, work, args)
    assert f"the output {out} is the input {inp}" in message, message
    assert "same file" in message and "choose another output path" in message


@pytest.mark.parametrize("args", [
    ["solve", "in.parquet", "--method", "ekf", "--history", "h.parquet", "--history-plot", "h.parquet"],
    ["solve", "in.parquet", "--method", "ekf", "-o", "x.json", "--history-plot", "./x.json"],
    ["observe", "in.parquet", "-o", "r.json", "--plot", "r.json"],
    ["validate", "in.parquet", "calib.json", "-o", "r.json", "--plot", "r.json"],
    ["montecarlo", "p.toml", "--runs", "2", "-o", "r.json", "--csv", "r.json"],
], ids=lambda v: " ".join(v))
def test_two_outputs_that_are_one_file_are_refused(args, work, run_magyro, assert_plain_failure):
    message = run_refused(run_magyro, assert_plain_failure, work, args)
    assert "two outputs are the same file" in message, message


def unwritable_folder(tmp_path: Path) -> Path:
    """A folder this process cannot create files in (a read-only folder; /sys for root)."""
    if os.geteuid() != 0:
        folder = tmp_path / "read_only"
        folder.mkdir()
        folder.chmod(0o500)
        return folder
    try:
        with tempfile.NamedTemporaryFile(dir="/sys"):
            pass
    except OSError:
        return Path("/sys")
    pytest.skip("no folder here refuses files to root")


OUTPUT_OPTIONS = [  # a command and its output option; the output path is appended
    ["solve", "in.parquet", "-o"],
    ["solve", "in.parquet", "--method", "ekf", "--history"],
    ["solve", "in.parquet", "--method", "ekf", "--history-plot"],
    ["observe", "in.parquet", "-o"],
    ["observe", "in.parquet", "--plot"],
    ["validate", "in.parquet", "calib.json", "-o"],
    ["validate", "in.parquet", "calib.json", "--plot"],
    ["simulate", "p.toml", "-o"],
    ["montecarlo", "p.toml", "--runs", "2", "-o"],
    ["montecarlo", "p.toml", "--runs", "2", "--csv"],
    ["import", "broad", "trial.mat", "-o"],
    ["import", "csv", "src.csv", "--gyro-unit", "rad/s", "--mag-unit", "uT", "-o"],
]


@pytest.mark.parametrize("args", OUTPUT_OPTIONS, ids=lambda v: " ".join(v))
def test_an_output_in_a_missing_folder_is_refused_before_any_work(args, work, run_magyro, assert_plain_failure):
    message = run_refused(run_magyro, assert_plain_failure, work, [*args, "no/such/dir/out.json"])
    assert "cannot write the output no/such/dir/out.json" in message, message
    assert "its folder no/such/dir does not exist" in message
    assert ".tmp" not in message


@pytest.mark.parametrize("args", [OUTPUT_OPTIONS[0], OUTPUT_OPTIONS[4], OUTPUT_OPTIONS[7], OUTPUT_OPTIONS[11]],
                         ids=lambda v: " ".join(v))
def test_an_output_that_is_a_folder_is_refused_before_any_work(args, work, run_magyro, assert_plain_failure):
    message = run_refused(run_magyro, assert_plain_failure, work, [*args, "existing_dir"])
    assert "cannot write the output existing_dir: it is a folder" in message, message


@pytest.mark.parametrize("args", [OUTPUT_OPTIONS[0], OUTPUT_OPTIONS[5], OUTPUT_OPTIONS[9], OUTPUT_OPTIONS[10]],
                         ids=lambda v: " ".join(v))
def test_an_output_in_an_unwritable_folder_is_refused_before_any_work(args, work, run_magyro, assert_plain_failure):
    folder = unwritable_folder(work)
    target = folder / "magyro-test-out.json"
    try:
        message = run_refused(run_magyro, assert_plain_failure, work, [*args, target])
    finally:
        if folder.parent == work:
            folder.chmod(0o700)
    assert f"cannot write the output {target}" in message, message
    assert "not writable" in message or "no file can be created" in message
    assert not target.exists()


def test_the_solve_still_writes_a_good_output(work, run_magyro):
    """The checks refuse only what they should: a plain solve to a new file is written as before."""
    r = run_magyro("solve", "in.parquet", "-o", "calib_out.json", "-q", cwd=work)
    assert r.returncode == 0, r.stderr
    assert magyro.Calibration.from_json(work / "calib_out.json").K_g.shape == (3, 3)


# --------------------------------------------------------------------------- outputs, in Python


def test_check_outputs_in_python(tmp_path, monkeypatch):
    src = tmp_path / "in.parquet"
    shutil.copy(BROAD_02, src)
    check_outputs([src, None, magyro.Options()], [tmp_path / "a.json", None, tmp_path / "b.png"])  # all fine
    check_outputs(["paper-table1"], [tmp_path / "paper-table1"])  # a problem's name is not a file
    with pytest.raises(InputError, match="is the input"):
        check_outputs([src], [tmp_path / "x" / ".." / "in.parquet"])
    with pytest.raises(InputError, match="two outputs are the same file"):
        check_outputs([src], [tmp_path / "a.json", tmp_path / "." / "a.json"])
    with pytest.raises(InputError, match="is the input"):  # the Python job refuses too, before loading
        solve_file(src, output=src)
    monkeypatch.setattr(atomic.os, "access", lambda *a, **k: False)
    with pytest.raises(InputError, match=r"its folder .* is not writable \(no permission\)"):
        check_outputs([src], [tmp_path / "c.json"])
    assert sorted(p.name for p in tmp_path.iterdir()) == ["in.parquet"]


def test_a_write_that_fails_late_names_the_output_not_the_temp_file(tmp_path, monkeypatch):
    target = tmp_path / "calib.json"
    target.write_text("previous\n")

    def disk_full(tmp):
        with open(tmp, "w") as f:
            f.write("half")
        raise OSError(errno.ENOSPC, "No space left on device", tmp)

    with pytest.raises(OSError) as info:
        atomic.write_atomically(target, disk_full)
    assert info.value.errno == errno.ENOSPC and info.value.filename == str(target)
    assert str(target) in str(info.value) and ".tmp" not in str(info.value)

    def arrow_like(tmp):  # an OSError without errno, its text naming the temp file
        raise OSError(f"IOError: cannot write to '{tmp}'")

    with pytest.raises(OSError) as info:
        atomic.write_atomically(target, arrow_like)
    assert str(target) in str(info.value) and ".tmp" not in str(info.value)
    with pytest.raises(OSError) as info:
        write_text_atomically(tmp_path / "missing" / "r.json", "x")
    assert info.value.filename == str(tmp_path / "missing" / "r.json")
    assert target.read_text() == "previous\n"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["calib.json"]


# --------------------------------------------------------------------------- time stamps not in seconds


@pytest.fixture(scope="module")
def broad02():
    return load_session(BROAD_02)


def with_time_scaled(session, factor: float):
    return dataclasses.replace(session, t_gyro_s=session.t_gyro_s * factor, t_mag_s=session.t_mag_s * factor,
                               t_acc_s=None, acc_m_s2=None, t_quat_s=None, quat_wxyz=None)


@pytest.mark.parametrize("factor, unit, name", [(1e3, "ms", "milliseconds"), (1e6, "us", "microseconds"),
                                                (1e9, "ns", "nanoseconds")])
def test_time_in_ms_us_ns_is_named_as_such(factor, unit, name, broad02, tmp_path):
    wrong = with_time_scaled(broad02, factor)
    path = tmp_path / f"t_{unit}.parquet"
    write_session(wrong, path)
    with pytest.raises(InputError) as info:
        load_session(path)
    message = str(info.value)
    assert f"the time column looks like {name} (median step " in message, message
    assert f"= 285.7 Hz if {unit}); convert it to seconds, or import with `magyro import csv --time-unit {unit}`" in message
    assert "gyro unit" not in message and "deg/s" not in message
    with pytest.raises(InputError, match=f"looks like {name}"):  # a Session made in Python: named before the unit check
        magyro.calibrate(wrong)


@pytest.mark.parametrize("factor, unit, step", [(1e3, "ms", "3.5 'seconds'"), (1e9, "ns", "3.5e+06 'seconds'")])
def test_cli_time_in_ms_or_ns_names_the_time_column(factor, unit, step, broad02, tmp_path, run_magyro,
                                                    assert_plain_failure):
    path = tmp_path / "t.parquet"
    write_session(with_time_scaled(broad02, factor), path)
    out = tmp_path / "calib.json"
    message = assert_plain_failure(run_magyro("solve", path, "-o", out), 2)
    assert f"median step {step} = 285.7 Hz if {unit}" in message and f"--time-unit {unit}" in message, message
    assert "gyro" not in message.split("median step")[0] and "deg/s" not in message
    assert not out.exists()


def test_seconds_are_left_alone(broad02):
    from magyro.io.checks import check_time_unit
    check_time_unit(broad02.t_gyro_s)
    check_time_unit(np.arange(200) * 1e-4)  # 10 kHz
    check_time_unit(np.arange(200) * 0.5)   # 2 Hz: slow, but seconds
    with pytest.raises(InputError, match="cannot be right"):
        check_time_unit(np.arange(200) * 1e-12)


# --------------------------------------------------------------------------- gyro unit, both ways


def unit_error(session) -> str | None:
    """The gyro-unit message prepare() gives for `session`, or None when it names another cause or none."""
    try:
        prepare(session, Options())
    except magyro.MagyroError as exc:
        return str(exc) if "labelled" in str(exc) else None
    return None


def scaled_gyro(session, factor: float):
    return dataclasses.replace(session, gyro_rad_s=session.gyro_rad_s * factor)


def test_rad_s_labelled_deg_s_is_caught_on_the_real_trial(broad02):
    with pytest.raises(InputError) as info:
        magyro.calibrate(scaled_gyro(broad02, 1 / DEG_PER_RAD))
    message = str(info.value)
    assert "slower than the magnetometer sees the field turn" in message, message
    assert "rad/s labelled deg/s; pass --gyro-unit rad/s" in message


def test_deg_s_labelled_rad_s_is_caught_on_the_real_trial(broad02):
    with pytest.raises(InputError) as info:
        magyro.calibrate(scaled_gyro(broad02, DEG_PER_RAD))
    message = str(info.value)
    assert "faster than the magnetometer sees the field turn" in message, message
    assert "deg/s labelled rad/s; pass --gyro-unit deg/s" in message


def test_cli_rad_s_data_passed_as_deg_s(tmp_path, run_magyro, assert_plain_failure):
    out = tmp_path / "calib.json"
    message = assert_plain_failure(run_magyro("solve", BROAD_02, "--gyro-unit", "deg/s", "-o", out), 2)
    assert "rad/s labelled deg/s" in message and "pass --gyro-unit rad/s" in message, message
    assert not out.exists()


def test_cli_deg_s_data_passed_as_rad_s(broad02, tmp_path, run_magyro, assert_plain_failure):
    path = tmp_path / "deg.parquet"
    write_session(scaled_gyro(broad02, DEG_PER_RAD), path)  # the numbers in deg/s, the metadata says rad/s
    out = tmp_path / "calib.json"
    message = assert_plain_failure(run_magyro("solve", path, "--gyro-unit", "rad/s", "-o", out), 2)
    assert "deg/s" in message and "pass --gyro-unit deg/s" in message, message
    assert not out.exists()


def phone_motion(amplitude_deg: float, band_hz=(0.03, 0.3), duration_s: float | None = None):
    p = load_problem("phone-module")
    motion = dataclasses.replace(p.motion, amplitude_deg=np.full(3, float(amplitude_deg)), band_hz=band_hz)
    return dataclasses.replace(p, motion=motion, duration_s=duration_s or p.duration_s)


def with_noisy_rest(session, rest_s: float = 600.0, noise: float = 0.02, seed: int = 0):
    """`rest_s` of rest put in the middle of the recording, and magnetometer noise `noise` x the field added."""
    rng = np.random.default_rng(seed)
    tg, g, tm, m = session.t_gyro_s, session.gyro_rad_s, session.t_mag_s, session.mag
    ig, im = len(tg) // 2, np.searchsorted(tm, tg[len(tg) // 2])
    dtg, dtm = np.median(np.diff(tg)), np.median(np.diff(tm))
    ng, nm = int(rest_s / dtg), int(rest_s / dtm)
    tg2 = np.concatenate([tg[:ig], tg[ig - 1] + dtg * np.arange(1, ng + 1), tg[ig:] + rest_s])
    g2 = np.concatenate([g[:ig], g[:50].mean(axis=0) + rng.normal(0, 0.003, (ng, 3)), g[ig:]])
    tm2 = np.concatenate([tm[:im], tm[im - 1] + dtm * np.arange(1, nm + 1), tm[im:] + rest_s])
    m2 = np.concatenate([m[:im], np.repeat(m[im - 1:im], nm, axis=0), m[im:]])
    m2 = m2 + rng.normal(0, noise * np.mean(np.linalg.norm(m - m.mean(axis=0), axis=1)), m2.shape)
    return dataclasses.replace(session, t_gyro_s=tg2, gyro_rad_s=g2, t_mag_s=tm2, mag=m2, t_acc_s=None, acc_m_s2=None,
                               t_quat_s=None, quat_wxyz=None)


@pytest.fixture(scope="module")
def sessions(broad02):
    """Real and simulated sessions in their right unit, including the hard cases for the thresholds."""
    phone = simulate(load_problem("phone-module"), 0)[0]
    return {
        "broad-02": broad02,
        "broad-07": load_session(BROAD_07),
        "paper-table1": simulate(load_problem("paper-table1"), 0)[0],
        "phone-module": phone,
        "shipped simulated": load_session(DATA / "simulated-phone-module.parquet"),
        "two-axes": simulate(load_problem("two-axes"), 0)[0],
        "shaking 1-4 Hz": simulate(phone_motion(90, band_hz=(1.0, 4.0)), 0)[0],
        "10 min of noisy rest": with_noisy_rest(phone),
    }


def test_right_units_never_look_wrong_and_both_mistakes_are_caught(sessions):
    for name, session in sessions.items():
        assert unit_error(session) is None, name
        slow = unit_error(scaled_gyro(session, 1 / DEG_PER_RAD))
        assert slow is not None and "pass --gyro-unit rad/s" in slow, (name, slow)
        fast = unit_error(scaled_gyro(session, DEG_PER_RAD))
        assert fast is not None and "pass --gyro-unit deg/s" in fast, (name, fast)


def test_the_thresholds_leave_a_wide_margin_on_real_data(broad02):
    """The ratio the slow check compares (gyro angle / field path) against its bound 0.25, read off the message."""
    import re

    from magyro.front import prepare as prep

    for path in (BROAD_02, BROAD_07):
        session = load_session(path)
        moving, levels, _ = moving_session(session, Options())
        field = ellipsoid.calibrated_field(*_fit(moving, levels))
        check_gyro_unit(moving, field)  # passes
        with pytest.raises(InputError) as info:
            check_gyro_unit(scaled_gyro(moving, 1 / DEG_PER_RAD), field)
        turned, seen = map(float, re.search(r"\(the gyro (\d+) deg, the field (\d+) deg\)", str(info.value)).groups())
        assert turned / seen < prep.MAX_SLOW_RATE_RATIO / 3, (path.name, turned, seen)
        assert turned * DEG_PER_RAD / seen > prep.MAX_SLOW_RATE_RATIO * 3, (path.name, turned, seen)


def _fit(session, levels):
    fit = ellipsoid.fit_ellipsoid(session.mag, levels.mag_sample_std)
    return fit.R, fit.h, session.mag


@pytest.mark.parametrize("amplitude_deg", [5, 10, 20])
@pytest.mark.parametrize("factor", [1.0, 1 / DEG_PER_RAD], ids=["right unit", "rad/s labelled deg/s"])
def test_a_device_that_barely_turns_is_not_a_unit_error(amplitude_deg, factor):
    """Shaking within +/-20 deg: too little motion (the gate's or the ellipsoid's verdict), never a unit."""
    session = scaled_gyro(simulate(phone_motion(amplitude_deg), 0)[0], factor)
    with pytest.raises(magyro.MagyroError) as info:
        prepare(session, Options())
    assert "labelled" not in str(info.value) and "--gyro-unit" not in str(info.value), str(info.value)
