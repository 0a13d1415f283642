"""The Cramer-Rao bound of the joint problem with the accelerometer (magyro.studies.crlb_accelerometer) and
`magyro montecarlo` with it."""
from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from magyro import calibrate
from magyro.nls.method import NLS
from magyro.nls.reduction import reduce_hessian
from magyro.options import Options
from magyro.studies import montecarlo as mc
from magyro.studies import crlb_accelerometer as ca_
from magyro.studies.crlb import cramer_rao_covariance, euler_std_deg
from magyro.result.reported import std_from_covariance
from magyro.studies.montecarlo_values import std_values
from magyro.studies.scenario import load_problem
from magyro.studies.simulate import simulate

pytestmark = pytest.mark.slow


@pytest.fixture(scope="module")
def problem():
    return load_problem("paper-table1-acc")


@pytest.fixture(scope="module")
def session(problem):
    return simulate(problem, 0)[0]


@pytest.fixture(scope="module")
def bound(problem, session):
    return ca_.accelerometer_cramer_rao(problem, session, draws=25)


def acc_std(acc) -> np.ndarray:
    return np.concatenate([[acc.std_K_a[i, j] for i, j in [(0, 0), (0, 1), (0, 2), (1, 1), (1, 2), (2, 2)]],
                           acc.std_bias_m_s2, acc.std_misalignment_deg])


def test_the_dense_white_information_is_the_problems_own(problem, session):
    """With the white noise only, the dense J^T Sigma^-1 J (the accelerometer's rows from its own Jacobian kernel,
    placed on the corrections and each interval's first node) is the information the solve's kernels give with
    the interval means weighted 1 / sqrt(sigma^2 sum c^2), attitudes eliminated by the sparse LDL."""
    options = Options(accelerometer=True)
    jp, lin, s, sigma = ca_.truth_accelerometer_problem(problem, session, options, NLS())
    start = lin.accelerometer

    def params(weight):
        return jp.parameters(lin, s.mag, problem.mag_noise_std, problem.gyro_noise_density_rad_s_sqrt_hz,
                             s.t_gyro_s, s.gyro_rad_s, s.t_mag_s, problem.mag_time_offset_s, weight)

    white = sigma**2 * np.sum(start.share**2, axis=1)
    weight = np.where(start.count > 0, 1.0 / np.sqrt(np.where(start.count > 0, white, 1.0)), 0.0)
    p = params(weight)
    own = np.linalg.inv(reduce_hessian(jp.hessian_values(np.zeros(jp.n_x), p), jp.n_theta, jp.B).information)
    used = np.repeat(start.count > 0, 3)
    J = ca_.accelerometer_jacobian_rows(jp, params(np.ones(jp.n_int)))[used]
    F = ca_.dense_information(jp, params(np.zeros(jp.n_int))) + J.T @ (J / np.repeat(white, 3)[used][:, None])
    dense = ca_.marginal_covariance(F, jp.n_theta)
    assert np.sqrt(np.diag(dense)) == pytest.approx(np.sqrt(np.diag(own)), rel=1e-6)


def test_a_still_hand_gives_the_white_bound(problem, session):
    still = dataclasses.replace(problem, accelerometer=dataclasses.replace(problem.accelerometer, hand_translation_m=0.0))
    b = ca_.accelerometer_cramer_rao(still, simulate(still, 0)[0], draws=5)
    assert np.array_equal(b.accelerometer_std, b.white_accelerometer_std)
    assert np.array_equal(b.covariance, b.white_covariance)


@pytest.mark.heavy   # a solve and the bound of a still hand: 45 s, in .ci/run's second pass
def test_a_device_turned_without_moving_reaches_the_white_bound(problem):
    """Turned about itself (no hand translation), the accelerometer's interval means carry the white noise alone and
    the solve weights them by it (`accelerometer.hand_detected`): its reported std is the bound. Counting the
    attitude's own small error as hand had kept the weights at a third of the white noise's and the std at
    1.2-1.5x the bound (80 seeds: the actual spread too, 1.25-1.55x)."""
    still = dataclasses.replace(problem, accelerometer=dataclasses.replace(problem.accelerometer, hand_translation_m=0.0))
    session = simulate(still, 0)[0]
    bound = ca_.accelerometer_cramer_rao(still, session, draws=5)
    reported = acc_std(calibrate(session, Options(accelerometer=True)).accelerometer)
    assert reported / bound.white_accelerometer_std == pytest.approx(np.ones(12), abs=0.05)


def test_the_hand_only_raises_the_bound(bound):
    """Sigma_hand is positive semi-definite, so the information with it is no larger: every std at least the white
    one (to rounding)."""
    assert np.all(np.isfinite(bound.accelerometer_std)) and np.all(bound.white_accelerometer_std > 0)
    assert np.all(bound.accelerometer_std >= bound.white_accelerometer_std * (1 - 1e-9))
    assert np.all(np.diag(bound.covariance) >= np.diag(bound.white_covariance) * (1 - 1e-9) - 1e-300)


def test_the_bound_is_below_the_solves_reported_std(problem, session, bound):
    """The joint NLS is a weighted least squares that counts the hand's intervals as independent; by Gauss-Markov its
    covariance is no smaller than the generalised least squares' that knows the hand's covariance, which is this
    bound. Its reported std estimates that covariance (measured 2.5-4x the bound on paper-table1-acc): it must not
    come out below the bound."""
    cal = calibrate(session, Options(accelerometer=True))
    assert np.all(bound.accelerometer_std < acc_std(cal.accelerometer))


def test_the_gyro_bound_without_the_accelerometer_is_crlb_py(problem, session):
    """Off (Options() on a problem with an [accelerometer]) montecarlo's CRLB is crlb.py's, bit for bit."""
    options = Options()
    task = mc.crlb_task(problem, 0, options, NLS())
    cov = cramer_rao_covariance(problem, session, options, NLS())
    expected = std_values(std_from_covariance(cov), options.estimate_time_offset)
    expected.update({f"euler_deg[{i}]": float(v) for i, v in enumerate(euler_std_deg(problem.C_b_m, cov))})
    assert task["error"] is None and task["values"] == expected and "white" not in task


@pytest.mark.heavy   # two solves with the accelerometer and its bound: 32 s, in .ci/run's second pass
def test_montecarlo_gains_the_accelerometers_rows(problem):
    result = mc.run_montecarlo(problem, 2, jobs=1)
    nls = result["nls"]
    rows = {r.name: r for r in nls.rows}
    for name in ca_.ACC_ROWS:
        r = rows[name]
        assert r.n == 2 and np.isfinite(r.crlb) and r.crlb > 0
        assert r.std_over_crlb == pytest.approx(r.std / r.crlb, rel=1e-12)
        assert result.crlb_white[name] <= r.crlb * (1 + 1e-9)
    d = result.to_dict()
    assert set(ca_.ACC_ROWS) <= set(d["crlb"]["white_std"]) and "accelerometer_targets" in d["methods"]["nls"]
    assert "target accelerometer std_over_crlb" in result.table()
