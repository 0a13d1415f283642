"""The whole calibration: from a Session to a Calibration (the Python API behind `magyro solve`).

    1. noise levels (given, or estimated from the data); rests found, the ones
       at both ends trimmed (the paper excludes them)
    2. magnetometer ellipsoid (paper step 1)          -> R0, h0, calibrated field m^m
    3. observability gate on the integral of M^T M    -> exit 3 when rank < 12
    4. linear gyro estimate (paper eq. 13)            -> K0, eps0
    5. nominal attitude by integrating the gyro with K0, eps0
    6. the joint least squares (problem.JointProblem), IPOPT; re-solved warm (at
       most twice) when the time offset moved the gyro look-up or the
       magnetometer noise proved different from the estimate (robust
       variance-component step)
    7. marginal covariance of the calibration parameters, QR split, std;
       rest-period bias check; windows where the field does not fit
    8. optionally (Options.split_check) each half calibrated alone and compared
       (magyro.consistency)
"""
from __future__ import annotations

import time
from dataclasses import dataclass, replace

import casadi as ca
import numpy as np

from magyro.result import consistency

from magyro.front import ellipsoid

from magyro.front import noise

from magyro.front import rests

from magyro import so3
from magyro.errors import InputError, ObservabilityError, SolverError
from magyro.front.initial import linear_gyro_estimate, with_time_offset
from magyro.observability.gate import ObservabilityAnalysis, analyse
from magyro.nls.problem import N_GLOBAL, TIME_OFFSET_SCALE_S, Grid, JointProblem, Linearisation, build_grid
from magyro.result.calibration import N_REPORTED, Calibration, axis_mapping_warning, qr_split, reported_vector, std_from_covariance
from magyro.session import Session

NODE_RATE_HZ = 25.0   # nodes per second: strides 1, 2 and 4 at 100 Hz give the same estimates and std to 1e-6
MAX_PASSES = 3
NOISE_RESCALE_TOLERANCE = 0.2     # re-solve when the robust residual scale is off by more than this
TIME_OFFSET_RELOOK_S2 = 1e-5      # re-solve when tau * (tau - tau0) exceeds this (s^2): the rotation
                                  # error of the gyro look-up at t - tau0/2 scales with it (1 ms at 10 ms)
CHI2_3DOF_MEDIAN = 2.3660         # median of |r|^2 for a 3-vector of unit normals
SUSPECT_WINDOW_S = 1.0
SUSPECT_FACTOR = 5.0            # BROAD: undisturbed trials reach 3.6x, a magnet beside the path 7.5x
FIELD_WINDOW_S = 0.5
MAX_FIELD_CHANGE = 0.05         # BROAD: 1-3 % across the capture volume; a magnet beside the path 7 %
MAX_DECREMENT = 1e-3  # chi^2 units: a step that would remove less than this changes nothing that matters
MIN_RATE_RATIO = 0.1


@dataclass
class Options:
    """Choices a user can make; None means 'estimate from the data' or 'automatic'."""

    gyro_noise_density_rad_s_sqrt_hz: float | None = None
    mag_noise_std: float | None = None      # in the magnetometer's unit
    stride: int | None = None               # one attitude node every `stride` magnetometer samples
    force: bool = False                     # solve even when the observability check fails
    max_iter: int = 100
    compiled: bool = True                   # compiled CasADi kernels (cached on disk)
    estimate_time_offset: bool = True       # magnetometer-to-gyro lag as a decision variable
    time_offset_s: float = 0.0              # its starting value (or its fixed value)
    loss: str = "l2"                        # "l2" or "huber" on the magnetometer residuals
    huber_threshold: float = 3.0            # in noise sigmas
    trim_rests: bool = True                 # drop the rests at both ends (the paper does)
    reweight_noise: bool = True             # robust variance-component step on the magnetometer noise
    split_check: bool = False               # also calibrate each half alone and compare (magyro.consistency)


