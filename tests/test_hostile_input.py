"""Hostile input cannot hurt (issue 25): nothing written outside its place, nothing lost, bounded memory, never an
internal error.

Each case runs the command in-process (typer's runner: no start-up per case) and asserts the exit code, the one
message naming the problem, and that nothing was written and no input changed. No solve, except one batch that
is resumed (session-scoped). The calibrations are made from given parameters, not solved.
"""
from __future__ import annotations

import copy
import hashlib
import json
import math
import os
import re
import shutil
import subprocess
import time
from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

from magyro.cli import app
from magyro.result.calibration import Calibration
from conftest import magyro_command
from unprivileged import run_unprivileged, unprivileged_folder  # noqa: F401 (a fixture)

DATA = Path(__file__).resolve().parents[1] / "data"
PROBLEMS = Path(__file__).resolve().parents[1] / "problems"
BROAD_02 = DATA / "broad-02.parquet"


def run(*args, cwd: Path | None = None):
    """The command in-process: (exit code, stdout, stderr)."""
    old = os.getcwd()
    try:
        if cwd is not None:
            os.chdir(cwd)
        r = CliRunner().invoke(app, [str(a) for a in args], catch_exceptions=False)
    finally:
        os.chdir(old)
    return r.exit_code, r.stdout, r.stderr


def refused(args, pattern: str, cwd: Path, code: int = 2, env: dict | None = None) -> str:
    """Run a command that must be refused: its exit code, ONE message matching `pattern`, nothing written in
    `cwd`, no input changed. Returns the message. With `env`, as a child process run by the unprivileged user
    (tests/unprivileged.py) in that environment."""
    before = snapshot(cwd)
    saved = os.environ.get("MAGYRO_PROGRESS")
    os.environ["MAGYRO_PROGRESS"] = "lines"     # every step of work a stderr line: one line is the refusal alone
    try:
        if env is None:
            exit_code, out, err = run(*args, cwd=cwd)
        else:
            done = run_unprivileged([*magyro_command(), *map(str, args)], cwd, {**env, "MAGYRO_PROGRESS": "lines"})
            exit_code, out, err = done.returncode, done.stdout, done.stderr
    finally:
        if saved is None:
            del os.environ["MAGYRO_PROGRESS"]
        else:
            os.environ["MAGYRO_PROGRESS"] = saved
    # its progress lines: the report's own, and reading the input (what is wrong may lie in it); any other step is work
    lines = [line for line in err.strip().splitlines()
             if not line.startswith(("report: ", "magyro step: reading "))]
    assert exit_code == code, (exit_code, out, err)
    assert len(lines) == 1 and lines[0].startswith("magyro: "), err
    assert "internal error" not in err and "Traceback" not in err, err
    assert re.search(pattern, lines[0]), lines[0]
    assert snapshot(cwd) == before, "a refused command wrote or changed something"
    return lines[0]


def snapshot(folder: Path) -> dict:
    out = {}
    for p in sorted(folder.rglob("*")):
        key = str(p.relative_to(folder))
        if p.is_symlink():
            out[key] = "link:" + os.readlink(p)
        elif p.is_file():
            out[key] = hashlib.sha256(p.read_bytes()).hexdigest()
        else:
            out[key] = "dir"
    return out


# --------------------------------------------------------------------------- calibrations


def good_calibration(unit: str = "uT") -> dict:
    """A calibration of given parameters, as magyro writes it (zero std, NaN condition: 'not measured')."""
    c = math.cos(0.02)
    cal = Calibration.from_parameters(
        K_g=[[1.01, 0.002, -0.001], [0.0, 0.99, 0.003], [0.0, 0.0, 1.005]], bias_rad_s=[0.01, -0.02, 0.005],
        C_b_m=[[c, -math.sin(0.02), 0.0], [math.sin(0.02), c, 0.0], [0.0, 0.0, 1.0]],
        R=np.diag([1 / 48.0, 1 / 50.0, 1 / 49.0]), h=[3.0, -2.0, 1.0], mag_unit=unit)
    return json.loads(cal.to_json())


def write_json(path: Path, data=None, text: str | None = None) -> Path:
    path.write_text(text if text is not None else json.dumps(data))
    return path


def mutated(f) -> dict:
    d = copy.deepcopy(good_calibration())
    f(d)
    return d


