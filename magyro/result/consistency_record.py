"""The split-half check as a calibration records it (JSON `consistency`): `SplitCheck`, and the z limits it is
judged by. The check itself, which calibrates each half and compares, is magyro.result.consistency.
"""
from __future__ import annotations

from dataclasses import dataclass, field

MAX_HALF_Z = 4.0   # one parameter; 12 unit normals exceed it with probability ~1e-3
MAX_RMS_Z = 2.0    # all twelve together; simulated sessions reached 1.35, BROAD trials 1.18 (white std: 3.2)


@dataclass(frozen=True)
class SplitCheck:
    """The split-half check of one calibration (JSON `consistency`).

    `parameters` maps each compared gyro parameter to its two half values, their
    difference, z, the reported std and the split-half std; `failed` lists the
    halves that could not be calibrated alone (then nothing is compared).
    """

    spans_s: tuple
    max_half_z: float = MAX_HALF_Z
    max_rms_z: float = MAX_RMS_Z
    parameters: dict = field(default_factory=dict)
    worst: str | None = None
    max_abs_z: float = float("nan")
    rms_z: float = float("nan")
    failed: tuple = ()

    @property
    def compared(self) -> bool:
        return not self.failed and bool(self.parameters)

    @property
    def agrees(self) -> bool:
        """Do the halves agree within their std? The one judgement of the halves, `magyro solve --split-check`'s
        (no warning) and the report's (section 5 good): the RMS of the twelve z within `max_rms_z` and every |z|
        within `max_half_z`. A parameter's `split_std` (half its one half-difference) is no part of it: one
        difference is one draw, not a std."""
        return self.compared and self.rms_z <= self.max_rms_z and self.max_abs_z <= self.max_half_z

    def to_dict(self) -> dict:
        out = {"spans_s": [list(s) for s in self.spans_s], "max_half_z": self.max_half_z, "max_rms_z": self.max_rms_z}
        if self.failed:
            out["failed"] = list(self.failed)
        else:
            out.update(parameters=self.parameters, worst=self.worst, max_abs_z=self.max_abs_z, rms_z=self.rms_z)
        return out

    @classmethod
    def from_dict(cls, data: dict) -> "SplitCheck":
        return cls(tuple(tuple(s) for s in data.get("spans_s", ())), float(data.get("max_half_z", MAX_HALF_Z)),
                   float(data.get("max_rms_z", MAX_RMS_Z)), dict(data.get("parameters", {})), data.get("worst"),
                   float(data.get("max_abs_z", float("nan"))), float(data.get("rms_z", float("nan"))),
                   tuple(data.get("failed", ())))