@dataclass
class Prepared:
    """Everything before the solve: noise, step-1 fit, gate, initial estimates."""

    session: Session                # trimmed to the moving span when Options.trim_rests
    sigma_mag: float
    gyro_density: float
    fit: ellipsoid.EllipsoidFit
    field_m: np.ndarray
    analysis: ObservabilityAnalysis
    rests: rests.Rests | None = None
    noise_source: str = ""


MIN_REST_FOR_NOISE_S = 2.0
MIN_MOVING_SAMPLES = 100


@dataclass(frozen=True)
class NoiseLevels:
    """Per-sample stds (what noise adds sample by sample) and effective white levels (what weights the fit)."""

    mag_sample_std: float          # magnetometer unit
    gyro_sample_std_rad_s: float
    mag_std: float                 # effective: per-sample std * sqrt(autocorrelation time)
    gyro_density_rad_s_sqrt_hz: float
    source: str


def noise_levels(session: Session, options: Options, found: rests.Rests) -> NoiseLevels:
    """Noise levels: given, from the longest rest (correlation included), or from third differences (white)."""
    rate = session.gyro_rate_hz
    if found.seconds >= MIN_REST_FOR_NOISE_S:
        longest = max(found.segments_s, key=lambda ab: ab[1] - ab[0])
        still = rests.rests_from_segments(session, [longest])
        mag_sample = float(np.sqrt(np.mean(np.var(still.mag_still, axis=0))))
        gyro_sample = float(np.sqrt(np.mean(np.var(still.gyro_still, axis=0))))
        mag_eff = noise.effective_std(still.mag_still)
        density = noise.effective_std(still.gyro_still) / np.sqrt(rate)
        source = f"the {longest[1] - longest[0]:.1f} s rest (correlation included)"
    else:
        mag_sample = mag_eff = noise.mag_noise_std(session.mag)
        density = noise.gyro_noise_density_rad_s_sqrt_hz(session.gyro_rad_s, rate)
        gyro_sample = density * np.sqrt(rate)
        source = "third differences (white noise assumed)"
    if options.mag_noise_std:
        mag_sample = mag_eff = options.mag_noise_std
    if options.gyro_noise_density_rad_s_sqrt_hz:
        density = options.gyro_noise_density_rad_s_sqrt_hz
        gyro_sample = density * np.sqrt(rate)
    if options.mag_noise_std or options.gyro_noise_density_rad_s_sqrt_hz:
        source = "given" if options.mag_noise_std and options.gyro_noise_density_rad_s_sqrt_hz else source + ", partly given"
    if not (mag_eff > 0 and density > 0):
        raise InputError(
            "cannot estimate the sensor noise from the data (the readings do not vary); "
            "pass --mag-noise and --gyro-noise"
        )
    return NoiseLevels(float(mag_sample), float(gyro_sample), float(mag_eff), float(density), source)


MAG_MUST_FOLLOW_DEG = 180.0


def gyro_angle_turned_deg(session: Session) -> float:
    """Total angle the raw gyro says the device turned (integral of |w| dt)."""
    return float(np.rad2deg(np.sum(np.linalg.norm(session.gyro_rad_s[1:], axis=1) * np.diff(session.t_gyro_s))))


def check_gyro_unit(session: Session, field_m: np.ndarray) -> None:
    """The gyro must turn the field as fast as the magnetometer sees it turn; deg/s labelled rad/s turns it 57x too fast."""
    t, y = session.t_gyro_s, session.gyro_rad_s
    step = max(1, int(round(0.1 * session.mag_rate_hz)))
    tm = session.t_mag_s[::step]
    fm = field_m[::step]
    seen = np.sum(np.linalg.norm(np.diff(fm, axis=0), axis=1))
    inside = (t >= tm[0]) & (t <= tm[-1])
    f_on_g = np.column_stack([np.interp(t[inside], session.t_mag_s, field_m[:, i]) for i in range(3)])
    w = np.gradient(t[inside])
    predicted = np.sum(np.linalg.norm(np.cross(f_on_g, y[inside]), axis=1) * w)
    if predicted > np.deg2rad(90) and seen / predicted < MIN_RATE_RATIO:
        raise InputError(
            f"the gyro turns {predicted / seen:.0f}x faster than the magnetometer sees the field turn: "
            "the gyro looks like deg/s labelled rad/s; pass --gyro-unit deg/s"
        )


