"""Cutting a session: in time (`trim`, `cut`) and in rate (`decimate`).

Unlike `Session.within`, these check what they give: at least `MIN_SAMPLES` gyro and
magnetometer samples, and they note the cut in the metadata (`trimmed_to_s`,
`decimated_by`), which a written session file keeps.
"""
from __future__ import annotations

from dataclasses import replace

import numpy as np

from magyro.errors import InputError
from magyro.io.checks import MIN_SAMPLES, session_from_table
from magyro.io.session_file import session_table
from magyro.session import Session


def trim(session: Session, t0_s: float, t1_s: float) -> Session:
    """The session cut to t0_s <= t <= t1_s: every sensor and the truth; times unchanged."""
    t0_s, t1_s = float(t0_s), float(t1_s)
    if not (np.isfinite(t0_s) and np.isfinite(t1_s)) or t1_s <= t0_s:
        raise InputError(f"trim window [{t0_s}, {t1_s}] s is empty; it needs t0 < t1")
    within = session.within(t0_s, t1_s)
    for name, t_x in (("gyro", within.t_gyro_s), ("magnetometer", within.t_mag_s)):
        if len(t_x) < MIN_SAMPLES:
            raise InputError(f"trim window [{t0_s:g}, {t1_s:g}] s keeps {len(t_x)} {name} samples, need at least "
                             f"{MIN_SAMPLES}; the session spans {session.t_gyro_s[0]:g} to "
                             f"{session.t_gyro_s[-1]:g} s")
    return replace(within, metadata={**session.metadata, "trimmed_to_s": f"{t0_s!r} {t1_s!r}"})


def cut(session: Session, start_s: float | None, end_s: float | None) -> Session:
    """`trim` to [start_s, end_s], an open end (None) being the first or last gyro time.

    With both None the session itself is returned, uncut and without `trimmed_to_s`.
    """
    if start_s is None and end_s is None:
        return session
    return trim(session, session.t_gyro_s[0] if start_s is None else start_s,
                session.t_gyro_s[-1] if end_s is None else end_s)


def decimate(session: Session, n: int) -> Session:
    """Every n-th row of the session's table (first row kept), no filtering.

    On a common time base (BROAD) this keeps every n-th sample of every sensor and of the
    truth; samples are original values, not averages. n = 1 returns the session itself.
    """
    n = int(n)
    if n < 1:
        raise InputError(f"decimation factor {n}; it must be a positive integer")
    if n == 1:
        return session
    table = session_table(session).iloc[::n].reset_index(drop=True)
    metadata = {**session.metadata, "decimated_by": str(n)}
    if "sampling_rate_hz" in metadata:
        metadata["sampling_rate_hz"] = repr(float(metadata["sampling_rate_hz"]) / n)
    return session_from_table(table, metadata, session.source, gyro_unit="rad/s", mag_unit=session.mag_unit)
