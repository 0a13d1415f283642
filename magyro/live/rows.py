"""The rows `magyro watch` receives, per sensor: kept as they grow, and as the solve would read them.

A logger that writes a sensor faster than it updates repeats its last reading (BROAD's magnetometer: 29 % of its rows
at 286 Hz). The recording check finds such a sensor (at least HELD_MIN_ROWS repeats and HELD_MIN_FRACTION of its
rows) and its repair drops every row that repeats the previous one exactly (`front.repairs`), so `magyro observe`
and the solve read the sensor without them. The watch does the same as the rows arrive (`SensorRows.kept`), and
saves what it received (`SensorRows.received`).
"""
from __future__ import annotations

import numpy as np

from magyro.front.recording import HELD_MIN_FRACTION, HELD_MIN_ROWS
from magyro.front.repairs import held_after


class Rows:
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


class SensorRows:
    """A sensor's rows as received (`received`: what watch saves) and as analysed (`kept`: once the sensor is found
    holding its readings, without the rows that repeat the previous one exactly; the same rows until then)."""

    def __init__(self):
        self.received = Rows()
        self.kept = self.received
        self.held = 0          # received rows that repeat the previous one exactly

    @property
    def holding(self) -> bool:
        """The recording check's rule: at least HELD_MIN_ROWS repeats, and HELD_MIN_FRACTION of the rows."""
        return self.held >= HELD_MIN_ROWS and self.held >= HELD_MIN_FRACTION * self.received.n

    def extend(self, rows) -> bool:
        """Take in rows; True when the sensor is found holding now (`kept` is then made again, without its repeats)."""
        n0, was = self.received.n, self.holding
        self.received.extend(rows)
        n = self.received.n
        if n == n0:
            return False
        values = self.received.a[:n, 1:]
        repeat = np.zeros(n - n0, dtype=bool)            # each new row against the one before it
        first = max(n0, 1)
        repeat[first - n0:] = np.all(values[first:] == values[first - 1: n - 1], axis=1)
        self.held += int(repeat.sum())
        if not self.holding:
            return False
        if not was:
            every = held_after(values, np.ones(n, dtype=bool))   # the repair's own rule (front.repairs)
            self.kept = Rows()
            self.kept.extend(self.received.a[:n][~every])
            return True
        self.kept.extend(self.received.a[n0:n][~repeat])
        return False
