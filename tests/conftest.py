"""Shared fixtures: sessions solved once per test run, and a `magyro` runner; how the run is spread over workers.

A solve takes seconds, so every (problem, seed) and the shipped broad-02 trial are calibrated once per run
(session scope) and the Calibration is shared by the tests that check it. The suite runs on two pytest-xdist
workers (pyproject.toml's addopts: `-n 2 --dist loadfile`, one test file per worker at a time, so a file's
module fixtures are made once); a solve two files share is made by the first worker that needs it and read by
the other from the run's temporary folder (`shared_across_workers`).
"""
from __future__ import annotations

import dataclasses
import os
import pickle
import subprocess
import sys
from pathlib import Path

import pytest

from magyro import calibrate
from magyro.io import load_session, write_session
from magyro.studies.scenario import load_problem
from magyro.studies.simulate import simulate

PAPER_SEEDS = (11, 12)
PHONE_SEEDS = (11, 12)


@dataclasses.dataclass(frozen=True)
class Solved:
    """A simulated session, its truth dict, and the calibration magyro made of it."""

    name: str
    seed: int
    session: object
    truth: dict
    cal: object


SHIPPED_BROAD_02 = Path(__file__).resolve().parents[1] / "data" / "broad-02.parquet"

# The test files that take longest (wall s of the whole file on one of two workers: 507, 407, 328, 316, 248,
# 245, 244, 214, 196, 145, 126, 122 on the busy 2-core machine, 2026-12-02), run first so that no worker starts a
# long file when the other is nearly done; the rest follow in their usual order.
HEAVY_FILES = ("test_corpus.py", "test_plan.py", "test_batch.py", "test_report.py", "test_executor.py",
               "test_cli_methods.py", "test_trajectory.py", "test_field_disturbance.py", "test_real_data.py",
               "test_examples.py", "test_cli.py", "test_watch.py")


def pytest_collection_modifyitems(config, items):
    """Heaviest files first (a stable sort: the order within a file and among the others is kept)."""
    rank = {name: k for k, name in enumerate(HEAVY_FILES)}
    items.sort(key=lambda item: rank.get(Path(str(item.fspath)).name, len(rank)))


def shared_across_workers(tmp_path_factory, key: str, compute):
    """compute() once per test run, whichever xdist worker asks first: its result is pickled under the run's
    temporary folder (common to the workers) behind a file lock, and the other workers read it."""
    try:
        import fcntl
    except ImportError:          # no flock (Windows): each worker computes its own
        return compute()
    root = tmp_path_factory.getbasetemp()
    if os.environ.get("PYTEST_XDIST_WORKER"):
        root = root.parent       # basetemp/popen-gwN -> the run's folder
    path = root / "shared-across-workers" / f"{key}.pickle"
    path.parent.mkdir(exist_ok=True)
    with open(path.with_suffix(".lock"), "w") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)      # released when the file closes
        if path.exists():
            return pickle.loads(path.read_bytes())
        value = compute()
        part = path.with_suffix(".part")
        part.write_bytes(pickle.dumps(value))
        part.replace(path)
        return value


@pytest.fixture(scope="session")
def broad02_solved(tmp_path_factory):
    """(session, calibration) of the shipped BROAD trial 2, the gyro and the magnetometer alone (default options but
    `accelerometer=False`, `magyro solve --no-accelerometer`): solved once per run (read-only)."""
    from magyro.options import Options

    session = load_session(SHIPPED_BROAD_02)
    return session, shared_across_workers(tmp_path_factory, "broad-02-gyro",
                                          lambda: calibrate(session, Options(accelerometer=False)))


@pytest.fixture(scope="session")
def broad02_acc_solved(tmp_path_factory):
    """(session, calibration) of the shipped BROAD trial 2 with the accelerometer in the least squares
    (`Options(accelerometer=True)`, `magyro solve --accelerometer`): solved once per run (read-only)."""
    from magyro.options import Options

    session = load_session(SHIPPED_BROAD_02)
    return session, shared_across_workers(tmp_path_factory, "broad-02-accelerometer",
                                          lambda: calibrate(session, Options(accelerometer=True)))


@pytest.fixture(scope="session")
def solve_cache(tmp_path_factory):
    """get(name, seed, via_file=None) -> Solved; each key solved once per run.

    With `via_file` (a directory) the session goes through write_session/load_session
    first, so the solve sees exactly what a user's file would give.
    """
    cache: dict = {}

    def solved(name: str, seed: int, via_file: Path | None) -> Solved:
        session, truth = simulate(load_problem(name), seed)
        if via_file is not None:
            path = Path(via_file) / f"{name}-{seed}.parquet"
            write_session(session, path)
            session = load_session(path)
        return Solved(name, seed, session, truth, calibrate(session))

    def get(name: str, seed: int, via_file: Path | None = None) -> Solved:
        key = (name, seed, via_file is not None)
        if key not in cache:
            cache[key] = shared_across_workers(tmp_path_factory, f"{name}-{seed}-{'file' if via_file else 'memory'}",
                                               lambda: solved(name, seed, via_file))
        return cache[key]

    return get


@pytest.fixture(scope="session", params=PAPER_SEEDS, ids=lambda s: f"seed{s}")
def paper_solved(request, solve_cache) -> Solved:
    return solve_cache("paper-table1", request.param)


@pytest.fixture(scope="session", params=PHONE_SEEDS, ids=lambda s: f"seed{s}")
def phone_solved(request, solve_cache, tmp_path_factory) -> Solved:
    return solve_cache("phone-module", request.param, via_file=tmp_path_factory.mktemp("phone"))


# --------------------------------------------------------------------------- the command line


def magyro_command() -> list[str]:
    """The venv's `magyro` console script, or `python -m magyro.cli` beside this interpreter."""
    script = Path(sys.executable).with_name("magyro")
    return [str(script)] if script.is_file() else [sys.executable, "-m", "magyro.cli"]


@pytest.fixture(scope="session")
def run_magyro():
    """run_magyro(*args, cwd=None) -> CompletedProcess (text, captured)."""

    def run(*args, cwd=None, timeout=300, env=None):
        return subprocess.run([*magyro_command(), *map(str, args)], capture_output=True, text=True,
                              cwd=cwd, timeout=timeout, env=None if env is None else {**os.environ, **env})

    return run


@pytest.fixture(scope="session")
def assert_plain_failure():
    """Check a failed run: the exit code, ONE stderr line starting 'magyro:', no traceback.

    Returns the message (without the 'magyro: ' prefix).
    """

    def check(result, code) -> str:
        codes = code if isinstance(code, tuple) else (code,)
        assert result.returncode in codes, (result.returncode, result.stdout, result.stderr)
        assert "Traceback" not in result.stderr and "Traceback" not in result.stdout, result.stderr
        lines = result.stderr.strip().splitlines()
        assert len(lines) == 1, result.stderr
        assert lines[0].startswith("magyro:"), lines[0]
        return lines[0][len("magyro:"):].strip()

    return check

