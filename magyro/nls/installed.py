"""The kernels compiled when magyro is installed, so that a machine's first solve compiles nothing.

`setup.py` calls `install_kernels` on the package being built. Installed are the kernels of both strides
magyro picks from (grid.STRIDES: 12, and 4 for sensors below 96 Hz), with
the time offset estimated, as `magyro solve`, `observe`, `--loss huber` and `--split-check` use them, without
and with the accelerometer (`--accelerometer`);
the loss, the rates, the gaps and the length of the session do not change a kernel. Other shapes are
compiled on first use and cached (kernels.py).
"""
from __future__ import annotations

from pathlib import Path

from magyro.nls.grid import STRIDES
from magyro.nls.kernels import build_libraries, find_compiler, generate_c, library_name
from magyro.nls.interval import (GAUSS_NEWTON_C, GAUSS_NEWTON_PRODUCTS, N_ACC_THETA, N_GLOBAL,
                                 accelerometer_jacobian_kernel, has_accelerometer, interval_kernels, kernel_key)


def installed_shapes() -> list[tuple[int, int, int, bool]]:
    """(stride, sub-steps, theta size, moving hard iron) of each installed kernel set (`kernel_key`'s arguments)."""
    return [(stride, 1, N_GLOBAL + 1 + acc, False) for stride in STRIDES for acc in (0, N_ACC_THETA)]


def install_kernels(folder: Path) -> list[Path]:
    """Compile the installed kernels into `folder`, the compilers side by side; the libraries made.
    Nothing (and no error) without a C compiler: the first solve then compiles, or interprets."""
    if find_compiler() is None:
        return []
    folder = Path(folder)
    jobs = [(GAUSS_NEWTON_C.encode(), folder / library_name(GAUSS_NEWTON_PRODUCTS, GAUSS_NEWTON_PRODUCTS))]
    for shape in installed_shapes():
        key = kernel_key(*shape)
        fns = interval_kernels(*shape) + ([accelerometer_jacobian_kernel(*shape)] if has_accelerometer(shape[2]) else [])
        jobs += [(generate_c(fn), folder / library_name(fn.name(), key)) for fn in fns]
    built = build_libraries(jobs)
    return [lib for (_, lib), ok in zip(jobs, built) if ok]
