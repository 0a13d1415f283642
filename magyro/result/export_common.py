"""What every export format shares (issue 12, 25): the model's lines, exact numbers, and the checks that keep a
non-finite or singular calibration from being written for another program."""
from __future__ import annotations

import numpy as np

from magyro.errors import InputError
from magyro.result.applicable import singular_matrix

MODEL_LINES = (
    "gyro, frame b:  w_b = K_g y + eps_b   (rad/s, gyro frame; the bias is ADDED: not y - b)",
    "gyro, frame m:  w_m = K y + eps       (rad/s, magnetometer frame; K = C_b_m K_g, eps = C_b_m eps_b)",
    "magnetometer:   m_m = R (y_m - h)     (unitless, unit norm; h in the magnetometer's unit)",
    "y: raw gyro in rad/s; y_m: raw magnetometer in its unit; matrices are row-major, [row][column]",
)
# added after MODEL_LINES when the calibration has an accelerometer (magyro solve --accelerometer)
ACC_MODEL_LINES = (
    "accelerometer:  f_a = K_a y_a + eps_a (m/s^2, accelerometer frame a; the bias is ADDED: not y_a - b)",
    "                f_b = C_b_a^T f_a     (m/s^2, gyro frame b; f_m = C_b_m f_b); y_a: raw accelerometer in m/s^2",
)


def model_lines(cal) -> tuple:
    """The model's comment lines for `cal`: MODEL_LINES, and ACC_MODEL_LINES when it has an accelerometer."""
    return MODEL_LINES + (ACC_MODEL_LINES if cal.accelerometer is not None else ())


def yaml_number(x: float) -> str:
    """17 significant digits, always with a '.' and an exponent: a float in YAML 1.1 and 1.2, and in JSON.
    InputError for a number that is not finite: nothing non-finite is ever exported."""
    x = float(x)
    if not np.isfinite(x):
        raise InputError("the export would hold a number that is not finite; nothing exported")
    return f"{x:.16e}"


def yaml_array(a) -> str:
    a = np.asarray(a, dtype=float)
    if a.ndim == 1:
        return "[" + ", ".join(yaml_number(v) for v in a) + "]"
    return "[" + ", ".join(yaml_array(row) for row in a) + "]"


def check_finite(cal) -> None:
    """InputError when any exported number of the calibration is not finite, or when K_g or R (or the accelerometer's
    K_a) is singular (every format checks this first: a singular matrix has no inverse for the tools, nor a field
    strength)."""
    if not np.all(np.isfinite(np.concatenate([np.ravel(a) for a in (cal.K_g, cal.bias_rad_s, cal.C_b_m, cal.K,
                                                                       cal.eps_rad_s, cal.R, cal.h)]))):
        raise InputError("the calibration holds a number that is not finite; nothing to export")
    acc = cal.accelerometer
    if acc is not None:
        if not np.all(np.isfinite(np.concatenate([np.ravel(a) for a in (acc.K_a, acc.bias_m_s2, acc.C_b_a,
                                                                           [acc.g_m_s2])]))):
            raise InputError("the calibration's accelerometer holds a number that is not finite; nothing to export")
    singular = singular_matrix(cal)
    if singular is not None:
        raise InputError(f"{singular}: it cannot be inverted; nothing to export")
