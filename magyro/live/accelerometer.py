"""The accelerometer's part of `magyro watch`: what its 12 parameters need, on the data so far (issue 26).

When the stream carries `ax ay az`, `AccelerometerPart` keeps what `magyro observe` says of the accelerometer's 12
parameters, `gravity.accelerometer_parameters` itself (the poses held, the rank, the spread, the advice), on the
accelerometer samples so far. It is recomputed every `ACC_EVERY_S` seconds of data and never sooner than
`ACC_COST_FACTOR` times its last cost. Live it reads every sample up to `ACC_MAX_SAMPLES`, then every n-th sample, at
most `ACC_MAX_SAMPLES` of them (the seconds per pose and the information are integrals over time: they hardly
change; the white noise then comes from the latest `NOISE_WINDOW` consecutive samples, which every n-th would
overstate), so that one recomputation costs the same whatever the recording's length. Live it is given no rests (g
is read where the gyro turns slowest, the white noise from third differences: `reference_g`'s and
`accelerometer_noise`'s own fallbacks); at the watch's end (`final`) it reads every sample with the rests `magyro
observe` finds, so the last status is observe's section.
"""
from __future__ import annotations

import math
import time

import numpy as np

ACC_EVERY_S = 2.0           # recomputed every this many seconds of data (as the monitor refits, FIT_EVERY_S) ...
ACC_COST_FACTOR = 10.0      # ... and at most every this many times its last cost (a tenth of a live stream's time)
ACC_MAX_SAMPLES = 20000     # live, it reads every n-th sample, at most this many (one recomputation: ~10 ms)


class AccelerometerPart:
    """`refresh(acc, gyro, ...)` with the rows (t, x, y, z) so far; `gravity` the latest answer (or None)."""

    def __init__(self, clock=time.perf_counter):
        self.clock = clock
        self.gravity = None                  # gravity.AccelerometerObservability of the accelerometer so far
        self.n = 0                           # accelerometer samples it was computed from
        self.exact = False                   # ... every one, with observe's rests (the watch's end)
        self.next_t = -math.inf              # session time of the next recomputation
        self.seconds: list[float] = []       # the cost of each recomputation (s, wall clock)

    def due(self, t_now, final: bool) -> bool:
        return final or (t_now is not None and t_now >= self.next_t)

    def refresh(self, acc: np.ndarray, gyro: np.ndarray, final: bool, session=None, early_until: int = 0,
                early_s: float = 0.5, noise_window: int = 4000) -> None:
        """Recompute from `acc` and `gyro` (views of the rows so far); `session()` gives the session, for the rests,
        when `final`; while fewer than `early_until` samples are in, every `early_s` of data."""
        from magyro.observability.gravity import accelerometer_parameters, white_noise_m_s2

        if not len(acc) or (self.n == len(acc) and (self.exact or not final)):
            return
        start = self.clock()
        rests_s = []
        if final and session is not None and (s := session()) is not None:
            from magyro.front.rests import find_rests
            rests_s = find_rests(s).segments_s
        a, g, white = acc, gyro, None
        if not final and len(acc) > ACC_MAX_SAMPLES:
            white = white_noise_m_s2(acc[-noise_window:, 1:])      # from consecutive samples, not every n-th
            a, g = acc[:: -(-len(acc) // ACC_MAX_SAMPLES)], gyro[:: max(1, -(-len(gyro) // ACC_MAX_SAMPLES))]
        try:
            self.gravity = accelerometer_parameters(a[:, 0], a[:, 1:], rests_s, g[:, 0] if len(g) else None,
                                                    g[:, 1:] if len(g) else None, white_m_s2=white)
        except (np.linalg.LinAlgError, ValueError, ZeroDivisionError):   # readings it cannot use (all zero, ...):
            self.gravity = None                                           # the watch goes on without its part
        self.n, self.exact = len(acc), final
        cost = self.clock() - start
        self.seconds.append(cost)
        every = early_s if len(acc) < early_until else ACC_EVERY_S
        self.next_t = float(acc[-1, 0]) + max(every, ACC_COST_FACTOR * cost)


def accelerometer_json(acc, samples: int, gyro_rank_with_gravity: int | None = None) -> dict:
    """The accelerometer's part of a status line: poses held (s), rank, spread, the poses missing and observe's
    advice; and what gravity adds to the gyro (`gyro_rank_with_gravity`: the gyro's rank with gravity beside the
    field, as observe's part 2 counts it; null until the accelerometer's part is computed)."""
    from magyro.observability.gravity import FACES, missing_poses

    def num(x):     # the status lines are strict JSON: a value that is not finite is null
        x = float(x)
        return round(x, 6) if math.isfinite(x) else None

    return {"samples": samples, "rank": int(acc.rank), "condition": num(acc.condition), "spread": num(acc.spread),
            "poses_s": {f: num(acc.face_s[f]) for f in FACES}, "missing_poses": missing_poses(acc.face_s),
            "sphere_fraction": num(acc.sphere_fraction), "g_reference_m_s2": num(acc.g_reference_m_s2),
            "advice": list(acc.advice), "gyro_rank_with_gravity": gyro_rank_with_gravity}
