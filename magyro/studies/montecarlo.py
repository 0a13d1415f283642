"""Monte Carlo accuracy study: the paper's Table I, with the Cramer-Rao bound beside it.

`run_montecarlo(problem, runs)` simulates `runs` sessions of one problem with
noise seeds seed0, seed0+1, ... (the motion is fixed by the problem), solves
each with one or more methods ("nls" the joint least squares, "ekf" the
paper's filter; "nls,ekf" solves the SAME sessions with both), and tabulates,
per parameter:

    truth, mean, std (ddof=1) over the successful runs,
    CRLB            one-sigma Cramer-Rao bound (crlb.cramer_rao_std, at truth),
    std / CRLB      1 for an efficient unbiased estimator,
    err / std       (mean - truth) / std, the bias in units of the spread,
    rep / act       mean over runs of the std the solver reported / the actual std,
    paper std       Wu & Pei's Table I std, where the paper gives one,
    vs paper        "yes" when magyro's std is smaller; otherwise whether the CRLB
                    would allow it ("no (CRLB allows)") or not ("no (CRLB > paper)").

Parameters, named after the calibration JSON (indices 0-based, as in its lists):

    K_g[i,j]              upper triangle (6)
    bias_deg_s[i]         eps_b in deg/s (3)
    misalignment_deg[i]   d = Log(C_est^T C_true) in deg, i.e. C_true = C_est Exp(d)
                          (`result.misalignment_vector(C_est, C_true)`, the SPEC's
                          definition of std.misalignment_deg); truth 0 (3)
    euler_deg[i]          [roll, pitch, yaw] of C_est (the paper's dcm2eul column), for
                          the comparison with the paper's misalignment std; solvers do
                          not report an Euler std, so rep/act is empty there (3)
    R[i,j], h[i]          magnetometer soft iron (upper triangle, 6) and hard iron (3)
    time_offset_s         magnetometer lag, when the method estimates it

The CRLB is computed once, at seed0's session: the Fisher information is
linearised at the true parameters and the true attitude, so the noise
realisation enters only through the gyro samples that drive the attitude
integration in the Jacobian (and through the rests found at the ends, if any);
from seed to seed that changes it by far less than the sampling error of a
50-run std. The Euler-angle CRLB maps the 3x3 CRLB covariance of d through the
Jacobian of dcm2eul; the other entries are `crlb.cramer_rao_std` as is.

Failed runs (any exception: unusable input, observability gate, solver
failure, a crashed worker) are kept with their seed and message and counted;
the table is built from the successful runs.
"""
from __future__ import annotations

import concurrent.futures as cf
import contextlib
import csv
import datetime as _dt
import importlib
import io
import json
import math
import multiprocessing
import os
import time
import traceback
from dataclasses import dataclass, field
from typing import Callable, Sequence

import numpy as np

from magyro import __version__

from magyro import so3
from magyro.errors import InputError
from magyro.io.sessions import one_line
from magyro.result.calibration import UPPER, misalignment_vector
from magyro.studies.simulate import Problem, simulate

SCHEMA = "magyro.montecarlo/1"
METHODS = ("nls", "ekf")
GYRO_GROUPS = ("K_g", "bias_deg_s", "misalignment_deg")
WORKER_THREAD_VARIABLES = ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS",
                           "VECLIB_MAXIMUM_THREADS", "NUMEXPR_NUM_THREADS")
DEFAULT_START_METHOD = "spawn"

# Targets of issue 4 for the gyro parameters (K_g upper 6, bias 3, misalignment d 3).
TARGET_STD_OVER_CRLB = 1.10
TARGET_ABS_ERR_OVER_STD = 0.3
TARGET_REPORTED_OVER_ACTUAL = (0.8, 1.25)

# Wu & Pei, Table I: the one-sigma over their 50 runs (EKF, their own 100 s motion).
PAPER_TABLE1_STD = {
    **{f"K_g[{i},{j}]": s for (i, j), s in zip(UPPER, (3.0e-4, 2.6e-4, 5.5e-4, 1.4e-4, 3.0e-4, 2.6e-4))},
    **{f"bias_deg_s[{i}]": s for i, s in enumerate((5.8e-3, 3.6e-3, 4.5e-3))},
    **{f"euler_deg[{i}]": s for i, s in enumerate((0.008, 0.018, 0.022))},
}
PAPER_TABLE1_MEAN = {
    **{f"K_g[{i},{j}]": s for (i, j), s in zip(UPPER, (1.1000, 0.0997, 0.1488, 1.2001, 0.2000, 1.3000))},
    **{f"bias_deg_s[{i}]": s for i, s in enumerate((0.997, 3.002, 1.997))},
    **{f"euler_deg[{i}]": s for i, s in enumerate((9.993, 19.969, 15.031))},
}
# The paper's simulation, to decide whether its Table I applies to a problem.
PAPER_SETUP = {"duration_s": 100.0, "gyro_noise_density_deg_s_sqrt_hz": 0.02, "mag_noise_std": 0.01,
               "K_g": [[1.1, 0.1, 0.15], [0.0, 1.2, 0.2], [0.0, 0.0, 1.3]], "gyro_bias_deg_s": [1.0, 3.0, 2.0],
               "misalignment_euler_deg": [10.0, 20.0, 15.0]}


