"""Tests for magyro.io: loading session files, the input checks, writing, atomic output."""
from __future__ import annotations

import os
import sys

import numpy as np
import pandas as pd
import pyarrow as pa
import pyarrow.parquet as pq
import pytest

from magyro.errors import InputError, one_line
from magyro.io import (MAX_PLAUSIBLE_RATE_RAD_S, MIN_SAMPLES, load_session, session_file, write_session,
                       write_text_atomically)
from magyro.session import Session
from unprivileged import run_unprivileged, unprivileged_folder  # noqa: F401 (a fixture)

N_ROWS = 200


def synthetic_table(n_rows: int = N_ROWS, rate_hz: float = 100.0) -> pd.DataFrame:
    """A slowly rotating field and a smooth gyro signal, every sensor on every row."""
    t_s = np.arange(n_rows) / rate_hz
    angle = 0.5 * t_s
    return pd.DataFrame({
        "t": t_s,
        "gx": 0.3 + 0.1 * np.sin(t_s), "gy": -0.2 + 0.05 * np.cos(t_s), "gz": 0.5 + 0.0 * t_s,
        "mx": 30.0 * np.cos(angle), "my": 30.0 * np.sin(angle), "mz": -20.0 + np.sin(2 * t_s),
    })


def async_table(duration_s: float = 2.0) -> pd.DataFrame:
    """Gyro at 200 Hz and magnetometer at 50 Hz (offset by 1 ms) in one table with NaNs."""
    t_gyro_s = np.arange(0, duration_s, 1 / 200)
    t_mag_s = np.arange(0, duration_s, 1 / 50) + 0.001
    gyro = pd.DataFrame({"t": t_gyro_s, "gx": np.sin(t_gyro_s), "gy": np.cos(t_gyro_s),
                         "gz": 0.1 * t_gyro_s})
    mag = pd.DataFrame({"t": t_mag_s, "mx": np.cos(t_mag_s), "my": np.sin(t_mag_s),
                        "mz": 0.5 + 0 * t_mag_s})
    return pd.concat([gyro, mag]).sort_values("t").reset_index(drop=True)[
        ["t", "gx", "gy", "gz", "mx", "my", "mz"]]


def write_parquet(df: pd.DataFrame, path, **metadata) -> None:
    table = pa.Table.from_pandas(df, preserve_index=False)
    merged = {**(table.schema.metadata or {}), **{k.encode(): v.encode() for k, v in metadata.items()}}
    pq.write_table(table.replace_schema_metadata(merged), path)


def load_df(df: pd.DataFrame, tmp_path, name="s.csv", **kwargs) -> Session:
    path = tmp_path / name
    if name.endswith(".csv"):
        df.to_csv(path, index=False)
    else:
        write_parquet(df, path)
    return load_session(path, **kwargs)


def assert_input_error(df: pd.DataFrame, tmp_path, *fragments, name="s.csv", **kwargs) -> str:
    with pytest.raises(InputError) as info:
        load_df(df, tmp_path, name=name, **kwargs)
    message = str(info.value)
    for fragment in fragments:
        assert fragment in message, message
    assert message.startswith(f"{tmp_path / name}: "), message
    assert "Traceback" not in message and "\n" not in message
    return message


# --------------------------------------------------------------------------- good inputs


def test_parquet_load_values_units_and_metadata(tmp_path):
    df = synthetic_table()
    path = tmp_path / "s.parquet"
    write_parquet(df, path, gyro_unit="rad/s", mag_unit="uT", rig="bench-3")
    s = load_session(path)
    np.testing.assert_array_equal(s.t_gyro_s, df["t"])
    np.testing.assert_array_equal(s.gyro_rad_s, df[["gx", "gy", "gz"]])
    np.testing.assert_array_equal(s.mag, df[["mx", "my", "mz"]])
    assert s.mag_unit == "uT"
    assert s.source == str(path)
    assert s.metadata == {"gyro_unit": "rad/s", "mag_unit": "uT", "rig": "bench-3"}
    assert s.t_acc_s is None and s.t_quat_s is None


