"""`magyro plan` on a base problem with an [accelerometer] (magyro/studies/plan_accelerometer.py).

One short plan for the module (45 s on paper-table1-acc, no comparison but the paper's motion, no refinement of the
gyro's search: about 12 s of CPU), measured from outside the planner: the six poses with observe's own functions on
the simulated sessions of the written file (two noise seeds, so two sways of the hand), the predicted std against
what `magyro montecarlo` computes for the file, the file through `magyro simulate`. And the plan of a base without an
accelerometer against main's (the commit this work started from), run from its own source.
"""
from __future__ import annotations

import json
import os
import re
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from magyro.studies.scenario import load_problem

DURATION_S = 45.0
BASE = "paper-table1-acc"
MAIN_COMMIT = "2ba23b4"     # main before `plan` knew the accelerometer
REPO = Path(__file__).resolve().parent.parent


@pytest.fixture(scope="module")
def acc_plan():
    from threadpoolctl import threadpool_limits

    from magyro.studies.plan import make_plan

    with threadpool_limits(limits=1):
        return make_plan(DURATION_S, base_problem=BASE, canonical=(), refine_evaluations=0)


@pytest.fixture(scope="module")
def acc_plan_file(acc_plan, tmp_path_factory):
    path = tmp_path_factory.mktemp("plan-acc") / "plan.toml"
    path.write_text(acc_plan.to_problem_toml())
    return path


@pytest.mark.slow
@pytest.mark.parametrize("seed", [0, 1])
def test_the_plan_holds_all_six_poses_as_observe_sees_them(acc_plan_file, seed):
    """On the written plan's simulated session (seed 0, and seed 1: another sway of the hand), `magyro observe`
    (`excitation.observe`) counts every pose held 2 s and gives no pose advice; counted on the samples where the
    device does not turn only (observe's g, weights and pose rule; the truth's rate), every pose is still held 2 s:
    the poses come from holds, not from turning through them."""
    from magyro.observability.excitation import observe
    from magyro.observability.gravity import (FACE_ENOUGH_S, FACES, accelerometer_information, face_seconds,
                                              missing_poses)
    from magyro.studies.motion import truth_body_rate
    from magyro.studies.simulate import simulate

    problem = load_problem(acc_plan_file)
    session, _ = simulate(problem, seed)
    observed = observe(session).accelerometer
    assert observed.rank == 12 and missing_poses(observed.face_s) == [], observed.face_s
    assert not any("Hold the device still" in a for a in observed.advice)
    _, _, W, u = accelerometer_information(session.t_acc_s, session.acc_m_s2, observed.g_reference_m_s2)
    still = np.linalg.norm(truth_body_rate(problem, session.t_acc_s), axis=1) == 0.0
    held = face_seconds(u, W * still)
    assert min(held[f] for f in FACES) >= FACE_ENOUGH_S, held


@pytest.mark.slow
def test_the_predicted_std_is_montecarlos_bound_on_the_written_plan(acc_plan, acc_plan_file):
    """The accelerometer's predicted std (table and [plan.accelerometer.predicted_std]) is what `magyro montecarlo`
    computes as its CRLB for the written file (`montecarlo.crlb_task` at seed 0): the same bound on the same session,
    so the file reads back with the plan's hand."""
    from magyro.io.toml_file import parse_toml
    from magyro.studies.crlb_accelerometer import ACC_ROWS
    from magyro.studies.montecarlo import METHODS, crlb_task, study_options

    problem = load_problem(acc_plan_file)
    task = crlb_task(problem, 0, study_options(problem, None), METHODS["nls"])
    assert task["error"] is None
    predicted = acc_plan.accelerometer.std
    assert list(predicted) == ACC_ROWS
    np.testing.assert_allclose([predicted[k] for k in ACC_ROWS], [task["values"][k] for k in ACC_ROWS], rtol=1e-9)
    written = parse_toml(acc_plan_file.read_text())["plan"]["accelerometer"]["predicted_std"]
    assert written == pytest.approx(predicted, rel=1e-12)
    assert all(np.isfinite(v) and v > 0 for v in predicted.values())


