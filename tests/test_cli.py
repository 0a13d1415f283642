"""`magyro` on the command line (docs/spec.md sections 3 and 4), run as a subprocess."""
from __future__ import annotations

import dataclasses
import hashlib
import importlib.metadata
import json
import math
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

import magyro
from magyro import so3
from magyro.options import Options
from magyro.front.prepare import prepare
from magyro.errors import InputError
from magyro.io import MAX_PLAUSIBLE_RATE_RAD_S, MIN_SAMPLES, load_session, write_session
from magyro.studies.scenario import load_problem
from magyro.studies.simulate import simulate

SEED = 1


def sha256(path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


def matrix(value, shape=(3, 3)) -> np.ndarray:
    a = np.array(value, dtype=float)
    assert a.shape == shape, (a.shape, shape)
    assert np.all(np.isfinite(a))
    return a


def assert_upper_triangular(M, what):
    scale = np.max(np.abs(M))
    assert np.all(np.abs(np.tril(M, -1)) <= 1e-12 * scale), f"{what} not upper triangular: {M}"
    assert np.all(np.diag(M) > 0), f"{what} diagonal not positive: {np.diag(M)}"


# --------------------------------------------------------------------------- version, simulate, solve


def test_version(run_magyro):
    r = run_magyro("--version")
    assert r.returncode == 0, r.stderr
    assert r.stdout.split() == ["magyro", magyro.__version__]
    assert magyro.__version__ == importlib.metadata.version("magyro")


@pytest.fixture(scope="module")
def sim_dir(tmp_path_factory, run_magyro):
    """`magyro simulate paper-table1 -o X.parquet --seed 1` in a fresh folder."""
    d = tmp_path_factory.mktemp("cli")
    sim = run_magyro("simulate", "paper-table1", "-o", "X.parquet", "--seed", SEED, cwd=d)
    assert sim.returncode == 0, sim.stderr
    return d


@pytest.fixture(scope="module")
def solved_dir(sim_dir, run_magyro):
    """Then `magyro solve X.parquet -o calib.json` (the session file hashed before)."""
    before = sha256(sim_dir / "X.parquet")
    solve = run_magyro("solve", "X.parquet", "-o", "calib.json", cwd=sim_dir)
    return {"dir": sim_dir, "solve": solve, "hash_before": before}


@pytest.mark.parametrize("args, message", [
    (["--history", "h.parquet"], "--history and --history-plot need --method ekf"),
])
def test_options_of_the_other_method_exit_2(args, message, sim_dir, run_magyro, assert_plain_failure):
    r = run_magyro("solve", "X.parquet", "-o", "never.json", *args, cwd=sim_dir)
    assert message in assert_plain_failure(r, 2)
    assert not (sim_dir / "never.json").exists() and not (sim_dir / "h.parquet").exists()


def test_simulate_writes_session_and_truth(sim_dir):
    d = sim_dir
    session, truth = simulate(load_problem("paper-table1"), SEED)
    loaded = load_session(d / "X.parquet")
    np.testing.assert_array_equal(loaded.t_gyro_s, session.t_gyro_s)
    np.testing.assert_array_equal(loaded.gyro_rad_s, session.gyro_rad_s)
    np.testing.assert_array_equal(loaded.mag, session.mag)
    written = json.loads((d / "X.truth.json").read_text())
    assert written["seed"] == SEED and written["problem"] == "paper-table1"
    np.testing.assert_allclose(written["gyro"]["K_g"], truth["gyro"]["K_g"], rtol=0, atol=0)
    np.testing.assert_allclose(written["field_i"], truth["field_i"], rtol=0, atol=0)


@pytest.mark.slow
def test_solve_exit_0_and_input_unchanged(solved_dir):
    r = solved_dir["solve"]
    assert r.returncode == 0, r.stderr
    assert "Traceback" not in r.stderr
    assert sha256(solved_dir["dir"] / "X.parquet") == solved_dir["hash_before"]


@pytest.mark.slow
def test_calibration_file_has_every_spec_key(solved_dir):
    assert solved_dir["solve"].returncode == 0, solved_dir["solve"].stderr
    c = json.loads((solved_dir["dir"] / "calib.json").read_text())
    assert c["schema"] == "magyro.calibration/1"

    K_g = matrix(c["gyro"]["K_g"])
    assert_upper_triangular(K_g, "gyro.K_g")
    bias_rad = matrix(c["gyro"]["bias_rad_s"], (3,))
    bias_deg = matrix(c["gyro"]["bias_deg_s"], (3,))
    np.testing.assert_allclose(bias_deg, np.rad2deg(bias_rad), rtol=1e-12)
    C = matrix(c["misalignment"]["C_b_m"])
    np.testing.assert_allclose(C.T @ C, np.eye(3), atol=1e-12)
    assert np.linalg.det(C) == pytest.approx(1.0, abs=1e-12)
    np.testing.assert_allclose(matrix(c["gyro"]["K"]), C @ K_g, atol=1e-12)
    euler = matrix(c["misalignment"]["euler_deg"], (3,))
    np.testing.assert_allclose(so3.euler_to_dcm(euler), C, atol=1e-12)

    R = matrix(c["magnetometer"]["R"])
    assert_upper_triangular(R, "magnetometer.R")
    matrix(c["magnetometer"]["h"], (3,))
    assert isinstance(c["magnetometer"]["unit"], str) and c["magnetometer"]["unit"] == "unitless"
    assert np.linalg.norm(matrix(c["field_i"], (3,))) == pytest.approx(1.0, abs=1e-9)

    std = c["std"]
    shapes = {"K_g": (3, 3), "bias_deg_s": (3,), "misalignment_deg": (3,), "R": (3, 3), "h": (3,)}
    for key, shape in shapes.items():
        s = matrix(std[key], shape)
        estimated = np.triu(np.ones(shape, dtype=bool)) if len(shape) == 2 else np.ones(shape, dtype=bool)
        assert np.all(s[estimated] > 0), (key, s)          # every estimated entry has an uncertainty ...
        assert np.all(s[~estimated] == 0), (key, s)        # ... and the triangular zeros have none

    ob = c["observability"]
    assert type(ob["rank"]) is int and ob["rank"] == 12
    assert type(ob["condition"]) is float and math.isfinite(ob["condition"]) and ob["condition"] >= 1.0
    sv = c["solver"]
    assert sv["method"] == "nls"
    assert isinstance(sv["status"], str) and sv["status"]
    assert type(sv["iterations"]) is int and sv["iterations"] >= 1
    assert type(sv["seconds"]) is float and sv["seconds"] >= 0


@pytest.mark.slow
def test_calibration_file_recovers_the_truth_file(solved_dir):
    """The numbers in calib.json, not just their shapes: within 4 of their own sigma of X.truth.json."""
    d = solved_dir["dir"]
    c = json.loads((d / "calib.json").read_text())
    truth = json.loads((d / "X.truth.json").read_text())
    iu = np.triu_indices(3)
    z = (np.array(c["gyro"]["K_g"]) - np.array(truth["gyro"]["K_g"]))[iu] / np.array(c["std"]["K_g"])[iu]
    assert np.all(np.abs(z) <= 4), z
    z = (np.array(c["gyro"]["bias_deg_s"]) - np.array(truth["gyro"]["bias_deg_s"])) / np.array(c["std"]["bias_deg_s"])
    assert np.all(np.abs(z) <= 4), z


@pytest.mark.slow
def test_gyro_unit_deg_s_gives_the_same_calibration(solved_dir, run_magyro):
    d = solved_dir["dir"]
    df = pd.read_parquet(d / "X.parquet")
    df[["gx", "gy", "gz"]] = np.rad2deg(df[["gx", "gy", "gz"]].to_numpy())
    df.to_parquet(d / "X_deg.parquet", index=False)
    r = run_magyro("solve", "X_deg.parquet", "--gyro-unit", "deg/s", "-o", "calib_deg.json", cwd=d)
    assert r.returncode == 0, r.stderr
    a = json.loads((d / "calib.json").read_text())
    b = json.loads((d / "calib_deg.json").read_text())
    np.testing.assert_allclose(b["gyro"]["K_g"], a["gyro"]["K_g"], atol=1e-9, rtol=0)
    np.testing.assert_allclose(b["gyro"]["bias_rad_s"], a["gyro"]["bias_rad_s"], atol=1e-9, rtol=0)


# --------------------------------------------------------------------------- unusable input: exit 2


@pytest.fixture(scope="module")
def table(sim_dir) -> pd.DataFrame:
    """The simulated session as a DataFrame (the session table of docs/spec.md), to be spoilt by each case."""
    return pd.read_parquet(sim_dir / "X.parquet")


def drop_column(df):
    return df.drop(columns=["my"])


def time_backwards(df):
    df = df.copy()
    df.loc[500, "t"] = df.loc[498, "t"]
    return df


def time_repeated(df):
    df = df.copy()
    df.loc[500, "t"] = df.loc[499, "t"]
    return df


def nan_in_gyro(df):
    df = df.copy()
    df.loc[700, "gy"] = np.nan
    return df


def nan_in_mag(df):
    df = df.copy()
    df.loc[700, "mz"] = np.nan
    return df


def few_mag_samples(df):
    df = df.copy()
    df.loc[df.index[MIN_SAMPLES // 2:], ["mx", "my", "mz"]] = np.nan
    return df


def deg_s_labelled_rad_s(df):
    df = df.copy()
    df[["gx", "gy", "gz"]] = np.rad2deg(df[["gx", "gy", "gz"]].to_numpy())
    return df


BAD = {
    # case: (spoil, words the message must contain)
    "missing-column": (drop_column, ["my", "missing"]),
    "time-backwards": (time_backwards, ["row 500", "increasing"]),
    "time-repeated": (time_repeated, ["row 500", "time"]),
    "nan-gyro": (nan_in_gyro, ["NaN", "row 700", "gy"]),
    "nan-mag": (nan_in_mag, ["NaN", "row 700", "mz"]),
    "few-mag": (few_mag_samples, ["magnetometer", str(MIN_SAMPLES // 2)]),
    "deg-s-as-rad-s": (deg_s_labelled_rad_s, ["deg/s"]),
}


CASES = [(case, ".csv") for case in BAD] + [("missing-column", ".parquet"), ("nan-mag", ".parquet")]


@pytest.mark.parametrize("case,suffix", CASES)
def test_unusable_input_exit_2(case, suffix, table, tmp_path, run_magyro, assert_plain_failure):
    spoil, words = BAD[case]
    path = tmp_path / f"bad{suffix}"
    df = spoil(table)
    if suffix == ".csv":
        df.to_csv(path, index=False)
    else:
        df.to_parquet(path, index=False)
    before = sha256(path)
    out = tmp_path / "calib.json"
    message = assert_plain_failure(run_magyro("solve", path, "-o", out), 2)
    for w in words:
        assert w in message, (w, message)
    assert not out.exists()
    assert sha256(path) == before


@pytest.mark.parametrize("content", [b"", b"t,gx,gy,gz,mx,my,mz\n"], ids=["zero-bytes", "header-only"])
def test_empty_file_exit_2(content, tmp_path, run_magyro, assert_plain_failure):
    path = tmp_path / "empty.csv"
    path.write_bytes(content)
    out = tmp_path / "calib.json"
    assert_plain_failure(run_magyro("solve", path, "-o", out), 2)
    assert not out.exists()


def test_failed_solve_leaves_an_existing_output_untouched(table, tmp_path, run_magyro, assert_plain_failure):
    path = tmp_path / "bad.csv"
    drop_column(table).to_csv(path, index=False)
    out = tmp_path / "calib.json"
    out.write_text("previous calibration\n")
    assert_plain_failure(run_magyro("solve", path, "-o", out), 2)
    assert out.read_text() == "previous calibration\n"


# ------------------------------------------------------------ deg/s labelled rad/s, below the load-time limit


def slow_paper_problem(stretch: float = 5.0):
    """paper-table1 played `stretch` times slower (same poses, rates / stretch), 50 Hz sensors.

    No shipped problem turns slowly enough that its rates in deg/s stay under the
    load-time limit (40 rad/s): paper-table1 peaks near 2.4 rad/s, x57 = 135. Slowing
    the same motion 5x keeps x57 near 28, so only the physical check can tell.
    """
    p = load_problem("paper-table1")
    m = p.motion
    motion = dataclasses.replace(m, band_hz=(m.band_hz[0] / stretch, m.band_hz[1] / stretch),
                                 ramp_s=m.ramp_s * stretch, rest_start_s=m.rest_start_s * stretch,
                                 rest_end_s=m.rest_end_s * stretch)
    return dataclasses.replace(p, name="paper-table1-slow", duration_s=p.duration_s * stretch,
                               gyro_rate_hz=50.0, mag_rate_hz=50.0, motion=motion)


@pytest.fixture(scope="module")
def slow_sessions():
    session, _ = simulate(slow_paper_problem(), SEED)
    wrong = dataclasses.replace(session, gyro_rad_s=np.rad2deg(session.gyro_rad_s))
    return session, wrong


def test_slow_deg_s_session_passes_the_load_time_limit(slow_sessions):
    _, wrong = slow_sessions
    p999 = np.percentile(np.linalg.norm(wrong.gyro_rad_s, axis=1), 99.9)
    assert 5.0 < p999 < MAX_PLAUSIBLE_RATE_RAD_S


def test_physical_unit_check_passes_the_right_unit(slow_sessions):
    right, _ = slow_sessions
    assert prepare(right, Options()).analysis.rank == 12


def test_physical_unit_check_catches_deg_s_labelled_rad_s(slow_sessions):
    _, wrong = slow_sessions
    with pytest.raises(InputError, match="deg/s"):
        prepare(wrong, Options())


def test_cli_catches_slow_deg_s_labelled_rad_s(slow_sessions, tmp_path, run_magyro, assert_plain_failure):
    _, wrong = slow_sessions
    path = tmp_path / "slow_deg.parquet"
    write_session(wrong, path)  # labelled rad/s in the file's metadata
    out = tmp_path / "calib.json"
    message = assert_plain_failure(run_magyro("solve", path, "-o", out), 2)
    assert "--gyro-unit deg/s" in message
    assert not out.exists()


# --------------------------------------------------------------------------- not an ellipsoid


def test_random_magnetometer_points_are_refused_plainly(table, tmp_path, run_magyro, assert_plain_failure):
    """mx my mz replaced by uniform noise in a +/-50 cube: no field at all.

    The gyro turned hundreds of degrees, so this is unusable input (2), not a motion problem.
    """
    df = table.copy()
    rows = df["mx"].notna()
    df.loc[rows, ["mx", "my", "mz"]] = np.random.default_rng(0).uniform(-50, 50, (int(rows.sum()), 3))
    path = tmp_path / "cube.parquet"
    df.to_parquet(path, index=False)
    out = tmp_path / "calib.json"
    message = assert_plain_failure(run_magyro("solve", path, "-o", out), 2)
    assert "do not follow" in message and "magnetometer" in message
    assert not out.exists()


# --------------------------------------------------------------------------- commands that read alike (issue 24)


def _help(*args) -> str:
    from typer.testing import CliRunner

    from magyro.cli import app

    result = CliRunner().invoke(app, [*args, "--help"], env={"COLUMNS": "250"}, prog_name="magyro")
    assert result.exit_code == 0, result.output
    return result.output


def _commands():
    import typer.main

    from magyro.cli import app

    return typer.main.get_command(app).commands


def test_help_renders_the_extras_in_brackets():
    """Each extra in brackets as written (rich took [plot] for markup), matplotlib's named from a clone too."""
    plot = "pip install '.[plot]' in a clone, 'magyro[plot]' from PyPI"
    assert plot in " ".join(_help("report").split())
    assert "Needs magyro[dask]" in _help("batch") and plot in " ".join(_help("batch").split())
    assert plot in " ".join(_help("solve").split())


def test_usage_lines_name_the_arguments_as_the_help_does():
    assert "Usage: magyro apply [OPTIONS] SESSION CALIB" in _help("apply")
    for name, command in _commands().items():
        for args in ([name, sub] for sub in command.commands) if hasattr(command, "commands") else [[name]]:
            usage = next(line for line in _help(*args).splitlines() if "Usage:" in line)
            assert "{" not in usage and "}" not in usage, usage


def test_the_summaries_list_every_subcommand_and_format():
    from magyro.result.export import FORMATS

    commands = _commands()
    summary_of = {name: command.help.split("\n\n")[0] for name, command in commands.items()}
    assert all(f"({sub})" in summary_of["import"] for sub in commands["import"].commands), summary_of["import"]
    assert all(f"({fmt})" in summary_of["export"] for fmt in FORMATS), summary_of["export"]
    top = " ".join(_help().split())
    assert "ROS bags (rosbag)" in top and "PX4 .params file (px4)" in top


def test_session_comes_before_the_calibration_everywhere():
    commands = _commands()
    for name in ("apply", "validate", "report"):
        arguments = [p.name for p in commands[name].params if p.param_type_name == "argument"]
        assert arguments == ["session", "calibration"], (name, arguments)


def test_no_repair_help_names_every_repair():
    from magyro.options import Repairs

    for name in ("solve", "observe", "check", "batch"):
        text = " ".join(_help(name).split())
        assert all(f"{repair}," in text for repair in Repairs.NAMES), (name, text)


@pytest.fixture(scope="module")
def spiked_clipped(tmp_path_factory):
    import degrade as D

    path = tmp_path_factory.mktemp("reads_alike") / "spiked.parquet"
    write_session(D.mag_spikes(D.clip_gyro(D.load("broad-02"), 250.0)), path)
    return path


def _fixes(run_magyro, session, *flags) -> dict:
    out = session.with_name(f"check{len(flags)}.json")
    result = run_magyro("check", session, "-q", "-o", out, *flags)
    assert result.returncode == 0, result.stderr
    return {(f["kind"], f["sensor"]): f["fix"] for f in json.loads(out.read_text())["findings"]}


def test_fix_lines_name_the_flag_and_tell_the_truth_under_no_repair(spiked_clipped, run_magyro):
    on = _fixes(run_magyro, spiked_clipped)
    off = _fixes(run_magyro, spiked_clipped, "--no-repair", "spikes", "--no-repair", "saturation")
    assert on[("spikes", "magnetometer")].startswith("magyro drops them (--no-repair spikes keeps the spikes)")
    assert "magyro cuts" in on[("saturation", "gyro")] and "--no-repair saturation" in on[("saturation", "gyro")]
    assert all("Repairs(" not in fix for fix in [*on.values(), *off.values()])
    for kind, sensor in (("spikes", "magnetometer"), ("saturation", "gyro")):
        fix = off[(kind, sensor)]
        assert fix.startswith(f"not repaired (--no-repair {kind}):") and "magyro" not in fix, fix
    assert off[("held", "magnetometer")] == on[("held", "magnetometer")]   # a repair left on says the same


@pytest.mark.parametrize("text, deg_s", [("0.0002rad/s/sqrt(Hz)", math.degrees(2e-4)), ("0.0002 rad/s/√Hz", math.degrees(2e-4)),
                                         ("0.02", 0.02), ("0.02deg/s/sqrt(Hz)", 0.02), ("5 mdps/sqrt(Hz)", 0.005),
                                         ("0.6deg/sqrt(h)", 0.01)])
def test_gyro_noise_takes_its_unit(text, deg_s):
    from magyro.cli.common import gyro_noise_density

    assert gyro_noise_density(text) == pytest.approx(deg_s, rel=1e-12)


def test_gyro_noise_in_rad_s_gives_the_same_result_as_in_deg_s(tmp_path, run_magyro, assert_plain_failure):
    session = Path(__file__).resolve().parents[1] / "data" / "broad-02.parquet"   # the repository's, not the install's
    reports = []
    for value in ("0.0002rad/s/sqrt(Hz)", repr(math.degrees(2e-4))):
        out = tmp_path / f"{len(reports)}.json"
        assert run_magyro("observe", session, "-q", "--gyro-noise", value, "-o", out).returncode == 0
        reports.append(json.loads(out.read_text(), object_hook=lambda d: {k: v for k, v in d.items() if k != "seconds"}))
    assert reports[0] == reports[1]
    assert "not a noise density" in run_magyro("observe", session, "--gyro-noise", "2furlongs").stderr
    assert "must be a positive number" in assert_plain_failure(run_magyro("observe", session, "--gyro-noise", "-1"), 2)
