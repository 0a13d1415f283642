"""Wall time of `magyro montecarlo`: 50 runs of the paper problem with --jobs 2 (target: under 2 minutes).

    python benchmarks/bench_montecarlo.py [--problem paper-table1] [--runs 50] [--jobs 2] [--out results.json]

`--jobs` takes a comma-separated list (e.g. 1,2) to compare. Each case runs
the real command, `magyro montecarlo PROBLEM --runs N --jobs J -q -o FILE`, as
its own process (start-up, the CRLB, every solve and the JSON included), and
reads the mean time of one solve inside the workers back from the JSON.

The table:

    runs, jobs      the case
    wall s          wall time of the whole command
    s/run           wall s / runs: what one more run costs with that many jobs
    solve s/run     mean wall time of one solve as measured inside its worker
    cpu s/run       mean CPU time of one solve (that worker's process only)
    idle est. s     runs * cpu s/run / jobs: the wall time on `jobs` otherwise idle
                    CPUs, start-up not included; what the machine's load hides
    failed          runs that failed (they are in the JSON with seed and message)
    load            the 1-minute load average before and after: the solves are
                    CPU bound, so other work on the machine slows them directly

With J jobs on a machine with at least J idle cores, wall ~ runs * solve / J
plus a few seconds of start-up and the CRLB.
"""
from __future__ import annotations

import argparse
import json
import os
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

TARGET_WALL_S = 120.0  # issue 4: 50 runs of the paper problem with --jobs 2


def magyro_executable() -> list[str]:
    beside_python = Path(sys.executable).parent / "magyro"
    if beside_python.exists():
        return [str(beside_python)]
    found = shutil.which("magyro")
    return [found] if found else [sys.executable, "-m", "magyro.cli"]


def run_case(problem: str, runs: int, jobs: int, folder: Path) -> dict:
    out = folder / f"mc_{runs}_{jobs}.json"
    load_before = os.getloadavg()[0]
    start = time.perf_counter()
    done = subprocess.run([*magyro_executable(), "montecarlo", problem, "--runs", str(runs), "--jobs", str(jobs),
                           "-q", "-o", str(out)], capture_output=True, text=True)
    wall_s = time.perf_counter() - start
    if done.returncode not in (0, 1) or not out.exists():
        sys.exit(f"magyro montecarlo failed ({done.returncode}): {done.stderr.strip()}")
    result = json.loads(out.read_text())
    solve = [m["solve_seconds_mean"] for m in result["methods"].values() if m["solve_seconds_mean"] is not None]
    cpu = [m["solve_cpu_seconds_mean"] for m in result["methods"].values() if m.get("solve_cpu_seconds_mean") is not None]
    cpu_per_run = sum(cpu) if cpu else None  # all methods of one seed
    return {"problem": problem, "runs": runs, "jobs": jobs, "wall_s": wall_s, "s_per_run": wall_s / runs,
            "solve_s_per_run": sum(solve) / len(solve) if solve else None, "cpu_s_per_run": cpu_per_run,
            "idle_estimate_s": None if cpu_per_run is None else runs * cpu_per_run / min(jobs, os.cpu_count() or 1),
            "failed": result["failed"],
            "start_method": result["start_method"], "load_before": load_before, "load_after": os.getloadavg()[0],
            "cpus": os.cpu_count()}


def table(rows: list[dict]) -> str:
    header = ["problem", "runs", "jobs", "wall s", "s/run", "solve s/run", "cpu s/run", "idle est. s", "failed",
              "load before/after"]
    lines = [header]
    for r in rows:
        num = lambda v, spec: "-" if v is None else format(v, spec)  # noqa: E731
        lines.append([r["problem"], str(r["runs"]), str(r["jobs"]), f"{r['wall_s']:.1f}", f"{r['s_per_run']:.2f}",
                      num(r["solve_s_per_run"], ".2f"), num(r["cpu_s_per_run"], ".2f"), num(r["idle_estimate_s"], ".0f"),
                      str(r["failed"]), f"{r['load_before']:.1f}/{r['load_after']:.1f}"])
    widths = [max(len(line[i]) for line in lines) for i in range(len(header))]
    return "\n".join("  ".join(c.rjust(w) if i else c.ljust(w) for i, (c, w) in enumerate(zip(line, widths)))
                     for line in lines)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--problem", default="paper-table1")
    ap.add_argument("--runs", type=int, default=50)
    ap.add_argument("--jobs", default="2", help="comma-separated, e.g. 1,2")
    ap.add_argument("--out", type=Path, help="also write the rows as JSON")
    args = ap.parse_args()
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        for jobs in (int(j) for j in args.jobs.split(",")):
            rows.append(run_case(args.problem, args.runs, jobs, Path(tmp)))
            print(f"done: {args.runs} runs, {jobs} jobs, {rows[-1]['wall_s']:.1f} s", file=sys.stderr, flush=True)
    print(f"{os.cpu_count()} CPUs")
    print(table(rows))
    for r in rows:
        if r["problem"] == "paper-table1" and r["runs"] == 50 and r["jobs"] == 2:
            verdict = "PASS" if r["wall_s"] < TARGET_WALL_S else "FAIL"
            print(f"target: 50 runs of paper-table1 with --jobs 2 in under {TARGET_WALL_S:.0f} s: {verdict} "
                  f"({r['wall_s']:.1f} s measured; on 2 otherwise idle CPUs about "
                  f"{r['idle_estimate_s'] or float('nan'):.0f} s plus start-up)")
    if args.out:
        args.out.write_text(json.dumps(rows, indent=2) + "\n")


if __name__ == "__main__":
    main()