def test_parquet_round_trip(tmp_path):
    df = synthetic_table()
    df[["ax", "ay", "az"]] = np.column_stack([np.zeros(N_ROWS), np.zeros(N_ROWS), 9.81 + df["t"]])
    df[["qw", "qx", "qy", "qz"]] = [1.0, 0.0, 0.0, 0.0]
    first = load_df(df, tmp_path, name="in.parquet", mag_unit="gauss")
    out = tmp_path / "out.parquet"
    write_session(first, out)
    assert pq.read_schema(out).metadata[b"gyro_unit"] == b"rad/s"
    assert pq.read_schema(out).metadata[b"mag_unit"] == b"gauss"
    again = load_session(out)
    assert again.mag_unit == "gauss"
    for name in ("t_gyro_s", "gyro_rad_s", "t_mag_s", "mag", "t_acc_s", "acc_m_s2",
                 "t_quat_s", "quat_wxyz"):
        np.testing.assert_array_equal(getattr(again, name), getattr(first, name), err_msg=name)


def test_write_session_without_truth_quat(tmp_path):
    df = synthetic_table()
    df[["qw", "qx", "qy", "qz"]] = [1.0, 0.0, 0.0, 0.0]
    s = load_df(df, tmp_path, name="in.parquet")
    write_session(s, tmp_path / "out.parquet", truth_quat=False)
    assert "qw" not in pq.read_schema(tmp_path / "out.parquet").names
    assert load_session(tmp_path / "out.parquet").t_quat_s is None


def test_csv_round_trip(tmp_path):
    df = synthetic_table()
    first = load_df(df, tmp_path, name="in.csv", gyro_unit="deg/s", mag_unit="counts")
    out = tmp_path / "out.csv"
    write_session(first, out)
    # CSV carries no metadata: the gyro is written in rad/s (the default), the mag unit is given again
    again = load_session(out, mag_unit="counts")
    assert again.mag_unit == "counts"
    np.testing.assert_array_equal(again.gyro_rad_s, first.gyro_rad_s)
    np.testing.assert_array_equal(again.mag, first.mag)
    np.testing.assert_array_equal(again.t_mag_s, first.t_mag_s)


def test_asynchronous_sensors_get_separate_time_bases(tmp_path):
    df = async_table(duration_s=2.0)
    for name in ("a.csv", "a.parquet"):
        s = load_df(df, tmp_path, name=name)
        assert len(s.t_gyro_s) == 400 and s.gyro_rad_s.shape == (400, 3)
        assert len(s.t_mag_s) == 100 and s.mag.shape == (100, 3)
        np.testing.assert_allclose(np.diff(s.t_gyro_s), 1 / 200)
        np.testing.assert_allclose(np.diff(s.t_mag_s), 1 / 50)
        assert s.gyro_rate_hz == pytest.approx(200) and s.mag_rate_hz == pytest.approx(50)


def test_write_session_merges_identical_times_and_leaves_nan(tmp_path):
    t_gyro_s = np.arange(400) / 200.0
    t_mag_s = t_gyro_s[::4].copy()  # every mag sample coincides with a gyro sample
    s = Session(t_gyro_s=t_gyro_s, gyro_rad_s=np.full((400, 3), 0.1),
                t_mag_s=t_mag_s, mag=np.ones((100, 3)), mag_unit="uT")
    write_session(s, tmp_path / "out.parquet")
    written = pd.read_parquet(tmp_path / "out.parquet")
    assert len(written) == 400
    assert list(written.columns) == ["t", "gx", "gy", "gz", "mx", "my", "mz"]
    assert written["mx"].notna().sum() == 100 and written["gx"].notna().all()
    np.testing.assert_array_equal(written["mx"].to_numpy()[::4], 1.0)


def test_union_of_times_on_write(tmp_path):
    s = load_df(async_table(duration_s=2.0), tmp_path, name="in.parquet")
    write_session(s, tmp_path / "out.csv")
    written = pd.read_csv(tmp_path / "out.csv")
    assert len(written) == 500
    assert np.all(np.diff(written["t"]) > 0)
    assert written["gx"].isna().sum() == 100 and written["mx"].isna().sum() == 400


def test_rows_without_gyro_or_mag_are_allowed(tmp_path):
    df = synthetic_table(n_rows=300)
    df.loc[100:149, ["gx", "gy", "gz", "mx", "my", "mz"]] = np.nan
    df[["ax", "ay", "az"]] = [0.0, 0.0, 9.81]
    s = load_df(df, tmp_path)
    assert len(s.t_gyro_s) == 250 and len(s.t_mag_s) == 250 and len(s.t_acc_s) == 300


