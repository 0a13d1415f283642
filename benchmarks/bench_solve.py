"""Speed and memory of `magyro solve`, the whole process, on 1k / 10k / 100k samples.

    python benchmarks/bench_solve.py [--sizes 1000,10000,100000] [--repeat 3] [--out results.json]

Sessions come from the shipped `paper-table1` problem (100 Hz) with its
duration set to samples / 100 Hz. Each solve runs as its own `magyro solve`
process; its peak RSS comes from os.wait4 on that one child, so every run is
measured on its own. See benchmarks/README.md.
"""
from __future__ import annotations

import argparse
import dataclasses
import json
import os
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from magyro.studies.scenario import load_problem
from magyro.studies.simulate import simulate
from magyro.io import write_session

PROBLEM = "paper-table1"
SEED = 0
TARGET_PROCESS_10K_S = 2.0
TARGET_SOLVE_10K_S = 1.0


def magyro_executable() -> str:
    beside_python = Path(sys.executable).parent / "magyro"
    return str(beside_python) if beside_python.exists() else (shutil.which("magyro") or "magyro")


def problem_for_samples(samples: int):
    """paper-table1 lasting samples / rate. Shorter than the paper's 100 s, the motion
    band is sped up by the same factor, so the session still holds the paper's motion
    cycles (at the paper's 0.02-0.2 Hz, 10 s does not turn the board enough for the
    magnetometer ellipsoid fit)."""
    problem = load_problem(PROBLEM)
    duration_s = samples / problem.gyro_rate_hz
    speedup = max(1.0, problem.duration_s / duration_s)
    motion = dataclasses.replace(problem.motion, band_hz=tuple(f * speedup for f in problem.motion.band_hz))
    return dataclasses.replace(problem, duration_s=duration_s, motion=motion)


def write_benchmark_session(samples: int, folder: Path) -> tuple[Path, int]:
    """A session file of about `samples` gyro and magnetometer samples, and its exact count."""
    session, _ = simulate(problem_for_samples(samples), SEED)
    path = folder / f"session_{samples}.parquet"
    write_session(session, path)
    return path, len(session.t_gyro_s)


def run_measured(argv: list[str], env: dict | None = None) -> tuple[float, float]:
    """Run one child process; (wall seconds, peak RSS MB of that child alone)."""
    with tempfile.TemporaryFile() as stderr:
        start = time.perf_counter()
        child = subprocess.Popen(argv, stdout=subprocess.DEVNULL, stderr=stderr, env=env)
        _, status, usage = os.wait4(child.pid, 0)
        wall_s = time.perf_counter() - start
        child.returncode = os.waitstatus_to_exitcode(status)
        if child.returncode != 0:
            stderr.seek(0)
            sys.exit(f"{' '.join(argv)} failed ({child.returncode}): {stderr.read().decode(errors='replace').strip()}")
    rss_bytes = usage.ru_maxrss if sys.platform == "darwin" else usage.ru_maxrss * 1024
    return wall_s, rss_bytes / 2**20


def solve_once(session: Path, calib: Path, env: dict | None = None) -> dict:
    """One `magyro solve` process: its wall time and peak RSS, and the solver's own timings."""
    wall_s, rss_mb = run_measured([magyro_executable(), "solve", str(session), "-o", str(calib), "-q"], env)
    solver = json.loads(calib.read_text())["solver"]
    return {"process_s": wall_s, "calibrate_s": solver["total_seconds"], "solve_s": solver["seconds"],
            "iterations": solver["iterations"], "peak_rss_mb": rss_mb}


def cold_solve(session: Path, calib: Path) -> dict:
    """A solve with an empty kernel cache, so it compiles the CasADi kernels first."""
    with tempfile.TemporaryDirectory() as cache:
        return solve_once(session, calib, env={**os.environ, "MAGYRO_CACHE_DIR": cache})


def median_of_runs(runs: list[dict]) -> dict:
    summary = {key: statistics.median(run[key] for run in runs) for key in runs[0]}
    summary["peak_rss_mb"] = max(run["peak_rss_mb"] for run in runs)
    return summary


def import_seconds() -> float:
    """Wall time of `python -c "import magyro.cli"` (interpreter start-up included)."""
    return run_measured([sys.executable, "-c", "import magyro.cli"])[0]


def interpreter_seconds() -> float:
    return run_measured([sys.executable, "-c", "pass"])[0]


def table(rows: list[dict]) -> str:
    lines = ["| samples | process wall s | calibrate s | solve s | iterations | peak RSS MB |",
             "|--------:|---------------:|------------:|--------:|-----------:|------------:|"]
    for r in rows:
        lines.append(f"| {r['samples']} | {r['process_s']:.2f} | {r['calibrate_s']:.2f} | {r['solve_s']:.2f} "
                     f"| {r['iterations']:g} | {r['peak_rss_mb']:.0f} |")
    return "\n".join(lines)


def verdict(value: float | None, limit: float) -> str:
    if value is None:
        return "n/a (10k not benchmarked)"
    return f"{'PASS' if value < limit else 'FAIL'} ({value:.2f} s)"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--sizes", default="1000,10000,100000", help="comma-separated sample counts")
    parser.add_argument("--repeat", type=int, default=3, help="solves per size (medians reported)")
    parser.add_argument("--out", type=Path, help="also write the raw numbers here as JSON")
    args = parser.parse_args()
    sizes = [int(s) for s in args.sizes.split(",")]

    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        sessions = {n: write_benchmark_session(n, folder) for n in sizes}
        calib = folder / "calib.json"

        cold = cold_solve(sessions[10000][0], calib) if 10000 in sizes else None
        solve_once(sessions[min(sizes)][0], calib)  # warm-up: fills the default kernel cache
        results = []
        for n in sizes:
            path, count = sessions[n]
            runs = [solve_once(path, calib) for _ in range(args.repeat)]
            results.append({"size": n, "samples": count, **median_of_runs(runs), "runs": runs})

    import_s, python_s = import_seconds(), interpreter_seconds()
    print(f"magyro solve, {PROBLEM} at 100 Hz, median of {args.repeat} runs (peak RSS: max over runs)\n")
    print(table(results))
    if cold is not None:
        print(f"\nfirst run (compiles kernels), 10k: process {cold['process_s']:.2f} s, "
              f"calibrate {cold['calibrate_s']:.2f} s, solve {cold['solve_s']:.2f} s")
    print(f'import: python -c "import magyro.cli" {import_s:.2f} s (bare interpreter {python_s:.2f} s)')
    at_10k = next((r for r in results if r["size"] == 10000), None)
    print(f"\ntargets: whole process on 10k < {TARGET_PROCESS_10K_S:g} s, solve on 10k < {TARGET_SOLVE_10K_S:g} s")
    print(f"  whole process on 10k: {verdict(at_10k and at_10k['process_s'], TARGET_PROCESS_10K_S)}")
    print(f"  solve on 10k:         {verdict(at_10k and at_10k['solve_s'], TARGET_SOLVE_10K_S)}")

    if args.out:
        args.out.write_text(json.dumps({"problem": PROBLEM, "repeat": args.repeat, "results": results,
                                        "first_run_10k": cold, "import_s": import_s,
                                        "interpreter_s": python_s}, indent=2) + "\n")


if __name__ == "__main__":
    main()
