"""The accuracy a recording can give, predicted before any solve: the one computation behind the verdict of
`magyro observe` and the gate of `magyro solve` (either method), so that the two never disagree.

    predicted = predicted_accuracy(prep, options, method)   # the one-sigma of every parameter, the room's field
    excitation_gate(predicted, options)                     # exit 3 below the refusal bound (--force: warnings)

The prediction is the field's alone: the gyro and the magnetometer in the plain least squares at the solve's node
stride, the accelerometer left out (gravity is shown beside observe's verdict, never in it), the Gauss-Newton
information at the linear estimate with the room's field disturbance measured and counted
(`magyro.nls.information.predicted_std_and_disturbance`); with a moving hard iron (`NLS(hard_iron_walk=...)`) the
field's wander is what the walk models, and is not counted as the room's (the solved std is bounded after the solve). A strong signal to noise along every direction is no
shortcut: the x-io Fusion example's quarter sphere has 1100x its noise floor along its weakest direction and a
field that wanders by 2.9 % along the path, which leaves a scale factor uncertain by 6.7 %.
"""
from __future__ import annotations

import dataclasses
import math
import time
from dataclasses import dataclass

from magyro.front.prepare import Prepared
from magyro.nls.information import predicted_std_and_disturbance
from magyro.nls.method import NLS
from magyro.nls.solve import default_stride
from magyro.observability.gate import accuracy_gate
from magyro.options import Options
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


def predicted_accuracy(prep: Prepared, options: Options, method=None) -> PredictedAccuracy:
    """The one-sigma this recording can give, before solving (the module docstring says what it counts)."""
    stride = prediction_stride(prep.session, method)
    plain = NLS(stride=stride, compiled=method.compiled if isinstance(method, NLS) else True)
    start = time.perf_counter()
    room = not (isinstance(method, NLS) and method.hard_iron_walk is not None)   # a walking hard iron is the wander
    std, disturbance = predicted_std_and_disturbance(prep, dataclasses.replace(options, accelerometer=False), plain,
                                                     room=room)
    return PredictedAccuracy(std, disturbance, stride, time.perf_counter() - start)


def bounded(options: Options) -> bool:
    """Does `options.max_std` bound any gyro parameter (a half of the split-half check has no bounds)?"""
    b = options.max_std
    return any(math.isfinite(v) for v in (b.scale_ppm, b.nonorthogonality_deg, b.bias_deg_s, b.misalignment_deg))


def excitation_gate(prep: Prepared, options: Options, method=None) -> list[str]:
    """The gate every solve runs before any solver work: `magyro observe`'s verdict, from the same prediction.
    ObservabilityError (exit 3) when a gyro parameter's predicted one-sigma is past `options.max_std`; with
    `options.force`, that shortfall as a warning. Nothing to compute without bounds."""
    if not bounded(options):
        return []
    predicted = predicted_accuracy(prep, options, method)
    wander = None if predicted.disturbance is None else predicted.disturbance.std_fraction
    return accuracy_gate(predicted.std, options, wander)
