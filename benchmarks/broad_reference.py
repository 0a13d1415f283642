"""Independent reference calibration of BROAD trials against the optical truth.

    python benchmarks/broad_reference.py [--trials 02,03,05,07,09,21,32,34,36]
                                         [--broad ../shared/data/broad] [--out ref.json]
                                         [--include-rests]

Sections 1-3 do not use magyro's solver. They fit the gyro and the magnetometer of each trial
directly against the optical orientation, to show what the sensor and the environment
allow: whether gyro scale and bias repeat between trials, whether the gyro's bias during
motion equals its rest mean, whether the magnetometer frame (relative to the gyro) is stable
between trials, and whether the attached-magnet trials' hard iron is constant in time.

Frames: `t` is the optical body frame (truth), `b` the gyro frame, `m` the magnetometer
frame. C_t is the optical attitude (t to ENU).

Each trial is cut to the movement span the benchmark marks, +/- 10 s.

1. Gyro. Windows of 0.1 s (29 samples). Per window the residual is
   log(dC_truth^T dC_gyro): dC_gyro integrates w_t = K_t y + b_t sample by sample (midpoint
   rule plus the dt^2/12 cross term), dC_truth is the optical rotation over the window, with
   the truth interpolated at t + lag_s. Unknowns: K_t (3x3), b_t (3), lag_s. Then
   K_t = C_b_t K_g (QR, K_g upper triangular, positive diagonal) and b_t = C_b_t b_g.
   Standard deviations come from the Jacobian, scaled by the residual variance. Windows
   inside the rests at the ends are left out (`--include-rests` keeps them), so the bias is
   the bias during motion; it is compared with the rest mean, -K_g mean(y_rest), over the
   rests `magyro.nls.solve.moving_session` finds (as magyro's rest check defines it).
2. Magnetometer. y(t) = A C_t(t - tau_s)^T m + h, m a unit vector (ENU). For fixed (m, tau)
   A and h are a linear least squares (solved from precomputed normal equations); m is found
   by Nelder-Mead from a coarse grid, tau by a bounded 1-D search on [0, 40] ms.
   A^-1 = C_m_t R (QR, R upper triangular, positive diagonal) and C_b_m = C_m_t^T C_b_t.
   Variants at the same tau: (a) h(t) a piecewise-linear spline in time, knots every 3 s;
   (b) a linear field gradient m(p) = m0 + G (p - mean p), G symmetric and traceless (per
   metre, relative to the field), p the optical position.
3. Summary: "day B" trials (02, 05, 07, 09) peak-to-peak against the repeatability in the
   paper's Table II.
4. magyro with an ideal magnetometer (`--ideal-magnetometer`): the real gyro, and in place
   of the real magnetometer y = A C_t(t - tau)^T m + h + white noise (0.72 uT, the real
   per-sample level), with A, h, m, tau from section 2. The field is then homogeneous and
   the magnetometer linear by construction, so what still scatters between trials is the
   gyro's own behaviour and the estimator, not the room.

Data: BROAD benchmark (CC BY 4.0), D. Laidig, M. Caruso, A. Cereatti, T. Seel, "BROAD - A
Benchmark for Robust Inertial Orientation Estimation", Data 6(7):72, 2021,
https://github.com/dlaidig/broad.
"""
from __future__ import annotations

import argparse
import json
import math
import sys
import time
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np
import scipy.io
import scipy.sparse
from scipy.optimize import least_squares, minimize, minimize_scalar

from magyro import so3
from magyro.options import Options
from magyro.front.prepare import moving_session
from magyro.io import import_broad_movement
from magyro.result.reported import qr_split
from magyro.session import Session

REPO = Path(__file__).resolve().parents[1]
DEFAULT_TRIALS = "02,03,05,07,09,21,32,34,36"
DEFAULT_BROAD = REPO.parent / "shared" / "data" / "broad"
DAY_B = ("02", "05", "07", "09")
PAPER_TABLE_II = {"scale_ppm": 4000.0, "nonorth_deg": 0.2, "bias_deg_s": 0.03, "misalignment_deg": 0.2}

MARGIN_S = 10.0              # kept either side of the movement span
WINDOW_SAMPLES = 29          # 0.1 s at 285.714 Hz
GYRO_TRUTH_REACH = 3         # truth must be valid this many samples beyond each window end
MAG_LAG_BOUNDS_S = (0.0, 0.04)
H_KNOT_S = 3.0
UPPER_OFF = ([0, 0, 1], [1, 2, 2])   # K_g upper off-diagonal entries xy, xz, yz


# --------------------------------------------------------------------------- data

