"""From a Session to a Calibration by the joint least squares: the steps in order.

    1. the shared front end (`magyro.front.prepare`): rests, noise, ellipsoid, unit check, gate
    2. the accuracy gate, before any solver work: the accuracy the motion can give, predicted as `magyro observe`
       predicts it (`magyro.observability.prediction`, one computation for both); too little is refused (exit 3)
    3. linearisation, grid and problem; IPOPT with warm re-solves (`magyro.nls.solve`)
    4. the Gauss-Newton decrement check: a solve that could still improve is refused
    5. the std with the room's field disturbance marginalised (`magyro.nls.disturbance`), the white std beside it,
       fit statistics and warnings assembled into the result (`magyro.nls.diagnostics`)
    6. when asked (`NLS(trajectory=True)`), the attitude at the nodes with its std (`magyro.nls.trajectory`)
"""
from __future__ import annotations

import dataclasses
import time

import numpy as np

from magyro.errors import AccelerometerRefused, ObservabilityError, SolverError
from magyro.result.parts import solver_outcome
from magyro.front import noise
from magyro.front.prepare import Prepared, prepare
from magyro.nls.diagnostics import assemble
from magyro.nls.method import NLS
from magyro.nls.problem import JointProblem, Linearisation
from magyro.nls.reduction import gauss_newton_decrement, reduce_hessian
from magyro.nls.hand_motion import hand_covariance_term, shifted_hand_covariance_term
from magyro.nls.hand_states import hand_in_frame_i, hand_prior, hand_reach_m, interleave_hand, prior_information
from magyro.nls.accelerometer import (HAND_LIMIT_OF_G, HandMotion, hand_motion, hand_too_big,
                                      still_hand_weights, white_variance)
from magyro.nls.solve import (LOW_START_FACTOR, build_problem, first_gyro_density, residual_matrix, solve_passes,
                              start_disagreement_deg,
                              solved_accelerometer_residuals, solved_excess)
from magyro.nls.disturbance import disturbance_covariance
from magyro.nls.variance import secant_factor, variance_components
from magyro.nls.trajectory import attitude_trajectory, solved_attitudes
from magyro.observability.gate import REFUSAL_BOUND_NOTE, accuracy_shortfalls, accuracy_summary, room_cause
from magyro.observability.prediction import excitation_gate
from magyro.options import Options
from magyro.progress import step
from magyro.result.calibration import Calibration
from magyro.session import Session
from magyro.text import significant

MAX_DECREMENT = 1e-3  # chi^2 units: a step that would remove less than this changes nothing that matters


def calibrate_nls(session: Session, options: Options | None = None, method: NLS | None = None) -> Calibration:
    """Calibrate gyro and magnetometer from one session (the joint least squares)."""
    options, method = options or Options(), method or NLS()
    t_start = time.perf_counter()
    step("rests, noise levels and the magnetometer's ellipsoid")
    prep = prepare(session, options)
    step("the accuracy the motion can give (magyro observe's verdict)")
    gate_warnings = excitation_gate(prep, options, method)   # before any solver work, the same verdict as observe's
    step("the linear estimate and the least-squares problem")
    grid, lin, problem = build_problem(prep, options, method)
    step(f"solving the least squares ({problem.n_x} unknowns, IPOPT)")
    disagreement_deg = start_disagreement_deg(prep, grid, lin)
    first_density = first_gyro_density(prep, disagreement_deg)
    sol = solve_passes(problem, prep, lin, method, level_estimator(problem, prep, lin), first_density=first_density)
    hand = None
    if sol.hand_found:   # its first pass measured the hand: the passes go on with the hand's velocity as states
        hand = solved_hand_motion(problem, lin, sol)
        step("the hand's velocity as states: the least squares again")
        problem, sol = solve_with_hand_states(problem, prep, lin, method, sol, hand)
    step("the uncertainty: information and the room's field")
    reduced = reduce_hessian(solved_hessian(problem, sol), problem.n_theta, problem.B)
    decrement = gauss_newton_decrement(reduced, problem.gradient_values(sol.x, sol.p))
    if not (np.isfinite(decrement) and decrement < MAX_DECREMENT) and not prep.analysis.full_rank:
        raise ObservabilityError(   # forced past the gate, and the data indeed do not pin a solution down
            f"--force cannot help the least squares here: the motion excites only {prep.analysis.rank} of the 12 gyro "
            f"parameters and the solve finds no unique solution (the solver {solver_outcome(sol.stats['return_status'])}); "
            f"--method ekf --force "
            f"gives an estimate whose std shows what is missing. {prep.analysis.summary()}", prep.analysis)
    if not (np.isfinite(decrement) and decrement < MAX_DECREMENT):
        raise SolverError(not_converged_message(sol, decrement, prep, first_density, disagreement_deg))
    sol.stats["gauss_newton_decrement"] = decrement
    if problem.accelerometer and not problem.hand:
        hand = solved_hand_motion(problem, lin, sol)
    cov_theta, disturbance = disturbance_covariance(problem, sol.x, sol.p, reduced, solved_attitudes(problem, lin, sol.x),
                                                    prep.session)
    if problem.hand:
        cov_theta = cov_theta + hand_states_term(problem, lin, sol, reduced)
    elif hand is not None:
        cov_theta = cov_theta + hand_term(problem, lin, sol, reduced, hand)
    cal = assemble(problem, prep, grid, sol, reduced, method, time.perf_counter() - t_start, cov_theta, disturbance)
    if hand is not None:
        cal.accelerometer.hand_rms_m_s2 = float(np.sqrt(hand.variance_m2_s4))
    if problem.hand:
        cal.solver.details["hand_states"] = hand_state_details(problem, sol)
    cal.solver.details["start_disagreement_deg"] = disagreement_deg
    acc_warnings = accelerometer_gate(cal, options)   # first: an accelerometer past its bound widens the gyro's std
    cal.warnings.extend(gate_warnings or solved_accuracy_gate(cal, options))
    cal.warnings.extend(acc_warnings)
    if method.trajectory:
        cal.trajectory = attitude_trajectory(problem, grid, lin, sol.x, reduced, prep.session, cal.R, cal.h, cov_theta)
    return cal