# --------------------------------------------------------------------------- parameters


@dataclass(frozen=True)
class Parameter:
    """One row of the table."""

    name: str     # e.g. "K_g[0,1]"
    group: str    # "K_g", "bias_deg_s", "misalignment_deg", "euler_deg", "R", "h", "time_offset_s"
    unit: str


def parameters(mag_unit: str, with_time_offset: bool) -> list[Parameter]:
    """The table's rows in order."""
    rows = [Parameter(f"K_g[{i},{j}]", "K_g", "-") for i, j in UPPER]
    rows += [Parameter(f"bias_deg_s[{i}]", "bias_deg_s", "deg/s") for i in range(3)]
    rows += [Parameter(f"misalignment_deg[{i}]", "misalignment_deg", "deg") for i in range(3)]
    rows += [Parameter(f"euler_deg[{i}]", "euler_deg", "deg") for i in range(3)]
    rows += [Parameter(f"R[{i},{j}]", "R", f"1/{mag_unit}") for i, j in UPPER]
    rows += [Parameter(f"h[{i}]", "h", mag_unit) for i in range(3)]
    if with_time_offset:
        rows.append(Parameter("time_offset_s", "time_offset_s", "s"))
    return rows


def _flatten(K_g, bias_deg_s, misalignment_deg, euler_deg, R, h, time_offset_s=None) -> dict[str, float]:
    out: dict[str, float] = {}
    if K_g is not None:
        out.update({f"K_g[{i},{j}]": float(np.asarray(K_g)[i, j]) for i, j in UPPER})
    if bias_deg_s is not None:
        out.update({f"bias_deg_s[{i}]": float(v) for i, v in enumerate(bias_deg_s)})
    if misalignment_deg is not None:
        out.update({f"misalignment_deg[{i}]": float(v) for i, v in enumerate(misalignment_deg)})
    if euler_deg is not None:
        out.update({f"euler_deg[{i}]": float(v) for i, v in enumerate(euler_deg)})
    if R is not None:
        out.update({f"R[{i},{j}]": float(np.asarray(R)[i, j]) for i, j in UPPER})
    if h is not None:
        out.update({f"h[{i}]": float(v) for i, v in enumerate(h)})
    if time_offset_s is not None:
        out["time_offset_s"] = float(time_offset_s)
    return out


def truth_values(problem: Problem) -> dict[str, float]:
    """The true value of every row; the misalignment error d is 0 at truth."""
    return _flatten(problem.K_g, problem.gyro_bias_deg_s, np.zeros(3), so3.dcm_to_euler(problem.C_b_m),
                    problem.R, problem.hard_iron, problem.mag_time_offset_s)


def estimate_values(cal, problem: Problem) -> dict[str, float]:
    """A calibration's estimate of every row.

    misalignment_deg = d with C_true = C_est Exp(d) (misalignment_vector(C_est, C_true));
    Euler angles are unwrapped to within 180 deg of the truth so a mean makes sense.
    """
    C_true = problem.C_b_m
    d_deg = np.rad2deg(misalignment_vector(np.asarray(cal.C_b_m), C_true))
    e_true = so3.dcm_to_euler(C_true)
    e = e_true + (so3.dcm_to_euler(np.asarray(cal.C_b_m)) - e_true + 180.0) % 360.0 - 180.0
    tau = cal.time_offset_s if getattr(cal, "time_offset_estimated", False) else None
    return _flatten(cal.K_g, np.rad2deg(np.asarray(cal.bias_rad_s)), d_deg, e, cal.R, cal.h, tau)


def std_values(std: dict, time_offset: bool = True) -> dict[str, float]:
    """A std dict laid out like Calibration.std (or crlb.cramer_rao_std) as rows (no Euler rows)."""
    get = lambda k: None if std.get(k) is None else np.asarray(std[k], dtype=float)  # noqa: E731
    tau = std.get("time_offset_s") if time_offset else None
    return _flatten(get("K_g"), get("bias_deg_s"), get("misalignment_deg"), None, get("R"), get("h"),
                    None if tau is None else float(np.asarray(tau).reshape(-1)[0]))