class TruthAttitude:
    """The optical attitude C_t (t to ENU) on a time base, interpolated between valid samples."""

    def __init__(self, t_s: np.ndarray, quat_wxyz: np.ndarray):
        self.valid = np.isfinite(quat_wxyz).all(axis=1)
        q = quat_wxyz[self.valid] / np.linalg.norm(quat_wxyz[self.valid], axis=1, keepdims=True)
        flips = np.cumprod(np.where(np.sum(q[1:] * q[:-1], axis=1) < 0, -1.0, 1.0))
        q[1:] *= flips[:, None]   # sign continuity, so that linear interpolation takes the short way
        self.t_valid_s, self.q_valid = t_s[self.valid], q
        self._invalid_before = np.concatenate([[0], np.cumsum(~self.valid)])

    def dcm_at(self, t_s: np.ndarray) -> np.ndarray:
        """C_t at times t_s by normalised linear interpolation of the quaternion."""
        q = np.column_stack([np.interp(t_s, self.t_valid_s, self.q_valid[:, j]) for j in range(4)])
        return so3.quat_to_dcm(q)

    def valid_around(self, idx: np.ndarray, reach: int) -> np.ndarray:
        """True where the truth is valid at every sample idx - reach .. idx + reach."""
        n = len(self.valid)
        lo, hi = np.clip(idx - reach, 0, n), np.clip(idx + reach + 1, 0, n)
        return (self._invalid_before[hi] - self._invalid_before[lo] == 0) & (idx - reach >= 0) & (idx + reach < n)


@dataclass
class Trial:
    name: str
    session: Session          # trimmed to the movement span +/- MARGIN_S
    t_s: np.ndarray           # the common time base of gyro, magnetometer and truth
    gyro_rad_s: np.ndarray
    mag_uT: np.ndarray
    pos_m: np.ndarray         # optical position, NaN where lost
    truth: TruthAttitude


def trial_path(broad_dir: Path, name: str) -> Path:
    found = sorted(Path(broad_dir).glob(f"{name}_*.mat"))
    if not found:
        sys.exit(f"no BROAD trial {name}_*.mat in {broad_dir}")
    return found[0]


def truth_on_gyro_times(session: Session) -> np.ndarray:
    """The truth quaternions on the gyro time base, NaN where the markers were lost."""
    t = session.t_gyro_s
    q = np.full((len(t), 4), np.nan)
    k = np.minimum(np.searchsorted(t, session.t_quat_s - 1e-9), len(t) - 1)
    same = np.abs(t[k] - session.t_quat_s) < 1e-6
    q[k[same]] = session.quat_wxyz[same]
    return q


def optical_position_m(path: Path, t_s: np.ndarray, rate_hz: float) -> np.ndarray:
    """opt_pos (m) at the samples t_s = k / rate_hz of the file."""
    pos = np.asarray(scipy.io.loadmat(str(path), variable_names=["opt_pos"])["opt_pos"], dtype=float)
    return pos[np.rint(t_s * rate_hz).astype(int)]


def load_trial(broad_dir: Path, name: str) -> Trial:
    path = trial_path(broad_dir, name)
    session = import_broad_movement(path, MARGIN_S)
    t_s = session.t_gyro_s
    if not np.array_equal(t_s, session.t_mag_s):
        sys.exit(f"{path}: gyro and magnetometer are not on one time base")
    rate_hz = float(session.metadata["sampling_rate_hz"])
    return Trial(name, session, t_s, session.gyro_rad_s, session.mag, optical_position_m(path, t_s, rate_hz),
                 TruthAttitude(t_s, truth_on_gyro_times(session)))


def table(title: str, header: list[str], rows: list[list[str]]) -> str:
    """Plain-text table, columns right-aligned (the first left-aligned)."""
    cells = [header] + rows
    widths = [max(len(r[j]) for r in cells) for j in range(len(header))]

    def line(r):
        return "  ".join(c.ljust(w) if j == 0 else c.rjust(w) for j, (c, w) in enumerate(zip(r, widths)))

    rule = "-" * len(line(header))
    return "\n".join([title, rule, line(header), rule] + [line(r) for r in rows] + [rule, ""])


def pm(value: float, std: float | None, digits: int) -> str:
    return f"{value:.{digits}f}" if std is None else f"{value:.{digits}f}±{std:.{digits}f}"


# --------------------------------------------------------------------------- gyro

def window_starts(trial: Trial, t_from_s: float, t_to_s: float) -> np.ndarray:
    """Window start indices: windows inside [t_from_s, t_to_s] with valid truth around both ends."""
    W = WINDOW_SAMPLES
    st = np.arange(0, len(trial.t_s) - W - GYRO_TRUTH_REACH, W)
    inside = (trial.t_s[st] >= t_from_s) & (trial.t_s[st + W] <= t_to_s)
    ok = trial.truth.valid_around(st, GYRO_TRUTH_REACH) & trial.truth.valid_around(st + W, GYRO_TRUTH_REACH)
    return st[inside & ok]


