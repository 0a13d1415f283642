"""Speed of `magyro observe` on 100 s at 100 Hz (target: under 1 s), and the node-stride study of its prediction.

    python benchmarks/bench_observe.py [--repeat 5] [--stride-study] [--cold] [--out results.json]

1. Simulates `paper-table1` (100 s, gyro and magnetometer at 100 Hz: 10001 samples each),
   noise seed 0, and writes it as Parquet to a temporary folder.
2. One warm-up `magyro observe` fills the compiled-kernel cache (`~/.cache/magyro` or
   `MAGYRO_CACHE_DIR`). With `--cold`, a first run with an empty cache is timed too.
3. **process s**: wall time of `magyro observe SESSION -o report.json -q`, each run its own
   process (start-up, imports, reading, the report, writing the JSON); median of `--repeat`.
   Timed as the user runs it, and again with `OPENBLAS_NUM_THREADS=1`.
4. **observe() s**: the call itself in this process, median of `--repeat`, and its part
   spent in the accuracy prediction (`report.prediction["seconds"]`).
5. With `--stride-study`: `magyro.nls.information.predicted_std` with `NLS(stride=...)` at
   node strides 1, 2, 5, 10, 20: its time with warm kernels, the first call's time (on a
   cold cache it includes compiling that stride's kernels), and the largest relative change
   of any predicted gyro or magnetometer std against stride 1. `magyro observe` predicts on
   nodes at 20 per second (stride 5 at 100 Hz); see docs/observability.md.

Absolute times depend on the machine and its load: compare on a quiet machine.
"""
from __future__ import annotations

import argparse
import json
import os
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from magyro.io import write_session
from magyro.studies.scenario import load_problem
from magyro.studies.simulate import simulate

PROBLEM = "paper-table1"
SEED = 0
TARGET_S = 1.0
STRIDES = (1, 2, 5, 10, 20)
STD_KEYS = ("K_g", "bias_deg_s", "misalignment_deg", "R", "h")


def magyro_executable() -> str:
    beside_python = Path(sys.executable).parent / "magyro"
    return str(beside_python) if beside_python.exists() else (shutil.which("magyro") or "magyro")


def run_process(argv: list[str], env: dict | None = None) -> float:
    start = time.perf_counter()
    done = subprocess.run(argv, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, env=env)
    wall = time.perf_counter() - start
    if done.returncode not in (0, 3):
        sys.exit(f"{' '.join(argv)} failed ({done.returncode}): {done.stderr.decode(errors='replace').strip()}")
    return wall


def observe_process_s(session: Path, report: Path, repeat: int, env: dict | None = None) -> list[float]:
    return [run_process([magyro_executable(), "observe", str(session), "-o", str(report), "-q"], env)
            for _ in range(repeat)]


def observe_call_s(session_obj, repeat: int) -> tuple[list[float], list[float]]:
    from magyro.observability import observe

    total, prediction = [], []
    for _ in range(repeat):
        start = time.perf_counter()
        report = observe(session_obj)
        total.append(time.perf_counter() - start)
        prediction.append(report.prediction["seconds"])
    return total, prediction


def flat_std(std) -> np.ndarray:
    return np.concatenate([np.ravel(np.asarray(getattr(std, k), dtype=float)) for k in STD_KEYS])