def moving_session(session: Session, options: Options) -> tuple[Session, NoiseLevels, rests.Rests]:
    """(the session as the calibration sees it, noise levels, rests): rests found, noise levels
    from them, and the session trimmed to its moving span when Options.trim_rests. A session
    that is one long rest stays whole: the gate then calls it static."""
    found = rests.find_rests(session)
    levels = noise_levels(session, options, found)
    if options.trim_rests and found.segments_s:
        moving = session.within(*rests.moving_span(session, found))
        if min(len(moving.t_mag_s), len(moving.t_gyro_s)) >= MIN_MOVING_SAMPLES:
            session = moving
    return session, levels, found


def prepare(session: Session, options: Options) -> Prepared:
    """Steps 1-3: noise, rests, ellipsoid, observability. Raises ObservabilityError unless forced."""
    session, levels, found = moving_session(session, options)
    sigma_mag, density = levels.mag_std, levels.gyro_density_rad_s_sqrt_hz
    gyro_std, mag_sample = levels.gyro_sample_std_rad_s, levels.mag_sample_std
    try:
        fit = ellipsoid.fit_ellipsoid(session.mag, mag_sample)
    except ellipsoid.DegenerateCloud as cloud:
        turned_deg = gyro_angle_turned_deg(session)
        if cloud.kind == "static" and turned_deg > MAG_MUST_FOLLOW_DEG:
            raise InputError(
                f"the gyro turned {turned_deg:.0f} deg but the magnetometer readings do not follow: they vary no "
                "more than their own noise; check that mx, my, mz are a magnetometer and are not noise or constant"
            ) from None
        field = ellipsoid.surrogate_field_directions(session.mag)
        analysis = analyse(session.t_gyro_s, session.gyro_rad_s, session.t_mag_s, field, gyro_std, mag_sample / np.mean(np.linalg.norm(session.mag, axis=1)))
        raise ObservabilityError(
            f"{cloud}; the magnetometer's soft/hard iron cannot be fitted. Gyro parameters: {analysis.summary()}",
            analysis,
        ) from None
    field = ellipsoid.calibrated_field(fit.R, fit.h, session.mag)
    check_gyro_unit(session, field)
    analysis = analyse(session.t_gyro_s, session.gyro_rad_s, session.t_mag_s, field, gyro_std, mag_sample * float(np.mean(np.diag(fit.R))))
    if not analysis.full_rank and not options.force:
        raise ObservabilityError(
            f"the motion does not excite every gyro parameter: {analysis.summary()} (--force solves anyway)", analysis
        )
    return Prepared(session, sigma_mag, density, fit, field, analysis, found, levels.source)


def nominal_attitudes(session: Session, K0, eps0, t_node_s) -> np.ndarray:
    """C_m^i at the nodes from the gyro corrected by K0, eps0; node 0 = I."""
    t, y = session.t_gyro_s, session.gyro_rad_s
    w = y @ K0.T + eps0
    C = so3.integrate_body_rates(t, w)
    i = np.clip(np.searchsorted(t, t_node_s, side="right") - 1, 0, len(t) - 1)
    Cn = C[i] @ so3.exp_so3(w[i] * (t_node_s - t[i])[:, None])
    return np.einsum("ji,njk->nik", Cn[0], Cn)