def integrate_windows(w_rad_s: np.ndarray, starts: np.ndarray, dt_s: float) -> np.ndarray:
    """dC over each window: product of Exp(dt (wa + wb) / 2 + dt^2 / 12 wa x wb) over its steps."""
    idx = starts[:, None] + np.arange(WINDOW_SAMPLES)[None]
    wa, wb = w_rad_s[idx], w_rad_s[idx + 1]
    phi = 0.5 * (wa + wb) * dt_s + dt_s**2 / 12.0 * np.cross(wa, wb)
    step = so3.exp_quat(phi.reshape(-1, 3)).reshape(len(starts), WINDOW_SAMPLES, 4)
    q = step[:, 0]
    for j in range(1, WINDOW_SAMPLES):
        q = so3.quat_multiply(q, step[:, j])
    return so3.quat_to_dcm(q)


def truth_window_rotations(trial: Trial, starts: np.ndarray, lag_s: float) -> np.ndarray:
    """C_t(ta + lag)^T C_t(tb + lag): the optical rotation over each window."""
    Ca = trial.truth.dcm_at(trial.t_s[starts] + lag_s)
    Cb = trial.truth.dcm_at(trial.t_s[starts + WINDOW_SAMPLES] + lag_s)
    return np.swapaxes(Ca, -1, -2) @ Cb


def unpack_gyro(p: np.ndarray) -> tuple[np.ndarray, np.ndarray, float]:
    """(K_t, b_t_rad_s, lag_s) from the 13 fitted numbers."""
    return p[:9].reshape(3, 3), p[9:12], float(p[12])


def gyro_residuals(p: np.ndarray, trial: Trial, starts: np.ndarray, dt_s: float) -> np.ndarray:
    K_t, b_t_rad_s, lag_s = unpack_gyro(p)
    dC_gyro = integrate_windows(trial.gyro_rad_s @ K_t.T + b_t_rad_s, starts, dt_s)
    dC_truth = truth_window_rotations(trial, starts, lag_s)
    return so3.log_so3(np.swapaxes(dC_truth, -1, -2) @ dC_gyro).ravel()


def gyro_reported(p: np.ndarray) -> np.ndarray:
    """[K_g diag - 1 (ppm) x3, non-orthogonality (deg) xy xz yz, bias_deg_s (gyro frame) x3,
    C_b_t euler (deg) x3, lag_ms]."""
    K_t, b_t_rad_s, lag_s = unpack_gyro(p)
    C_b_t, K_g = qr_split(K_t)
    b_g_rad_s = C_b_t.T @ b_t_rad_s
    return np.concatenate([(np.diag(K_g) - 1.0) * 1e6, np.rad2deg(K_g[UPPER_OFF]), np.rad2deg(b_g_rad_s),
                           so3.dcm_to_euler(C_b_t), [1e3 * lag_s]])


def propagated_std(f, x: np.ndarray, cov: np.ndarray, step: float = 1e-7) -> np.ndarray:
    """std of f(x) for x with covariance cov (forward-difference Jacobian)."""
    f0 = f(x)
    J = np.empty((len(f0), len(x)))
    for j in range(len(x)):
        dx = np.zeros_like(x)
        dx[j] = step
        J[:, j] = (f(x + dx) - f0) / step
    return np.sqrt(np.maximum(np.diag(J @ cov @ J.T), 0.0))


def rests_and_moving_span(trial: Trial):
    """(rests, moving span (t0, t1) in s) as magyro's calibration finds them."""
    moving, _, rests = moving_session(trial.session, Options())
    return rests, (float(moving.t_gyro_s[0]), float(moving.t_gyro_s[-1]))


def rest_bias_rad_s(rests, K_g: np.ndarray) -> np.ndarray:
    """The bias the rests imply, -K_g mean(y_rest) (magyro.nls.solve.rest_check); NaN without rests."""
    if rests.gyro_mean_rad_s is None:
        return np.full(3, np.nan)
    return -K_g @ rests.gyro_mean_rad_s


