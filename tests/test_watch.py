"""`magyro watch` and `magyro simulate --stream` (magyro.live, magyro.cli.live; issue 16 item 1).

The staged recording: the sensors and field of problems/three-axes.toml, still for 10 s, then
+/-90 deg back and forth about the gyro x axis alone (10-25 s), y alone (25-40 s), z alone
(40-55 s), then all three axes at once (the three-axes problem's multisine) until 110 s. The
cumulative excitation therefore goes through rank 2, 6, 9 and 12, and later reaches the accuracy
targets. Timing (the monitor's cost per sample) is in benchmarks/bench_watch.py, not here.
"""
from __future__ import annotations

import dataclasses
import io
import json
import math
import os
import re
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path
from unittest import mock

import numpy as np
import pytest

import magyro
from magyro.errors import InputError
from magyro.io import load_session, write_session
from magyro.live.monitor import ExcitationMonitor
from magyro.live.prediction import GROUPS, Predictor
from magyro.live.sources import LineParser, resolve_source
from magyro.live.stream import session_lines, stream_session
from magyro.observability.gate import noise_matrix
from magyro.observability.matrix import information_integral
from magyro.studies import motion, simulate as sim
from magyro.studies.scenario import load_problem

PHASES = ((10.0, 25.0, "x"), (25.0, 40.0, "y"), (40.0, 55.0, "z"))   # one axis at a time, after a 10 s rest
EXPECTED_RANKS = (2, 6, 9, 12)      # still, then one, two, three axes turned
TURN_HZ = 0.25
CHUNK_S = 0.1                       # the monitor takes in 0.1 s of data per update (it updates every 0.05 s live)


def staged_session(duration_s: float = 110.0, seed: int = 0):
    """The staged recording (module docstring), through `magyro.studies.simulate.simulate` with its motion replaced."""
    problem = dataclasses.replace(load_problem("three-axes"), duration_s=duration_s)
    rng = np.random.default_rng(2)
    factors = [motion.Factor(np.eye(3)["xyz".index(axis)], np.array([math.pi / 2]), np.array([TURN_HZ]),
                          np.array([-2 * math.pi * TURN_HZ * start]), start, stop, 0.5)
               for start, stop, axis in PHASES]
    for axis in "xyz":
        freqs, phases, w = rng.uniform(0.05, 0.3, 4), rng.uniform(0, 2 * np.pi, 4), rng.uniform(0.5, 1.0, 4)
        factors.append(motion.Factor(np.eye(3)["xyz".index(axis)], math.radians(120.0) * w / w.sum(), freqs, phases,
                                  PHASES[-1][1], duration_s, 0.5))
    with mock.patch.object(motion, "motion_factors", lambda p: factors):   # where the truth's motion is drawn
        return sim.simulate(problem, seed)[0]


def feed(monitor: ExcitationMonitor, session, chunk_s: float = CHUNK_S, until_s: float | None = None, stop=None):
    """Feed the session in chunks of `chunk_s` seconds, updating after each; the statuses. `stop(status)` ends it."""
    g = np.column_stack([session.t_gyro_s, session.gyro_rad_s])
    m = np.column_stack([session.t_mag_s, session.mag])
    t_end = session.t_gyro_s[-1] if until_s is None else until_s
    edges = np.arange(1, int(round(t_end / chunk_s)) + 2) * chunk_s - 1e-9
    ig, im = np.searchsorted(g[:, 0], edges), np.searchsorted(m[:, 0], edges)
    out = []
    for k in range(len(edges)):
        monitor.add(g[(ig[k - 1] if k else 0): ig[k]], m[(im[k - 1] if k else 0): im[k]])
        out.append(monitor.update())
        if stop is not None and stop(out[-1]):
            break
    return out


@pytest.fixture(scope="module")
def staged():
    return staged_session()


# --------------------------------------------------------------------------- lines