def matches_paper(problem: Problem) -> bool:
    """True when the problem is the paper's simulation (so its Table I std applies)."""
    p = PAPER_SETUP
    return (math.isclose(problem.duration_s, p["duration_s"])
            and math.isclose(problem.gyro_noise_density_deg_s_sqrt_hz, p["gyro_noise_density_deg_s_sqrt_hz"])
            and math.isclose(problem.mag_noise_std / problem.field_strength, p["mag_noise_std"])
            and np.allclose(problem.K_g, p["K_g"]) and np.allclose(problem.gyro_bias_deg_s, p["gyro_bias_deg_s"])
            and np.allclose(problem.misalignment_euler_deg, p["misalignment_euler_deg"]))


# --------------------------------------------------------------------------- the CRLB


def crlb_covariance(problem: Problem, session, options) -> np.ndarray:
    """Covariance of the reported vector (result.REPORTED layout) at truth: the Euler-angle CRLB needs the
    3x3 covariance of d, not only its diagonal."""
    from magyro.studies.crlb import cramer_rao_covariance

    return cramer_rao_covariance(problem, session, options)


def euler_jacobian_deg_per_rad(C: np.ndarray, step: float = 1e-6) -> np.ndarray:
    """d dcm2eul(C Exp(x)) / dx at x = 0, deg per rad (3x3, central differences)."""
    J = np.empty((3, 3))
    for k in range(3):
        e = np.zeros(3)
        e[k] = step
        J[:, k] = (so3.dcm_to_euler(C @ so3.exp_so3(e)) - so3.dcm_to_euler(C @ so3.exp_so3(-e))) / (2 * step)
    return J


def euler_crlb_deg(problem: Problem, session, options) -> np.ndarray:
    """CRLB one-sigma of [roll, pitch, yaw] of C_b^m, deg: J cov(d) J^T with d in rad."""
    from magyro.result.calibration import REPORTED

    cov = crlb_covariance(problem, session, options)
    sl = REPORTED["misalignment_deg"]
    cov_d_rad = np.deg2rad(np.deg2rad(cov[sl, sl]))
    J = euler_jacobian_deg_per_rad(problem.C_b_m)
    return np.sqrt(np.maximum(np.diag(J @ cov_d_rad @ J.T), 0.0))


def _crlb_task(problem: Problem, seed: int, options) -> dict:
    """The CRLB rows at `seed`'s session, or the reason there is none."""
    from magyro.studies.crlb import cramer_rao_std

    t0 = time.perf_counter()
    try:
        session, _ = simulate(problem, seed)
        values = std_values(cramer_rao_std(problem, session, options), options.estimate_time_offset)
        values.update({f"euler_deg[{i}]": float(v) for i, v in enumerate(euler_crlb_deg(problem, session, options))})
        return {"seed": seed, "values": values, "error": None, "seconds": time.perf_counter() - t0}
    except Exception as exc:  # the table is still useful without a CRLB
        return {"seed": seed, "values": {}, "error": one_line(exc, limit=None), "seconds": time.perf_counter() - t0}


# --------------------------------------------------------------------------- one run


def solve_nls(session, options):
    from magyro.nls.solve import calibrate

    return calibrate(session, options)


def solve_ekf(session, options):
    return _ekf_function()(session, options)[0]


# method name -> function(session, options) -> Calibration. Looked up at call time (tests patch it).
SOLVERS: dict[str, Callable] = {"nls": solve_nls, "ekf": solve_ekf}


def _ekf_function():
    """magyro.ekf.filter.ekf_calibrate, or InputError when that module is not there (yet)."""
    try:
        module = importlib.import_module("magyro.ekf")
        return module.ekf_calibrate
    except (ImportError, AttributeError):
        raise InputError("method ekf is not available yet (magyro.ekf.filter.ekf_calibrate is missing)") from None


def parse_methods(method: str | Sequence[str]) -> list[str]:
    """"nls", "ekf", "nls,ekf" or a list -> checked list of distinct methods, in order."""
    names = [m.strip().lower() for m in (method.split(",") if isinstance(method, str) else method)]
    names = [m for m in names if m]
    if not names:
        raise InputError(f"no method given; use one of {', '.join(METHODS)} or a comma-separated list")
    unknown = [m for m in names if m not in SOLVERS]
    if unknown:
        raise InputError(f"unknown method(s) {', '.join(unknown)}; use {', '.join(METHODS)} or e.g. nls,ekf")
    if len(set(names)) != len(names):
        raise InputError(f"method listed twice in {','.join(names)}")
    if "ekf" in names:
        _ekf_function()
    return names