def gyro_reference(trial: Trial, include_rests: bool) -> dict:
    """Gyro calibration against the truth, and its bias against the rest mean."""
    rests, span = rests_and_moving_span(trial)
    span = (trial.t_s[0], trial.t_s[-1]) if include_rests else span
    starts = window_starts(trial, *span)
    dt_s = float(np.mean(np.diff(trial.t_s)))
    p0 = np.r_[np.eye(3).ravel(), np.zeros(3), 0.0]
    sol = least_squares(gyro_residuals, p0, args=(trial, starts, dt_s), diff_step=1e-7,
                        x_scale=np.r_[np.full(9, 1e-2), np.full(3, 1e-3), 1e-3])
    r = sol.fun
    consecutive = np.diff(starts) == WINDOW_SAMPLES
    r3 = r.reshape(-1, 3)
    lag1_corr = [float(np.corrcoef(r3[:-1][consecutive, a], r3[1:][consecutive, a])[0, 1]) for a in range(3)]
    cov = np.linalg.pinv(sol.jac.T @ sol.jac) * (r @ r) / (len(r) - len(p0))
    rep, rep_std = gyro_reported(sol.x), propagated_std(gyro_reported, sol.x, cov)
    K_t, b_t_rad_s, lag_s = unpack_gyro(sol.x)
    C_b_t, K_g = qr_split(K_t)
    rest_deg_s = np.rad2deg(rest_bias_rad_s(rests, K_g))
    return {
        "windows": int(len(starts)),
        "span_s": [float(span[0]), float(span[1])],
        "rms_mrad": float(1e3 * np.sqrt(np.mean(r**2))),
        "residual_lag1_corr": lag1_corr,   # between consecutive windows (they share an end sample)
        "K_t": K_t.tolist(), "b_t_deg_s": np.rad2deg(b_t_rad_s).tolist(),
        "C_b_t": C_b_t.tolist(), "K_g": K_g.tolist(),
        "scale_ppm": rep[0:3].tolist(), "scale_ppm_std": rep_std[0:3].tolist(),
        "nonorth_deg": rep[3:6].tolist(), "nonorth_deg_std": rep_std[3:6].tolist(),
        "bias_deg_s": rep[6:9].tolist(), "bias_deg_s_std": rep_std[6:9].tolist(),
        "C_b_t_euler_deg": rep[9:12].tolist(), "C_b_t_euler_deg_std": rep_std[9:12].tolist(),
        "lag_ms": float(rep[12]), "lag_ms_std": float(rep_std[12]),
        "rest_s": rests.seconds, "rest_bias_deg_s": rest_deg_s.tolist(),
        "bias_minus_rest_deg_s": (rep[6:9] - rest_deg_s).tolist(),
    }


# --------------------------------------------------------------------------- magnetometer

def unit_vector(az: float, el: float) -> np.ndarray:
    return np.array([np.cos(el) * np.cos(az), np.cos(el) * np.sin(az), np.sin(el)])


def sym_traceless(g: np.ndarray) -> np.ndarray:
    a, b, c, d, e = g
    return np.array([[a, b, c], [b, d, e], [c, e, -a - d]])


def field_matrix(theta: np.ndarray) -> np.ndarray:
    """M = [m0] or [m0 | G] (3 x nz): theta = (az, el) or (az, el, 5 gradient numbers per metre)."""
    m0 = unit_vector(theta[0], theta[1])[:, None]
    return m0 if len(theta) == 2 else np.hstack([m0, sym_traceless(theta[2:7])])


def hat_basis(t_s: np.ndarray, knot_s: float | None) -> scipy.sparse.csr_matrix:
    """h(t) = B c: a constant (knot_s None) or a piecewise-linear spline with knots every knot_s."""
    n = len(t_s)
    if knot_s is None:
        return scipy.sparse.csr_matrix(np.ones((n, 1)))
    n_knots = int(math.ceil((t_s[-1] - t_s[0]) / knot_s)) + 1
    k = np.clip(np.floor((t_s - t_s[0]) / knot_s).astype(int), 0, n_knots - 2)
    f = (t_s - t_s[0]) / knot_s - k
    rows = np.r_[np.arange(n), np.arange(n)]
    B = scipy.sparse.csr_matrix((np.r_[1 - f, f], (rows, np.r_[k, k + 1])), shape=(n, n_knots))
    used = np.asarray(B.sum(axis=0)).ravel() > 1e-9   # drop knots with no samples (long truth gaps)
    return B[:, used].tocsr()


class MagNormalEquations:
    """y_n = A C_n^T M z_n + B_n c for fixed lag: A (3x3) and c (K x 3) by linear least squares.

    u_n = C_n^T M z_n = P_n vec(M), so every normal-equation block is a contraction of
    sums over samples that are computed once; each trial (M) then costs O(K^3), not O(N).
    """

    def __init__(self, C: np.ndarray, z: np.ndarray, B: scipy.sparse.csr_matrix, y: np.ndarray):
        n, nz = z.shape
        self.nz, self.n = nz, n
        P = np.einsum("nki,na->nika", C, z).reshape(n, 3 * 3 * nz)   # P[n, (i, k, a)] = C[n,k,i] z[n,a]
        q = 3 * nz
        self.PtP = (P.T @ P).reshape(3, q, 3, q)
        self.PtB = np.asarray(B.T @ P).T.reshape(3, q, B.shape[1])
        self.Pty = (P.T @ y).reshape(3, q, 3)
        self.BtB = (B.T @ B).toarray()
        self.Bty = np.asarray(B.T @ y)
        self.yty = float(np.sum(y * y))

    def solve(self, M: np.ndarray) -> tuple[np.ndarray, float]:
        """(coefficients [A^T; c] of shape (3 + K, 3), mean square residual)."""
        mu = M.ravel()
        U = np.einsum("c,icjd,d->ij", mu, self.PtP, mu)
        UB = np.einsum("c,ick->ik", mu, self.PtB)
        Uy = np.einsum("c,ica->ia", mu, self.Pty)
        N = np.block([[U, UB], [UB.T, self.BtB]])
        rhs = np.vstack([Uy, self.Bty])
        try:
            coef = np.linalg.solve(N, rhs)
        except np.linalg.LinAlgError:
            coef = np.linalg.lstsq(N, rhs, rcond=None)[0]
        return coef, max(self.yty - float(np.sum(coef * rhs)), 0.0) / (3 * self.n)


