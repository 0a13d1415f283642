"""Small fast helpers of the filter, in scalar arithmetic.

The filter runs once per sample in Python: 3-vectors and 3x3 blocks are done
in plain floats, matrices as row-major 9-tuples (a numpy call costs more than
the arithmetic itself). `exp9` repeats `so3.exp_so3` for one vector: it is
kept for speed.
"""
from __future__ import annotations

import math

import numpy as np


def exp9(x: float, y: float, z: float) -> tuple:
    """Exp of one rotation vector (Rodrigues) as a row-major 9-tuple.

    The same maths and small-angle branch as `so3.exp_so3`, in scalar
    arithmetic: this runs at every gyro sample.
    """
    th2 = x * x + y * y + z * z
    if th2 < 1e-12:
        a, b = 1.0 - th2 / 6.0, 0.5 - th2 / 24.0
    else:
        th = math.sqrt(th2)
        a, b = math.sin(th) / th, (1.0 - math.cos(th)) / th2
    bxy, bxz, byz = b * x * y, b * x * z, b * y * z
    return (1.0 - b * (y * y + z * z), bxy - a * z, bxz + a * y,
            bxy + a * z, 1.0 - b * (x * x + z * z), byz - a * x,
            bxz - a * y, byz + a * x, 1.0 - b * (x * x + y * y))


def mul33(A, B) -> tuple:
    """Product of two row-major 9-tuples."""
    a11, a12, a13, a21, a22, a23, a31, a32, a33 = A
    b11, b12, b13, b21, b22, b23, b31, b32, b33 = B
    return (a11 * b11 + a12 * b21 + a13 * b31, a11 * b12 + a12 * b22 + a13 * b32, a11 * b13 + a12 * b23 + a13 * b33,
            a21 * b11 + a22 * b21 + a23 * b31, a21 * b12 + a22 * b22 + a23 * b32, a21 * b13 + a22 * b23 + a23 * b33,
            a31 * b11 + a32 * b21 + a33 * b31, a31 * b12 + a32 * b22 + a33 * b32, a31 * b13 + a32 * b23 + a33 * b33)


def inv_sym33(S: np.ndarray) -> tuple:
    """Inverse of a symmetric positive definite 3x3 (cofactors): (its 6 distinct entries, the matrix, det S)."""
    (a, b, c), (_, e, f), (_, _, i) = S.tolist()
    A, B, C = e * i - f * f, c * f - b * i, b * f - c * e
    det = a * A + b * B + c * C
    k = 1.0 / det
    A, B, C, E, F, I = A * k, B * k, C * k, (a * i - c * c) * k, (b * c - a * f) * k, (a * e - b * b) * k
    return (A, B, C, E, F, I), np.array([[A, B, C], [B, E, F], [C, F, I]]), det


def carry_basis(B, m) -> np.ndarray:
    """The basis B moved to the plane normal to the unit vector m, staying closest to B (Gram-Schmidt).

    B_new^T B_old = I + O(|dm|^2), so the tangent coordinates need no reset to first order.
    """
    (p1, q1), (p2, q2), (p3, q3) = B.tolist()
    m1, m2, m3 = m
    k = m1 * p1 + m2 * p2 + m3 * p3
    a1, a2, a3 = p1 - k * m1, p2 - k * m2, p3 - k * m3
    n = 1.0 / math.sqrt(a1 * a1 + a2 * a2 + a3 * a3)
    a1, a2, a3 = a1 * n, a2 * n, a3 * n
    k = m1 * q1 + m2 * q2 + m3 * q3
    l = a1 * q1 + a2 * q2 + a3 * q3
    b1, b2, b3 = q1 - k * m1 - l * a1, q2 - k * m2 - l * a2, q3 - k * m3 - l * a3
    n = 1.0 / math.sqrt(b1 * b1 + b2 * b2 + b3 * b3)
    return np.array([[a1, b1 * n], [a2, b2 * n], [a3, b3 * n]])