@pytest.mark.slow
def test_the_written_plan_simulates_with_its_accelerometer(acc_plan, acc_plan_file, tmp_path):
    """`magyro simulate plan.toml` writes the accelerometer's columns and its truth: the [accelerometer] section is
    the base's."""
    from typer.testing import CliRunner

    from magyro.cli import app
    from magyro.io import load_session

    out = tmp_path / "session.csv"
    result = CliRunner().invoke(app, ["simulate", str(acc_plan_file), "-o", str(out)])
    assert result.exit_code == 0, result.output
    session = load_session(out)
    assert session.acc_m_s2 is not None and session.acc_m_s2.shape == (len(session.t_gyro_s), 3)
    assert "accelerometer" in json.loads(out.with_name("session.truth.json").read_text())
    back, base = load_problem(acc_plan_file).accelerometer, load_problem(BASE).accelerometer
    for key in ("K_a", "bias_m_s2", "misalignment_euler_deg", "noise_density_ug_sqrt_hz", "g_m_s2",
                "hand_translation_m"):
        np.testing.assert_array_equal(getattr(back, key), getattr(base, key))


@pytest.mark.slow
def test_the_table_says_how_long_each_pose_is_held_and_what_it_cost(acc_plan):
    a = acc_plan.accelerometer
    text = acc_plan.table()
    held = next(line for line in text.splitlines() if line.strip().startswith("held still"))
    assert [float(v) for v in held.split()[2:]] == pytest.approx([a.held_s[f] for f in a.held_s], abs=0.051)
    assert f"{a.searched_worst_ratio:.2f} as searched, {acc_plan.worst_ratio:.2f} with the poses held" in text
    assert "K_a[0,0]" in text and "acc_misalignment_deg[2]" in text


def _normalised(text: str) -> str:
    """The plan's text without the seconds the search took (the one thing that differs from run to run)."""
    return re.sub(r"scorings in \d+ s", "scorings in N s", text)


PLAN_SCRIPT = """
import sys
from threadpoolctl import threadpool_limits
from magyro.studies.plan import make_plan
with threadpool_limits(limits=1):
    p = make_plan(20.0, max_rate_deg_s=150.0, base_problem="paper-table1", canonical=("axis-x",),
                  refine_evaluations=4)
sys.stdout.write(p.table() + "\\n=====\\n" + p.to_problem_toml())
"""


@pytest.mark.slow
def test_a_plan_without_accelerometer_is_mains(tmp_path):
    """Without an [accelerometer] the plan is what main made before this work: main's source (MAIN_COMMIT, from
    git) and this one's each plan 20 s on paper-table1, in their own process; table and file are the same text but
    for the seconds the search took."""
    try:
        archive = subprocess.run(["git", "-C", str(REPO), "archive", MAIN_COMMIT, "magyro", "problems"],
                                 capture_output=True, check=True).stdout
    except (OSError, subprocess.CalledProcessError):
        pytest.skip(f"main's source ({MAIN_COMMIT}) is not at hand: no git checkout")
    main_dir = tmp_path / "main"
    main_dir.mkdir()
    subprocess.run(["tar", "-x", "-C", str(main_dir)], input=archive, check=True)

    def run(source: Path) -> str:
        env = {**os.environ, "PYTHONPATH": str(source), "OMP_NUM_THREADS": "1"}
        out = subprocess.run([sys.executable, "-c", PLAN_SCRIPT], capture_output=True, text=True, env=env, check=True,
                             cwd=source)
        check = subprocess.run([sys.executable, "-c", "import magyro; print(magyro.__file__)"], capture_output=True,
                               text=True, env=env, check=True, cwd=source).stdout
        assert check.startswith(str(source)), check          # the source meant, not an installed magyro
        return _normalised(out.stdout)

    mine, mains = run(REPO), run(main_dir)
    assert "accelerometer" not in mine
    assert mine == mains
