"""How `magyro solve` scales with the session's length: time and peak memory from 10k to 3.6M samples.

    python benchmarks/bench_scale.py [--sizes 10000,100000,360000,3600000] [--repeat 1] [--timeout 900]
                                     [--out results.json]

Sessions come from the shipped `paper-table1` problem (100 Hz) with its duration
set to samples / 100 Hz, as in bench_solve.py. Each solve runs as its own
`magyro solve` process; its peak RSS comes from os.wait4 on that one child.
Before a size is run, its peak RSS is estimated linearly from the largest size
measured so far; a size whose estimate exceeds 80 % of the machine's RAM is
skipped with the reason printed, rather than left to swap or to the kernel's
OOM killer. See benchmarks/README.md.
"""
from __future__ import annotations

import argparse
import json
import os
import signal
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from bench_solve import PROBLEM, SEED, magyro_executable, problem_for_samples
from machine_load import busy_cpu_s, other_load_line, own_cpu_s, provenance

# The last measurement of the 360k session's solve (b02bd52: 1.3 GB; 3.1 GB when this benchmark was written).
PRIOR_SIZE, PRIOR_RSS_MB = 360000, 1302.0
RAM_FRACTION = 0.8
POLL_S = 0.2

# The issue's targets.
TARGET_360K_PROCESS_S = 20.0
TARGET_360K_RSS_MB = 1024.0     # 1 GB, in the table's MB (MiB)
TARGET_3_6M_RSS_MB = 8192.0     # 8 GB
TARGET_GROWTH_360K_36K = 11.0


def mem_total_mb() -> float:
    """MemTotal from /proc/meminfo, in MB (MiB)."""
    for line in Path("/proc/meminfo").read_text().splitlines():
        if line.startswith("MemTotal:"):
            return int(line.split()[1]) / 1024
    raise RuntimeError("no MemTotal in /proc/meminfo")


def rss_mb_of(pid: int) -> float:
    """Current resident set of a running process, MB; 0 once it is gone."""
    try:
        for line in Path(f"/proc/{pid}/status").read_text().splitlines():
            if line.startswith("VmRSS:"):
                return int(line.split()[1]) / 1024
    except OSError:
        pass
    return 0.0


def run_guarded(argv: list[str], timeout_s: float, rss_limit_mb: float, env: dict | None = None) -> dict:
    """Run one child; its wall time, peak RSS (os.wait4 on it alone) and how it ended:
    ok, failed (exit code and the last stderr line), timeout, or killed for memory (its RSS passed
    `rss_limit_mb`, checked every POLL_S: a safety net behind the estimate)."""
    with tempfile.TemporaryFile() as stderr:
        start = time.perf_counter()
        child = subprocess.Popen(argv, stdout=subprocess.DEVNULL, stderr=stderr, env=env, start_new_session=True)
        outcome = "ok"
        while True:
            pid, status, usage = os.wait4(child.pid, os.WNOHANG)
            if pid:
                break
            elapsed = time.perf_counter() - start
            if elapsed > timeout_s or rss_mb_of(child.pid) > rss_limit_mb:
                outcome = "timeout" if elapsed > timeout_s else "memory"
                os.killpg(child.pid, signal.SIGKILL)  # its own session: the child and any compiler it started
                _, status, usage = os.wait4(child.pid, 0)
                break
            time.sleep(POLL_S)
        wall_s = time.perf_counter() - start
        child.returncode = os.waitstatus_to_exitcode(status)
        error = ""
        if outcome == "timeout":
            error = f"killed after the {timeout_s:g} s timeout"
        elif outcome == "memory":
            error = f"killed: its RSS passed {rss_limit_mb:.0f} MB"
        elif child.returncode != 0:
            stderr.seek(0)
            lines = stderr.read().decode(errors="replace").strip().splitlines()
            outcome, error = "failed", f"exit {child.returncode}: {lines[-1] if lines else ''}"
    rss_bytes = usage.ru_maxrss if sys.platform == "darwin" else usage.ru_maxrss * 1024
    return {"outcome": outcome, "error": error, "process_s": wall_s, "peak_rss_mb": rss_bytes / 2**20}


