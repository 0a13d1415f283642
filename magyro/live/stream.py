"""A session played back as the CSV lines `magyro watch` reads, in (accelerated) real time.

`magyro simulate PROBLEM --stream` writes the simulated recording this way: one line per sample,
gyro `t,gx,gy,gz,,,` (rad/s) and magnetometer `t,,,,mx,my,mz` on lines of their own, merged in time
order (the gyro first at equal times), each number in Python's shortest repr that reads back to
the same float (so a session saved by `magyro watch` equals the streamed one exactly). A header
line `t,gx,gy,gz,mx,my,mz` comes first. A session with an accelerometer adds its lines, `t,,,,,,,ax,ay,az`
(m/s^2, after the other two at equal times), and the header `t,gx,gy,gz,mx,my,mz,ax,ay,az`; one without is
written exactly as before. Lines are paced by their time stamps: `speed` 1 is real
time, X is X times faster, 0 as fast as the pipe takes them.
"""
from __future__ import annotations

import time

import numpy as np

from magyro.session import Session

HEADER = "t,gx,gy,gz,mx,my,mz\n"
HEADER_ACC = "t,gx,gy,gz,mx,my,mz,ax,ay,az\n"
PACE_EVERY_S = 0.01      # lines are written in groups this long (in session time) before the clock is checked


def session_lines(session: Session):
    """(t, line) of every sample in time order, the gyro before the magnetometer (before the accelerometer) at
    equal times."""
    g = [(float(t), 0, f"{t!r},{x!r},{y!r},{z!r},,,\n")
         for t, (x, y, z) in zip(session.t_gyro_s.tolist(), session.gyro_rad_s.tolist())]
    m = [(float(t), 1, f"{t!r},,,,{x!r},{y!r},{z!r}\n")
         for t, (x, y, z) in zip(session.t_mag_s.tolist(), session.mag.tolist())]
    a = []
    if session.acc_m_s2 is not None and session.t_acc_s is not None:
        a = [(float(t), 2, f"{t!r},,,,,,,{x!r},{y!r},{z!r}\n")
             for t, (x, y, z) in zip(session.t_acc_s.tolist(), session.acc_m_s2.tolist())]
    return [(t, line) for t, _, line in sorted(g + m + a, key=lambda r: (r[0], r[1]))]


def header_line(session: Session) -> str:
    """The header line: `ax,ay,az` named only when the session has an accelerometer."""
    return HEADER_ACC if session.acc_m_s2 is not None and session.t_acc_s is not None else HEADER


def stream_session(session: Session, out, speed: float = 1.0, header: bool = True, clock=time.monotonic,
                   sleep=time.sleep) -> int:
    """Write `session` to the text stream `out` as CSV lines paced at `speed` x real time; the lines written.

    A reader that goes away (BrokenPipeError) ends the stream quietly.
    """
    if speed < 0 or not np.isfinite(speed):
        from magyro.errors import InputError

        raise InputError(f"--speed {speed}: give 0 (as fast as possible) or a positive factor (1 = real time)")
    lines = session_lines(session)
    written = 0
    try:
        if header:
            out.write(header_line(session))
        if not lines:
            out.flush()
            return 0
        t_first = lines[0][0]
        start = clock()
        group: list[str] = []
        group_end = t_first + PACE_EVERY_S
        for t, line in lines:
            if t >= group_end and group:
                out.write("".join(group))
                written += len(group)
                group = []
                group_end = t + PACE_EVERY_S
                if speed > 0:
                    out.flush()
                    wait = (t - t_first) / speed - (clock() - start)
                    if wait > 0:
                        sleep(wait)
            group.append(line)
        out.write("".join(group))
        written += len(group)
        out.flush()
    except BrokenPipeError:
        pass
    return written
