"""Shared fixtures: sessions solved once per test run, and a `magyro` runner; how the run is spread over workers.

A solve takes seconds, so every (problem, seed) and the shipped broad-02 trial are calibrated once per run
(session scope) and the Calibration is shared by the tests that check it. The suite runs on two pytest-xdist
workers (pyproject.toml's addopts: `-n 2 --dist loadfile`, one test file per worker at a time, so a file's
module fixtures are made once); a solve two files share is made by the first worker that needs it and read by
the other from the run's temporary folder (`shared_across_workers`).
"""
from __future__ import annotations

import dataclasses
import json
import os
import pickle
import re
import subprocess
import sys
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]


def _without_the_checkout(path: list[str]) -> list[str]:
    """sys.path without the repository's root ('' or its path, which `python -m pytest` run from it puts first)."""
    return [p for p in path if Path(p or os.curdir).resolve() != REPO]


# The tests test magyro as installed (`pip install .`, or an editable install when one iterates), never the source
# tree beside them by accident: `python -m pytest` from the root puts the root first on sys.path, where `magyro/` is
# the source without its compiled kernels and without magyro.problems (installed from problems/). The children the
# tests start (`python -m magyro`, `python -c`) would do the same from the root: PYTHONSAFEPATH (Python 3.11+) keeps
# the working directory and a script's folder off their sys.path (PYTHONPATH still counts).
sys.path[:] = _without_the_checkout(sys.path)
os.environ["PYTHONSAFEPATH"] = "1"

from magyro import calibrate  # noqa: E402
from magyro.io import load_session, write_session  # noqa: E402
from magyro.studies.scenario import load_problem  # noqa: E402
from magyro.studies.simulate import simulate  # noqa: E402

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

# The test files that take longest, run first so that no worker starts a long file when the other is nearly done;
# the rest follow in their usual order. Measured 2026-12-07 at c5a5f6f (the README's command, CI's environment,
# OPENBLAS_CORETYPE=Zen; --durations=0 summed per file, setup and teardown included): 493, 357, 245, 223, 196, 180,
# 175, 158, 152, 137, 136, 130 s of 4036 s on two workers (34 min wall beside busy neighbours, load 10-15 on the 2
# cores: the ratios matter, not the seconds). test_corpus.py, first until then (507 s on 2026-12-02), took 9 s: its
# whole solves are `heavy` now.
HEAVY_FILES = ("test_batch.py", "test_crlb_accelerometer.py", "test_doc_numbers.py", "test_accelerometer.py",
               "test_report.py", "test_gaps.py", "test_watch.py", "test_plan_accelerometer.py",
               "test_accelerometer_real.py", "test_executor.py", "test_ekf.py", "test_cli.py")


# The files whose tests compare numbers magyro exports or solves with numbers written down before (stored exports,
# the docs' records and rendered pages, papers' figures): the marker `numeric`, which .ci/run runs again under other
# OpenBLAS kernels (OPENBLAS_CORETYPE) to show that they hold on any CPU.
NUMERIC_FILES = ("test_accelerometer_apply_export.py", "test_apply_export.py", "test_calibrate.py",
                 "test_doc_numbers.py", "test_kernels.py", "test_targets.py")


def pytest_collection_modifyitems(config, items):
    """Heaviest files first (a stable sort: the order within a file and among the others is kept); NUMERIC_FILES'
    tests marked `numeric`; a `heavy` test is `slow` too, so that the quick subset `-m "not slow"` (which replaces
    addopts' -m 'not heavy') leaves it out as well (4 heavy tests were not marked slow). This runs before pytest's
    -m selection (a conftest's hook before the builtin plugins')."""
    rank = {name: k for k, name in enumerate(HEAVY_FILES)}
    items.sort(key=lambda item: rank.get(Path(str(item.fspath)).name, len(rank)))
    for item in items:
        if Path(str(item.fspath)).name in NUMERIC_FILES:
            item.add_marker(pytest.mark.numeric)
        if item.get_closest_marker("heavy") and not item.get_closest_marker("slow"):
            item.add_marker(pytest.mark.slow)


# --------------------------------------------------------------------------- what CI checks of a run