def test_truth_quaternion_rows_with_nan_dropped(tmp_path):
    df = synthetic_table()
    df[["qw", "qx", "qy", "qz"]] = [1.0, 0.0, 0.0, 0.0]
    df.loc[10:19, ["qw", "qx", "qy", "qz"]] = np.nan  # tracking lost
    df.loc[30, "qy"] = np.nan  # partly lost
    s = load_df(df, tmp_path)
    assert s.quat_wxyz.shape == (N_ROWS - 11, 4)
    assert 10 not in np.round(s.t_quat_s * 100) and 30 not in np.round(s.t_quat_s * 100)


def test_units_from_metadata_and_argument_overrides(tmp_path):
    df = synthetic_table()
    df[["gx", "gy", "gz"]] = np.degrees(df[["gx", "gy", "gz"]])
    path = tmp_path / "s.parquet"
    write_parquet(df, path, gyro_unit="deg/s", mag_unit="uT")
    from_metadata = load_session(path)
    np.testing.assert_allclose(from_metadata.gyro_rad_s, np.radians(df[["gx", "gy", "gz"]]))
    assert from_metadata.mag_unit == "uT"
    overridden = load_session(path, gyro_unit="rad/s", mag_unit="gauss")
    np.testing.assert_array_equal(overridden.gyro_rad_s, df[["gx", "gy", "gz"]])
    assert overridden.mag_unit == "gauss"


def test_default_units(tmp_path):
    s = load_df(synthetic_table(), tmp_path)
    assert s.mag_unit == "unknown"
    np.testing.assert_array_equal(s.gyro_rad_s, synthetic_table()[["gx", "gy", "gz"]])


@pytest.mark.parametrize("unit", ["deg/s", "DPS", "Deg/S", "deg / s"])
def test_deg_s_aliases_convert(tmp_path, unit):
    df = synthetic_table()
    s = load_df(df, tmp_path, gyro_unit=unit)
    np.testing.assert_allclose(s.gyro_rad_s, np.radians(df[["gx", "gy", "gz"]]), rtol=1e-15)


@pytest.mark.parametrize("unit", ["rad/s", "RPS", "Rad/s"])
def test_rad_s_aliases(tmp_path, unit):
    df = synthetic_table()
    s = load_df(df, tmp_path, gyro_unit=unit)
    np.testing.assert_array_equal(s.gyro_rad_s, df[["gx", "gy", "gz"]])


def test_load_does_not_modify_input(tmp_path):
    for name in ("s.csv", "s.parquet"):
        path = tmp_path / name
        if name.endswith(".csv"):
            synthetic_table().to_csv(path, index=False)
        else:
            write_parquet(synthetic_table(), path, gyro_unit="rad/s")
        before, mtime = path.read_bytes(), path.stat().st_mtime_ns
        files_before = sorted(tmp_path.iterdir())
        load_session(path)
        assert path.read_bytes() == before and path.stat().st_mtime_ns == mtime
        assert sorted(tmp_path.iterdir()) == files_before


def test_parquet_content_with_other_suffix_is_read_as_parquet(tmp_path):
    path = tmp_path / "session.dat"
    write_parquet(synthetic_table(), path, mag_unit="uT")
    assert load_session(path).mag_unit == "uT"


# --------------------------------------------------------------------------- bad files


def test_missing_file(tmp_path):
    with pytest.raises(InputError, match="no such file"):
        load_session(tmp_path / "nope.parquet")


@pytest.mark.parametrize("name", ["empty.csv", "empty.parquet"])
def test_zero_byte_file(tmp_path, name):
    (tmp_path / name).write_bytes(b"")
    with pytest.raises(InputError, match=r"empty.*0 bytes") as info:
        load_session(tmp_path / name)
    assert name in str(info.value)


@pytest.mark.parametrize("name", ["rows.csv", "rows.parquet"])
def test_zero_rows(tmp_path, name):
    with pytest.raises(InputError, match="no data rows") as info:
        load_df(synthetic_table().iloc[:0], tmp_path, name=name)
    assert name in str(info.value)


