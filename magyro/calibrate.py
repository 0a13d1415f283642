"""The whole calibration: from a Session to a Calibration (the Python API behind `magyro solve`).

    1. noise levels (given, or estimated from the data)
    2. magnetometer ellipsoid (paper step 1)          -> R0, h0, calibrated field m^m
    3. observability gate on the integral of M^T M    -> exit 3 when rank < 12
    4. linear gyro estimate (paper eq. 13)            -> K0, eps0
    5. nominal attitude by integrating the gyro with K0, eps0
    6. the joint least squares (problem.JointProblem), IPOPT
    7. marginal covariance of the calibration parameters, QR split, std
"""
from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np
from scipy.linalg import solveh_banded

from . import magfit, noise, so3
from .errors import InputError, ObservabilityError, SolverError
from .initial import linear_gyro_estimate
from .observability import ObservabilityAnalysis, analyse
from .problem import N_GLOBAL, Grid, JointProblem, Linearisation, build_grid
from .result import Calibration, qr_split, reported_vector, std_from_covariance
from .session import Session

NODE_RATE_HZ = 100.0
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


@dataclass
class Prepared:
    """Everything before the solve: noise, step-1 fit, gate, initial estimates."""

    session: Session
    sigma_mag: float
    gyro_density: float
    fit: magfit.EllipsoidFit
    field_m: np.ndarray
    analysis: ObservabilityAnalysis


def noise_levels(session: Session, options: Options) -> tuple[float, float]:
    sigma_mag = options.mag_noise_std or noise.mag_noise_std(session.mag)
    density = options.gyro_noise_density_rad_s_sqrt_hz or noise.gyro_noise_density_rad_s_sqrt_hz(
        session.gyro_rad_s, session.gyro_rate_hz
    )
    if not (sigma_mag > 0 and density > 0):
        raise InputError(
            "cannot estimate the sensor noise from the data (the readings do not vary); "
            "pass --mag-noise and --gyro-noise-density"
        )
    return float(sigma_mag), float(density)


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


def prepare(session: Session, options: Options) -> Prepared:
    """Steps 1-3: noise, ellipsoid, observability. Raises ObservabilityError unless forced."""
    sigma_mag, density = noise_levels(session, options)
    gyro_std = density * np.sqrt(session.gyro_rate_hz)
    try:
        fit = magfit.fit_ellipsoid(session.mag, sigma_mag)
    except magfit.DegenerateCloud as cloud:
        field = magfit.surrogate_field_directions(session.mag)
        analysis = analyse(session.t_gyro_s, session.gyro_rad_s, session.t_mag_s, field, gyro_std, sigma_mag / np.mean(np.linalg.norm(session.mag, axis=1)))
        raise ObservabilityError(
            f"{cloud}; the magnetometer's soft/hard iron cannot be fitted. Gyro parameters: {analysis.summary()}",
            analysis,
        ) from None
    field = magfit.calibrated_field(fit.R, fit.h, session.mag)
    check_gyro_unit(session, field)
    analysis = analyse(session.t_gyro_s, session.gyro_rad_s, session.t_mag_s, field, gyro_std, sigma_mag * float(np.mean(np.diag(fit.R))))
    if not analysis.full_rank and not options.force:
        raise ObservabilityError(
            f"the motion does not excite every gyro parameter: {analysis.summary()} (--force solves anyway)", analysis
        )
    return Prepared(session, sigma_mag, density, fit, field, analysis)


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


def linearise(prep: Prepared, grid: Grid) -> Linearisation:
    s = prep.session
    lin0 = linear_gyro_estimate(s.t_gyro_s, s.gyro_rad_s, s.t_mag_s, prep.field_m)
    C = nominal_attitudes(s, lin0.K, lin0.eps, grid.t_node_s)
    m0 = initial_field(C, prep.field_m[grid.node_mag_index])
    S0 = np.linalg.inv(prep.fit.R)
    return Linearisation(S0, prep.fit.h, lin0.K, lin0.eps, m0, C, float(np.mean(np.diag(S0))))


