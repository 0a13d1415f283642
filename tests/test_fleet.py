"""A fleet of simulated devices: --seeds, the [spread] section, device_scenario, simulate_fleet, the CLI."""
from __future__ import annotations

import csv
import dataclasses
import json
import math

import numpy as np
import pytest
from typer.testing import CliRunner

import magyro
from magyro.cli import app
from magyro.errors import InputError
from magyro.io import load_session
from magyro.studies.fleet import MAX_SEEDS, device_scenario, parse_seeds, simulate_fleet
from magyro.studies.scenario import PROBLEMS_DIR, Spread, load_problem, parse_problem
from magyro.studies.simulate import simulate

try:  # Python >= 3.11
    import tomllib
except ModuleNotFoundError:  # pragma: no cover - Python 3.10
    import tomli as tomllib  # type: ignore[no-redef]


# --------------------------------------------------------------------------- --seeds


@pytest.mark.parametrize("text,seeds", [
    ("3", [3]), ("0", [0]), ("0-4", [0, 1, 2, 3, 4]), ("7-7", [7]), ("1,5,9", [1, 5, 9]),
    (" 1, 5-7 ,20", [1, 5, 6, 7, 20]), ("0-199", list(range(200))),
])
def test_parse_seeds(text, seeds):
    assert parse_seeds(text) == seeds


def test_parse_seeds_up_to_the_limit():
    assert len(parse_seeds(f"0-{MAX_SEEDS - 1}")) == MAX_SEEDS


@pytest.mark.parametrize("text,says", [
    ("", "empty"), ("  ", "empty"), ("a", "'a' is not a non-negative integer"), ("1.5", "'1.5'"),
    ("-3", "non-negative"), ("3--5", "non-negative"), ("5-2", "range 5-2 is empty"), ("1,,2", "''"),
    ("1-", "''"), ("1,1", "seed 1 is given twice"), ("0-5,3", "seed 3 is given twice"),
    (f"0-{MAX_SEEDS}", f"more than {MAX_SEEDS}"), ("0-99999999999999", f"more than {MAX_SEEDS}"),
])
def test_parse_seeds_refuses(text, says):
    with pytest.raises(InputError, match="--seeds") as err:
        parse_seeds(text)
    assert says in str(err.value)


# --------------------------------------------------------------------------- [spread] in problem files


def _raw(name="production-line"):
    return tomllib.loads((PROBLEMS_DIR / f"{name}.toml").read_text())


def test_spread_is_parsed_and_defaults_to_none():
    assert load_problem("paper-table1").spread == Spread() and Spread().is_zero
    s = load_problem("production-line").spread
    assert (s.scale_ppm, s.nonorthogonality_deg, s.bias_deg_s, s.misalignment_deg, s.soft_iron, s.hard_iron) == (
        5000.0, 0.3, 0.3, 1.0, 0.01, 10.0)
    raw = _raw("paper-table1")
    raw["spread"] = {"bias_deg_s": 0.5}
    assert parse_problem(raw).spread == Spread(bias_deg_s=0.5)


@pytest.mark.parametrize("key,value,says", [
    ("bias_deg_s", -0.1, "[spread]: bias_deg_s must be non-negative"),
    ("hard_iron", "big", "[spread]: hard_iron must be a finite number"),
    ("time_offset_s", math.inf, "[spread]: time_offset_s must be a finite number"),
    ("scale_ppm", 200000.0, "[spread]: scale_ppm must be at most 100000"),
    ("soft_iron", 0.5, "[spread]: soft_iron must be at most 0.1"),
    ("bias", 0.1, "[spread]: unknown key(s) ['bias']"),
])
def test_spread_checks_name_the_key(key, value, says):
    raw = _raw()
    raw["spread"][key] = value
    with pytest.raises(InputError) as err:
        parse_problem(raw)
    assert says in str(err.value)


def test_spread_must_be_a_table():
    raw = _raw()
    raw["spread"] = 3
    with pytest.raises(InputError, match=r"\[spread\] must be a table"):
        parse_problem(raw)


# --------------------------------------------------------------------------- the draw


def test_no_spread_device_is_the_problem_and_its_session_is_simulate():
    p = load_problem("short-30s")
    assert device_scenario(p, 5) is p
    zero = parse_problem({**_raw("short-30s"), "spread": {k: 0.0 for k in Spread().to_dict()}})
    assert device_scenario(zero, 5) is zero
    a, ta = simulate(p, 5)
    b, tb = simulate(device_scenario(p, 5), 5)
    np.testing.assert_array_equal(a.gyro_rad_s, b.gyro_rad_s)
    np.testing.assert_array_equal(a.mag, b.mag)
    assert ta == tb


