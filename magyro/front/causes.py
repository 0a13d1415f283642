"""What a magnetometer cloud that fits no ellipsoid means, named in one order of causes (issue 22).

The readings are judged against the gyro, which does not need the magnetometer to say how the
device turned:

1. the device barely turned (at most SMALL_TURN_DEG from its first attitude): too little motion (exit 3);
2. it turned about one axis only (that axis never tilted more than SINGLE_AXIS_TILT_DEG): the field
   sweeps one circle, which fits no ellipsoid, whatever shape the fit takes (exit 3, naming the axis);
   or mostly about one axis (`Turning.mostly_one_axis`): a multicopter flying turns in yaw while its attitude
   control swings it by some degrees about the other two and back. Those swings add up to many degrees of
   turning (every axis passes EVERY_AXIS_TURN_DEG), and over a long flight the gyro's bias tilts its
   integrated attitude far (the F450's main axis "tilted" 118 deg where the accelerometer saw under 14), so
   neither says what the field saw: the net turn over NET_WINDOW_S windows does. Where the main axis carries
   MOSTLY_ONE_AXIS_FRACTION of the squared net turning and the other two swing by less than
   SINGLE_AXIS_TILT_DEG RMS, the field sweeps little more than a circle (exit 3, naming the axis);
3. it turned far about every axis, yet the readings stay within their noise or in one plane: the
   magnetometer does not follow the turning (a dead axis, constant values, not a magnetometer; exit 2).
   A cloud the ellipsoid fit calls static (spread under 10 noise stds, with the noise of the rest) whose
   spread is still FOLLOWS_IN_NOISE_STD times its white noise (third differences) or more varies, and is no
   dead sensor: its small spread is the motion's (the quadcopters' magnetometers, 8.6 x their noise,
   follow the heading);
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
NET_WINDOW_S = 2.0             # the net turn over windows this long: swings that come back cancel in it
MOSTLY_ONE_AXIS_FRACTION = 0.7   # the main axis's share of the squared net turning for "mostly one axis"
FOLLOWS_IN_NOISE_STD = 3.0     # readings spread this many white-noise stds or more: the sensor is not dead


@dataclass(frozen=True)
class Turning:
    """How the gyro (less a rest bias when known) says the device turned."""

    span_deg: float                # the farthest it got from its first attitude
    turn_deg: tuple                # integral of |w . e_i| dt about the principal axes e_i, smallest first
    main_axis: np.ndarray          # body-frame unit vector of the axis it turned about most
    main_axis_tilt_deg: float      # how far that axis itself ever tilted from its first direction
    net_main_axis: np.ndarray | None = None   # body axis of most net turning over NET_WINDOW_S windows
    net_main_fraction: float = 0.0            # its share of the squared net turning
    net_other_rms_deg: float = 0.0            # RMS net turn per window about the other two axes (the larger)

    @property
    def single_axis(self) -> bool:
        return self.main_axis_tilt_deg < SINGLE_AXIS_TILT_DEG and self.span_deg >= SMALL_TURN_DEG

    @property
    def mostly_one_axis(self) -> bool:
        return (not self.single_axis and self.span_deg >= SMALL_TURN_DEG
                and self.net_main_fraction >= MOSTLY_ONE_AXIS_FRACTION
                and self.net_other_rms_deg < SINGLE_AXIS_TILT_DEG)

    @property
    def every_axis(self) -> bool:
        return (min(self.turn_deg) >= EVERY_AXIS_TURN_DEG and self.main_axis_tilt_deg >= 3 * SINGLE_AXIS_TILT_DEG
                and self.span_deg >= FAR_SPAN_DEG   # shaking adds up turns without going anywhere
                and not self.mostly_one_axis)       # nor do a multicopter's swings about its level axes

    def main_axis_words(self, axis: np.ndarray | None = None) -> str:
        """'its z axis' or 'an axis between its x and z axes (0.71, 0.00, 0.71)'."""
        axis = self.main_axis if axis is None else axis
        a = np.abs(axis)
        k = int(np.argmax(a))
        if a[k] > 0.9:
            return f"its {'xyz'[k]} axis"
        two = np.argsort(a)[-2:]
        return (f"an axis between its {'xyz'[min(two)]} and {'xyz'[max(two)]} axes "
                f"({', '.join(f'{v:.2f}' for v in axis)})")


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
    net_axis, net_fraction, net_other_deg = net_turning(t, w)
    return Turning(span, tuple(float(x) for x in turn), main, tilt, net_axis, net_fraction, net_other_deg)


def net_turning(t_s: np.ndarray, w_rad_s: np.ndarray) -> tuple[np.ndarray | None, float, float]:
    """(main axis, its share, the other axes' larger RMS in deg) of the net turns (integral of w dt, small
    angles) over consecutive NET_WINDOW_S windows; (None, 0, 0) for less than two windows."""
    edges = np.searchsorted(t_s, np.arange(t_s[0], t_s[-1], NET_WINDOW_S))
    if len(edges) < 3:
        return None, 0.0, 0.0
    dt = np.diff(t_s, append=t_s[-1])
    angle = np.concatenate([np.zeros((1, 3)), np.cumsum(w_rad_s * dt[:, None], axis=0)])
    net = angle[edges[1:]] - angle[edges[:-1]]
    lam, axes = np.linalg.eigh(net.T @ net)
    if lam[-1] <= 0:
        return None, 0.0, 0.0
    main = axes[:, -1] * np.sign(axes[np.argmax(np.abs(axes[:, -1])), -1])
    return main, float(lam[-1] / lam.sum()), float(np.rad2deg(np.sqrt(max(lam[1], 0.0) / len(net))))


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
    if motion.mostly_one_axis:
        return ObservabilityError(
            f"the device turned mostly about one axis, {motion.main_axis_words(motion.net_main_axis)} (its yaw, "
            f"if it is a vehicle: {100 * motion.net_main_fraction:.0f} % of its net turning over "
            f"{NET_WINDOW_S:g} s windows), while the other two only swung by {motion.net_other_rms_deg:.0f} deg RMS "
            "and came back, as a multicopter's attitude control does: the field sweeps little more than one "
            "circle, which fixes neither the magnetometer's ellipsoid nor the gyro's other axes; turn the device "
            f"far about all three of its axes (tilt it, roll it over), not only about this one.{gyro_note}", analysis)
    return None


def readings_vary(mag: np.ndarray) -> bool:
    """The magnetometer's largest spread is FOLLOWS_IN_NOISE_STD white-noise stds (third differences) or more:
    the readings change; a dead or constant sensor's spread is its noise."""
    from magyro.front.differences import white_noise_std

    mag = np.asarray(mag, dtype=float)
    if len(mag) < 10:
        return False
    spread = float(np.sqrt(max(np.linalg.eigvalsh(np.cov(mag.T))[-1], 0.0)))
    return spread >= FOLLOWS_IN_NOISE_STD * float(np.sqrt(np.mean(white_noise_std(mag) ** 2)))


