"""The accuracy a recording can give, predicted before any solve: the one computation behind the verdict of
`magyro observe` and the gate of `magyro solve` (either method), so that the two never disagree.

    predicted = predicted_accuracy(prep, options, method)   # the one-sigma of every parameter, the room's field
    excitation_gate(prep, options, method)                  # exit 3 past the refusal bound (--force: warnings)

The prediction is the field's alone: the gyro and the magnetometer in the plain least squares at the solve's node
stride, the accelerometer left out (gravity is shown beside observe's verdict, never in it), the Gauss-Newton
information at the linear estimate with the room's field disturbance measured and counted
(`magyro.nls.information.predicted_std_and_disturbance`); with a moving hard iron (`NLS(hard_iron_walk=...)`) the
field's wander is what the walk models, and is not counted as the room's (the solved std is bounded after the
solve). A strong signal to noise alone is no shortcut: the x-io Fusion example's quarter sphere has 1100x its noise
floor along its weakest direction and a field that wanders by 2.9 % along the path, which leaves a scale factor
uncertain by 6.7 %. The solve's gate skips the prediction only where the motion is strong AND the field steady
(`prediction_needed`); observe always makes it.
"""
from __future__ import annotations

import dataclasses
import math
import time
from dataclasses import dataclass

import numpy as np

from magyro.front.prepare import Prepared
from magyro.nls.disturbance import window_means
from magyro.nls.information import predicted_std_and_disturbance
from magyro.nls.method import NLS
from magyro.nls.solve import default_stride
from magyro.errors import InputError
from magyro.front.causes import turning
from magyro.observability.gate import accuracy_gate, accuracy_shortfalls, accuracy_summary, holes_cause
from magyro.observability.report import SPHERE_BANDS, SPHERE_SECTORS, sphere_cell
from magyro.options import Options, StdBounds
from magyro.result.parts import Std
from magyro.session import Session


@dataclass(frozen=True)
class PredictedAccuracy:
    """The predicted one-sigma (laid out like `Calibration.std`), the room's field disturbance it counts (or None),
    the node stride it was computed at and what it cost (s)."""

    std: Std
    disturbance: object | None
    stride: int
    seconds: float


def prediction_stride(session: Session, method=None) -> int:
    """The least squares' node stride (`NLS.stride`), or the solve's default when it leaves it open (or for the EKF,
    which has none): the prediction and the solve share their kernels."""
    stride = method.stride if isinstance(method, NLS) else None
    return int(stride or default_stride(session))


def predicted_accuracy(prep: Prepared, options: Options, method=None, steady_field: bool = False) -> PredictedAccuracy:
    """The one-sigma this recording can give, before solving (the module docstring says what it counts);
    `steady_field`: as if the field held still along the path (the room's wander not counted)."""
    stride = prediction_stride(prep.session, method)
    plain = NLS(stride=stride, compiled=method.compiled if isinstance(method, NLS) else True)
    start = time.perf_counter()
    room = not steady_field and not (isinstance(method, NLS) and method.hard_iron_walk is not None)   # a walking
    # hard iron is the wander
    std, disturbance = predicted_std_and_disturbance(prep, dataclasses.replace(options, accelerometer=False), plain,
                                                     room=room)
    return PredictedAccuracy(std, disturbance, stride, time.perf_counter() - start)


def bounded(options: Options) -> bool:
    """Does `options.max_std` bound any gyro parameter (a half of the split-half check has no bounds)?"""
    b = options.max_std
    return any(math.isfinite(v) for v in (b.scale_ppm, b.nonorthogonality_deg, b.bias_deg_s, b.misalignment_deg))


# Where the prediction (0.5-1 s of CPU on a 100 s session, as much as the solve) can be skipped: a motion strong in
# every direction (signal to noise above 100 along the weakest: weak third axes of +/-30, 45 and 60 deg reached 23,
# 68 and 135; BROAD 238-654) in a field that holds its size along the path (the calibrated magnitude's 0.2 s means
# within 1.5 % RMS: BROAD's undisturbed trials 0.5-1.2 %), with the default bounds. The x-io Fusion example has 1100
# in signal to noise but a field that wanders by 2.9 %, which leaves a scale factor uncertain by 6.7 %: the wander
# is what the screen must see. tests/test_wild_corpus.py checks the screen against observe's verdict on every real
# recording at hand.
SCREEN_SNR = 100.0
SCREEN_WANDER = 0.015
SCREEN_WINDOW_S = 0.2
# ... and turned far about every axis: a quiet sensor's signal to noise says nothing of a room's wander, which the
# turning must average out. PX4's bench test (InertialNav, ../shared/data/wild) has 2335 in signal to noise and a
# 0.5 % wander, but turned 190-386 deg about its principal axes, and its prediction is 4x past the bounds; BROAD's
# trials turn 2000-30000 deg, the shipped phone simulation 1700, the ArduPlane flight 5000
SCREEN_TURN_DEG = 1000.0


