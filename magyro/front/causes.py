"""What a magnetometer cloud that fits no ellipsoid means, named in one order of causes (issue 22).

The readings are judged against the gyro, which does not need the magnetometer to say how the
device turned:

1. the device barely turned (at most SMALL_TURN_DEG from its first attitude): too little motion (exit 3);
2. it turned about one axis only (that axis never tilted more than SINGLE_AXIS_TILT_DEG): the field
   sweeps one circle, which fits no ellipsoid, whatever shape the fit takes (exit 3, naming the axis);
3. it turned far about every axis, yet the readings stay within their noise or in one plane: the
   magnetometer does not follow the turning (a dead axis, constant values, not a magnetometer; exit 2);
4. it turned about every axis and the cloud is no ellipsoid (a hyperboloid): the field is not the same
   everywhere along the path (iron or a magnet moved, or the device moved near iron; exit 2);
5. otherwise the field directions cover too little of the sphere (exit 3).

Units, clocks and sensor faults (saturation, a normalised or a constant magnetometer) are the
recording check's, before any of this (magyro.front.recording).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from magyro import so3
from magyro.errors import InputError, MagyroError, ObservabilityError
from magyro.session import Session, hole_steps

SPAN_RATE_HZ = 50.0            # the attitude is integrated at about this rate (degrees matter here, not less)
SMALL_TURN_DEG = 60.0          # a degenerate cloud within this turn is too little motion, whatever its shape
SINGLE_AXIS_TILT_DEG = 15.0    # the main turning axis never tilted more than this: one axis only
EVERY_AXIS_TURN_DEG = 180.0    # turned at least this much about each principal axis: "every axis" ...
FAR_SPAN_DEG = 90.0            # ... and this far from the first attitude


@dataclass(frozen=True)
class Turning:
    """How the gyro (less a rest bias when known) says the device turned."""

    span_deg: float                # the farthest it got from its first attitude
    turn_deg: tuple                # integral of |w . e_i| dt about the principal axes e_i, smallest first
    main_axis: np.ndarray          # body-frame unit vector of the axis it turned about most
    main_axis_tilt_deg: float      # how far that axis itself ever tilted from its first direction

    @property
    def single_axis(self) -> bool:
        return self.main_axis_tilt_deg < SINGLE_AXIS_TILT_DEG and self.span_deg >= SMALL_TURN_DEG

    @property
    def every_axis(self) -> bool:
        return (min(self.turn_deg) >= EVERY_AXIS_TURN_DEG and self.main_axis_tilt_deg >= 3 * SINGLE_AXIS_TILT_DEG
                and self.span_deg >= FAR_SPAN_DEG)   # shaking adds up turns without going anywhere

    def main_axis_words(self) -> str:
        """'its z axis' or 'an axis between its x and z axes (0.71, 0.00, 0.71)'."""
        a = np.abs(self.main_axis)
        k = int(np.argmax(a))
        if a[k] > 0.9:
            return f"its {'xyz'[k]} axis"
        two = np.argsort(a)[-2:]
        return (f"an axis between its {'xyz'[min(two)]} and {'xyz'[max(two)]} axes "
                f"({', '.join(f'{v:.2f}' for v in self.main_axis)})")


def turning(session: Session, bias_rad_s: np.ndarray | None = None) -> Turning:
    """The gyro's account of the motion: attitude span, turn about each principal axis, the main axis's tilt.
    Holes in the record start again from the attitude before them."""
    step = max(1, int(session.gyro_rate_hz // SPAN_RATE_HZ))
    t, w = session.t_gyro_s[::step], session.gyro_rad_s[::step]
    if bias_rad_s is not None:
        w = w - bias_rad_s
    w = np.where(np.append(hole_steps(t), False)[:, None], 0.0, w)   # nothing turns across a hole
    q = so3.integrated_quaternions(t, w)    # unit quaternions: no (N, 3, 3) matrix of every sample
    span = float(np.rad2deg(np.max(2.0 * np.arctan2(np.linalg.norm(q[:, 1:], axis=1), np.abs(q[:, 0])))))
    dt = np.gradient(t)
    _, axes = np.linalg.eigh((w * dt[:, None]).T @ w)
    turn = np.rad2deg(np.abs(w @ axes).T @ dt)
    main = axes[:, -1] * np.sign(axes[np.argmax(np.abs(axes[:, -1])), -1])
    v = q[:, 1:]   # main^T C main = 1 - 2 (|v|^2 - (v . main)^2) for C of the unit quaternion (w, v)
    tilt = float(np.rad2deg(np.arccos(np.clip(np.min(1.0 - 2.0 * (np.sum(v * v, axis=1) - (v @ main) ** 2)), -1.0, 1.0))))
    return Turning(span, tuple(float(x) for x in turn), main, tilt)


def motion_error(motion: Turning, gyro_note: str = "", analysis=None) -> ObservabilityError | None:
    """Causes 1 and 2 (exit 3), or None when the device turned far about more than one axis."""
    if motion.span_deg < SMALL_TURN_DEG:
        return ObservabilityError(
            f"the device turned too little: at most {motion.span_deg:.0f} deg from its first attitude (gyro), so "
            "the field directions cover a small patch of the sphere and neither the magnetometer's iron nor the "
            "gyro can be calibrated; turn the device through large angles (90 deg or more) about all three of "
            f"its axes, so that the field sweeps much of the sphere.{gyro_note}", analysis)
    if motion.single_axis:
        return ObservabilityError(
            f"the device turned about one axis only, {motion.main_axis_words()} ({motion.span_deg:.0f} deg, while that "
            f"axis itself tilted at most {motion.main_axis_tilt_deg:.0f} deg): the field sweeps one circle, which "
            "fixes neither the magnetometer's ellipsoid nor the gyro's other axes; turn the device about all three of "
            f"its axes (tilt it, roll it over), not only about this one.{gyro_note}", analysis)
    return None


def magnetometer_fault(motion: Turning, cloud_kind: str) -> InputError | None:
    """Causes 3 and 4 (exit 2): the device turned far about every axis, so the cloud's shape is the sensor's or
    the field's fault, not the motion's. None otherwise."""
    if not motion.every_axis:
        return None
    turned = f"the gyro says the device turned {', '.join(f'{x:.0f}' for x in motion.turn_deg)} deg about its three " \
             "principal axes"
    if cloud_kind in ("static", "planar"):
        what = "vary no more than their own noise" if cloud_kind == "static" else "lie in one plane"
        return InputError(
            f"{turned}, but the magnetometer readings {what}: they do not follow the turning (an axis dead or "
            "constant, or columns that are not a magnetometer's); check mx, my, mz")
    return InputError(
        f"{turned}, but the magnetometer readings lie on no ellipsoid (the fitted surface is a hyperboloid): the "
        "field is not the same everywhere along the path (iron or a magnet near the device moved, or the device "
        "moved near iron); record away from iron, steel furniture and magnets, turning the device in place")


def cloud_error(session: Session, cloud_kind: str, cloud_message: str, bias_rad_s, analysis_of) -> MagyroError:
    """The error for a magnetometer cloud that fits no ellipsoid (`cloud_kind`: static, planar, sparse, or
    hyperboloid), in the order of the module's docstring. `analysis_of()` gives the gate's analysis on raw
    directions (only computed for an exit 3)."""
    motion = turning(session, bias_rad_s)
    fault = magnetometer_fault(motion, cloud_kind)
    if fault is not None:
        return fault
    if cloud_kind == "static" and motion.span_deg > SMALL_TURN_DEG:
        return InputError(
            f"the gyro says the device turned {motion.span_deg:.0f} deg from its first attitude but the magnetometer "
            "readings do not follow: they vary no more than their own noise; check that mx, my, mz are a "
            "magnetometer and are not noise or constant")
    analysis = analysis_of()
    gyro_note = "" if analysis.full_rank else f" Gyro parameters: {analysis.summary().rstrip('.')}."
    error = motion_error(motion, gyro_note, analysis)
    if error is not None:
        return error
    if cloud_kind == "hyperboloid":
        cloud_message = ("the magnetometer readings do not determine an ellipsoid: the field directions cover too "
                         "little of the sphere (rotation about one or two axes only?)")
    return ObservabilityError(f"{cloud_message}; the magnetometer's soft/hard iron cannot be fitted. Turn the device "
                              f"through large angles about all three of its axes.{gyro_note}", analysis)