@dataclass
class Outcome:
    """One method on one seed: the estimates, or why there are none."""

    seed: int
    method: str
    ok: bool
    seconds: float = 0.0                               # wall time of the solve
    estimate: dict = field(default_factory=dict)       # row name -> value
    reported_std: dict = field(default_factory=dict)   # row name -> the solver's one-sigma
    solver: dict = field(default_factory=dict)         # status, iterations, ...
    error: str | None = None
    error_type: str | None = None
    exit_code: int | None = None                       # the CLI exit code this error has
    cpu_seconds: float = 0.0                           # CPU time of the solve (its process only)

    def to_dict(self) -> dict:
        d = {"seed": self.seed, "method": self.method, "ok": self.ok, "seconds": self.seconds,
             "cpu_seconds": self.cpu_seconds}
        if self.ok:
            d.update(estimate=_json_dict(self.estimate), reported_std=_json_dict(self.reported_std),
                     solver=_json_dict(self.solver))
        else:
            d.update(error=self.error, error_type=self.error_type, exit_code=self.exit_code)
        return d


def _failure(seed: int, method: str, exc: BaseException, seconds: float) -> Outcome:
    return Outcome(seed, method, False, seconds, error=one_line(exc, limit=None), error_type=type(exc).__name__,
                   exit_code=int(getattr(exc, "exit_code", 1)))


def run_seed(problem: Problem, seed: int, methods: Sequence[str], options) -> list[Outcome]:
    """Simulate seed's session once and solve it with every method; never raises (but on Ctrl-C)."""
    t0 = time.perf_counter()
    try:
        session, _ = simulate(problem, seed)
    except Exception as exc:
        return [_failure(seed, m, exc, time.perf_counter() - t0) for m in methods]
    out = []
    for m in methods:
        t0, c0 = time.perf_counter(), time.process_time()
        try:
            cal = SOLVERS[m](session, options)
            est = estimate_values(cal, problem)
            rep = std_values(cal.std, "time_offset_s" in est)
            solver = {k: cal.solver.get(k) for k in ("method", "status", "iterations", "seconds") if k in cal.solver}
            out.append(Outcome(seed, m, True, time.perf_counter() - t0, est, rep, solver))
        except Exception as exc:
            if os.environ.get("MAGYRO_DEBUG"):
                traceback.print_exc()
            out.append(_failure(seed, m, exc, time.perf_counter() - t0))
        out[-1].cpu_seconds = time.process_time() - c0
    return out


def _worker_init() -> None:
    """Pool initializer: one BLAS/OpenMP thread per worker (the env is also set before spawning)."""
    for name in WORKER_THREAD_VARIABLES:
        os.environ[name] = "1"


@contextlib.contextmanager
def _single_threaded_children():
    """Set the thread-count variables while the pool's workers start (spawned children read them at import)."""
    saved = {name: os.environ.get(name) for name in WORKER_THREAD_VARIABLES}
    try:
        for name in WORKER_THREAD_VARIABLES:
            os.environ[name] = "1"
        yield
    finally:
        for name, value in saved.items():
            if value is None:
                os.environ.pop(name, None)
            else:
                os.environ[name] = value


# --------------------------------------------------------------------------- statistics


@dataclass
class Row:
    """One parameter's statistics over the successful runs of one method."""

    name: str
    group: str
    unit: str
    truth: float
    n: int
    mean: float
    std: float
    crlb: float
    std_over_crlb: float
    mean_error_over_std: float
    reported_over_actual: float
    paper_std: float | None = None
    paper_mean: float | None = None
    vs_paper: str = ""

    def to_dict(self) -> dict:
        return {k: _json_number(v) for k, v in self.__dict__.items()}


def _nan() -> float:
    return float("nan")


def _ratio(a: float, b: float) -> float:
    return a / b if (np.isfinite(a) and np.isfinite(b) and b != 0) else _nan()


def vs_paper(std: float, crlb: float, paper_std: float | None) -> str:
    """Does magyro's std beat the paper's; if not, would the CRLB allow it?"""
    if paper_std is None or not np.isfinite(std):
        return ""
    if std < paper_std:
        return "yes"
    if np.isfinite(crlb) and crlb < paper_std:
        return "no (CRLB allows)"
    return "no (CRLB > paper)" if np.isfinite(crlb) else "no"


