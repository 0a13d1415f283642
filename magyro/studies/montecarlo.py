"""Monte Carlo accuracy study: the paper's Table I, with the Cramer-Rao bound beside it.

`run_montecarlo(problem, runs)` simulates `runs` sessions of one problem with
noise seeds seed0, seed0+1, ... (the motion is fixed by the problem), solves
each with one or more methods ("nls" the joint least squares, "ekf" the
paper's filter; "nls,ekf" solves the SAME sessions with both), and tabulates
every parameter (`montecarlo_values`) with its statistics (`montecarlo_table`);
`montecarlo_output` writes the result as JSON and CSV.

The CRLB is computed once, at seed0's session: the Fisher information is
linearised at the true parameters and the true attitude, so the noise
realisation enters only through the gyro samples that drive the attitude
integration in the Jacobian (and through the rests found at the ends, if any);
from seed to seed that changes it by far less than the sampling error of a
50-run std. The Euler-angle CRLB maps the 3x3 CRLB covariance of d through the
Jacobian of dcm2eul (`crlb.euler_std_deg`); the other entries are
`crlb.cramer_rao_std` as is.

A problem with an [accelerometer] is solved with it (Options(accelerometer=True) unless options are given; the
EKF without it, which it cannot calibrate), and its table gains the accelerometer's 12 rows. Their bound, and the
gyro's and magnetometer's then, is `crlb_accelerometer.accelerometer_cramer_rao`: the hand's acceleration counted
as noise of its known ensemble; the white-noise bound (the hand still) is kept beside it (`crlb_white`).

Failed runs (any exception: unusable input, observability gate, solver
failure, a crashed worker) are kept with their seed and message and counted;
the table is built from the successful runs.
"""
from __future__ import annotations

import contextlib
import dataclasses
import datetime as _dt
import os
import time
import traceback
from typing import Callable, Sequence

import numpy as np

from magyro.ekf.method import EKF
from magyro.errors import InputError, one_line
from magyro.executor import executor_for, run_unordered
from magyro.methods import run_method
from magyro.progress import counting
from magyro.nls.method import NLS
from magyro.options import Options
from magyro.result.reported import std_from_covariance
from magyro.studies.crlb import cramer_rao_covariance, euler_std_deg
from magyro.studies.crlb_accelerometer import ACC_ROWS, accelerometer_cramer_rao
from magyro.studies.montecarlo_output import MethodResult, MonteCarloResult
from magyro.studies.montecarlo_table import PAPER_TABLE1_MEAN, PAPER_TABLE1_STD, matches_paper, table_rows
from magyro.studies.montecarlo_values import (Outcome, accelerometer_std_values, estimate_values, parameters,
                                              std_values, truth_values)
from magyro.studies.scenario import Scenario
from magyro.studies.simulate import simulate

# method name -> method object (run by `magyro.methods.run_method(method, session, options)`), looked up when a
# study starts (tests patch it). The CRLB is the bound of METHODS["nls"]'s discretisation.
METHODS: dict = {"nls": NLS(), "ekf": EKF()}

ProgressCallback = Callable[[int, int, list], None]


def parse_methods(method: str | Sequence[str]) -> list[str]:
    """"nls", "ekf", "nls,ekf" or a list -> checked list of distinct methods, in order."""
    names = [m.strip().lower() for m in (method.split(",") if isinstance(method, str) else method)]
    names = [m for m in names if m]
    if not names:
        raise InputError(f"no method given; use one of {', '.join(METHODS)} or a comma-separated list")
    unknown = [m for m in names if m not in METHODS]
    if unknown:
        raise InputError(f"unknown method(s) {', '.join(unknown)}; use {', '.join(METHODS)} or e.g. nls,ekf")
    if len(set(names)) != len(names):
        raise InputError(f"method listed twice in {','.join(names)}")
    return names


# --------------------------------------------------------------------------- one seed