def installed_magyro_problem() -> str | None:
    """Why this run does not test an installed wheel (None when it does): MAGYRO_TEST_INSTALLED=wheel (.ci/run) asks
    that both this process and a child started from the repository's root import magyro from outside it."""
    import magyro

    if Path(magyro.__file__).resolve().is_relative_to(REPO):
        return f"the tests import magyro from the checkout ({magyro.__file__}), not from the installed wheel"
    child = subprocess.run([sys.executable, "-c", "import magyro; print(magyro.__file__)"], cwd=REPO,
                           capture_output=True, text=True, timeout=120)
    if child.returncode != 0 or Path(child.stdout.strip()).resolve().is_relative_to(REPO):
        return f"a child started from the checkout imports magyro from {child.stdout.strip() or child.stderr!r}"
    return None


def pytest_configure(config):
    if os.environ.get("MAGYRO_TEST_INSTALLED") == "wheel" and not hasattr(config, "workerinput"):
        problem = installed_magyro_problem()
        if problem:
            raise pytest.UsageError(f"MAGYRO_TEST_INSTALLED=wheel: {problem}")


_SKIPS: list[tuple[str, str]] = []        # (test id, reason) of every skipped test, in the main process
_UNEXPECTED: list[tuple[str, str]] = []


def skip_reason(report) -> str:
    longrepr = report.longrepr
    reason = longrepr[2] if isinstance(longrepr, tuple) else str(longrepr)
    return reason.removeprefix("Skipped: ")


def allowed_skips(path: Path) -> list[re.Pattern]:
    """The patterns of an allowed-skips file: one regular expression a line, matched against a skip's reason;
    '#' starts a comment (the why of each), blank lines are ignored."""
    patterns = []
    for line in path.read_text(encoding="utf-8").splitlines():
        line = line.split(" #", 1)[0].strip() if not line.lstrip().startswith("#") else ""
        if line:
            patterns.append(re.compile(line))
    return patterns


def pytest_runtest_logreport(report):
    if report.skipped and not hasattr(report, "wasxfail"):
        _SKIPS.append((report.nodeid, skip_reason(report)))


def pytest_sessionfinish(session, exitstatus):
    """With MAGYRO_ALLOWED_SKIPS (a file, tests/ci_allowed_skips.txt in .ci/run) a test that skipped for a reason
    not on it fails the run: on CI's machine a skip is a test that did not run. MAGYRO_SKIPS_JSON: the skips written
    there as JSON."""
    if hasattr(session.config, "workerinput"):
        return
    if os.environ.get("MAGYRO_SKIPS_JSON"):
        Path(os.environ["MAGYRO_SKIPS_JSON"]).write_text(json.dumps([{"test": t, "reason": r} for t, r in _SKIPS],
                                                                    indent=1) + "\n", encoding="utf-8")
    if os.environ.get("MAGYRO_ALLOWED_SKIPS"):
        patterns = allowed_skips(Path(os.environ["MAGYRO_ALLOWED_SKIPS"]))
        _UNEXPECTED[:] = [(t, r) for t, r in _SKIPS if not any(p.search(r) for p in patterns)]
        if _UNEXPECTED and session.exitstatus in (pytest.ExitCode.OK, pytest.ExitCode.NO_TESTS_COLLECTED):
            session.exitstatus = pytest.ExitCode.TESTS_FAILED


def pytest_terminal_summary(terminalreporter):
    if not os.environ.get("MAGYRO_ALLOWED_SKIPS"):
        return
    allowed = os.environ["MAGYRO_ALLOWED_SKIPS"]
    if _UNEXPECTED:
        terminalreporter.section("skips not allowed here", sep="=", red=True, bold=True)
        for test, reason in _UNEXPECTED:
            terminalreporter.write_line(f"{test}: {reason}")
        terminalreporter.write_line(f"{len(_UNEXPECTED)} of {len(_SKIPS)} skips are not on {allowed}: "
                                    "the run fails (make those tests run here, or list their reason with why)")
    else:
        terminalreporter.write_line(f"{len(_SKIPS)} skipped, every one on {allowed}")


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