def table_rows(params: Sequence[Parameter], truth: dict, outcomes: Sequence[Outcome], crlb: dict,
               paper: dict | None, paper_mean: dict | None = None) -> list[Row]:
    """The statistics of every parameter over the successful outcomes."""
    ok = [o for o in outcomes if o.ok]
    rows = []
    for p in params:
        values = np.array([o.estimate[p.name] for o in ok if p.name in o.estimate], dtype=float)
        reported = np.array([o.reported_std[p.name] for o in ok if p.name in o.reported_std], dtype=float)
        n = len(values)
        mean = float(values.mean()) if n else _nan()
        std = float(values.std(ddof=1)) if n >= 2 else _nan()
        t = truth.get(p.name, _nan())
        c = crlb.get(p.name, _nan())
        paper_std = (paper or {}).get(p.name)
        rows.append(Row(
            name=p.name, group=p.group, unit=p.unit, truth=t, n=n, mean=mean, std=std, crlb=c,
            std_over_crlb=_ratio(std, c), mean_error_over_std=_ratio(mean - t, std),
            reported_over_actual=_ratio(float(reported.mean()), std) if len(reported) else _nan(),
            paper_std=paper_std, paper_mean=(paper_mean or {}).get(p.name), vs_paper=vs_paper(std, c, paper_std),
        ))
    return rows


def std_ratio_interval(n: int, level: float = 0.95) -> tuple[float, float]:
    """Where std/CRLB of an efficient unbiased estimator falls with probability `level` over n runs.

    (n-1) s^2 / sigma^2 ~ chi^2(n-1) for normal estimates, so s / sigma lies in
    [sqrt(q_lo / (n-1)), sqrt(q_hi / (n-1))].
    """
    if n < 2:
        return _nan(), _nan()
    from scipy.stats import chi2

    a = (1.0 - level) / 2.0
    return math.sqrt(chi2.ppf(a, n - 1) / (n - 1)), math.sqrt(chi2.ppf(1.0 - a, n - 1) / (n - 1))


def err_over_std_bound(n: int, level: float = 0.95) -> float:
    """|mean error| / std of an unbiased estimator stays below this with probability `level` over n runs.

    (mean - truth) / (s / sqrt(n)) ~ Student t(n-1), so |mean - truth| / s < t_q(n-1) / sqrt(n).
    """
    if n < 2:
        return _nan()
    from scipy.stats import t

    return float(t.ppf(0.5 + level / 2.0, n - 1) / math.sqrt(n))


def target_checks(rows: Sequence[Row]) -> dict:
    """The issue's targets on the gyro parameters (K_g 6, bias 3, misalignment d 3)."""
    gyro = [r for r in rows if r.group in GYRO_GROUPS]
    lo, hi = TARGET_REPORTED_OVER_ACTUAL

    def check(name, value_of, ok_of, limit):
        values = {r.name: value_of(r) for r in gyro}
        failing = [k for k, v in values.items() if not (np.isfinite(v) and ok_of(v))]
        finite = [v for v in values.values() if np.isfinite(v)]
        return {"target": limit, "pass": not failing and bool(gyro), "failing": failing,
                "worst": _json_number(max(finite, key=lambda v: abs(v - 1.0) if name == "reported_over_actual" else abs(v)) if finite else None)}

    return {
        "std_over_crlb": check("std_over_crlb", lambda r: r.std_over_crlb, lambda v: v <= TARGET_STD_OVER_CRLB,
                               f"<= {TARGET_STD_OVER_CRLB}"),
        "abs_mean_error_over_std": check("abs_mean_error_over_std", lambda r: abs(r.mean_error_over_std),
                                         lambda v: v <= TARGET_ABS_ERR_OVER_STD, f"<= {TARGET_ABS_ERR_OVER_STD}"),
        "reported_over_actual": check("reported_over_actual", lambda r: r.reported_over_actual,
                                      lambda v: lo <= v <= hi, f"in [{lo}, {hi}]"),
    }


# --------------------------------------------------------------------------- the result


@dataclass
class MethodResult:
    """One method's table, runs and failures."""

    method: str
    rows: list[Row]
    outcomes: list[Outcome]

    @property
    def failed(self) -> list[Outcome]:
        return [o for o in self.outcomes if not o.ok]

    @property
    def succeeded(self) -> int:
        return sum(o.ok for o in self.outcomes)

    def row(self, name: str) -> Row:
        return next(r for r in self.rows if r.name == name)

    def targets(self) -> dict:
        return target_checks(self.rows)

    def to_dict(self) -> dict:
        solve_s = [o.seconds for o in self.outcomes if o.ok]
        cpu_s = [o.cpu_seconds for o in self.outcomes if o.ok]
        return {
            "method": self.method,
            "succeeded": self.succeeded,
            "failed": len(self.failed),
            "failures": [o.to_dict() for o in self.failed],
            "solve_seconds_mean": _json_number(float(np.mean(solve_s)) if solve_s else None),
            "solve_cpu_seconds_mean": _json_number(float(np.mean(cpu_s)) if cpu_s else None),
            "parameters": [r.to_dict() for r in self.rows],
            "targets": self.targets(),
            "runs": [o.to_dict() for o in self.outcomes],
        }