def crlb_task(problem: Scenario, seed: int, options: Options, nls: NLS) -> dict:
    """The CRLB rows at `seed`'s session (with the accelerometer: with the hand, and the white-noise bound as
    "white"), or the reason there is none."""
    t0 = time.perf_counter()
    try:
        session, _ = simulate(problem, seed)
        if options.accelerometer and problem.accelerometer is not None:
            bound = accelerometer_cramer_rao(problem, session, options, nls)
            values = crlb_values(problem, bound.covariance, options)
            values.update(zip(ACC_ROWS, map(float, bound.accelerometer_std)))
            white = crlb_values(problem, bound.white_covariance, options)
            white.update(zip(ACC_ROWS, map(float, bound.white_accelerometer_std)))
            return {"values": values, "white": white, "error": None, "seconds": time.perf_counter() - t0}
        cov = cramer_rao_covariance(problem, session, options, nls)
        return {"values": crlb_values(problem, cov, options), "error": None, "seconds": time.perf_counter() - t0}
    except Exception as exc:  # the table is still useful without a CRLB
        return {"values": {}, "error": one_line(exc, limit=None), "seconds": time.perf_counter() - t0}


def crlb_values(problem: Scenario, cov: np.ndarray, options: Options) -> dict:
    """The rows of a reported vector's CRLB covariance, the Euler angles' through dcm2eul."""
    values = std_values(std_from_covariance(cov), options.estimate_time_offset)
    values.update({f"euler_deg[{i}]": float(v) for i, v in enumerate(euler_std_deg(problem.C_b_m, cov))})
    return values


def study_options(problem: Scenario, options: Options | None) -> Options:
    """The options a study solves with: as given, else the accelerometer calibrated when the problem has one."""
    if options is not None:
        return options
    acc = problem.accelerometer
    return Options() if acc is None else Options(accelerometer=True, gravity_m_s2=acc.g_m_s2)


def method_options(method, options: Options) -> Options:
    """The EKF does not calibrate the accelerometer: it solves the same session without it."""
    return dataclasses.replace(options, accelerometer=False) if isinstance(method, EKF) else options


def run_seed(problem: Scenario, seed: int, methods: dict, options: Options) -> list[Outcome]:
    """Simulate seed's session once and solve it with every method (name -> method object).

    Never raises (but on Ctrl-C): a failure becomes a failed Outcome.
    """
    t0 = time.perf_counter()
    try:
        session, _ = simulate(problem, seed)
    except Exception as exc:
        return [Outcome.failure(seed, m, exc, time.perf_counter() - t0) for m in methods]
    out = []
    for name, method in methods.items():
        t0, c0 = time.perf_counter(), time.process_time()
        try:
            cal = run_method(method, session, method_options(method, options))
            est = estimate_values(cal, problem)
            rep = std_values(cal.std, "time_offset_s" in est)
            rep.update(accelerometer_std_values(getattr(cal, "accelerometer", None)))
            solver = {k: getattr(cal.solver, k) for k in ("method", "status", "iterations", "seconds")}
            out.append(Outcome(seed, name, True, time.perf_counter() - t0, est, rep, solver))
        except Exception as exc:
            if os.environ.get("MAGYRO_DEBUG"):
                traceback.print_exc()
            out.append(Outcome.failure(seed, name, exc, time.perf_counter() - t0))
        out[-1].cpu_seconds = time.process_time() - c0
    return out


# --------------------------------------------------------------------------- on an executor


def study_task(kind: str, problem: Scenario, seed: int, methods: dict, options: Options, nls: NLS):
    """One task of a study on an executor: the CRLB at `seed` ("crlb") or `seed`'s run with every method ("run")."""
    return crlb_task(problem, seed, options, nls) if kind == "crlb" else run_seed(problem, seed, methods, options)


def _run_on(executor, problem: Scenario, seeds: list[int], methods: dict, options: Options, nls: NLS,
            finished: Callable[[int, list[Outcome]], None]) -> dict:
    """The CRLB task and every seed on `executor` (`finished` called as each seed completes); the CRLB's result."""
    crlb = {"values": {}, "white": {}, "error": None}

    def done(item: tuple, result, error) -> None:
        kind, seed = item
        if kind == "crlb":
            crlb.update(result if error is None else {"values": {}, "error": one_line(error, limit=None)})
        else:   # a worker that died (BrokenProcessPool, KilledWorker) or could not unpickle fails its seed only
            finished(seed, result if error is None else [Outcome.failure(seed, m, error, 0.0) for m in methods])

    items = [("crlb", seeds[0])] + [("run", seed) for seed in seeds]
    run_unordered(executor, study_task, items, done,
                  arguments=lambda item: (item[0], problem, item[1], methods, options, nls), warm_first=True)
    return crlb


