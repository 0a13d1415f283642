"""Degrade a real recording the way real loggers and sensors do (issue 11's corpus), for tests and benchmarks.

Every function takes a `Session` (the shipped BROAD trials: `load("broad-02")`) and returns a
new one; the input and its arrays are never modified. The metadata key `degraded` says what
was done. Each docstring names the real behaviour it imitates.

    clean = load("broad-02")
    bursty = burst_stamps(clean)                 # a serial logger stamping buffered data on arrival
    clipped = clip_gyro(clean, 250.0)            # an MPU6050 at +/-250 deg/s
    window = single_axis_window(clean)           # the trial's own near-single-axis stretch

`CORPUS` lists every defect with the trial it is applied to, for benchmarks/degraded_corpus.py.
"""
from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np

from magyro.io import load_session
from magyro.session import Session

DATA = Path(__file__).resolve().parents[1] / "data"
SHIPPED = ("broad-02", "broad-07", "simulated-phone-module")


def load(name: str) -> Session:
    """A shipped session of data/ by name (broad-02, broad-07, simulated-phone-module)."""
    return load_session(DATA / f"{name}.parquet")


def _marked(session: Session, what: str, **changes) -> Session:
    done = session.metadata.get("degraded")
    return replace(session, metadata={**session.metadata, "degraded": f"{done}; {what}" if done else what}, **changes)


def _restamp(t: np.ndarray | None, old: np.ndarray, new: np.ndarray):
    return None if t is None else new[np.searchsorted(old, t)]


# --------------------------------------------------------------------------- clocks


def burst_stamps(session: Session, period_s: float = 0.25, spread_s: float = 0.003, jitter_s: float = 0.002,
                 seed: int = 0) -> Session:
    """Host arrival stamps of buffered data: a board that sends its FIFO every `period_s` over a serial
    link, and a logger that stamps each sample when it is read. The samples taken during burst j
    all arrive after the burst's end, (j + 1) period + a random latency in [0, jitter_s], stamped
    spread over `spread_s` (a fast link: ~71 BROAD samples within 3 ms). Gyro, magnetometer and
    accelerometer rows share the stamps; the optical truth keeps its own clock."""
    rng = np.random.default_rng(seed)
    t = np.unique(np.concatenate([x for x in (session.t_gyro_s, session.t_mag_s, session.t_acc_s) if x is not None]))
    burst = np.floor((t - t[0]) / period_s).astype(int)
    starts = np.flatnonzero(np.diff(burst, prepend=-1))
    counts = np.diff(np.append(starts, len(t)))
    position = np.arange(len(t)) - np.repeat(starts, counts)
    latency = rng.uniform(0.0, jitter_s, burst[-1] + 1)
    arrival = t[0] + (burst + 1) * period_s + latency[burst] + spread_s * (position + 1) / np.repeat(counts, counts)
    assert np.all(np.diff(arrival) > 0) and np.all(arrival >= t)
    return _marked(session, f"burst stamps every {period_s:g} s", t_gyro_s=_restamp(session.t_gyro_s, t, arrival),
                   t_mag_s=_restamp(session.t_mag_s, t, arrival), t_acc_s=_restamp(session.t_acc_s, t, arrival))


def drifting_burst_stamps(session: Session, ppm: float = 450.0, wander_s: float = 0.068, period_s: float = 0.25,
                          seed: int = 0) -> Session:
    """Host-stamped serial bursts (`burst_stamps`) from a board whose clock drifts against the host's (issue 22:
    an MPU6050 + HMC5883L logged over serial, +450 ppm, earliest arrivals wandering by 68 ms): the board's
    oscillator runs `ppm` slow and warms and cools, so that its k-th sample is taken at the true (host) time
    `drifted_times(t_k)`, `wander_s` off any straight line in k. The gyro and magnetometer are read at those
    times (interpolated), then stamped on arrival in bursts. The true sample times are in the metadata key
    `true_times` as 'drifted_times'; `drifted_times(session, t)` computes them."""
    moved = {}
    for t_name, x_name in (("t_gyro_s", "gyro_rad_s"), ("t_mag_s", "mag")):
        t, x = getattr(session, t_name), getattr(session, x_name)
        taken = drifted_times(session, t, ppm, wander_s)
        moved[t_name] = taken
        moved[x_name] = np.column_stack([np.interp(taken, t, x[:, i]) for i in range(3)])
    board = replace(session, t_acc_s=None, acc_m_s2=None, **moved) if session.t_acc_s is not None else \
        replace(session, **moved)
    return _marked(burst_stamps(board, period_s=period_s, seed=seed),
                   f"board clock drifting {ppm:+g} ppm, wandering {wander_s * 1e3:g} ms; host-stamped bursts")