@dataclass
class MonteCarloResult:
    problem: str
    problem_source: str
    runs: int
    seed0: int
    jobs: int
    methods: dict[str, MethodResult]
    truth: dict
    crlb: dict
    crlb_seed: int
    crlb_error: str | None
    paper_applies: bool
    wall_s: float
    start_method: str | None
    created: str
    mag_unit: str = ""

    @property
    def seeds(self) -> list[int]:
        return list(range(self.seed0, self.seed0 + self.runs))

    @property
    def failed_count(self) -> int:
        return sum(len(m.failed) for m in self.methods.values())

    @property
    def all_succeeded(self) -> bool:
        return self.failed_count == 0

    def __getitem__(self, method: str) -> MethodResult:
        return self.methods[method]

    # -- JSON
    def to_dict(self) -> dict:
        lo, hi = std_ratio_interval(min((m.succeeded for m in self.methods.values()), default=0))
        return {
            "schema": SCHEMA,
            "magyro_version": __version__,
            "created": self.created,
            "problem": {"name": self.problem, "source": self.problem_source, "mag_unit": self.mag_unit},
            "runs": self.runs,
            "seeds": self.seeds,
            "jobs": self.jobs,
            "start_method": self.start_method,
            "wall_seconds": self.wall_s,
            "all_succeeded": self.all_succeeded,
            "failed": self.failed_count,
            "truth": self.truth,
            "crlb": {"seed": self.crlb_seed, "error": self.crlb_error, "std": _json_dict(self.crlb),
                     "note": "Fisher information of the joint least squares at the true parameters and attitude "
                             "(crlb.cramer_rao_std), at the session of the first seed; the noise realisation enters "
                             "only through the gyro samples in the Jacobian. Euler-angle rows: J cov(d) J^T."},
            "misalignment_definition": "misalignment_deg = d = Log(C_b_m_est^T C_b_m_true) in deg "
                                       "(C_true = C_est Exp(d), result.misalignment_vector(C_est, C_true)); truth 0",
            "paper_table1": {"applies": self.paper_applies, "std": PAPER_TABLE1_STD if self.paper_applies else None,
                             "mean": PAPER_TABLE1_MEAN if self.paper_applies else None},
            "std_over_crlb_95pct_interval_if_efficient": [_json_number(lo), _json_number(hi)],
            "methods": {name: m.to_dict() for name, m in self.methods.items()},
        }

    def to_json(self) -> str:
        return json.dumps(self.to_dict(), indent=2, allow_nan=False)

    # -- CSV (the table, one row per method and parameter)
    CSV_COLUMNS = ("method", "parameter", "group", "unit", "truth", "n", "mean", "std", "crlb", "std_over_crlb",
                   "mean_error_over_std", "reported_over_actual", "paper_std", "paper_mean", "vs_paper")

    def to_csv(self) -> str:
        buf = io.StringIO()
        w = csv.writer(buf, lineterminator="\n")
        w.writerow(self.CSV_COLUMNS)
        for name, m in self.methods.items():
            for r in m.rows:
                d = r.__dict__
                w.writerow([name, r.name] + ["" if _is_missing(d[k]) else _csv_value(d[k]) for k in self.CSV_COLUMNS[2:]])
        return buf.getvalue()

    # -- text
    def table(self) -> str:
        out = []
        seeds = f"seeds {self.seed0}..{self.seed0 + self.runs - 1}" if self.runs > 1 else f"seed {self.seed0}"
        for name, m in self.methods.items():
            out.append(f"{self.problem}: {self.runs} runs ({seeds}), method {name}: "
                       f"{m.succeeded} succeeded, {len(m.failed)} failed")
            out.append(format_rows(m.rows, self.paper_applies))
            lo, hi = std_ratio_interval(m.succeeded)
            if np.isfinite(lo):
                out.append(f"with {m.succeeded} runs an efficient unbiased estimator's std/CRLB lies in [{lo:.2f}, {hi:.2f}] "
                           f"and its |err/std| below {err_over_std_bound(m.succeeded):.2f} (each 95 %)")
            out.extend(_targets_text(m.targets()))
            if self.paper_applies:
                out.append(_paper_summary(m.rows))
            for o in m.failed:
                out.append(f"FAILED seed {o.seed}: {o.error_type} (exit {o.exit_code}): {o.error}")
            out.append("")
        out.append("misalignment_deg = d, C_b_m(true) = C_b_m(est) Exp(d); euler_deg = dcm2eul(C_b_m(est)) "
                   "[roll, pitch, yaw], the paper's column.")
        if self.crlb_error:
            out.append(f"no CRLB: {self.crlb_error}")
        else:
            out.append(f"CRLB at truth, computed once at seed {self.crlb_seed}'s session.")
        out.append(f"{self.wall_s:.1f} s wall, {self.jobs} job(s)")
        return "\n".join(out)