def solved_hessian(problem: JointProblem, sol):
    """triu(J^T J) for the std: at the point of the Gauss-Newton Hessian IPOPT evaluated last, else (no iteration
    in the last pass) at the solution. At convergence the two points differ by a step too small to matter: the
    estimates are those of the solution either way, and the std moved by < 1e-6 of itself where compared
    (benchmarks/same_estimates.py on BROAD 02, paper-table1 and the bench_limit sessions). Evaluated here, after
    IPOPT gave its memory back, rather than kept from the solve (`on_numpy.KeptHessian`).

    With the hand's velocity as states, at the solution: there the hand's sensitivities (`hand_motion.
    hand_sensitivities`, the Jacobian at the solution profiled by this Hessian's node responses) nearly cancel where
    the states take up the hand, and a Hessian one step back left them off by as much as the hand is large (BROAD
    trial 34, a hand of 2.2 m/s^2: K_a's std 2-5x apart between solves stopped one step apart; at the solution the
    same to 1e-3)."""
    x = None if problem.hand else problem.last_hessian_point(sol.p)
    return problem.hessian_values(sol.x if x is None else x, sol.p)


def solved_hand_motion(problem: JointProblem, lin: Linearisation, sol) -> HandMotion:
    """The hand's acceleration at the solution: its size and autocorrelation (`magyro.nls.accelerometer.hand_motion`)."""
    r = residual_matrix(problem, sol.x, sol.p) if sol.residuals is None else sol.residuals
    return hand_motion(solved_excess(problem, lin.accelerometer, sol.x, sol.p), sol.acc_weight, lin.accelerometer,
                       solved_accelerometer_residuals(problem, r, sol.acc_weight))


def hand_term(problem: JointProblem, lin: Linearisation, sol, reduced, hand: HandMotion) -> np.ndarray:
    """What the hand's correlated acceleration adds to the corrections' covariance (`magyro.nls.hand_motion`)."""
    used = sol.acc_weight > 0    # an interval with no accelerometer sample has weight 0: no hand counted there
    held = np.divide(1.0, sol.acc_weight**2, out=np.zeros_like(sol.acc_weight), where=used) - white_variance(lin.accelerometer)
    weights_hand = np.where(used, np.sqrt(np.maximum(held, 0.0)), 0.0)
    return hand_covariance_term(problem, sol.x, sol.p, reduced, reduced.information, hand.hand_std_m_s2,
                                weights_hand, hand.correlation, hand.variance_m2_s4)


def solve_with_hand_states(problem: JointProblem, prep: Prepared, lin: Linearisation, method: NLS, sol, hand: HandMotion):
    """(the problem with the hand's velocity as states, its solution from where `sol`, the first pass of the one
    without them, left off): the interval means weighted by their white noise alone (nls/hand_states.py), the passes
    going on (`solve_passes`); its convergence is checked as any solve's (`calibrate_nls`)."""
    staged = JointProblem(problem.grid, compiled=problem.compiled, estimate_time_offset=problem.estimate_time_offset,
                          huber=problem.huber, walk_density=problem.walk_density, accelerometer=True,
                          hand_prior=hand_prior(hand.variance_m2_s4))
    sigma_mag, density, tau0, x = sol.following
    start = dataclasses.replace(sol, x=interleave_hand(problem, staged, x), sigma_mag=sigma_mag, gyro_density=density,
                                tau0_s=tau0, acc_weight=still_hand_weights(lin.accelerometer))
    solved = solve_passes(staged, prep, lin, method, level_estimator(staged, prep, lin), start)
    solved.passes += sol.passes
    return staged, solved