@pytest.fixture
def folder(tmp_path):
    shutil.copy(BROAD_02, tmp_path / "s.parquet")
    write_json(tmp_path / "good.json", good_calibration())
    return tmp_path


def _set(path: str, value):
    def f(d):
        *keys, last = path.split(".")
        for k in keys:
            d = d[k]
        d[last] = value
    return f


WRONG = {   # file -> (its text, the message)
    "schema-list": (mutated(_set("schema", [1])), r"schema must be a string, not list"),
    "units-list": (mutated(_set("units", [1])), r"units must be an object or null, not list"),
    "magnetometer-list": (mutated(_set("magnetometer", [1])), r"magnetometer must be an object, not list"),
    "noise-list": (mutated(_set("noise", [1])), r"noise must be an object or null, not list"),
    "rests-string": (mutated(_set("rests", "abc")), r"rests must be an object or null, not str"),
    "warnings-7": (mutated(_set("warnings", 7)), r"warnings must be a list, not int"),
    "tolerance-abc": (mutated(_set("observability.tolerance", "abc")), r"observability.tolerance must be a number"),
    "time-offset-nan": (mutated(_set("time_offset_s", float("nan"))), r"time_offset_s must be a finite number"),
    "K_g-shape": (mutated(_set("gyro.K_g", [[1, 0], [0, 1]])), r"gyro.K_g must have shape \(3, 3\)"),
}


@pytest.mark.parametrize("name", sorted(WRONG))
def test_a_calibration_of_the_wrong_type_anywhere_is_refused_with_its_key(folder, name):
    data, message = WRONG[name]
    write_json(folder / "bad.json", data)
    refused(["export", "bad.json", "-f", "yaml", "-o", "out.yaml"], message, folder)


@pytest.mark.parametrize("name, text, message", [
    ("iterations-inf", lambda t: t.replace('"iterations": 0', '"iterations": Infinity'), r"solver.iterations must be a whole number"),
    ("rank-nan", lambda t: t.replace('"rank": 12', '"rank": NaN'), r"observability.rank must be a whole number"),
    ("int-5000", lambda t: t.replace('"iterations": 0', '"iterations": ' + "9" * 5000), r"integer of 5000 digits"),
    ("deep", lambda t: t[:-1] + ', "x": ' + "[" * 200_000 + "]" * 200_000 + "}", r"nested deeper than 64 levels"),
])
def test_json_numbers_and_nesting_out_of_bounds_are_refused(folder, name, text, message):
    (folder / "bad.json").write_text(text(json.dumps(good_calibration())))
    refused(["export", "bad.json", "-f", "c", "-o", "out.h"], message, folder)


def _cuts() -> dict:
    text = json.dumps(good_calibration(), indent=2)
    return {"empty": "", "in-a-number": text[:text.index('"K_g"') + 12], "in-a-string": text[:text.index("calibration/1") + 4],
            "in-a-key": text[:text.index('"gyro"') + 3]}


@pytest.mark.parametrize("cut", sorted(_cuts()))
@pytest.mark.parametrize("command", ["export", "apply", "validate", "report"])
def test_a_calibration_cut_short_is_named_so_by_every_command(folder, cut, command):
    (folder / "cut.json").write_text(_cuts()[cut])
    args = {"export": ["export", "cut.json", "-f", "yaml", "-o", "o.yaml"],
            "apply": ["apply", "s.parquet", "cut.json", "-o", "o.parquet"],
            "validate": ["validate", "s.parquet", "cut.json", "-o", "o.json"],
            "report": ["report", "s.parquet", "cut.json", "-o", "o.html"]}[command]
    refused(args, r"cut\.json: a calibration cut short", folder)


def test_a_file_given_in_the_wrong_place_is_named_for_what_it_is(folder):
    refused(["apply", "good.json", "s.parquet", "-o", "o.parquet"], r"s\.parquet: this is a session \(Parquet", folder)
    refused(["validate", "good.json", "s.parquet"], r"good\.json: this is a magyro JSON file \(magyro\.calibration\), "
            "not a session", folder)


def test_report_refuses_a_time_offset_that_is_not_a_number(folder):
    write_json(folder / "nan.json", mutated(_set("time_offset_s", float("nan"))))
    refused(["report", "s.parquet", "nan.json", "-o", "r.html"], r"time_offset_s must be a finite number", folder)


