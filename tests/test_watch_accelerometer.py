"""`magyro watch` with an accelerometer in the stream (issue 26: observability, taught, in watch).

The stream's lines take three more fields, `ax ay az` in m/s^2 (`t,gx,gy,gz,mx,my,mz,ax,ay,az`, or
`t,,,,,,,ax,ay,az` alone); watch then says the poses held, the rank of the accelerometer's 12 parameters and the
poses still to hold, `magyro observe`'s accelerometer section (`gravity.accelerometer_parameters`) on the data so far.

On real data: BROAD trial 02 (data/broad-02.parquet, 286 Hz, every pose but "x down" held) replayed through watch's
file input as the stream lines `magyro simulate --stream` writes; its first 3 s (the first rest, z up) alone.
With its accelerometer rows, every status is what the same recording gives without them, but for the accelerometer's
own part.
"""
from __future__ import annotations

import dataclasses
import io
import json
from unittest import mock

import numpy as np
import pytest

import magyro
from magyro.io import load_session
from magyro.live.display import accelerometer_text, plain_line
from magyro.live.monitor import ExcitationMonitor
from magyro.live.prediction import Predictor
from magyro.live.sources import LineParser
from magyro.live.stream import stream_session
from magyro.live.watch import watch
from magyro.observability.gravity import FACES, missing_poses
from test_observe_accelerometer import DATA
from test_watch import feed, staged  # noqa: F401  (staged: the fixture)

FIRST_REST_END_S = 40.0      # BROAD 02's first rest (37.1-39.9 s): the device lies z up


def replay(session, tmp_path, name: str):
    """`session` written as watch's stream lines to a file, followed by watch until idle (predictions inline, only the
    last one, on the whole recording); the result and the saved session."""
    src, out, status = tmp_path / f"{name}.csv", tmp_path / f"{name}.parquet", tmp_path / f"{name}.jsonl"
    with open(src, "w") as f:
        stream_session(session, f, speed=0)
    result = watch(str(src), output=out, status=status, idle=0.3, quiet=True, predictor_mode="inline",
                   refresh=1e6)
    return result, load_session(out), [json.loads(line) for line in status.read_text().splitlines()]


@pytest.fixture(scope="module")
def broad02():
    return load_session(DATA / "broad-02.parquet")


@pytest.fixture(scope="module")
def replayed02(broad02, tmp_path_factory):
    return replay(broad02, tmp_path_factory.mktemp("watch02"), "broad02")


@pytest.fixture(scope="module")
def replayed02_first(broad02, tmp_path_factory):
    return replay(broad02.within(broad02.t_gyro_s[0], FIRST_REST_END_S), tmp_path_factory.mktemp("watch02z"), "first")


def agrees_with(acc, section) -> None:
    """The watch's accelerometer part and observe's section: the same poses, rank, spread and advice."""
    assert acc.rank == section.rank
    for f in FACES:
        assert acc.face_s[f] == pytest.approx(section.face_s[f], rel=1e-9, abs=1e-9), f
    assert acc.spread == pytest.approx(section.spread, rel=1e-9, abs=1e-12)
    assert acc.g_reference_m_s2 == pytest.approx(section.g_reference_m_s2, rel=1e-12)
    assert acc.cells_visited == section.cells_visited
    assert acc.advice == section.advice


# --------------------------------------------------------------------------- lines


def test_lines_with_an_accelerometer():
    p = LineParser()
    gyro, mag, acc = p.feed(b"t,gx,gy,gz,mx,my,mz,ax,ay,az\n"
                            b"0.0,1,2,3,10,20,30,0.1,0.2,9.8\n"
                            b"0.01,,,,,,,0.3,0.4,9.7\n"
                            b"0.01,4,5,6,,,\n"
                            b"0.02,,,,11,21,31,,,\n"
                            b"0.02,,,,,,,1,2,\n"             # a partial accelerometer: bad
                            b"0.005,,,,,,,1,2,3\n"           # its time does not increase: out of order
                            b"0.03,1,2,3,10,20,30,1,2\n")    # nine fields: bad
    assert p.counts.header == 1 and p.counts.bad == 2 and p.counts.out_of_order == 1
    assert acc == [(0.0, 0.1, 0.2, 9.8), (0.01, 0.3, 0.4, 9.7)] and p.counts.acc == 2
    assert [r[0] for r in gyro] == [0.0, 0.01] and [r[0] for r in mag] == [0.0, 0.02]
    assert p.counts.to_dict()["acc"] == 2 and "acc" not in LineParser().counts.to_dict()


