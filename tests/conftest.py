"""Shared fixtures: simulated sessions solved once per test run, and a `magyro` runner.

A solve takes seconds, so every (problem, seed) is calibrated once (session scope)
and the Calibration is shared by the tests that check it.
"""
from __future__ import annotations

import dataclasses
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


@pytest.fixture(scope="session")
def solve_cache():
    """get(name, seed, via_file=None) -> Solved; each key solved once per run.

    With `via_file` (a directory) the session goes through write_session/load_session
    first, so the solve sees exactly what a user's file would give.
    """
    cache: dict = {}

    def get(name: str, seed: int, via_file: Path | None = None) -> Solved:
        key = (name, seed, via_file is not None)
        if key not in cache:
            session, truth = simulate(load_problem(name), seed)
            if via_file is not None:
                path = Path(via_file) / f"{name}-{seed}.parquet"
                write_session(session, path)
                session = load_session(path)
            cache[key] = Solved(name, seed, session, truth, calibrate(session))
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

    def run(*args, cwd=None, timeout=300):
        return subprocess.run([*magyro_command(), *map(str, args)], capture_output=True, text=True,
                              cwd=cwd, timeout=timeout)

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