def test_corrupt_parquet(tmp_path):
    path = tmp_path / "bad.parquet"
    write_parquet(synthetic_table(), path)
    path.write_bytes(path.read_bytes()[:300])
    with pytest.raises(InputError, match="cannot be read as Parquet") as info:
        load_session(path)
    assert "bad.parquet" in str(info.value)


def test_binary_garbage_as_csv(tmp_path):
    path = tmp_path / "garbage.csv"
    path.write_bytes(np.random.default_rng(0).bytes(4000) + b"\x00")
    with pytest.raises(InputError, match="not a CSV text file") as info:
        load_session(path)
    assert "garbage.csv" in str(info.value)


def test_undecodable_csv(tmp_path):
    path = tmp_path / "latin.csv"
    path.write_bytes(b"t,gx\n0,\xff\xfe\n")
    with pytest.raises(InputError, match="cannot be read as CSV") as info:
        load_session(path)
    assert "latin.csv" in str(info.value)


READ_AS_ANOTHER = """
import sys
from magyro.errors import InputError
from magyro.io import load_session
try:
    load_session(sys.argv[1])
except InputError as error:
    print("InputError:", error)
else:
    print("read")
"""


@pytest.mark.skipif(os.name != "posix", reason="a file of mode 000 is refused only on POSIX systems")
def test_unreadable_file(unprivileged_folder):
    """load_session of a file its user may not read (as root, the check runs as the user nobody)."""
    folder, env = unprivileged_folder
    path = folder / "locked.csv"
    synthetic_table().to_csv(path, index=False)
    path.chmod(0)
    done = run_unprivileged([sys.executable, "-c", READ_AS_ANOTHER, str(path)], folder, env)
    assert done.returncode == 0, done.stderr
    assert done.stdout.startswith("InputError:") and "locked.csv: cannot be read" in done.stdout, done.stdout


def test_directory_is_not_a_file(tmp_path):
    with pytest.raises(InputError, match="not a regular file"):
        load_session(tmp_path)


# --------------------------------------------------------------------------- bad content


def test_missing_columns_named_with_found_ones(tmp_path):
    df = synthetic_table().drop(columns=["gy", "mz"])
    msg = assert_input_error(df, tmp_path, "missing column(s) gy, mz",
                             "found columns: t, gx, gz, mx, my")
    assert "ax" in msg  # says what is optional


def test_partial_optional_group_is_missing_columns(tmp_path):
    df = synthetic_table()
    df["ax"] = 0.0
    assert_input_error(df, tmp_path, "missing column(s) ay, az")


def test_time_not_numeric(tmp_path):
    df = synthetic_table()
    df["t"] = df["t"].astype(str)
    df.loc[7, "t"] = "12:00:01"
    assert_input_error(df, tmp_path, "row 7", "column t", "'12:00:01'", "not a number")


def test_time_not_numeric_parquet_type(tmp_path):
    df = synthetic_table()
    df["t"] = pd.date_range("2024-01-01", periods=N_ROWS, freq="10ms")
    assert_input_error(df, tmp_path, "column t has type", "numbers", name="s.parquet")


@pytest.mark.parametrize("bad", [np.nan, np.inf])
def test_time_not_finite(tmp_path, bad):
    df = synthetic_table()
    df.loc[12, "t"] = bad
    assert_input_error(df, tmp_path, "row 12", "time t is " + {np.nan: "NaN", np.inf: "inf"}[bad], name="s.parquet")


def test_time_goes_backwards(tmp_path):
    df = synthetic_table()
    df.loc[50, "t"] = 0.2
    assert_input_error(df, tmp_path, "row 50", "time goes backwards", "t = 0.2 s",
                       "after t = 0.49 s at row 49")


def test_duplicate_time(tmp_path):
    df = synthetic_table()
    df.loc[21, "t"] = df.loc[20, "t"]
    assert_input_error(df, tmp_path, "row 21", "duplicate time", "t = 0.2 s", "row 20")


def test_partial_gyro_sample(tmp_path):
    df = synthetic_table()
    df.loc[33, "gy"] = np.nan
    assert_input_error(df, tmp_path, "NaN where a sample should be", "row 33", "column gy",
                       "gx = ")