def hand_states_term(problem: JointProblem, lin: Linearisation, sol, reduced) -> np.ndarray:
    """What the hand adds to the corrections' covariance when its velocity is a state: the hand the states and the
    residuals hold (`hand_states.hand_in_frame_i`), shifted to every time it could have come
    (`hand_motion.shifted_hand_covariance_term`), less the share of the information that the velocity's prior
    holds, which is no data (`hand_states.prior_information`)."""
    used = sol.acc_weight > 0
    r = residual_matrix(problem, sol.x, sol.p) if sol.residuals is None else sol.residuals
    hand = np.where(used[:, None], hand_in_frame_i(problem, sol.x, sol.p,
                                                   solved_accelerometer_residuals(problem, r, sol.acc_weight)), 0.0)
    white = np.where(used, white_variance(lin.accelerometer), 0.0)
    term = shifted_hand_covariance_term(problem, sol.x, sol.p, reduced, reduced.information, hand, white)
    info_inv = np.linalg.inv(reduced.information)
    return term - info_inv @ prior_information(problem, reduced) @ info_inv


def hand_state_details(problem: JointProblem, sol) -> dict:
    """The hand's velocity process the states were solved with, and how far they say the hand took the device."""
    prior = problem.hand_prior
    return {"sigma_v_m_s": prior.sigma_v_m_s, "tau_s": prior.tau_s, "reach_m": hand_reach_m(problem, sol.x)}


def not_converged_message(sol, decrement: float, prep: Prepared | None = None, first_density: float | None = None,
                          disagreement_deg: float | None = None) -> str:
    """Why the solve is refused (exit 1), with the evidence and what was tried: never a printed nan."""
    still = (f"a further Gauss-Newton step would still reduce chi^2 by {significant(decrement)}" if np.isfinite(decrement) else
             "the Gauss-Newton step cannot be computed there: the information is singular or not finite")
    return (f"the solver did not converge: it {solver_outcome(sol.stats['return_status'])} after "
            f"{sol.stats['iter_count']} iterations{passes_said(getattr(sol, 'passes', 1))} "
            f"({still}); tried: {what_was_tried(prep, first_density, disagreement_deg)}; the data do not fit the model at the "
            f"point it reached: a field that is not homogeneous, a clock that is not steady or a gyro that saturates "
            f"are the usual causes (magyro check looks for the last two)")


def passes_said(passes: int) -> str:
    """' in N passes' when the solve re-weighted between passes, else nothing."""
    return f" in {passes} passes" if passes > 1 else ""


def what_was_tried(prep: Prepared | None, first_density: float | None, disagreement_deg: float | None) -> str:
    """The start and the weighting the solve went from, in words (for its refusal)."""
    start = ("the gyro integrated with the linear estimate (paper eq. 13)"
             + ("" if disagreement_deg is None else
                f", its field directions {disagreement_deg:.0f} deg off the measured ones (90th percentile)"))
    if first_density is not None and prep is not None:
        weights = (f"the gyro's guessed noise level started {1 / LOW_START_FACTOR:g}x below its guess "
                   f"({np.rad2deg(prep.gyro_density):.3g} deg/s/sqrt(Hz)) and estimated by the solve")
    elif prep is not None and prep.levels is not None and noise.GUESS in (prep.levels.gyro_source, prep.levels.mag_source):
        weights = "the guessed noise levels estimated by the solve"
    else:
        weights = "the noise levels as measured" + ("" if prep is None or prep.levels is None else f" ({prep.levels.source})")
    return f"{start}; {weights}; --gyro-noise with your gyro's noise density may help"


def level_estimator(problem: JointProblem, prep: Prepared, lin: Linearisation):
    """The variance-component step of `solve_passes` when a noise level is a guess (no rest, not given), else None:
    the least squares then estimates the guessed levels (`magyro.nls.variance`)."""
    levels = prep.levels
    if levels is None:
        return None
    gyro, mag = levels.gyro_source == noise.GUESS, levels.mag_source == noise.GUESS
    if not (gyro or mag):
        return None

    tried = {"gyro": [], "mag": []}

    def step(x, r, sigma_mag, density, tau0_s):
        found = variance_components(problem, prep, lin, x, r, sigma_mag, density, tau0_s, gyro, mag)
        return dataclasses.replace(found, gyro_factor=secant_factor(tried["gyro"], density, found.gyro_factor),
                                   mag_factor=secant_factor(tried["mag"], sigma_mag, found.mag_factor))
    return step


