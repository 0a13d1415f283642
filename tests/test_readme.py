"""The README is a newcomer's path (issue 40): at most 150 lines, its two commands first, the bias sign before the
walk-through, and every command in it runnable.

Every `magyro ...` command of the README's code blocks is parsed by the real command line, as the shell would hand
it over (every subcommand and option known, every value of its type, nothing required missing), without running
it. The cheap ones (check, the imports, apply, export, validate) then run end to end in a temporary folder on
shipped data under the names the README uses: `session.parquet` is data/broad-02.parquet, `calib.json` the suite's
one default solve of it (conftest's broad02_acc_solved, what `magyro solve` gives), `sensor_data.csv` the shipped
x-io recording, `flight.ulg` the shipped PX4 log, the per-sensor CSVs and app exports are written as
tests/test_import_csv_files.py writes them, and `recording.bag` as tests/test_rosbag.py does (rosbags installed). Those not run say why (PARSED_ONLY); a command the README gains is run
or named there, or this fails.
"""
from __future__ import annotations

import importlib.util
import re
import shlex
import shutil
import sys
import zipfile
from pathlib import Path

import pytest
import typer
from typer.testing import CliRunner

from magyro.cli import app
from magyro.io import load_session

try:
    import tomllib
except ImportError:        # Python 3.10
    import tomli as tomllib

sys.path.insert(0, str(Path(__file__).resolve().parent))
from test_import_csv_files import phyphox_export, sensor_logger_export  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
README = ROOT / "README.md"
DATA = ROOT / "data"

MAX_LINES = 150
INSTALL_AND_SOLVE = ("python3 -m venv .venv && .venv/bin/pip install . && "
                     ".venv/bin/magyro solve data/broad-02.parquet -o calib.json")
INSTALL_AND_TEST = "python3 -m venv .venv && .venv/bin/pip install '.[test]' && .venv/bin/python -m pytest -q"
QUICK_SUBSET = 'python -m pytest -q -m "not slow and not heavy"'

SHIPPED = {"session.parquet": DATA / "broad-02.parquet", "sensor_data.csv": DATA / "wild" / "fusion" / "sensor_data.csv",
           "flight.ulg": DATA / "px4-sample-appended-multiple.ulg"}
RUN = {"check", "import csv", "import ulog", "import rosbag", "apply", "export", "validate"}   # a second or two each
PARSED_ONLY = {           # the README's commands not run here, and why
    "magyro solve data/broad-02.parquet -o calib.json": "a solve; calib.json is the suite's one solve of it",
    "magyro solve session.parquet -o calib.json --split-check": "three solves (tests/test_consistency.py)",
    "magyro observe session.parquet": "seconds of excitation analysis (tests/test_observe.py)",
    "magyro report session.parquet calib.json -o report.html": "two more solves (tests/test_report.py)",
    "magyro plan --duration 60 -o plan.toml": "a search of under a minute (tests/test_plan.py)",
    "magyro watch - -o session.parquet": "reads a live logger (tests/test_watch.py)",
    "magyro watch /dev/ttyUSB0 --baud 115200 -o session.parquet": "needs a serial port",
    "magyro simulate phone-module --stream": "a minute in real time (tests/test_watch.py runs the demo)",
    "magyro watch -": "the demo's watcher (tests/test_watch.py)",
}
NO_ROSBAGS = "magyro import rosbag recording.bag -o session.parquet"    # parsed only without rosbags to write the bag



# --------------------------------------------------------------------------- the README's commands


def code_blocks(text: str) -> list[str]:
    """The fenced code blocks' contents, in page order."""
    return re.findall(r"^```[\w-]*\n(.*?)^```", text, flags=re.S | re.M)


def shell_commands(block: str) -> list[list[str]]:
    """The simple commands of a block as the shell splits them: continuation lines joined, comments dropped,
    split at `&&` and `|`."""
    commands = []
    for line in block.replace("\\\n", " ").splitlines():
        words, command = shlex.split(line, comments=True), []
        for word in [*words, "&&"]:
            if word in ("&&", "|"):
                if command:
                    commands.append(command)
                command = []
            else:
                command.append(word)
    return commands


def magyro_commands() -> list[list[str]]:
    """Every `magyro ...` (or `.venv/bin/magyro ...`) command of the README's code blocks: its arguments."""
    found = [c[1:] for b in code_blocks(README.read_text(encoding="utf-8")) for c in shell_commands(b)
             if Path(c[0]).name == "magyro"]
    assert found, "no magyro command in the README's code blocks"
    return found


def parsed(args: list[str]):
    """The command line's context for `magyro ARGS`: parsed and converted, the command not run (a usage error
    raises, as it would exit 2 on the command line)."""
    command = typer.main.get_command(app)
    ctx = command.make_context("magyro", list(args))
    while hasattr(command, "resolve_command"):          # a group: on to the subcommand
        protected = getattr(ctx, "_protected_args", None) or getattr(ctx, "protected_args", [])
        name, command, rest = command.resolve_command(ctx, [*protected, *ctx.args])
        ctx = command.make_context(name, rest, parent=ctx)
    return ctx


def command_name(ctx) -> str:
    """`import csv`, `solve`: the subcommand's path below `magyro`."""
    names = []
    while ctx.parent is not None:
        names.insert(0, ctx.info_name)
        ctx = ctx.parent
    return " ".join(names)


