"""The suite holds on any machine (issue 40): no path of one machine in tests/ or benchmarks/, and CI's list of
allowed skips says why for each."""
from __future__ import annotations

import re
from pathlib import Path

from conftest import allowed_skips

REPO = Path(__file__).resolve().parents[1]
# a folder of someone's machine (the repository's old fallbacks to the shared folder of the machine it was written
# on, a home), or an absolute path to a Python or pip (a venv of one machine: write `python`, or a path relative to
# the repository)
MACHINE_PATH = re.compile(r"(?<![\w.~-])(?:/(?:work|home|root|Users|mnt)/|/[^\s`'\"()]*/bin/(?:python|pip)\b)")
TEXT_SUFFIXES = {".py", ".md", ".txt", ".toml", ".json", ".yaml", ".csv", ".cfg", ".ini", ".sh", ".h", ".params"}


def machine_paths(folder: Path, root: Path = REPO) -> list[str]:
    found = []
    for path in sorted(folder.rglob("*")):
        if path.is_file() and path.suffix in TEXT_SUFFIXES and "__pycache__" not in path.parts:
            for number, line in enumerate(path.read_text(encoding="utf-8", errors="replace").splitlines(), 1):
                found += [f"{path.relative_to(root)}:{number}: {m.group(0)}" for m in MACHINE_PATH.finditer(line)]
    return found


def test_no_machine_path_in_tests_or_benchmarks():
    assert machine_paths(REPO / "tests") + machine_paths(REPO / "benchmarks") == []


def test_the_machine_path_check_finds_them(tmp_path):
    work = "/" + "work/"          # not written whole: this file is checked too
    lines = [f"WILD = Path('{work}shared/data/wild')", f"{work}venv/bin/python benchmarks/bench_solve.py",
             "--magyc /tmp/magyc-venv/bin" + "/python", "~/x and ../shared/data and /proc/meminfo and /usr/bin/chromium",
             "python -m venv magyc-venv && magyc-venv/bin/pip install magyc"]
    (tmp_path / "t.py").write_text("\n".join(lines) + "\n")
    found = [f.split(": ", 1)[1] for f in machine_paths(tmp_path, tmp_path)]
    assert found == [work, work, "/tmp/magyc-venv/bin" + "/python"]


def test_every_allowed_skip_says_why():
    """tests/ci_allowed_skips.txt: every pattern a valid regular expression with a comment on the line above it."""
    path = Path(__file__).resolve().parent / "ci_allowed_skips.txt"
    lines = path.read_text(encoding="utf-8").splitlines()
    for k, line in enumerate(lines):
        if line.strip() and not line.lstrip().startswith("#"):
            assert k > 0 and lines[k - 1].lstrip().startswith("#") and len(lines[k - 1].strip("# ")) > 10, line
    assert len(allowed_skips(path)) == sum(1 for line in lines if line.strip() and not line.lstrip().startswith("#"))


def test_an_allowed_skip_pattern_matches_its_reason_only(tmp_path):
    listed = tmp_path / "allowed.txt"
    listed.write_text("# a machine without X\nneeds X\\b  # trailing comment\n\n")
    patterns = allowed_skips(listed)
    assert [p.pattern for p in patterns] == ["needs X\\b"]
    assert any(p.search("this needs X here") for p in patterns)
    assert not any(p.search("needs ../shared/data/wild (absent here)") for p in patterns)
