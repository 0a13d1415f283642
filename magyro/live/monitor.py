"""`ExcitationMonitor`: the excitation of a recording while it is being made.

The fast part, on every `update()` (several times a second), costs O(1) per new sample:

- **the integral of M^T M (paper eq. 11)** is not recomputed from the start. With
  ytilde = [y_g; 1] and the calibrated field an affine map of the raw magnetometer reading,
  m = R (y_m - h) = A q with q = [y_m; 1] and A = [R, -R h] (3 x 4),

      M^T M = (ytilde ytilde^T) (x) (|m|^2 I - m m^T)

  is a fixed linear function (given A) of the 16 x 16 outer product of z = ytilde (x) q. The
  monitor keeps G = integral of z z^T dt (trapezoid over the gyro times, the magnetometer
  interpolated linearly there, holes left out: exactly `matrix.information_integral`'s rule) and
  projects it with the current A. So when the ellipsoid fit improves, the whole integral is
  re-projected *exactly* onto the new field directions in O(1), and the sensor-noise matrix N
  of `gate.noise_matrix` comes from the same G (its blocks integral ytilde ytilde^T and
  integral q q^T). The rank is then counted exactly as the gate counts it
  (`gate.directional_rank`: an eigen-direction counts above 10x what noise alone puts in it).
- **field directions before the magnetometer is calibrated**: the choice is a running ellipsoid
  fit (`ellipsoid.fit_ellipsoid` on all readings so far, refreshed every `FIT_EVERY_S` seconds of
  data once there are `MIN_FIT_SAMPLES` readings; the last good fit is kept when a later cloud
  does not fit). Until the first fit succeeds (a static or one-axis cloud determines no
  ellipsoid), the field directions are observe's surrogate, the raw readings over their mean
  length (`ellipsoid.surrogate_field_directions`, with one common length instead of each
  reading's own, which keeps m affine in the reading and hence the exact re-projection above).
  The noise level in field units is observe's: per-sample std times mean(diag R), or over the
  mean reading length before a fit.
- **noise levels**: white-noise stds from robust third differences (`front.noise.white_noise_std`)
  of the last `NOISE_WINDOW` samples, refreshed with the fit.
- **coverage**: the equal-area sphere cells of the field directions (`observability.report.sphere_cell`),
  marked as readings arrive and recounted when the fit changes.

The slow part, the predicted one-sigma of every gyro parameter, is `magyro observe`'s own
(`magyro.observe` on the session so far: the recording check, rests, ellipsoid, Gauss-Newton
information of the joint problem), run by a `Predictor` in a background process (or thread, or
inline for tests) whenever the rank is 12 and the previous prediction has finished, at most every
`refresh_s` (2) seconds of data and every twice the last prediction's cost. Live, a prediction of
the data up to t is therefore shown at t + its cost (0.5 s on 99 s of data in a real-time run). A prediction carries the data time it refers to; "enough" is that
prediction meeting every target. benchmarks/bench_watch.py measures its cost.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from magyro.errors import InputError
from magyro.front import ellipsoid
from magyro.front.noise import white_noise_std
from magyro.front.rests import WINDOW_S, still_prefix_s
from magyro.observability.advice import direction_advice
from magyro.live.prediction import GROUPS, Prediction, Predictor, meets, targets_dict
from magyro.observability.gate import FLOOR_FACTOR, NUMERICAL_RTOL, directional_rank
from magyro.session import HOLE_FACTOR, Session

FIT_EVERY_S = 2.0           # the ellipsoid and the noise levels are refreshed every this many seconds of data
MIN_FIT_SAMPLES = 200       # magnetometer readings before the first fit is tried
NOISE_WINDOW = 4000         # samples of each sensor the noise levels are estimated from
DT_WINDOW = 4096            # gyro steps whose median sets the hole threshold (the gate: all steps)
MIN_NOISE_SAMPLES = 50      # per sensor, before the noise levels (and so any rank) are given
EARLY_REFRESH_S = 0.5       # refresh interval while fewer than NOISE_WINDOW samples are in
TURN_DEG = 90               # the turn the instruction asks for
END_REST_S = 2.0            # after ENOUGH, the device is put down this long before the recording stops: the end
                            # rest (front.rests) gives the bias check and, with the start rest, the noise levels
AXES = "xyz"


# --------------------------------------------------------------------------- growing arrays


class _Rows:
    """Rows (t, x, y, z) appended in blocks; `view()` is the filled part (views stay valid as it grows)."""

    def __init__(self, capacity: int = 4096):
        self.a = np.empty((capacity, 4))
        self.n = 0

    def extend(self, rows) -> None:
        """Append rows; a row whose time does not increase (over all rows so far) is dropped."""
        rows = np.asarray(rows, dtype=float).reshape(-1, 4)
        last = self.a[self.n - 1, 0] if self.n else -np.inf
        before = np.maximum.accumulate(np.concatenate([[last], rows[:-1, 0]])) if len(rows) else rows[:, 0]
        rows = rows[rows[:, 0] > before]
        need = self.n + len(rows)
        if need > len(self.a):
            bigger = np.empty((max(need, 2 * len(self.a)), 4))
            bigger[: self.n] = self.a[: self.n]
            self.a = bigger
        self.a[self.n: need] = rows
        self.n = need

    def view(self) -> np.ndarray:
        return self.a[: self.n]


# --------------------------------------------------------------------------- the status


@dataclass
class Status:
    """What the monitor knows after an `update()`."""

    t_s: float                      # session time of the latest sample (the stream's own t, as saved)
    gyro_samples: int
    mag_samples: int
    rank: int
    noise_floor: float              # the largest eigenvalue of the noise matrix N
    eigenvalues: np.ndarray         # normalised (largest 1), ascending
    signal_to_noise: np.ndarray     # per eigen-direction, weakest first (rank: those above FLOOR_FACTOR)
    condition: float
    coverage: float                 # fraction of the SPHERE cells the field direction visited
    cells_visited: int
    field_source: str               # "ellipsoid fit" | "raw readings (no fit yet)"
    instruction: str
    detail: str
    targets: dict
    prediction: Prediction | None   # the latest finished prediction
    predicting: bool                # a prediction is being computed
    enough: bool                    # the latest prediction meets every target
    enough_at_s: float | None       # session time of the data end of the first prediction that met them
    still_s: float = 0.0            # how long the gyro has been still at the end of the data (s; 0 before ENOUGH)

    @property
    def predicted(self) -> dict | None:
        """{group: largest predicted one-sigma} or None."""
        if self.prediction is None or self.prediction.std is None:
            return None
        return {g: float(np.max(v)) for g, v in self.prediction.std.items()}

    def to_json_dict(self) -> dict:
        p = self.prediction
        return {
            "t_s": round(self.t_s, 6), "rank": self.rank,
            "noise_floor": self.noise_floor if math.isfinite(self.noise_floor) else None,
            "coverage": round(self.coverage, 6), "cells_visited": self.cells_visited,
            "gyro_samples": self.gyro_samples, "mag_samples": self.mag_samples,
            "field": self.field_source,
            "predicted_std": None if self.predicted is None else {
                g: (v if math.isfinite(v) else None) for g, v in self.predicted.items()},
            "predicted_at_s": None if p is None else round(p.t_s, 6),
            "verdict": None if p is None else p.verdict, "targets": self.targets,
            "enough": self.enough, "enough_at_s": self.enough_at_s, "still_s": round(self.still_s, 6),
            "instruction": self.instruction,
        }


def enough_instruction(still_s: float) -> str:
    """ENOUGH's instruction: rest the device first (`END_REST_S`), then stop."""
    if still_s >= END_REST_S:
        return f"ENOUGH, and still for {still_s:.1f} s: stop the recording now (Ctrl-C)"
    return (f"ENOUGH: the motion meets every target; put the device down and leave it still for {END_REST_S:g} s, "
            "then stop the recording (Ctrl-C)")