@dataclass
class MagData:
    """The magnetometer samples used (valid truth within the lag range, valid position)."""

    t_s: np.ndarray
    y_uT: np.ndarray
    dp_m: np.ndarray      # position minus its mean
    truth: TruthAttitude

    def normal_equations(self, lag_s: float, knot_s: float | None, gradient: bool) -> MagNormalEquations:
        C = self.truth.dcm_at(self.t_s - lag_s)
        z = np.hstack([np.ones((len(self.t_s), 1))] + ([self.dp_m] if gradient else []))
        return MagNormalEquations(C, z, hat_basis(self.t_s, knot_s), self.y_uT)


def mag_data(trial: Trial) -> MagData:
    reach = int(math.ceil(MAG_LAG_BOUNDS_S[1] * trial.session.gyro_rate_hz)) + 1
    use = trial.truth.valid_around(np.arange(len(trial.t_s)), reach) & np.isfinite(trial.pos_m).all(axis=1)
    pos = trial.pos_m[use]
    return MagData(trial.t_s[use], trial.mag_uT[use], pos - pos.mean(axis=0), trial.truth)


GRID_AZ = np.linspace(-np.pi, np.pi, 13)[:-1]
GRID_EL = np.linspace(-1.3, 1.3, 7)


def best_direction(eq: MagNormalEquations, start: np.ndarray | None) -> tuple[np.ndarray, float]:
    """(az, el) of m minimising the residual: Nelder-Mead from `start`, or from the best of a coarse grid."""
    def cost(theta):
        return eq.solve(field_matrix(theta))[1]

    if start is None:
        start = min(((a, e) for a in GRID_AZ for e in GRID_EL), key=lambda ae: cost(np.array(ae)))
    sol = minimize(cost, np.asarray(start, float), method="Nelder-Mead",
                   options={"xatol": 1e-8, "fatol": 1e-12, "maxfev": 4000})
    return sol.x, float(sol.fun)


def best_gradient_field(eq: MagNormalEquations, start: np.ndarray) -> tuple[np.ndarray, float]:
    """(az, el, G) minimising the residual with a field gradient: Nelder-Mead, restarted until it settles."""
    def cost(theta):
        return eq.solve(field_matrix(theta))[1]

    x, f = np.r_[start, np.zeros(5)], math.inf
    for _ in range(5):
        simplex = np.vstack([x] + [x + np.eye(7)[j] * (0.02 if j < 2 else 0.01) for j in range(7)])
        sol = minimize(cost, x, method="Nelder-Mead",
                       options={"initial_simplex": simplex, "xatol": 1e-9, "fatol": 1e-13, "maxfev": 20000,
                                "adaptive": True})
        settled = f - sol.fun < 1e-9 * sol.fun
        x, f = sol.x, float(sol.fun)
        if settled:
            break
    return x, f


def frame_from_A(A: np.ndarray) -> np.ndarray:
    """C_m_t from A^-1 = C_m_t R, R upper triangular with positive diagonal."""
    Q, R = np.linalg.qr(np.linalg.inv(A))
    return Q @ np.diag(np.sign(np.diag(R)))


def mag_solution(data: MagData, eq: MagNormalEquations, lag_s: float, theta: np.ndarray, knot_s: float | None,
                 C_b_t: np.ndarray) -> dict:
    """A, h(t), residuals and frames at the fitted (theta, lag); m's sign chosen so that det A > 0."""
    M = field_matrix(theta)
    coef, _ = eq.solve(M)
    A = coef[:3].T
    if np.linalg.det(A) < 0:      # y is unchanged by (M, A) -> (-M, -A)
        M, A = -M, -A
    C = data.truth.dcm_at(data.t_s - lag_s)
    z = np.hstack([np.ones((len(data.t_s), 1))] + ([data.dp_m] if M.shape[1] > 1 else []))
    u = np.einsum("nki,kl,nl->ni", C, M, z)
    h_uT = np.asarray(hat_basis(data.t_s, knot_s) @ coef[3:])
    r = data.y_uT - u @ A.T - h_uT
    C_m_t = frame_from_A(A)
    C_b_m = C_m_t.T @ C_b_t
    out = {
        "rms_uT": float(np.sqrt(np.mean(r**2))),
        "m_enu": M[:, 0].tolist(), "A": A.tolist(),
        "h_uT": h_uT.mean(axis=0).tolist(), "h_p2p_uT": np.ptp(h_uT, axis=0).tolist(),
        "C_m_t": C_m_t.tolist(), "C_m_t_euler_deg": so3.dcm_to_euler(C_m_t).tolist(),
        "C_b_m": C_b_m.tolist(), "C_b_m_euler_deg": so3.dcm_to_euler(C_b_m).tolist(),
    }
    if M.shape[1] > 1:
        G = M[:, 1:]
        out["G_per_m"] = G.tolist()
        out["G_percent_per_m"] = float(100 * np.linalg.norm(G))
    return out


