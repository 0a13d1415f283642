"""Throughput of the paper's error-state EKF (magyro.ekf), in samples per second.

    python benchmarks/bench_ekf.py [--problems paper-table1,phone-module] [--repeat 3] [--out results.json]

For each problem (noise seed 0) it times, in this process:

- **filter**: the per-sample loop alone (`magyro.ekf.streaming.run_filter` on a
  fresh StreamingCalibrator), with the 9 magnetometer consider states (default,
  26 states) and without them (17 states, the paper's filter);
- **calibrate**: the whole two-step method, `EKF().calibrate_with_history`
  (noise, gate, ellipsoid, Newton, eq. 13, filter, std, history), wall time.

Samples = gyro samples + magnetometer samples fed to the filter. Median of
`--repeat` runs. Wall-clock numbers depend on the machine and its load; the
"per CPU s" columns (process CPU time) are less sensitive to other load.
"""
from __future__ import annotations

import argparse
import datetime
import json
import os
import platform
import statistics
import subprocess
import sys
import time
from pathlib import Path

from magyro import ekf
from magyro.ekf.prior import initial_estimate
from magyro.ekf.streaming import run_filter
from magyro.front.prepare import prepare
from magyro.options import Options
from magyro.studies.scenario import load_problem
from magyro.studies.simulate import simulate

SEED = 0


def filter_run(session, prep, ref, init, consider: bool) -> tuple[float, int, float]:
    f = ekf.StreamingCalibrator(ref.R, ref.h, init.K0, init.eps0, None, prep.gyro_density, prep.sigma_mag,
                                P0=init.P0, cov_Rh=ref.covariance if consider else None)
    start, cpu = time.perf_counter(), time.process_time()
    run_filter(session, f)
    seconds, cpu_s = time.perf_counter() - start, time.process_time() - cpu
    return seconds, f.gyro_samples + f.mag_updates, cpu_s


def bench(problem_name: str, repeat: int) -> dict:
    session, _ = simulate(load_problem(problem_name), SEED)
    prep = prepare(session, Options())
    s = prep.session
    ref = ekf.refine_magnetometer(s.mag, prep.fit.R, prep.fit.h, prep.sigma_mag)
    init = initial_estimate(s, ref)
    out = {"problem": problem_name, "duration_s": s.duration_s, "gyro_hz": s.gyro_rate_hz, "mag_hz": s.mag_rate_hz}
    for consider in (True, False):
        runs = [filter_run(s, prep, ref, init, consider) for _ in range(repeat)]
        sec = statistics.median(r[0] for r in runs)
        cpu_s = statistics.median(r[2] for r in runs)
        key = "filter_26" if consider else "filter_17"
        out[key + "_s"] = sec
        out["samples"] = runs[0][1]
        out[key + "_samples_per_s"] = runs[0][1] / sec
        out[key + "_samples_per_cpu_s"] = runs[0][1] / cpu_s
    walls = []
    for _ in range(repeat):
        start = time.perf_counter()
        ekf.EKF().calibrate_with_history(session)
        walls.append(time.perf_counter() - start)
    out["calibrate_s"] = statistics.median(walls)
    out["calibrate_samples_per_s"] = out["samples"] / out["calibrate_s"]
    return out


def table(rows: list[dict]) -> str:
    lines = ["| problem | samples | filter 26 states s | samples/s | per CPU s | filter 17 states s | samples/s "
             "| per CPU s | EKF calibrate s | samples/s |",
             "|---|--:|--:|--:|--:|--:|--:|--:|--:|--:|"]
    for r in rows:
        lines.append(f"| {r['problem']} ({r['duration_s']:.0f} s, gyro {r['gyro_hz']:.0f} Hz, mag {r['mag_hz']:.0f} Hz) "
                     f"| {r['samples']} | {r['filter_26_s']:.2f} | {r['filter_26_samples_per_s']:,.0f} "
                     f"| {r['filter_26_samples_per_cpu_s']:,.0f} "
                     f"| {r['filter_17_s']:.2f} | {r['filter_17_samples_per_s']:,.0f} "
                     f"| {r['filter_17_samples_per_cpu_s']:,.0f} "
                     f"| {r['calibrate_s']:.2f} | {r['calibrate_samples_per_s']:,.0f} |")
    return "\n".join(lines)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--problems", default="paper-table1,phone-module")
    parser.add_argument("--repeat", type=int, default=3)
    parser.add_argument("--out", help="also write the numbers here as JSON")
    args = parser.parse_args()
    sys.path.insert(0, str(Path(__file__).resolve().parent))
    from machine_load import busy_cpu_s, other_load_line, own_cpu_s

    start = (time.perf_counter(), busy_cpu_s(), own_cpu_s())
    rows = [bench(p, args.repeat) for p in args.problems.split(",")]
    load = other_load_line(start)
    print(f"magyro.ekf throughput, noise seed {SEED}, median of {args.repeat} runs\n")
    print(table(rows))
    print(load)
    if args.out:
        root = Path(__file__).resolve().parents[1]
        done = subprocess.run(["git", "-C", str(root), "rev-parse", "--short", "HEAD"], capture_output=True, text=True)
        record = {"command": f"python benchmarks/bench_ekf.py --repeat {args.repeat} --out {args.out}",
                  "date": datetime.date.today().isoformat(), "commit": done.stdout.strip() or "unknown",
                  "machine": f"{platform.machine()}, {os.cpu_count()} CPUs, Python {platform.python_version()}",
                  "other_load": load, "repeat": args.repeat, "rows": rows}
        with open(args.out, "w") as fh:
            json.dump(record, fh, indent=1)


if __name__ == "__main__":
    main()
