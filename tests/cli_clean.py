"""Run the `magyro` command line and assert that nothing a user should never see reaches them (issue 22):
no traceback, no Python warning, no printed "nan"."""
from __future__ import annotations

import re
import subprocess
import sys
from pathlib import Path

NAN = re.compile(r"\bnan\b", re.IGNORECASE)


def magyro_command() -> list[str]:
    script = Path(sys.executable).with_name("magyro")
    return [str(script)] if script.is_file() else [sys.executable, "-m", "magyro.cli"]


def run_clean(*args, timeout: float = 600) -> subprocess.CompletedProcess:
    """The finished run; fails the test if stdout or stderr holds a traceback, a warning or a 'nan'."""
    result = subprocess.run([*magyro_command(), *map(str, args)], capture_output=True, text=True, timeout=timeout)
    both = result.stdout + result.stderr
    assert "Traceback" not in both, both
    assert "Warning" not in result.stderr, result.stderr
    assert not NAN.search(both), both
    return result


def refusal(result: subprocess.CompletedProcess, code: int) -> str:
    """The one-line message of a refusal with exit `code` (without 'magyro: ')."""
    assert result.returncode == code, (result.returncode, result.stdout[-2000:], result.stderr)
    lines = [line for line in result.stderr.strip().splitlines() if line.startswith("magyro:")]
    assert len(lines) == 1, result.stderr
    return lines[0][len("magyro:"):].strip()
