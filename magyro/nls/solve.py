"""The solve: linearisation point, the joint problem built on its grid, IPOPT with warm re-solves.

    1. linear gyro estimate (paper eq. 13) at the best magnetometer lag -> K0, eps0
    2. nominal attitude by integrating the gyro with K0, eps0
    3. the joint least squares (`magyro.nls.problem.JointProblem`), IPOPT; re-solved
       warm (at most twice) when the time offset moved the gyro look-up or the
       magnetometer noise proved different from the estimate (robust
       variance-component step)
"""
from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np

from magyro import so3
from magyro.front import noise
from magyro.front.initial import linear_gyro_estimate, with_time_offset
from magyro.front.prepare import Prepared
from magyro.nls.grid import STRIDES, Grid, build_grid, typical_segment_s
from magyro.nls.method import NLS
from magyro.options import Options
from magyro.observability.gate import unexcited_directions
from magyro.nls.accelerometer import (accelerometer_start, hand_detected, solved_hand_weights, specific_force_excess,
                                      still_hand_weights)
from magyro.nls.interval import N_GLOBAL, TIME_OFFSET_SCALE_S, data_layout
from magyro.nls.problem import JointProblem, Linearisation
from magyro.errors import InputError, ObservabilityError
from magyro.result.reported import mirror_is_credible, qr_split
from magyro.session import HOLE_FACTOR, Session, hole_steps, runs_of_true

MIN_NODE_RATE_HZ = 8.0   # attitude nodes per second at least (strides 12 and 4 agree: benchmarks/stride_agreement.py)
MAX_PASSES = 3
NOISE_RESCALE_TOLERANCE = 0.2     # re-solve when the robust residual scale is off by more than this
TIME_OFFSET_RELOOK_S2 = 1e-5      # re-solve when tau * (tau - tau0) exceeds this (s^2): the rotation
                                  # error of the gyro look-up at t - tau0/2 scales with it (1 ms at 10 ms)
CHI2_3DOF_MEDIAN = noise.CHI2_3DOF_MEDIAN


def stretch_bounds(t_s: np.ndarray) -> list[tuple[int, int]]:
    """[a, b) sample ranges of the hole-free stretches of a record."""
    cuts = np.flatnonzero(hole_steps(t_s)) + 1
    edges = np.concatenate([[0], cuts, [len(t_s)]])
    return list(zip(edges[:-1], edges[1:]))