def search_lag(data: MagData, knot_s: float | None) -> tuple[float, np.ndarray]:
    """(lag_s, (az, el)): bounded 1-D search on the lag, m re-fitted at each (grid once, then warm starts)."""
    state = {"theta": None}

    def cost_at_lag(lag_s):
        theta, f = best_direction(data.normal_equations(lag_s, knot_s, False), state["theta"])
        state["theta"] = theta
        return f

    cost_at_lag(0.0155)
    lag_s = float(minimize_scalar(cost_at_lag, bounds=MAG_LAG_BOUNDS_S, method="bounded",
                                  options={"xatol": 1e-6}).x)
    theta, _ = best_direction(data.normal_equations(lag_s, knot_s, False), state["theta"])
    return lag_s, theta


def mag_reference(trial: Trial, C_b_t: np.ndarray) -> dict:
    """Magnetometer against the truth: lag and m with a constant h, then the two variants at that lag.

    The lag the spline-h model would choose by itself is reported too (a check on the magnet trials,
    where a constant h is wrong)."""
    data = mag_data(trial)
    lag_s, theta = search_lag(data, None)
    plain = mag_solution(data, data.normal_equations(lag_s, None, False), lag_s, theta, None, C_b_t)

    eq_h = data.normal_equations(lag_s, H_KNOT_S, False)
    theta_h = min([best_direction(eq_h, theta), best_direction(eq_h, None)], key=lambda c: c[1])[0]
    spline = mag_solution(data, eq_h, lag_s, theta_h, H_KNOT_S, C_b_t)
    spline["own_tau_ms"] = 1e3 * search_lag(data, H_KNOT_S)[0]

    eq_g = data.normal_equations(lag_s, None, True)
    theta_g, _ = best_gradient_field(eq_g, theta)
    gradient = mag_solution(data, eq_g, lag_s, theta_g, None, C_b_t)
    return {"samples": int(len(data.t_s)), "tau_ms": 1e3 * lag_s, "plain": plain, "h_spline": spline,
            "gradient": gradient}


# --------------------------------------------------------------------------- tables

def gyro_tables(results: dict, include_rests: bool) -> str:
    rows, bias_rows = [], []
    for name, r in results.items():
        g = r["gyro"]
        rows.append([name, str(g["windows"]), f"{g['rms_mrad']:.3f}", pm(g["lag_ms"], g["lag_ms_std"], 2)]
                    + [pm(v, s, 0) for v, s in zip(g["scale_ppm"], g["scale_ppm_std"])]
                    + [pm(v, s, 3) for v, s in zip(g["nonorth_deg"], g["nonorth_deg_std"])])
        bias_rows.append([name] + [pm(v, s, 4) for v, s in zip(g["bias_deg_s"], g["bias_deg_s_std"])]
                         + [f"{g['rest_s']:.1f}"] + [f"{v:.4f}" for v in g["rest_bias_deg_s"]]
                         + [f"{v:+.4f}" for v in g["bias_minus_rest_deg_s"]])
    a = table("Gyro against optical truth (0.1 s windows; std from the Jacobian, residual-scaled)",
              ["trial", "windows", "rms mrad", "lag ms", "K_g-1 x ppm", "y ppm", "z ppm",
               "nonorth xy deg", "xz deg", "yz deg"], rows)
    fitted_over = "motion and rests" if include_rests else "motion only"
    b = table(f"Gyro bias (gyro frame, deg/s): reference (fitted over {fitted_over}), rest mean -K_g mean(y_rest), "
              "difference",
              ["trial", "bias x", "bias y", "bias z", "rest s", "rest x", "rest y", "rest z",
               "ref-rest x", "ref-rest y", "ref-rest z"], bias_rows)
    return a + "\n" + b


