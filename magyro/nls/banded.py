"""The banded Cholesky of the attitude block (`reduction.reduce_hessian`): LAPACK's dpbtrf / dpbtrs.

Called straight from the LAPACK that numpy's wheel ships (OpenBLAS, 64-bit integers, through ctypes), since
importing scipy.linalg for them cost 0.27 s of every solve's start-up (a 100 s session's whole solve is ~1 s).
Where numpy has no such library (another build of numpy), scipy's wrappers of the same routines are used.
Both take and give LAPACK's upper banded form: ab[u + i - j, j] = D[i, j] for i <= j, u + 1 rows.
"""
from __future__ import annotations

import ctypes
import glob
import os

import numpy as np

COL_MAJOR = 102


def _numpy_lapack():
    """(dpbtrf, dpbtrs) of numpy's bundled OpenBLAS (LAPACKE, 64-bit integers), or None."""
    folder = os.path.join(os.path.dirname(os.path.dirname(np.__file__)), "numpy.libs")
    for path in sorted(glob.glob(os.path.join(folder, "libscipy_openblas64_*.so"))):
        try:
            lib = ctypes.CDLL(path)
            trf, trs = lib.scipy_LAPACKE_dpbtrf64_, lib.scipy_LAPACKE_dpbtrs64_
        except (OSError, AttributeError):
            continue
        i64, dbl = ctypes.c_int64, ctypes.POINTER(ctypes.c_double)
        trf.argtypes = [ctypes.c_int, ctypes.c_char, i64, i64, dbl, i64]
        trf.restype = i64
        trs.argtypes = [ctypes.c_int, ctypes.c_char, i64, i64, i64, dbl, i64, dbl, i64]
        trs.restype = i64
        return trf, trs
    return None


_LAPACK = _numpy_lapack()


def _pointer(a: np.ndarray):
    return a.ctypes.data_as(ctypes.POINTER(ctypes.c_double))


def cholesky_banded(ab: np.ndarray) -> np.ndarray:
    """The upper Cholesky factor of a symmetric positive definite banded matrix, in the same banded form;
    np.linalg.LinAlgError when it is not positive definite (as scipy.linalg.cholesky_banded)."""
    if _LAPACK is None:
        from scipy.linalg import cholesky_banded as scipy_cholesky_banded
        return scipy_cholesky_banded(ab)
    kd, n = ab.shape[0] - 1, ab.shape[1]
    factor = np.array(ab.T, dtype=float, order="C")   # column-major (kd + 1) x n, as LAPACK reads it
    info = _LAPACK[0](COL_MAJOR, b"U", n, kd, _pointer(factor), kd + 1)
    if info != 0:
        raise np.linalg.LinAlgError(f"banded Cholesky: leading minor {info} is not positive definite" if info > 0
                                    else f"banded Cholesky: argument {-info} is wrong")
    return factor.T


def cho_solve_banded(factor_and_lower, b: np.ndarray) -> np.ndarray:
    """x with D x = b, D given by its upper banded Cholesky factor (as scipy.linalg.cho_solve_banded)."""
    factor, lower = factor_and_lower
    if _LAPACK is None or lower:
        from scipy.linalg import cho_solve_banded as scipy_cho_solve_banded
        return scipy_cho_solve_banded(factor_and_lower, b)
    kd, n = factor.shape[0] - 1, factor.shape[1]
    b = np.asarray(b, dtype=float)
    columns = b.reshape(n, -1)
    x = np.array(columns.T, order="C")                # column-major n x nrhs
    ab = np.ascontiguousarray(factor.T)
    info = _LAPACK[1](COL_MAJOR, b"U", n, kd, columns.shape[1], _pointer(ab), kd + 1, _pointer(x), n)
    if info != 0:
        raise np.linalg.LinAlgError(f"banded solve: argument {-info} is wrong")
    return x.T.reshape(b.shape)
