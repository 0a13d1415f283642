"""The accelerometer in the joint least squares: its data on the grid, its start, its weights, what it reports.

Model (docs/spec.md section 1): the accelerometer reads y_a with f^a = K_a y_a + eps_a in its own frame a
(K_a upper triangular, eps_a in m/s^2) and f^a = C_b_a f^b. In the problem's frame m

    f^m = A y_a + b,   A = C_a^m K_a,   b = C_a^m eps_a,   C_a^m = C_b^m C_b_a^T

and the specific force is the hand's acceleration plus gravity's reaction: f^m = C_i^m (a^i + g u^i), u^i the up
direction in frame i (2 dof), g the local gravity (given). The residuals are the readings', y_a = M f^m + c with
M = A^-1 and c = -M b (as the magnetometer's are y_m - h - R^-1 C m): the hand's acceleration is in the readings,
and a fit of f = A y + b that took the readings as exact regressors shrank every scale factor by the hand's share
of their variance (BROAD 07, 09, 21, 30: K_a 0.12-0.75 and C_b_a up to 76 deg). Per interval (interval.py):

  * the interval's mean of y_a - M g C_i^m(t_j) u^i - c over its segment starts t_j, weighted by
    1 / sqrt(sigma_w^2 / n + s_h^2(t)): sigma_w the accelerometer's white noise per sample, s_h^2(t) the hand's
    acceleration variance there (the residuals' mean square over a second, less the white part: zero at rest,
    tenths of m/s^2 while a hand turns the device). The hand's acceleration lasts longer than an interval: the
    std counts that correlation (nls/hand_motion.py);
  * at the first node inside each rest (`rests_at_nodes`), the rest's mean accelerometer against gravity, weighted
    by the white noise of that mean alone: still, the device's attitude is that node's, and the hand adds nothing.
    The interval means wholly inside a rest are left out: the rest counts once.

A hand that accelerates the device by more than HAND_LIMIT_OF_G of g while turning moves with the turning and biases
the fit in a way no std counts: the solve refuses the accelerometer then (`hand_too_big`, nls/run.py).

The weights come from the residuals at the start and are measured again from the solved residuals
(`hand_weights`, called between IPOPT's passes).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from magyro import so3
from magyro.front.differences import white_noise_std
from magyro.nls.grid import Grid
from magyro.nls.interval import GLOBAL_SLICES, N_ACC_THETA
from magyro.result.accelerometer import HAND_LIMIT_OF_G, HAND_REACH_M
from magyro.result.reported import qr_split
from magyro.session import HOLE_FACTOR

HAND_WINDOW_S = 1.0          # the weights: the hand's acceleration variance is measured over this window
HAND_MAX_LAG_S = 30.0        # its autocorrelation is measured up to this lag (a hand's slowest sway)
HAND_SIZE_WINDOW_S = 30.0    # the std: its variance is measured over as long (`hand_motion`)
HAND_OF_WHITE = 1.0          # the weights count a hand whose variance along gravity is above this many white noises


@dataclass
class AccelerometerStart:
    """The accelerometer's data on the grid, its linearisation point and its white noise."""

    y: np.ndarray              # (n_int, stride, 3) raw accelerometer at each segment start
    share: np.ndarray          # (n_int, stride) weight of each segment start in its interval's mean (rows sum to 1 or 0)
    count: np.ndarray          # (n_int,) samples in each interval's mean
    rests: list                # RestAtNode of every rest that holds a node: its mean counts there, once
    A0: np.ndarray
    b0: np.ndarray
    u0_i: np.ndarray           # unit up direction in frame i
    g_m_s2: float
    sigma_white_m_s2: float    # the accelerometer's white noise per sample (RMS over the axes)
    interval_s: np.ndarray     # (n_int,)
    weight: np.ndarray         # (n_int,) the interval means' weights at the start
    grid: Grid | None = None   # the grid it sits on (its gyro, for the lever arm's acceleration)

    def globals(self) -> dict:
        """The linearisation of the readout y = M f + c (interval.accelerometer_readout): M0 = A0^-1, c0 = -M0 b0."""
        M0 = np.linalg.inv(self.A0)
        return {"M0": M0, "c0": -M0 @ self.b0, "u0": self.u0_i, "Bu": so3.tangent_basis(self.u0_i),
                "g_acc": np.array([self.g_m_s2])}

    def columns(self, weight=None) -> dict:
        """The per-interval data of the kernels (interval.data_layout, accelerometer part)."""
        n = len(self.count)
        w = self.weight if weight is None else weight
        rest0, rest1 = np.zeros((n, 3)), np.zeros((n, 3))
        w0, w1 = np.zeros((n, 1)), np.zeros((n, 1))
        for r in self.rests:     # the kernel reads a rest at an interval's start node, or at the last interval's end
            mean, weight = (rest0, w0) if r.node < n else (rest1, w1)
            k = min(r.node, n - 1)
            mean[k], weight[k] = r.mean_raw, np.sqrt(r.samples) / self.sigma_white_m_s2
        return {"yacc": self.y.reshape(n, -1), "cacc": self.share, "w_acc": np.asarray(w, float)[:, None],
                "yrest0": rest0, "wrest0": w0, "yrest1": rest1, "wrest1": w1}