def banded_upper(H_pp_triu) -> np.ndarray:
    """Upper banded storage (bandwidth 5) of the block-tridiagonal attitude block."""
    coo = H_pp_triu.tocoo()
    n = H_pp_triu.shape[0]
    ab = np.zeros((6, n))
    ab[5 + coo.row - coo.col, coo.col] = coo.data
    return ab


@dataclass(frozen=True)
class Reduced:
    """J^T J with the trajectory eliminated: the marginal information of the 23 calibration corrections."""

    information: np.ndarray   # Schur complement H_tt - H_tp D^-1 H_pt
    H_tp: np.ndarray
    D_banded: np.ndarray      # attitude block D, upper banded storage
    Dinv_Hpt: np.ndarray      # D^-1 H_pt


def reduce_hessian(H_triu) -> Reduced:
    """Eliminate the attitudes from triu(J^T J) by a banded solve (no dense N x N inverse)."""
    G = N_GLOBAL
    H_tt = H_triu[:G, :G].toarray()
    H_tt = H_tt + np.triu(H_tt, 1).T
    H_tp = H_triu[:G, G:].toarray()
    ab = banded_upper(H_triu[G:, G:])
    Dinv_Hpt = solveh_banded(ab, H_tp.T, check_finite=False)
    return Reduced(H_tt - H_tp @ Dinv_Hpt, H_tp, ab, Dinv_Hpt)


def gauss_newton_decrement(red: Reduced, grad) -> float:
    """g^T H^-1 g: how much the objective (chi^2 units) a further Gauss-Newton step would still remove."""
    g_t, g_p = grad[:N_GLOBAL], grad[N_GLOBAL:]
    Dinv_gp = solveh_banded(red.D_banded, g_p, check_finite=False)
    x_t = np.linalg.solve(red.information, g_t - red.H_tp @ Dinv_gp)
    x_p = Dinv_gp - red.Dinv_Hpt @ x_t
    return float(g_t @ x_t + g_p @ x_p)


def to_scipy(dm):
    import scipy.sparse as sps

    sp = dm.sparsity()
    return sps.csc_matrix((np.array(dm.nonzeros()), np.array(sp.row()), np.array(sp.colind())), shape=dm.shape)


def propagate(problem: JointProblem, theta, g, cov_theta, C_ref) -> np.ndarray:
    """Covariance of the reported vector by central differences through the QR split."""
    def f(th):
        S, h, K, eps, m = (np.array(v) for v in problem.physical_function(th, g))
        return reported_vector(K, eps.ravel(), S, h.ravel(), m.ravel(), C_ref)

    step = 1e-6
    J = np.empty((len(f(theta)), N_GLOBAL))
    for i in range(N_GLOBAL):
        e = np.zeros(N_GLOBAL)
        e[i] = step
        J[:, i] = (f(theta + e) - f(theta - e)) / (2 * step)
    return J @ cov_theta @ J.T


def predicted_std(prep: Prepared, options: Options | None = None) -> dict:
    """One-sigma accuracy this recording can give, before solving.

    The Gauss-Newton (Fisher) information of the joint problem at the initial
    estimate, with the session's noise levels, trajectory marginalised out and
    propagated like the solved std. Entries are inf where the information is
    singular (unobservable).
    """
    options = options or Options()
    s = prep.session
    grid = build_grid(s.t_gyro_s, s.gyro_rad_s, s.t_mag_s, options.stride or default_stride(s))
    lin = linearise(prep, grid)
    problem = JointProblem(grid, compiled=options.compiled)
    p = problem.parameters(lin, s.mag, prep.sigma_mag, prep.gyro_density)
    x0 = np.zeros(problem.n_x)
    info = reduce_hessian(to_scipy(problem.hessian_function(x0, p))).information
    lam = np.linalg.eigvalsh(info)
    if lam[0] <= lam[-1] * 1e-14:
        return {k: np.full_like(np.asarray(v, dtype=float), np.inf) for k, v in
                std_from_covariance(np.eye(33)).items()}
    C0, _ = qr_split(lin.K0)
    g = p[: problem.n_glob_p]
    return std_from_covariance(propagate(problem, np.zeros(N_GLOBAL), g, np.linalg.inv(info), C0))


