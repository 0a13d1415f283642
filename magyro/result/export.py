"""A calibration exported for other programs (issue 12): a plain YAML file, or a C99 header.

Both carry the model of docs/spec.md section 1 with every number written so that it reads back
to the same double:

    gyro, frame b:   w_b = K_g y + eps_b      (rad/s; the bias is ADDED, not subtracted)
    gyro, frame m:   w_m = K y + eps          (K = C_b_m K_g, eps = C_b_m eps_b)
    magnetometer:    m_m = R (y_m - h)        (unit norm; h in the magnetometer's unit)
    accelerometer:   f_a = K_a y_a + eps_a    (m/s^2, when the calibration has one; f_b = C_b_a^T f_a)

`export_text(cal, "yaml" | "c" | "kalibr" | "px4" | "ardupilot", source=...)` returns the text; `magyro export`
writes it. The formats of other tools (Kalibr's scale-misalignment IMU yaml, a PX4 .params file) are in
magyro/result/export_tools.py, ArduPilot's parameter file in magyro/result/export_ardupilot.py, with their
mappings and what they cannot hold.
"""
from __future__ import annotations

import json

import numpy as np

from magyro.errors import InputError
from magyro.result.calibration import SCHEMA, Calibration
from magyro.result.export_common import MODEL_LINES, check_finite, model_lines, yaml_array, yaml_number  # noqa: F401 (API)
from magyro.result.export_ardupilot import ardupilot_text
from magyro.result.export_tools import kalibr_text, px4_text
from magyro.text import c_comment

FORMATS = ("yaml", "c", "kalibr", "px4", "ardupilot")

def export_text(cal: Calibration, fmt: str, source: str = "") -> str:
    """The calibration as text in format `fmt` (one of FORMATS); `source` names where it came from."""
    if fmt == "yaml":
        return yaml_text(cal, source)
    if fmt == "c":
        return c_header(cal, source)
    if fmt in ("kalibr", "px4"):
        return (kalibr_text if fmt == "kalibr" else px4_text)(cal, source)
    if fmt == "ardupilot":
        return ardupilot_text(cal, source)
    raise InputError(f"unknown export format '{fmt}'; use one of: {', '.join(FORMATS)}")


# --------------------------------------------------------------------------- YAML


def yaml_text(cal: Calibration, source: str = "") -> str:
    """A plain YAML file: the model in comments, then the parameters (flow-style lists, row-major matrices)."""
    check_finite(cal)
    lines = ["# magyro calibration, exported for other programs (magyro export --format yaml)",
             *(f"# {line}" for line in model_lines(cal)),
             "# Every number reads back to the same double.",
             f"schema: {json.dumps(SCHEMA)}",
             f"source: {json.dumps(str(source))}",
             "gyro:",
             "  # w_b = K_g y + bias_rad_s; K_g upper triangular (scale on the diagonal, non-orthogonality above)",
             f"  K_g: {yaml_array(cal.K_g)}",
             f"  bias_rad_s: {yaml_array(cal.bias_rad_s)}",
             "  # w_m = K y + eps_rad_s, the same rates in the magnetometer frame",
             f"  K: {yaml_array(cal.K)}",
             f"  eps_rad_s: {yaml_array(cal.eps_rad_s)}",
             "misalignment:",
             "  # C_b_m turns gyro-frame vectors into magnetometer-frame vectors: w_m = C_b_m w_b",
             f"  C_b_m: {yaml_array(cal.C_b_m)}",
             "magnetometer:",
             "  # m_m = R (y_m - h); R upper triangular, in 1/unit; h in unit",
             f"  unit: {json.dumps(cal.mag_unit)}",
             f"  R: {yaml_array(cal.R)}",
             f"  h: {yaml_array(cal.h)}",
             ]
    acc = cal.accelerometer
    if acc is not None:
        lines += ["accelerometer:",
                  "  # f_a = K_a y_a + bias_m_s2 (m/s^2, accelerometer frame a); K_a upper triangular (scale on the",
                  "  # diagonal, non-orthogonality above); the bias is ADDED",
                  f"  K_a: {yaml_array(acc.K_a)}",
                  f"  bias_m_s2: {yaml_array(acc.bias_m_s2)}",
                  "  # C_b_a turns gyro-frame vectors into accelerometer-frame vectors: f_a = C_b_a f_b, f_b = C_b_a^T f_a",
                  f"  C_b_a: {yaml_array(acc.C_b_a)}",
                  "  # the gravity, m/s^2, the accelerometer was calibrated against",
                  f"  g_m_s2: {yaml_number(acc.g_m_s2)}",
                  ]
    return "\n".join(lines) + "\n"


# --------------------------------------------------------------------------- C99 header


def _c_number(x: float) -> str:
    """The shortest decimal that reads back to the same double (C99 strtod rounds correctly)."""
    x = float(x)
    if not np.isfinite(x):
        raise InputError("the export would hold a number that is not finite; nothing exported")
    text = repr(x)
    return text if any(c in text for c in ".e") else text + ".0"


def _c_array(a) -> str:
    a = np.asarray(a, dtype=float)
    if a.ndim == 1:
        return "{" + ", ".join(_c_number(v) for v in a) + "}"
    return "{\n    " + ",\n    ".join(_c_array(row) for row in a) + "\n}"


