"""Every still counts (issue 39): the still detector, the unchanged path without stills, the accelerometer with
the stills of a pose recording."""
from __future__ import annotations

import dataclasses
import itertools

import numpy as np
import pytest

from magyro import calibrate, so3
from magyro.front.rests import find_rests
from magyro.errors import InputError
from magyro.front.stills import MIN_STILL_S, Stills, distinct_poses, find_stills
from magyro.options import Options
from magyro.result.calibration import Calibration
from magyro.studies.hand import truth_acceleration
from magyro.studies.scenario import Motion, Turn, load_problem
from magyro.studies.simulate import simulate

HOLD_S, TURN_S = 4.0, 3.0


def turns_motion(turns: list) -> Motion:
    return Motion(kind="turns", seed=0, axes=(), amplitude_deg=np.zeros(0), band_hz=(0.05, 0.5), components=1,
                  rest_start_s=0.0, rest_end_s=0.0, ramp_s=1.0, initial_euler_deg=np.zeros(3), turns=tuple(turns))


def pose_turns(n_turns: int, seed: int) -> list:
    """A hold, then `n_turns` times a turn (random axis, 90-150 deg) and a hold."""
    rng = np.random.default_rng(seed)
    turns = [Turn(None, 0.0, HOLD_S)]
    for _ in range(n_turns):
        axis = rng.standard_normal(3)
        turns += [Turn(axis / np.linalg.norm(axis), float(rng.uniform(90, 150)), TURN_S), Turn(None, 0.0, HOLD_S)]
    return turns


def icosahedron() -> np.ndarray:
    p = (1 + 5 ** 0.5) / 2
    v = np.array([[0, s1, s2 * p] for s1 in (-1, 1) for s2 in (-1, 1)], dtype=float)
    v = np.concatenate([v, np.roll(v, 1, axis=1), np.roll(v, 2, axis=1)])
    return v / np.linalg.norm(v, axis=1)[:, None]


def twelve_pose_turns(seed: int) -> list:
    """The body z up, then the 12 icosahedron gravity directions in a seeded order, each held HOLD_S."""
    poses = np.concatenate([[[0.0, 0.0, 1.0]], icosahedron()[np.random.default_rng(seed).permutation(12)]])
    turns = [Turn(None, 0.0, HOLD_S)]
    for d_from, d_to in zip(poses[:-1], poses[1:]):
        axis = np.cross(d_to, d_from)
        if np.linalg.norm(axis) < 1e-9:
            axis = np.cross(d_from, [1.0, 0.0, 0.0] if abs(d_from[0]) < 0.9 else [0.0, 1.0, 0.0])
        angle = float(np.degrees(np.arccos(np.clip(d_from @ d_to, -1, 1))))
        turns += [Turn(axis / np.linalg.norm(axis), angle, TURN_S), Turn(None, 0.0, HOLD_S)]
    return turns


def pose_problem(name: str, turns: list, hand_while_turning: bool = True):
    base = load_problem(name)
    acc = dataclasses.replace(base.accelerometer, hand_while_turning=hand_while_turning)
    return dataclasses.replace(base, motion=turns_motion(turns), duration_s=sum(t.seconds for t in turns),
                               accelerometer=acc)


def test_the_detector_finds_every_held_pose_between_the_end_rests_and_how_long_each_is_held():
    problem = pose_problem("phone-module-acc", pose_turns(4, seed=3))
    session, _ = simulate(problem, 3)
    found = find_stills(session, find_rests(session))
    assert len(found.segments_s) == 3                       # 5 holds: the first and last are the end rests
    held = np.array([b - a for a, b in found.segments_s])
    assert np.all((held > HOLD_S - 1.0) & (held <= HOLD_S)), held
    starts = np.array([a for a, _ in found.segments_s])
    assert np.allclose(starts, HOLD_S + TURN_S + (HOLD_S + TURN_S) * np.arange(3), atol=0.5)
    assert found.poses == 5


def test_the_hand_while_turning_leaves_the_held_poses_still_and_moves_the_turns():
    problem = pose_problem("phone-module-acc", pose_turns(2, seed=4))
    t_s = np.linspace(0.0, problem.duration_s, 4001)
    hand = np.linalg.norm(truth_acceleration(problem, t_s, 4), axis=1)
    holding = (t_s % (HOLD_S + TURN_S)) < HOLD_S
    assert np.all(hand[holding] == 0.0)
    assert np.max(hand[~holding]) > 0.05
    swaying = pose_problem("phone-module-acc", pose_turns(2, seed=4), hand_while_turning=False)
    assert np.max(np.linalg.norm(truth_acceleration(swaying, t_s, 4), axis=1)[holding]) > 0.01


