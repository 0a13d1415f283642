"""The README's walk-through leaves the clone clean (issue 40, item 6): every file its commands write in the
clone's top folder (`-o calib.json`, `-o report.html`, ...) is in .gitignore, so `git status` shows none."""
from __future__ import annotations

import re
import shutil
import subprocess
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def written_by_the_readme() -> set[str]:
    """The outputs the README's commands name by a plain file name (placeholders like SESSION or OUTDIR aside)."""
    text = (ROOT / "README.md").read_text(encoding="utf-8")
    names = re.findall(r"(?:-o|--output|--plot|--history-plot)\s+([A-Za-z0-9_.-]+\.(?:json|html|png|toml|parquet|csv))",
                       text)
    return {n for n in names if not n.isupper() and not n.startswith(("SESSION", "CALIB", "FILE", "OUT"))}


def test_the_readme_outputs_are_ignored():
    names = written_by_the_readme()
    assert "calib.json" in names   # command 1 of the README
    ignored = {line.strip() for line in (ROOT / ".gitignore").read_text().splitlines()}
    missing = sorted(n for n in names if f"/{n}" not in ignored and n not in ignored)
    assert not missing, f"add to .gitignore: {', '.join('/' + n for n in missing)}"
    if shutil.which("git") and (ROOT / ".git").exists():
        run = subprocess.run(["git", "check-ignore", *sorted(names)], cwd=ROOT, capture_output=True, text=True)
        assert set(run.stdout.split()) == names, run.stdout