def solved_accuracy_gate(cal: Calibration, options: Options) -> list[str]:
    """The bounds of `options.max_std` on the solved std, which counts the room's field disturbance: a motion that
    excites every parameter well (no check before the solve) can still leave a std too large in a room whose field
    wanders. Refused (exit 3) as the prediction is, or with --force a warning."""
    shortfalls = accuracy_shortfalls(cal.std, options.max_std)
    if not shortfalls:
        return []
    disturbance = cal.noise.field_disturbance
    cause = room_cause(None if disturbance is None else disturbance.std_fraction)
    summary = accuracy_summary(shortfalls, "one-sigma")
    if options.force:
        return [f"solved with --force although the std exceeds its bounds: {summary}{cause}"]
    raise ObservabilityError(f"the calibration is too uncertain to be worth having: {summary}{cause} (--force reports it "
                             f"anyway; {REFUSAL_BOUND_NOTE})")


def accelerometer_shortfalls(acc, bounds) -> list[str]:
    """The accelerometer's one-sigma above the refusal bound (`StdBounds.acc_*`), each said with its bound."""
    out = []
    for i in range(3):
        if 1e6 * acc.std_K_a[i, i] > bounds.acc_scale_ppm:
            out.append(f"scale K_a[{i},{i}] {significant(1e6 * acc.std_K_a[i, i])} ppm (bound {bounds.acc_scale_ppm:g})")
    for i, j in ((0, 1), (0, 2), (1, 2)):
        if np.rad2deg(acc.std_K_a[i, j]) > bounds.acc_nonorthogonality_deg:
            out.append(f"non-orthogonality K_a[{i},{j}] {significant(np.rad2deg(acc.std_K_a[i, j]))} deg "
                       f"(bound {bounds.acc_nonorthogonality_deg:g})")
    for i, axis in enumerate("xyz"):
        if acc.std_bias_m_s2[i] > bounds.acc_bias_m_s2:
            out.append(f"bias {axis} {significant(acc.std_bias_m_s2[i])} m/s^2 (bound {bounds.acc_bias_m_s2:g})")
        if acc.std_misalignment_deg[i] > bounds.acc_misalignment_deg:
            out.append(f"misalignment d{axis} {significant(acc.std_misalignment_deg[i])} deg "
                       f"(bound {bounds.acc_misalignment_deg:g})")
    return out


def accelerometer_gate(cal: Calibration, options: Options) -> list[str]:
    """The refusal bound on the accelerometer's solved std (exit 3; with --force a warning). Its std counts the hand's
    acceleration: a device swung fast, or far from the point it turns about, leaves gravity too little to say."""
    acc = cal.accelerometer
    if acc is None:
        return []
    shortfalls = accelerometer_shortfalls(acc, options.max_std)
    hand = acc.hand_rms_m_s2
    if hand is not None and hand_too_big(hand, acc.g_m_s2):
        cost = (f"with its velocity as states the accelerometer's scale factors come out uncertain by up to "
                f"{significant(100 * np.max(np.diag(acc.std_K_a)))} % one-sigma (BROAD's fast trials, forced: 2.1-5.2 %, "
                "within 2.1 std of the slow trials' 1.000)" if "hand_states" in cal.solver.details
                else "a hand that moves with the turning biases the accelerometer's scale factors and bias by more than "
                     "their std (BROAD, against its optical truth: 4-30 %)")
        summary = (f"the hand accelerated the device by {significant(hand)} m/s^2 RMS while it turned, more than "
                   f"{100 * HAND_LIMIT_OF_G:g} % of g ({significant(HAND_LIMIT_OF_G * acc.g_m_s2)} m/s^2): {cost}")
    elif shortfalls:
        summary = ("the accelerometer's calibration is too uncertain to be worth having: one-sigma " + ", ".join(shortfalls))
    else:
        return []
    summary += ("; the hand's acceleration while turning swamps what gravity says: turn the device more slowly, "
                "about its own middle, with a few seconds still between turns")
    if options.force:
        return [f"solved with --force although {summary}"]
    # --force alone does not report it: by default an accelerometer past its bound is left out, forced or not
    # (`magyro.api.solved_with_history`); only with --accelerometer does --force keep it
    raise AccelerometerRefused(f"{summary} (--accelerometer --force reports it anyway; with --no-accelerometer the "
                               f"gyro and the magnetometer are calibrated alone)")
