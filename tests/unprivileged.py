"""A user that a file of mode 000 is refused to, for the tests of unreadable inputs. Root reads any file (CI runs as
root), so as root the check runs in a child process as the unprivileged user nobody (setpriv, util-linux); anyone
else is refused the file already and runs it as themselves."""
from __future__ import annotations

import os
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

import pytest


def as_unprivileged() -> list[str]:
    """The argv prefix that runs a command as a user refused a file of mode 000 ([] when this process is not root)."""
    if os.geteuid() != 0:
        return []
    import pwd

    setpriv = shutil.which("setpriv")
    if setpriv is None:
        pytest.skip("running as root without setpriv (util-linux) to check as the user nobody: root reads a file of "
                    "mode 000")
    nobody = pwd.getpwnam("nobody")
    return [setpriv, f"--reuid={nobody.pw_uid}", f"--regid={nobody.pw_gid}", "--clear-groups", "--"]


@pytest.fixture
def unprivileged_folder():
    """(folder, env): a folder the unprivileged user can work in (pytest's tmp_path is root's, mode 700), with
    `work/` to run in and the environment of its child (HOME and the kernel cache inside the folder, not in work/)."""
    base = Path(tempfile.mkdtemp(prefix="magyro-unprivileged-"))
    (base / "work").mkdir()
    if os.geteuid() == 0:
        import pwd

        nobody = pwd.getpwnam("nobody")
        for path in (base, base / "work"):
            os.chown(path, nobody.pw_uid, nobody.pw_gid)
    env = {**os.environ, "HOME": str(base), "MAGYRO_CACHE_DIR": str(base / "cache")}
    try:
        yield base / "work", env
    finally:
        shutil.rmtree(base, ignore_errors=True)


def run_unprivileged(argv: list[str], cwd: Path, env: dict, timeout: float = 300) -> subprocess.CompletedProcess:
    """argv as the unprivileged user; fails the test with the child's stderr when it could not start at all (an
    interpreter in a folder that user cannot enter: .ci/run makes its venv's folder readable)."""
    done = subprocess.run([*as_unprivileged(), *argv], cwd=cwd, env=env, capture_output=True, text=True,
                          timeout=timeout)
    assert "ModuleNotFoundError" not in done.stderr and "Permission denied: '" + sys.executable not in done.stderr, \
        done.stderr
    return done