def test_stream_lines_carry_the_accelerometer_and_read_back_exactly(broad02):
    s = broad02.within(broad02.t_gyro_s[0], broad02.t_gyro_s[0] + 1.0)
    out = io.StringIO()
    assert stream_session(s, out, speed=0) == len(s.t_gyro_s) + len(s.t_mag_s) + len(s.t_acc_s)
    text = out.getvalue().splitlines()
    assert text[0] == "t,gx,gy,gz,mx,my,mz,ax,ay,az" and text[3].startswith(f"{float(s.t_acc_s[0])!r},,,,,,,")
    gyro, mag, acc = LineParser().feed(out.getvalue().encode())
    assert np.array_equal(np.array(acc)[:, 0], s.t_acc_s) and np.array_equal(np.array(acc)[:, 1:], s.acc_m_s2)
    assert np.array_equal(np.array(gyro)[:, 1:], s.gyro_rad_s) and np.array_equal(np.array(mag)[:, 1:], s.mag)


# --------------------------------------------------------------------------- without an accelerometer: as before


SUMMARY = ("magyro watch: no new data for 0.3 s; 3001 gyro, 3001 magnetometer samples; "
           "30.0 s, rank 9/12, coverage 22%; not enough yet: turn about the device's z axis, "
           "+/-90 deg; session written to DIR/out.parquet")


def fed_with_accelerometer(monitor: ExcitationMonitor, session, until_s: float):
    """`test_watch.feed`, with the session's accelerometer rows added in the same chunks."""
    g = np.column_stack([session.t_gyro_s, session.gyro_rad_s])
    m = np.column_stack([session.t_mag_s, session.mag])
    a = np.column_stack([session.t_acc_s, session.acc_m_s2])
    edges = np.arange(1, int(round(until_s / 0.5)) + 2) * 0.5 - 1e-9
    ig, im, ia = (np.searchsorted(x[:, 0], edges) for x in (g, m, a))
    out = []
    for k in range(len(edges)):
        lo = (lambda i: i[k - 1] if k else 0)
        monitor.add(g[lo(ig): ig[k]], m[lo(im): im[k]], a[lo(ia): ia[k]])
        out.append(monitor.update())
    return out


def test_the_accelerometer_adds_its_part_and_changes_nothing_else(broad02):
    """BROAD 02's first 45 s (its first rest, then turning) fed with and without its accelerometer rows: every status is the same but for the
    accelerometer's own part (its JSON key, its text after the gyro's), number for number."""
    s = broad02.within(broad02.t_gyro_s[0], broad02.t_gyro_s[0] + 45.0)
    t0 = s.t_gyro_s[0]
    s = dataclasses.replace(s, t_gyro_s=s.t_gyro_s - t0, t_mag_s=s.t_mag_s - t0, t_acc_s=s.t_acc_s - t0)
    with mock.patch("magyro.live.prediction.COST_FACTOR", 0.0):
        plain = feed(ExcitationMonitor(predictor=Predictor("inline", refresh_s=8.0)), s, chunk_s=0.5, until_s=45.0)
        both = fed_with_accelerometer(ExcitationMonitor(predictor=Predictor("inline", refresh_s=8.0)), s, 45.0)
    assert len(plain) == len(both) and any(x.accelerometer is not None for x in both)
    for x, y in zip(plain, both):
        assert x.accelerometer is None
        mine = y.to_json_dict()
        mine.pop("accelerometer", None)
        assert json.dumps(mine, default=str) == json.dumps(x.to_json_dict(), default=str)
        assert plain_line(y).startswith(plain_line(x))


