"""The accelerometer's part of a calibration (JSON `accelerometer` and `std.accelerometer`; docs/spec.md section 4).

f^a = K_a y_a + eps_a in the accelerometer's frame a (m/s^2), f^a = C_b_a f^b; `apply` is the one place this is
evaluated. Its std: `misalignment_deg` is that of d in C_b_a(true) = C_b_a(est) Exp(d).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from magyro import so3
from magyro.errors import InputError
from magyro.result.parts import as_list, read_array, read_number

UPPER = [(0, 0), (0, 1), (0, 2), (1, 1), (1, 2), (2, 2)]
HAND_LIMIT_OF_G = 0.07   # the hand's RMS acceleration while turning above which gravity is not read (nls `hand_too_big`)
HAND_REACH_M = 0.5       # the device's position stays within this std (m) of where it is turned (nls `reach_cap`)


@dataclass
class AccelerometerCalibration:
    K_a: np.ndarray            # (3, 3) upper triangular: scale factors and non-orthogonality
    bias_m_s2: np.ndarray      # eps_a, added: f^a = K_a y_a + eps_a
    C_b_a: np.ndarray          # gyro frame to accelerometer frame
    g_m_s2: float              # the gravity it was calibrated against
    up_i: np.ndarray           # the up direction in frame i (the magnetometer frame at the start)
    std_K_a: np.ndarray        # (3, 3) upper
    std_bias_m_s2: np.ndarray
    std_misalignment_deg: np.ndarray
    lever_arm_m: np.ndarray | None = None       # from the point the device turned about, in the magnetometer's frame
    std_lever_arm_m: np.ndarray | None = None
    hand_rms_m_s2: float | None = None          # the hand's acceleration while turning, RMS per axis (nls `hand_motion`)

    @classmethod
    def from_reported(cls, K_a, bias_m_s2, C_b_a, g_m_s2, up_i, std_vector, lever_arm_m=None,
                      std_lever_arm_m=None) -> "AccelerometerCalibration":
        """From the parameters and the std of the reported vector (`magyro.nls.accelerometer.ACC_REPORTED`)."""
        std_K = np.zeros((3, 3))
        for k, (r, c) in enumerate(UPPER):
            std_K[r, c] = std_vector[k]
        return cls(np.asarray(K_a, float), np.asarray(bias_m_s2, float), np.asarray(C_b_a, float), float(g_m_s2),
                   np.asarray(up_i, float), std_K, np.asarray(std_vector[6:9], float), np.asarray(std_vector[9:12], float),
                   None if lever_arm_m is None else np.asarray(lever_arm_m, float),
                   None if std_lever_arm_m is None else np.asarray(std_lever_arm_m, float))

    @property
    def euler_deg(self) -> np.ndarray:
        """[roll, pitch, yaw] of C_b_a."""
        return so3.dcm_to_euler(self.C_b_a)

    def apply(self, acc_m_s2, frame: str = "a") -> np.ndarray:
        """The calibrated specific force (m/s^2): K_a y + eps_a in the accelerometer's frame (`frame="a"`), or turned
        into the gyro's (`frame="b"`). Rows are samples; the input is not changed."""
        f = np.asarray(acc_m_s2, dtype=float) @ self.K_a.T + self.bias_m_s2
        if frame == "a":
            return f
        if frame == "b":
            return f @ self.C_b_a     # C_b_a^T f per row
        raise InputError(f"unknown frame '{frame}' for the accelerometer; use a (its own) or b (the gyro's)")

    def to_dict(self) -> dict:
        return {"K_a": as_list(self.K_a), "bias_m_s2": as_list(self.bias_m_s2), "C_b_a": as_list(self.C_b_a),
                "euler_deg": as_list(self.euler_deg), "g_m_s2": float(self.g_m_s2), "up_i": as_list(self.up_i),
                **({} if self.lever_arm_m is None else {"lever_arm_m": as_list(self.lever_arm_m)}),
                **({} if self.hand_rms_m_s2 is None else {"hand_rms_m_s2": float(self.hand_rms_m_s2)})}

    def std_dict(self) -> dict:
        return {"K_a": as_list(self.std_K_a), "bias_m_s2": as_list(self.std_bias_m_s2),
                "misalignment_deg": as_list(self.std_misalignment_deg),
                **({} if self.std_lever_arm_m is None else {"lever_arm_m": as_list(self.std_lever_arm_m)})}

    @classmethod
    def from_dict(cls, data: dict, std: dict | None) -> "AccelerometerCalibration":
        where = "accelerometer"
        C = read_array(data, "C_b_a", (3, 3), where)
        if not np.allclose(C.T @ C, np.eye(3), atol=1e-6) or np.linalg.det(C) < 0:
            raise InputError("accelerometer.C_b_a is not a proper rotation matrix")
        std = std or {}
        zero = lambda name, shape: (read_array(std, name, shape, "std.accelerometer") if name in std else np.zeros(shape))
        return cls(read_array(data, "K_a", (3, 3), where), read_array(data, "bias_m_s2", (3,), where), C,
                   read_number(data, "g_m_s2", where, finite=True),
                   read_array(data, "up_i", (3,), where) if "up_i" in data else np.array([0.0, 0.0, 1.0]),
                   zero("K_a", (3, 3)), zero("bias_m_s2", (3,)), zero("misalignment_deg", (3,)),
                   read_array(data, "lever_arm_m", (3,), where) if "lever_arm_m" in data else None,
                   zero("lever_arm_m", (3,)) if "lever_arm_m" in data else None,
                   read_number(data, "hand_rms_m_s2", where, finite=True) if "hand_rms_m_s2" in data else None)

    @property
    def gravity_source(self) -> str:
        """Where `g_m_s2` came from, in words: the standard gravity (the default), or a value given with --gravity."""
        from magyro.options import STANDARD_GRAVITY_M_S2

        if self.g_m_s2 == STANDARD_GRAVITY_M_S2:
            return "standard gravity, the default; --gravity gives the local value"
        return "given with --gravity"

    def table_lines(self) -> list[str]:
        lines = ["accelerometer K_a (scale on diagonal, non-orthogonality above), +/- 1 sigma"]
        for i in range(3):
            cells = [" " * 22 if j < i else f"{self.K_a[i, j]:9.5f} +/- {self.std_K_a[i, j]:8.5f}" for j in range(3)]
            lines.append("  " + "  ".join(cells))
        b, sb = self.bias_m_s2, self.std_bias_m_s2
        lines.append("accelerometer bias (m/s^2)  " + "  ".join(f"{b[i]:+8.4f} +/- {sb[i]:.4f}" for i in range(3)))
        e, se = self.euler_deg, self.std_misalignment_deg
        lines.append("misalignment C_b_a, roll pitch yaw (deg)  "
                     + "  ".join(f"{e[i]:+8.3f} +/- {se[i]:.3f}" for i in range(3)))
        if self.lever_arm_m is not None:
            lines.append("turned about a point, lever arm (cm, magnetometer frame)  " + "  ".join(
                f"{100 * self.lever_arm_m[i]:+.1f} +/- {100 * self.std_lever_arm_m[i]:.1f}" for i in range(3)))
        if self.hand_rms_m_s2 is not None:
            lines.append(f"the hand accelerated the device by {self.hand_rms_m_s2:.2f} m/s^2 RMS while turning "
                         f"(refused above {100 * HAND_LIMIT_OF_G:g} % of g, {HAND_LIMIT_OF_G * self.g_m_s2:.2f})")
        lines.append(f"gravity {self.g_m_s2:.5f} m/s^2 ({self.gravity_source})")
        return lines