def test_lines_full_split_header_bad_and_units():
    p = LineParser(gyro_unit="deg/s")
    gyro, mag, _ = p.feed(b"t,gx,gy,gz,mx,my,mz\n0.0,1,2,3,10,20,30\n0.01,180,0,0,,,\r\n0.01,,,,11,21,31\nhello\n0.02,1,2\n")
    assert p.counts.header == 1 and p.counts.bad == 2
    assert [r[0] for r in gyro] == [0.0, 0.01] and gyro[1][1] == pytest.approx(math.pi)
    assert mag == [(0.0, 10.0, 20.0, 30.0), (0.01, 11.0, 21.0, 31.0)]
    # a partial line waits for its end; a time that does not increase is skipped and counted
    gyro, mag, acc = p.feed(b"0.03,0,0,")
    assert (gyro, mag, acc) == ([], [], [])
    gyro, mag, _ = p.feed(b"1,,,\n0.01,0,0,0,,,\n0.04,nan,0,0,,,\n0.05,1,2,3,4,5,\n")
    assert [r[0] for r in gyro] == [0.03] and p.counts.out_of_order == 1 and p.counts.bad == 4
    assert p.finish() == ([], [], [])
    assert p.feed(b"0.06,0,0,0") == ([], [], []) and len(p.finish()[0]) == 1   # the last line without its newline


def test_stream_lines_interleave_and_read_back_exactly(staged):
    s = staged.within(0.0, 2.0)
    out = io.StringIO()
    assert stream_session(s, out, speed=0) == len(s.t_gyro_s) + len(s.t_mag_s)
    text = out.getvalue().splitlines()
    assert text[0] == "t,gx,gy,gz,mx,my,mz" and text[1].endswith(",,,") and text[2].startswith("0.0,,,,")
    p = LineParser()
    gyro, mag, acc = p.feed(out.getvalue().encode())
    assert acc == [] and p.counts.acc == 0
    assert np.array_equal(np.array(gyro)[:, 1:], s.gyro_rad_s) and np.array_equal(np.array(mag)[:, 1:], s.mag)


def test_stream_is_paced_by_the_time_stamps(staged):
    s = staged.within(0.0, 10.0)
    now = [0.0]
    stream_session(s, io.StringIO(), speed=4.0, clock=lambda: now[0], sleep=lambda dt: now.__setitem__(0, now[0] + dt))
    assert now[0] == pytest.approx(10.0 / 4.0, abs=0.02)
    assert [t for t, _ in session_lines(s)] == sorted(t for t, _ in session_lines(s))


def test_sources():
    assert resolve_source("-").kind == "stdin"
    assert resolve_source("/dev/ttyUSB0").kind == "serial" and resolve_source("COM3").kind == "serial"
    with pytest.raises(InputError, match="no such file"):
        resolve_source("/nonexistent/recording.csv")


def test_serial_needs_pyserial(tmp_path):
    from magyro.live.watch import watch

    try:
        import serial  # noqa: F401
        pytest.skip("pyserial is installed")
    except ImportError:
        pass
    with pytest.raises(InputError, match="pyserial"):
        watch("/dev/ttyUSB9", quiet=True, predictor_mode="inline")


# --------------------------------------------------------------------------- the monitor


def test_incremental_integral_is_the_gate_s(staged):
    """The running integral of M^T M and the noise matrix equal the gate's, computed from where the gate starts (after
    the leading rest), exactly."""
    mon = ExcitationMonitor()
    feed(mon, staged, until_s=60.0)
    assert mon.start_s > 0.5        # the staged session opens with a rest
    s = staged.within(mon.start_s, mon.t_last)
    fit = mon.fit
    assert fit is not None
    field = (s.mag - fit.h) @ fit.R.T
    info, N = mon.matrices()
    ref = information_integral(s.t_gyro_s, s.gyro_rad_s, s.t_mag_s, field)
    ref_N = noise_matrix(s.t_gyro_s, s.gyro_rad_s, s.t_mag_s, field, mon.gyro_std, mon.mag_std_unit_field)
    assert np.max(np.abs(info - ref)) < 1e-9 * np.max(np.abs(ref))
    assert np.max(np.abs(N - ref_N)) < 1e-6 * np.max(np.abs(ref_N))


