"""Noise levels estimated by the least squares itself: variance components between IPOPT passes.

Without rests the noise levels before the solve are guesses (third differences,
`magyro.front.differences`): at a phone's 25-40 Hz the hand's motion makes the
gyro's 10-300x too large. The solve then estimates them as variance components
(Helmert; Foerstner's form): a group k of whitened residuals r_k (the gyro
mismatch of every linked interval, the magnetometer samples) re-weights by

    sigma_k^2 <- sigma_k^2 * sum(r_k^2) / redundancy_k,   redundancy_k = n_k - tr(H^-1 H_k)

with H = J^T J the Gauss-Newton information and H_k its part from group k:
tr(H^-1 H_k) is how many of the unknowns group k determines, so the redundancy
counts only the residuals left to measure its noise. With a good gyro most of
the gyro mismatch is absorbed by the attitudes (the redundancy is a few
percent of the intervals); without it the gyro level would come out far too
small. The magnetometer's sum is robust (median of |r|^2 against its chi^2
median) and counts the residuals' autocorrelation time, as the re-weighting of
a session with rests does (`magyro.nls.solve.magnetometer_noise_factor`).

H_k is the difference of H and H evaluated with group k's noise doubled; the
trace needs H^-1 only on H's own pattern: the theta block through the reduced
information, the attitude blocks by a block-tridiagonal selected inverse.
"""
from __future__ import annotations

from dataclasses import dataclass

import casadi as ca
import numpy as np

from magyro.front import noise
from magyro.front.prepare import Prepared
from magyro.nls.information import Reduced, reduce_hessian, tridiagonal_blocks
from magyro.nls.reduction import block_tridiagonal_inverse_band  # noqa: F401  (also for the tests)
from magyro.nls.problem import JointProblem, Linearisation
from magyro.nls.solve import (CHI2_3DOF_MEDIAN, gyro_residuals, magnetometer_residuals, problem_parameters)

PROBE_FACTOR = 2.0         # a group's noise times this scales its Hessian part by 1 / PROBE_FACTOR^2
MIN_REDUNDANCY = 50.0      # fewer redundant residuals than this measure no level to 10 % (1 / sqrt(2 r)): it stays


@dataclass(frozen=True)
class VarianceComponents:
    """What one variance-component step found: factors on the noise stds and each group's redundancy."""

    gyro_factor: float
    mag_factor: float
    gyro_redundancy: float
    mag_redundancy: float




