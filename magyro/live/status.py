"""What `magyro watch` shows after each update (`Status`, its JSON line) and ENOUGH's instruction."""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from magyro.live.accelerometer import accelerometer_json
from magyro.live.prediction import Prediction

END_REST_S = 2.0            # after ENOUGH, the device is put down this long before the recording stops: the end
                            # rest (front.rests) gives the bias check and, with the start rest, the noise levels


@dataclass
class Status:
    """What the monitor knows after an `update()`."""

    t_s: float                      # session time of the latest sample (the stream's own t, as saved)
    gyro_samples: int
    mag_samples: int
    rank: int
    noise_floor: float              # the largest eigenvalue of the noise matrix N
    eigenvalues: np.ndarray         # normalised (largest 1), ascending
    signal_to_noise: np.ndarray     # per eigen-direction, weakest first (rank: those above FLOOR_FACTOR)
    condition: float
    coverage: float                 # fraction of the SPHERE cells the field direction visited
    cells_visited: int
    field_source: str               # "ellipsoid fit" | "raw readings (no fit yet)"
    instruction: str
    detail: str
    targets: dict
    prediction: Prediction | None   # the latest finished prediction
    predicting: bool                # a prediction is being computed
    enough: bool                    # the latest prediction meets every target
    enough_at_s: float | None       # session time of the data end of the first prediction that met them
    still_s: float = 0.0            # how long the gyro has been still at the end of the data (s; 0 before ENOUGH)
    accelerometer: object = None    # gravity.AccelerometerObservability (its 12 parameters) of the data so far, or None
    acc_samples: int = 0
    rank_with_gravity: int | None = None   # the gyro's rank with gravity beside the field (observe's part 2), or None

    @property
    def predicted(self) -> dict | None:
        """{group: largest predicted one-sigma} or None."""
        if self.prediction is None or self.prediction.std is None:
            return None
        return {g: float(np.max(v)) for g, v in self.prediction.std.items()}

    def to_json_dict(self) -> dict:
        p = self.prediction
        return {
            "t_s": round(self.t_s, 6), "rank": self.rank,
            "noise_floor": self.noise_floor if math.isfinite(self.noise_floor) else None,
            "coverage": round(self.coverage, 6), "cells_visited": self.cells_visited,
            "gyro_samples": self.gyro_samples, "mag_samples": self.mag_samples,
            "field": self.field_source,
            "predicted_std": None if self.predicted is None else {
                g: (v if math.isfinite(v) else None) for g, v in self.predicted.items()},
            "predicted_at_s": None if p is None else round(p.t_s, 6),
            "verdict": None if p is None else p.verdict, "targets": self.targets,
            "enough": self.enough, "enough_at_s": self.enough_at_s, "still_s": round(self.still_s, 6),
            "instruction": self.instruction,
        } | ({} if self.accelerometer is None else {"accelerometer": accelerometer_json(
            self.accelerometer, self.acc_samples, self.rank_with_gravity)})


def enough_instruction(still_s: float) -> str:
    """ENOUGH's instruction: rest the device first (`END_REST_S`), then stop."""
    if still_s >= END_REST_S:
        return f"ENOUGH, and still for {still_s:.1f} s: stop the recording now (Ctrl-C)"
    return (f"ENOUGH: the motion meets every target; put the device down and leave it still for {END_REST_S:g} s, "
            "then stop the recording (Ctrl-C)")