def test_without_an_accelerometer_watch_saves_none(staged, tmp_path):  # noqa: F811
    src = tmp_path / "rec.csv"
    with open(src, "w") as f:
        stream_session(staged.within(0, 30.0), f, speed=0)
    assert "ax" not in src.read_text().splitlines()[0]
    result = watch(str(src), output=tmp_path / "out.parquet", idle=0.3, quiet=True, predictor_mode="inline")
    assert result.summary.replace(str(tmp_path), "DIR") == SUMMARY
    saved = load_session(tmp_path / "out.parquet")
    assert saved.acc_m_s2 is None and "acc_unit" not in saved.metadata


# --------------------------------------------------------------------------- BROAD 02 through watch


def test_the_replay_ends_with_observe_s_accelerometer_section(broad02, replayed02):
    """The whole of BROAD 02 through watch: its last status is `magyro observe`'s section, on the recording and on
    the session watch saved (which keeps ax ay az exactly)."""
    result, saved, lines = replayed02
    acc = result.status.accelerometer
    assert acc is not None and result.status.acc_samples == len(broad02.t_acc_s)
    np.testing.assert_array_equal(saved.t_acc_s, broad02.t_acc_s)
    np.testing.assert_array_equal(saved.acc_m_s2, broad02.acc_m_s2)
    assert saved.metadata["acc_unit"] == "m/s^2"
    observed = magyro.observe(broad02).accelerometer
    agrees_with(acc, observed)
    agrees_with(acc, magyro.observe(saved).accelerometer)
    assert acc.rank == 12 and missing_poses(acc.face_s) == ["-x"]
    # what it says: the poses held (observe's seconds), the rank, the pose to hold next, observe's advice
    poses = " ".join(f"{face} {observed.face_s[face]:.1f}" for face in FACES)
    assert f"accelerometer: rank 12/12, poses (s) {poses}; hold still with x down" in result.summary
    assert "with its x axis down (gravity along +x, ax = -g)" in result.summary
    assert "33994 accelerometer samples" in result.summary
    last = lines[-1]["accelerometer"]
    assert last["rank"] == 12 and last["missing_poses"] == ["-x"] and last["samples"] == len(broad02.t_acc_s)
    assert last["poses_s"]["+z"] == pytest.approx(acc.face_s["+z"], rel=1e-6)
    # the live statuses before the end (no rests given: g where the gyro turns slowest) say the same in kind
    live = [line["accelerometer"] for line in lines[:-1] if "accelerometer" in line]
    assert live and live[-1]["rank"] == 12 and live[-1]["missing_poses"] == ["-x"]


def test_the_first_rest_alone_asks_for_the_other_poses(broad02, replayed02_first):
    """BROAD 02's first 3 s (lying z up): rank 3 of 12, and watch asks for the five other poses, as observe does."""
    result, saved, _ = replayed02_first
    acc = result.status.accelerometer
    agrees_with(acc, magyro.observe(saved).accelerometer)
    assert acc.rank == 3 and missing_poses(acc.face_s) == ["+x", "-x", "+y", "-y", "-z"]
    assert acc.face_s["+z"] > 2.0
    assert "hold still with x up, x down, y up, y down, z down" in accelerometer_text(acc)
    assert "hold still with x up, x down, y up, y down, z down" in result.summary


def test_the_live_line_says_the_accelerometer_only_when_there_is_one(broad02):
    s = broad02.within(broad02.t_gyro_s[0], 45.0)
    with_acc, without = ExcitationMonitor(), ExcitationMonitor()
    rows = lambda t, x: np.column_stack([t, x])  # noqa: E731
    with_acc.add(rows(s.t_gyro_s, s.gyro_rad_s), rows(s.t_mag_s, s.mag), rows(s.t_acc_s, s.acc_m_s2))
    without.add(rows(s.t_gyro_s, s.gyro_rad_s), rows(s.t_mag_s, s.mag))
    a, b = with_acc.update(), without.update()
    assert "| accelerometer: rank 9/12, poses (s) +x 0.0" in plain_line(a)
    assert plain_line(a).startswith(plain_line(b))
    assert "accelerometer" not in plain_line(b) and "accelerometer" not in b.to_json_dict()
    assert a.to_json_dict()["accelerometer"]["rank"] == 9