def write_session_in_child(samples: int, path: Path, room: bool = False) -> int:
    """Simulate and write the session in a child process, so the simulation's memory (about 2.5 GB at 3.6M
    samples) is returned to the machine before the solve is measured. The exact sample count."""
    out = subprocess.run([sys.executable, __file__, "--write-session", str(samples), str(path)]
                         + (["--room"] if room else []), check=True, capture_output=True, text=True)
    return int(out.stdout.split()[-1])


def write_session_here(samples: int, path: Path, room: bool = False) -> None:
    from magyro.io import write_session
    from magyro.studies.simulate import simulate
    session, _ = simulate(problem_for_samples(samples), SEED)
    write_session(with_room_disturbance(session) if room else session, path)
    print(len(session.t_gyro_s))


def solve_once(session: Path, calib: Path, timeout_s: float, rss_limit_mb: float, env: dict) -> dict:
    """One `magyro solve` process, and the solver's own timings from its JSON when it finished."""
    calib.unlink(missing_ok=True)
    cache = Path(env["MAGYRO_CACHE_DIR"])
    before = sum(1 for p in cache.rglob("*") if p.is_file())
    argv = [magyro_executable(), "solve", str(session), "-o", str(calib), "-q"]
    run = run_guarded(argv, timeout_s, rss_limit_mb, env)
    run["new_kernels"] = sum(1 for p in cache.rglob("*") if p.is_file()) - before
    if run["outcome"] == "ok":
        solver = json.loads(calib.read_text())["solver"]
        run.update(calibrate_s=solver["total_seconds"], solve_s=solver["seconds"], iterations=solver["iterations"],
                   passes=solver.get("passes"), nodes=solver.get("nodes"))
    return run


def estimate_rss_mb(samples: int, measured: dict[int, float]) -> tuple[float, str]:
    """Peak RSS of a solve of `samples`, scaled linearly from the largest size measured (this run's
    measurements, else the prior 360k record). Linear from a small size over-estimates (the fixed
    part of the memory is scaled too), so the estimate errs on the safe side."""
    known = {PRIOR_SIZE: PRIOR_RSS_MB, **measured}
    base = max(known)
    source = "measured here" if base in measured else "earlier measurement"
    return known[base] * samples / base, f"{base} samples: {known[base]:.0f} MB, {source}"


def summarise(size: int, samples: int | None, runs: list[dict]) -> dict:
    ok = [r for r in runs if r["outcome"] == "ok"]
    row = {"size": size, "samples": samples, "status": "ok" if len(ok) == len(runs) else runs[-1]["outcome"],
           "runs": runs, "peak_rss_mb": max(r["peak_rss_mb"] for r in runs)}
    if ok:
        for key in ("process_s", "calibrate_s", "solve_s", "iterations"):
            row[key] = statistics.median(r[key] for r in ok)
        row["new_kernels"] = max(r["new_kernels"] for r in ok)
    else:
        row["process_s"] = max(r["process_s"] for r in runs)   # a timeout: a lower bound
    if not ok or len(ok) < len(runs):
        row["reason"] = next(r["error"] or r["outcome"] for r in runs if r["outcome"] != "ok")
    return row


def fmt(value, spec: str) -> str:
    return "-" if value is None else format(value, spec)


def table(rows: list[dict]) -> str:
    lines = ["| size | samples | process wall s | calibrate s | IPOPT s | iterations | peak RSS MB "
             "| size x | time x | calibrate x | RSS x | status |",
             "|-----:|--------:|---------------:|------------:|--------:|-----------:|------------:"
             "|-------:|-------:|------------:|------:|--------|"]
    previous = None
    for r in rows:
        measured = r["status"] == "ok"
        growth = {"size": None, "time": None, "cal": None, "rss": None}
        if measured and previous is not None:
            growth = {"size": r["size"] / previous["size"], "time": r["process_s"] / previous["process_s"],
                      "cal": r["calibrate_s"] / previous["calibrate_s"],
                      "rss": r["peak_rss_mb"] / previous["peak_rss_mb"]}
        status = r["status"] if measured else (r.get("reason") or r["status"])
        if r["status"] in ("skipped", "failed"):
            status = f"{r['status']}: {status}"
        lines.append(f"| {r['size']} | {fmt(r.get('samples'), 'd')} "
                     f"| {fmt(r.get('process_s'), '.2f')}{' (>)' if r['status'] == 'timeout' else ''} "
                     f"| {fmt(r.get('calibrate_s'), '.2f')} | {fmt(r.get('solve_s'), '.2f')} "
                     f"| {fmt(r.get('iterations'), 'g')} | {fmt(r.get('peak_rss_mb'), '.0f')} "
                     f"| {fmt(growth['size'], '.1f')} | {fmt(growth['time'], '.2f')} | {fmt(growth['cal'], '.2f')} "
                     f"| {fmt(growth['rss'], '.2f')} | {status} |")
        if measured:
            previous = r
    return "\n".join(lines)