def mag_tables(results: dict) -> str:
    rows = []
    for name, r in results.items():
        m, g = r["mag"], r["gyro"]
        rows.append([name, str(m["samples"]), f"{m['tau_ms']:.2f}", f"{m['tau_ms'] + g['lag_ms']:.2f}",
                     f"{m['plain']['rms_uT']:.3f}", f"{m['h_spline']['rms_uT']:.3f}",
                     f"{m['h_spline']['own_tau_ms']:.2f}"]
                    + [f"{v:.2f}" for v in m["h_spline"]["h_p2p_uT"]]
                    + [f"{m['gradient']['rms_uT']:.3f}", f"{m['gradient']['G_percent_per_m']:.2f}"])
    a = table("Magnetometer against optical truth (tau: truth at t - tau; mag-gyro = tau + gyro lag)",
              ["trial", "samples", "tau ms", "mag-gyro ms", "rms const h uT", f"rms h {H_KNOT_S:g}s uT", "(own tau ms)",
               "h p2p x uT", "y uT", "z uT", "rms grad uT", "|G| %/m"], rows)
    frows = []
    for name, r in results.items():
        m, g = r["mag"], r["gyro"]
        frows.append([name] + [f"{v:.3f}" for v in g["C_b_t_euler_deg"]]
                     + [f"{v:.3f}" for v in m["plain"]["C_m_t_euler_deg"]]
                     + [f"{v:.3f}" for v in m["plain"]["C_b_m_euler_deg"]]
                     + [f"{v:.3f}" for v in m["gradient"]["C_b_m_euler_deg"]]
                     + [f"{v:.3f}" for v in m["h_spline"]["C_b_m_euler_deg"]])
    b = table("Frames, euler [roll pitch yaw] deg: C_b_t (gyro), C_m_t (mag), C_b_m = C_m_t^T C_b_t "
              f"(constant h; with the gradient; with h every {H_KNOT_S:g} s)",
              ["trial", "C_b_t r", "p", "y", "C_m_t r", "p", "y", "C_b_m r", "p", "y", "grad C_b_m r", "p", "y",
               "h3s C_b_m r", "p", "y"], frows)
    return a + "\n" + b


def day_b_summary(results: dict) -> dict | None:
    trials = [t for t in DAY_B if t in results]
    if len(trials) < 2:
        return None

    def p2p(get):
        return np.ptp(np.array([get(results[t]) for t in trials], dtype=float), axis=0).tolist()

    return {
        "trials": trials,
        "scale_ppm": p2p(lambda r: r["gyro"]["scale_ppm"]),
        "nonorth_deg": p2p(lambda r: r["gyro"]["nonorth_deg"]),
        "bias_deg_s": p2p(lambda r: r["gyro"]["bias_deg_s"]),
        "C_b_m_euler_deg": p2p(lambda r: r["mag"]["plain"]["C_b_m_euler_deg"]),
        "C_b_m_euler_deg_gradient": p2p(lambda r: r["mag"]["gradient"]["C_b_m_euler_deg"]),
        "C_b_t_euler_deg": p2p(lambda r: r["gyro"]["C_b_t_euler_deg"]),
    }


def day_b_table(s: dict) -> str:
    P = PAPER_TABLE_II
    rows = [
        ["K_g diagonal (ppm)"] + [f"{v:.0f}" for v in s["scale_ppm"]] + [f"{P['scale_ppm']:.0f}"],
        ["non-orthogonality xy xz yz (deg)"] + [f"{v:.3f}" for v in s["nonorth_deg"]] + [f"{P['nonorth_deg']:g}"],
        ["bias (deg/s)"] + [f"{v:.4f}" for v in s["bias_deg_s"]] + [f"{P['bias_deg_s']:g}"],
        ["C_b_m euler, const h (deg)"] + [f"{v:.3f}" for v in s["C_b_m_euler_deg"]] + [f"{P['misalignment_deg']:g}"],
        ["C_b_m euler, gradient (deg)"] + [f"{v:.3f}" for v in s["C_b_m_euler_deg_gradient"]]
        + [f"{P['misalignment_deg']:g}"],
        ["C_b_t euler (gyro to optical; deg)"] + [f"{v:.3f}" for v in s["C_b_t_euler_deg"]] + ["-"],
    ]
    return table(f"Day B ({', '.join(s['trials'])}): peak-to-peak across trials against the paper's Table II "
                 "repeatability", ["quantity", "x / roll", "y / pitch", "z / yaw", "paper Table II"], rows)


# --------------------------------------------------------------------------- magyro, ideal magnetometer

IDEAL_MAG_NOISE_UT = 0.72     # the real per-sample std at rest (BROAD, day B)
IDEAL_MAG_TRUTH_REACH = 10    # samples of valid truth needed around each synthetic sample


def ideal_magnetometer_session(trial: Trial, mag: dict, seed: int = 0) -> Session:
    """The trial with its magnetometer replaced by the fitted model driven by the truth, plus white noise."""
    fit = mag["plain"]
    A, h, m = np.asarray(fit["A"]), np.asarray(fit["h_uT"]), np.asarray(fit["m_enu"])
    ok = trial.truth.valid_around(np.arange(len(trial.t_s)), IDEAL_MAG_TRUTH_REACH)
    C = trial.truth.dcm_at(trial.t_s[ok] - 1e-3 * mag["tau_ms"])
    noise = IDEAL_MAG_NOISE_UT * np.random.default_rng(seed).standard_normal((int(ok.sum()), 3))
    y = np.einsum("nki,k->ni", C, m) @ A.T + h + noise
    return replace(trial.session, t_mag_s=trial.t_s[ok], mag=y)