def test_fleet_without_spread_writes_exactly_simulate(tmp_path):
    p = load_problem("short-30s")
    paths = simulate_fleet(p, [2, 9], tmp_path)
    for seed, path in zip([2, 9], paths):
        session, truth = simulate(p, seed)
        loaded = load_session(path)
        np.testing.assert_array_equal(loaded.gyro_rad_s, session.gyro_rad_s)
        np.testing.assert_array_equal(loaded.mag, session.mag)
        written = json.loads(path.with_name(path.stem + ".truth.json").read_text())
        assert written["gyro"] == truth["gyro"] and written["magnetometer"] == truth["magnetometer"]


def test_devices_differ_and_repeat():
    p = load_problem("production-line")
    a, b, a2 = device_scenario(p, 0), device_scenario(p, 1), device_scenario(p, 0)
    assert not np.array_equal(a.K_g, b.K_g)
    np.testing.assert_array_equal(a.K_g, a2.K_g)
    np.testing.assert_array_equal(a.hard_iron, a2.hard_iron)
    assert a.spread.is_zero and a.motion is p.motion
    for d in (a, b):
        for M in (d.K_g, d.soft_iron):
            assert np.all(np.tril(M, -1) == 0.0) and np.all(np.diag(M) > 0.0)


def test_each_spread_key_draws_its_stated_std():
    """4000 devices: every drawn entry has mean = the file's value and std = the stated spread, within 4.5
    sampling sigma; the entries are uncorrelated."""
    spread = Spread(scale_ppm=5000.0, nonorthogonality_deg=0.3, bias_deg_s=0.3, misalignment_deg=1.0,
                    soft_iron=0.01, hard_iron=10.0, time_offset_s=0.002)
    p = dataclasses.replace(load_problem("production-line"), spread=spread, mag_time_offset_s=0.01)
    n = 4000
    devices = [device_scenario(p, seed) for seed in range(n)]
    iu = [(0, 1), (0, 2), (1, 2)]

    def stack(f):
        return np.array([f(d) for d in devices])

    columns = {  # key -> (draws in the key's own unit, the file's value, stated std)
        "scale_ppm": (stack(lambda d: 1e6 * np.diag(d.K_g) / np.diag(p.K_g)), 1e6 * np.ones(3), spread.scale_ppm),
        "nonorthogonality_deg": (stack(lambda d: np.rad2deg([d.K_g[i, j] for i, j in iu])),
                                 np.rad2deg([p.K_g[i, j] for i, j in iu]), spread.nonorthogonality_deg),
        "bias_deg_s": (stack(lambda d: d.gyro_bias_deg_s), p.gyro_bias_deg_s, spread.bias_deg_s),
        "misalignment_deg": (stack(lambda d: d.misalignment_euler_deg), p.misalignment_euler_deg,
                             spread.misalignment_deg),
        "soft_iron (diagonal)": (stack(lambda d: np.diag(d.soft_iron) / np.diag(p.soft_iron)), np.ones(3),
                                 spread.soft_iron),
        "soft_iron (above)": (stack(lambda d: [d.soft_iron[i, j] for i, j in iu]),
                              np.array([p.soft_iron[i, j] for i, j in iu]), spread.soft_iron),
        "hard_iron": (stack(lambda d: d.hard_iron), p.hard_iron, spread.hard_iron),
        "time_offset_s": (stack(lambda d: [d.mag_time_offset_s]), np.array([p.mag_time_offset_s]),
                          spread.time_offset_s),
    }
    all_z = []
    for key, (draws, value, sigma) in columns.items():
        mean, std = draws.mean(axis=0), draws.std(axis=0, ddof=1)
        assert np.all(np.abs(mean - value) < 4.5 * sigma / math.sqrt(n)), (key, mean, value)
        assert np.all(np.abs(std / sigma - 1.0) < 4.5 / math.sqrt(2 * n)), (key, std, sigma)
        all_z.append((draws - value) / sigma)
    corr = np.corrcoef(np.hstack(all_z), rowvar=False)
    off = corr[~np.eye(len(corr), dtype=bool)]
    assert np.all(np.abs(off) < 4.5 / math.sqrt(n)), np.abs(off).max()


