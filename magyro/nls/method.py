"""The joint nonlinear least squares as a method object: its own knobs, apart from the physics (`Options`).

    magyro.calibrate(session, options, method=NLS(stride=2, loss="huber"))

Knobs only: the least squares that reads them is `magyro.nls.run.calibrate_nls`, reached through
`magyro.methods.run_method` (this module imports no other part of magyro.nls).
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

from magyro.errors import InputError

LOSSES = ("l2", "huber")


@dataclass(frozen=True)
class NLS:
    """Ellipsoid, K, eps, C_b_m, the field and the attitude trajectory as one least squares (IPOPT)."""

    name: ClassVar[str] = "nls"
    stride: int | None = None        # one attitude node every `stride` segments, a segment per gyro or magnetometer
                                     # sample (None: 12, or 4 below 96 Hz)
    max_iter: int = 100
    compiled: bool = True            # compiled CasADi kernels, cached on disk (MAGYRO_JIT=0 turns them off)
    loss: str = "l2"                 # "l2" or "huber" on the magnetometer residuals
    huber_threshold: float = 3.0     # in noise sigmas
    reweight_noise: bool = True      # robust variance-component step on the magnetometer noise
    trajectory: bool = False         # keep the solved attitude at the nodes (Calibration.trajectory)
    hard_iron_walk: float | None = None   # a moving hard iron: its random-walk density, magnetometer unit / sqrt(s)
    hand_states: bool = True         # with the accelerometer and a hand that moved the device: the hand's velocity as
                                     # states at the nodes (nls/hand_states.py); False: the interval means weighted by it

    def __post_init__(self):
        if self.loss not in LOSSES:
            raise InputError(f"unknown loss '{self.loss}'; use l2 or huber")
        if self.hard_iron_walk is not None and not self.hard_iron_walk > 0:
            raise InputError(f"the hard iron's walk must be a positive density (unit / sqrt(s)), not {self.hard_iron_walk}")
        if self.stride is not None and self.stride < 1:
            raise InputError(f"stride must be at least 1, not {self.stride}")

    @property
    def huber(self) -> float | None:
        """The Huber threshold in sigmas, or None for plain least squares."""
        return self.huber_threshold if self.loss == "huber" else None
