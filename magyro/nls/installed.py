"""The kernels compiled when magyro is installed, so that a machine's first solve compiles nothing.

`setup.py` calls `install_kernels` on the package being built. Installed are the kernels of both strides
magyro picks from (grid.STRIDES: 12, and 4 for sensors below 96 Hz), with the time offset estimated, in the
three forms the default commands use them:

    magnetometer and gyro alone   `--no-accelerometer`, a session without one, `observe`, and the room's
                                  sandwich of every solve with the accelerometer (problem.magnetometer_jacobian_kernel)
    with the accelerometer        the default solve's first pass; `--no-hand-states`, or a hand too small to find
    with the hand's velocity      the default solve's passes once its first pass found the hand (run.py,
    as states                     solve_with_hand_states): `magyro solve data/broad-02.parquet` as the README runs it

each with the Jacobian of the accelerometer's interval means where the accelerometer is in. `--loss huber` and
`--split-check` use the same kernels (the loss is a parameter; a half is a shorter session); the rates, the gaps and
the length of the session do not change a kernel. Other shapes (a stride of the user's, a moving hard iron, no time
offset) are compiled on first use and cached (kernels.py).
"""
from __future__ import annotations

from pathlib import Path

from magyro.nls.grid import STRIDES
from magyro.nls.kernels import build_libraries, find_compiler, generate_c, library_name
from magyro.nls.interval import (GAUSS_NEWTON_C, GAUSS_NEWTON_PRODUCTS, N_ACC_THETA, N_GLOBAL,
                                 accelerometer_jacobian_kernel, has_accelerometer, interval_kernels, kernel_key)

N_THETA_TIME_OFFSET = N_GLOBAL + 1   # the calibration's corrections with the time offset, without the accelerometer

# (theta size, hand's velocity as states) of the three forms above
INSTALLED_FORMS = ((N_THETA_TIME_OFFSET, False), (N_THETA_TIME_OFFSET + N_ACC_THETA, False),
                   (N_THETA_TIME_OFFSET + N_ACC_THETA, True))


def installed_shapes() -> list[tuple[int, int, int, bool, bool]]:
    """(stride, sub-steps, theta size, moving hard iron, hand states) of each installed kernel set (`kernel_key`'s
    arguments)."""
    return [(stride, 1, n_theta, False, hand) for stride in STRIDES for n_theta, hand in INSTALLED_FORMS]


def install_kernels(folder: Path) -> list[Path]:
    """Compile the installed kernels into `folder`, the compilers side by side; the libraries made.
    Nothing (and no error) without a C compiler: the first solve then compiles, or interprets."""
    if find_compiler() is None:
        return []
    folder = Path(folder)
    jobs = [(GAUSS_NEWTON_C.encode(), folder / library_name(GAUSS_NEWTON_PRODUCTS, GAUSS_NEWTON_PRODUCTS))]
    for shape in installed_shapes():
        key = kernel_key(*shape)
        jobs += [(generate_c(fn), folder / library_name(fn.name(), key)) for fn in shape_kernels(shape)]
    built = build_libraries(jobs)
    return [lib for (_, lib), ok in zip(jobs, built) if ok]


def shape_kernels(shape: tuple[int, int, int, bool, bool]) -> list:
    """The SX kernels of one installed shape: the interval's three, and the accelerometer means' Jacobian with it."""
    with_accelerometer = has_accelerometer(shape[2])
    return interval_kernels(*shape) + ([accelerometer_jacobian_kernel(*shape)] if with_accelerometer else [])
