"""The Cramer-Rao bound of the joint problem with the accelerometer (issue 26): its 12 parameters, and the gyro's.

As `crlb.py` for the gyro, the Fisher information of the joint least squares (`Options(accelerometer=True)`) at the
TRUE parameters and the TRUE attitude, the attitude states marginalised, propagated to the reported parameters by the
functions a solve uses (`information.propagate` for the gyro's and the magnetometer's, `accelerometer_result` for the
accelerometer's K_a upper triangle, bias_m_s2 and misalignment_deg). What differs is the noise of the accelerometer's
interval means: besides the white noise, the hand's acceleration. To the calibration the hand is noise whose ensemble
the simulation knows (`studies.hand.hand_translation`: per world axis a few sinusoids with frequencies uniform in the
motion's band, phases uniform, weights uniform in [0.5, 1], scaled so the axis peaks at hand_translation_m, drawn per
noise seed). Its covariance over the intervals' means is

    Sigma_hand[k, l] = sum_{j in k, j' in l} c_j c_j' R(t_j, t_j') L_j L_j'^T,     L_j = K_a^-1 C_b^a C_w^b(t_j),

c_j the interval's share of each segment start (the kernel's `cacc`), L_j the reading of a world acceleration, and
R(t, t') I_3 the hand's covariance in the world (the axes drawn alike and independently, so isotropic). R is the
ensemble's, taken from `HAND_DRAWS` draws of the hand alone (no solve): per draw its frequencies and amplitudes as
drawn, its phases averaged over exactly (each sinusoid contributes 1/2 (u u^T + v v^T), u and v its acceleration at
its phase and a quarter turn on); what that leaves out is the small dependence of the peak's scaling on the phases.

The bound is cov = (J^T Sigma^-1 J)^-1 over every residual: J the Jacobian at the truth (calibration corrections
and attitude states), Sigma identity for the whitened magnetometer, gyro and rest residuals and, for the interval
means (unweighted, m/s^2), diag(sigma_w^2 sum_j c_j^2) + Sigma_hand, dense. Everything is dense: n_x = n_theta +
3 n_int and 3 n_int accelerometer rows, fine for the simulated problems (100 s, about 800 intervals: matrices of
2400-3000 squared) and not meant for hour-long recordings. The white-noise bound (the hand still, Sigma_hand = 0)
is given beside it (`AccelerometerBound.white`), and so is what the solve's own weighting reaches with the same
hand (`independent_weights_covariance`: not a bound, the sandwich of the weights that count each interval as
independent).

What the bound means: it is the Cramer-Rao bound with the hand taken as Gaussian of its ensemble's covariance, i.e.
the covariance of the best linear (generalised least squares) estimator that knows that covariance. The real sway is
not Gaussian (a few sinusoids), and a Gaussian has the least information of any noise of its covariance, so no
linear unbiased estimator does better, while a nonlinear one might in principle. The hand is narrow-band (the
motion's band over the session: a hundred or so degrees of freedom against thousands of interval means), so an
estimator that knows its spectrum can filter most of it out: the bound with the hand is only 1.1-2.5x the white
one on paper-table1-acc. The joint NLS does not weight by it (its weights count each interval as independent, its
std adds the correlation afterwards), so its spread may exceed this bound by much more than sampling.
The ensemble's covariance was checked against 200 direct draws of the hand (not phase-averaged): the interval means'
variance and their covariance 8 intervals apart agree to 2 % on paper-table1-acc.
"""
from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import casadi as ca
import numpy as np

from magyro.front.prepare import moving_session
from magyro.nls.accelerometer import accelerometer_result, accelerometer_start, segment_start_times
from magyro.nls.grid import build_grid
from magyro.nls.information import propagate
from magyro.nls.method import NLS
from magyro.nls.problem import JointProblem
from magyro.nls.solve import default_stride
from magyro.options import Options
from magyro.result.reported import N_REPORTED, qr_split, std_from_covariance
from magyro.session import Session
from magyro.studies.crlb import truth_linearisation
from magyro.studies.hand import gravity_up_i, hand_translation, translation_derivatives
from magyro.studies.motion import truth_attitude, truth_body_attitude
from magyro.studies.scenario import Scenario

HAND_DRAWS = 100          # draws of the hand alone that make its ensemble's covariance: the bound moves < 2 % from 25 to 400 (paper-table1-acc)
HAND_SEED0 = 1_000_000    # their seeds: hand_translation(problem, HAND_SEED0 + d), apart from any study's noise seeds
UPPER = [(0, 0), (0, 1), (0, 2), (1, 1), (1, 2), (2, 2)]
ACC_ROWS = ([f"K_a[{i},{j}]" for i, j in UPPER]
            + [f"bias_m_s2[{i}]" for i in range(3)] + [f"acc_misalignment_deg[{i}]" for i in range(3)])


