"""A hard iron that moves: h(t) = h + field_scale * eta_n over the interval from node n (`NLS(hard_iron_walk=...)`).

A magnet or iron fixed to the board adds a constant field in the sensor's frame: the
paper's hard iron h. In BROAD's attached-magnet trials it is not constant (docs/real-data.md
section 4: 3-80 uT peak to peak over a trial), so h may walk: eta is a random walk from
eta_0 = 0 (node 0; the constant h carries the level), one step per interval weighted by
1 / sqrt(q dt), q the walk's density squared (magnetometer unit^2 / s). The walk's states sit
beside each node's attitude in the block-tridiagonal part of the problem, so the problem's
shape and cost grow as the attitudes do.
"""
from __future__ import annotations

import numpy as np

from magyro.nls.interval import global_number
from magyro.nls.problem import JointProblem
from magyro.session import Session


def hard_iron_walk_states(problem: JointProblem, x: np.ndarray) -> np.ndarray:
    """eta at every node (N, 3), node 0 the gauge 0 (field_scale units); zeros when the hard iron is constant."""
    if not problem.walk:
        return np.zeros((problem.n_int + 1, 3))
    return np.vstack([np.zeros(3), x[problem.n_theta:].reshape(-1, problem.B)[:, 3:6]])


def hard_iron_at_samples(problem: JointProblem, x: np.ndarray, p: np.ndarray, session: Session) -> np.ndarray:
    """The hard iron in effect at every magnetometer sample of `session` (n, 3), in its unit: h + field_scale * eta
    of the interval the sample starts a segment of (the last node's for the last sample)."""
    theta, g = x[: problem.n_theta], problem.globals_of(p)
    h = np.array(problem.physical_function(theta, g)[1]).ravel()
    field_scale = global_number(g, "field_scale")
    eta = hard_iron_walk_states(problem, x)
    grid = problem.grid
    per_sample = np.zeros((len(session.t_mag_s), 3))
    interval = np.repeat(np.arange(problem.n_int), grid.stride)
    starts = grid.mag_index.ravel()
    on_sample = grid.mag_weight.ravel() > 0
    per_sample[starts[on_sample]] = eta[interval[on_sample]]
    per_sample[grid.last_mag_index] = eta[-1]
    return h + field_scale * per_sample