def test_partial_mag_sample(tmp_path):
    df = async_table()
    row = int(np.flatnonzero(df["mx"].notna())[5])
    df.loc[row, "mz"] = np.nan
    assert_input_error(df, tmp_path, "NaN where a sample should be", f"row {row}", "column mz",
                       "magnetometer")


def test_partial_acc_sample(tmp_path):
    df = synthetic_table()
    df[["ax", "ay", "az"]] = [0.0, 0.0, 9.81]
    df.loc[4, "ay"] = np.nan
    assert_input_error(df, tmp_path, "NaN where a sample should be", "row 4", "column ay")


@pytest.mark.parametrize("bad,shown", [(np.inf, "inf"), (-np.inf, "-inf")])
@pytest.mark.parametrize("column", ["gz", "mx"])
def test_inf_in_sensor_column(tmp_path, bad, shown, column):
    df = synthetic_table()
    df.loc[9, column] = bad
    assert_input_error(df, tmp_path, f"{shown} where a sample should be", "row 9",
                       f"column {column}", name="s.parquet")


def test_text_in_sensor_column(tmp_path):
    df = synthetic_table().astype({"my": object})
    df.loc[15, "my"] = "n/a?"
    assert_input_error(df, tmp_path, "row 15", "column my", "'n/a?'", "not a number")


def test_too_few_mag_samples(tmp_path):
    df = synthetic_table()
    df.loc[42:, ["mx", "my", "mz"]] = np.nan
    assert_input_error(df, tmp_path, "too few magnetometer samples", "found 42",
                       f"at least {MIN_SAMPLES}")


def test_too_few_gyro_samples(tmp_path):
    df = synthetic_table(n_rows=99)
    assert_input_error(df, tmp_path, "too few gyro samples", "found 99")


def test_unknown_gyro_unit_argument(tmp_path):
    assert_input_error(synthetic_table(), tmp_path, "unknown gyro unit 'rpm'", "--gyro-unit",
                       gyro_unit="rpm")


def test_unknown_gyro_unit_metadata(tmp_path):
    path = tmp_path / "s.parquet"
    write_parquet(synthetic_table(), path, gyro_unit="mrad/s")
    with pytest.raises(InputError, match="unknown gyro unit 'mrad/s'.*metadata"):
        load_session(path)
    assert load_session(path, gyro_unit="rad/s").gyro_rad_s.shape == (N_ROWS, 3)


def test_deg_s_labelled_rad_s(tmp_path):
    df = synthetic_table()
    df[["gx", "gy", "gz"]] = [200.0, -150.0, 2000.0]  # deg/s, within a 2000 dps MEMS range
    assert_input_error(df, tmp_path, "look like deg/s", "pass --gyro-unit deg/s")
    s = load_df(df, tmp_path, gyro_unit="deg/s")
    assert np.linalg.norm(s.gyro_rad_s, axis=1).max() < MAX_PLAUSIBLE_RATE_RAD_S


def test_implausible_even_in_deg_s(tmp_path):
    df = synthetic_table()
    df[["gx", "gy", "gz"]] = [0.0, 0.0, 1e5]
    assert_input_error(df, tmp_path, "implausible", "deg/s", gyro_unit="deg/s")


def test_rare_spikes_do_not_trip_the_rate_check(tmp_path):
    df = synthetic_table(n_rows=5000, rate_hz=1000.0)
    df.loc[100, "gx"] = 500.0  # one glitch, below the 99.9th percentile
    assert load_df(df, tmp_path).gyro_rad_s.shape == (5000, 3)


# --------------------------------------------------------------------------- atomic writes


def test_write_text_atomically(tmp_path):
    path = tmp_path / "report.json"
    write_text_atomically(path, '{"a": 1}\n')
    assert path.read_text() == '{"a": 1}\n'
    write_text_atomically(path, "second")
    assert path.read_text() == "second"
    assert [p.name for p in tmp_path.iterdir()] == ["report.json"]


def test_write_into_missing_directory_leaves_nothing(tmp_path):
    s = load_df(synthetic_table(), tmp_path)
    target = tmp_path / "no" / "such" / "dir" / "out.parquet"
    with pytest.raises(OSError):
        write_session(s, target)
    with pytest.raises(OSError):
        write_text_atomically(tmp_path / "no" / "r.json", "x")
    assert not (tmp_path / "no").exists()


