"""`magyro plan` and the "turns" motion kind (issue 16, item 2).

The turns kind: its parse errors, its body rate against its attitude, its rests. The plan: made once per module for
60 s at the paper motion's 121 deg/s with a short refinement (about 25 s of CPU), then the targets: issue 24's, every
gyro parameter's predicted std at most 0.8x that of the paper's motion from each of 6 start poses (not reached:
benchmarks/plan_start_poses.py prints the table), and issue 16's, 30 simulated runs of the written problem (about
10 s with 2 jobs) whose actual spread is within 15 % of the predicted std (benchmarks/bench_plan.py prints it).
"""
from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from magyro import so3
from magyro.errors import InputError
from magyro.io.toml_file import parse_toml
from magyro.studies.scenario import PROBLEMS_DIR, load_problem, parse_problem
from magyro.studies.simulate import sample_times, truth_attitude, truth_body_attitude, truth_body_rate, truth_rate_m

TURNS = [
    {"rest_s": 1.0},
    {"axis": [1, 0, 0], "angle_deg": 180, "seconds": 2.0},
    {"rest_s": 0.5},
    {"axis": [0, 1, 1], "angle_deg": -90, "seconds": 1.5},
    {"axis": [0.2, -0.5, 0.8], "angle_deg": 360, "seconds": 3.0},
    {"axis": [0, 0, 1], "angle_deg": 45, "seconds": 0.7},
]


def _raw(turns=None, duration=12.0, **motion):
    raw = parse_toml((PROBLEMS_DIR / "paper-table1.toml").read_text())
    raw["problem"]["duration_s"] = duration
    raw["motion"] = {"kind": "turns", "initial_euler_deg": [5.0, -10.0, 30.0],
                     "turns": [dict(t) for t in (TURNS if turns is None else turns)], **motion}
    return raw


def _turns_problem(**kw):
    return parse_problem(_raw(**kw), source="turns-test")


# --------------------------------------------------------------------------- the "turns" kind


def test_turns_parse():
    p = _turns_problem()
    steps = p.motion.turns
    assert [s.is_rest for s in steps] == [True, False, True, False, False, False]
    np.testing.assert_allclose(steps[3].axis, np.array([0, 1, 1]) / math.sqrt(2))
    assert steps[3].angle_deg == -90.0 and steps[4].peak_rate_deg_s == pytest.approx(225.0)


@pytest.mark.parametrize("edit,needle", [
    (lambda r: r["motion"]["turns"][1].update(axis=[1, 0]), "axis must be a list of 3"),
    (lambda r: r["motion"]["turns"][1].update(axis=[0, 0, 0]), "non-zero"),
    (lambda r: r["motion"]["turns"][1].update(angle_deg=0), "angle_deg must not be 0"),
    (lambda r: r["motion"]["turns"][1].update(angle_deg="90"), "angle_deg must be a finite number"),
    (lambda r: r["motion"]["turns"][1].update(seconds=-1.0), "seconds must be positive"),
    (lambda r: r["motion"]["turns"][1].update(second=1.0), r"turns\[1\]: unknown key"),
    (lambda r: r["motion"]["turns"][1].pop("seconds"), r"missing key\(s\) \['seconds'\]"),
    (lambda r: r["motion"]["turns"][0].update(axis=[1, 0, 0]), "a rest has rest_s only"),
    (lambda r: r["motion"]["turns"][0].update(rest_s=0), "rest_s must be positive"),
    (lambda r: r["motion"]["turns"].append(3), "must be a table"),
    (lambda r: r["motion"].update(turns=[]), "non-empty list"),
    (lambda r: r["motion"].update(turns={"rest_s": 1}), "non-empty list"),
    (lambda r: r["motion"].update(turns=[{"rest_s": 1.0}]), "only rests"),
    (lambda r: r["motion"].pop("turns"), "needs turns"),
    (lambda r: r["motion"].update(amplitude_deg=[1.0]), "do not apply to kind \"turns\""),
    (lambda r: r["motion"].update(kind="euler"), "turns is for kind \"turns\" only"),
    (lambda r: r["problem"].update(duration_s=8.0), "longer than duration_s"),
    (lambda r: r["motion"]["turns"][1].update(seconds=0.05), "not be resolved"),
    (lambda r: r.update(extra={"a": 1}), "unknown section"),
    (lambda r: r.update(plan=3), r"\[plan\] must be a table"),
    (lambda r: r["gyro"].update(colour="red"), r"\[gyro\]: unknown key"),
])
def test_turns_bad_input_is_a_plain_input_error(edit, needle):
    raw = _raw()
    edit(raw)
    with pytest.raises(InputError, match=needle):
        parse_problem(raw, source="turns-test")


