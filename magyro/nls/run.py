"""From a Session to a Calibration by the joint least squares: the steps in order.

    1. the shared front end (`magyro.front.prepare`): rests, noise, ellipsoid, unit check, gate
    2. linearisation, grid and problem; IPOPT with warm re-solves (`magyro.nls.solve`)
    3. the Gauss-Newton decrement check: a solve that could still improve is refused
    4. the marginal information, std and warnings assembled into the result (`magyro.nls.diagnostics`)
"""
from __future__ import annotations

import time

import numpy as np

from magyro.errors import SolverError
from magyro.front.prepare import prepare
from magyro.nls.diagnostics import assemble
from magyro.nls.information import gauss_newton_decrement, reduce_hessian
from magyro.nls.method import NLS
from magyro.nls.solve import build_problem, solve_passes
from magyro.options import Options
from magyro.result.calibration import Calibration
from magyro.session import Session

MAX_DECREMENT = 1e-3  # chi^2 units: a step that would remove less than this changes nothing that matters


def calibrate_nls(session: Session, options: Options | None = None, method: NLS | None = None) -> Calibration:
    """Calibrate gyro and magnetometer from one session (the joint least squares)."""
    options, method = options or Options(), method or NLS()
    t_start = time.perf_counter()
    prep = prepare(session, options)
    grid, lin, problem = build_problem(prep, options, method)
    sol = solve_passes(problem, prep, lin, method)
    reduced = reduce_hessian(problem.hessian_function(sol.x, sol.p), problem.n_theta)
    decrement = gauss_newton_decrement(reduced, np.array(problem.gradient_function(sol.x, sol.p)).ravel())
    if not (np.isfinite(decrement) and decrement < MAX_DECREMENT):
        raise SolverError(
            f"the solver did not converge: {sol.stats['return_status']} after {sol.stats['iter_count']} iterations "
            f"(a further Gauss-Newton step would still reduce chi^2 by {decrement:.3g})"
        )
    sol.stats["gauss_newton_decrement"] = decrement
    return assemble(problem, prep, grid, sol, reduced, method, time.perf_counter() - t_start)