def test_the_accelerometer_s_part_takes_a_bounded_share_of_the_stream(broad02):
    """Recomputed every ACC_EVERY_S of data, never sooner than ACC_COST_FACTOR times its last cost: a part that
    takes 0.5 s waits 5 s of data, so it takes at most a tenth of a live stream's time however long the recording."""
    from magyro.live import accelerometer as part

    s = broad02.within(broad02.t_gyro_s[0], 80.0)
    rows = lambda t, x: np.column_stack([t, x])  # noqa: E731
    mon = ExcitationMonitor()
    mon.add(rows(s.t_gyro_s, s.gyro_rad_s), rows(s.t_mag_s, s.mag), rows(s.t_acc_s, s.acc_m_s2))
    mon.update()
    assert len(mon.acc_part.seconds) == 1
    assert mon.acc_part.next_t >= s.t_acc_s[-1] + part.ACC_EVERY_S
    clock = iter([0.0, 0.5])     # the next recomputation "takes" 0.5 s
    mon.acc_part.clock = lambda: next(clock)
    status = mon.update(final=True)
    assert mon.acc_part.next_t == pytest.approx(s.t_acc_s[-1] + part.ACC_COST_FACTOR * 0.5)
    assert mon.acc_part.exact and status.accelerometer is mon.acc_part.gravity
    mon.update()                 # no new data, not due: the part is the exact one, kept
    assert len(mon.acc_part.seconds) == 2 and mon.acc_part.exact


def test_an_accelerometer_that_reads_nothing_does_not_stop_the_watch(broad02):
    s = broad02.within(broad02.t_gyro_s[0], 45.0)
    rows = lambda t, x: np.column_stack([t, x])  # noqa: E731
    mon = ExcitationMonitor()
    mon.add(rows(s.t_gyro_s, s.gyro_rad_s), rows(s.t_mag_s, s.mag), rows(s.t_acc_s, 0.0 * s.acc_m_s2))
    status = mon.update()
    assert status.accelerometer is None or "accelerometer" in json.dumps(status.to_json_dict(), allow_nan=False)
    assert mon.session().acc_m_s2.shape == s.acc_m_s2.shape


@pytest.mark.parametrize("most", [20000, 3000])
def test_live_it_reads_every_n_th_sample_and_says_the_same(broad02, most):
    """Past ACC_MAX_SAMPLES the live part reads every n-th sample (its cost then independent of the length; BROAD 02
    has 33994 samples: every 2nd, and with 3000 every 12th): the same rank and poses to hold, every pose's seconds
    within 2 % (or 0.1 s) of all samples' (no rests given either way)."""
    from magyro.observability.gravity import accelerometer_parameters

    rows = lambda t, x: np.column_stack([t, x])  # noqa: E731
    mon = ExcitationMonitor()
    mon.add(rows(broad02.t_gyro_s, broad02.gyro_rad_s), rows(broad02.t_mag_s, broad02.mag),
            rows(broad02.t_acc_s, broad02.acc_m_s2))
    with mock.patch("magyro.live.accelerometer.ACC_MAX_SAMPLES", most):
        live = mon.update().accelerometer
    whole = accelerometer_parameters(broad02.t_acc_s, broad02.acc_m_s2, [], broad02.t_gyro_s, broad02.gyro_rad_s)
    assert live.rank == whole.rank == 12
    assert missing_poses(live.face_s) == missing_poses(whole.face_s) == ["-x"]
    for f in FACES:
        assert live.face_s[f] == pytest.approx(whole.face_s[f], rel=0.02, abs=0.1), f
    assert live.g_reference_m_s2 == pytest.approx(whole.g_reference_m_s2, rel=1e-3)


