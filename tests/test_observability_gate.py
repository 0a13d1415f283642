"""The observability gate (paper's theorem) on the shipped motions, in the API and the CLI.

With M = [y_g^T (x) (m^m x), m^m x], the integral of M^T M has rank 2 when the device
is still (m x has rank 2), and each gyro axis that turns adds the 3 entries of its
column of K to the observable set: one axis 6, two axes 9, three axes 12.
"""
from __future__ import annotations

import dataclasses
import json
import re

import numpy as np
import pytest

from magyro import calibrate
from magyro.errors import ObservabilityError
from magyro.front.prepare import prepare
from magyro.io import write_session
from magyro.observability.gate import FLOOR_FACTOR, WELL_CONDITIONED
from magyro.options import Options
from magyro.studies.scenario import load_problem
from magyro.studies.simulate import simulate

SEED = 11
# problem -> (rank the theorem predicts, gyro axes the motion turns)
THEOREM = {
    "static": (2, ""),
    "axis-x": (6, "x"),
    "axis-y": (6, "y"),
    "axis-z": (6, "z"),
    "two-axes": (9, "xy"),
    "three-axes": (12, "xyz"),
    "paper-table1": (12, "xyz"),
}
FAILING = [name for name, (rank, _) in THEOREM.items() if rank < 12]
PASSING = [name for name, (rank, _) in THEOREM.items() if rank == 12]


def gate_rank(session) -> int:
    """The rank the gate reports: from the ObservabilityError, or from prepare() when it passes."""
    try:
        return prepare(session, Options()).analysis.rank
    except ObservabilityError as e:
        assert e.report is not None, "ObservabilityError without its report"
        return e.report.rank


def responses_named(message: str) -> set[str]:
    """Gyro axes whose response (column of K) the message calls unobservable."""
    return set(re.findall(r"\b([xyz])-axis response", message))


def rotation_advice_axes(message: str) -> set[str]:
    """Axes in the advice sentence 'Rotate the device about its ... axis ...'."""
    m = re.search(r"rotate the device about its ([^.]*)", message, flags=re.IGNORECASE)
    assert m, f"no rotation advice in: {message}"
    return set(re.findall(r"\b([xyz])[ -]axis", m.group(1)))


@pytest.mark.parametrize("name", list(THEOREM))
def test_gate_rank_matches_the_theorem(name):
    session, _ = simulate(load_problem(name), SEED)
    assert gate_rank(session) == THEOREM[name][0]


@pytest.mark.parametrize("name", FAILING)
def test_calibrate_refuses_and_names_the_unexcited_axes(name):
    session, _ = simulate(load_problem(name), SEED)
    with pytest.raises(ObservabilityError) as info:
        calibrate(session)
    err = info.value
    assert err.exit_code == 3
    assert err.report.rank == THEOREM[name][0] and not err.report.full_rank
    message = str(err)
    assert "\n" not in message
    turned = set(THEOREM[name][1])
    unexcited = set("xyz") - turned
    assert responses_named(message) == unexcited, message
    if turned:
        assert rotation_advice_axes(message) == unexcited, message
    else:  # still: turn about all three axes
        assert re.search(r"all three", message), message


@pytest.mark.parametrize("name", PASSING)
def test_gate_passes_three_axis_motion_with_margin(name):
    """Not just over the line: the weakest direction holds far more than noise, and no direction lags far behind."""
    analysis = prepare(simulate(load_problem(name), SEED)[0], Options()).analysis
    assert analysis.rank == 12
    assert np.min(analysis.signal_to_noise) > 10 * FLOOR_FACTOR  # 550 (three-axes), 1200 (paper-table1)
    assert analysis.condition < WELL_CONDITIONED                 # 50 (three-axes), 10 (paper-table1)


@pytest.mark.parametrize("name", FAILING)
def test_cli_exits_3_with_the_message_and_writes_nothing(name, tmp_path, run_magyro, assert_plain_failure):
    session, _ = simulate(load_problem(name), SEED)
    path = tmp_path / f"{name}.parquet"
    write_session(session, path)
    out = tmp_path / "calib.json"
    message = assert_plain_failure(run_magyro("solve", path, "-o", out), 3)
    assert responses_named(message) == set("xyz") - set(THEOREM[name][1]), message
    assert not out.exists()


# --------------------------------------------------------------------------- --force


def noisy_gyro_mostly_one_axis():
    """A session the gate must refuse although its ellipsoid is well determined.

    No shipped problem is both: the single/two-axis motions leave the field directions
    on circles (no unique ellipsoid), the others are full rank. So paper-table1's sensors
    with a poor gyro (0.5 deg/s/sqrt(Hz)), 40 s at 50 Hz, turned through 150 deg about x
    while tilting up to 60 deg about y: the field sweeps a wide band of the sphere (the
    ellipsoid fits), but the gyro's z rate (adot_x sin a_y) stays within the noise floor.
    """
    p = load_problem("paper-table1")
    motion = dataclasses.replace(p.motion, axes=("x", "y"), amplitude_deg=np.array([150.0, 60.0]))
    problem = dataclasses.replace(p, name="noisy-gyro-x-tilt-y", duration_s=40.0, gyro_rate_hz=50.0,
                                  mag_rate_hz=50.0, gyro_noise_density_deg_s_sqrt_hz=0.5, motion=motion)
    return simulate(problem, SEED)


@pytest.mark.slow
def test_force_solves_a_rank_deficient_session(tmp_path, run_magyro, assert_plain_failure):
    session, truth = noisy_gyro_mostly_one_axis()
    rank = prepare(session, Options(force=True)).analysis.rank  # the ellipsoid fits: no error here
    assert rank < 12
    path = tmp_path / "weak.parquet"
    write_session(session, path)
    out = tmp_path / "calib.json"

    message = assert_plain_failure(run_magyro("solve", path, "-o", out), 3)
    assert f"rank {rank} of 12" in message and "--force" in message
    assert "z" in responses_named(message), message
    assert not out.exists()

    forced = run_magyro("solve", path, "-o", out, "--force")
    assert forced.returncode == 0, forced.stderr
    calib = json.loads(out.read_text())
    assert calib["observability"]["rank"] == rank  # the file says the solve was forced past the gate
    # and its std stays honest: the truth within 4 reported sigma
    iu = np.triu_indices(3)
    z = (np.array(calib["gyro"]["K_g"]) - np.array(truth["gyro"]["K_g"]))[iu] / np.array(calib["std"]["K_g"])[iu]
    assert np.all(np.abs(z) <= 4.0), z
    z = (np.array(calib["gyro"]["bias_deg_s"]) - truth["gyro"]["bias_deg_s"]) / np.array(calib["std"]["bias_deg_s"])
    assert np.all(np.abs(z) <= 4.0), z