def _is_missing(v) -> bool:
    return v is None or (isinstance(v, float) and not np.isfinite(v))


def _csv_value(v):
    return repr(float(v)) if isinstance(v, (float, np.floating)) else v


def _json_number(v):
    if isinstance(v, (float, np.floating)):
        return float(v) if np.isfinite(v) else None
    if isinstance(v, np.integer):
        return int(v)
    return v


def _json_dict(d: dict) -> dict:
    return {k: _json_number(v) for k, v in d.items()}


def _fmt(v, spec: str) -> str:
    return "-" if _is_missing(v) else format(v, spec)


def format_rows(rows: Sequence[Row], with_paper: bool) -> str:
    header = ["parameter", "truth", "mean", "std", "CRLB", "std/CRLB", "err/std", "rep/act"]
    if with_paper:
        header += ["paper std", "vs paper"]
    lines = [header]
    for r in rows:
        cells = [r.name, _fmt(r.truth, ".6g"), _fmt(r.mean, ".7g"), _fmt(r.std, ".3g"), _fmt(r.crlb, ".3g"),
                 _fmt(r.std_over_crlb, ".2f"), _fmt(r.mean_error_over_std, "+.2f"), _fmt(r.reported_over_actual, ".2f")]
        if with_paper:
            cells += [_fmt(r.paper_std, ".3g"), r.vs_paper]
        lines.append(cells)
    widths = [max(len(line[i]) for line in lines) for i in range(len(header))]
    text = []
    for line in lines:
        parts = [line[0].ljust(widths[0])] + [c.rjust(w) for c, w in zip(line[1:-1], widths[1:-1])]
        parts.append(line[-1].ljust(widths[-1]) if with_paper else line[-1].rjust(widths[-1]))
        text.append("  ".join(parts).rstrip())
    return "\n".join(text)


def _targets_text(targets: dict) -> list[str]:
    out = []
    for name, t in targets.items():
        if t["worst"] is None:
            out.append(f"target gyro {name} {t['target']}: n/a (fewer than 2 successful runs)")
            continue
        verdict = "PASS" if t["pass"] else "FAIL (" + ", ".join(t["failing"]) + ")"
        out.append(f"target gyro {name} {t['target']}: {verdict}; worst {_fmt(t['worst'], '.3f')}")
    return out


def _paper_summary(rows: Sequence[Row]) -> str:
    compared = [r for r in rows if r.paper_std is not None and np.isfinite(r.std)]
    better = [r for r in compared if r.vs_paper == "yes"]
    allows = [r.name for r in compared if r.vs_paper == "no (CRLB allows)"]
    forbids = [r.name for r in compared if r.vs_paper == "no (CRLB > paper)"]
    text = f"vs the paper's Table I std: smaller in {len(better)} of {len(compared)}"
    if allows:
        text += f"; larger although the CRLB allows smaller: {', '.join(allows)}"
    if forbids:
        text += f"; larger where even the CRLB exceeds the paper's std (this motion cannot do better): {', '.join(forbids)}"
    return text


# --------------------------------------------------------------------------- the driver


ProgressCallback = Callable[[int, int, list], None]