def fed_and_observed(session, at_s: tuple[float, ...]):
    """The monitor fed `session` (its clock from 0) in 0.5 s chunks, and at each time of `at_s`: (the watch's rank, its
    rank with gravity, observe's rank, observe's with gravity) on the data so far; and the monitor."""
    t0 = session.t_gyro_s[0]
    s = dataclasses.replace(session, t_gyro_s=session.t_gyro_s - t0, t_mag_s=session.t_mag_s - t0,
                            t_acc_s=session.t_acc_s - t0)
    rows = [np.column_stack([t, x]) for t, x in ((s.t_gyro_s, s.gyro_rad_s), (s.t_mag_s, s.mag), (s.t_acc_s, s.acc_m_s2))]
    mon, seen, done = ExcitationMonitor(), {}, [0, 0, 0]
    for edge in np.arange(0.5, max(at_s) + 0.01, 0.5):
        upto = [int(np.searchsorted(r[:, 0], edge)) for r in rows]
        mon.add(*(r[a:b] for r, a, b in zip(rows, done, upto)))
        done = upto
        status = mon.update(final=edge in at_s)       # final: the accelerometer's part on all the data so far
        if edge in at_s:
            report = magyro.observe(s.within(0.0, mon.t_last))
            seen[edge] = (status.rank, status.rank_with_gravity, report.analysis.rank, report.accelerometer.gyro.rank)
    return seen, mon


@pytest.mark.parametrize("name, at_s, first", [("broad-02", (3.5, 4.5, 6.5), (8, 12)),
                                               ("broad-07", (2.5, 3.5, 4.5, 5.5), (2, 3))])
def test_watch_counts_the_gyro_s_rank_as_observe_does_and_what_gravity_adds(name, at_s, first):
    """BROAD trials 02 and 07 from their start (a rest, then turning), through the watch and through `magyro observe`
    on the same data so far: the same rank of the gyro's 12 parameters from the field, and the same with gravity
    beside it (observe's part 2). Just after trial 02's rest the field sees 8 of them and gravity the rest (12).
    Integrated from the first sample, with the noise levels of third differences and an ellipsoid fitted to the rest
    too, the watch read 12 from the field alone there, where observe reads 8; and on trial 07, whose logger repeats
    29 % of its magnetometer rows (observe's recording check drops them), 11-12 where observe reads 8 (3-4 s)."""
    seen, mon = fed_and_observed(load_session(DATA / f"{name}.parquet"), at_s)
    for t, (watch_rank, watch_with, observe_rank, observe_with) in seen.items():
        assert (watch_rank, watch_with) == (observe_rank, observe_with), (t, seen[t])
    assert seen[at_s[0]][:2] == first and seen[at_s[-1]][:2] == (12, 12)


def test_watch_reads_a_sensor_that_holds_its_readings_as_the_repair_does():
    """BROAD trial 07's magnetometer repeats 29 % of its rows: watch analyses them as the recording check's repair
    leaves them (every repeat dropped, the first of each run kept) and saves them as received."""
    from magyro.front.repairs import repair_recording
    from magyro.options import Repairs

    s = load_session(DATA / "broad-07.parquet").within(0.0, 1e9)
    repaired, _ = repair_recording(s, Repairs(restamp_bursts=False, drop_held=True, cut_saturation=False,
                                              drop_spikes=False, align_clocks=False))
    mon = ExcitationMonitor()
    step = 200
    for k in range(0, len(s.t_mag_s), step):
        mon.add(np.column_stack([s.t_gyro_s, s.gyro_rad_s])[k: k + step], np.column_stack([s.t_mag_s, s.mag])[k: k + step])
    assert len(repaired.t_mag_s) < 0.8 * len(s.t_mag_s)
    np.testing.assert_array_equal(mon.mag.view()[:, 0], repaired.t_mag_s)
    np.testing.assert_array_equal(mon.mag.view()[:, 1:], repaired.mag)
    np.testing.assert_array_equal(mon.gyro.view()[:, 1:], repaired.gyro_rad_s)
    np.testing.assert_array_equal(mon.session().mag, s.mag)          # saved as received
