"""The solver kernels: a small fixed set, compiled when magyro is installed, shared by every session shape.

Issue 14: every new rate, `--loss huber` and `observe` used to compile kernels of their own (one user's
cache held 21 after half an hour), and the first solve waited 10-20 s for a compiler.
"""
from __future__ import annotations

import dataclasses
import os
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

import magyro
from magyro.nls.grid import build_grid
from magyro.nls.hand_states import hand_prior
from magyro.nls.installed import installed_shapes
from magyro.nls.interval import kernel_key
from magyro.nls.problem import JointProblem
from magyro.nls.solve import default_stride

DATA = Path(__file__).resolve().parents[1] / "data"


def default_problem(session, **problem_options) -> JointProblem:
    grid = build_grid(session.t_gyro_s, session.gyro_rad_s, session.t_mag_s, default_stride(session))
    return JointProblem(grid, compiled=False, **problem_options)


def resampled(session, gyro_hz: float, mag_hz: float, offset_s: float = 0.0):
    """The session with its gyro and magnetometer taken at other rates (nearest sample), stamps on other clocks."""
    def at(t, t_new, values):
        return values[np.clip(np.searchsorted(t, t_new), 0, len(t) - 1)]
    t0, t1 = session.t_gyro_s[0], session.t_gyro_s[-1]
    t_gyro = np.arange(t0, t1, 1 / gyro_hz)
    t_mag = np.arange(t0 + offset_s, t1, 1 / mag_hz)
    return dataclasses.replace(session, t_gyro_s=t_gyro, gyro_rad_s=at(session.t_gyro_s, t_gyro, session.gyro_rad_s),
                               t_mag_s=t_mag, mag=at(session.t_mag_s, t_mag, session.mag))


@pytest.fixture(scope="module")
def broad02():
    return magyro.load_session(DATA / "broad-02.parquet")