def c_header(cal: Calibration, source: str = "") -> str:
    """A C99 header: `static const double` parameters and `static inline` apply functions, no allocation."""
    check_finite(cal)
    arrays = (("magyro_K_g", cal.K_g, "[3][3]", "gyro scale and non-orthogonality, upper triangular"),
              ("magyro_bias_rad_s", cal.bias_rad_s, "[3]", "eps_b, rad/s, ADDED: w_b = K_g y + eps_b"),
              ("magyro_K", cal.K, "[3][3]", "C_b_m K_g"),
              ("magyro_eps_rad_s", cal.eps_rad_s, "[3]", "eps = C_b_m eps_b, rad/s"),
              ("magyro_C_b_m", cal.C_b_m, "[3][3]", "gyro frame to magnetometer frame"),
              ("magyro_R", cal.R, "[3][3]", f"magnetometer soft iron, 1/{c_comment(cal.mag_unit)}"),
              ("magyro_h", cal.h, "[3]", f"magnetometer hard iron, {c_comment(cal.mag_unit)}"))
    lines = ["/* magyro calibration, exported for other programs (magyro export --format c).",
             f" * source: {c_comment(source)}",
             f" * magnetometer unit: {c_comment(cal.mag_unit)}",
             *(f" *   {c_comment(line)}" for line in model_lines(cal)),
             " * C99, no allocation; include it in one or more .c files. */",
             "#ifndef MAGYRO_CALIBRATION_H",
             "#define MAGYRO_CALIBRATION_H",
             ""]
    acc = cal.accelerometer
    if acc is not None:
        arrays += (("magyro_K_a", acc.K_a, "[3][3]", "accelerometer scale and non-orthogonality, upper triangular"),
                   ("magyro_bias_m_s2", acc.bias_m_s2, "[3]", "eps_a, m/s^2, ADDED: f_a = K_a y_a + eps_a"),
                   ("magyro_C_b_a", acc.C_b_a, "[3][3]", "gyro frame to accelerometer frame: f_a = C_b_a f_b"))
    for name, value, shape, what in arrays:
        lines.append(f"/* {what} */")
        lines.append(f"static const double {name}{shape} = {_c_array(value)};")
    if acc is not None:
        lines.append("/* the gravity the accelerometer was calibrated against, m/s^2 */")
        lines.append(f"static const double magyro_g_m_s2 = {_c_number(acc.g_m_s2)};")
    lines += ["",
              "/* w = M y + b for a 3x3 M and 3-vectors y, b */",
              "static inline void magyro_affine3(const double M[3][3], const double y[3], const double b[3], double w[3])",
              "{",
              "    int i;",
              "    for (i = 0; i < 3; ++i) {",
              "        w[i] = M[i][0] * y[0] + M[i][1] * y[1] + M[i][2] * y[2] + b[i];",
              "    }",
              "}",
              "",
              "/* calibrated rate in the gyro frame b: w = K_g y + eps_b (rad/s in, rad/s out) */",
              "static inline void magyro_apply_gyro(const double y[3], double w[3])",
              "{",
              "    magyro_affine3(magyro_K_g, y, magyro_bias_rad_s, w);",
              "}",
              "",
              "/* calibrated rate in the magnetometer frame m: w = K y + eps (rad/s in, rad/s out) */",
              "static inline void magyro_apply_gyro_m(const double y[3], double w[3])",
              "{",
              "    magyro_affine3(magyro_K, y, magyro_eps_rad_s, w);",
              "}",
              "",
              "/* calibrated field in the magnetometer frame: m = R (y_m - h), unit norm */",
              "static inline void magyro_apply_mag(const double y_m[3], double m[3])",
              "{",
              "    const double d[3] = {y_m[0] - magyro_h[0], y_m[1] - magyro_h[1], y_m[2] - magyro_h[2]};",
              "    const double zero[3] = {0.0, 0.0, 0.0};",
              "    magyro_affine3(magyro_R, d, zero, m);",
              "}",
              ""]
    if acc is not None:
        lines += ["/* calibrated specific force in the accelerometer frame a: f_a = K_a y_a + eps_a (m/s^2 in, m/s^2 out) */",
                  "static inline void magyro_apply_acc(const double y_a[3], double f_a[3])",
                  "{",
                  "    magyro_affine3(magyro_K_a, y_a, magyro_bias_m_s2, f_a);",
                  "}",
                  "",
                  "/* calibrated specific force in the gyro frame b: f_b = C_b_a^T (K_a y_a + eps_a) (m/s^2) */",
                  "static inline void magyro_apply_acc_b(const double y_a[3], double f_b[3])",
                  "{",
                  "    double f_a[3];",
                  "    int i;",
                  "    magyro_apply_acc(y_a, f_a);",
                  "    for (i = 0; i < 3; ++i) {",
                  "        f_b[i] = magyro_C_b_a[0][i] * f_a[0] + magyro_C_b_a[1][i] * f_a[1] + magyro_C_b_a[2][i] * f_a[2];",
                  "    }",
                  "}",
                  "",
                  "/* calibrated specific force in the magnetometer frame m: f_m = C_b_m C_b_a^T (K_a y_a + eps_a) (m/s^2) */",
                  "static inline void magyro_apply_acc_m(const double y_a[3], double f_m[3])",
                  "{",
                  "    double f_b[3];",
                  "    const double zero[3] = {0.0, 0.0, 0.0};",
                  "    magyro_apply_acc_b(y_a, f_b);",
                  "    magyro_affine3(magyro_C_b_m, f_b, zero, f_m);",
                  "}",
                  ""]
    lines.append("#endif /* MAGYRO_CALIBRATION_H */")
    return "\n".join(lines) + "\n"