def nominal_attitudes(session: Session, K0, eps0, t_node_s) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(C_m^i at the nodes, stretch of each node, node inside a hole): the gyro corrected by K0, eps0,
    integrated over each hole-free stretch of the gyro record on its own (never across a hole); each
    stretch starts at I. A node inside a hole takes the attitude of the last gyro sample before it.
    """
    t, y = session.t_gyro_s, session.gyro_rad_s
    w = y @ K0.T + eps0
    q = np.empty((len(t), 4))   # quaternions, turned into matrices at the nodes only (a twelfth of the samples)
    stretch = np.empty(len(t), dtype=int)
    for k, (a, b) in enumerate(stretch_bounds(t)):
        q[a:b] = integrated_like_body_rates(t[a:b], w[a:b])
        stretch[a:b] = k
    i = np.clip(np.searchsorted(t, t_node_s, side="right") - 1, 0, len(t) - 1)
    ahead = t_node_s - t[i]
    in_hole = ahead > HOLE_FACTOR * np.median(np.diff(t))
    ahead = np.where(in_hole, 0.0, ahead)   # no extrapolation into a hole
    return so3.quat_to_dcm(q[i]) @ so3.exp_so3(w[i] * ahead[:, None]), stretch[i], in_hole


def integrated_like_body_rates(t_s: np.ndarray, omega_rad_s: np.ndarray) -> np.ndarray:
    """The unit quaternions whose matrices `so3.integrate_body_rates` gives, multiplied in its order (its
    log-depth prefix product over the whole stretch): the linearisation point is then the same bit for bit, and
    with it IPOPT's path (the blocked product of `so3.integrated_quaternions`, 3x faster, moved two of Table I's 50
    solves by 1.2e-6 and 1.7e-6 of their std through rounding). Only the matrices are saved: made at the nodes."""
    dt = np.diff(t_s)[:, None]
    wa, wb = omega_rad_s[:-1], omega_rad_s[1:]
    steps = so3.exp_quat(0.5 * (wa + wb) * dt + (dt**2 / 12.0) * np.cross(wa, wb))
    return so3.cumulative_quat_product(np.concatenate([np.array([[1.0, 0.0, 0.0, 0.0]]), steps]))


def aligned_stretches(C_nodes: np.ndarray, stretch: np.ndarray, in_hole: np.ndarray, field_m_nodes: np.ndarray,
                      on_sample: np.ndarray, t_node_s: np.ndarray):
    """(C_m^i at the nodes with node 0 = I, m^i): the stretches after the first joined to it.

    Across a hole the gyro says nothing, so each later stretch is turned by the
    smallest rotation that makes its first measured field direction agree with
    m^i (found on the first stretch); its rotation about m^i stays the
    previous stretch's, a gauge the calibration does not depend on. The nodes
    inside a hole turn evenly from the attitude before it to the one after.
    """
    C = np.einsum("ji,njk->nik", C_nodes[0], C_nodes)
    first = stretch == stretch[0]
    m_i = initial_field(C[first & on_sample], field_m_nodes[first & on_sample])
    for k in np.unique(stretch[~first]):
        nodes = np.flatnonzero(stretch == k)
        start = nodes[on_sample[nodes]][0] if on_sample[nodes].any() else nodes[0]
        guess = C[nodes[0] - 1]               # as if nothing turned across the hole
        relative = np.einsum("ji,njk->nik", C_nodes[start], C_nodes[nodes])   # the stretch from its start node
        measured = field_m_nodes[start] / np.linalg.norm(field_m_nodes[start])
        turn = so3.rotation_between(guess.T @ m_i, measured)
        C[nodes] = (guess @ turn.T) @ relative
    for a, b in runs_of_true(in_hole):
        before, after = C[max(a - 1, 0)], C[min(b + 1, len(C) - 1)]
        share = (t_node_s[a : b + 1] - t_node_s[max(a - 1, 0)]) / (t_node_s[min(b + 1, len(C) - 1)] - t_node_s[max(a - 1, 0)])
        C[a : b + 1] = before @ so3.exp_so3(share[:, None] * so3.log_so3(before.T @ after))
    return C, m_i


def initial_field(C_nodes, field_m_nodes, seconds_n: int = 100) -> np.ndarray:
    """The unit field m^i implied by the first nodes' attitudes and calibrated field."""
    m = np.einsum("nij,nj->ni", C_nodes[:seconds_n], field_m_nodes[:seconds_n]).mean(axis=0)
    return m / np.linalg.norm(m)


def default_stride(session: Session) -> int:
    """Segments per attitude node: the largest of the few STRIDES that keeps MIN_NODE_RATE_HZ nodes a second.

    Segments run between the boundaries of `grid.segment_starts` (every magnetometer sample and gyro time),
    a typical (median) segment apart. Over an interval the attitude only carries the integrated gyro, so
    fewer nodes cost no accuracy (paper-table1 at 100 Hz and BROAD trial 02 at strides 12 and 4:
    benchmarks/stride_agreement.py, its record quoted in docs/how-it-works.md) and save memory and time: the nodes set the size of the Hessian and
    of IPOPT's linear algebra. The choice is from a fixed set so that the kernels, which depend on the
    stride only, are few and installed with magyro: 12 at 100-1000 Hz (BROAD's 285.7 Hz, a phone's 200 Hz
    gyro with a 50 Hz magnetometer), 4 below 96 Hz."""
    segment_s = typical_segment_s(session.t_gyro_s, session.t_mag_s)
    if segment_s is None:
        return STRIDES[0]
    return max([s for s in STRIDES if 1.0 / (segment_s * s) >= MIN_NODE_RATE_HZ], default=STRIDES[0])


