"""The ``[accelerometer]`` section of a problem file (magyro.studies.scenario)."""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from magyro import so3
from magyro.options import STANDARD_GRAVITY_M_S2
from magyro.studies.problem_values import _non_negative, _positive, _upper_triangular, _vector3



@dataclass(frozen=True, eq=False)
class Accelerometer:
    """The ``[accelerometer]`` section: an accelerometer sampled at the gyro's times (docs/spec.md conventions).

    It measures the specific force f = a - g_vec (at rest f^w = (0, 0, +g)) in its own frame a:
    f^a = K_a y_a + eps_a, f^a = C_b^a f^b, so y_a = K_a^-1 (C_b^a C_w^b (a^w - g_vec) - eps_a) + n_a.
    The device's position moves by about `hand_translation_m` per world axis (`magyro.studies.simulate`).
    """

    K_a: np.ndarray                      # (3, 3) upper triangular, positive diagonal (scale, non-orthogonality)
    bias_m_s2: np.ndarray                # (3,) eps_a, accelerometer frame
    misalignment_euler_deg: np.ndarray   # (3,) [roll, pitch, yaw] of C_b^a (gyro -> accelerometer)
    noise_density_ug_sqrt_hz: float      # white noise density, micro-g per sqrt(Hz)
    g_m_s2: float = STANDARD_GRAVITY_M_S2   # the local gravity's magnitude
    hand_translation_m: float = 0.0      # peak of the device's position on each world axis (0: turned in place)
    hand_while_turning: bool = False     # a "turns" motion: the hand moves the device only while it turns, the held
                                         # poses truly still (magyro.studies.hand.turning_spans); False: it sways
                                         # through them too

    @property
    def C_b_a(self) -> np.ndarray:
        return so3.euler_to_dcm(self.misalignment_euler_deg)

    @property
    def noise_density_m_s2_sqrt_hz(self) -> float:
        return 1e-6 * STANDARD_GRAVITY_M_S2 * self.noise_density_ug_sqrt_hz

    def sample_std_m_s2(self, rate_hz: float) -> float:
        """Per-sample std of n_a at `rate_hz`: density * sqrt(rate), as the gyro's."""
        return self.noise_density_m_s2_sqrt_hz * math.sqrt(rate_hz)


ACCELEROMETER_KEYS = {"K_a": True, "bias_m_s2": True, "misalignment_euler_deg": False,
                      "noise_density_ug_sqrt_hz": True, "g_m_s2": False, "hand_translation_m": False,
                      "hand_while_turning": False}


def _parse_accelerometer(acc: dict, where: str) -> Accelerometer:
    return Accelerometer(
        K_a=_upper_triangular(acc["K_a"], where, "K_a"),
        bias_m_s2=_vector3(acc["bias_m_s2"], where, "bias_m_s2"),
        misalignment_euler_deg=_vector3(acc.get("misalignment_euler_deg", [0.0, 0.0, 0.0]), where,
                                        "misalignment_euler_deg"),
        noise_density_ug_sqrt_hz=_non_negative(acc["noise_density_ug_sqrt_hz"], where, "noise_density_ug_sqrt_hz"),
        g_m_s2=_positive(acc.get("g_m_s2", STANDARD_GRAVITY_M_S2), where, "g_m_s2"),
        hand_translation_m=_non_negative(acc.get("hand_translation_m", 0.0), where, "hand_translation_m"),
        hand_while_turning=_flag(acc.get("hand_while_turning", False), where, "hand_while_turning"),
    )


def _flag(value, where: str, key: str) -> bool:
    if not isinstance(value, bool):
        from magyro.errors import InputError

        raise InputError(f"{where}: {key} must be true or false, not {value!r}")
    return value