def test_export_reads_a_path_that_looks_like_json_as_a_path(folder):
    refused(["export", "{cal}.json", "-f", "yaml"], r"\{cal\}\.json: no such file", folder)
    shutil.copy(folder / "good.json", folder / "{cal}.json")
    code, out, err = run("export", "{cal}.json", "-f", "yaml", cwd=folder)
    assert code == 0 and "K_g:" in out, err


def test_a_calibration_without_std_is_applied_validated_and_exported(folder):
    write_json(folder / "nostd.json", mutated(lambda d: d.pop("std")))
    write_json(folder / "nostdK.json", mutated(lambda d: d["std"].pop("K")))
    for name in ("nostd.json", "nostdK.json"):
        code, _, err = run("export", name, "-f", "px4", "-o", f"{name}.params", cwd=folder)
        assert code == 0 and (folder / f"{name}.params").is_file(), err
    code, _, err = run("apply", "s.parquet", "nostd.json", "-o", "a.parquet", cwd=folder)
    assert code == 0, err
    from magyro.io import load_session

    raw, done = load_session(folder / "s.parquet"), load_session(folder / "a.parquet")
    expected, _ = Calibration.from_json(folder / "nostd.json").apply(raw.gyro_rad_s)
    np.testing.assert_allclose(done.gyro_rad_s, expected, rtol=1e-12)
    code, out, err = run("validate", "s.parquet", "nostd.json", cwd=folder)
    assert code == 0 and "calibrated / raw" in out, err


@pytest.fixture
def calibrated(folder):
    code, _, err = run("apply", "s.parquet", "good.json", "-o", "cal.parquet", cwd=folder)
    assert code == 0, err
    return folder


@pytest.mark.parametrize("command", ["apply", "validate", "report"])
def test_no_command_applies_a_calibration_to_a_calibrated_session(calibrated, command):
    args = {"apply": ["apply", "cal.parquet", "good.json", "-o", "o.parquet"],
            "validate": ["validate", "cal.parquet", "good.json", "-o", "o.json"],
            "report": ["report", "cal.parquet", "good.json", "-o", "o.html"]}[command]
    refused(args, r"cal\.parquet: already calibrated", calibrated)


def test_a_calibration_in_another_magnetometer_unit_is_not_applied(folder):
    write_json(folder / "gauss.json", good_calibration("G"))
    refused(["apply", "s.parquet", "gauss.json", "-o", "o.parquet"],
            r"the magnetometer is in uT, the calibration was made in G", folder)
    refused(["report", "s.parquet", "gauss.json", "-o", "o.html"], r"made in G", folder)


@pytest.mark.parametrize("K_g, message", [
    ([[1.7e308, 0, 0], [0, 1, 0], [0, 0, 1]], r"K_g is singular or nearly so"),
    ([[1, 1, 0], [1, 1, 0], [0, 0, 1]], r"K_g is singular or nearly so"),
])
def test_apply_refuses_a_matrix_that_would_write_infinities(folder, K_g, message):
    write_json(folder / "k.json", mutated(_set("gyro.K_g", K_g)))
    refused(["apply", "s.parquet", "k.json", "-o", "o.parquet"], message, folder)


@pytest.mark.parametrize("fmt", ["yaml", "c", "kalibr", "px4"])
@pytest.mark.parametrize("key, value, message", [
    ("magnetometer.R", [[0, 0, 0]] * 3, r"magnetometer R is singular"),
    ("gyro.K_g", [[1, 1, 0], [1, 1, 0], [0, 0, 1]], r"gyro K_g is singular"),   # not triangular, singular
])
def test_export_refuses_a_singular_calibration_in_every_format(folder, fmt, key, value, message):
    write_json(folder / "sing.json", mutated(_set(key, value)))
    refused(["export", "sing.json", "-f", fmt, "-o", "out.txt"], message, folder)


HOSTILE_UNIT = "\x1b]2;pwn\x07\x1b[2J\u202e\x9b\x00"


