"""The recording check's cost against a solve: `python benchmarks/bench_recording_check.py [--out FILE] [SESSION ...]`.

For each session (default: the shipped BROAD trials), the check and its repairs (best of 5) and one default solve,
both in this process, and the check's share of the solve. Target (issue 22): under 10 % of the solve.
"""
from __future__ import annotations

import json
import sys
import time
from pathlib import Path

import magyro
from magyro.front.repairs import repair_recording

ROOT = Path(__file__).resolve().parents[1]
DEFAULT = [ROOT / "data" / "broad-02.parquet", ROOT / "data" / "broad-07.parquet"]


def best_seconds(job, rounds: int = 5) -> float:
    """The shortest of `rounds` timings of `job()`."""
    times = []
    for _ in range(rounds):
        start = time.perf_counter()
        job()
        times.append(time.perf_counter() - start)
    return min(times)


def main(paths, out: Path | None = None) -> None:
    sys.path.insert(0, str(Path(__file__).resolve().parent))
    from machine_load import busy_cpu_s, other_load_line, own_cpu_s, provenance

    load_start, rows = (time.perf_counter(), busy_cpu_s(), own_cpu_s()), []
    print(f"{'session':<24} {'samples':>8} {'check (ms)':>11} {'solve (s)':>10} {'share':>7}")
    for path in paths:
        session = magyro.load_session(path)
        repair_recording(session)                     # imports and first-call costs out of the timing
        check_s = best_seconds(lambda: repair_recording(session))
        start = time.perf_counter()
        magyro.calibrate(session)
        solve_s = time.perf_counter() - start
        samples = len(session.t_gyro_s) + len(session.t_mag_s)
        print(f"{Path(path).name:<24} {samples:>8} {1000 * check_s:>11.1f} {solve_s:>10.2f} {check_s / solve_s:>7.1%}")
        rows.append({"session": Path(path).name, "samples": samples, "check_s": check_s, "solve_s": solve_s})
    load = other_load_line(load_start)
    print(load)
    if out:
        record = {"rows": rows, "other_load": load,
                  **provenance("python benchmarks/bench_recording_check.py --out FILE")}
        out.write_text(json.dumps(record, indent=1) + "\n", encoding="utf-8")


if __name__ == "__main__":
    argv = sys.argv[1:]
    target = None
    if "--out" in argv:
        i = argv.index("--out")
        target, argv = Path(argv[i + 1]), argv[:i] + argv[i + 2:]
    main(argv or DEFAULT, target)