def run_montecarlo(problem: Problem, runs: int, jobs: int = 1, method: str | Sequence[str] = "nls", seed0: int = 0,
                   options=None, progress: ProgressCallback | None = None,
                   start_method: str | None = None) -> MonteCarloResult:
    """`runs` sessions (seeds seed0 ..), each solved by every method; the table of the successes.

    jobs > 1 solves in that many processes (`start_method` "spawn", the
    default, or "fork"/"forkserver"), each with one BLAS/OpenMP thread (a
    forked worker keeps the BLAS threads its parent already started).
    jobs == 1 solves in this process (so SOLVERS can be patched in tests).
    `progress(done, runs, outcomes)` is called as each seed finishes, with that
    seed's list of Outcome (one per method).
    """
    from magyro.nls.solve import Options

    if not isinstance(runs, (int, np.integer)) or runs < 1:
        raise InputError(f"--runs must be a positive integer, got {runs!r}")
    if not isinstance(jobs, (int, np.integer)) or jobs < 1:
        raise InputError(f"--jobs must be a positive integer, got {jobs!r}")
    if seed0 < 0:
        raise InputError(f"--seed0 must be non-negative, got {seed0}")
    methods = parse_methods(method)
    options = options or Options()
    seeds = list(range(seed0, seed0 + runs))
    t_start = time.perf_counter()
    by_seed: dict[int, list[Outcome]] = {}
    done = 0

    def finished(seed: int, outcomes: list[Outcome]) -> None:
        nonlocal done
        by_seed[seed] = outcomes
        done += 1
        if progress is not None:
            progress(done, runs, outcomes)

    workers = min(jobs, runs)
    used_start_method = None
    if workers == 1:
        crlb = _crlb_task(problem, seed0, options)
        for seed in seeds:
            finished(seed, run_seed(problem, seed, methods, options))
    else:
        used_start_method = start_method or DEFAULT_START_METHOD
        context = multiprocessing.get_context(used_start_method)
        with _single_threaded_children():
            pool = cf.ProcessPoolExecutor(max_workers=workers, mp_context=context, initializer=_worker_init)
            try:
                crlb_future = pool.submit(_crlb_task, problem, seed0, options)
                futures = {pool.submit(run_seed, problem, seed, methods, options): seed for seed in seeds}
                for fut in cf.as_completed(futures):
                    seed = futures[fut]
                    try:
                        outcomes = fut.result()
                    except Exception as exc:  # a worker died (BrokenProcessPool) or could not unpickle
                        outcomes = [_failure(seed, m, exc, 0.0) for m in methods]
                    finished(seed, outcomes)
                try:
                    crlb = crlb_future.result()
                except Exception as exc:
                    crlb = {"seed": seed0, "values": {}, "error": one_line(exc, limit=None)}
            except BaseException:
                pool.shutdown(wait=False, cancel_futures=True)
                raise
            pool.shutdown(wait=True)

    truth = truth_values(problem)
    paper = matches_paper(problem)
    results = {}
    for m in methods:
        outcomes = [o for seed in seeds for o in by_seed[seed] if o.method == m]
        with_tau = any("time_offset_s" in o.estimate for o in outcomes if o.ok)
        params = parameters(problem.mag_unit, with_tau)
        rows = table_rows(params, truth, outcomes, crlb["values"], PAPER_TABLE1_STD if paper else None,
                          PAPER_TABLE1_MEAN if paper else None)
        results[m] = MethodResult(m, rows, outcomes)
    return MonteCarloResult(
        problem=problem.name, problem_source=problem.source_path, runs=runs, seed0=seed0, jobs=jobs,
        methods=results, truth=truth, crlb=crlb["values"], crlb_seed=seed0, crlb_error=crlb["error"],
        paper_applies=paper, wall_s=time.perf_counter() - t_start, start_method=used_start_method,
        created=_dt.datetime.now(_dt.timezone.utc).replace(microsecond=0).isoformat(), mag_unit=problem.mag_unit,
    )


def write_outputs(result: MonteCarloResult, json_path=None, csv_path=None) -> None:
    """The JSON (schema magyro.montecarlo/1) and the CSV table, each written whole or not at all."""
    from magyro.io.sessions import write_text_atomically

    if json_path is not None:
        write_text_atomically(json_path, result.to_json() + "\n")
    if csv_path is not None:
        write_text_atomically(csv_path, result.to_csv())


@contextlib.contextmanager
def progress_display(total: int, enabled: bool = True, stream=None):
    """A progress callback for run_montecarlo: a rich bar on a terminal, else one "run k/N" line per run.

    Everything goes to stderr, so stdout holds only the table.
    """
    import sys

    stream = stream or sys.stderr
    if not enabled:
        yield None
        return

    def describe(outcomes: list[Outcome]) -> str:
        parts = []
        for o in outcomes:
            parts.append(f"{o.method} ok {o.seconds:.1f} s" if o.ok else f"{o.method} FAILED ({o.error_type}: {o.error})")
        return f"seed {outcomes[0].seed}: " + ", ".join(parts)

    try:
        if not stream.isatty():
            raise ImportError
        from rich.console import Console
        from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeElapsedColumn
    except (ImportError, AttributeError, ValueError):
        def plain(done: int, n: int, outcomes: list[Outcome]) -> None:
            print(f"run {done}/{n} {describe(outcomes)}", file=stream, flush=True)

        yield plain
        return

    console = Console(file=stream)
    with Progress(TextColumn("runs"), BarColumn(), MofNCompleteColumn(), TimeElapsedColumn(),
                  TextColumn("{task.fields[last]}"), console=console) as bar:
        task = bar.add_task("runs", total=total, last="")

        def rich_progress(done: int, n: int, outcomes: list[Outcome]) -> None:
            failed = [o for o in outcomes if not o.ok]
            if failed:
                console.print(f"run {done}/{n} {describe(outcomes)}")
            bar.update(task, completed=done, last=describe(outcomes)[:60])

        yield rich_progress