def input_files(ctx) -> list[str]:
    """The files a command reads: its arguments' values ('-' is standard input)."""
    values = [ctx.params[p.name] for p in ctx.command.params if p.param_type_name == "argument"]
    return [str(v) for value in values for v in (value if isinstance(value, (list, tuple)) else [value])]


def line(args: list[str]) -> str:
    return shlex.join(["magyro", *args])


# --------------------------------------------------------------------------- the page


def test_the_readme_is_short_and_starts_with_the_two_commands():
    text = README.read_text(encoding="utf-8")
    assert len(text.splitlines()) <= MAX_LINES
    first = [c for c in code_blocks(text)[0].splitlines() if c.strip() and not c.startswith("#")]
    assert first == [INSTALL_AND_SOLVE, INSTALL_AND_TEST]
    assert text.index("```") < text.index("\n## "), "the two commands come before the first section"


def test_the_quick_subset_keeps_the_default_marker_out():
    """`-m "not slow"` alone would replace pyproject's `not heavy` and run the heaviest tests."""
    text = README.read_text(encoding="utf-8")
    assert QUICK_SUBSET in text and "-m \"not slow\"" not in text
    markers = tomllib.loads((ROOT / "pyproject.toml").read_text())["tool"]["pytest"]["ini_options"]["markers"]
    assert {"slow", "heavy"} <= {m.split(":")[0] for m in markers}


def test_the_bias_sign_comes_before_the_walk_through():
    text = README.read_text(encoding="utf-8")
    assert text.index("The bias is added, not subtracted") < text.index("## Calibrate your own device")
    assert "omega_b = K_g y + eps_b" in text


def test_every_extra_the_readme_installs_exists():
    extras = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]["optional-dependencies"]
    named = re.findall(r"pip install '\.\[(\w+)\]'", README.read_text(encoding="utf-8"))
    assert named and set(named) <= set(extras)


def test_every_link_of_the_readme_leads_to_a_file():
    links = re.findall(r"\]\(([^)#]+)\)", README.read_text(encoding="utf-8"))
    assert links and [link for link in links if not (ROOT / link).exists()] == []


# --------------------------------------------------------------------------- the commands


@pytest.mark.parametrize("args", magyro_commands(), ids=line)
def test_every_magyro_command_parses(args):
    parsed(args)


def test_the_parse_refuses_what_the_command_line_refuses():
    """The dry parse is the real one: an unknown option, a missing one and a value of the wrong type fail."""
    for args in (["solve", "session.parquet", "--no-such-option"], ["export", "calib.json"],
                 ["plan", "--duration", "a minute"], ["import", "cvs", "a.csv"]):
        with pytest.raises(Exception) as refused:
            parsed(args)
        assert getattr(refused.value, "exit_code", None) == 2, args


@pytest.fixture(scope="module")
def shipped_folder(tmp_path_factory, broad02_acc_solved):
    """The files the README's commands read, under its names (never the repository's own folder)."""
    import numpy as np
    import pandas as pd

    folder = tmp_path_factory.mktemp("readme-inputs")
    for name, path in SHIPPED.items():
        shutil.copy(path, folder / name)
    broad02_acc_solved[1].to_json(folder / "calib.json")
    table = pd.read_parquet(SHIPPED["session.parquet"]).iloc[:3000]   # per-sensor CSVs: 10 s of the trial
    for name, sensor in (("gyro.csv", "g"), ("mag.csv", "m")):
        columns = {"t": "time", f"{sensor}x": "x", f"{sensor}y": "y", f"{sensor}z": "z"}
        table[list(columns)].rename(columns=columns).to_csv(folder / name, index=False)
    export = sensor_logger_export(folder / "sensor-logger")
    with zipfile.ZipFile(folder / "sensor-logger-export.zip", "w") as archive:
        for csv in export.glob("*.csv"):
            archive.write(csv, csv.name)
    phyphox_export(folder / "phyphox-export")
    if importlib.util.find_spec("rosbags"):
        from test_rosbag import write_bag

        write_bag(folder / "recording.bag", load_session(SHIPPED["session.parquet"]), n=3000, ros=1)
    assert np.isfinite(broad02_acc_solved[1].K_g).all()
    return folder


def test_the_readme_s_commands_run_on_shipped_data(shipped_folder, tmp_path, monkeypatch):
    """The cheap commands run end to end (exit 0, their output written); every other one is in PARSED_ONLY."""
    ran, skipped = [], []
    for k, args in enumerate(magyro_commands()):
        ctx = parsed(args)
        if command_name(ctx) not in RUN or any(not (shipped_folder / f).exists() for f in input_files(ctx) if f != "-"):
            skipped.append(line(args))
            continue
        here = tmp_path / str(k)
        shutil.copytree(shipped_folder, here)
        monkeypatch.chdir(here)
        result = CliRunner().invoke(app, args)
        assert result.exit_code == 0, (line(args), result.output, result.exception)
        output = ctx.params.get("output")
        assert output is None or (here / output).stat().st_size > 0, (line(args), result.output)
        ran.append(command_name(ctx))
    bag = (shipped_folder / "recording.bag").exists()
    assert sorted(skipped) == sorted([*PARSED_ONLY, *([] if bag else [NO_ROSBAGS])]), (
        "a command of the README neither runs here nor says why not")
    assert set(ran) == RUN - ({"import rosbag"} if not bag else set())
