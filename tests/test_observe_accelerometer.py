"""`magyro observe` with an accelerometer: what its 12 parameters need, and what gravity adds to the gyro's.

All on real recordings: BROAD trials 02 (rests, slow rotation about every axis) and 07 (fast, held mostly z up),
and the x-io IMU's sensor_data.csv (hand-turned, 107 s of its 135 z up), all shipped in data/. The pose test cuts
BROAD 02's accelerometer to the samples where the specific force lies within 30 deg of +z: the same recording, as
if the device had never been held otherwise.
"""
from __future__ import annotations

import dataclasses
import json
import math
from pathlib import Path

import numpy as np
import pytest

import magyro
from magyro.io import load_session
from magyro.observability.gravity import FACE_ENOUGH_S, FACES, SPREAD_ENOUGH

DATA = Path(__file__).resolve().parents[1] / "data"
SECTION = "accelerometer (gravity, a second reference vector"


def without_accelerometer(session):
    return dataclasses.replace(session, t_acc_s=None, acc_m_s2=None)


def gravity_near_plus_z(session, within_deg: float = 30.0):
    """The session with only the accelerometer samples whose reading lies within `within_deg` of +z."""
    u = session.acc_m_s2 / np.linalg.norm(session.acc_m_s2, axis=1, keepdims=True)
    keep = u[:, 2] > math.cos(math.radians(within_deg))
    return dataclasses.replace(session, t_acc_s=session.t_acc_s[keep], acc_m_s2=session.acc_m_s2[keep])


@pytest.fixture(scope="module")
def broad02():
    return load_session(DATA / "broad-02.parquet")


@pytest.fixture(scope="module")
def report02(broad02):
    return magyro.observe(broad02)


@pytest.fixture(scope="module")
def report02_plain(broad02):
    return magyro.observe(without_accelerometer(broad02))


@pytest.fixture(scope="module")
def report02_z_up(broad02):
    return magyro.observe(gravity_near_plus_z(broad02))


@pytest.fixture(scope="module")
def report07():
    return magyro.observe(load_session(DATA / "broad-07.parquet"))


@pytest.fixture(scope="module")
def report_xio(tmp_path_factory, run_magyro):
    out = tmp_path_factory.mktemp("xio") / "f.parquet"
    r = run_magyro("import", "csv", DATA / "wild" / "fusion" / "sensor_data.csv", "--gyro-unit", "deg/s",
                   "--mag-unit", "uT", "--acc-unit", "g", "-o", out)
    assert r.returncode == 0, r.stderr
    return magyro.observe(load_session(out))


def missing_poses(report) -> set[str]:
    return missing_poses_of(report.accelerometer)


def missing_poses_of(accelerometer) -> set[str]:
    return {f for f in FACES if accelerometer.face_s[f] < FACE_ENOUGH_S}


def asks_for(advice: str, face: str) -> bool:
    axis, up = face[1], face[0] == "+"
    return f"its {axis} axis {'up' if up else 'down'} (gravity along {'-' if up else '+'}{axis}" in advice


# --------------------------------------------------------------------------- without an accelerometer: as before


def test_a_session_without_accelerometer_reports_what_it_reported(report02, report02_plain):
    """The accelerometer adds a section after the table and a JSON key; the rest, verdict included, is unchanged
    (the field-only theorem stays the default number)."""
    assert report02_plain.accelerometer is None
    plain = report02_plain.table()
    assert SECTION not in plain and "accelerometer" not in plain
    with_acc = report02.table().splitlines()
    cut = next(i for i, line in enumerate(with_acc) if line.startswith(SECTION))
    assert "\n".join(with_acc[:cut]) == plain
    a, b = report02.to_dict(), report02_plain.to_dict()
    assert "accelerometer" not in b and "accelerometer" in a
    a.pop("accelerometer")
    for d in (a, b):
        d["prediction"].pop("seconds")
    assert a == b


def test_the_cli_shows_the_section_only_with_an_accelerometer(run_magyro, tmp_path):
    r = run_magyro("observe", DATA / "broad-02.parquet", "-o", tmp_path / "r.json")
    assert r.returncode == 0, r.stderr
    assert SECTION in r.stdout and "gyro with gravity" in r.stdout
    report = json.loads((tmp_path / "r.json").read_text())
    assert report["schema"] == "magyro.observability/1"
    acc = report["accelerometer"]
    assert acc["parameters"]["rank"] == 12 and acc["gyro_with_gravity"]["rank"] == 12
    assert set(acc["poses"]) == set(FACES)
    r = run_magyro("observe", DATA / "simulated-phone-module.parquet", "-o", tmp_path / "s.json")
    assert r.returncode == 0, r.stderr
    assert "accelerometer" not in r.stdout
    assert "accelerometer" not in json.loads((tmp_path / "s.json").read_text())


