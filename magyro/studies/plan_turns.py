"""The turns of a plan (`magyro plan`), as a person does them by hand: the device's axes, the pace of a turn
at a peak rate (a minimum-jerk profile, peak 1.875 x its mean rate, rounded up to 0.1 s), the moves laid out
in time between rests, the motion as a problem scenario of kind "turns", and the plan written as
instructions (the start pose from the device's magnetometer and up, then one line a turn).
"""
from __future__ import annotations

import dataclasses
import math

import numpy as np

from magyro.studies.scenario import Scenario, Turn

_S2, _S3 = 1.0 / math.sqrt(2.0), 1.0 / math.sqrt(3.0)
AXES = {"x": (1.0, 0.0, 0.0), "y": (0.0, 1.0, 0.0), "z": (0.0, 0.0, 1.0),
        "x+y": (_S2, _S2, 0.0), "y+z": (0.0, _S2, _S2), "z+x": (_S2, 0.0, _S2),
        "x-y": (_S2, -_S2, 0.0), "y-z": (0.0, _S2, -_S2), "z-x": (-_S2, 0.0, _S2),
        "x+y+z": (_S3, _S3, _S3), "x-y+z": (_S3, -_S3, _S3), "x+y-z": (_S3, _S3, -_S3), "-x+y+z": (-_S3, _S3, _S3)}
REST_S = 1.0                   # still at both ends, at least
PACE_STEP_S = 0.1              # turn durations are rounded up to this
PEAK_OVER_MEAN = 1.875         # smoothstep: peak slope 15/8


def turn_seconds(angle_deg: float, max_rate_deg_s: float) -> float:
    """The fastest pace (a multiple of 0.1 s) whose peak rate, 1.875 |angle| / T, is at most max_rate."""
    t = PEAK_OVER_MEAN * abs(angle_deg) / max_rate_deg_s
    return round(max(PACE_STEP_S, math.ceil(t / PACE_STEP_S - 1e-9) * PACE_STEP_S), 6)


def layout(moves, duration_s: float, max_rate_deg_s: float, first_rest_s: float = REST_S) -> tuple[Turn, ...]:
    """Rest `first_rest_s`, the moves (axis name, signed angle, pause before) while they fit with a rest of at least
    REST_S after them, the end rest."""
    steps = [Turn(None, 0.0, first_rest_s)]
    t = first_rest_s
    for k, (axis, angle, pause) in enumerate(moves):
        seconds = turn_seconds(angle, max_rate_deg_s)
        pause = pause if k > 0 else 0.0
        if t + pause + seconds + REST_S > duration_s + 1e-9:
            break
        if pause > 0:
            steps.append(Turn(None, 0.0, pause))
        steps.append(Turn(np.array(AXES[axis]), float(angle), seconds))
        t += pause + seconds
    steps.append(Turn(None, 0.0, round(duration_s - t, 9)))
    return tuple(steps)


def fitting(moves, duration_s: float, max_rate_deg_s: float, first_rest_s: float = REST_S) -> int:
    """How many of the moves the layout holds."""
    return sum(not st.is_rest for st in layout(moves, duration_s, max_rate_deg_s, first_rest_s))


def axis_label(axis: np.ndarray) -> str:
    """"+x", "-y", "+x+y" (a diagonal), or the vector itself."""
    a = np.asarray(axis, float)
    nz = np.abs(a) > 1e-9
    if np.allclose(np.abs(a[nz]), np.abs(a[nz])[0], atol=1e-6):
        return "".join(("+" if a[i] > 0 else "-") + "xyz"[i] for i in range(3) if nz[i])
    return "[" + ", ".join(f"{v:.3f}" for v in a) + "]"


def start_pose_instruction(C0: np.ndarray) -> str:
    """Where to hold the device before the first turn, from C0 = C_b^w (body to ENU): the device axes nearest
    to up and to magnetic north (the field's horizontal part points north), with how far off they are."""
    C0 = np.asarray(C0, float)
    up = int(np.argmax(np.abs(C0[2])))
    rest = [i for i in range(3) if i != up]
    north = rest[int(np.argmax(np.abs(C0[1, rest])))]
    label = lambda i, sign: ("+" if sign > 0 else "-") + "xyz"[i]   # noqa: E731
    up_label, north_label = label(up, C0[2, up]), label(north, C0[1, north])
    off_up = np.degrees(np.arccos(min(1.0, abs(C0[2, up]))))
    off_north = np.degrees(np.arccos(min(1.0, abs(C0[1, north]) / max(np.hypot(C0[0, north], C0[1, north]), 1e-12))))
    text = f"start with the device's {up_label} axis pointing up and its {north_label} axis toward magnetic north"
    if off_up > 1 or off_north > 1:
        text += f" (the plan's pose is {off_up:.0f} deg from up and {off_north:.0f} deg from north there)"
    return text


def instructions(turns: tuple[Turn, ...]) -> list[str]:
    """The turns as instructions to a person, one line per step."""
    lines = []
    for k, st in enumerate(turns, 1):
        if st.is_rest:
            lines.append(f"{k:3d}. hold the device still for {st.seconds:.1f} s")
            continue
        axis, angle = (st.axis, st.angle_deg) if st.angle_deg > 0 else (-st.axis, -st.angle_deg)
        label = axis_label(axis)
        what = "axis" if len(label) == 2 or label.startswith("[") else "diagonal axis"
        lines.append(f"{k:3d}. turn about the device's {label} {what} by {angle:g} deg in {st.seconds:.1f} s")
    return lines


def plan_scenario(base: Scenario, turns: tuple[Turn, ...], duration_s: float, name: str = "plan",
                  description: str = "") -> Scenario:
    """The base sensors with a "turns" motion (checked like a problem file's; the hand's sway, if the base has an
    accelerometer, is the one the written plan reads back with: scenario.TURNS_HAND)."""
    from magyro.studies.scenario import TURNS_HAND, _check_consistency

    motion = dataclasses.replace(base.motion, kind="turns", axes=(), amplitude_deg=np.zeros(0),
                                 rest_start_s=0.0, rest_end_s=0.0, turns=tuple(turns), **TURNS_HAND)
    s = dataclasses.replace(base, name=name, description=description, duration_s=duration_s, motion=motion,
                            source_path="")
    _check_consistency(s, name)
    return s