def test_a_zero_key_leaves_the_others_draws_alone():
    p = load_problem("production-line")
    only_bias = dataclasses.replace(p, spread=Spread(bias_deg_s=p.spread.bias_deg_s))
    a, b = device_scenario(p, 11), device_scenario(only_bias, 11)
    np.testing.assert_array_equal(a.gyro_bias_deg_s, b.gyro_bias_deg_s)
    np.testing.assert_array_equal(b.K_g, p.K_g)
    np.testing.assert_array_equal(b.hard_iron, p.hard_iron)


# --------------------------------------------------------------------------- the command line


def test_cli_writes_sessions_truths_and_manifest(tmp_path):
    out = tmp_path / "new" / "fleet"
    r = CliRunner().invoke(app, ["simulate", "production-line", "--seeds", "3,7-8", "-o", str(out)])
    assert r.exit_code == 0, r.output
    assert r.output.count("\n") == 1 and "3 sessions" in r.output and "manifest.csv" in r.output
    with open(out / "manifest.csv", newline="") as f:
        rows = list(csv.DictReader(f))
    assert [(row["device_id"], row["session"]) for row in rows] == [
        (f"production-line-{s:04d}", f"production-line-{s:04d}.parquet") for s in (3, 7, 8)]
    assert sorted(f.name for f in out.iterdir()) == sorted(
        ["manifest.csv"] + [f"production-line-{s:04d}{ext}" for s in (3, 7, 8) for ext in (".parquet", ".truth.json")])
    p = load_problem("production-line")
    for s in (3, 7, 8):
        device = device_scenario(p, s)
        session, truth = simulate(device, s)
        loaded = load_session(out / f"production-line-{s:04d}.parquet")
        np.testing.assert_array_equal(loaded.gyro_rad_s, session.gyro_rad_s)
        np.testing.assert_array_equal(loaded.mag, session.mag)
        written = json.loads((out / f"production-line-{s:04d}.truth.json").read_text())
        assert written["seed"] == s and written["device"]["seed"] == s
        np.testing.assert_array_equal(written["gyro"]["K_g"], device.K_g)       # this device's, not the file's
        np.testing.assert_array_equal(written["magnetometer"]["h"], device.hard_iron)
        assert written["time_offset_s"] == device.mag_time_offset_s
        assert not np.array_equal(written["gyro"]["K_g"], p.K_g)


def test_cli_seed_and_seeds_together_is_exit_2_with_one_message(tmp_path, run_magyro, assert_plain_failure):
    out = tmp_path / "fleet"
    r = run_magyro("simulate", "production-line", "--seed", "3", "--seeds", "0-4", "-o", out)
    message = assert_plain_failure(r, 2)
    assert "--seed" in message and "--seeds" in message
    assert not out.exists()


@pytest.mark.parametrize("seeds,says", [("5-1", "empty"), ("x", "'x'")])
def test_cli_bad_seeds_is_exit_2(tmp_path, seeds, says):
    r = CliRunner().invoke(app, ["simulate", "production-line", "--seeds", seeds, "-o", str(tmp_path / "f")])
    assert r.exit_code == 2 and says in r.output
    assert not (tmp_path / "f").exists()


def test_cli_seeds_output_that_is_a_file_is_exit_2(tmp_path):
    (tmp_path / "f").write_text("")
    r = CliRunner().invoke(app, ["simulate", "production-line", "--seeds", "1", "-o", str(tmp_path / "f")])
    assert r.exit_code == 2 and "is not one" in r.output


# --------------------------------------------------------------------------- a device calibrated


def test_a_production_line_device_is_calibrated_to_its_own_truth():
    p = load_problem("production-line")
    seed = 3
    device = device_scenario(p, seed)
    session, truth = simulate(device, seed)
    cal = magyro.calibrate(session)
    K_g = np.array(truth["gyro"]["K_g"])
    z_scale = (np.diag(cal.K_g) - np.diag(K_g)) / np.diag(cal.std.K_g)
    z_bias = (cal.bias_deg_s - np.array(truth["gyro"]["bias_deg_s"])) / cal.std.bias_deg_s
    assert np.all(np.abs(z_scale) < 4.0), z_scale
    assert np.all(np.abs(z_bias) < 4.0), z_bias
    # and the device's own errors are far from the file's: the solve found this device, not the nominal one
    assert np.max(np.abs(np.diag(cal.K_g) - np.diag(p.K_g)) / np.diag(cal.std.K_g)) > 10.0