def linearise(prep: Prepared, grid: Grid, options: Options, search_lag: bool = True) -> Linearisation:
    """The point the corrections are taken about: ellipsoid, eq. (13) gyro estimate, nominal attitude, field."""
    s, field_m = prep.session, prep.field_m
    unexcited = unexcited_directions(prep.analysis)   # forced past the gate: an ideal gyro where nothing is seen
    if options.estimate_time_offset and search_lag and unexcited is None:
        lin0 = with_time_offset(s.t_gyro_s, s.gyro_rad_s, s.t_mag_s, field_m)
    else:
        lin0 = linear_gyro_estimate(s.t_gyro_s, s.gyro_rad_s, s.t_mag_s, field_m, time_offset_s=options.time_offset_s,
                                    unexcited=unexcited)
    check_axis_mapping(lin0.K, prep)  # a mirrored gyro shows already in the linear estimate: say so before solving
    C_nodes, stretch, in_hole = nominal_attitudes(s, lin0.K, lin0.eps, grid.t_node_s)
    C, m0 = aligned_stretches(C_nodes, stretch, in_hole, field_m[grid.node_mag_index], grid.node_on_sample,
                              grid.t_node_s)
    S0 = np.linalg.inv(prep.fit.R)
    acc = None
    if options.accelerometer:
        if s.acc_m_s2 is None or len(s.acc_m_s2) < 2:
            raise InputError("--accelerometer: the session has no accelerometer (columns ax ay az, m/s^2); import it "
                             "with its accelerometer, or solve without --accelerometer")
        acc = accelerometer_start(prep.untrimmed or s, s, grid, C, lin0.K, prep.accelerometer_rests_s,
                                  options.gravity_m_s2)
    return Linearisation(S0, prep.fit.h, lin0.K, lin0.eps, m0, C, float(np.mean(np.diag(S0))), lin0.time_offset_s,
                         acc)


def check_axis_mapping(K0: np.ndarray, prep: Prepared) -> None:
    """InputError (exit 2) for a gyro whose axes mirror the magnetometer's, when the linear estimate says so
    credibly; a mirrored estimate that is no plausible gyro is the noise of too little motion (exit 3)."""
    try:
        qr_split(K0)
    except InputError:
        if mirror_is_credible(K0):
            raise
        raise ObservabilityError(
            "the motion is too short or too weak to tell the gyro's axes apart: its linear estimate (paper eq. 13) "
            "comes out mirrored and is no plausible gyro (scale factors "
            + ", ".join(f"{v:.2g}" for v in np.abs(np.linalg.qr(K0)[1].diagonal()))
            + "), which is noise, not a wrong axis mapping; record longer, turning about every axis", prep.analysis) from None


FAR_START_DEG = 60.0      # the start's field directions this far off the measured ones (90th percentile): far.
                          # hand_turned seed 10 (130 deg) and the iPhone replica (82) reach the iteration limit from
                          # the guess itself; 33-66 deg converge either way, and phone-fast-hand.toml's 41-48 deg as
                          # they always did
LOW_START_FACTOR = 0.01   # a guessed gyro level starts this much below its guess when the start is far