def initial_field(C_nodes, field_m_nodes, seconds_n: int = 100) -> np.ndarray:
    m = np.einsum("nij,nj->ni", C_nodes[:seconds_n], field_m_nodes[:seconds_n]).mean(axis=0)
    return m / np.linalg.norm(m)


def default_stride(session: Session) -> int:
    return max(1, int(round(session.mag_rate_hz / NODE_RATE_HZ)))


def linearise(prep: Prepared, grid: Grid, options: Options, search_lag: bool = True) -> Linearisation:
    s = prep.session
    if options.estimate_time_offset and search_lag:
        lin0 = with_time_offset(s.t_gyro_s, s.gyro_rad_s, s.t_mag_s, prep.field_m)
    else:
        lin0 = linear_gyro_estimate(s.t_gyro_s, s.gyro_rad_s, s.t_mag_s, prep.field_m, time_offset_s=options.time_offset_s)
    qr_split(lin0.K)  # a mirrored gyro shows already in the linear estimate: say so before solving
    C = nominal_attitudes(s, lin0.K, lin0.eps, grid.t_node_s)
    on_sample = grid.node_on_sample
    m0 = initial_field(C[on_sample], prep.field_m[grid.node_mag_index[on_sample]])
    S0 = np.linalg.inv(prep.fit.R)
    return Linearisation(S0, prep.fit.h, lin0.K, lin0.eps, m0, C, float(np.mean(np.diag(S0))), lin0.time_offset_s)


@dataclass(frozen=True)
class Reduced:
    """J^T J with the trajectory eliminated: the marginal information of the calibration corrections."""

    information: np.ndarray   # Schur complement H_tt - H_tp D^-1 H_pt
    H_tp: np.ndarray
    D: ca.DM                  # the attitude block (sparse, block tridiagonal), full symmetric
    D_solver: ca.Linsol       # its sparse LDL factorisation
    Dinv_Hpt: np.ndarray      # D^-1 H_pt

    def solve_D(self, b: np.ndarray) -> np.ndarray:
        return np.array(self.D_solver.solve(self.D, ca.DM(b))).reshape(np.shape(b))


def reduce_hessian(H_triu: ca.DM, G: int) -> Reduced:
    """Eliminate the attitudes (after the first G unknowns) from triu(J^T J) by a sparse LDL
    of the block-tridiagonal attitude block: no dense N x N matrix is ever formed."""
    H_tt = np.array(ca.densify(H_triu[:G, :G]))
    H_tt = H_tt + np.triu(H_tt, 1).T
    H_tp = np.array(ca.densify(H_triu[:G, G:]))
    D_triu = H_triu[G:, G:]
    D = D_triu + ca.triu(D_triu, False).T
    solver = ca.Linsol("attitude_block", "ldl", D.sparsity())
    solver.sfact(D)
    solver.nfact(D)
    Dinv_Hpt = np.array(solver.solve(D, ca.DM(H_tp.T)))
    return Reduced(H_tt - H_tp @ Dinv_Hpt, H_tp, D, solver, Dinv_Hpt)


def gauss_newton_decrement(red: Reduced, grad) -> float:
    """g^T H^-1 g: how much the objective (chi^2 units) a further Gauss-Newton step would still remove."""
    G = red.H_tp.shape[0]
    g_t, g_p = grad[:G], grad[G:]
    Dinv_gp = red.solve_D(g_p)
    x_t = np.linalg.solve(red.information, g_t - red.H_tp @ Dinv_gp)
    x_p = Dinv_gp - red.Dinv_Hpt @ x_t
    return float(g_t @ x_t + g_p @ x_p)


def propagate(problem: JointProblem, theta, g, cov_theta, C_ref) -> np.ndarray:
    """Covariance of the reported vector by central differences through R = S^-1 and the QR split."""
    def f(th):
        S, h, K, eps, m, tau = (np.array(v) for v in problem.physical_function(th, g))
        return reported_vector(K, eps.ravel(), S, h.ravel(), m.ravel(), C_ref, float(tau.item()))

    step = 1e-6
    n = problem.n_theta
    J = np.empty((len(f(theta)), n))
    for i in range(n):
        e = np.zeros(n)
        e[i] = step
        J[:, i] = (f(theta + e) - f(theta - e)) / (2 * step)
    return J @ cov_theta @ J.T