def test_rank_follows_the_motion_within_a_second(staged):
    statuses = feed(ExcitationMonitor(), staged, until_s=PHASES[-1][1])
    t = np.array([s.t_s for s in statuses])
    rank = np.array([s.rank for s in statuses])
    starts = [0.0] + [start for start, _, _ in PHASES]
    ends = [start for start, _, _ in PHASES] + [PHASES[-1][1]]
    for expected, start, end in zip(EXPECTED_RANKS, starts, ends):
        reached = t[(rank == expected) & (t >= start)]
        assert reached.size, f"rank {expected} never shown after {start} s"
        assert reached[0] <= start + 1.0, f"rank {expected} shown {reached[0] - start:.2f} s after the change at {start} s"
        assert rank[np.searchsorted(t, end) - 1] == expected     # and still shown at the end of the phase
    # the instruction names the axis still missing
    at = {round(s.t_s, 2): s.instruction for s in statuses}
    assert "x axis" in at[9.99] and "y axis" in at[24.99] and "z axis" in at[39.99]
    assert 0 < statuses[-1].coverage < 1


def test_the_time_shown_is_session_time(staged):
    """Issue 24: watch shows and writes the samples' own t (the session time the saved file keeps), not the seconds
    since the first sample: a recording whose clock starts at 100 s is at 105 s after 5 s of data."""
    from magyro.live.display import plain_line

    shift_s = 100.0
    head = staged.within(0.0, 5.0)
    mon = ExcitationMonitor()
    mon.add(np.column_stack([head.t_gyro_s + shift_s, head.gyro_rad_s]),
            np.column_stack([head.t_mag_s + shift_s, head.mag]))
    status = mon.update()
    last_s = max(head.t_gyro_s[-1], head.t_mag_s[-1]) + shift_s
    assert status.t_s == pytest.approx(last_s) and status.to_json_dict()["t_s"] == pytest.approx(last_s)
    assert f"t {last_s:7.1f} s" in plain_line(status)


def test_the_plain_line_says_skipped_lines_only_when_some_were_and_how_many(staged):
    """issue 40: `watch` on a pipe ended every line with ', 1 lines skipped': the stream's header. Now a header is
    no skip; bad lines and out-of-order samples are named, each counted, singular or plural."""
    from magyro.live.display import plain_line

    head = staged.within(0.0, 2.0)
    mon = ExcitationMonitor()
    mon.add(np.column_stack([head.t_gyro_s, head.gyro_rad_s]), np.column_stack([head.t_mag_s, head.mag]))
    status = mon.update()
    p = LineParser()
    p.feed(b"t,gx,gy,gz,mx,my,mz\n0.0,1,2,3,10,20,30\n")
    assert p.counts.header == 1 and "skipped" not in plain_line(status, p.counts) and "lines" not in plain_line(status, p.counts)
    p.feed(b"hello\n0.0,1,2,3,,,\n")
    assert plain_line(status, p.counts).endswith(", skipped 1 bad line and 1 out-of-order sample")
    p.feed(b"0.01,1,2\n")
    assert plain_line(status, p.counts).endswith(", skipped 2 bad lines and 1 out-of-order sample")


LIVE_LAG_S = 1.0   # live, a prediction of the data up to t is shown at t + its cost: about 1 s on 100 s of data


def test_enough_agrees_with_observe_on_the_saved_session(staged, tmp_path):
    """The first prediction meeting every target is magyro observe's on the saved session up to that moment,
    and within 5 % of it on the session up to the moment a live watch would show it."""
    from magyro.observability.report import accuracy_rows

    predictor = Predictor("inline", refresh_s=8.0)
    mon = ExcitationMonitor(predictor=predictor)
    with mock.patch("magyro.live.prediction.COST_FACTOR", 0.0):   # predictions every 8 s of data, whatever the load
        statuses = feed(mon, staged, stop=lambda s: s.enough)
    enough = statuses[-1]
    assert enough.enough and enough.enough_at_s == enough.prediction.t_s
    mon.predictor = None
    feed(mon, staged, until_s=enough.t_s + 2 * LIVE_LAG_S)     # the recording goes on after ENOUGH
    path = tmp_path / "watched.parquet"
    write_session(mon.session(), path)
    saved = load_session(path)
    t0 = saved.t_gyro_s[0]
    for lag, rtol in ((0.0, 1e-9), (LIVE_LAG_S, 0.05)):
        cut = magyro.observe(saved.within(t0, enough.prediction.t_s + lag))   # session time, as watch shows it
        assert cut.verdict == "sufficient"
        for g, (_, values, _, target) in zip(GROUPS, accuracy_rows(cut.predicted_std, cut.targets)):
            np.testing.assert_allclose(enough.prediction.std[g], values, rtol=rtol, err_msg=f"{g}, lag {lag} s")
            assert max(values) <= target
    before = [p for p in predictor.history if p.t_s < enough.prediction.t_s]
    assert before and before[-1].verdict != "sufficient"     # the moment before, observe said not yet