@pytest.mark.parametrize("rates", [None, (100, 100), (200, 50, 0.0013), (50, 50), (1000, 100, 0.0021)])
def test_the_usual_rates_need_only_installed_kernels(broad02, rates):
    """BROAD's 285.7 Hz, the paper's 100 Hz, a phone's 200/50 Hz on two clocks, 50 Hz, a 1 kHz gyro: every default
    problem, with either loss, is one of the installed shapes; so is the half of a split check."""
    installed = {kernel_key(*shape) for shape in installed_shapes()}
    session = broad02 if rates is None else resampled(broad02, *rates)
    for huber in (None, 3.0):
        assert default_problem(session, huber=huber).kernel_key in installed, (rates, huber)
    half = dataclasses.replace(session, t_gyro_s=session.t_gyro_s[: len(session.t_gyro_s) // 2],
                               gyro_rad_s=session.gyro_rad_s[: len(session.t_gyro_s) // 2])
    assert default_problem(half).kernel_key in installed


@pytest.mark.parametrize("rates", [None, (50, 50)])
def test_the_hand_states_need_only_installed_kernels(broad02, rates):
    """The default solve's passes with the hand's velocity as states (issue 40: they compiled on first use), on
    BROAD 02 as the README solves it (stride 12) and at 50 Hz (stride 4). Its first pass, without them, is one of
    the installed shapes too (`installed.INSTALLED_FORMS`; the installed wheel's test below runs both)."""
    installed = {kernel_key(*shape) for shape in installed_shapes()}
    session = broad02 if rates is None else resampled(broad02, *rates)
    assert default_problem(session, accelerometer=True, hand_prior=hand_prior(1.0)).kernel_key in installed


def test_the_phone_module_and_broad_share_one_kernel_set(broad02):
    phone = magyro.load_session(DATA / "simulated-phone-module.parquet")
    assert default_problem(phone).kernel_key == default_problem(broad02).kernel_key


def test_other_shapes_are_not_installed_and_say_what_they_are(broad02):
    installed = {kernel_key(*shape) for shape in installed_shapes()}
    assert default_problem(broad02, walk_density=1.0).kernel_key not in installed
    assert default_problem(broad02, estimate_time_offset=False).kernel_key not in installed


README_FIRST_SOLVE = ["solve", "data/broad-02.parquet", "-o", "calib.json"]   # the README's first command


def installed_magyro(cwd: Path) -> tuple[Path | None, str]:
    """(the `magyro` script beside sys.executable, '') when it runs magyro as a wheel installs it, its kernels
    compiled into the package; else (None, why not). Probed from `cwd`, outside the checkout, as the script imports."""
    script = Path(sys.executable).with_name("magyro")
    if not script.exists():
        return None, f"no magyro script beside {Path(sys.executable).name}"
    probe = ("import pathlib, magyro.nls.kernels as k; package = pathlib.Path(k.__file__).parents[2]; "
             "print((package / 'pyproject.toml').exists(), any(k.INSTALLED.glob('*.so')))")
    done = subprocess.run([sys.executable, "-c", probe], cwd=cwd, capture_output=True, text=True,
                          env=without_source_path())
    if done.returncode != 0:
        return None, f"magyro does not import: {done.stderr.strip().splitlines()[-1:]}"
    source_tree, has_kernels = (word == "True" for word in done.stdout.split())
    if source_tree:
        return None, "magyro is imported from a source tree (an editable install), which compiles on first use"
    if not has_kernels:
        return None, "the installed magyro holds no compiled kernels (installed without a C compiler)"
    return script, ""


def without_source_path() -> dict:
    """The environment, less what would put the checkout's magyro (PYTHONPATH), interpreted kernels (MAGYRO_JIT) or
    another kernel cache in place of the installed magyro and its kernels."""
    return {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH", "MAGYRO_JIT", "MAGYRO_CACHE_DIR")}


def test_the_readme_first_solve_compiles_nothing_in_a_fresh_install(tmp_path):
    """Issue 40: the README's first command, `magyro solve data/broad-02.parquet -o calib.json` with its defaults
    (the accelerometer in, and on BROAD 02 the hand's velocity as states), run by the installed `magyro` on an empty
    kernel cache, compiles 0 kernels: every kernel it uses was compiled when the wheel was installed. It compiled 4
    (the hand states' kernels) before they were installed."""
    script, why_not = installed_magyro(tmp_path)
    if script is None:
        pytest.skip(f"needs magyro installed as a wheel (`pip install .`, as .ci/run does): {why_not}")
    (tmp_path / "data").mkdir()
    shutil.copy(DATA / "broad-02.parquet", tmp_path / "data")
    cache = tmp_path / "cache"
    done = subprocess.run([str(script), *README_FIRST_SOLVE], cwd=tmp_path, capture_output=True, text=True,
                          env={**without_source_path(), "MAGYRO_CACHE_DIR": str(cache)})
    assert done.returncode == 0, done.stderr
    assert (tmp_path / "calib.json").exists()
    compiled = sorted(p.name for p in cache.rglob("*.so")) if cache.exists() else []
    assert compiled == [], f"the first solve compiled {len(compiled)} kernels: {compiled}"


@pytest.mark.parametrize("G, B, R", [(24, 3, 39), (41, 3, 45), (24, 6, 42)])
def test_the_gauss_newton_products_sum_as_the_kernel_did(G, B, R):
    """The products J^T J of the intervals' Jacobians: the compiled C loop and numpy give the same numbers bit for
    bit (each entry summed over the residuals in their order, interval after interval, as the SX kernel with the
    products inside did), exact zeros of J (structural zeros of the kernel's) skipped or not alike."""
    from magyro.nls.kernels import jit_enabled
    from magyro.nls.on_numpy import GaussNewtonProducts

    compiled = GaussNewtonProducts(G, B)
    if not jit_enabled() or compiled.c_parts is None:
        pytest.skip("no C compiler: only numpy's products")
    rng = np.random.default_rng(0)
    J = rng.normal(size=(7, R, G + 2 * B)) * rng.lognormal(0, 3, size=(1, R, G + 2 * B))
    J[:, : R - 3, G + B :] = 0.0   # J_k1 only in the gyro rows, as in the kernel
    J[:, R - 3 :, :6] = 0.0
    H_c, H_np = np.ones((G, G)), np.ones((G, G))
    parts_c = compiled(J, H_c)
    parts_np = GaussNewtonProducts(G, B, compiled=False)(J, H_np)
    upper = np.triu_indices(G)
    assert np.array_equal(H_c[upper], H_np[upper])
    assert all(np.array_equal(a, b) for a, b in zip(parts_c, parts_np))
    full = np.ones((G, G)) + np.einsum("mri,mrj->ij", J[:, :, :G], J[:, :, :G])
    assert np.allclose(H_c[upper], full[upper], rtol=1e-12, atol=1e-12 * np.abs(full).max())