def build_problem(prep: Prepared, options: Options, search_lag: bool = True) -> tuple[Grid, Linearisation, JointProblem]:
    s = prep.session
    grid = build_grid(s.t_gyro_s, s.gyro_rad_s, s.t_mag_s, options.stride or default_stride(s))
    lin = linearise(prep, grid, options, search_lag)
    huber = options.huber_threshold if options.loss == "huber" else None
    if options.loss not in ("l2", "huber"):
        raise InputError(f"unknown loss '{options.loss}'; use l2 or huber")
    problem = JointProblem(grid, compiled=options.compiled, estimate_time_offset=options.estimate_time_offset, huber=huber)
    return grid, lin, problem


def problem_parameters(problem: JointProblem, prep: Prepared, lin: Linearisation, sigma_mag: float, tau0_s: float) -> np.ndarray:
    s = prep.session
    return problem.parameters(lin, s.mag, sigma_mag, prep.gyro_density, s.t_gyro_s, s.gyro_rad_s, s.t_mag_s, tau0_s)


def predicted_std(prep: Prepared, options: Options | None = None) -> dict:
    """One-sigma accuracy this recording can give, before solving.

    The Gauss-Newton (Fisher) information of the joint problem at the initial
    estimate, with the session's noise levels, trajectory marginalised out and
    propagated like the solved std. Entries are inf where the information is
    singular (unobservable). The linearisation point is the plain eq. (13)
    estimate: the lag search that the solve needs to converge changes a
    prediction by no more than the few percent it moves K.
    """
    options = options or Options()
    grid, lin, problem = build_problem(prep, options, search_lag=False)
    p = problem_parameters(problem, prep, lin, prep.sigma_mag, lin.time_offset_s)
    return information_std(problem, lin, p)


def information_covariance(problem: JointProblem, lin: Linearisation, p) -> np.ndarray:
    """Covariance of the reported vector (result.REPORTED layout) from the Gauss-Newton information
    at the linearisation point; all inf where the information is singular (a direction the data do not see)."""
    info = reduce_hessian(problem.hessian_function(np.zeros(problem.n_x), p), problem.n_theta).information
    lam = np.linalg.eigvalsh(info)
    if lam[0] <= lam[-1] * 1e-14:
        return np.full((N_REPORTED, N_REPORTED), np.inf)
    C0, _ = qr_split(lin.K0)
    return propagate(problem, np.zeros(problem.n_theta), p[: problem.n_glob_p], np.linalg.inv(info), C0)


def information_std(problem: JointProblem, lin: Linearisation, p) -> dict:
    """One-sigma of every reported parameter from the Gauss-Newton information at the linearisation point."""
    return std_from_covariance(information_covariance(problem, lin, p))


def magnetometer_noise_factor(problem: JointProblem, x, p) -> float:
    """Ratio of the magnetometer residuals' effective scale to the assumed noise (1 when the noise model holds).

    Robust per-sample scale (median of |r|^2 against its chi^2 median) times
    the square root of the residuals' integrated autocorrelation time, so
    correlated model error (a field not quite homogeneous) counts as what it
    is: fewer independent samples.
    """
    r = residual_matrix(problem, x, p)[:, :-3].reshape(-1, 3)[problem.grid.sample_mask]  # time-ordered samples
    scale = np.sqrt(np.median(np.sum(r**2, axis=1)) / CHI2_3DOF_MEDIAN)
    return float(scale * np.sqrt(noise.integrated_autocorrelation_time(r)))