@dataclass
class AccelerometerBound:
    """The bound with the hand (`std`, `accelerometer_std`) and with the white noise only (`white`,
    `white_accelerometer_std`): the gyro's and magnetometer's as `crlb.cramer_rao_std` lays them out, the
    accelerometer's 12 in ACC_ROWS order."""

    std: object
    accelerometer_std: np.ndarray
    white: object
    white_accelerometer_std: np.ndarray
    covariance: np.ndarray          # the reported vector's (result.REPORTED), with the hand
    white_covariance: np.ndarray
    weighted_accelerometer_std: np.ndarray   # not a bound: the solve's weighting's spread (`independent_weights_covariance`)


def truth_accelerometer_problem(problem: Scenario, session: Session, options: Options, nls: NLS):
    """(joint problem, linearisation at the truth with the accelerometer's start there, the moving session, the
    white noise per sample): the grid as `crlb.cramer_rao_covariance`'s; the accelerometer's data on it as a solve's
    (`accelerometer_start`), its linearisation point the truth: A = C_a^m K_a, b = C_a^m eps_a, up^i re-based as the
    field is, the white noise the problem's."""
    s, _, found = moving_session(session, options)
    grid = build_grid(s.t_gyro_s, s.gyro_rad_s, s.t_mag_s, nls.stride or default_stride(s))
    lin = truth_linearisation(problem, grid.t_node_s)
    acc = problem.accelerometer
    sigma = acc.sample_std_m_s2(problem.gyro_rate_hz)
    start = accelerometer_start(session, s, grid, lin.C_m_i_nominal, lin.K0, found.segments_s, acc.g_m_s2)
    C_a_m = problem.C_b_m @ acc.C_b_a.T
    C0 = truth_attitude(problem, grid.t_node_s[:1])[0]
    start = dataclasses.replace(start, A0=C_a_m @ acc.K_a, b0=C_a_m @ acc.bias_m_s2, u0_i=C0.T @ gravity_up_i(problem),
                                g_m_s2=float(acc.g_m_s2), sigma_white_m_s2=sigma)
    lin = dataclasses.replace(lin, accelerometer=start)
    jp = JointProblem(grid, compiled=nls.compiled, estimate_time_offset=options.estimate_time_offset, accelerometer=True)
    return jp, lin, s, sigma


def hand_readout_samples(problem: Scenario, start, draws: int = HAND_DRAWS):
    """Yield, a draw at a time, G (3 n_int, m) with Sigma_hand = sum over draws of G G^T / draws: the interval means'
    readings (`start.share`-weighted over the segment starts) of each sinusoid of the draw at its phase and a
    quarter turn on (phase-averaged, weight 1/2), along each world axis. A draw without a hand (None) yields
    nothing."""
    grid = start.grid
    t = segment_start_times(grid)                                    # (n_int, stride)
    n_int, stride = t.shape
    acc = problem.accelerometer
    readout = np.linalg.solve(acc.K_a, acc.C_b_a)                    # K_a^-1 C_b^a
    L = readout @ np.swapaxes(truth_body_attitude(problem, t.ravel()), -1, -2)   # (n, 3, 3): reading of a^w
    L = L.reshape(n_int, stride, 3, 3) * start.share[:, :, None, None]
    for d in range(draws):
        tr = hand_translation(problem, HAND_SEED0 + d)
        if tr is None:
            return
        K = tr.amplitudes_m.shape[1]
        columns = []
        for k in range(K):
            one = np.zeros_like(tr.amplitudes_m)
            one[:, k] = tr.amplitudes_m[:, k]
            for quarter in (0.0, 0.5 * np.pi):
                a = translation_derivatives(dataclasses.replace(tr, amplitudes_m=one, phases_rad=tr.phases_rad + quarter),
                                            t.ravel())[1].reshape(n_int, stride, 3)   # axis e: its own sinusoid k
                # the world axis e's acceleration a_e(t) e_e, read: sum_j L_j[:, e] a_e(t_j) per interval
                columns.append(np.einsum("ksie,kse->kie", L, a).reshape(3 * n_int, 3) * np.sqrt(0.5))
        yield np.concatenate(columns, axis=1)


def hand_covariance(problem: Scenario, start, draws: int = HAND_DRAWS) -> np.ndarray:
    """Sigma_hand (3 n_int, 3 n_int), m^2/s^4: the hand's acceleration in the interval means, over its ensemble (see
    the module). Zeros without a hand."""
    n = 3 * len(start.count)
    out = np.zeros((n, n))
    count = 0
    for G in hand_readout_samples(problem, start, draws):
        out += G @ G.T
        count += 1
    return out / max(count, 1)


def accelerometer_jacobian_rows(jp: JointProblem, p: np.ndarray) -> np.ndarray:
    """(3 n_int, n_x) d (interval mean, unweighted) / d x at x = 0 (the truth): the parameters `p` made with unit
    accelerometer weights. Interval k's mean depends on the corrections and its first node (node 0 is the gauge)."""
    G, B, n_int = jp.n_theta, jp.B, jp.n_int
    data = jp.data_of(p)
    zeros = ca.DM.zeros(B, n_int)
    J_theta, J_node = jp.accelerometer_jacobian.map(n_int)(ca.DM.zeros(G), zeros, zeros, ca.DM(jp.globals_of(p)),
                                                           ca.DM(data.T))
    J_theta = np.array(J_theta).reshape(3, n_int, G).transpose(1, 0, 2)      # (n_int, 3, G)
    J_node = np.array(J_node).reshape(3, n_int, B).transpose(1, 0, 2)        # (n_int, 3, B)
    J = np.zeros((n_int, 3, jp.n_x))
    J[:, :, :G] = J_theta
    for k in range(1, n_int):
        J[k, :, G + B * (k - 1) : G + B * k] = J_node[k]
    return J.reshape(3 * n_int, jp.n_x)