def start_disagreement_deg(prep: Prepared, grid: Grid, lin: Linearisation) -> float:
    """How far the start is from what the magnetometer says: the angle (deg, 90th percentile over the nodes on a
    magnetometer sample) between the field direction the start's attitudes predict (C_m^i^T m^i) and the measured
    one (the ellipsoid's calibrated field). The gyro integrated with the linear estimate drifts: at 25 Hz that
    scale comes out 2-5 % high, and a hand that keeps rolling the phone over takes it 70-150 deg off within two
    minutes (issue 38's iPhones); BROAD's trials and the slower phone sessions stay within 20 deg."""
    measured = prep.field_m[grid.node_mag_index][grid.node_on_sample]
    predicted = np.einsum("nji,j->ni", lin.C_m_i_nominal[grid.node_on_sample], lin.m0)
    cos = np.sum(predicted * measured, axis=1) / np.linalg.norm(measured, axis=1)
    return float(np.percentile(np.rad2deg(np.arccos(np.clip(cos, -1.0, 1.0))), 90)) if len(cos) else 0.0


def first_gyro_density(prep: Prepared, disagreement_deg: float) -> float | None:
    """The gyro level the first pass is weighted with, when not the prepared one: a guessed level (the solve
    estimates it, `magyro.nls.variance`) starts LOW_START_FACTOR below its guess when the start is far from the
    magnetometer. Tightly tied to the gyro, the attitudes follow the gyro's calibration as a whole, which the
    magnetometer pulls back (the iPhone replica: 21-27 iterations, every gyro parameter within 1.4 std of the
    truth); loosely tied, each is pulled on its own towards the nearest field direction and IPOPT's steps shrink
    to 1e-3..1e-6 (the iteration limit). The variance components then raise the level to what the residuals say."""
    if prep.levels is None or prep.levels.gyro_source != noise.GUESS or not disagreement_deg > FAR_START_DEG:
        return None
    return prep.gyro_density * LOW_START_FACTOR


def build_problem(prep: Prepared, options: Options, method: NLS,
                  search_lag: bool = True) -> tuple[Grid, Linearisation, JointProblem]:
    """The grid, the linearisation point and the problem of a prepared session."""
    s = prep.session
    grid = build_grid(s.t_gyro_s, s.gyro_rad_s, s.t_mag_s, method.stride or default_stride(s))
    lin = linearise(prep, grid, options, search_lag)
    problem = JointProblem(grid, compiled=method.compiled, estimate_time_offset=options.estimate_time_offset,
                           huber=method.huber, walk_density=method.hard_iron_walk, accelerometer=options.accelerometer)
    return grid, lin, problem


def problem_parameters(problem: JointProblem, prep: Prepared, lin: Linearisation, sigma_mag: float, tau0_s: float,
                       gyro_density: float | None = None, acc_weight=None) -> np.ndarray:
    """The problem's parameter vector: linearisation point, noise weights (the gyro's `prep.gyro_density` unless
    given; the accelerometer's intervals `lin.accelerometer.weight` unless given) and the session's data."""
    s = prep.session
    density = prep.gyro_density if gyro_density is None else gyro_density
    return problem.parameters(lin, s.mag, sigma_mag, density, s.t_gyro_s, s.gyro_rad_s, s.t_mag_s, tau0_s, acc_weight)


def magnetometer_noise_factor(problem: JointProblem, residuals: np.ndarray) -> float:
    """Ratio of the magnetometer residuals' effective scale to the assumed noise (1 when the noise model holds).

    `noise.whitened_effective_scale` of the magnetometer residuals; `residuals`: `residual_matrix` at the solution.
    """
    r = magnetometer_residuals(residuals, problem.grid.stride)[problem.grid.sample_mask]
    return noise.whitened_effective_scale(r)


def residual_matrix(problem: JointProblem, x, p) -> np.ndarray:
    """Whitened residuals, one row per interval: the magnetometer samples, then the gyro mismatch (then the hard
    iron's walk step, when it moves)."""
    return problem.residual_values(x, p).reshape(problem.n_int, problem.n_res_per_interval)


def magnetometer_residuals(r: np.ndarray, stride: int) -> np.ndarray:
    """The magnetometer residuals of a residual matrix, one row per segment in time order, (n_int stride, 3)."""
    return r[:, : 3 * stride].reshape(-1, 3)


