"""Host-arrival stamps of a serial logger, for variants of real bursty recordings (issue 38 item 2).

A board (an MPU6050 read by a microcontroller) samples on its own clock and sends what its FIFO holds
`burst_samples` at a time over a serial link; the host stamps each line when it reads it. So the stamps are:

- bursts: the lines of one send arrive `line_spacing_s` apart, a random latency after the burst's last
  sample was taken, then nothing until the next send (the waits);
- a queue: the link never delivers two lines closer than `line_spacing_s`, so a late burst pushes the next;
- stalls: the host stops reading for a while (`stalls`, and `stale_wait_s` right after the stale first burst:
  a port opened, a board reset); nothing is lost, the samples of the stall arrive in one long burst after it;
- a stale first burst: `stale_first_samples` samples already waiting when the logger starts arrive at once;
- a drifting board clock (`board_times`): the k-th sample is taken at t0 + k P (1 + ppm) + a slow wander, in
  the host's (the session's) time;
- lost lines (`lost_lines`, `serial_logged`): a share of the lines garbled on the link and dropped by the
  logger, one here and one there, with no long wait to show it: the row index is no longer the sample counter.

    t_arrival_s = arrival_stamps(t_true_s, SerialLogger(stale_first_samples=12), seed=1)
    session, t_true_s = serial_logged(session, SerialLogger(), seed=1, ppm=450.0, wander_s=0.068)

Only the gyro is stamped on arrival here (the magnetometer keeps its clock), as on the recordings it mirrors.
"""
from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from magyro.session import Session

WANDER_SINES = 3   # the board clock's wander: this many random sinusoids over the session


@dataclass(frozen=True)
class SerialLogger:
    """How a serial logger delivers a board's samples (see the module's docstring)."""

    burst_samples: int = 4                  # samples sent at once
    line_spacing_s: float = 0.002           # between the lines of a burst (the link's speed)
    latency_s: tuple = (0.0005, 0.004)      # uniform: from the burst's last sample to its first line's arrival
    stale_first_samples: int = 0            # samples waiting in the buffer when logging starts (0: none)
    stale_wait_s: float = 0.25              # the host's pause after reading them
    stalls: tuple = ()                      # ((at_s, wait_s), ...): the host stops reading at at_s for wait_s


def arrival_stamps(t_true_s: np.ndarray, logger: SerialLogger = SerialLogger(), seed: int = 0) -> np.ndarray:
    """The host's arrival stamps (s, strictly increasing, never before the sample was taken) of samples taken at
    `t_true_s` and delivered the way `logger` says; the latencies are drawn from `seed`."""
    t_true_s = np.asarray(t_true_s, dtype=float)
    n = len(t_true_s)
    rng = np.random.default_rng(seed)
    burst = burst_of_each_sample(n, logger.burst_samples, logger.stale_first_samples)
    last = np.flatnonzero(np.diff(np.append(burst, burst[-1] + 1)))     # each burst's last sample
    sent_s = t_true_s[last] + rng.uniform(*logger.latency_s, len(last))
    first_line = np.searchsorted(burst, np.arange(len(last)))
    line = np.arange(n) - first_line[burst]
    nominal_s = sent_s[burst] + logger.line_spacing_s * line
    stalls = list(logger.stalls)
    if logger.stale_first_samples:
        stalls.append((float(nominal_s[logger.stale_first_samples - 1]) + 1e-9, logger.stale_wait_s))
    for at_s, wait_s in stalls:
        inside = (nominal_s >= at_s) & (nominal_s < at_s + wait_s)
        nominal_s[inside] = at_s + wait_s
    return queued(nominal_s, logger.line_spacing_s)


def burst_of_each_sample(n: int, burst_samples: int, stale_first_samples: int = 0) -> np.ndarray:
    """The send each of n samples goes out in: the stale ones first, together, then `burst_samples` at a time."""
    k = np.arange(n)
    stale = min(stale_first_samples, n)
    rest = (k - stale) // burst_samples + (1 if stale else 0)
    return np.where(k < stale, 0, rest)


def queued(nominal_s: np.ndarray, spacing_s: float) -> np.ndarray:
    """Arrival times of lines due at `nominal_s` on a link that delivers one line per `spacing_s` at most:
    a_i = max(nominal_i, a_(i-1) + spacing)."""
    step = spacing_s * np.arange(len(nominal_s))
    return np.maximum.accumulate(nominal_s - step) + step


def board_times(t_s: np.ndarray, ppm: float = 0.0, wander_s: float = 0.0, seed: int = 0) -> np.ndarray:
    """When a board whose clock runs `ppm` slow and wanders (`wander_s` peak to peak, a sum of WANDER_SINES random
    sinusoids over the span) takes the samples it means to take at `t_s`, in the host's time (never earlier)."""
    t_s = np.asarray(t_s, dtype=float)
    span_s = float(t_s[-1] - t_s[0]) or 1.0
    rng = np.random.default_rng([seed, 38])
    phase = (t_s - t_s[0]) / span_s
    cycles = rng.uniform(0.5, 2.0, WANDER_SINES)
    shift = rng.uniform(0.0, 2 * np.pi, WANDER_SINES)
    wander = np.sum(np.sin(2 * np.pi * cycles * phase[:, None] + shift), axis=1)
    wander = wander - wander.min()
    if wander_s and np.ptp(wander) > 0:
        wander = wander * (wander_s / np.ptp(wander))
    else:
        wander = np.zeros_like(t_s)
    return t_s + (t_s - t_s[0]) * ppm * 1e-6 + wander


def serial_logged(session: Session, logger: SerialLogger = SerialLogger(), seed: int = 0, ppm: float = 0.0,
                  wander_s: float = 0.0, lost_lines: float = 0.0) -> tuple[Session, np.ndarray]:
    """(the session with its gyro sampled by a drifting board and stamped on arrival by `logger`, the true times of
    those gyro samples). The gyro is read at `board_times` of its stamps (interpolated; samples past the end are
    left out); a share `lost_lines` of the lines is then dropped at random; the magnetometer and the rest are
    kept as they are."""
    t_taken_s = board_times(session.t_gyro_s, ppm, wander_s, seed)
    inside = t_taken_s <= session.t_gyro_s[-1]
    t_taken_s = t_taken_s[inside]
    gyro = np.column_stack([np.interp(t_taken_s, session.t_gyro_s, session.gyro_rad_s[:, i]) for i in range(3)])
    stamps_s = arrival_stamps(t_taken_s, logger, seed)
    if lost_lines:
        keep = np.random.default_rng([seed, 39]).random(len(stamps_s)) >= lost_lines
        stamps_s, gyro, t_taken_s = stamps_s[keep], gyro[keep], t_taken_s[keep]
    logged = replace(session, t_gyro_s=stamps_s, gyro_rad_s=gyro, t_acc_s=None, acc_m_s2=None,
                     source=f"{session.source} serial-logged (seed {seed})")
    return logged, t_taken_s
