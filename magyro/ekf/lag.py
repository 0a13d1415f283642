"""The magnetometer's lag behind the gyro from the filter's own likelihood, and what its uncertainty adds to the std.

Eq. (13)'s lag search (`magyro.front.initial.with_time_offset`: a golden section on the linear fit's residual)
is a good start but a poor estimate: on paper-table1 its lag scattered by 0.70 ms where the Cramer-Rao bound is
0.144 ms, and bias x moves by -11.8e-3 deg/s per ms of lag, so the filter run at that lag had a bias x std of
1.44 x CRLB (0.82 with the lag known), and a reported std that knew nothing of the lag (the Table I record
docs/numbers/montecarlo-paper-table1.json at commit f243c5c; the record now holds the lag of this module's).

The filter's innovations nu_k, with covariance S_k, are the readings' likelihood at a given lag, the states
integrated out by the filter itself:

    -log L(lag) = 1/2 sum_k (nu_k^T S_k^-1 nu_k + log det S_k) + const

(`ErrorStateEKF.nll_sum`), summed over the same readings at every lag: those whose stamps lie `MAX_LAG_S` inside
the gyro's span (`likelihood_span`), which every lag tried keeps inside it. Near its minimum -log L is a
parabola in the lag: its vertex is the lag, the inverse of its curvature (the observed information) the lag's
variance. `search_lag` runs the filter at eq. (13)'s lag and LAG_STEP_S either side, and fits the parabola
through the three when its vertex lies between them (else it walks to the minimum first).

The filter's covariance is the parameters' covariance given the lag. The lag's own variance adds, by the law of
total covariance, var g g^T, with g the reported parameters' change per second of lag, a central difference
between the runs at the two neighbours (`LagEstimate.sensitivity`, `magyro.ekf.uncertainty.with_lag`).
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, Callable

import numpy as np

from magyro.front.initial import MAX_TIME_OFFSET_S

LAG_STEP_S = 1e-3          # the first runs: eq. (13)'s lag +/- 1 ms (the lag's std: 0.14 ms on paper-table1 and BROAD 07)
MAX_LAG_RUNS = 12          # filter runs the search may make besides the one at eq. (13)'s lag
MAX_LAG_S = MAX_TIME_OFFSET_S   # the lags tried stay within +/- this (eq. 13's search range)


@dataclass(frozen=True)
class LagEstimate:
    """The lag at the likelihood's vertex, its std, and the runs at the two lags either side of it."""

    lag_s: float
    std_s: float
    below: tuple[float, Any]   # (lag_s, what the run there gave) of the neighbour below the lowest run ...
    above: tuple[float, Any]   # ... and above it
    runs: int                  # filter runs made by the search

    def sensitivity(self, reported: Callable[[float, Any], np.ndarray]) -> np.ndarray:
        """d(reported)/d(lag), per second: the central difference of `reported(lag_s, run)` between the neighbours."""
        (a, run_a), (b, run_b) = self.below, self.above
        return (reported(b, run_b) - reported(a, run_a)) / (b - a)


def likelihood_span(t_gyro_s: np.ndarray) -> tuple[float, float]:
    """The stamps of the magnetometer readings the likelihood sums over: those every lag within +/- MAX_LAG_S
    keeps inside the gyro's span (a reading shifted out of it is no update, and one update fewer moves the sum
    by about 12 on paper-table1, as much as 0.5 ms of lag does)."""
    return float(t_gyro_s[0]) + MAX_LAG_S, float(t_gyro_s[-1]) - MAX_LAG_S


def parabola_vertex(x: tuple[float, float, float], f: tuple[float, float, float]) -> tuple[float, float]:
    """(vertex, second derivative) of the parabola through (x_i, f_i), x increasing (vertex nan on a line)."""
    d1 = (f[1] - f[0]) / (x[1] - x[0])
    d2 = (f[2] - f[1]) / (x[2] - x[1])
    curvature = 2.0 * (d2 - d1) / (x[2] - x[0])
    return (0.5 * (x[0] + x[1]) - d1 / curvature if curvature else math.nan), curvature


class _NoLag(Exception):
    """The search has made MAX_LAG_RUNS runs, or a run has no likelihood."""


def search_lag(run_at: Callable[[float], tuple[float, Any]], lag0_s: float, first: tuple[float, Any],
               step_s: float = LAG_STEP_S) -> LagEstimate | None:
    """The lag at the vertex of -log L, from runs of the filter: run_at(lag_s) -> (-log L, what the run gave);
    `first` is the run at lag0_s.

    The parabola is taken through three runs LAG_STEP_S apart, centred on lag0_s, when its vertex lies between
    the outer two (there -log L is a parabola: on BROAD 02 the three runs around eq. 13's lag put the vertex
    where three runs centred on it do, to 1e-3 ms). When it does not, the search steps outward from the lower
    side, doubling its step, until the likelihood rises again, and centres the next three runs on the vertex
    of the parabola through the lowest run and its two neighbours (far from its minimum -log L is no
    parabola: through runs 4 and 8 ms apart its curvature was 2.5 times too small, its vertex still within
    0.1 ms). None when that takes more than MAX_LAG_RUNS runs or leaves +/- MAX_LAG_S (the likelihood does not
    bracket a lag), or when a run has no finite -log L (its S lost positive definiteness: seen on a split-check
    half of BROAD 21)."""
    runs = {lag0_s: first}

    def at(lag_s: float) -> float:
        if lag_s not in runs:
            if len(runs) > MAX_LAG_RUNS:
                raise _NoLag
            runs[lag_s] = run_at(lag_s)
        if not math.isfinite(runs[lag_s][0]):
            raise _NoLag
        return runs[lag_s][0]

    def inside(lag_s: float) -> float:
        """The centre of three runs, kept so that all three lie within +/- MAX_LAG_S."""
        return float(np.clip(lag_s, -MAX_LAG_S + step_s, MAX_LAG_S - step_s))

    centre = inside(lag0_s)
    try:
        for _ in range(MAX_LAG_RUNS):
            x = (centre - step_s, centre, centre + step_s)
            f = tuple(at(v) for v in x)
            vertex, curvature = parabola_vertex(x, f)
            if curvature > 0.0 and x[0] <= vertex <= x[2]:
                return LagEstimate(float(vertex), float(curvature ** -0.5), (x[0], runs[x[0]][1]),
                                   (x[2], runs[x[2]][1]), len(runs) - 1)
            side = -1.0 if f[0] < f[2] else 1.0
            walked, step = [centre, centre + side * step_s], step_s
            while True:
                step *= 2.0
                lag = float(np.clip(walked[-1] + side * step, -MAX_LAG_S, MAX_LAG_S))
                if lag == walked[-1]:
                    return None
                walked.append(lag)
                if at(lag) > at(walked[-2]):
                    break
            bracket = tuple(sorted(walked[-3:]))
            centre = inside(parabola_vertex(bracket, tuple(at(v) for v in bracket))[0])
    except _NoLag:
        pass
    return None