def drifted_times(session: Session, t: np.ndarray, ppm: float = 450.0, wander_s: float = 0.068) -> np.ndarray:
    """The true times at which a board clock drifting by `ppm` and wandering by `wander_s` takes samples that it
    counts as `t` (its own clock)."""
    t0 = float(min(session.t_gyro_s[0], session.t_mag_s[0]))
    span = float(max(session.t_gyro_s[-1], session.t_mag_s[-1]) - t0)
    return t + ppm * 1e-6 * (t - t0) + 0.5 * wander_s * np.sin(2 * np.pi * (t - t0) / span)


def wrong_time_unit(session: Session, factor: float = 1e3) -> Session:
    """Stamps that are not seconds: an Arduino logging millis() (factor 1e3), micros() (1e6), or an
    Android export of SensorEvent.timestamp in nanoseconds (1e9), written to the `t` column as is."""
    scaled = {name: None if getattr(session, name) is None else getattr(session, name) * factor
              for name in ("t_gyro_s", "t_mag_s", "t_acc_s", "t_quat_s")}
    return _marked(session, f"time x {factor:g}", **scaled)


def mag_clock_drift(session: Session, ppm: float) -> Session:
    """The magnetometer stamped from its own clock (or as k / nominal rate) while the gyro is stamped by
    the host: a MEMS magnetometer's internal oscillator is off by 0.1-5 %, so its stamps stretch by
    1 + ppm 1e-6 from its first sample."""
    t = session.t_mag_s
    return _marked(session, f"magnetometer clock {ppm:+g} ppm", t_mag_s=t[0] + (t - t[0]) * (1 + ppm * 1e-6))


def mag_time_offset(session: Session, seconds: float) -> Session:
    """The magnetometer's stamps late by a constant: a driver that stamps a sample when its slow read
    (or its buffer) completes, or a sensor stream logged with a fixed delay."""
    return _marked(session, f"magnetometer stamps {seconds:+g} s", t_mag_s=session.t_mag_s + seconds)


def hole(session: Session, t0_s: float, seconds: float) -> Session:
    """A span with no gyro and no magnetometer (nor accelerometer) samples: a logger that stalled (an SD
    card write, a Bluetooth drop-out) while the device kept moving. The optical truth is kept."""
    def cut(t, x):
        if t is None:
            return None, None
        keep = (t < t0_s) | (t > t0_s + seconds)
        return t[keep].copy(), x[keep].copy()

    t_g, g = cut(session.t_gyro_s, session.gyro_rad_s)
    t_m, m = cut(session.t_mag_s, session.mag)
    t_a, a = cut(session.t_acc_s, session.acc_m_s2)
    return _marked(session, f"{seconds:g} s hole at {t0_s:g} s", t_gyro_s=t_g, gyro_rad_s=g, t_mag_s=t_m, mag=m,
                   t_acc_s=t_a, acc_m_s2=a)


# --------------------------------------------------------------------------- values


def clip_gyro(session: Session, limit_deg_s: float) -> Session:
    """A gyro at a small full scale: an MPU6050 at +/-250 deg/s clips every axis at the range, a
    plateau of identical samples while the true rate is beyond it."""
    limit = np.radians(limit_deg_s)
    return _marked(session, f"gyro clipped at +/-{limit_deg_s:g} deg/s",
                   gyro_rad_s=np.clip(session.gyro_rad_s, -limit, limit))


def mag_spikes(session: Session, n: int = 20, size: float | None = None, seed: int = 0) -> Session:
    """Isolated wrong magnetometer samples: a torn I2C read (high byte of the new sample with the low
    byte of the old), a bit flip, or a read during the sensor's update. `n` spikes, one per equal
    stretch of the recording, each on one random axis with a random sign, of `size` in the
    magnetometer's unit (default: the field strength, i.e. the median |mag|)."""
    rng = np.random.default_rng(seed)
    mag = session.mag.copy()
    size = float(np.median(np.linalg.norm(mag, axis=1))) if size is None else float(size)
    edges = np.linspace(3, len(mag) - 3, n + 1).astype(int)
    rows = np.array([rng.integers(a + 2, b - 2) for a, b in zip(edges[:-1], edges[1:])])
    mag[rows, rng.integers(0, 3, n)] += size * rng.choice([-1.0, 1.0], n)
    return _marked(session, f"{n} magnetometer spikes of {size:.3g} {session.mag_unit}", mag=mag)


def clip_mag(session: Session, share: float = 0.1, axis: int = 0) -> Session:
    """A magnetometer at the end of its range: one axis pinned at the value `share` of its samples exceed (an
    x-IMU at 16 G in a strong field, mx pinned in 46 % of the samples)."""
    mag = session.mag.copy()
    limit = float(np.quantile(mag[:, axis], 1.0 - share))
    mag[:, axis] = np.minimum(mag[:, axis], limit)
    return _marked(session, f"magnetometer {'xyz'[axis]} pinned in {100 * share:g} % of the samples", mag=mag)