def field_wander_fraction(prep: Prepared) -> float:
    """RMS of the calibrated field's magnitude over SCREEN_WINDOW_S means, less one: the room's wander and the
    ellipsoid's error together (no less than the wander the prediction would measure)."""
    means = window_means(prep.session.t_mag_s, np.linalg.norm(prep.field_m, axis=1), SCREEN_WINDOW_S)
    return float(np.sqrt(np.mean((means - np.mean(means)) ** 2)) / np.mean(means))


def prediction_needed(prep: Prepared, options: Options) -> bool:
    """Must the solve's gate compute the prediction, or is the motion certainly within the default bounds?"""
    if options.max_std != StdBounds():
        return True
    snr = prep.analysis.signal_to_noise
    if snr is None or not prep.analysis.full_rank or float(np.min(snr)) < SCREEN_SNR:
        return True
    if field_wander_fraction(prep) > SCREEN_WANDER:
        return True
    return min(prepared_turning(prep).turn_deg) < SCREEN_TURN_DEG


def prepared_turning(prep: Prepared):
    """How the gyro, less the rests' bias when there are rests, says the device turned (`causes.turning`)."""
    return turning(prep.session, prep.rests.gyro_mean_rad_s if prep.rests is not None else None)


def excitation_gate(prep: Prepared, options: Options, method=None) -> list[str]:
    """The gate every solve runs before any solver work: `magyro observe`'s verdict, from the same prediction.
    ObservabilityError (exit 3) when a gyro parameter's predicted one-sigma is past `options.max_std`; with
    `options.force`, that shortfall as a warning. Nothing to compute without bounds, or where the screen
    (`prediction_needed`) finds the motion strong and the field steady."""
    if not bounded(options) or not prediction_needed(prep, options):
        return []
    predicted = predicted_accuracy(prep, options, method)
    refuse_a_field_fault(prep, options, method, predicted)
    wander = None if predicted.disturbance is None else predicted.disturbance.std_fraction
    return accuracy_gate(predicted.std, options, wander, holes_cause(prep.session.t_gyro_s))


def refuse_a_field_fault(prep: Prepared, options: Options, method, predicted: PredictedAccuracy) -> None:
    """Raise `field_fault`'s InputError (exit 2) unless `options.force` (then the motion's verdict speaks)."""
    fault = field_fault(prep, options, method, predicted)
    if fault is not None and not options.force:
        raise fault


FIELD_FAULT_WANDER = 0.01   # a wander below 1 % of the field is never named as the field's fault
FIELD_FAULT_SPHERE = 0.75   # ... nor one over a motion whose field directions visit less of the sphere's cells: more
                            # of the sphere averages a wander out (the x-io Fusion example's quarter sphere, 2.9 %)


def field_fault(prep: Prepared, options: Options, method, predicted: PredictedAccuracy) -> InputError | None:
    """InputError (exit 2) when the room's field, not the motion, is why the predicted one-sigma is past the bound:
    the device turned far about every axis (`magyro.front.causes.Turning.every_axis`, as for a cloud that fits no
    ellipsoid), its field directions visited most of the sphere, and the same prediction in a steady field is within the bounds. An x-IMU tumbled through the whole
    sphere in a field that wanders by 7 % was told to turn more about its z axis (issue 38); a motion is only
    asked for where more motion would help. None otherwise (the motion's verdict stands)."""
    wander = None if predicted.disturbance is None else predicted.disturbance.std_fraction
    shortfalls = accuracy_shortfalls(predicted.std, options.max_std)
    if not shortfalls or wander is None or not wander > FIELD_FAULT_WANDER:
        return None
    motion = prepared_turning(prep)
    cells = np.unique(sphere_cell(prep.field_m)).size / (SPHERE_BANDS * SPHERE_SECTORS)
    if not (motion.every_axis and cells >= FIELD_FAULT_SPHERE):
        return None
    if accuracy_shortfalls(predicted_accuracy(prep, options, method, steady_field=True).std, options.max_std):
        return None
    return InputError(
        f"the field is not the same along the path: it wanders by {100 * wander:.1f} % of its size (iron, steel or a "
        f"magnet near the device, or the device moved near iron), which leaves {accuracy_summary(shortfalls, motion_advice=False)}; the "
        f"motion is not what is missing: the gyro says the device turned "
        f"{', '.join(f'{x:.0f}' for x in motion.turn_deg)} deg about its three principal axes, and in a steady field "
        f"the same motion would be within the bounds; record away from iron, steel furniture and magnets, turning "
        f"the device in place (--force solves anyway, its std counting the wander)")
