"""The calibration result: QR split, uncertainty propagation, JSON (SPEC section 4), table."""
from __future__ import annotations

import json
from dataclasses import dataclass, field

import numpy as np

from magyro import so3
from magyro.errors import InputError

SCHEMA = "magyro.calibration/1"
UPPER = [(0, 0), (0, 1), (0, 2), (1, 1), (1, 2), (2, 2)]
# layout of the reported vector (reported_vector), used to unpack its covariance
REPORTED = {
    "K_g": slice(0, 6), "bias_deg_s": slice(6, 9), "misalignment_deg": slice(9, 12), "R": slice(12, 18),
    "h": slice(18, 21), "K": slice(21, 30), "field_i": slice(30, 33), "time_offset_s": slice(33, 34),
}
N_REPORTED = 34


def qr_split(K: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(C_b_m, K_g) with K = C_b_m K_g, K_g upper triangular with positive diagonal.

    Raises InputError when C_b_m would be improper (det -1). Only the gyro's
    handedness can show up here: a mirrored magnetometer is absorbed by the
    model (y -> D y is fitted by D R^-1 D, D C D and K -> -D K, all proper), so
    it appears instead as a misalignment near 180 deg (see `axis_mapping_warning`).
    """
    Q, Rq = np.linalg.qr(K)
    D = np.diag(np.sign(np.diag(Rq)))
    C, Kg = Q @ D, D @ Rq
    if np.linalg.det(C) < 0:
        raise InputError(
            "the gyro axes are a mirror image of the magnetometer's (det C_b_m = -1): the gyro's axis mapping is "
            "wrong (one gyro axis negated, or two swapped); negate one gyro column (e.g. gz) or swap two, "
            "and solve again"
        )
    return C, Kg


MISALIGNMENT_WARNING_DEG = 90.0


def axis_mapping_warning(C_b_m: np.ndarray) -> str | None:
    """A plain warning when the gyro-to-magnetometer rotation is too large to be a mounting tolerance."""
    angle = float(np.rad2deg(np.linalg.norm(so3.log_so3(C_b_m))))
    if angle <= MISALIGNMENT_WARNING_DEG:
        return None
    return (
        f"the gyro-to-magnetometer misalignment is {angle:.0f} deg: far more than a mounting tolerance. "
        "An axis mapping is probably wrong (a magnetometer axis negated or swapped looks exactly like this); "
        "check the axis conventions of both sensors"
    )


@dataclass
class Calibration:
    """Everything `magyro solve` reports. Matrices as numpy arrays."""

    K_g: np.ndarray
    bias_rad_s: np.ndarray
    K: np.ndarray
    eps_rad_s: np.ndarray
    C_b_m: np.ndarray
    R: np.ndarray
    h: np.ndarray
    mag_unit: str
    field_i: np.ndarray
    std: dict                      # one-sigma: K_g, bias_deg_s, misalignment_deg, R, h, K, field_i
    observability: dict            # rank, condition, ...
    solver: dict                   # method, status, iterations, seconds, ...
    noise: dict = field(default_factory=dict)
    fit: dict = field(default_factory=dict)
    time_offset_s: float = 0.0     # magnetometer lag behind the gyro
    time_offset_estimated: bool = False
    rests: dict | None = None      # rest segments and the bias they imply
    warnings: list = field(default_factory=list)
    covariance_theta: np.ndarray | None = None  # 23x23, internal correction parameters
    consistency: dict | None = None  # split-half check (magyro.consistency), when asked for

    @property
    def bias_deg_s(self) -> np.ndarray:
        return np.rad2deg(self.bias_rad_s)

    @property
    def euler_deg(self) -> np.ndarray:
        return so3.dcm_to_euler(self.C_b_m)

    def to_dict(self) -> dict:
        L = lambda a: np.asarray(a, dtype=float).tolist()  # noqa: E731
        return {
            "schema": SCHEMA,
            "gyro": {
                "K_g": L(self.K_g),
                "bias_rad_s": L(self.bias_rad_s),
                "bias_deg_s": L(self.bias_deg_s),
                "K": L(self.K),
                "eps_m_rad_s": L(self.eps_rad_s),
            },
            "misalignment": {"C_b_m": L(self.C_b_m), "euler_deg": L(self.euler_deg)},
            "magnetometer": {"R": L(self.R), "h": L(self.h), "unit": self.mag_unit,
                             "field_strength": float(1.0 / np.cbrt(np.prod(np.diag(self.R))))},
            "field_i": L(self.field_i),
            "time_offset_s": float(self.time_offset_s),
            "time_offset_estimated": self.time_offset_estimated,
            "std": {k: L(v) for k, v in self.std.items()},
            "rests": self.rests,
            "warnings": list(self.warnings),
            "observability": self.observability,
            "solver": self.solver,
            "noise": self.noise,
            "fit": self.fit,
            **({"consistency": self.consistency} if self.consistency is not None else {}),
        }

    def to_json(self) -> str:
        return json.dumps(self.to_dict(), indent=2)

    def table(self) -> str:
        """A short, truth-free human summary: estimate +/- one sigma (like the paper's Tables I/II)."""
        s = self.std
        lines = []
        lines.append("gyro K_g (scale on diagonal, non-orthogonality above), +/- 1 sigma")
        for i in range(3):
            cells = []
            for j in range(3):
                if j < i:
                    cells.append(" " * 22)
                else:
                    cells.append(f"{self.K_g[i, j]:9.5f} +/- {s['K_g'][i][j]:8.5f}")
            lines.append("  " + "  ".join(cells))
        b, sb = self.bias_deg_s, s["bias_deg_s"]
        lines.append("gyro bias (deg/s)      " + "  ".join(f"{b[i]:+8.4f} +/- {sb[i]:.4f}" for i in range(3)))
        e, se = self.euler_deg, s["misalignment_deg"]
        lines.append("misalignment C_b_m, roll pitch yaw (deg)  " + "  ".join(f"{e[i]:+8.3f} +/- {se[i]:.3f}" for i in range(3)))
        h, sh = self.h, s["h"]
        lines.append(f"magnetometer h ({self.mag_unit})  " + "  ".join(f"{h[i]:+.4g} +/- {sh[i]:.2g}" for i in range(3)))
        lines.append("magnetometer R diagonal  " + "  ".join(f"{self.R[i, i]:.5g} +/- {s['R'][i][i]:.2g}" for i in range(3)))
        if self.time_offset_estimated:
            lines.append(f"magnetometer lag behind the gyro (ms)  {1e3 * self.time_offset_s:+.2f} +/- {1e3 * s['time_offset_s']:.2f}")
        if self.rests and self.rests.get("bias_deg_s"):
            rb = self.rests["bias_deg_s"]
            lines.append(f"bias from {self.rests['seconds']:.1f} s of rest (deg/s)  " + "  ".join(f"{v:+8.4f}" for v in rb))
        if self.consistency and "max_abs_z" in self.consistency:
            c = self.consistency
            lines.append(f"split-half check: the halves differ by {c['rms_z']:.1f} sigma RMS, at most {c['max_abs_z']:.1f} "
                         f"({c['worst']}); above {c['max_rms_z']:.0f} RMS or {c['max_half_z']:.0f} is a warning")
        ob = self.observability
        lines.append(f"observability: rank {ob['rank']} of 12, condition {ob['condition']:.3g}")
        sv = self.solver
        lines.append(f"solver: {sv['method']} {sv['status']}, {sv['iterations']} iterations, {sv['seconds']:.2f} s")
        lines.extend(f"warning: {w}" for w in self.warnings)
        return "\n".join(lines)


def misalignment_vector(C_ref: np.ndarray, C: np.ndarray) -> np.ndarray:
    """d with C = C_ref Exp(d)."""
    return so3.log_so3(C_ref.T @ C)


def reported_vector(K, eps, S, h, m_i, C_ref, tau_s: float = 0.0) -> np.ndarray:
    """The reported parameters as one vector (layout REPORTED), for uncertainty propagation."""
    C, Kg = qr_split(K)
    R = np.linalg.inv(S)
    return np.concatenate([
        [Kg[i, j] for i, j in UPPER],
        np.rad2deg(C.T @ eps),
        np.rad2deg(misalignment_vector(C_ref, C)),
        [R[i, j] for i, j in UPPER],
        h,
        K.reshape(-1),
        m_i,
        [tau_s],
    ])


def std_from_covariance(cov_out: np.ndarray) -> dict:
    """Unpack the diagonal of the reported-vector covariance into the SPEC `std` layout."""
    sd = np.sqrt(np.maximum(np.diag(cov_out), 0.0))
    Kg = np.zeros((3, 3))
    R = np.zeros((3, 3))
    for n, (i, j) in enumerate(UPPER):
        Kg[i, j] = sd[REPORTED["K_g"].start + n]
        R[i, j] = sd[REPORTED["R"].start + n]
    return {
        "K_g": Kg,
        "bias_deg_s": sd[REPORTED["bias_deg_s"]],
        "misalignment_deg": sd[REPORTED["misalignment_deg"]],
        "R": R,
        "h": sd[REPORTED["h"]],
        "K": sd[REPORTED["K"]].reshape(3, 3),
        "field_i": sd[REPORTED["field_i"]],
        "time_offset_s": sd[REPORTED["time_offset_s"]][0],
    }