def magnetometer_fault(motion: Turning, cloud_kind: str, mag: np.ndarray | None = None) -> InputError | None:
    """Causes 3 and 4 (exit 2): the device turned far about every axis, so the cloud's shape is the sensor's or
    the field's fault, not the motion's. None otherwise, and None for a "static" cloud whose readings `mag`
    (when given) vary beyond their white noise: its small spread is the motion's, not a dead sensor's."""
    if not motion.every_axis:
        return None
    if cloud_kind == "static" and mag is not None and readings_vary(mag):
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
    fault = magnetometer_fault(motion, cloud_kind, session.mag)
    if fault is not None:
        return fault
    if cloud_kind == "static" and motion.span_deg > SMALL_TURN_DEG and not readings_vary(session.mag):
        return InputError(
            f"the gyro says the device turned {motion.span_deg:.0f} deg from its first attitude but the magnetometer "
            "readings do not follow: they vary no more than their own noise; check that mx, my, mz are a "
            "magnetometer and are not noise or constant")
    analysis = analysis_of()
    gyro_note = "" if analysis.full_rank else f" Gyro parameters: {analysis.summary().rstrip('.')}."
    error = motion_error(motion, gyro_note, analysis)
    if error is not None and motion.mostly_one_axis and cloud_kind == "planar":   # the cloud's word, then the axis
        return ObservabilityError(f"the magnetometer readings lie in one plane (a circle of field directions): "
                                  f"{error}", analysis)
    if error is not None:
        return error
    if cloud_kind == "hyperboloid":
        cloud_message = ("the magnetometer readings do not determine an ellipsoid: the field directions cover too "
                         "little of the sphere (rotation about one or two axes only?)")
    return ObservabilityError(f"{cloud_message}; the magnetometer's soft/hard iron cannot be fitted. Turn the device "
                              f"through large angles about all three of its axes.{gyro_note}", analysis)