def test_failure_mid_write_leaves_no_partial_file(tmp_path, monkeypatch):
    s = load_df(synthetic_table(), tmp_path, name="in.csv")
    target = tmp_path / "out.parquet"

    def half_then_fail(table, where, **kwargs):
        with open(where, "wb") as f:
            f.write(b"PAR1 partial")
        raise RuntimeError("disk full")

    monkeypatch.setattr(session_file.pq, "write_table", half_then_fail)
    with pytest.raises(RuntimeError, match="disk full"):
        write_session(s, target)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["in.csv"]


def test_failure_mid_write_keeps_previous_file(tmp_path, monkeypatch):
    s = load_df(synthetic_table(), tmp_path, name="in.csv")
    target = tmp_path / "out.csv"
    target.write_text("previous")

    def fail(*args, **kwargs):
        raise KeyboardInterrupt

    monkeypatch.setattr(pd.DataFrame, "to_csv", fail)
    with pytest.raises(KeyboardInterrupt):
        write_session(s, target)
    assert target.read_text() == "previous"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["in.csv", "out.csv"]


def test_the_solve_path_imports_neither_pandas_nor_scipy():
    """Loading a Parquet session and everything `magyro solve` imports stays off pandas and scipy
    (each adds 0.2-0.4 s to every run; benchmarks/bench_solve.py times the whole process)."""
    import subprocess
    import sys
    from pathlib import Path

    shipped = Path(__file__).resolve().parents[1] / "data" / "broad-02.parquet"
    code = ("import sys, magyro.cli, magyro.nls.solve, magyro.result.consistency, magyro.io; "
            f"magyro.io.load_session({str(shipped)!r}); "
            "print(sorted(m for m in ('pandas', 'scipy', 'pyarrow.compute') if m in sys.modules))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "[]", out.stdout


def test_magyro_io_imports_each_name_on_first_use():
    """`import magyro.io` loads nothing heavy; atomic output needs no pyarrow, an importer loads pandas."""
    import subprocess
    import sys

    code = ("import sys\n"
            "heavy = lambda: [m for m in ('pyarrow', 'pandas', 'scipy') if m in sys.modules]\n"
            "import magyro.io as io\n"
            "print(heavy())\n"
            "from magyro.io import write_text_atomically\n"
            "print(heavy())\n"
            "from magyro.io import load_session\n"
            "print(heavy())\n"
            "print(io.import_csv.__module__, io.convert_broad.__module__, heavy())\n")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.splitlines() == ["[]", "[]", "['pyarrow']",
                                       "magyro.io.csv_import magyro.io.broad ['pyarrow', 'pandas']"], out.stdout


def test_every_public_name_of_magyro_io_is_what_it_says():
    """No public name is shadowed by a submodule of the same name, whatever was imported first."""
    import inspect
    import subprocess
    import sys

    import magyro.io

    code = ("import importlib, inspect, magyro.io as io\n"
            "for m in ('atomic', 'broad', 'checks', 'columns', 'csv_columns', 'csv_import', 'csv_text', 'csv_units', "
            "'csv_zip', 'cutting', 'session_file'):\n"
            "    importlib.import_module('magyro.io.' + m)\n"
            "print(sorted(n for n in io.__all__ if inspect.ismodule(getattr(io, n))))\n")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "[]", out.stdout
    for name in magyro.io.__all__:
        value = getattr(magyro.io, name)
        assert not inspect.ismodule(value), name
        if callable(value):
            assert value.__module__.startswith("magyro.io.") and value.__name__ == name, name
    with pytest.raises(AttributeError, match="has no attribute 'no_such_name'"):
        magyro.io.no_such_name
    assert magyro.io.__all__ == list(magyro.io._EXPORTS)
    assert {"import_broad", "import_csv", "load_session"} <= set(dir(magyro.io))


def test_one_line():
    assert one_line(ValueError("bad\n  value\tat  row 3 ")) == "bad value at row 3"
    assert one_line(KeyError()) == "KeyError"
    assert one_line(RuntimeError("x" * 300)) == "x" * 200
    assert one_line(RuntimeError("x" * 300), limit=None) == "x" * 300