def magnet_pass(session: Session, t0_s: float | None = None, seconds: float = 10.0, gain: float = 0.6) -> Session:
    """A magnet carried past the device: for `seconds` from `t0_s` (default: 60 s in) the field grows by up to
    `gain` of itself (about the ellipsoid's centre), rising and falling quickly at the ends."""
    from magyro.front.ellipsoid import fit_ellipsoid

    t0_s = float(session.t_mag_s[0] + 60.0) if t0_s is None else t0_s
    mag = session.mag.copy()
    centre = fit_ellipsoid(mag).h
    inside = (session.t_mag_s >= t0_s) & (session.t_mag_s < t0_s + seconds)
    ramp = np.sin(np.pi * (session.t_mag_s[inside] - t0_s) / seconds) ** 0.2
    mag[inside] = centre + (mag[inside] - centre) * (1 + gain * ramp[:, None])
    return _marked(session, f"a magnet passing for {seconds:g} s (field +{100 * gain:.0f} %)", mag=mag)


def held_mag(session: Session, mag_rate_hz: float = 65.0, log_rate_hz: float | None = None) -> Session:
    """A slow magnetometer logged on a faster clock by sample-and-hold: a ~65 Hz magnetometer (e.g. an
    AK8963 in its 100 Hz mode, an HMC5883L at 75 Hz) read on every tick of a 256 Hz log, each row
    repeating the last value. The sensor's samples are the trial's own (its distinct rows, the
    latest one at each `mag_rate_hz` tick); the rows are on the gyro's clock (`log_rate_hz` None)
    or on a clock of their own."""
    t, m = session.t_mag_s, session.mag
    new = np.concatenate([[True], np.any(m[1:] != m[:-1], axis=1)])
    t, m = t[new], m[new]
    ticks = np.arange(t[0], t[-1], 1.0 / mag_rate_hz)
    values = m[np.searchsorted(t, ticks, side="right") - 1]
    rows = session.t_gyro_s if log_rate_hz is None else np.arange(t[0], t[-1], 1.0 / log_rate_hz)
    rows = rows[rows >= ticks[0]]
    held = values[np.searchsorted(ticks, rows, side="right") - 1]
    return _marked(session, f"magnetometer at {mag_rate_hz:g} Hz held on a "
                   f"{'gyro' if log_rate_hz is None else f'{log_rate_hz:g} Hz'} log clock",
                   t_mag_s=rows.copy(), mag=held)


def gyro_in_deg_s_labelled_rad_s(session: Session) -> Session:
    """deg/s numbers read as rad/s: most MEMS drivers (MPU6050, LSM6DS*, BMI160) report deg/s, and the
    user did not pass --gyro-unit deg/s."""
    return _marked(session, "gyro deg/s labelled rad/s", gyro_rad_s=np.degrees(session.gyro_rad_s))


def gyro_in_rad_s_labelled_deg_s(session: Session) -> Session:
    """rad/s numbers read as deg/s: an Android or Sensor Logger export (rad/s) imported with
    --gyro-unit deg/s, so the loader divides by 57.3."""
    return _marked(session, "gyro rad/s labelled deg/s", gyro_rad_s=np.radians(session.gyro_rad_s))


# --------------------------------------------------------------------------- windows of too little motion


def _dcm(q: np.ndarray) -> np.ndarray:
    w, x, y, z = (q / np.linalg.norm(q, axis=1)[:, None]).T
    return np.stack([np.stack([1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)], -1),
                     np.stack([2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)], -1),
                     np.stack([2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)], -1)], -2)


def _windows(session: Session, seconds: float, step_s: float):
    """(t0, truth quaternions, gyro) of every window of `seconds`, truth at ~100 Hz."""
    t_q, q = session.t_quat_s, session.quat_wxyz
    every = max(1, int(round((len(t_q) - 1) / (t_q[-1] - t_q[0]) / 100)))
    t_q, q = t_q[::every], q[::every]
    for t0 in np.arange(t_q[0], t_q[-1] - seconds, step_s):
        sel = (t_q >= t0) & (t_q <= t0 + seconds) & np.all(np.isfinite(q), axis=1)
        g = (session.t_gyro_s >= t0) & (session.t_gyro_s <= t0 + seconds)
        yield float(t0), q[sel], session.gyro_rad_s[g]


def max_deviation_deg(q: np.ndarray) -> float:
    """Largest angle between an attitude of `q` (wxyz) and their mean attitude."""
    mean = np.linalg.eigh(q.T @ q)[1][:, -1]
    return float(np.degrees(2 * np.arccos(np.clip(np.min(np.abs(q @ mean)), 0.0, 1.0))))


