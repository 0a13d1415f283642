"""`ExcitationMonitor`: the excitation of a recording while it is being made.

The fast part, on every `update()` (several times a second), costs O(1) per new sample:

- **the integral of M^T M (paper eq. 11)** is not recomputed from the start. With
  ytilde = [y_g; 1] and the calibrated field an affine map of the raw magnetometer reading,
  m = R (y_m - h) = A q with q = [y_m; 1] and A = [R, -R h] (3 x 4),

      M^T M = (ytilde ytilde^T) (x) (|m|^2 I - m m^T)

  is a fixed linear function (given A) of the 16 x 16 outer product of z = ytilde (x) q. The
  monitor keeps G = integral of z z^T dt (trapezoid over the gyro times, the magnetometer
  interpolated linearly there, holes left out: exactly `matrix.information_integral`'s rule) and
  projects it with the current A (`integral.RunningIntegral`, `integral.information_and_noise`). So when the ellipsoid fit improves, the whole integral is
  re-projected *exactly* onto the new field directions in O(1), and the sensor-noise matrix N
  of `gate.noise_matrix` comes from the same G (its blocks integral ytilde ytilde^T and
  integral q q^T). The rank is then counted exactly as the gate counts it
  (`gate.directional_rank`: an eigen-direction counts above 10x what noise alone puts in it).
- **what the gate reads**: the integrals start where observe's gate starts, after the rest the recording opens
  with (`integral.leading_rest`: the rest's end less 0.1 s, settled once the device has moved for a second), and
  they read a sensor that repeats its readings without the repeats, as the recording check's repair leaves it
  (`rows.SensorRows`). Otherwise the watch and observe disagreed just where a user looks: on BROAD 02 just after
  its first rest the watch read rank 12 where observe reads 8, and on BROAD 07 (29 % of its magnetometer rows
  repeated) 11-12 where observe reads 8.
- **field directions before the magnetometer is calibrated**: the choice is a running ellipsoid
  fit (`ellipsoid.fit_ellipsoid` on the readings from the gate's start on, refreshed every `FIT_EVERY_S` seconds
  of data once there are `MIN_FIT_SAMPLES` readings; the last good fit is kept when a later cloud
  does not fit). Until the first fit succeeds (a static or one-axis cloud determines no
  ellipsoid), the field directions are observe's surrogate, the raw readings over their mean
  length (`ellipsoid.surrogate_field_directions`, with one common length instead of each
  reading's own, which keeps m affine in the reading and hence the exact re-projection above).
  The noise level in field units is observe's: per-sample std times mean(diag R), or over the
  mean reading length before a fit.
- **noise levels**: the gate's (`front.noise.noise_levels`): the leading rest's spread when it lasts 2 s, else the
  differences' levels (`floor_level`, `third_difference_level`) of the last `NOISE_WINDOW` samples, refreshed
  with the fit.
- **coverage**: the equal-area sphere cells of the field directions (`observability.report.sphere_cell`),
  marked as readings arrive and recounted when the fit changes.
- **the accelerometer** (when the stream carries `ax ay az`): `magyro.live.accelerometer`.

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

import numpy as np

from magyro.errors import InputError
from magyro.front import ellipsoid
from magyro.front.noise import floor_level, third_difference_level
from magyro.front.rests import WINDOW_S, still_prefix_s
from magyro.live.accelerometer import AccelerometerPart
from magyro.live.rows import Rows, SensorRows
from magyro.live.integral import (RunningIntegral, field_reference, gravity_reference, information_and_noise,
                                  leading_rest, rest_noise_levels)
from magyro.observability.advice import direction_advice
from magyro.live.prediction import GROUPS, Prediction, Predictor, meets, targets_dict
from magyro.observability.gate import FLOOR_FACTOR, NUMERICAL_RTOL, directional_rank
from magyro.live.status import END_REST_S, Status, enough_instruction  # noqa: F401  (END_REST_S: watch's)
from magyro.session import Session

FIT_EVERY_S = 2.0           # the ellipsoid and the noise levels are refreshed every this many seconds of data
MIN_FIT_SAMPLES = 200       # magnetometer readings before the first fit is tried
NOISE_WINDOW = 4000         # samples of each sensor the noise levels are estimated from
DT_WINDOW = 4096            # gyro steps whose median sets the hole threshold (the gate: all steps)
MIN_NOISE_SAMPLES = 50      # per sensor, before the noise levels (and so any rank) are given
EARLY_REFRESH_S = 0.5       # refresh interval while fewer than NOISE_WINDOW samples are in
TURN_DEG = 90               # the turn the instruction asks for
AXES = "xyz"


# --------------------------------------------------------------------------- the monitor


class ExcitationMonitor:
    """Feed samples with `add(gyro_rows, mag_rows, acc_rows)` (rows (t, x, y, z), gyro in rad/s, accelerometer
    in m/s^2), call `update()`.

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
        self._gyro_rows = SensorRows()
        self._mag_rows = SensorRows()
        self.acc = Rows()
        self.acc_part = AccelerometerPart()    # its 12 parameters on the data so far (magyro.live.accelerometer)
        self.start_s: float | None = None     # where the integrals start: after the leading rest (`_follow_leading_rest`)
        self._start_fixed = False
        self._rest_span: tuple[float, float] | None = None    # the leading rest so far (`leading_rest`)
        self._rest_noise: tuple[float, float] | None = None   # (gyro, magnetometer) per-sample std from it
        self._restart_integrals(0)
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
    def add(self, gyro_rows=(), mag_rows=(), acc_rows=()) -> None:
        began = self._gyro_rows.extend(gyro_rows) if len(gyro_rows) else False
        began |= self._mag_rows.extend(mag_rows) if len(mag_rows) else False
        if began:
            self._start_again()
        if len(acc_rows):
            self.acc.extend(acc_rows)

    @property
    def gyro(self) -> Rows:
        """The gyro rows as the solve reads them (`rows.SensorRows.kept`)."""
        return self._gyro_rows.kept

    @property
    def mag(self) -> Rows:
        """The magnetometer rows as the solve reads them (`rows.SensorRows.kept`)."""
        return self._mag_rows.kept

    def _start_again(self) -> None:
        """A sensor was found holding its readings, and its rows were made again without the repeats: everything
        read from them is read again at the next update (the leading rest, the noise levels, the fit, the
        integrals, the coverage)."""
        self.start_s, self._start_fixed, self._rest_span, self._rest_noise = None, False, None, None
        self.fit, self._A, self._next_fit_t = None, None, -math.inf
        self._restart_integrals(0)
        self._cells[:] = False
        self._cells_done = 0

    @property
    def t_last(self) -> float | None:
        lasts = [r.a[r.n - 1, 0] for r in (self._gyro_rows.received, self._mag_rows.received, self.acc) if r.n]
        return max(lasts) if lasts else None

    def session(self, kept: bool = False) -> Session | None:
        """The data so far as received (None until both sensors have a sample): what watch saves, and what
        `magyro observe` (the prediction) reads, through its own recording check; `kept`: as the solve reads it
        (`gyro`, `mag`)."""
        gyro, mag = (self.gyro, self.mag) if kept else (self._gyro_rows.received, self._mag_rows.received)
        if not (gyro.n and mag.n):
            return None
        g, m = gyro.view().copy(), mag.view().copy()
        metadata = {"gyro_unit": "rad/s", "mag_unit": self.mag_unit, "recorded_by": "magyro watch"}
        acc = {}
        if self.acc.n:
            a = self.acc.view().copy()
            acc = {"t_acc_s": a[:, 0], "acc_m_s2": a[:, 1:]}
            metadata["acc_unit"] = "m/s^2"
        return Session(t_gyro_s=g[:, 0], gyro_rad_s=g[:, 1:], t_mag_s=m[:, 0], mag=m[:, 1:], mag_unit=self.mag_unit,
                       source=self.source, metadata=metadata, **acc)

    # ------------------------------------------------------------------ the fast part
    def update(self, final: bool = False) -> Status:
        """Take in the samples added since the last update; the status (prediction refreshed when due).
        `final`: the data is complete; the accelerometer's part is computed on it as `magyro observe` does."""
        t_now = self.t_last
        if self.acc.n and self.acc_part.due(t_now, final):
            self.acc_part.refresh(self.acc.view(), self.gyro.view(), final, self.session, NOISE_WINDOW,
                                  EARLY_REFRESH_S, NOISE_WINDOW)
        self._follow_leading_rest()
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

    def _restart_integrals(self, first_gyro: int) -> None:
        """Both integrals empty, to be taken from gyro row `first_gyro` on."""
        self.field_integral = RunningIntegral(first_gyro)      # the field's (`integral.field_reference`)
        self.gravity_integral = RunningIntegral(first_gyro)    # gravity's direction's (`integral.gravity_reference`)

    def _follow_leading_rest(self) -> None:
        """Start the integrals where `magyro observe`'s gate starts: after the rest the recording opens with
        (`integral.leading_rest`), as the solve sees the session. While the device still lies there the start moves with
        the rest's end (nothing is integrated: a rest adds nothing the solve uses); it is fixed once the device has
        moved for MIN_REST_S. Integrated from the start instead, the rest's bias information made the watch read
        rank 12 on BROAD 02's first 3.5 s (3 s of rest, then half a second of turning) where observe reads 8."""
        if self._start_fixed or min(self.gyro.n, self.mag.n) < MIN_NOISE_SAMPLES:
            return
        lead = leading_rest(self.gyro.view(), self.mag.view())
        if lead.start_s != self.start_s:
            self.start_s = lead.start_s
            self._restart_integrals(int(np.searchsorted(self.gyro.a[: self.gyro.n, 0], lead.start_s, side="left")))
        self._start_fixed = lead.settled
        if lead.span_s != self._rest_span:   # the rest grew: its noise levels (and the fit with them) again, now
            self._rest_span = lead.span_s
            self._rest_noise = rest_noise_levels(self.session(kept=True), lead.span_s, self.options)
            self._next_fit_t = -math.inf

    def _integrate(self) -> None:
        if self.mag.n:
            mag = self.mag.view()
            self.field_integral.extend(self.gyro.view(), mag[:, 0], field_reference(mag[:, 0], mag[:, 1:]),
                                       self._update_typical_dt)
        if self.acc.n >= 2:
            acc = self.acc.view()
            self.gravity_integral.extend(self.gyro.view(), acc[:, 0],
                                         gravity_reference(acc[:, 0], acc[:, 1:], self.g_reference_m_s2,
                                                           self.expected_size),
                                         lambda done: self._typical_dt)

    @property
    def g_reference_m_s2(self) -> float:
        """The accelerometer's reading of g: its part's (at the stillest samples so far), else the standard one."""
        from magyro.options import STANDARD_GRAVITY_M_S2

        acc = self.acc_part.gravity
        return float(acc.g_reference_m_s2) if acc is not None else STANDARD_GRAVITY_M_S2

    @property
    def expected_size(self):
        """The size the accelerometer reads still, by direction (`gravity.expected_size`, its part's on the rows so
        far), or None (then g)."""
        acc = self.acc_part.gravity
        return acc.expected_size if acc is not None else None

    def _update_typical_dt(self, done: int) -> float | None:
        """The gyro's step over the last DT_WINDOW rows taken in (`done`): a longer step is a hole."""
        n = min(done, self.gyro.n)
        if n >= 3:
            t = self.gyro.a[max(0, n - DT_WINDOW): n, 0]
            self._typical_dt = float(np.median(np.diff(t)))
        return self._typical_dt

    def _refresh_noise_and_fit(self) -> None:
        # the noise levels by the gate's rules (`front.noise.noise_levels`): the leading rest's spread, else the
        # differences' levels of the latest NOISE_WINDOW samples
        if self._rest_noise is not None:
            self.gyro_std, self.mag_std = self._rest_noise
        elif self.gyro.n >= MIN_NOISE_SAMPLES:
            self.gyro_std = floor_level(self.gyro.a[max(0, self.gyro.n - NOISE_WINDOW): self.gyro.n, 1:])[0]
        if self._rest_noise is None and self.mag.n >= MIN_NOISE_SAMPLES:
            self.mag_std = third_difference_level(self.mag.a[max(0, self.mag.n - NOISE_WINDOW): self.mag.n, 1:])[0]
        if self.mag.n >= MIN_FIT_SAMPLES:
            try:
                fit = ellipsoid.fit_ellipsoid(self._analysed_mag(), self.mag_std)
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

    def _analysed_mag(self) -> np.ndarray:
        """The magnetometer readings the gate's ellipsoid is fitted to: from `start_s` on (all before it is known)."""
        rows = self.mag.view()
        if self.start_s is None:
            return rows[:, 1:]
        return rows[np.searchsorted(rows[:, 0], self.start_s, side="left"):, 1:]

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
        return information_and_noise(self.field_integral.G, A, self.gyro_std, self.mag_std_unit_field)

    def gravity_matrices(self) -> tuple[np.ndarray, np.ndarray] | None:
        """(integral of M^T M, N) with gravity's direction as the reference, or None before the accelerometer's
        part: its direction's noise is the white noise and the hand's (`gravity.observe_accelerometer`'s)."""
        acc = self.acc_part.gravity
        if acc is None or not np.any(self.gravity_integral.G):
            return None
        sigma_u = math.hypot(acc.white_noise_m_s2, acc.hand_m_s2) / acc.g_reference_m_s2
        return information_and_noise(self.gravity_integral.G, np.column_stack([np.eye(3), np.zeros(3)]), self.gyro_std, sigma_u)

    def rank_with_gravity(self, info: np.ndarray, N: np.ndarray) -> int | None:
        """The gyro's rank with gravity beside the field (`gravity.combined_rank`), or None without it."""
        from magyro.observability.gravity import combined_rank

        gravity = self.gravity_matrices()
        if gravity is None or not self.noise_known:
            return None
        lam, V = np.linalg.eigh(info + gravity[0])
        return combined_rank(lam, V, (info, N), gravity)

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
            enough_at_s=self.enough_at_s, still_s=still_s, accelerometer=self.acc_part.gravity,
            rank_with_gravity=self.rank_with_gravity(info, N),
            acc_samples=self.acc.n)

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