def dense_information(jp: JointProblem, p: np.ndarray) -> np.ndarray:
    """J^T J (n_x, n_x), dense and symmetric, from the problem's Gauss-Newton kernels at x = 0."""
    U = np.array(ca.DM(jp.hessian_pattern, jp.hessian_values(np.zeros(jp.n_x), p)).full())
    return U + U.T - np.diag(np.diag(U))


def marginal_covariance(F: np.ndarray, n_theta: int) -> np.ndarray:
    """The corrections' block of F^-1 (the states marginalised); all inf where F is singular."""
    lam = np.linalg.eigvalsh(F)
    if lam[0] <= lam[-1] * 1e-14:
        return np.full((n_theta, n_theta), np.inf)
    return np.linalg.inv(F)[:n_theta, :n_theta]


def accelerometer_cramer_rao(problem: Scenario, session: Session, options: Options | None = None,
                             nls: NLS | None = None, draws: int = HAND_DRAWS) -> AccelerometerBound:
    """The bound of the joint problem with the accelerometer, with the hand and with the white noise only."""
    if problem.accelerometer is None:
        raise ValueError(f"problem {problem.name} has no [accelerometer]")
    options = dataclasses.replace(options or Options(), accelerometer=True)
    nls = nls or NLS()
    jp, lin, s, sigma = truth_accelerometer_problem(problem, session, options, nls)
    start = lin.accelerometer
    n_int = jp.n_int

    def params(weight):
        return jp.parameters(lin, s.mag, problem.mag_noise_std, problem.gyro_noise_density_rad_s_sqrt_hz,
                             s.t_gyro_s, s.gyro_rad_s, s.t_mag_s, problem.mag_time_offset_s, weight)

    p_rest = params(np.zeros(n_int))              # magnetometer, gyro and the rests: whitened already
    F0 = dense_information(jp, p_rest)
    p_unit = params(np.ones(n_int))
    used = np.repeat(start.count > 0, 3)
    J = accelerometer_jacobian_rows(jp, p_unit)[used]
    white = np.repeat(sigma**2 * np.sum(start.share**2, axis=1), 3)[used]
    hand = hand_covariance(problem, start, draws)[np.ix_(used, used)]
    g = jp.globals_of(p_unit)
    C0, _ = qr_split(lin.K0)

    def reported(cov_theta):
        if not np.all(np.isfinite(cov_theta)):
            return np.full((N_REPORTED, N_REPORTED), np.inf), np.full(12, np.inf)
        acc = accelerometer_result(jp, np.zeros(jp.n_theta), g, cov_theta)
        return (propagate(jp, np.zeros(jp.n_theta), g, cov_theta, C0),
                np.concatenate([[acc.std_K_a[i, j] for i, j in UPPER], acc.std_bias_m_s2, acc.std_misalignment_deg]))

    def bound(Sigma):
        Jw = np.linalg.solve(np.linalg.cholesky(Sigma), J)
        return reported(marginal_covariance(F0 + Jw.T @ Jw, jp.n_theta))

    (cov_h, acc_h), (cov_w, acc_w) = bound(np.diag(white) + hand), bound(np.diag(white))
    _, acc_weighted = reported(independent_weights_covariance(F0, J, white, hand, jp.n_theta))
    return AccelerometerBound(std_from_covariance(cov_h), acc_h, std_from_covariance(cov_w), acc_w, cov_h, cov_w,
                              acc_weighted)


def independent_weights_covariance(F0: np.ndarray, J: np.ndarray, white: np.ndarray, hand: np.ndarray,
                                   n_theta: int) -> np.ndarray:
    """The corrections' covariance of the least squares that weights each interval mean by 1 / (white + the hand's
    variance there), as the solve does (nls/accelerometer.py `hand_weights`, the hand's size taken alike on the three
    axes), when the hand's acceleration has the covariance `hand`: the sandwich F_w^-1 (F0 + J^T W Sigma W J) F_w^-1,
    F_w = F0 + J^T W J. Not a bound: what the solve's weighting gives at best (its weights from the true hand, its
    std from the true correlation), the spread to compare its actual one and its reported std with."""
    own = np.repeat(np.diag(hand).reshape(-1, 3).mean(axis=1), 3)
    W = 1.0 / (white + own)
    JW = J * W[:, None]
    F_inv = np.linalg.inv(F0 + J.T @ JW)
    return (F_inv @ (F0 + JW.T @ (np.diag(white) + hand) @ JW) @ F_inv)[:n_theta, :n_theta]