def stride_study(session_obj, repeat: int) -> list[dict]:
    from magyro.front.prepare import prepare
    from magyro.nls.information import predicted_std
    from magyro.nls.method import NLS
    from magyro.options import Options

    options = Options()
    prep = prepare(session_obj, options)
    rows, reference = [], None
    for stride in STRIDES:
        start = time.perf_counter()
        std = flat_std(predicted_std(prep, options, NLS(stride=stride)))  # compiles the kernels if not cached
        first = time.perf_counter() - start
        times = []
        for _ in range(repeat):
            start = time.perf_counter()
            predicted_std(prep, options, NLS(stride=stride))
            times.append(time.perf_counter() - start)
        if reference is None:
            reference = std
        seen = reference > 0
        change = float(np.max(np.abs(std[seen] / reference[seen] - 1.0)))
        rows.append({"stride": stride, "nodes_per_s": session_obj.mag_rate_hz / stride,
                     "seconds": statistics.median(times), "first_call_seconds": first,
                     "max_change_vs_stride_1": change})
    return rows


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=5)
    parser.add_argument("--stride-study", action="store_true", help="time predicted_std at strides 1..20")
    parser.add_argument("--cold", action="store_true", help="also time a first run with an empty kernel cache")
    parser.add_argument("--out", type=Path)
    args = parser.parse_args()

    sys.path.insert(0, str(Path(__file__).resolve().parent))
    from machine_load import busy_cpu_s, other_load_line, own_cpu_s

    start = (time.perf_counter(), busy_cpu_s(), own_cpu_s())
    session_obj, _ = simulate(load_problem(PROBLEM), SEED)
    results: dict = {"problem": PROBLEM, "samples": len(session_obj.t_gyro_s), "repeat": args.repeat}
    with tempfile.TemporaryDirectory() as tmp:
        session = Path(tmp) / "session.parquet"
        report = Path(tmp) / "report.json"
        write_session(session_obj, session)
        if args.cold:
            with tempfile.TemporaryDirectory() as cache:
                results["cold_process_s"] = run_process(
                    [magyro_executable(), "observe", str(session), "-o", str(report), "-q"],
                    {**os.environ, "MAGYRO_CACHE_DIR": cache})
        observe_process_s(session, report, 1)  # warm-up: fills the kernel cache
        results["process_s"] = observe_process_s(session, report, args.repeat)
        results["process_one_blas_thread_s"] = observe_process_s(
            session, report, args.repeat, {**os.environ, "OPENBLAS_NUM_THREADS": "1"})
        results["prediction_stride"] = json.loads(report.read_text())["prediction"]["stride"]
    results["import_s"] = run_process([sys.executable, "-c", "import magyro.cli, magyro.observability.excitation"])
    results["call_s"], results["prediction_s"] = observe_call_s(session_obj, args.repeat)

    med = {k: statistics.median(results[k]) for k in ("process_s", "process_one_blas_thread_s", "call_s", "prediction_s")}
    print(f"magyro observe, {PROBLEM}: {results['samples']} gyro + {results['samples']} magnetometer samples "
          f"(100 s at 100 Hz), median of {args.repeat}\n")
    print("| what | seconds |")
    print("|---|---:|")
    if "cold_process_s" in results:
        print(f"| whole process, first run (empty kernel cache: compiles) | {results['cold_process_s']:.2f} |")
    print(f"| whole process (`magyro observe SESSION -o report.json -q`) | {med['process_s']:.2f} |")
    print(f"| whole process, OPENBLAS_NUM_THREADS=1 | {med['process_one_blas_thread_s']:.2f} |")
    print(f"| python -c 'import magyro.cli, magyro.observability.excitation' | {results['import_s']:.2f} |")
    print(f"| observe() call | {med['call_s']:.2f} |")
    print(f"| of which the accuracy prediction (stride {results['prediction_stride']}) | {med['prediction_s']:.2f} |")
    verdict = "PASS" if med["process_s"] < TARGET_S else "FAIL"
    print(f"\ntarget: whole process under {TARGET_S:g} s: {verdict} ({med['process_s']:.2f} s)")
    if args.stride_study:
        results["strides"] = stride_study(session_obj, args.repeat)
        print("\npredicted_std against the node stride (warm kernels):\n")
        print("| stride | nodes per second | seconds (warm) | first call (compiles if not cached) | largest change vs stride 1 |")
        print("|---:|---:|---:|---:|---:|")
        for r in results["strides"]:
            print(f"| {r['stride']} | {r['nodes_per_s']:g} | {r['seconds']:.2f} | {r['first_call_seconds']:.2f} "
                  f"| {100 * r['max_change_vs_stride_1']:.2f} % |")
    results["other_load"] = other_load_line(start)
    print(results["other_load"])
    if args.out:
        import datetime
        import platform

        root = Path(__file__).resolve().parents[1]
        done = subprocess.run(["git", "-C", str(root), "rev-parse", "--short", "HEAD"], capture_output=True, text=True)
        flags = " --stride-study" * args.stride_study + " --cold" * args.cold
        results.update(command=f"python benchmarks/bench_observe.py --repeat {args.repeat}{flags} --out FILE",
                       date=datetime.date.today().isoformat(), commit=done.stdout.strip() or "unknown",
                       machine=f"{platform.machine()}, {os.cpu_count()} CPUs, Python {platform.python_version()}")
        args.out.write_text(json.dumps(results, indent=2) + "\n")


if __name__ == "__main__":
    main()