def gyro_residuals(r: np.ndarray, stride: int) -> np.ndarray:
    """The gyro mismatch of each interval, (n_int, 3)."""
    return r[:, 3 * stride : 3 * stride + 3]


def accelerometer_residuals(problem: JointProblem, r: np.ndarray) -> np.ndarray:
    """The accelerometer's weighted interval means, (n_int, 3): the columns after the gyro's (and the walk's)."""
    first = 3 * problem.grid.stride + 3 + (3 if problem.walk else 0)
    return r[:, first : first + 3]


ACC_REWEIGHT_TOLERANCE = 0.1   # re-solve when the accelerometer's weights moved by more than this (RMS of log)


def solved_excess(problem: JointProblem, start, x: np.ndarray, p: np.ndarray) -> np.ndarray:
    """(n_int,) the specific force's excess over g in each interval at the solution (x, p)
    (`accelerometer.specific_force_excess`): the accelerometer as calibrated there, less its lever arm's
    acceleration."""
    theta, g = x[: problem.n_theta], problem.globals_of(p)
    A, b, _, _, lever = (np.array(v) for v in problem.accelerometer_function(theta, g))
    K, eps = (np.array(v) for v in problem.physical_function(theta, g)[2:4])
    return specific_force_excess(start, A, b.ravel(), K, eps.ravel(), lever.ravel(), sub_steps_of(problem, p))