def test_hand_while_turning_is_read_from_the_problem_file_and_must_be_true_or_false():
    from magyro.io.toml_file import read_toml
    from magyro.studies.scenario import parse_problem, resolve_problem_path

    raw = read_toml(resolve_problem_path("phone-module-acc"))
    assert parse_problem(raw).accelerometer.hand_while_turning is False
    raw["accelerometer"]["hand_while_turning"] = True
    assert parse_problem(raw).accelerometer.hand_while_turning is True
    raw["accelerometer"]["hand_while_turning"] = "yes"
    with pytest.raises(InputError, match="hand_while_turning"):
        parse_problem(raw)


def test_a_device_turning_all_along_has_no_still():
    problem = load_problem("phone-module-acc")
    session, _ = simulate(dataclasses.replace(problem, duration_s=30.0), 1)
    found = find_stills(session, find_rests(session))
    assert found.segments_s == [] and found.seconds == 0.0


def test_distinct_poses_are_gravity_directions_more_than_twenty_degrees_apart():
    tilt = lambda deg: np.array([np.sin(np.radians(deg)), 0.0, np.cos(np.radians(deg))])
    assert distinct_poses(np.array([tilt(0), tilt(10), tilt(25), tilt(180)])) == 3
    assert distinct_poses(np.array([d for d in itertools.repeat(tilt(5), 4)])) == 1
    assert MIN_STILL_S >= 2.0


def without_timings(d):
    if isinstance(d, dict):
        return {k: without_timings(v) for k, v in d.items()
                if k not in ("total_seconds", "stills") and not (k == "seconds" and "iterations" in d)}
    if isinstance(d, list):
        return [without_timings(x) for x in d]
    return d


@pytest.mark.slow
def test_a_recording_without_middle_stills_calibrates_bit_for_bit_as_with_the_stills_off():
    problem = load_problem("phone-module-acc")
    session, _ = simulate(dataclasses.replace(problem, duration_s=40.0), 2)
    on = calibrate(session, Options(accelerometer=True))
    off = calibrate(session, Options(accelerometer=True, stills=False))
    assert on.stills is not None and on.stills.segments_s == []
    assert without_timings(on.to_dict()) == without_timings(off.to_dict())   # the same machine, the same path
    assert off.stills is None and "stills" not in off.to_dict()
    assert Calibration.from_json(on.to_json()).stills == on.stills


def test_a_stills_entry_that_is_none_is_refused_naming_it():
    for bad in ({"segments_s": [[1.0]]}, {"segments_s": "x"}, {"poses": 2.5}, {"seconds": "3"}):
        with pytest.raises(InputError, match="stills"):
            Stills.from_dict(bad)
    assert Stills.from_dict({"segments_s": [[1, 4]], "seconds": 3, "poses": 2}) == Stills([(1.0, 4.0)], 3.0, 2)


def map_error_ppm(K, eps, K_true, eps_true, g_m_s2: float) -> float:
    """The worst error of the calibrated specific force over 26 directions, ppm of g."""
    directions = np.array([v for v in itertools.product((-1, 0, 1), repeat=3) if any(v)], dtype=float)
    f = g_m_s2 * directions / np.linalg.norm(directions, axis=1)[:, None]
    y = np.linalg.solve(K_true, (f - eps_true).T).T
    return float(1e6 * np.max(np.linalg.norm(y @ np.asarray(K).T + eps - f, axis=1)) / g_m_s2)


@pytest.mark.slow
def test_the_stills_of_a_twelve_pose_recording_make_the_accelerometer_better_and_it_stays_within_its_std():
    problem = pose_problem("phone-module-acc", twelve_pose_turns(seed=1))
    session, _ = simulate(problem, 1)
    truth = problem.accelerometer
    errors = {}
    for stills in (False, True):
        cal = calibrate(session, Options(accelerometer=True, stills=stills))
        a = cal.accelerometer
        errors[stills] = map_error_ppm(a.K_a, a.bias_m_s2, truth.K_a, truth.bias_m_s2, truth.g_m_s2)
    assert errors[True] < errors[False], errors
    assert "stills between the end rests: 11," in cal.table() and "13 distinct poses" in cal.table()
    assert cal.to_dict()["stills"]["count"] == 11
    iu = np.triu_indices(3)
    d_deg = np.rad2deg(so3.log_so3(a.C_b_a.T @ truth.C_b_a))     # C_b_a(true) = C_b_a(est) Exp(d)
    z = np.concatenate([((a.K_a - truth.K_a) / np.where(a.std_K_a > 0, a.std_K_a, 1.0))[iu],
                        (a.bias_m_s2 - truth.bias_m_s2) / a.std_bias_m_s2, d_deg / a.std_misalignment_deg])
    assert np.max(np.abs(z)) < 4.0, z