# --------------------------------------------------------------------------- the monitor


class ExcitationMonitor:
    """Feed samples with `add(gyro_rows, mag_rows)` (rows (t, x, y, z), gyro in rad/s), call `update()`.

    `predictor`: a `Predictor` (None: no prediction, rank and coverage only).
    """

    def __init__(self, targets=None, predictor: "Predictor | None" = None, mag_unit: str = "unknown",
                 source: str = "watch", options=None):
        from magyro.observability.report import SPHERE_BANDS, SPHERE_SECTORS
        from magyro.targets import Targets

        self.targets = targets or Targets()
        self.predictor = predictor
        self.options = options
        self.mag_unit = mag_unit
        self.source = source
        self.gyro = _Rows()
        self.mag = _Rows()
        self.G = np.zeros((16, 16))            # integral of z z^T dt, z = ytilde (x) q
        self._done = 0                         # gyro samples integrated (or left out before the first reading)
        self._prev_t: float | None = None
        self._prev_z: np.ndarray | None = None
        self._typical_dt: float | None = None
        self._A = None                         # (3, 4): m = A [y_m; 1]
        self.fit: ellipsoid.EllipsoidFit | None = None
        self._next_fit_t = -math.inf
        self.gyro_std = 0.0                    # per-sample, rad/s
        self.mag_std = 0.0                     # per-sample, magnetometer unit
        self._cells = np.zeros(SPHERE_BANDS * SPHERE_SECTORS, dtype=bool)
        self._cells_done = 0
        self.prediction: Prediction | None = None
        self.enough_at_s: float | None = None
        self.status: Status | None = None

    # ------------------------------------------------------------------ input
    def add(self, gyro_rows=(), mag_rows=()) -> None:
        if len(gyro_rows):
            self.gyro.extend(gyro_rows)
        if len(mag_rows):
            self.mag.extend(mag_rows)

    @property
    def t_last(self) -> float | None:
        lasts = [r.a[r.n - 1, 0] for r in (self.gyro, self.mag) if r.n]
        return max(lasts) if lasts else None

    def session(self) -> Session | None:
        """The data so far as a session (None until both sensors have a sample)."""
        if not (self.gyro.n and self.mag.n):
            return None
        g, m = self.gyro.view().copy(), self.mag.view().copy()
        return Session(t_gyro_s=g[:, 0], gyro_rad_s=g[:, 1:], t_mag_s=m[:, 0], mag=m[:, 1:], mag_unit=self.mag_unit,
                       source=self.source, metadata={"gyro_unit": "rad/s", "mag_unit": self.mag_unit,
                                                     "recorded_by": "magyro watch"})

    # ------------------------------------------------------------------ the fast part
    def update(self) -> Status:
        """Take in the samples added since the last update; the status (prediction refreshed when due)."""
        t_now = self.t_last
        if t_now is not None and (t_now >= self._next_fit_t or not self.noise_known):
            self._refresh_noise_and_fit()
            early = min(self.gyro.n, self.mag.n) < NOISE_WINDOW      # the noise levels settle: refresh them sooner
            self._next_fit_t = t_now + (EARLY_REFRESH_S if early else FIT_EVERY_S)
        self._integrate()
        self._mark_cells()
        status = self._status()
        if self.predictor is not None:
            self._predict(status)
            status = self._status()
        self.status = status
        return status

    def _integrate(self) -> None:
        n_mag = self.mag.n
        if n_mag == 0 or self._done >= self.gyro.n:
            return
        tm_all = self.mag.a[:n_mag, 0]
        g = self.gyro.a[self._done: self.gyro.n]
        stop = int(np.searchsorted(g[:, 0], tm_all[-1], side="right"))   # wait for the reading after them
        block = g[:stop]
        block = block[block[:, 0] >= tm_all[0]]                             # before the first reading: left out
        self._done += stop
        if not len(block):
            return
        t = block[:, 0]
        lo = max(0, int(np.searchsorted(tm_all, t[0])) - 1)
        tm, ym = tm_all[lo:], self.mag.a[lo:n_mag, 1:]
        q = np.column_stack([np.interp(t, tm, ym[:, j]) for j in range(3)] + [np.ones(len(t))])
        ytil = np.column_stack([block[:, 1:], np.ones(len(t))])
        z = (ytil[:, :, None] * q[:, None, :]).reshape(len(t), 16)
        if self._prev_t is not None:
            t = np.concatenate([[self._prev_t], t])
            z = np.vstack([self._prev_z, z])
        self._prev_t, self._prev_z = float(t[-1]), z[-1].copy()
        if len(t) < 2:
            return
        dt = np.diff(t)
        self._update_typical_dt()
        if self._typical_dt is not None:
            dt = np.where(dt > HOLE_FACTOR * self._typical_dt, 0.0, dt)
        w = 0.5 * dt
        self.G += (z[:-1] * w[:, None]).T @ z[:-1] + (z[1:] * w[:, None]).T @ z[1:]

    def _update_typical_dt(self) -> None:
        n = min(self._done, self.gyro.n)
        if n >= 3:
            t = self.gyro.a[max(0, n - DT_WINDOW): n, 0]
            self._typical_dt = float(np.median(np.diff(t)))

    def _refresh_noise_and_fit(self) -> None:
        if self.gyro.n >= MIN_NOISE_SAMPLES:
            g = self.gyro.a[max(0, self.gyro.n - NOISE_WINDOW): self.gyro.n, 1:]
            self.gyro_std = float(np.sqrt(np.mean(white_noise_std(g) ** 2)))
        if self.mag.n >= MIN_NOISE_SAMPLES:
            m = self.mag.a[max(0, self.mag.n - NOISE_WINDOW): self.mag.n, 1:]
            self.mag_std = float(np.sqrt(np.mean(white_noise_std(m) ** 2)))
        if self.mag.n >= MIN_FIT_SAMPLES:
            try:
                fit = ellipsoid.fit_ellipsoid(self.mag.view()[:, 1:], self.mag_std)
            except (ellipsoid.DegenerateCloud, InputError, np.linalg.LinAlgError):
                fit = None
            if fit is not None and np.all(np.isfinite(fit.R)) and np.all(np.isfinite(fit.h)):
                self.fit = fit
                self._set_map(np.column_stack([fit.R, -fit.R @ fit.h]))
                return
        if self.fit is None and self.mag.n:
            rho = float(np.mean(np.linalg.norm(self.mag.view()[:, 1:], axis=1)))
            if rho > 0:
                self._set_map(np.column_stack([np.eye(3) / rho, np.zeros(3)]))

    def _set_map(self, A: np.ndarray) -> None:
        self._A = A
        self._cells[:] = False       # the field directions moved: count the cells again
        self._cells_done = 0

    @property
    def mag_std_unit_field(self) -> float:
        if self.fit is not None:
            return self.mag_std * float(np.mean(np.diag(self.fit.R)))
        rho = 1.0 / self._A[0, 0] if self._A is not None and self._A[0, 0] > 0 else 1.0
        return self.mag_std / rho

    def _mark_cells(self) -> None:
        from magyro.observability.report import sphere_cell

        if self._A is None or self._cells_done >= self.mag.n:
            return
        y = self.mag.a[self._cells_done: self.mag.n, 1:]
        m = y @ self._A[:, :3].T + self._A[:, 3]
        ok = np.linalg.norm(m, axis=1) > 0
        self._cells[np.unique(sphere_cell(m[ok]))] = True
        self._cells_done = self.mag.n

    def matrices(self) -> tuple[np.ndarray, np.ndarray]:
        """(integral of M^T M, noise matrix N), both 12 x 12, for the data integrated so far."""
        A = self._A if self._A is not None else np.column_stack([np.eye(3), np.zeros(3)])
        G4 = self.G.reshape(4, 4, 4, 4)                      # [a, c, b, d]: ytilde_a q_c ytilde_b q_d
        norm2 = np.einsum("acbd,cd->ab", G4, A.T @ A)          # integral ytilde_a ytilde_b |m|^2
        mm = np.einsum("acbd,ic,jd->aibj", G4, A, A)          # integral ytilde_a ytilde_b m_i m_j
        info = (np.einsum("ab,ij->aibj", norm2, np.eye(3)) - mm).reshape(12, 12)
        Y = G4[:, 3, :, 3]                                    # integral ytilde ytilde^T
        P = Y[3, 3] * np.eye(3) - A @ G4[3, :, 3, :] @ A.T    # integral (I - m m^T)
        # |m| is 1 only up to the noise (and the fit): along the field, P can come out slightly negative where
        # the gate's unit directions make it 0; clipped, so that no direction reads as noise-free
        lam_p, V_p = np.linalg.eigh(0.5 * (P + P.T))
        P = (V_p * np.maximum(lam_p, 0.0)) @ V_p.T
        sm = self.mag_std_unit_field
        N = (np.kron(np.diag([1.0, 1.0, 1.0, 0.0]), self.gyro_std ** 2 * P)
             + np.kron(2.0 * sm ** 2 * Y, np.eye(3)))
        return 0.5 * (info + info.T), 0.5 * (N + N.T)

    @property
    def noise_known(self) -> bool:
        return self.gyro_std > 0 and self.mag_std > 0

    def _status(self) -> Status:
        info, N = self.matrices()
        lam, V = np.linalg.eigh(info)
        if lam[-1] > 0 and self.noise_known:
            rank, snr = directional_rank(lam, V, N)
        else:
            rank, snr = 0, np.zeros(12)
        floor = float(np.linalg.eigvalsh(N)[-1])
        order = np.argsort(snr, kind="stable")
        lam, V, snr = lam[order], V[:, order], snr[order]
        top = float(np.max(lam)) if lam.size and np.max(lam) > 0 else 1.0
        lam_sorted = np.sort(lam)
        condition = float(lam_sorted[-1] / lam_sorted[0]) if lam_sorted[0] > NUMERICAL_RTOL * top else math.inf
        t_last = self.t_last
        t_s = 0.0 if t_last is None else float(t_last)
        instruction, detail = self._instruction(rank, V, snr)
        p = self.prediction
        enough = bool(rank == 12 and p is not None and meets(p, self.targets))
        still_s = self.still_at_end_s() if enough else 0.0
        return Status(
            t_s=t_s, gyro_samples=self.gyro.n, mag_samples=self.mag.n, rank=int(rank), noise_floor=floor,
            eigenvalues=lam_sorted / top, signal_to_noise=snr, condition=condition,
            coverage=float(self._cells.mean()), cells_visited=int(self._cells.sum()),
            field_source="ellipsoid fit" if self.fit is not None else "raw readings (no fit yet)",
            instruction=enough_instruction(still_s) if enough else instruction,
            detail=detail, targets=targets_dict(self.targets), prediction=p,
            predicting=bool(self.predictor is not None and self.predictor.busy), enough=enough,
            enough_at_s=self.enough_at_s, still_s=still_s)

    def still_at_end_s(self) -> float:
        """How long the gyro has been still at the end of the data (the rests' own rule, `front.rests`)."""
        g = self.gyro.view()
        recent = g[np.searchsorted(g[:, 0], g[-1, 0] - 2 * END_REST_S - WINDOW_S):]   # times increase (_Rows)
        if len(recent) < 5 or self.gyro_std <= 0:
            return 0.0
        t_back_s = recent[-1, 0] - recent[::-1, 0]
        return still_prefix_s(t_back_s, recent[::-1, 1:], np.full(3, self.gyro_std))

    def _instruction(self, rank: int, V: np.ndarray, snr: np.ndarray) -> tuple[str, str]:
        """The motion to make next, in one short line, and the longer advice (`advice.direction_advice`)."""
        if not self.noise_known:
            return "waiting for gyro and magnetometer samples (the noise levels first)", ""
        if rank < 12:
            weak = V[:, : 12 - rank]
            share = np.sum(weak ** 2, axis=1)
            axis_share = np.array([share[3 * j: 3 * j + 3].mean() for j in range(3)])
            # the first axis (x, y, z) nearly as weak as the weakest: one turn at a time, in a fixed order
            j = int(np.flatnonzero(axis_share >= 0.9 * np.max(axis_share))[0])
            if axis_share[j] >= 0.2:
                return (f"turn about the device's {AXES[j]} axis, +/-{TURN_DEG} deg",
                        direction_advice(V[:, 0]))
            return ("turn back and forth at varied rates (start and stop)", direction_advice(V[:, 0]))
        p = self.prediction
        if p is None or p.std is None:
            why = "predicting the accuracy" if self.predictor is not None else "all 12 parameters excited"
            return f"keep turning about all three axes ({why})", direction_advice(V[:, 0])
        worst, axis = None, 0
        targets = targets_dict(self.targets)
        for g in GROUPS:
            values = np.asarray(p.std[g], dtype=float)
            ratio = float(np.max(values)) / targets[g] if targets[g] > 0 else math.inf
            if worst is None or ratio > worst[0]:
                worst, axis = (ratio, g), int(np.argmax(values))
        group = worst[1]
        if group == "scale_ppm":
            text = f"turn more, and faster, about the device's {AXES[axis]} axis, +/-{TURN_DEG} deg"
        elif group == "nonorth_deg":
            text = f"turn more about the device's {AXES[(1, 2, 2)[axis]]} axis, +/-{TURN_DEG} deg"
        elif group == "bias_deg_s":
            text = "keep recording, turning about every axis in both directions"
        else:
            text = f"turn through large angles about all three axes, +/-{TURN_DEG} deg"
        return text, direction_advice(V[:, 0]) if snr[0] < 10 * FLOOR_FACTOR else ""

    # ------------------------------------------------------------------ the slow part
    def _predict(self, status: Status) -> None:
        done = self.predictor.poll()
        if done is not None:
            self.prediction = done
            if self.enough_at_s is None and status.rank == 12 and meets(done, self.targets):
                self.enough_at_s = done.t_s
        if status.rank == 12 and self.predictor.due(status.t_s):
            session = self.session()
            if session is not None:
                self.predictor.submit(session, status.t_s)
                done = self.predictor.poll()        # inline: already there
                if done is not None:
                    self.prediction = done
                    if self.enough_at_s is None and meets(done, self.targets):
                        self.enough_at_s = done.t_s

    def close(self) -> None:
        if self.predictor is not None:
            self.predictor.close()
