"""The checked values of a problem file: numbers, vectors and matrices, each refused with where and what it must be."""
from __future__ import annotations

import math

import numpy as np

from magyro.errors import InputError


def _number(value, where: str, key: str) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
        raise InputError(f"{where}: {key} must be a finite number, got {value!r}")
    return float(value)


def _positive(value, where: str, key: str) -> float:
    x = _number(value, where, key)
    if x <= 0:
        raise InputError(f"{where}: {key} must be positive, got {value!r}")
    return x


def _non_negative(value, where: str, key: str) -> float:
    x = _number(value, where, key)
    if x < 0:
        raise InputError(f"{where}: {key} must be non-negative, got {value!r}")
    return x


def _string(value, where: str, key: str) -> str:
    if not isinstance(value, str):
        raise InputError(f"{where}: {key} must be a string, got {value!r}")
    return value


def _vector(value, where: str, key: str, n: int) -> np.ndarray:
    if not isinstance(value, list) or len(value) != n:
        raise InputError(f"{where}: {key} must be a list of {n} numbers, got {value!r}")
    return np.array([_number(v, where, key) for v in value])


def _vector3(value, where: str, key: str) -> np.ndarray:
    return _vector(value, where, key, 3)


def _upper_triangular(value, where: str, key: str) -> np.ndarray:
    if not isinstance(value, list) or len(value) != 3 or any(not isinstance(r, list) for r in value):
        raise InputError(f"{where}: {key} must be a 3x3 list of lists, got {value!r}")
    M = np.array([_vector3(row, where, key) for row in value])
    if np.any(np.tril(M, -1) != 0.0):
        raise InputError(f"{where}: {key} must be upper triangular (zeros below the diagonal), got {M.tolist()}")
    if np.any(np.diag(M) <= 0.0):
        raise InputError(f"{where}: {key} must have a positive diagonal, got {np.diag(M).tolist()}")
    return M