def segment_start_times(grid: Grid) -> np.ndarray:
    """(n_int, stride) times of every segment start: the grid's segment boundaries but the last."""
    return grid.t_segment_s[:-1].reshape(grid.mag_index.shape)


def samples_at(t_s: np.ndarray, values: np.ndarray, at_s: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(values interpolated at `at_s`, True where a sample is near: inside the record and no hole)."""
    flat = at_s.reshape(-1)
    y = np.stack([np.interp(flat, t_s, values[:, i]) for i in range(3)], axis=-1)
    dt = float(np.median(np.diff(t_s)))
    k = np.clip(np.searchsorted(t_s, flat), 1, len(t_s) - 1)
    nearest = np.minimum(np.abs(flat - t_s[k - 1]), np.abs(t_s[k] - flat))
    ok = (flat >= t_s[0]) & (flat <= t_s[-1]) & (nearest <= HOLE_FACTOR * dt)
    return y.reshape(at_s.shape + (3,)), ok.reshape(at_s.shape)


def rest_mean(t_s: np.ndarray, acc: np.ndarray, segment: tuple[float, float] | None) -> tuple[np.ndarray | None, int]:
    if segment is None:
        return None, 0
    keep = (t_s >= segment[0]) & (t_s <= segment[1])
    return (acc[keep].mean(axis=0), int(keep.sum())) if keep.sum() >= 10 else (None, 0)


@dataclass(frozen=True)
class RestAtNode:
    """A rest that holds a node: the node, the rest's mean raw accelerometer, its samples, its span (s)."""

    node: int
    mean_raw: np.ndarray
    samples: int
    span_s: tuple[float, float]


def rests_at_nodes(full_session, t_node_s: np.ndarray, rest_segments) -> list[RestAtNode]:
    """Every rest of the session (the front end's, `rest_segments`) that holds a node and has 10 samples, at the
    first node inside it: still, the device's attitude there is the node's and the hand adds nothing, so the rest's
    mean is read against gravity at that node, weighted by the white noise of that mean alone."""
    out = []
    for seg in rest_segments:
        inside = np.flatnonzero((t_node_s >= seg[0]) & (t_node_s <= seg[1]))
        mean, n = rest_mean(full_session.t_acc_s, full_session.acc_m_s2, seg)
        if len(inside) and mean is not None:
            out.append(RestAtNode(int(inside[0]), mean, n, (float(seg[0]), float(seg[1]))))
    return out


def inside_rests(t_node_s: np.ndarray, rests: list[RestAtNode]) -> np.ndarray:
    """(n_int,) True for an interval wholly inside a rest counted at its node: its samples are in the rest's mean
    already, and counted again as an interval's mean they made the rest count twice."""
    inside = np.zeros(len(t_node_s) - 1, bool)
    for r in rests:
        inside |= (t_node_s[:-1] >= r.span_s[0]) & (t_node_s[1:] <= r.span_s[1])
    return inside


def white_noise_m_s2(full_session, rest_segments) -> float:
    """The accelerometer's white noise per sample, RMS over the axes: its spread at the rests, else its third
    differences."""
    t, a = full_session.t_acc_s, full_session.acc_m_s2
    still = [a[(t >= s0) & (t <= s1)] for s0, s1 in rest_segments]
    still = [x - x.mean(axis=0) for x in still if len(x) >= 10]
    if still:
        return float(np.sqrt(np.mean(np.concatenate(still) ** 2)))
    return float(np.sqrt(np.mean(white_noise_std(a) ** 2)))


def accelerometer_start(full_session, session, grid: Grid, C_m_i_nodes: np.ndarray, K0: np.ndarray,
                        rest_segments, g_m_s2: float) -> AccelerometerStart:
    """The accelerometer's data on the grid and its start: A0 = C_b^m (the accelerometer's axes taken as the
    gyro's), b0 = 0, u^i from the first rest (or the first interval) read in that frame; weights from the
    residuals there."""
    y, ok = samples_at(session.t_acc_s, session.acc_m_s2, segment_start_times(grid))
    rests = rests_at_nodes(full_session, grid.t_node_s, rest_segments)
    ok &= ~inside_rests(grid.t_node_s, rests)[:, None]
    count = ok.sum(axis=1)
    share = np.where(count[:, None] > 0, ok / np.maximum(count, 1)[:, None], 0.0)
    A0 = qr_split(K0)[0]
    first = next((r for r in rests if r.node == 0), None)
    at_node0 = first.mean_raw if first is not None else np.einsum("sj,sjk->k", share[:1], y[:1])
    u0 = A0 @ at_node0
    u0 = u0 / np.linalg.norm(u0)
    sigma = white_noise_m_s2(full_session, rest_segments)
    start = AccelerometerStart(y, share, count, rests, A0, np.zeros(3), u0, float(g_m_s2), sigma,
                               grid.interval_s, np.zeros(len(count)), grid)
    start.weight = hand_weights(start_residuals(start, C_m_i_nodes), start)
    return start


@dataclass(frozen=True)
class HandMotion:
    """What the accelerometer says of the hand: the interval means' weights (as solved), the hand's acceleration std
    per interval (m/s^2, zero at rest) and its autocorrelation at lags of 0, 1, 2, ... intervals (Bartlett-tapered)."""

    weight: np.ndarray
    hand_std_m_s2: np.ndarray
    correlation: np.ndarray
    variance_m2_s4: float       # the hand's variance per axis the correlation's spectrum is capped with (`reach_cap`)


def start_residuals(start: AccelerometerStart, C_m_i_nodes: np.ndarray) -> np.ndarray:
    """(n_int, 3) unweighted interval means of A0 y + b0 - g C_i^m u^i at the start, the attitude taken at each
    interval's first node (the solve's own residuals turn with the gyro inside the interval)."""
    f = np.einsum("ij,ksj->ksi", start.A0, start.y) + start.b0
    mean_f = np.einsum("ks,ksi->ki", start.share, f)
    up = np.einsum("kji,j->ki", C_m_i_nodes[:-1], start.u0_i)
    return np.where(start.count[:, None] > 0, mean_f - start.g_m_s2 * up, 0.0)


def hand_weights(e: np.ndarray, start: AccelerometerStart, correlated: float = 1.0) -> np.ndarray:
    """(n_int,) weights 1 / sqrt(sigma_w^2 / n + c s_h^2) of the interval means from their unweighted residuals e
    (n_int, 3): s_h^2(t) per axis the residuals' mean square over HAND_WINDOW_S less the white part, c =
    `correlated` (`correlation_factor`: 1 for a hand independent from one interval to the next)."""
    used = start.count > 0
    white = white_variance(start)
    local = local_mean_square(np.sqrt(np.sum(e**2, axis=1) / 3.0), used, intervals_in(HAND_WINDOW_S, start))
    return np.where(used, 1.0 / np.sqrt(white + correlated * np.maximum(local - white, 0.0)), 0.0)


def still_hand_weights(start: AccelerometerStart) -> np.ndarray:
    """(n_int,) the interval means' weights where no hand moves the device: the white noise's alone."""
    return np.where(start.count > 0, 1.0 / np.sqrt(white_variance(start)), 0.0)


def hand_detected(excess: np.ndarray, start: AccelerometerStart) -> bool:
    """Does a hand accelerate the device enough to count in the weights: is the variance of the specific force's
    size (`specific_force_excess`, less its mean: the hand's acceleration along gravity, which no attitude absorbs)
    over the whole record more than the white noise of an interval mean plus as much again (HAND_OF_WHITE)?

    The size, not the residuals: an attitude still wrong by a few hundredths of a degree (the magnetometer's and the
    gyro's noise) leaves g times that in the residuals, and the solve pulls it out only as far as the
    accelerometer's weights let it. Counted as hand (10-30 times, `correlation_factor`), it kept those weights at a
    third of the white noise's after three passes where nothing moved the device (paper-table1-acc without a hand,
    80 seeds: the accelerometer's std 1.25-1.55x its Cramer-Rao bound). The size's variance is 1.3-1.9 times the
    white noise's there (the fit's own error in A and b, shrinking pass by pass), 11-12 times with the simulated
    5 cm hand, 300-3500 times on BROAD (trials 02 and 07). A hand below the bound is still counted in the std
    (`hand_motion`)."""
    used = start.count > 0
    if used.sum() < 2:
        return False
    e = excess[used] - np.mean(excess[used])
    return float(np.mean(e**2)) > (1.0 + HAND_OF_WHITE) * float(np.mean(white_variance(start)[used]))


def solved_hand_weights(e: np.ndarray, start: AccelerometerStart) -> np.ndarray:
    """(n_int,) the interval means' weights from the solved residuals e (n_int, 3): the hand's variance counted as
    many times as its spectrum at its peak exceeds a white one's (`correlation_factor` of the residuals'
    autocorrelation). A hand sways at the frequencies the device turns at, where the calibration is sensitive:
    weighted as independent, a few seconds of sway counted as dozens of independent intervals and pulled the gyro
    with them (paper-table1-acc, 12 seeds: the gyro up to 4.8 of its std from the truth, its std up to 1.9x the
    same session's without the accelerometer; weighted by c: 2.1 and 1.13x)."""
    used = start.count > 0
    rho = hand_autocorrelation(e, used, start)
    return hand_weights(e, start, correlation_factor(rho, hand_variance(e, used, start), interval_of(start)))


def hand_variance(x: np.ndarray, used: np.ndarray, start: AccelerometerStart) -> float:
    """The hand's variance per axis, m^2/s^4, in a series x (n_int, k) of what it leaves in the `used` intervals:
    x's mean square less the white noise's."""
    if not used.any():
        return 0.0
    return max(float(np.mean(x[used] ** 2)) - float(np.mean(white_variance(start)[used])), 0.0)


def intervals_in(seconds: float, start: AccelerometerStart) -> int:
    """How many of the grid's typical intervals make `seconds` (at least 1)."""
    return max(1, int(round(seconds / interval_of(start))))


def interval_of(start: AccelerometerStart) -> float:
    """The grid's typical interval, s: the time step of the hand's autocorrelation."""
    return float(np.median(start.interval_s))


def hand_autocorrelation(x: np.ndarray, used: np.ndarray, start: AccelerometerStart) -> np.ndarray:
    """The hand's autocorrelation over intervals (`tapered_autocorrelation`, up to HAND_MAX_LAG_S) from a series x
    (n_int, k) of what it leaves in the `used` intervals, over its share of x's mean square (the rest is the white
    noise's)."""
    max_lag = min(int(used.sum()) // 2, int(round(HAND_MAX_LAG_S / interval_of(start))))
    total = float(np.mean(x[used] ** 2)) if used.any() else 0.0
    share = hand_variance(x, used, start) / total if total > 0 else 0.0
    return tapered_autocorrelation(x[used], max_lag, share)


def hand_spectrum(rho: np.ndarray, n: int, variance_m2_s4: float, interval_s: float,
                  reach_m: float = HAND_REACH_M) -> np.ndarray:
    """The hand's spectrum over a white one's of the same variance at the n // 2 + 1 frequencies of an n-point
    transform (n > 2 max lag: no lag wraps around): that of the autocorrelation rho (lags 0, 1, ...; tapered, so
    never negative), capped where no hand could put it (`reach_cap`)."""
    lag = len(rho) - 1
    kernel = np.zeros(n)
    kernel[: lag + 1] = rho
    if lag:
        kernel[n - lag :] = rho[1:][::-1]
    spectrum = np.fft.rfft(kernel).real
    return np.minimum(spectrum, reach_cap(np.fft.rfftfreq(n, interval_s), variance_m2_s4, interval_s, reach_m))


def reach_cap(f_hz: np.ndarray, variance_m2_s4: float, interval_s: float, reach_m: float = HAND_REACH_M) -> np.ndarray:
    """The most of the hand's spectrum (over a white one's of its variance per axis, `variance_m2_s4`) that a
    device held within HAND_REACH_M of where it is turned can have at the frequencies f_hz.

    Its acceleration is its position's second derivative, so its power below f is at most (2 pi f)^4 times the
    position's variance: d/df of (2 pi f)^4 HAND_REACH_M^2 bounds its one-sided density, which a white process of
    the hand's variance over intervals of interval_s has at 2 variance interval_s. The bound is zero at zero
    frequency: a hand has no acceleration that lasts. What the measured autocorrelation puts there is the fit's
    own slow error (a scale or bias not yet right, a tilt the room's field pulled the attitude into), and counted
    as hand it made the std count the room twice (BROAD trial 30, a magnet beside the path: the gyro's bias z std
    1.5 deg/s with the accelerometer, 12x the std without it, while its dead reckoning improved 4.5x; the optical
    position puts under 0.1 % of every trial's hand acceleration below 0.1 Hz, the autocorrelation put 12x a white
    process's there). HAND_REACH_M: BROAD's optical position has a std of 0.04-0.16 m on each axis in the
    hand-turned trials and 0.14-0.45 m in those that carry the device about (21, 30)."""
    if variance_m2_s4 <= 0:
        return np.full(np.shape(f_hz), np.inf)
    return 4.0 * (2.0 * np.pi) ** 4 * np.asarray(f_hz) ** 3 * reach_m**2 / (2.0 * variance_m2_s4 * interval_s)


def correlation_factor(rho: np.ndarray, variance_m2_s4: float, interval_s: float) -> float:
    """The peak over frequency of the hand's spectrum (`hand_spectrum` of the autocorrelation rho, lags 0, 1, ...)
    against a white process's of the same variance (at least 1): how much more variance a correlated process puts
    at its worst frequency than independent intervals would."""
    n = 1 << int(np.ceil(np.log2(8 * len(rho))))
    return float(max(hand_spectrum(rho, n, variance_m2_s4, interval_s).max(), 1.0))


def hand_too_big(hand_rms_m_s2: float, g_m_s2: float) -> bool:
    """Does the hand accelerate the device too much for gravity to calibrate the accelerometer: above
    HAND_LIMIT_OF_G of g (RMS per axis while turning, `hand_motion`)?

    Such a hand moves with the turning, and no std counts what that does: the fit takes part of it for scale and
    bias. BROAD against its optical truth: with the hand's acceleration taken out of the readings (the optical
    position's, turned into the body), trial 09's K_a x came out 0.994 +/- 0.004; as recorded, 0.857 +/- 0.011
    (the hand 1.19 m/s^2 RMS). Trials 07, 09, 21, 30, 34, 36 (hand 1.0-2.4 m/s^2) gave scale factors 4-30 % from
    1; trials 02, 03, 05 (hand 0.32-0.43 m/s^2) within 0.35 % and their std, the optical position's hand
    0.27-0.35 m/s^2. The bound sits between the two groups: 0.69 m/s^2 at 9.81."""
    return hand_rms_m_s2 > HAND_LIMIT_OF_G * g_m_s2


def white_variance(start: AccelerometerStart) -> np.ndarray:
    """(n_int,) the white noise's variance in each interval's mean, per axis, m^2/s^4."""
    return start.sigma_white_m_s2 ** 2 / np.maximum(start.count, 1)


def specific_force_excess(start: AccelerometerStart, A: np.ndarray, b: np.ndarray, K: np.ndarray | None = None,
                          eps: np.ndarray | None = None, lever_m: np.ndarray | None = None,
                          sub_steps: tuple | None = None) -> np.ndarray:
    """(n_int,) |mean of A y + b - the lever arm's acceleration| - g over each interval (0 where it has no sample):
    the hand's acceleration along gravity, which no attitude can explain away (a tilt turns the specific force, it
    does not change its size). The lever arm's (turning about a point `lever_m` away, the gyro calibrated by K,
    eps) is the model's, not the hand's; `sub_steps` (dt, gyro_a, gyro_b) as `Grid.sub_steps` gives them, made
    from the grid when not given."""
    f = np.einsum("ij,ksj->ksi", A, start.y) + b
    if lever_m is not None:
        f = f - lever_acceleration(start.grid.sub_steps() if sub_steps is None else sub_steps, K, eps, lever_m)
    mean_f = np.einsum("ks,ksi->ki", start.share, f)
    return np.where(start.count > 0, np.linalg.norm(mean_f, axis=1) - start.g_m_s2, 0.0)


def lever_acceleration(sub_steps: tuple, K: np.ndarray, eps: np.ndarray, lever_m: np.ndarray) -> np.ndarray:
    """(n_int, stride, 3) alpha x r + w x (w x r) at every segment start, as the kernel has it: w the calibrated rate
    there, alpha the segment's mean angular acceleration, from the sub-steps (dt, gyro_a, gyro_b) of
    `Grid.sub_steps`."""
    dt, ya, yb = sub_steps
    wa = ya @ K.T + eps                                            # (n_int, stride, L, 3)
    wb = yb @ K.T + eps
    seg_s = dt.sum(axis=2)
    alpha = (wb - wa).sum(axis=2) / np.where(seg_s > 0, seg_s, 1.0)[..., None]
    w = wa[:, :, 0]
    r = np.broadcast_to(lever_m, w.shape)
    return np.cross(alpha, r) + np.cross(w, np.cross(w, r))


def local_mean_square(x: np.ndarray, used: np.ndarray, window: int) -> np.ndarray:
    """(n,) the mean of x^2 (n,) over `window` intervals about each (all n when the record is shorter), counting the
    used ones only."""
    kernel = np.ones(max(1, min(window, len(x))))
    return np.convolve(np.where(used, x**2, 0.0), kernel, "same") / np.maximum(
        np.convolve(used.astype(float), kernel, "same"), 1.0)


def hand_motion(excess: np.ndarray, weight: np.ndarray, start: AccelerometerStart, residuals: np.ndarray) -> HandMotion:
    """The hand's acceleration at the solution, for the std (nls/hand_motion.py).

    Its size from the solved residuals (n_int, 3), `hand_size`; its autocorrelation (`tapered_autocorrelation`,
    isotropic) from the specific force's size (`specific_force_excess`): the hand along gravity, no tilt absorbs it."""
    used = weight > 0
    hand, variance = hand_size(residuals, used, start)
    e = np.where(used, excess - (np.mean(excess[used]) if used.any() else 0.0), 0.0)  # less what g or a scale leaves
    return HandMotion(weight, np.sqrt(hand), hand_autocorrelation(e[:, None], used, start), variance)


def hand_size(x: np.ndarray, used: np.ndarray, start: AccelerometerStart) -> tuple[np.ndarray, float]:
    """(the hand's variance per axis in each interval, m^2/s^4, 0 where unused; its mean over the used ones): the
    mean square of x (n_int, 3) over HAND_SIZE_WINDOW_S less the white noise's. Over 1 s a slow sway's square swings
    from 0 to twice its mean (paper-table1-acc, 12 seeds: std/spread 0.22-0.79 with 1 s, 0.44-1.4 with 30 s)."""
    local = local_mean_square(np.sqrt(np.sum(x**2, axis=1) / 3.0), used, intervals_in(HAND_SIZE_WINDOW_S, start))
    hand = np.where(used, np.maximum(local - white_variance(start), 0.0), 0.0)
    return hand, float(np.mean(hand[used])) if used.any() else 0.0


def tapered_autocorrelation(z: np.ndarray, max_lag: int, hand_share: float) -> np.ndarray:
    """rho_l (1 - l / (max_lag + 1)) for l = 0..max_lag: rho the hand's autocorrelation, the sample autocovariance
    of the whitened residuals z (n, 3), averaged over the axes, over the hand's share of their variance (the white
    noise has none past lag 0). A hand's acceleration is narrow-band (it sways at the frequencies it turns at),
    which no exponential kernel describes; the Bartlett taper keeps the covariance positive semi-definite."""
    n = len(z)
    if n < 2 or max_lag < 1 or hand_share <= 0:
        return np.ones(1)
    z = z - z.mean(axis=0)
    acov = np.fft.irfft(np.abs(np.fft.rfft(z, 2 * n, axis=0)) ** 2, axis=0)[: max_lag + 1].mean(axis=1) / n
    rho = np.clip(acov / (acov[0] * hand_share), -1.0, 1.0)
    rho[0] = 1.0
    return rho * (1.0 - np.arange(max_lag + 1) / (max_lag + 1))


# ------------------------------------------------------------------------------------------ what it reports
ACC_REPORTED = {"K_a": slice(0, 6), "bias_m_s2": slice(6, 9), "misalignment_deg": slice(9, 12)}
UPPER = [(0, 0), (0, 1), (0, 2), (1, 1), (1, 2), (2, 2)]


def accelerometer_parameters(A: np.ndarray, b: np.ndarray, C_b_m: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(K_a, eps_a in m/s^2, C_b_a) from f^m = A y + b and the gyro's C_b^m: A = C_a^m K_a (QR)."""
    C_a_m, K_a = qr_split(A)
    return K_a, C_a_m.T @ b, C_a_m.T @ C_b_m


def reported_accelerometer(A, b, C_b_m, C_b_a_ref) -> np.ndarray:
    """The accelerometer's reported vector (ACC_REPORTED): K_a's upper triangle, eps_a, and the misalignment's
    rotation vector (deg) against C_b_a_ref."""
    K_a, eps_a, C_b_a = accelerometer_parameters(A, b, C_b_m)
    d = np.rad2deg(so3.log_so3(C_b_a_ref.T @ C_b_a))
    return np.concatenate([[K_a[r, c] for r, c in UPPER], eps_a, d])


def accelerometer_result(problem, theta: np.ndarray, g: np.ndarray, cov_theta: np.ndarray):
    """The accelerometer's calibration at the solution, its std propagated from `cov_theta` (the corrections'
    covariance) by central differences through the QR splits of A and K."""
    from magyro.result.accelerometer import AccelerometerCalibration

    def parts(th):
        A, b, u, g_acc, _ = (np.array(v) for v in problem.accelerometer_function(th, g))
        C_b_m = qr_split(np.array(problem.physical_function(th, g)[2]))[0]
        return A, b.ravel(), C_b_m, u.ravel(), float(g_acc.item())

    A, b, C_b_m, u, g_acc = parts(theta)
    K_a, eps_a, C_b_a = accelerometer_parameters(A, b, C_b_m)
    f = lambda th: reported_accelerometer(*parts(th)[:3], C_b_a)
    step, n = 1e-6, len(theta)
    J = np.zeros((12, n))   # the other columns move neither A, b nor K: their differences were exact zeros
    for i in columns_moving_reported(n):
        e = np.zeros(n)
        e[i] = step
        J[:, i] = (f(theta + e) - f(theta - e)) / (2 * step)
    std = np.sqrt(np.maximum(np.diag(J @ cov_theta @ J.T), 0.0))
    lever = slice(len(theta) - 3, len(theta))    # the lever arm, m in frame m: the last three corrections
    return AccelerometerCalibration.from_reported(K_a, eps_a, C_b_a, g_acc, u, std, theta[lever] * 1.0,
                                                  np.sqrt(np.maximum(np.diag(cov_theta)[lever], 0.0)))


def columns_moving_reported(n_theta: int) -> list[int]:
    """The corrections the accelerometer's reported values depend on: the gyro's K (C_b^m, through which the
    misalignment is read) and the readout's M and c (A and b), 21 of the 41. Differencing only these halves the
    evaluations (BROAD 02: 82 against 42) and gives the same J, bit for bit."""
    acc = n_theta - N_ACC_THETA
    return list(range(GLOBAL_SLICES["dK"].start, GLOBAL_SLICES["dK"].stop)) + list(range(acc, acc + 12))