# --------------------------------------------------------------------------- what the accelerometer needs


def test_broad02_shows_gravity_from_every_side(report02):
    """Trial 02 turns about every axis with rests between: all 12 accelerometer parameters excited, gravity spread
    over most of the sphere; the one short pose (x down, under 2 s) is the one the advice asks for."""
    a = report02.accelerometer
    assert a.rank == 12 and a.condition < 20
    assert a.spread > 0.3 and a.sphere_fraction > 0.8
    assert 9.7 < a.g_reference_m_s2 < 9.95
    assert missing_poses(report02) == {"-x"}
    assert len(a.advice) == 1 and asks_for(a.advice[0], "-x")
    assert not any(asks_for(a.advice[0], f) for f in FACES if f != "-x")
    json.dumps(report02.to_dict(), allow_nan=False)


def test_gravity_only_near_plus_z_asks_for_the_five_other_poses(report02_z_up):
    """BROAD 02 with only its z-up accelerometer samples: the z reading barely changes, so the response to z cannot
    be told from the bias (rank 9, the null direction A[:,z] against b) and the advice names the five poses missing
    and the z axis."""
    a = report02_z_up.accelerometer
    assert a.rank == 9
    weakest = a.directions[0]
    assert not weakest[2] and weakest[4].startswith("0.71 A[:,z] - 0.70 b")
    assert a.spread < 0.01 < SPREAD_ENOUGH and np.argmax(np.abs(a.spread_weakest)) == 2
    assert missing_poses(report02_z_up) == {"+x", "-x", "+y", "-y", "-z"}
    poses = a.advice[0]
    assert all(asks_for(poses, f) for f in ("+x", "-x", "+y", "-y", "-z")) and not asks_for(poses, "+z")
    assert "along z" in a.advice[1] and "z axis points up and down" in a.advice[1]
    # the gyro's part: the field's theorem and verdict do not move
    assert report02_z_up.rank == 12 and a.gyro.rank_field_only == 12


def test_broad07_held_z_up_asks_for_the_sides(report07):
    """Trial 07 (fast turns, the device kept mostly z up): only the z-up pose is held."""
    a = report07.accelerometer
    assert missing_poses(report07) == {"+x", "-x", "+y", "-y", "-z"}
    assert all(asks_for(a.advice[0], f) for f in ("+x", "-x", "+y", "-y", "-z"))
    assert a.spread < 0.2 and a.sphere_fraction < 0.7


def test_xio_recording_never_upside_down(report_xio):
    """The x-io IMU's recording: the sides held, never z down, and gravity's z component hardly varies."""
    a = report_xio.accelerometer
    assert missing_poses(report_xio) == {"-z"}
    assert asks_for(a.advice[0], "-z")
    assert a.spread < SPREAD_ENOUGH and np.argmax(np.abs(a.spread_weakest)) == 2
    assert any("along z" in x for x in a.advice)


# --------------------------------------------------------------------------- what gravity adds to the gyro


@pytest.mark.parametrize("name", ["report02", "report07", "report_xio"])
def test_gravity_adds_information_to_the_gyro(name, request):
    """Gravity's M added to the field's: never fewer excited directions, more information along each of the
    field's weakest, and the field-only numbers those of the theorem (the report's own rank and condition)."""
    report = request.getfixturevalue(name)
    g = report.accelerometer.gyro
    assert g.rank_field_only == report.rank and g.condition_field_only == report.condition
    assert g.rank >= g.rank_field_only and g.rank_gravity_only == 12
    assert len(g.weakest) == 3 and all(w.information_gain > 1.05 for w in g.weakest)
    assert not any(w.rescued for w in g.weakest)   # nothing to rescue: the field alone excites all 12
    assert 0.0 < g.rotation_about_field < 1.0 and 0.0 < g.rotation_about_gravity < 1.0
    # Europe: the field dips some 65 deg, so its line is about 25 deg from gravity's
    assert 10 < g.field_gravity_angle_deg < 35
    json.dumps(report.to_dict(), allow_nan=False)


@pytest.fixture(scope="module")
def report02_first_rest(broad02):
    return magyro.observe(broad02.within(37.1, 39.9))


def test_at_rest_gravity_sees_the_bias_along_the_field(report02_first_rest):
    """BROAD 02's first rest (37.1-39.9 s, before the movement): the field sees the gyro bias across it (rank 2),
    gravity across itself (2), both together the whole bias (3); the direction gravity rescues is the bias along
    the field."""
    r = report02_first_rest
    g = r.accelerometer.gyro
    assert (r.rank, g.rank_field_only, g.rank_gravity_only, g.rank) == (2, 2, 2, 3)
    assert len(g.weakest) == 10                     # every direction the field leaves unexcited
    rescued = [w for w in g.weakest if w.rescued]
    assert rescued
    v = max(rescued, key=lambda w: w.snr_gravity).vector
    assert np.sum(v[9:] ** 2) > 0.95               # the bias, no column of K
    field = np.mean(r.field_directions, axis=0)
    assert abs(v[9:] @ field) / (np.linalg.norm(v[9:]) * np.linalg.norm(field)) > 0.95
    assert "RESCUED by gravity" in r.table()
    # the accelerometer at rest: one pose, b alone is seen
    assert r.accelerometer.rank == 3 and set(missing_poses(r)) == {"+x", "-x", "+y", "-y", "-z"}