def test_control_and_bidi_characters_in_a_unit_never_reach_the_terminal(folder):
    cal = good_calibration()
    cal["magnetometer"]["unit"] = cal["units"]["magnetometer"] = HOSTILE_UNIT
    write_json(folder / "evil.json", cal)
    message = refused(["export", "evil.json", "-f", "c"], r"is not a unit: it holds control or bidi", folder)
    assert not any(ch in message for ch in "\x1b\x07\u202e\x9b\x00")
    import pyarrow.parquet as pq

    table = pq.read_table(BROAD_02)
    metadata = {**(table.schema.metadata or {}), b"mag_unit": HOSTILE_UNIT.encode()}
    pq.write_table(table.replace_schema_metadata(metadata), folder / "evil.parquet")
    message = refused(["solve", "evil.parquet", "-o", "c.json"], r"evil\.parquet: the magnetometer unit .* is not a unit",
                      folder)
    assert "\\x1b" in message and "\x1b" not in message


def test_a_unit_cannot_break_out_of_a_c_comment(folder):
    cal = good_calibration()
    cal["magnetometer"]["unit"] = cal["units"]["magnetometer"] = "uT */ int x; /* µ"
    write_json(folder / "c.json", cal)
    code, out, err = run("export", "c.json", "-f", "c", cwd=folder)
    assert code == 0, err
    for comment in re.findall(r"/\*(.*?)\*/", out, flags=re.S):
        assert "/*" not in comment
    assert out.isascii()
    if shutil.which("gcc"):
        (folder / "cal.h").write_text(out)
        (folder / "m.c").write_text('#include "cal.h"\nint main(void) { double w[3] = {0, 0, 0}; '
                                    "magyro_apply_gyro(w, w); return (int)w[0]; }\n")
        r = subprocess.run(["gcc", "-std=c99", "-Wall", "-Wextra", "-Werror", "-Wbidi-chars=any", "-c", "m.c",
                            "-o", "m.o"], cwd=folder, capture_output=True, text=True)
        assert r.returncode == 0, r.stderr


# --------------------------------------------------------------------------- problem and limits files


def problem_text(**changes) -> str:
    text = (PROBLEMS / "short-30s.toml").read_text()
    for key, value in changes.items():
        pattern = re.compile(rf"(?m)^{key} = .*$")
        if pattern.search(text):
            text = pattern.sub(lambda m: f"{key} = {value}", text, count=1)
        else:
            text = text.replace("[motion]", f"[motion]\n{key} = {value}", 1)
    return text


@pytest.mark.parametrize("name", ['"../../escaped"', '"/any/dir/pwn"', r'"a\u0000b"', r'"x\u007fy"', '".hidden"'])
def test_a_problem_name_cannot_write_outside_the_fleet_folder(tmp_path, name):
    (tmp_path / "evil.toml").write_text(problem_text(name=name))
    refused(["simulate", "evil.toml", "--seeds", "0-1", "-o", "a/b/fleet"], r"evil\.toml \[problem\]: name .* cannot "
            r"name a file", tmp_path)


@pytest.mark.parametrize("key, value, cap", [
    ("components", "100000000", r"components = 100000000 is above the cap of 1000"),
    ("duration_s", "1e9", r"duration_s = 1e\+09 is above the cap of 86400 s"),
    ("rate_hz", "1e9", r"rate_hz = 1e\+09 is above the cap of 10000 Hz"),
])
def test_simulated_sizes_are_capped_and_the_refusal_names_the_cap(tmp_path, key, value, cap):
    (tmp_path / "big.toml").write_text(problem_text(**{key: value}))
    refused(["simulate", "big.toml", "-o", "big.parquet"], cap, tmp_path)   # before any sample is made


@pytest.mark.parametrize("what", ["problem", "limits"])
@pytest.mark.parametrize("case, message", [
    ("int401", r"is an integer of more than 40 digits"),
    ("deep", r"nested too deep"),
])
def test_toml_integers_and_nesting_out_of_bounds_are_refused(tmp_path, what, case, message):
    value = "9" * 401 if case == "int401" else "[" * 50_000 + "]" * 50_000
    if what == "problem":
        (tmp_path / "p.toml").write_text(problem_text().replace("[motion]", f"[motion]\nx = {value}", 1)
                                         if case == "deep" else problem_text(duration_s=value))
        refused(["simulate", "p.toml", "-o", "s.parquet"], message, tmp_path)
    else:
        shutil.copy(BROAD_02, tmp_path / "s.parquet")
        (tmp_path / "l.toml").write_text(f"[limits]\nx = {value}\n")
        refused(["batch", "s.parquet", "-o", "out", "--limits", "l.toml"], message, tmp_path)