README = Path(__file__).resolve().parents[1] / "README.md"


def test_the_readme_demo_reaches_enough_then_asks_for_the_rest_before_stop():
    """The README's `magyro simulate PROBLEM --stream | magyro watch -`: ENOUGH at the time the README says
    (within one prediction refresh), before the problem's end rest; ENOUGH asks for END_REST_S still, and once the
    device lies still that long it says to stop. The watcher's own predictions, inline."""
    from magyro.live.monitor import END_REST_S
    from magyro.live.prediction import REFRESH_S

    demo = re.search(r"magyro simulate (\S+) --stream \| magyro watch - +#.*?ENOUGH at about (\d+) s", README.read_text())
    assert demo, "the README's watch demo and its ENOUGH time"
    problem, said_s = load_problem(demo.group(1)), float(demo.group(2))
    session = sim.simulate(problem, 0)[0]
    mon = ExcitationMonitor(predictor=Predictor("inline"))
    with mock.patch("magyro.live.prediction.COST_FACTOR", 0.0):   # predictions every REFRESH_S of data, whatever the load
        at_enough = feed(mon, session, stop=lambda s: s.enough)[-1]
    assert at_enough.enough, "the demo never reaches ENOUGH"
    assert abs(mon.enough_at_s - said_s) <= REFRESH_S
    assert mon.enough_at_s < problem.duration_s - problem.motion.rest_end_s
    assert f"leave it still for {END_REST_S:g} s" in at_enough.instruction and "now" not in at_enough.instruction
    mon.predictor = None
    last = feed(mon, session)[-1]
    assert last.enough and last.still_s >= END_REST_S
    assert last.instruction.startswith("ENOUGH, and still for") and "stop the recording now" in last.instruction


# --------------------------------------------------------------------------- the command line


def cli_prefix() -> list[str]:
    return [sys.executable, "-m", "magyro"]


def stream_command(problem: str, speed: float) -> list[str]:
    """`magyro simulate PROBLEM --stream --speed X`."""
    return cli_prefix() + ["simulate", problem, "--stream", "--speed", str(speed)]


def wait_for_session_time(watcher, t_s: float, timeout_s: float = 120.0) -> str:
    """Read the watcher's status lines until one shows the recording at t_s or later (whatever the machine's load);
    returns the lines read."""
    deadline = time.monotonic() + timeout_s
    seen = []
    while time.monotonic() < deadline:
        line = watcher.stderr.readline()
        if not line:
            break
        seen.append(line)
        found = re.search(r"\bt\s+([0-9.]+) s", line)
        if found and float(found.group(1)) >= t_s:
            return "".join(seen)
    raise AssertionError("the watcher showed no session time of %g s: %s" % (t_s, "".join(seen)))


def env():
    return {**os.environ, "OPENBLAS_NUM_THREADS": "1"}


def test_no_samples_nothing_saved_exit_2(tmp_path):
    out = tmp_path / "s.parquet"
    res = subprocess.run(cli_prefix() + ["watch", "-", "-o", str(out), "-q"], input="t,gx,gy,gz,mx,my,mz\nnonsense\n",
                         capture_output=True, text=True, timeout=60, env=env())
    assert res.returncode == 2 and "nothing to save" in res.stderr and "1 bad" in res.stderr
    assert not out.exists()


