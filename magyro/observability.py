"""The paper's observability theorem, evaluated on a session.

The 12 gyro parameters [vec K; eps] are observable when the integral of
M^T M over the session is nonsingular (paper eq. 10-11). With real, noisy
data the matrix is never exactly singular, so the rank is counted against a
**noise floor**: sensor noise alone adds at most

    floor = integral of ( sigma_g,sample^2 + 2 sigma_m^2 (1 + |y_g|^2) ) dt

to any eigenvalue (gyro noise enters M through y_g, magnetometer noise
through m^m x, whose outer product has expectation 2 sigma_m^2 I). An
eigen-direction counts as excited only when its eigenvalue exceeds
`FLOOR_FACTOR` times that floor (and a numerical tolerance). Units: K is
dimensionless, eps in rad/s, so the matrix is in s * (rad/s)^2 for the K
block and s for the eps block.

This module is shared by `magyro solve` (the gate) and `magyro observe`.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .excitation import PARAMETER_NAMES, information_integral, trapezoid_weights

FLOOR_FACTOR = 10.0
NUMERICAL_RTOL = 1e-12
AXES = "xyz"


@dataclass(frozen=True)
class ObservabilityAnalysis:
    rank: int
    condition: float
    eigenvalues: np.ndarray            # ascending, raw units
    eigenvectors: np.ndarray           # columns, matching eigenvalues
    tolerance: float                   # the rank threshold actually used
    noise_floor: float
    information: np.ndarray            # the 12x12 integral of M^T M
    weak_directions: list[str] = field(default_factory=list)
    advice: list[str] = field(default_factory=list)

    @property
    def eigenvalues_normalised(self) -> np.ndarray:
        return self.eigenvalues / self.eigenvalues[-1]

    @property
    def full_rank(self) -> bool:
        return self.rank == 12

    def summary(self) -> str:
        head = f"rank {self.rank} of 12 (condition {self.condition:.3g})"
        if self.full_rank:
            return head
        return head + ". Unobservable share: " + ", ".join(self.weak_directions) + ". " + " ".join(self.advice)


def noise_floor(t_gyro_s, gyro_rad_s, gyro_sample_std_rad_s: float, mag_std_unit_field: float) -> float:
    """The largest eigenvalue sensor noise alone could add to the integral of M^T M."""
    w = trapezoid_weights(t_gyro_s)
    rate2 = np.sum(gyro_rad_s**2, axis=1)
    return float(np.sum(w * (gyro_sample_std_rad_s**2 + 2.0 * mag_std_unit_field**2 * (1.0 + rate2))))


def count_rank(eigenvalues: np.ndarray, floor: float) -> tuple[int, float]:
    tol = max(FLOOR_FACTOR * floor, NUMERICAL_RTOL * eigenvalues[-1])
    return int(np.sum(eigenvalues > tol)), tol


def analyse(t_gyro_s, gyro_rad_s, t_mag_s, field_m, gyro_sample_std_rad_s: float, mag_std_unit_field: float) -> ObservabilityAnalysis:
    """Rank, condition and plain-language weak directions of the integral of M^T M."""
    info = information_integral(t_gyro_s, gyro_rad_s, t_mag_s, field_m)
    lam, V = np.linalg.eigh(info)
    floor = noise_floor(t_gyro_s, gyro_rad_s, gyro_sample_std_rad_s, mag_std_unit_field)
    rank, tol = count_rank(lam, floor)
    condition = float(lam[-1] / lam[0]) if lam[0] > 0 else float("inf")
    weak = unobservable_groups(V[:, : 12 - rank])
    advice = motion_advice(t_gyro_s, gyro_rad_s, t_mag_s, field_m) if rank < 12 else []
    return ObservabilityAnalysis(rank, condition, lam, V, tol, floor, info, weak, advice)


PARAMETER_GROUPS = {
    "gyro x-axis response (K11 K21 K31)": [0, 1, 2],
    "gyro y-axis response (K12 K22 K32)": [3, 4, 5],
    "gyro z-axis response (K13 K23 K33)": [6, 7, 8],
    "gyro bias (eps)": [9, 10, 11],
}


def unobservable_groups(weak_vectors: np.ndarray, at_least: float = 0.1) -> list[str]:
    """Parameter groups with the share of each that lies in the weak subspace, largest first.

    A parameter's share is the squared length of its unit vector projected onto the
    weak subspace (1 = entirely unobservable); a group's share is the mean over it.
    """
    share = np.sum(weak_vectors**2, axis=1)
    groups = [(float(np.mean(share[idx])), name) for name, idx in PARAMETER_GROUPS.items()]
    return [f"{name} {100 * w:.0f}%" for w, name in sorted(groups, reverse=True) if w >= at_least]


def motion_advice(t_gyro_s, gyro_rad_s, t_mag_s, field_m) -> list[str]:
    """What motion would excite the missing directions, in plain words."""
    w = trapezoid_weights(t_gyro_s)
    centred = gyro_rad_s - np.average(gyro_rad_s, axis=0, weights=w)
    cov = (centred * w[:, None]).T @ centred / w.sum()
    lam, V = np.linalg.eigh(cov)
    total = lam.sum()
    if total <= 0 or np.sqrt(lam[-1]) < np.deg2rad(2.0):
        return ["The device was (nearly) still: turn it by hand about all three of its axes, through large angles."]
    out = []
    missing = V[:, lam < 0.02 * lam[-1]]
    if missing.shape[1]:
        out.append(f"Rotate the device about its {axes_in_subspace(missing)} too.")
    mean_field = np.mean(field_m, axis=0)
    if np.linalg.norm(mean_field) > 0.95:
        out.append("The field direction barely changed: rotate so that the field is not along the rotation axis.")
    if not out:
        out.append("Vary the rotation rate and turn about all three device axes, with the field not along the rotation axis.")
    return out


def axes_in_subspace(basis: np.ndarray) -> str:
    """Name the device axes lying (mostly) in the span of `basis`, or give the directions."""
    inside = [AXES[i] for i in range(3) if np.sum(basis[i] ** 2) > 0.8]
    if len(inside) == basis.shape[1]:
        return " and ".join(f"{a} axis" for a in inside)
    return " and ".join("axis [" + ", ".join(f"{c:+.2f}" for c in basis[:, k]) + "]" for k in range(basis.shape[1]))