def inverse_on_pattern(red: Reduced, H_triu: ca.DM) -> np.ndarray:
    """H^-1 at the nonzeros of triu(H), in their order, off-diagonal entries counted twice: so that
    tr(H^-1 P) = sum(inverse_on_pattern * triu(P) values) for any symmetric P with H's pattern."""
    rows, cols = (np.asarray(v) for v in H_triu.sparsity().get_triplet())
    G, b = red.H_tp.shape[0], red.block
    Si = np.linalg.inv(red.information)
    W = red.Dinv_Hpt                       # D^-1 H_pt, (n_p, G)
    inv = np.empty(len(rows))
    tt = cols < G
    inv[tt] = Si[rows[tt], cols[tt]]
    tp = (rows < G) & (cols >= G)
    inv[tp] = -(Si @ W.T)[rows[tp], cols[tp] - G]
    pp = rows >= G
    r, c = rows[pp] - G, cols[pp] - G
    diag, upper = block_tridiagonal_inverse_band(red.diagonal, red.upper)
    same = r // b == c // b
    d_inv = np.where(same, diag[r // b, r % b, c % b], upper[np.minimum(r // b, len(upper) - 1), r % b, c % b])
    inv[pp] = d_inv + np.einsum("ia,ab,ib->i", W[r], Si, W[c])
    return np.where(rows == cols, 1.0, 2.0) * inv


def group_part(problem: JointProblem, x, H: ca.DM, p_probe: np.ndarray) -> np.ndarray:
    """triu of a group's part of H (nonzero values): H minus H with the group's noise PROBE_FACTOR times larger,
    scaled back."""
    H_probe = problem.hessian_function(x, ca.DM(p_probe))
    shrink = 1.0 / PROBE_FACTOR**2
    return (np.array(H.nonzeros()) - np.array(H_probe.nonzeros())) / (1.0 - shrink)


def component_factor(sum_squares: float, n: int, trace: float) -> tuple[float, float]:
    """(factor on the std, redundancy) of one group. With fewer than MIN_REDUNDANCY redundant residuals the level
    is not measured (factor 1), unless the residuals are far larger than it allows (3 std of their chi^2 above
    the mean): a level too small shows however few residuals are left."""
    redundancy = n - trace
    if not (np.isfinite(redundancy) and redundancy > 0 and sum_squares > 0):
        return 1.0, float(redundancy)
    ratio = sum_squares / redundancy
    if redundancy < MIN_REDUNDANCY and ratio < 1.0 + 3.0 * np.sqrt(2.0 / redundancy):
        return 1.0, float(redundancy)
    return float(np.sqrt(ratio)), float(redundancy)


def variance_components(problem: JointProblem, prep: Prepared, lin: Linearisation, x: np.ndarray, r: np.ndarray,
                        sigma_mag: float, density: float, tau0_s: float, estimate_gyro: bool,
                        estimate_mag: bool) -> VarianceComponents:
    """One variance-component step at the solution x of the problem weighted by (sigma_mag, density);
    `r` its residual matrix. Only the groups asked for are re-weighted (a given level stays)."""
    grid = problem.grid
    x_dm = ca.DM(x)
    p = problem_parameters(problem, prep, lin, sigma_mag, tau0_s, density)
    H = problem.hessian_function(x_dm, ca.DM(p))
    try:
        inverse = inverse_on_pattern(reduce_hessian(H, problem.n_theta, problem.B), H)
    except np.linalg.LinAlgError:   # the information is singular here: no redundancy to measure a level with
        inverse = None
    if inverse is None or not np.all(np.isfinite(inverse)):
        return VarianceComponents(1.0, 1.0, float("nan"), float("nan"))
    gyro = gyro_residuals(r, grid.stride)[grid.gyro_linked]
    mag = magnetometer_residuals(r, grid.stride)[grid.sample_mask]
    gyro_factor = mag_factor = 1.0
    gyro_red = mag_red = float("nan")
    if estimate_gyro:
        part = group_part(problem, x_dm, H, problem_parameters(problem, prep, lin, sigma_mag, tau0_s,
                                                                 density * PROBE_FACTOR))
        gyro_factor, gyro_red = component_factor(float(np.sum(gyro**2)), gyro.size, float(inverse @ part))
    if estimate_mag:
        part = group_part(problem, x_dm, H, problem_parameters(problem, prep, lin, sigma_mag * PROBE_FACTOR, tau0_s,
                                                                 density))
        robust_sum = mag.size * np.median(np.sum(mag**2, axis=1)) / CHI2_3DOF_MEDIAN
        mag_factor, mag_red = component_factor(float(robust_sum), mag.size, float(inverse @ part))
        mag_factor *= float(np.sqrt(noise.integrated_autocorrelation_time(mag)))
    return VarianceComponents(gyro_factor, mag_factor, gyro_red, mag_red)


MAX_STEP = np.log(10.0)    # an accelerated step moves a level by at most 10x


def secant_factor(history: list, level: float, factor: float) -> float:
    """The factor to apply to `level`, accelerated: the plain step (sigma <- sigma * factor) closes the gap slowly
    when a level is far off (each pass moves a 30x guess by 5-20 %), so the zero of log(factor) against
    log(level) is found by secant steps on the levels tried so far (`history`, appended to), never shorter than the
    plain step nor longer than 10x."""
    s, f = float(np.log(level)), float(np.log(factor))
    history.append((s, f))
    if len(history) < 2 or f == 0.0:
        return factor
    (s0, f0), (s1, f1) = history[-2], history[-1]
    if s1 == s0 or f1 == f0:
        return factor
    slope = (f1 - f0) / (s1 - s0)
    if slope >= 0:
        return factor
    step = -f1 / slope
    step = np.sign(f1) * min(max(abs(step), abs(f1)), MAX_STEP)
    return float(np.exp(step))

