"""How long the test suite takes: the record behind the README's sentence on the tests' time.

    python benchmarks/suite_time.py [--out docs/numbers/suite-time.json] [-- PYTEST ARGS...]

Runs `python -m pytest -q` (the README's command, with pyproject.toml's workers) in a child process, once, and
records its wall time, the counts pytest prints ("889 passed, 3 skipped"), the machine and how much CPU other
processes took meanwhile (a suite time is clean only on a quiet machine). With arguments after `--` it times
that subset instead (`-- -m "not slow"`). docs/make_readme_numbers.py renders the README's block `suite-time`
from the record when the README has that block's markers.
"""
from __future__ import annotations

import argparse
import re
import subprocess
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from machine_load import busy_cpu_s, other_load_line, own_cpu_s, provenance, write_record  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]


def counts(output: str) -> dict[str, int]:
    """pytest's last summary line as {"passed": 889, "skipped": 3, ...}."""
    lines = [line for line in output.splitlines() if re.search(r"\d+ (passed|failed)", line)]
    return {word: int(n) for n, word in re.findall(r"(\d+) (\w+)", lines[-1])} if lines else {}


def main() -> None:
    argv = sys.argv[1:]
    extra = argv[argv.index("--") + 1:] if "--" in argv else []
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path)
    args = parser.parse_args(argv[:argv.index("--")] if "--" in argv else argv)
    command = [sys.executable, "-m", "pytest", "-q", *extra]
    start = (time.perf_counter(), busy_cpu_s(), own_cpu_s())
    done = subprocess.run(command, cwd=ROOT, capture_output=True, text=True)
    wall = time.perf_counter() - start[0]
    record = {"wall_s": wall, "exit": done.returncode, "counts": counts(done.stdout),
              "pytest_args": ["-q", *extra], "other_load": other_load_line(start),
              **provenance("python benchmarks/suite_time.py" + (" -- " + " ".join(extra) if extra else "")
                           + " --out docs/numbers/suite-time.json")}
    print(f"{' '.join(command[1:])}: exit {done.returncode}, {record['counts']}, {wall / 60:.1f} min wall; "
          f"{record['other_load']}")
    if args.out:
        write_record(args.out, record)
        print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