def test_pipeline_end_to_end(tmp_path):
    out, status = tmp_path / "s.parquet", tmp_path / "st.jsonl"
    producer = subprocess.Popen(stream_command("three-axes", 0), stdout=subprocess.PIPE, env=env())
    watcher = subprocess.run(cli_prefix() + ["watch", "-", "-o", str(out), "--status", str(status), "-q"],
                             stdin=producer.stdout, capture_output=True, text=True, timeout=120, env=env())
    producer.stdout.close()
    assert producer.wait(timeout=30) == 0
    assert watcher.returncode == 0, watcher.stderr
    assert "session written" in watcher.stderr and "skipped" not in watcher.stderr   # its header is no skip
    expected, _ = sim.simulate(load_problem("three-axes"), 0)
    got = load_session(out)
    for a, b in (("t_gyro_s", "t_gyro_s"), ("gyro_rad_s", "gyro_rad_s"), ("t_mag_s", "t_mag_s"), ("mag", "mag")):
        np.testing.assert_allclose(getattr(got, a), getattr(expected, b), rtol=1e-15, atol=0)
    lines = [json.loads(line) for line in status.read_text().splitlines()]
    assert lines and all({"t_s", "rank", "coverage", "predicted_std", "enough"} <= set(d) for d in lines)
    assert lines[-1]["rank"] == 12 and lines[-1]["t_s"] == pytest.approx(60.0)
    assert set(lines[-1]["predicted_std"]) == set(GROUPS)   # the final prediction, on the whole recording


@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGTERM], ids=["SIGINT", "SIGTERM"])
def test_a_signal_mid_stream_still_saves_the_session_whole(tmp_path, sig):
    out = tmp_path / "s.csv"
    # paced 3x real time (20 s for the 60 s recording): the signal at 5 s of data comes long before the end of input
    # even on a loaded machine (at 10x the stream could end before the signal, and the watch said "end of input")
    producer = subprocess.Popen(stream_command("three-axes", 3), stdout=subprocess.PIPE, env=env())
    # Ctrl-C as in a terminal's foreground: a test run started in the background (nohup, `&`) hands its children
    # SIGINT ignored, and a Python started so keeps ignoring it
    watcher = subprocess.Popen(cli_prefix() + ["watch", "-", "-o", str(out)], stdin=producer.stdout,
                               stderr=subprocess.PIPE, text=True, env=env(),
                               preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))
    producer.stdout.close()
    try:
        seen = wait_for_session_time(watcher, 5.0)   # samples have arrived, the 60 s recording is not over
        assert watcher.poll() is None
        watcher.send_signal(sig)
        _, rest = watcher.communicate(timeout=30)
        err = seen + rest
    finally:
        producer.kill()
        producer.wait()
    assert watcher.returncode == 0, err
    assert ("interrupted" if sig == signal.SIGINT else "stopped (SIGTERM)") in err and "session written" in err
    got = load_session(out)
    expected, _ = sim.simulate(load_problem("three-axes"), 0)
    n = len(got.t_gyro_s)
    assert 200 < n < len(expected.t_gyro_s)
    np.testing.assert_allclose(got.gyro_rad_s, expected.gyro_rad_s[:n], rtol=1e-15)
    np.testing.assert_allclose(got.mag, expected.mag[: len(got.t_mag_s)], rtol=1e-15)


def test_a_file_being_written_is_followed_until_idle(tmp_path, staged):
    from magyro.live.watch import watch

    src, out = tmp_path / "rec.csv", tmp_path / "out.parquet"
    s = staged.within(0.0, 12.0)
    lines = [line for _, line in session_lines(s)]
    src.write_text("t,gx,gy,gz,mx,my,mz\n" + "".join(lines[:1000]))

    def writer():
        with open(src, "a") as f:
            for k in range(1000, len(lines), 500):
                time.sleep(0.1)
                f.write("garbage line\n" + "".join(lines[k: k + 500]))
                f.flush()

    thread = threading.Thread(target=writer)
    thread.start()
    result = watch(str(src), output=out, idle=0.6, quiet=True, predictor_mode="inline")
    text = result.summary
    assert result.saved and result.status.rank == 6     # still, then turns about x
    thread.join()
    assert "no new data for 0.6 s" in text and "session written" in text
    got = load_session(out)
    np.testing.assert_array_equal(got.gyro_rad_s, s.gyro_rad_s)
    np.testing.assert_array_equal(got.t_mag_s, s.t_mag_s)
    assert f"{(len(lines) - 1000 + 499) // 500} bad" in text