def test_plan_refuses_a_base_whose_name_holds_del(tmp_path):
    (tmp_path / "b.toml").write_text(problem_text(name=r'"x\u007fy"'))
    refused(["plan", "--duration", "30", "--base", "b.toml", "-o", "plan.toml"], r"\\x7f", tmp_path)


def test_text_written_into_toml_reads_back(tmp_path):
    from magyro.io.toml_file import parse_toml
    from magyro.text import toml_string

    text = 'a\x7fb\x00c\u202e"\\ µ\U0001f600'
    assert parse_toml(f"x = {toml_string(text)}\n")["x"] == text


# --------------------------------------------------------------------------- batch


def test_batch_refuses_an_input_named_like_its_summary_before_any_work(tmp_path):
    (tmp_path / "F").mkdir()
    shutil.copy(BROAD_02, tmp_path / "F" / "summary.parquet")
    shutil.copy(BROAD_02, tmp_path / "F" / "dev1.parquet")
    refused(["batch", "F", "-o", "F"], r"the output F/summary\.parquet is the input F/summary\.parquet", tmp_path)


@pytest.mark.parametrize("folder_at", ["summary.html", "calibrations/s.json", "rows/s.json"])
def test_batch_refuses_an_output_that_is_a_folder_before_solving(tmp_path, folder_at):
    shutil.copy(BROAD_02, tmp_path / "s.parquet")
    (tmp_path / "out" / folder_at).mkdir(parents=True)
    refused(["batch", "s.parquet", "-o", "out"], rf"cannot write the output out/{re.escape(folder_at)}: it is a folder",
            tmp_path)     # one stderr line: no device was solved (each would be a progress line)


def test_batch_names_a_manifest_line_that_is_not_utf8(tmp_path):
    shutil.copy(BROAD_02, tmp_path / "s.parquet")
    (tmp_path / "m.csv").write_bytes(b"device_id,session\nd1,s.parquet\n\xff\xfe,x\n")
    refused(["batch", "m.csv", "-o", "out"], r"m\.csv line 3: not UTF-8", tmp_path)


@pytest.mark.parametrize("target", ["nowhere.parquet", "loop.parquet"])
def test_batch_names_a_symlink_that_leads_nowhere(tmp_path, target):
    (tmp_path / "F").mkdir()
    shutil.copy(BROAD_02, tmp_path / "F" / "a.parquet")
    os.symlink(target, tmp_path / "F" / "loop.parquet")
    refused(["batch", "F", "-o", "out"], r"F/loop\.parquet: a symbolic link that leads to no file", tmp_path)


def test_an_unreadable_input_is_named_as_unreadable(unprivileged_folder):
    """The command run by a user the input is refused to (as root, the user nobody: tests/unprivileged.py)."""
    folder, env = unprivileged_folder
    shutil.copy(BROAD_02, folder / "s.parquet")
    os.chmod(folder / "s.parquet", 0)
    refused(["batch", "s.parquet", "-o", "out"], r"s\.parquet: cannot be read: permission denied", folder, env=env)


@pytest.mark.parametrize("command", [["solve", "s.parquet"], ["observe", "s.parquet"], ["check", "s.parquet"]])
def test_an_unreadable_session_is_named_as_unreadable_not_corrupt(unprivileged_folder, command):
    """pyarrow's refusal of a file it may not open read 'cannot be read as Parquet ... the file is corrupt or not
    a Parquet file': the wrong cause."""
    folder, env = unprivileged_folder
    shutil.copy(BROAD_02, folder / "s.parquet")
    os.chmod(folder / "s.parquet", 0)
    message = refused(command, r"s\.parquet: cannot be read: permission denied", folder, env=env)
    assert "corrupt" not in message


def test_an_unreadable_calibration_is_named_as_unreadable(unprivileged_folder):
    """typer's Path arguments default to click's readable=True, which answered an unreadable file with its usage
    error (5 lines, "Path 'c.json' is not readable") before magyro read it: the CLI's paths are readable=False, so
    magyro's own reader names the file."""
    folder, env = unprivileged_folder
    write_json(folder / "c.json", good_calibration())
    os.chmod(folder / "c.json", 0)
    refused(["export", "c.json", "-f", "yaml"], r"c\.json: cannot be read: permission denied", folder, env=env)