def verdict(row: dict | None, key: str, limit: float, unit: str) -> str:
    """PASS / FAIL / not measured for `row[key] <= limit`. A timeout or a memory kill that already passed
    the limit is a FAIL; a skipped size is not measured."""
    if row is None:
        return "not measured (size not in --sizes)"
    value = row.get(key)
    if row["status"] == "ok":
        return f"{'PASS' if value <= limit else 'FAIL'} ({value:.2f} {unit})"
    if value is not None and value > limit and row["status"] in ("timeout", "memory"):
        return f"FAIL ({row['status']} at {value:.2f} {unit})"
    return f"not measured ({row['status']}: {row.get('reason', '')})"


def with_room_disturbance(session):
    """The session with the field's magnitude varying along the path, as in a real room (BROAD: 1-3 %): the
    magnetometer scaled about its mean by 1 + 0.01 sin(2 pi t / 17 s) + 0.005 sin(2 pi t / 5.3 s). Then the
    std counts the disturbance (magyro.nls.disturbance), which a homogeneous simulation never runs."""
    import dataclasses

    import numpy as np
    t = session.t_mag_s
    centre = session.mag.mean(axis=0)
    factor = 1 + 0.01 * np.sin(2 * np.pi * t / 17.0) + 0.005 * np.sin(2 * np.pi * t / 5.3)
    return dataclasses.replace(session, mag=centre + (session.mag - centre) * factor[:, None])


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--sizes", default="10000,36000,100000,360000,3600000", help="comma-separated sample counts")
    parser.add_argument("--repeat", type=int, default=1, help="solves per size (medians reported)")
    parser.add_argument("--timeout", type=float, default=900.0, help="seconds per solve before it is killed")
    parser.add_argument("--out", type=Path, help="also write the raw numbers here as JSON")
    parser.add_argument("--room", action="store_true",
                        help="vary the field's magnitude along the path (1.5 %%), as in a real room: the std then "
                             "counts the disturbance, as on real recordings")
    parser.add_argument("--write-session", nargs=2, metavar=("SAMPLES", "PATH"), help=argparse.SUPPRESS)
    args = parser.parse_args()
    load_start = (time.perf_counter(), busy_cpu_s(), own_cpu_s())
    if args.write_session:
        write_session_here(int(args.write_session[0]), Path(args.write_session[1]), args.room)
        return
    sizes = sorted(int(s) for s in args.sizes.split(","))
    ram_mb = mem_total_mb()
    rss_limit_mb = RAM_FRACTION * ram_mb

    rows: list[dict] = []
    measured: dict[int, float] = {}
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        # A kernel cache of this benchmark's own, filled by one warm-up solve of the smallest size (the kernels do
        # not depend on the session's length); the "new kernels" in the JSON show if a run compiled all the same.
        env = {**os.environ, "MAGYRO_CACHE_DIR": str(folder / "cache")}
        (folder / "cache").mkdir()
        calib = folder / "calib.json"
        warm_up = folder / "warm_up.parquet"
        write_session_in_child(min(sizes), warm_up)
        warm = solve_once(warm_up, calib, args.timeout, rss_limit_mb, env)
        print(f"warm-up solve ({min(sizes)} samples, fills the kernel cache): {warm['outcome']}, "
              f"{warm['process_s']:.1f} s, {warm['new_kernels']} kernels compiled", flush=True)
        stop_reason = ""
        for n in sizes:
            estimate, basis = estimate_rss_mb(n, measured)
            if stop_reason:
                rows.append({"size": n, "samples": None, "status": "skipped", "reason": stop_reason})
            elif estimate > rss_limit_mb:
                reason = (f"estimated peak RSS {estimate / 1024:.1f} GB (linear from {basis}) > "
                          f"{RAM_FRACTION:.0%} of RAM ({rss_limit_mb / 1024:.1f} of {ram_mb / 1024:.1f} GB)")
                rows.append({"size": n, "samples": None, "status": "skipped", "reason": reason,
                             "estimated_rss_mb": estimate})
            if rows and rows[-1]["size"] == n:
                print(f"{n} samples: skipped, {rows[-1]['reason']}", flush=True)
                continue
            session = folder / f"session_{n}.parquet"
            t0 = time.perf_counter()
            count = write_session_in_child(n, session, args.room)
            print(f"{n} samples: simulated and written in {time.perf_counter() - t0:.1f} s; estimated peak RSS "
                  f"{estimate:.0f} MB (linear from {basis}); solving...", flush=True)
            runs = []
            for _ in range(args.repeat):
                runs.append(solve_once(session, calib, args.timeout, rss_limit_mb, env))
                r = runs[-1]
                print(f"  {r['outcome']}: process {r['process_s']:.1f} s, peak RSS {r['peak_rss_mb']:.0f} MB"
                      + (f", calibrate {r['calibrate_s']:.1f} s, IPOPT {r['solve_s']:.1f} s, "
                         f"{r['new_kernels']} kernels compiled" if r["outcome"] == "ok" else f" {r['error']}"),
                      flush=True)
                if r["outcome"] != "ok":
                    break
            session.unlink()
            row = summarise(n, count, runs)
            row["estimated_rss_mb"] = estimate
            rows.append(row)
            if row["status"] == "ok":
                measured[n] = row["peak_rss_mb"]
            elif row["status"] in ("timeout", "memory"):
                stop_reason = f"{n} samples ended by {row['status']}"

    by_size = {r["size"]: r for r in rows}
    load_line = other_load_line(load_start)
    print(f"\nmagyro solve, {PROBLEM} at 100 Hz{', field magnitude varying 1.5 % along the path (--room)' if args.room else ''}, median of {args.repeat} run(s) (peak RSS: max over runs); "
          f"x = ratio to the previous measured size; RAM {ram_mb / 1024:.1f} GB, timeout {args.timeout:g} s")
    print(f"{load_line}\n")
    print(table(rows))
    growth = None
    if by_size.get(36000, {}).get("status") == "ok" and by_size.get(360000, {}).get("status") == "ok":
        a, b = by_size[36000], by_size[360000]
        growth = {"status": "ok", "ratio": b["process_s"] / a["process_s"],
                  "calibrate_ratio": b["calibrate_s"] / a["calibrate_s"], "solve_ratio": b["solve_s"] / a["solve_s"],
                  "rss_ratio": b["peak_rss_mb"] / a["peak_rss_mb"]}
        print(f"\n360k / 36k: process time x{growth['ratio']:.2f}, calibrate x{growth['calibrate_ratio']:.2f}, "
              f"IPOPT x{growth['solve_ratio']:.2f}, peak RSS x{growth['rss_ratio']:.2f} (10x the samples)")
    print("\ntargets (the issue's):")
    print(f"  360k whole process <= {TARGET_360K_PROCESS_S:g} s:      "
          f"{verdict(by_size.get(360000), 'process_s', TARGET_360K_PROCESS_S, 's')}")
    print(f"  360k peak RSS <= 1 GB:           "
          f"{verdict(by_size.get(360000), 'peak_rss_mb', TARGET_360K_RSS_MB, 'MB')}")
    print(f"  3.6M peak RSS <= 8 GB:           "
          f"{verdict(by_size.get(3600000), 'peak_rss_mb', TARGET_3_6M_RSS_MB, 'MB')}")
    print(f"  time(360k) / time(36k) <= {TARGET_GROWTH_360K_36K:g}:   "
          + (f"{'PASS' if growth['ratio'] <= TARGET_GROWTH_360K_36K else 'FAIL'} (x{growth['ratio']:.2f}, "
             "whole process)" if growth else "not measured (needs 36000 and 360000 in --sizes, both solved)"))

    if args.out:
        args.out.write_text(json.dumps({"problem": PROBLEM, "repeat": args.repeat, "timeout_s": args.timeout,
                                        "ram_mb": ram_mb, "rss_limit_mb": rss_limit_mb, "warm_up": warm,
                                        "results": rows, "growth_360k_36k": growth,
                                        "other_load": load_line,
                                        **provenance(f"python benchmarks/bench_scale.py --sizes {args.sizes} "
                                                     f"--repeat {args.repeat} --out FILE")}, indent=2) + "\n")


if __name__ == "__main__":
    main()