def test_plan_section_is_informational():
    raw = _raw()
    raw["plan"] = {"anything": 1, "predicted_std": {"K_g[0,0]": 1e-4}}
    assert parse_problem(raw).motion.kind == "turns"


def test_turns_rate_integrates_to_the_attitude():
    """Integrating the analytic body rate (exact exponential steps of 0.5 ms, the rate at each step's middle)
    gives the analytic attitude to 1e-6 rad over the whole motion; in the m frame too."""
    p = _turns_problem()
    dt = 5e-4
    t = np.arange(0.0, 12.0 + dt / 2, dt)
    C = truth_body_attitude(p, t)
    steps = so3.exp_so3(truth_body_rate(p, t[:-1] + dt / 2) * dt)
    Ci = C[0].copy()
    worst = 0.0
    for k in range(len(steps)):
        Ci = Ci @ steps[k]
        if k % 20 == 19:
            worst = max(worst, float(np.linalg.norm(so3.log_so3(Ci.T @ C[k + 1]))))
    assert worst < 1e-6
    # the m frame: dC_m^i/dt = C_m^i (w^m x), by central differences
    tt = np.random.default_rng(0).uniform(0.0, 12.0, 300)
    h = 1e-4
    fd = so3.log_so3(np.swapaxes(truth_attitude(p, tt), 1, 2) @ truth_attitude(p, tt + h)) / h
    np.testing.assert_allclose(fd, truth_rate_m(p, tt + h / 2), atol=1e-6, rtol=0)


def test_turns_pose_rate_and_rests():
    p = _turns_problem()
    C0 = so3.euler_to_dcm([5.0, -10.0, 30.0])
    after = C0 @ so3.exp_so3(np.pi * np.array([1.0, 0, 0]))
    # still in the rests: before, between and after the turns (and before t = 0, after the end)
    for a, b, C in [(-1.0, 1.0, C0), (3.0, 3.5, after)]:
        t = np.linspace(a, b, 50)
        np.testing.assert_array_equal(truth_body_rate(p, t), 0.0)
        np.testing.assert_allclose(truth_body_attitude(p, t), np.broadcast_to(C, (50, 3, 3)), atol=1e-14)
    t_end = np.linspace(1 + 2 + 0.5 + 1.5 + 3.0 + 0.7, 13.0, 50)
    np.testing.assert_allclose(truth_body_rate(p, t_end), 0.0, atol=1e-15, rtol=0)   # 8.7 s: end of a turn
    end = after
    for st in p.motion.turns[3:]:
        end = end @ so3.exp_so3(math.radians(st.angle_deg) * st.axis)
    np.testing.assert_allclose(truth_body_attitude(p, t_end), np.broadcast_to(end, (50, 3, 3)), atol=1e-12)
    # the rate is continuous and along the turn's axis, peaking at 1.875 angle / seconds half way
    w = truth_body_rate(p, sample_times(1000.0, 12.0))
    assert np.abs(np.diff(w, axis=0)).max() < 0.01
    np.testing.assert_allclose(truth_body_rate(p, [2.0])[0], [1.875 * np.pi / 2.0, 0, 0], rtol=1e-12)


# --------------------------------------------------------------------------- the plan


TARGET_RATE_DEG_S = 121.0      # the paper motion's own peak rate (issue 24)
TEST_REFINEMENT = 10           # refinement evaluations here (the command's default: plan.REFINE_EVALUATIONS)


@pytest.fixture(scope="module")
def plan():
    """One plan for the whole module: 60 s at the paper's 121 deg/s, one canonical comparison, a short refinement;
    BLAS on one thread as the command line runs it (on a busy machine its threads only wait for each other)."""
    from threadpoolctl import threadpool_limits

    from magyro.studies.plan import make_plan

    with threadpool_limits(limits=1):
        return make_plan(60.0, max_rate_deg_s=TARGET_RATE_DEG_S, canonical=("three-axes",),
                         refine_evaluations=TEST_REFINEMENT)


@pytest.fixture(scope="module")
def plan_file(plan, tmp_path_factory):
    path = tmp_path_factory.mktemp("plan") / "plan.toml"
    path.write_text(plan.to_problem_toml())
    return path


@pytest.mark.slow
@pytest.mark.xfail(strict=True, reason="issue 24's target is not reached: the best plan found predicts up to about "
                                       "1.1-1.5x the paper motion's std on some bias, K_g[0,1] or misalignment from "
                                       "some start pose (benchmarks/plan_start_poses.py prints the table)")