def residual_matrix(problem: JointProblem, x, p) -> np.ndarray:
    """Whitened residuals, one row per interval: the magnetometer samples, then the gyro mismatch."""
    return np.array(problem.residual_function(x, p)).reshape(problem.n_int, problem.n_res_per_interval)


@dataclass
class Solution:
    x: np.ndarray
    p: np.ndarray
    sigma_mag: float
    tau0_s: float
    stats: dict
    passes: int
    seconds: float


def solve_passes(problem: JointProblem, prep: Prepared, lin: Linearisation, options: Options) -> Solution:
    """IPOPT, then at most two warm re-solves: new time-offset look-up, re-weighted magnetometer noise."""
    solver = problem.solver({"ipopt.max_iter": options.max_iter})
    sigma_mag, tau0 = prep.sigma_mag, lin.time_offset_s
    x = np.zeros(problem.n_x)
    seconds, iterations = 0.0, 0
    for n_pass in range(1, MAX_PASSES + 1):
        p = problem_parameters(problem, prep, lin, sigma_mag, tau0)
        t0 = time.perf_counter()
        x = np.array(solver(x0=x, p=p)["x"]).ravel()
        seconds += time.perf_counter() - t0
        stats = dict(solver.stats())
        iterations += int(stats["iter_count"])
        stats["iter_count"] = iterations
        tau = float(problem.physical_function(x[: problem.n_theta], p[: problem.n_glob_p])[5].full().item())
        factor = magnetometer_noise_factor(problem, x, p) if options.reweight_noise else 1.0
        moved = abs(tau - tau0) * max(abs(tau), abs(tau0)) > TIME_OFFSET_RELOOK_S2
        reweight = abs(factor - 1.0) > NOISE_RESCALE_TOLERANCE
        if n_pass == MAX_PASSES or not (moved or reweight):
            return Solution(x, p, sigma_mag, tau0, stats, n_pass, seconds)
        if moved and problem.n_theta > N_GLOBAL:
            x[N_GLOBAL] += (tau0 - tau) / TIME_OFFSET_SCALE_S  # same tau, now about the new tau0
            tau0 = tau
        if reweight:
            sigma_mag *= factor
    raise AssertionError("unreachable")


def calibrate(session: Session, options: Options | None = None) -> Calibration:
    """Calibrate gyro and magnetometer from one session (the joint least squares)."""
    options = options or Options()
    t_start = time.perf_counter()
    prep = prepare(session, options)
    grid, lin, problem = build_problem(prep, options)
    sol = solve_passes(problem, prep, lin, options)
    reduced = reduce_hessian(problem.hessian_function(sol.x, sol.p), problem.n_theta)
    decrement = gauss_newton_decrement(reduced, np.array(problem.gradient_function(sol.x, sol.p)).ravel())
    if not (np.isfinite(decrement) and decrement < MAX_DECREMENT):
        raise SolverError(
            f"the solver did not converge: {sol.stats['return_status']} after {sol.stats['iter_count']} iterations "
            f"(a further Gauss-Newton step would still reduce chi^2 by {decrement:.3g})"
        )
    sol.stats["gauss_newton_decrement"] = decrement
    cal = assemble(problem, prep, grid, sol, reduced, options, time.perf_counter() - t_start)
    if options.split_check:
        with_split_check(cal, prep.session, options)
    return cal


def with_split_check(cal: Calibration, moving: Session, options: Options) -> None:
    """Add the split-half consistency report (and its warning) to `cal`."""
    report = consistency.split_check(moving, cal, replace(options, split_check=False), calibrate)
    cal.consistency = report
    warning = consistency.split_warning(report)
    if warning:
        cal.warnings.append(warning)