def test_batch_into_its_own_input_folder_resumes(tmp_path):
    """batch F -o F: the summary it wrote into F is its own output, not a device, on the rerun (one solve)."""
    (tmp_path / "F").mkdir()
    shutil.copy(BROAD_02, tmp_path / "F" / "dev1.parquet")
    code, out, err = run("batch", "F", "-o", "F", cwd=tmp_path)
    assert code == 0 and (tmp_path / "F" / "summary.parquet").is_file(), err
    code, out, err = run("batch", "F", "-o", "F", cwd=tmp_path)
    assert code == 0, err
    assert "1 devices" in out and "0 solved now, 1 kept" in out


# --------------------------------------------------------------------------- watch


def test_watch_counts_absurd_values_as_bad_lines_and_saves(tmp_path):
    from magyro.live.watch import watch

    lines = ["t,gx,gy,gz,mx,my,mz"]
    lines += [f"{0.01 * i!r},0.1,0.2,0.3,{30 * math.cos(0.01 * i)!r},{30 * math.sin(0.01 * i)!r},10"
              for i in range(600)]
    lines += [f"{0.01 * i!r},1e300,1e300,1e300,1e300,1e300,1e300" for i in range(600, 800)]
    (tmp_path / "in.csv").write_text("\n".join(lines) + "\n")
    result = watch(str(tmp_path / "in.csv"), output=tmp_path / "s.parquet", idle=0.3, quiet=True,
                   predictor_mode="inline")
    assert result.saved and "200 bad" in result.summary
    from magyro.io import load_session

    assert len(load_session(tmp_path / "s.parquet").t_gyro_s) == 600


def test_watch_saves_what_it_received_when_it_fails_itself(tmp_path, monkeypatch):
    from magyro.live import monitor
    from magyro.live.watch import watch

    calls = {"n": 0}
    update = monitor.ExcitationMonitor.update

    def failing(self, final=False):
        calls["n"] += 1   # the rows' gyro never changes: held, the monitor analyses one of them; it received 300
        if len(self.session().t_gyro_s) >= 300:
            raise np.linalg.LinAlgError("Eigenvalues did not converge")
        return update(self, final)

    monkeypatch.setattr(monitor.ExcitationMonitor, "update", failing)
    rows = [f"{0.01 * i!r},0.1,0.2,0.3,30,{i % 7},10" for i in range(500)]
    (tmp_path / "in.csv").write_text("\n".join(rows) + "\n")
    with pytest.raises(RuntimeError, match="LinAlgError.*saved in"):
        watch(str(tmp_path / "in.csv"), output=tmp_path / "s.parquet", idle=0.3, quiet=True, predictor_mode="inline")
    from magyro.io import load_session

    assert len(load_session(tmp_path / "s.parquet").t_gyro_s) == 500


def test_watch_line_buffer_is_linear_and_capped():
    from magyro.live.sources import MAX_LINE_BYTES, LineParser

    parser = LineParser()
    chunk = b"1" * 65536
    start = time.perf_counter()
    for _ in range(256):   # one 16 MiB line, in the reader's chunks
        assert parser.feed(chunk) == ([], [], [])
        assert parser._tail_bytes <= MAX_LINE_BYTES
    gyro, mag, _ = parser.feed(b"\n0.0,0.1,0.2,0.3,1,2,3\n")
    assert time.perf_counter() - start < 2.0
    assert len(gyro) == 1 and len(mag) == 1 and parser.counts.bad == 1


# --------------------------------------------------------------------------- temp files of killed runs


def test_a_killed_runs_temp_file_is_removed_by_the_next_write(tmp_path):
    from magyro.io import atomic, write_text_atomically

    stale, fresh = tmp_path / ".out.json.abcd1234.tmp", tmp_path / ".out.json.efgh5678.tmp"
    stale.write_text("half")
    fresh.write_text("being written")
    os.utime(stale, (time.time() - 3600, time.time() - 3600))
    atomic._swept.discard(os.path.abspath(tmp_path))
    write_text_atomically(tmp_path / "out.json", "{}")
    assert not stale.exists() and fresh.exists() and (tmp_path / "out.json").read_text() == "{}"