def off_axis_and_turn_deg(q: np.ndarray, gyro: np.ndarray) -> tuple[float, float]:
    """(largest tilt of the main rotation axis, range of the angle turned about it), deg: the axis is the
    gyro's principal direction; its tilt is measured on the truth, relative to the first attitude."""
    axis = np.linalg.eigh(gyro.T @ gyro)[1][:, -1]
    C = _dcm(q)
    moved = np.einsum("ji,njk,k->ni", C[0], C, axis)        # C0^T C(t) axis
    tilt = np.degrees(np.arccos(np.clip(moved @ axis, -1, 1)))
    turned = np.degrees(np.cumsum(gyro @ axis)) / len(gyro)
    return float(tilt.max()), float(np.ptp(turned) * len(gyro))


def shaking_window(session: Session, max_deg: float = 22.0, seconds: float = 6.0, step_s: float = 0.5) -> Session:
    """The trial cut to a window where the device only shakes: every attitude within `max_deg` of the
    window's mean (optical truth), the one with the most gyro motion. Imitates a flight-controller or
    hand-held log that never turns the device over (issue 11: +/-20 deg gave a wrong 'not a
    magnetometer'). On broad-07 that is the fast shaking about x at 88-94 s (within 22 deg, 190 deg/s
    RMS; no 6 s window of the shipped trials stays within 20 deg)."""
    best = max(((float(np.sqrt(np.mean(g ** 2))), t0) for t0, q, g in _windows(session, seconds, step_s)
                if len(q) > 10 and max_deviation_deg(q) <= max_deg), default=None)
    if best is None:
        raise ValueError(f"no {seconds:g} s window of {session.source} stays within {max_deg:g} deg")
    t0 = best[1]
    return _marked(session.within(t0, t0 + seconds), f"shaking within {max_deg:g} deg, {t0:.1f}-{t0 + seconds:.1f} s")


def single_axis_window(session: Session, max_off_axis_deg: float = 7.0, seconds: float = 15.0,
                       step_s: float = 0.5, min_turn_deg: float = 90.0) -> Session:
    """The trial cut to a window of nearly single-axis rotation: the main rotation axis tilts by at most
    `max_off_axis_deg` (optical truth) while the device turns at least `min_turn_deg` about it; the
    one that turns most. Imitates a user who turns the device about one axis only (issue 11: +/-7
    and +/-4.5 deg about the others passed the gate, then the NLS failed and the EKF exited 0 wrong).
    On broad-02 that is the rotation about x from the start, 37-52 s, rest included."""
    best = None
    for t0, q, g in _windows(session, seconds, step_s):
        if len(q) > 10:
            tilt, turned = off_axis_and_turn_deg(q, g)
            if tilt <= max_off_axis_deg and turned >= min_turn_deg and (best is None or turned > best[0]):
                best = (turned, t0)
    if best is None:
        raise ValueError(f"no {seconds:g} s window of {session.source} turns about one axis within "
                         f"{max_off_axis_deg:g} deg")
    t0 = best[1]
    return _marked(session.within(t0, t0 + seconds),
                   f"single axis within {max_off_axis_deg:g} deg, {t0:.1f}-{t0 + seconds:.1f} s")


# --------------------------------------------------------------------------- the corpus

CORPUS = (
    # (name, trial, degrade, the target: exit 0 within 2000 ppm / 0.05 deg/s / 0.1 deg of the clean
    # trial, or the exit code of the right refusal; None: no target, reported only)
    ("burst stamps (0.25 s)", "broad-02", burst_stamps, 0),
    ("gyro clipped at 250 deg/s", "broad-02", lambda s: clip_gyro(s, 250.0), 0),
    ("gyro clipped at 1000 deg/s", "broad-07", lambda s: clip_gyro(s, 1000.0), 0),
    ("30 s hole", "broad-02", lambda s: hole(s, 80.0, 30.0), 0),
    ("20 magnetometer spikes", "broad-02", mag_spikes, 0),
    ("magnetometer 65 Hz held", "broad-02", held_mag, 0),
    ("time in ms", "broad-02", wrong_time_unit, 2),
    ("time in ns", "broad-02", lambda s: wrong_time_unit(s, 1e9), 2),
    ("deg/s labelled rad/s", "broad-02", gyro_in_deg_s_labelled_rad_s, 2),
    ("rad/s labelled deg/s", "broad-02", gyro_in_rad_s_labelled_deg_s, 2),
    ("magnetometer clock +2000 ppm", "broad-07", lambda s: mag_clock_drift(s, 2000.0), None),
    ("magnetometer clock +2 %", "broad-07", lambda s: mag_clock_drift(s, 20000.0), None),
    ("magnetometer 0.3 s late", "broad-07", lambda s: mag_time_offset(s, 0.3), None),
    ("shaking within 22 deg", "broad-07", shaking_window, 3),
    ("single axis within 7 deg", "broad-02", single_axis_window, 3),
)