def residual_summary(problem: JointProblem, r: np.ndarray) -> dict:
    """Fit statistics of the whitened residual matrix r (one row per interval)."""
    mag = r[:, :-3].reshape(-1, 3)[problem.grid.sample_mask]
    n_res = mag.size + r[:, -3:].size   # the segments bridging a gap have no magnetometer residual
    dof = n_res - problem.n_x
    return {
        "mag_rms_normalised": float(np.sqrt(np.mean(mag**2))),
        "gyro_rms_normalised": float(np.sqrt(np.mean(r[:, -3:] ** 2))),
        "variance_factor": float(np.sum(r**2)) / dof,
        "residuals": int(n_res),
        "unknowns": int(problem.n_x),
    }


def runs_of_true(mask: np.ndarray) -> list[tuple[int, int]]:
    """(first, last) index of every run of True."""
    edges = np.diff(np.concatenate([[0], mask.astype(int), [0]]))
    return list(zip(np.flatnonzero(edges == 1), np.flatnonzero(edges == -1) - 1))


def suspect_segments(grid: Grid, residuals: np.ndarray) -> list[dict]:
    """Windows where the magnetometer fits far worse than typical (spikes, iron or a magnet near the path)."""
    r = residuals[:, :-3]
    samples = 3 * grid.mag_weight.sum(axis=1)  # residual entries per interval with a magnetometer sample
    t = grid.t_node_s[:-1]
    window = np.floor((t - t[0]) / SUSPECT_WINDOW_S).astype(int)
    n_w = window.max() + 1
    count = np.bincount(window, weights=samples, minlength=n_w)
    rms = np.sqrt(np.bincount(window, weights=np.sum(r**2, axis=1), minlength=n_w) / np.maximum(count, 1))
    has = count > 0   # a window inside a gap in the magnetometer record has nothing to judge
    typical = np.median(rms[has])
    bad = has & (rms > SUSPECT_FACTOR * typical)
    out = []
    for a, b in runs_of_true(bad):
        out.append({
            "t0_s": float(t[0] + a * SUSPECT_WINDOW_S), "t1_s": float(t[0] + (b + 1) * SUSPECT_WINDOW_S),
            "residual_vs_typical": float(rms[a : b + 1].max() / typical),
        })
    return out


def field_magnitude_change(session: Session, R: np.ndarray, h: np.ndarray) -> dict:
    """Largest departure of the calibrated field magnitude |R (y - h)| from 1, over FIELD_WINDOW_S windows.

    The method assumes a homogeneous field: its magnitude must not change along
    the path. A magnet or iron near the path shows as a local change.
    """
    norm = np.linalg.norm(ellipsoid.calibrated_field(R, h, session.mag), axis=1)
    window = np.floor((session.t_mag_s - session.t_mag_s[0]) / FIELD_WINDOW_S).astype(int)
    mean = np.bincount(window, weights=norm) / np.maximum(np.bincount(window), 1)
    dev = np.abs(mean - 1.0)
    worst = int(np.argmax(dev))
    return {"max_fraction": float(dev[worst]), "at_s": float(session.t_mag_s[0] + (worst + 0.5) * FIELD_WINDOW_S),
            "median_fraction": float(np.median(dev))}


def rest_check(found: rests.Rests | None, K_g: np.ndarray, bias_rad_s: np.ndarray) -> dict | None:
    """The bias the rests imply (eps_b = -K_g mean(y_rest)) against the estimate."""
    if found is None or found.gyro_mean_rad_s is None:
        return None
    at_rest = -K_g @ found.gyro_mean_rad_s
    return {
        **found.to_dict(),
        "bias_deg_s": np.rad2deg(at_rest).tolist(),
        "estimate_minus_rest_deg_s": np.rad2deg(bias_rad_s - at_rest).tolist(),
    }