# --------------------------------------------------------------------------- the study


def run_montecarlo(problem: Scenario, runs: int, jobs: int = 1, method: str | Sequence[str] = "nls", seed0: int = 0,
                   options: Options | None = None, progress: ProgressCallback | None = None,
                   start_method: str | None = None, scheduler: str | None = None) -> MonteCarloResult:
    """`runs` sessions (seeds seed0 ..), each solved by every method; the table of the successes.

    jobs > 1 solves in that many processes (`start_method` "spawn", the
    default, or "fork"/"forkserver"), each with one BLAS/OpenMP thread (a
    forked worker keeps the BLAS threads its parent already started).
    jobs == 1 solves in this process; `scheduler` (a Dask scheduler's address)
    solves on that cluster instead (`magyro.executor`), with the same numbers.
    `progress(done, runs, outcomes)` is
    called as each seed finishes, with that seed's list of Outcome (one per
    method).
    """
    if not isinstance(runs, (int, np.integer)) or runs < 1:
        raise InputError(f"--runs must be a positive integer, got {runs!r}")
    if not isinstance(jobs, (int, np.integer)) or jobs < 1:
        raise InputError(f"--jobs must be a positive integer, got {jobs!r}")
    if seed0 < 0:
        raise InputError(f"--seed0 must be non-negative, got {seed0}")
    methods = {m: METHODS[m] for m in parse_methods(method)}
    nls = METHODS["nls"]
    options = study_options(problem, options)
    seeds = list(range(seed0, seed0 + runs))
    t_start = time.perf_counter()
    by_seed: dict[int, list[Outcome]] = {}

    def finished(seed: int, outcomes: list[Outcome]) -> None:
        by_seed[seed] = outcomes
        if progress is not None:
            progress(len(by_seed), runs, outcomes)

    executor = executor_for(min(jobs, runs), scheduler, start_method)
    used_start_method = getattr(executor, "start_method", None)
    with executor:
        crlb = _run_on(executor, problem, seeds, methods, options, nls, finished)

    truth = truth_values(problem)
    paper = matches_paper(problem)
    results = {}
    for m in methods:
        outcomes = [o for seed in seeds for o in by_seed[seed] if o.method == m]
        with_tau = any("time_offset_s" in o.estimate for o in outcomes if o.ok)
        with_acc = any("K_a[0,0]" in o.estimate for o in outcomes if o.ok)
        rows = table_rows(parameters(problem.mag_unit, with_tau, with_acc), truth, outcomes, crlb["values"],
                          PAPER_TABLE1_STD if paper else None, PAPER_TABLE1_MEAN if paper else None)
        results[m] = MethodResult(m, rows, outcomes)
    return MonteCarloResult(
        problem=problem.name, problem_source=problem.source_path, runs=runs, seed0=seed0, jobs=jobs,
        methods=results, truth=truth, crlb=crlb["values"], crlb_error=crlb["error"], crlb_white=crlb.get("white") or {},
        paper_applies=paper, wall_s=time.perf_counter() - t_start, start_method=used_start_method,
        created=_dt.datetime.now(_dt.timezone.utc).replace(microsecond=0).isoformat(), mag_unit=problem.mag_unit,
    )


@contextlib.contextmanager
def progress_display(total: int, enabled: bool = True, stream=None):
    """A progress callback for run_montecarlo (`magyro.progress.counting`): a bar on a terminal, else one
    "run k/N" line per run, on stderr, so stdout holds only the table."""
    with counting(total, "runs", enabled, stream) as tick:
        if tick is None:
            yield None
            return

        def show(done: int, n: int, outcomes: list[Outcome]) -> None:
            tick(done, describe_outcomes(outcomes), alarm=any(not o.ok for o in outcomes))

        yield show


def describe_outcomes(outcomes: list[Outcome]) -> str:
    parts = [f"{o.method} ok {o.seconds:.1f} s" if o.ok else f"{o.method} FAILED ({o.error_type}: {o.error})"
             for o in outcomes]
    return f"seed {outcomes[0].seed}: " + ", ".join(parts)