def sub_steps_of(problem: JointProblem, p: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(dt (n_int, stride, L), gyro_a, gyro_b (n_int, stride, L, 3)): the grid's sub-steps (`Grid.sub_steps`) as the
    parameter vector p holds them, views of it: making them again from the gyro record cost the accelerometer's
    solve 8 ms on BROAD 02."""
    data, g = problem.data_of(p), problem.grid
    shape = (problem.n_int, g.stride, g.substeps)
    o, held = 0, {}
    for name, k in data_layout(g.stride, g.substeps, problem.walk, problem.accelerometer):
        held[name], o = data[:, o : o + k], o + k
    return held["dt"].reshape(shape), held["ya"].reshape(shape + (3,)), held["yb"].reshape(shape + (3,))


def solved_accelerometer_residuals(problem: JointProblem, r: np.ndarray, weight: np.ndarray) -> np.ndarray:
    """(n_int, 3) the accelerometer's interval means' residuals, unweighted (m/s^2), from the residual matrix r."""
    used = weight > 0
    return np.where(used[:, None], accelerometer_residuals(problem, r) / np.where(used, weight, 1.0)[:, None], 0.0)


def accelerometer_reweighted(problem: JointProblem, lin: Linearisation, x: np.ndarray, p: np.ndarray, r: np.ndarray,
                             weight: np.ndarray):
    """(the accelerometer's interval weights measured at the solution x, p: the white noise's alone where the
    specific force's size shows no hand, else from the solved residuals r; whether they moved; whether a hand
    moved the device)."""
    hand = hand_detected(solved_excess(problem, lin.accelerometer, x, p), lin.accelerometer)
    if hand:
        new = solved_hand_weights(solved_accelerometer_residuals(problem, r, weight), lin.accelerometer)
    else:
        new = still_hand_weights(lin.accelerometer)
    ok = (weight > 0) & (new > 0)
    moved = float(np.sqrt(np.mean(np.log(new[ok] / weight[ok]) ** 2))) if ok.any() else 0.0
    return new, moved > ACC_REWEIGHT_TOLERANCE, hand


def shifted_to(x: np.ndarray, tau0: float, tau: float) -> np.ndarray:
    """x with its time-offset correction about tau instead of tau0: the same tau."""
    out = np.array(x, dtype=float)
    out[N_GLOBAL] += (tau0 - tau) / TIME_OFFSET_SCALE_S
    return out


@dataclass
class Solution:
    """The solver's point, the parameters it was solved with, and how it got there."""

    x: np.ndarray
    p: np.ndarray
    sigma_mag: float
    tau0_s: float
    stats: dict
    passes: int
    seconds: float
    residuals: np.ndarray | None = None    # residual_matrix at (x, p), when the last pass computed it
    gyro_density: float | None = None      # the gyro level p was weighted with (prep's unless estimated)
    variance: object = None                # the last `variance.VarianceComponents` step, when the levels were estimated
    levels_settled: bool = True            # False: the estimated levels still moved on the last pass
    acc_weight: np.ndarray | None = None   # the accelerometer's interval weights p was made with
    hand_found: bool = False               # stopped after its first pass: a hand, whose velocity becomes a state
    following: tuple | None = None         # (sigma_mag, gyro density, tau0, x) the next solve starts from


# A pass that may find a hand (the accelerometer's first, with NLS.hand_states) stops at the first step that moves
# the objective by less than 1e-3 of itself: the hand is measured there (the velocity prior's sigma_v on BROAD 02
# and 07 within 3e-4 of itself, K_a within 1e-6 and its std within 1e-3 of itself against the pass polished to
# 1e-10) and the states' solve polishes the rest (BROAD 02: 3 iterations instead of 5). 1e-2 stopped the poorly
# excited first half of trial 2 in its damped steps, 10 % of the way down, with sigma_v 3x too large. Where it
# finds no hand the pass goes on from there to the full stop.
LOOSE_STOP = {"ipopt.acceptable_obj_change_tol": 1e-3, "ipopt.acceptable_iter": 1}


def ipopt_stop(problem: JointProblem, method: NLS) -> dict:
    """IPOPT's stopping options for this problem's passes. With the hand's velocity as states, the first step that
    moves the objective by less than 1e-8 of itself (BROAD 02: 2.7e-6 of 1772, the step after it 5e-11; 07: 5e-6 of
    9095), one step fewer than two steps under 1e-10, the stop of every other problem (whose numbers stay bit for
    bit). Either way the Gauss-Newton decrement is checked afterwards (`run.calibrate_nls`: below 1e-3), and the
    states' std is taken at the solution itself (`run.solved_hessian`)."""
    return {"ipopt.max_iter": method.max_iter,
            **({"ipopt.acceptable_obj_change_tol": 1e-8, "ipopt.acceptable_iter": 1} if problem.hand else {})}


CONVERGED = ("Solve_Succeeded", "Solved_To_Acceptable_Level")   # IPOPT's statuses of a pass that ended where it should
VARIANCE_TOLERANCE = 0.05   # estimated levels are settled when the last step moved each by less than this
MAX_VARIANCE_PASSES = 12    # passes when the levels are estimated (each a warm start of a few iterations)


def solve_passes(problem: JointProblem, prep: Prepared, lin: Linearisation, method: NLS,
                 variance_step=None, start: Solution | None = None, first_density: float | None = None) -> Solution:
    """IPOPT, then warm re-solves: new time-offset look-up, re-weighted noise levels.

    With rests (or given levels) at most two re-solves, the magnetometer re-weighted by its residuals'
    robust scale. With a `variance_step` (noise levels that were guesses, `magyro.nls.variance`) the
    levels are estimated: re-solved until a step moves neither by more than VARIANCE_TOLERANCE.
    `variance_step(x, r, sigma_mag, density, tau0_s)` returns the step's factors on the two levels.

    Where a hand moved the device and its velocity is to become a state (`NLS.hand_states`), the first pass is all
    this solve does (`Solution.hand_found`; its next levels in `following`). From a `start` (that solve's
    `following`, its x laid out for this problem, and the weights `start.acc_weight`) the passes go on from there,
    counting its iterations and time. `first_density`: the gyro level of the first pass, when not the prepared one
    (`first_gyro_density`). A pass that did not converge ends the passes: its point is no place to re-weight from
    (re-weighted there, the iPhone replica's magnetometer level grew 657x and the next step met a singular matrix)."""
    stop = ipopt_stop(problem, method)
    # a first pass that may find a hand need not be polished: the states' solve goes on from it
    loose = ({**stop, **LOOSE_STOP} if start is None and problem.accelerometer and not problem.hand
             and method.hand_states else None)
    if start is None:
        sigma_mag, density, tau0 = prep.sigma_mag, first_density or prep.gyro_density, lin.time_offset_s
        acc_weight = None if lin.accelerometer is None else lin.accelerometer.weight
        x, seconds, iterations = np.zeros(problem.n_x), 0.0, 0
    else:
        sigma_mag, density, tau0 = start.sigma_mag, start.gyro_density, start.tau0_s
        acc_weight, x, seconds, iterations = start.acc_weight, start.x, start.seconds, int(start.stats["iter_count"])
    estimating = variance_step is not None
    max_passes = MAX_VARIANCE_PASSES if estimating else MAX_PASSES
    step = None
    n_pass = 1
    try:
        while True:
            p = problem_parameters(problem, prep, lin, sigma_mag, tau0, density, acc_weight)
            t0 = time.perf_counter()
            solver = problem.solver(loose or stop)   # made on first use, kept until released
            x, stats = problem.solve(solver, x, p)   # through buffers: no DM of p (0.6-1 s and 68 MB at 360k samples)
            seconds += time.perf_counter() - t0
            iterations += int(stats["iter_count"])
            stats["iter_count"] = iterations
            if stats["return_status"] not in CONVERGED:
                return Solution(x, p, sigma_mag, tau0, stats, n_pass, seconds, None, density, step, step is None,
                                acc_weight)
            tau = float(problem.physical_function(x[: problem.n_theta], problem.globals_of(p))[5].full().item())
            r = residual_matrix(problem, x, p) if (method.reweight_noise or estimating or problem.accelerometer) else None
            if estimating:
                step = variance_step(x, r, sigma_mag, density, tau0)
                gyro_factor, mag_factor = step.gyro_factor, step.mag_factor
                reweight = max(abs(gyro_factor - 1.0), abs(mag_factor - 1.0)) > VARIANCE_TOLERANCE
            else:
                gyro_factor, mag_factor = 1.0, (1.0 if r is None else magnetometer_noise_factor(problem, r))
                reweight = abs(mag_factor - 1.0) > NOISE_RESCALE_TOLERANCE
            moved = abs(tau - tau0) * max(abs(tau), abs(tau0)) > TIME_OFFSET_RELOOK_S2
            new_acc, acc_moved, hand = (accelerometer_reweighted(problem, lin, x, p, r, acc_weight)
                                        if problem.accelerometer and not problem.hand else (None, False, False))
            shift = moved and problem.estimate_time_offset   # the same tau, about the new tau0
            following = (sigma_mag * mag_factor if reweight else sigma_mag, density * gyro_factor if reweight
                         else density, tau if shift else tau0, shifted_to(x, tau0, tau) if shift else x)
            if hand and method.hand_states:   # the hand's velocity becomes a state (nls/hand_states.py)
                return Solution(x, p, sigma_mag, tau0, stats, n_pass, seconds, r, density, step, not reweight,
                                acc_weight, True, following)
            if loose is not None:   # no hand: the same pass again to the full stop, from where the loose one stopped
                loose = None
                continue
            if n_pass == max_passes or not (moved or reweight or acc_moved):
                return Solution(x, p, sigma_mag, tau0, stats, n_pass, seconds, r, density, step, not reweight,
                                acc_weight)
            if acc_moved:
                acc_weight = new_acc
            sigma_mag, density, tau0, x = following
            n_pass += 1
    finally:
        problem.release_solver()   # IPOPT's memory back before the std
    raise AssertionError("unreachable")