def test_plan_beats_the_paper_motion_from_every_start_pose(plan):
    """Issue 24's target: at 60 s and the paper motion's peak rate of 121 deg/s, every gyro parameter's predicted std
    at most 0.8x that of the paper's motion started from the same pose, from each of the 6 start poses."""
    assert len(plan.start_poses) == 6 and all(len(r) == 12 for r in plan.ratio_by_pose)
    assert plan.worst_ratio <= 0.8, plan.pose_table()


@pytest.mark.slow
def test_plan_scores_are_those_of_each_start_pose_alone(plan):
    """The search's shared computation from all poses (crlb.cramer_rao_at_poses) gives what one bound a pose gives:
    the plan's and the paper motion's std from two of the poses, each computed on its own session, and the worst
    ratio printed is the largest of them."""
    from magyro.studies.crlb import with_start_pose
    from magyro.studies.plan_scoring import gyro_std

    for k in (1, 4):
        pose = plan.start_poses[k][1]
        alone = gyro_std(with_start_pose(plan.problem(), pose))
        reference = gyro_std(with_start_pose(plan.reference.scenario, pose))
        assert alone == pytest.approx(plan.pose_std[k], rel=1e-8)
        assert reference == pytest.approx(plan.pose_reference_std[k], rel=1e-8)
    assert plan.worst_ratio == max(max(r.values()) for r in plan.ratio_by_pose)
    assert f"at most {plan.worst_ratio:.2f}x" in plan.table()


@pytest.mark.slow
def test_plan_is_a_motion_a_hand_can_do(plan):
    turns = plan.turns
    assert turns[0].is_rest and turns[0].seconds >= 1.0 and turns[-1].is_rest and turns[-1].seconds >= 1.0
    assert sum(st.seconds for st in turns) == pytest.approx(60.0)
    assert max(st.peak_rate_deg_s for st in turns) <= TARGET_RATE_DEG_S + 1e-9
    for st in turns:
        if not st.is_rest:
            assert abs(st.angle_deg) in (90.0, 180.0, 360.0)
            assert np.sum(np.abs(st.axis) > 1e-9) in (1, 2, 3)
    text = plan.table()
    assert "turn about the device's" in text and "plan/paper" in text and "three-axes" in text
    assert plan.reference.std is not None and "band x" in plan.reference.how
    for name, pose in plan.start_poses:          # the table names every start pose with its worst ratio
        assert any(line.split()[:1] == name.split()[:1] and f"[{', '.join(f'{v:g}' for v in pose)}]" in line
                   for line in text.splitlines())


@pytest.mark.slow
def test_plan_file_reads_back_as_the_plan(plan, plan_file):
    p = load_problem(plan_file)
    assert p.motion.kind == "turns" and p.duration_s == 60.0
    assert len(p.motion.turns) == len(plan.turns)
    raw = parse_toml(plan_file.read_text())
    assert raw["plan"]["predicted_std"] == pytest.approx(plan.std)
    w = truth_body_rate(p, sample_times(p.gyro_rate_hz, p.duration_s))
    assert np.rad2deg(np.linalg.norm(w, axis=1)).max() <= TARGET_RATE_DEG_S + 1e-6
    poses = raw["plan"]["start_poses"]
    assert list(poses) == [name for name, _ in plan.start_poses]
    assert [poses[name]["max_ratio"] for name in poses] == pytest.approx([max(r.values()) for r in plan.ratio_by_pose])
    assert raw["plan"]["max_ratio_over_start_poses"] == pytest.approx(plan.worst_ratio)


@pytest.mark.slow
def test_monte_carlo_of_the_plan_matches_its_predicted_std(plan, plan_file):
    """The issue's target: 30 simulated runs of the written plan (`magyro montecarlo plan.toml --runs 30 --jobs 2`,
    about 10 s) have an actual spread within 15 % of the predicted std: the mean over the 12 gyro parameters of
    actual / predicted in [0.85, 1.15] (from 30 runs alone, if the prediction were exact, that mean falls within
    about [0.89, 1.10] 99 % of the time: `std_ratio_interval`)."""
    from magyro.studies.montecarlo import run_montecarlo
    from magyro.studies.plan import GYRO_ROWS

    result = run_montecarlo(load_problem(plan_file), runs=30, jobs=2)
    nls = result.methods["nls"]
    assert nls.succeeded == 30
    predicted = np.array([plan.std[name] for name in GYRO_ROWS])
    np.testing.assert_allclose([result.crlb[name] for name in GYRO_ROWS], predicted, rtol=1e-6)  # the same bound
    ratio = np.array([nls.row(name).std for name in GYRO_ROWS]) / predicted
    assert 0.85 <= float(np.mean(ratio)) <= 1.15, dict(zip(GYRO_ROWS, ratio.round(3)))