def warnings_for(segments: list[dict], rest: dict | None, analysis: ObservabilityAnalysis, C_b_m: np.ndarray,
                 fit: ellipsoid.EllipsoidFit, field_change: dict) -> list[str]:
    out = []
    if field_change["max_fraction"] > MAX_FIELD_CHANGE:
        out.append(
            f"the field magnitude changes by {100 * field_change['max_fraction']:.1f}% around "
            f"{field_change['at_s']:.1f} s (typically {100 * field_change['median_fraction']:.1f}%): the field is not "
            "homogeneous there (a magnet or iron near the path) or the magnetometer is not linear; this calibration "
            "assumes a homogeneous field, so re-record away from iron, or try --loss huber"
        )
    if fit.uniqueness < ellipsoid.MIN_UNIQUENESS:
        out.append(
            f"the field directions cover little of the sphere (ellipsoid uniqueness {fit.uniqueness:.2f}): "
            "the magnetometer's R and h rest on the gyro as much as on the ellipsoid; turn through more orientations"
        )
    mapping = axis_mapping_warning(C_b_m)
    if mapping:
        out.append(mapping)
    for seg in segments:
        out.append(
            f"the magnetometer does not fit the model during {seg['t0_s']:.1f}-{seg['t1_s']:.1f} s "
            f"(residual {seg['residual_vs_typical']:.1f}x the typical): a magnet or iron near the path, or a spike; "
            "check the recording, or use --loss huber to weigh those samples down"
        )
    if not analysis.full_rank:
        out.append(f"solved with --force although the motion is insufficient: {analysis.summary()}")
    return out


def assemble(problem: JointProblem, prep: Prepared, grid: Grid, sol: Solution, reduced: Reduced,
             options: Options, total_s: float) -> Calibration:
    g = sol.p[: problem.n_glob_p]
    theta = sol.x[: problem.n_theta]
    S, h, K, eps, m_i, tau = (np.array(v) for v in problem.physical_function(theta, g))
    h, eps, m_i, tau = h.ravel(), eps.ravel(), m_i.ravel(), float(tau.item())
    C, Kg = qr_split(K)
    residuals = residual_matrix(problem, sol.x, sol.p)
    fit = residual_summary(problem, residuals)
    # No a-posteriori variance-factor scaling: the noise levels are already calibrated (given, from
    # rests with their correlation, or re-weighted from the residuals' effective scale); the plain
    # factor counts correlated samples as independent and would undo that. It is reported in `fit`.
    cov_theta = np.linalg.inv(reduced.information)
    std = std_from_covariance(propagate(problem, theta, g, cov_theta, C))
    segments = suspect_segments(grid, residuals)
    rest = rest_check(prep.rests, Kg, C.T @ eps)
    fit["suspect_segments"] = segments
    fit["field_change"] = field_magnitude_change(prep.session, np.linalg.inv(S), h)
    a = prep.analysis
    stats = sol.stats
    return Calibration(
        K_g=Kg, bias_rad_s=C.T @ eps, K=K, eps_rad_s=eps, C_b_m=C, R=np.linalg.inv(S), h=h,
        mag_unit=prep.session.mag_unit, field_i=m_i, std=std,
        observability={"rank": a.rank, "condition": a.condition, "tolerance": a.tolerance,
                       "eigenvalues_normalised": a.eigenvalues_normalised.tolist()},
        solver={"method": "nls", "status": stats["return_status"], "iterations": int(stats["iter_count"]),
                "seconds": float(sol.seconds), "total_seconds": float(total_s),
                "gauss_newton_decrement": stats["gauss_newton_decrement"], "passes": sol.passes,
                "nodes": int(grid.nodes), "stride": int(grid.stride), "loss": options.loss},
        noise={"gyro_density_rad_s_sqrt_hz": prep.gyro_density, "mag_std": sol.sigma_mag,
               "mag_std_estimated": prep.sigma_mag, "source": prep.noise_source},
        fit=fit,
        time_offset_s=tau,
        time_offset_estimated=problem.n_theta > N_GLOBAL,
        rests=rest,
        warnings=warnings_for(segments, rest, a, C, prep.fit, fit["field_change"]),
        covariance_theta=cov_theta,
    )