def test_at_the_start_of_the_motion_two_reference_vectors_reach_full_rank_first(broad02):
    """BROAD 02's rest and the first 1.6 s of its motion: the field alone excites 8 of the 12 gyro parameters,
    gravity alone 8, both together all 12."""
    g = magyro.observe(broad02.within(37.1, 41.5)).accelerometer.gyro
    assert (g.rank_field_only, g.rank_gravity_only, g.rank) == (8, 8, 12)
    assert sum(w.rescued for w in g.weakest) == 4
    assert g.condition < g.condition_field_only / 10


WILD = Path(__file__).resolve().parents[2] / "shared" / "data" / "wild"   # as tests/test_wild_corpus.py finds it


@pytest.mark.skipif(not (WILD / "imu_tools").is_dir(), reason=f"the corpus of real recordings ({WILD}) is absent")
def test_turning_about_the_vertical_only_gravity_sees_none_of_it(run_magyro, tmp_path):
    """imu_tools' Phidgets IMU lying upside down and turned about the vertical (2017 bag): gravity stays along +z in
    the body (the "z down" pose, nothing else), so its own M sees none of the turning and cannot reach full rank."""
    out = tmp_path / "p.parquet"
    r = run_magyro("import", "rosbag", WILD / "imu_tools" / "imutools-2017-phidgets_imu_upside_down.bag", "-o", out)
    assert r.returncode == 0, r.stderr
    a = magyro.observe(load_session(out)).accelerometer
    assert missing_poses_of(a) == {"+x", "-x", "+y", "-y", "+z"}
    assert a.rank == 3 and a.directions[0][4].startswith("0.71 A[:,z] + 0.71 b")
    assert a.gyro.rotation_about_gravity > 0.95 and a.gyro.rank_gravity_only < 12


def test_the_figure_draws_gravity_beside_the_field(report02, report02_plain):
    pytest.importorskip("matplotlib")
    from magyro.observability.plot import report_figure

    def texts(report):
        fig = report_figure(report)
        sphere = fig.axes[0]
        legend = sphere.get_legend()
        panel = next(ax for ax in fig.axes if ax.texts)       # the text panel
        return ([t.get_text() for t in legend.get_texts()] if legend else []), panel.texts[0].get_text()

    legend, text = texts(report02)
    assert any(t.startswith("specific force (up), accelerometer") for t in legend)
    assert "accelerometer: rank 12 of 12" in text and "x axis down" in text
    legend, text = texts(report02_plain)
    assert legend == [] and "accelerometer" not in text


# --------------------------------------------------------------------------- an uncalibrated accelerometer


def through_mems_errors(session):
    """The session with its accelerometer read through the scale, non-orthogonality and bias errors of
    problems/paper-table1-acc.toml's (a MEMS part: scale 1.2, -1.5, 1.8 %, bias 0.15, -0.25, 0.2 m/s^2): f = K_a y + eps
    read backwards. BROAD's accelerometer is calibrated (|f| at its rests within 0.15 % of g); a board's is not."""
    from magyro.studies.scenario import load_problem

    acc = load_problem("paper-table1-acc").accelerometer
    K_a, eps = np.asarray(acc.K_a), np.asarray(acc.bias_m_s2)
    return dataclasses.replace(session, acc_m_s2=(session.acc_m_s2 - eps) @ np.linalg.inv(K_a).T)


def test_an_uncalibrated_accelerometer_holds_the_same_poses(broad02, report02):
    """Observe reads stillness against the size the accelerometer reads still in each direction
    (`gravity.expected_size`), not against the rests' g: through a MEMS part's errors, BROAD 02 reads 9.46-10.24 m/s^2
    still depending on the pose, and against g alone its x-down and y-up poses counted 65 % and 67 % of their
    calibrated seconds. Every pose keeps its seconds to within 5 %, and the same pose is missing."""
    degraded = magyro.observe(through_mems_errors(broad02)).accelerometer
    calibrated = report02.accelerometer
    for face in FACES:
        assert degraded.face_s[face] == pytest.approx(calibrated.face_s[face], rel=0.05), face
    assert missing_poses_of(degraded) == missing_poses(report02)
    assert degraded.rank == calibrated.rank