def test_std_ratio_interval_is_the_sampling_error_of_a_std():
    from magyro.studies.plan import std_ratio_interval

    low, high = std_ratio_interval(np.eye(12), 30, level=0.99)          # 12 independent: narrow
    assert 0.87 < low < 0.93 and 1.05 < high < 1.11    # 0.99 -+ 2.58 x 0.13 / sqrt(12)
    low1, high1 = std_ratio_interval(np.ones((12, 12)), 30, level=0.99)  # fully correlated: one std's spread
    assert low1 < 0.8 and high1 > 1.2


def test_one_session_serves_every_start_pose():
    """crlb.cramer_rao_at_poses equals cramer_rao_covariance on each pose's own simulated session."""
    from magyro.studies.crlb import cramer_rao_at_poses, cramer_rao_covariance, with_start_pose
    from magyro.studies.simulate import simulate

    problem = _turns_problem(duration=12.0)
    problem = dataclasses.replace(problem, mag_time_offset_s=0.004)      # the lag shifts the field samples too
    poses = [[5.0, -10.0, 30.0], [90.0, 0.0, 0.0], [-150.0, 60.0, -120.0]]
    jacobians: dict = {}
    for shared, pose in zip(cramer_rao_at_poses(problem, poses, jacobians=jacobians), poses):
        alone = with_start_pose(problem, pose)
        np.testing.assert_allclose(shared, cramer_rao_covariance(alone, simulate(alone, 0)[0]), rtol=1e-7, atol=0)
    assert len(jacobians) == 3                                         # one propagation Jacobian a pose


def test_the_paper_motion_starts_at_the_start_pose_already_turning():
    """The reference of `magyro plan` (plan_scoring.PAPER_MOTION, docs/spec.md): no rests, each angle relative to its
    value at t = 0, a peak body rate of about 121 deg/s at 60 s on the paper's sensors."""
    from magyro.studies.crlb import with_start_pose
    from magyro.studies.plan_scoring import paper_motion, peak_rate_deg_s

    reference = with_start_pose(dataclasses.replace(paper_motion(load_problem("paper-table1")), duration_s=60.0),
                                [30.0, -20.0, 100.0])
    np.testing.assert_allclose(truth_body_attitude(reference, [0.0])[0], so3.euler_to_dcm([30.0, -20.0, 100.0]),
                               atol=1e-12)
    assert np.rad2deg(np.linalg.norm(truth_body_rate(reference, [0.0])[0])) > 10.0
    assert 115.0 < peak_rate_deg_s(reference) < 127.0


# --------------------------------------------------------------------------- the command


@pytest.fixture()
def plan_app():
    import typer

    from magyro.cli.simulation import plan_command

    app = typer.Typer()
    app.callback()(lambda: None)
    app.command("plan")(plan_command)
    return app


@pytest.mark.parametrize("args,needle", [
    (["--duration", "-5"], "--duration must be a positive number"),
    (["--duration", "2"], "--duration must be at least"),
    (["--duration", "60", "--max-rate", "0"], "--max-rate must be a positive number"),
    (["--duration", "60", "--gyro-noise", "-0.1"], "--gyro-noise must be a positive number"),
    (["--duration", "60", "--base", "no-such-problem"], "not found"),
    (["--duration", "60", "-o", "/no/such/folder/plan.toml"], "plan.toml"),
])
def test_plan_command_bad_input_exits_2_with_one_message(plan_app, args, needle):
    from typer.testing import CliRunner

    result = CliRunner().invoke(plan_app, ["plan", *args, "-q"])
    assert result.exit_code == 2, result.output
    lines = [line for line in result.output.splitlines() if line.strip()]
    assert len(lines) == 1 and lines[0].startswith("magyro: ") and needle in lines[0], result.output


def test_the_start_pose_is_an_instruction():
    """A start pose as an instruction (the table gives the base problem's as an example of one)."""
    from magyro import so3
    from magyro.studies.plan import start_pose_instruction

    assert start_pose_instruction(so3.euler_to_dcm([0, 0, 0])).endswith("+z axis pointing up and its +y axis toward "
                                                                         "magnetic north")
    assert "+y axis pointing up and its -z axis toward magnetic north" in start_pose_instruction(so3.euler_to_dcm([90, 0, 0]))
    assert "+x axis toward magnetic north" in start_pose_instruction(so3.euler_to_dcm([0, 0, 90]))
    assert "41 deg from north" in start_pose_instruction(so3.euler_to_dcm([5, -10, 40]))