def calibrate(session: Session, options: Options | None = None) -> Calibration:
    """Calibrate gyro and magnetometer from one session (the joint least squares)."""
    options = options or Options()
    t_start = time.perf_counter()
    prep = prepare(session, options)
    grid = build_grid(session.t_gyro_s, session.gyro_rad_s, session.t_mag_s, options.stride or default_stride(session))
    lin = linearise(prep, grid)
    problem = JointProblem(grid, compiled=options.compiled)
    p = problem.parameters(lin, session.mag, prep.sigma_mag, prep.gyro_density)
    solver = problem.solver({"ipopt.max_iter": options.max_iter})
    t_solve = time.perf_counter()
    sol = solver(x0=np.zeros(problem.n_x), p=p)
    solve_s = time.perf_counter() - t_solve
    stats = solver.stats()
    x = np.array(sol["x"]).ravel()
    reduced = reduce_hessian(to_scipy(problem.hessian_function(x, p)))
    decrement = gauss_newton_decrement(reduced, np.array(problem.gradient_function(x, p)).ravel())
    if not (np.isfinite(decrement) and decrement < MAX_DECREMENT):
        raise SolverError(
            f"the solver did not converge: {stats['return_status']} after {stats['iter_count']} iterations "
            f"(a further Gauss-Newton step would still reduce chi^2 by {decrement:.3g})"
        )
    stats = dict(stats, gauss_newton_decrement=decrement)
    return assemble(problem, prep, grid, p, x, reduced, stats, solve_s, time.perf_counter() - t_start)


def residual_summary(problem: JointProblem, x, p) -> dict:
    r = np.array(problem.residual_function(x, p)).reshape(problem.n_int, problem.n_res_per_interval)
    n_res = r.size
    ssr = float(np.sum(r**2))
    dof = n_res - problem.n_x
    return {
        "mag_rms_normalised": float(np.sqrt(np.mean(r[:, :-3] ** 2))),
        "gyro_rms_normalised": float(np.sqrt(np.mean(r[:, -3:] ** 2))),
        "variance_factor": ssr / dof,
        "residuals": int(n_res),
        "unknowns": int(problem.n_x),
    }


def assemble(problem, prep: Prepared, grid: Grid, p, x, reduced: Reduced, stats, solve_s: float, total_s: float) -> Calibration:
    g = p[: problem.n_glob_p]
    theta = x[:N_GLOBAL]
    S, h, K, eps, m_i = (np.array(v) for v in problem.physical_function(theta, g))
    h, eps, m_i = h.ravel(), eps.ravel(), m_i.ravel()
    C, Kg = qr_split(K)
    fit = residual_summary(problem, x, p)
    cov_theta = np.linalg.inv(reduced.information) * fit["variance_factor"]
    std = std_from_covariance(propagate(problem, theta, g, cov_theta, C))
    a = prep.analysis
    return Calibration(
        K_g=Kg, bias_rad_s=C.T @ eps, K=K, eps_rad_s=eps, C_b_m=C, R=np.linalg.inv(S), h=h,
        mag_unit=prep.session.mag_unit, field_i=m_i, std=std,
        observability={"rank": a.rank, "condition": a.condition, "tolerance": a.tolerance,
                       "eigenvalues_normalised": a.eigenvalues_normalised.tolist()},
        solver={"method": "nls", "status": stats["return_status"], "iterations": int(stats["iter_count"]),
                "seconds": float(solve_s), "total_seconds": float(total_s),
                "gauss_newton_decrement": stats["gauss_newton_decrement"], "nodes": int(grid.nodes),
                "stride": int(grid.stride)},
        noise={"gyro_density_rad_s_sqrt_hz": prep.gyro_density, "mag_std": prep.sigma_mag},
        fit=fit,
        covariance_theta=cov_theta,
    )
