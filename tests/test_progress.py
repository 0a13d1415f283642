"""Progress of long work: the library names its steps (`magyro.progress.step`), the command line shows them as one
live line on a terminal, and nothing anywhere else."""
from __future__ import annotations

import io
from pathlib import Path

import magyro
from magyro.progress import reporting, showing, step

DATA = Path(__file__).resolve().parents[1] / "data"


class Terminal(io.StringIO):
    def isatty(self) -> bool:
        return True


def test_a_solve_with_its_split_check_names_its_steps_in_order():
    steps: list[str] = []
    with reporting(steps.append):
        magyro.calibrate(magyro.load_session(DATA / "simulated-phone-module.parquet"), magyro.Options(split_check=True))
    expected = ["checking the recording", "rests, noise levels", "solving the least squares", "the uncertainty",
                "checking that the result explains", "split-half check: the first half", "split-half check: the second half"]
    found = [next(i for i, s in enumerate(steps) if s.startswith(e)) for e in expected]
    assert found == sorted(found), steps
    assert any("unknowns, IPOPT" in s for s in steps)


def test_steps_go_nowhere_without_a_reporter_and_after_the_block():
    seen: list[str] = []
    step("before")
    with reporting(seen.append):
        step("inside")
    step("after")
    assert seen == ["inside"]


def test_shown_on_a_terminal_only():
    quiet, tty = io.StringIO(), Terminal()
    with showing(stream=quiet):
        step("solving the least squares")
    assert quiet.getvalue() == ""
    with showing(stream=tty):
        step("solving the least squares")
    assert "solving the least squares" in tty.getvalue()
    off = Terminal()
    with showing(enabled=False, stream=off):
        step("solving the least squares")
    assert off.getvalue() == ""


def test_the_command_line_prints_no_progress_when_not_on_a_terminal(tmp_path, run_magyro):
    done = run_magyro("solve", DATA / "simulated-phone-module.parquet", "-o", tmp_path / "c.json")
    assert done.returncode == 0 and done.stderr == "", done.stderr


def test_batch_progress_lines_keep_whole_messages(tmp_path):
    """issue 40: `batch` progress lines cut a device's message mid-sentence (at 80 characters; the terminal's bar at
    60). Now the log form prints it whole, and the bar shortens it at a word with '...'."""
    from typer.testing import CliRunner

    from magyro.cli import app
    from magyro.progress import LAST_WIDTH, counting
    from magyro.text import shortened

    folder = tmp_path / "devices"
    folder.mkdir()
    (folder / "dev1.csv").write_text("t,gx,gy,gz\n0,0,0,0\n0.01,0,0,0\n")
    res = CliRunner().invoke(app, ["batch", str(folder), "-o", str(tmp_path / "out")])
    line = next(x for x in res.output.splitlines() if x.startswith("device 1/1 dev1"))
    assert line.endswith("(optional: ax ay az, qw qx qy qz))"), line   # the message's own end, then the line's

    message = "dev1: unusable input (devices/dev1.csv: missing column(s) mx, my, mz; found columns: t, gx, gy, gz)"
    short = shortened(message, LAST_WIDTH)
    assert short.endswith("...") and len(short) <= LAST_WIDTH and message.startswith(short[:-3])
    assert message[len(short) - 3] in " ,;:(" or message[len(short) - 4] in ",;:("   # cut at a word
    assert shortened("short enough", LAST_WIDTH) == "short enough"

    class Terminal(io.StringIO):
        def isatty(self):
            return True

    screen = Terminal()
    with counting(1, "devices", stream=screen) as tick:
        tick(1, message, alarm=True)
    import re
    shown = " ".join(re.sub(r"\x1b\[[0-9;?]*[A-Za-z]", "", screen.getvalue()).split())
    assert message in shown and short in shown   # a failure printed whole (wrapped at words), the bar shortened