def magyro_ideal(trial: Trial, ref: dict) -> dict:
    """magyro's gyro estimates on the ideal-magnetometer session, with their std."""
    from magyro import calibrate

    cal = calibrate(ideal_magnetometer_session(trial, ref["mag"]), Options(accelerometer=False))
    std = cal.std
    return {
        "scale_ppm": (1e6 * (np.diag(cal.K_g) - 1)).tolist(), "scale_ppm_std": (1e6 * np.diag(std.K_g)).tolist(),
        "nonorth_deg": np.rad2deg(cal.K_g[UPPER_OFF]).tolist(),
        "nonorth_deg_std": np.rad2deg(np.asarray(std.K_g)[UPPER_OFF]).tolist(),
        "bias_deg_s": cal.bias_deg_s.tolist(), "bias_deg_s_std": np.asarray(std.bias_deg_s).tolist(),
        "lag_ms": 1e3 * cal.time_offset_s,
    }


def ideal_table(results: dict) -> str:
    rows = []
    for name, r in results.items():
        if "ideal" not in r:
            continue
        i, g = r["ideal"], r["gyro"]
        rows.append([name] + [pm(v, s, 0) for v, s in zip(i["scale_ppm"], i["scale_ppm_std"])]
                    + [pm(v, s, 3) for v, s in zip(i["nonorth_deg"], i["nonorth_deg_std"])]
                    + [pm(v, s, 4) for v, s in zip(i["bias_deg_s"], i["bias_deg_s_std"])]
                    + [f"{v:+.4f}" for v in np.asarray(i["bias_deg_s"]) - np.asarray(g["rest_bias_deg_s"])])
    trials = [t for t in DAY_B if t in results and "ideal" in results[t]]
    if len(trials) >= 2:
        def p2p(key):
            return np.ptp(np.array([results[t]["ideal"][key] for t in trials]), axis=0)
        rows.append([f"p2p {'/'.join(trials)}"] + [f"{v:.0f}" for v in p2p("scale_ppm")]
                    + [f"{v:.3f}" for v in p2p("nonorth_deg")] + [f"{v:.4f}" for v in p2p("bias_deg_s")] + [""] * 3)
    return table("magyro on the real gyro with an ideal magnetometer (truth-driven, homogeneous field); "
                 "Table II: 4000 ppm, 0.2 deg, 0.03 deg/s",
                 ["trial", "K_g-1 x ppm", "y ppm", "z ppm", "nonorth xy deg", "xz deg", "yz deg",
                  "bias x", "bias y", "bias z", "-rest x", "-rest y", "-rest z"], rows)


# --------------------------------------------------------------------------- main

def reference_for(broad_dir: Path, name: str, include_rests: bool, ideal: bool) -> dict:
    start = time.perf_counter()
    trial = load_trial(broad_dir, name)
    gyro = gyro_reference(trial, include_rests)
    mag = mag_reference(trial, np.asarray(gyro["C_b_t"]))
    out = {"gyro": gyro, "mag": mag}
    if ideal:
        out["ideal"] = magyro_ideal(trial, out)
    return {**out, "seconds": time.perf_counter() - start}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--trials", default=DEFAULT_TRIALS, help="comma-separated trial numbers")
    ap.add_argument("--broad", type=Path, default=DEFAULT_BROAD, help="folder with the BROAD .mat files")
    ap.add_argument("--out", type=Path, help="also write the numbers here as JSON")
    ap.add_argument("--include-rests", action="store_true",
                    help="fit the gyro over the rests at the ends too (default: the moving span only)")
    ap.add_argument("--ideal-magnetometer", action="store_true",
                    help="also run magyro with the magnetometer replaced by the truth-driven fitted model")
    args = ap.parse_args()

    start = time.perf_counter()
    results = {}
    for name in [t.strip() for t in args.trials.split(",") if t.strip()]:
        results[name] = reference_for(args.broad, name, args.include_rests, args.ideal_magnetometer)
        print(f"trial {name}: {results[name]['seconds']:.1f} s", file=sys.stderr, flush=True)
    print(gyro_tables(results, args.include_rests))
    print(mag_tables(results))
    summary = day_b_summary(results)
    if summary:
        print(day_b_table(summary))
    if args.ideal_magnetometer:
        print(ideal_table(results))
    total_s = time.perf_counter() - start
    print(f"runtime {total_s:.1f} s for {len(results)} trial(s)")
    if args.out:
        sys.path.insert(0, str(Path(__file__).resolve().parent))
        from machine_load import provenance

        flags = " --ideal-magnetometer" * args.ideal_magnetometer + " --include-rests" * args.include_rests
        args.out.write_text(json.dumps({**provenance(f"python benchmarks/broad_reference.py{flags} --out FILE"),
                                        "trials": results, "day_b": summary, "paper_table_ii": PAPER_TABLE_II,
                                        "runtime_s": total_s, "include_rests": args.include_rests,
                                        "credit": "BROAD (CC BY 4.0): Laidig, Caruso, Cereatti, Seel, Data 6(7):72, "
                                                  "2021"}, indent=1))


if __name__ == "__main__":
    main()
