"""Predicted one-sigma (`magyro observe`, seed 0) against the actual spread of `magyro solve` estimates.

    python benchmarks/predicted_vs_actual.py [--problem paper-table1] [--runs 30] [--jobs 1] [--out result.json]

1. Simulates the problem with noise seed 0 and runs `magyro.observability.observe` on it:
   its `predicted_std` is the prediction, made before any solve (the node stride
   observe uses for it is printed; the stride-1 prediction is shown beside it).
2. Simulates the same problem with noise seeds 1..N and calibrates each with
   `magyro.calibrate` (what `magyro solve` runs). The sample standard
   deviation of each gyro parameter across the N estimates is the actual spread.
   The misalignment is d with C_b_m(true) = C_b_m(est) Exp(d), in degrees (docs/spec.md section 4).
3. Prints one row per gyro parameter: predicted, actual, ratio predicted/actual,
   and whether the ratio is within +/-25 %. With N runs the sample std itself
   scatters by about 1/sqrt(2(N-1)) (13 % at N = 30), so a ratio a little outside
   the band on one parameter out of twelve is what chance alone gives.

It takes a few minutes (one solve per run). See docs/observability.md for a result.
"""
from __future__ import annotations

import argparse
import json
import math
import os
import sys
import time
from concurrent.futures import ProcessPoolExecutor

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")  # before numpy: one BLAS thread per process (12x12 problems)

import numpy as np  # noqa: E402

UPPER = [(0, 0), (0, 1), (0, 2), (1, 1), (1, 2), (2, 2)]
BAND = 0.25


def parameter_names() -> list[str]:
    names = [f"K_g[{i + 1},{j + 1}]" for i, j in UPPER]
    names += [f"bias_{a} (deg/s)" for a in "xyz"]
    names += [f"misalignment_{a} (deg)" for a in ("roll", "pitch", "yaw")]
    return names


def gyro_vector_from_std(std) -> np.ndarray:
    """The gyro part of a `magyro.result.parts.Std` (a calibration's or observe's), in `parameter_names()` order."""
    K = np.asarray(std.K_g, dtype=float)
    return np.concatenate([[K[i, j] for i, j in UPPER], np.asarray(std.bias_deg_s, float),
                           np.asarray(std.misalignment_deg, float)])


def one_run(problem_name: str, seed: int) -> dict:
    """Solve one seeded session; the gyro estimates (misalignment as d against the truth) and reported std."""
    from magyro import calibrate
    from magyro.result.reported import misalignment_vector
    from magyro.studies.scenario import load_problem
    from magyro.studies.simulate import simulate

    session, truth = simulate(load_problem(problem_name), seed)
    start = time.perf_counter()
    cal = calibrate(session)
    d = np.rad2deg(misalignment_vector(cal.C_b_m, np.asarray(truth["misalignment"]["C_b_m"], dtype=float)))
    estimate = np.concatenate([[cal.K_g[i, j] for i, j in UPPER], cal.bias_deg_s, d])
    return {"seed": seed, "estimate": estimate.tolist(), "reported_std": gyro_vector_from_std(cal.std).tolist(),
            "seconds": time.perf_counter() - start}


def prediction(problem_name: str) -> tuple[np.ndarray, np.ndarray, dict]:
    """(observe's predicted std, the stride-1 predicted std, observe's prediction info), seed 0."""
    from magyro.front.prepare import prepare
    from magyro.nls.information import predicted_std
    from magyro.nls.method import NLS
    from magyro.observability import observe
    from magyro.options import Options
    from magyro.studies.scenario import load_problem
    from magyro.studies.simulate import simulate

    session, _ = simulate(load_problem(problem_name), 0)
    report = observe(session)
    if report.predicted_std is None:
        sys.exit(f"{problem_name}: observe gives no prediction ({report.reason})")
    stride1 = predicted_std(prepare(session, Options()), Options(), NLS(stride=1))
    return gyro_vector_from_std(report.predicted_std), gyro_vector_from_std(stride1), report.prediction


def table(names, predicted, predicted_1, actual, reported) -> str:
    lines = ["| parameter | predicted (observe) | predicted (stride 1) | actual spread | mean reported std (solve) "
             "| predicted / actual | within +/-25 % |",
             "|---|---:|---:|---:|---:|---:|:---:|"]
    for n, p, p1, a, r in zip(names, predicted, predicted_1, actual, reported):
        ratio = p / a
        lines.append(f"| {n} | {p:.3g} | {p1:.3g} | {a:.3g} | {r:.3g} | {ratio:.2f} | "
                     f"{'yes' if abs(ratio - 1) <= BAND else 'NO'} |")
    return "\n".join(lines)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--problem", default="paper-table1")
    parser.add_argument("--runs", type=int, default=30, help="solved sessions (noise seeds 1..N)")
    parser.add_argument("--jobs", type=int, default=1, help="solves in parallel processes")
    parser.add_argument("--out", help="also write the numbers as JSON here")
    args = parser.parse_args()

    started = time.perf_counter()
    predicted, predicted_1, info = prediction(args.problem)
    seeds = list(range(1, args.runs + 1))
    if args.jobs > 1:
        with ProcessPoolExecutor(args.jobs) as pool:
            runs = list(pool.map(one_run, [args.problem] * len(seeds), seeds))
    else:
        runs = [one_run(args.problem, s) for s in seeds]
    estimates = np.array([r["estimate"] for r in runs])
    actual = estimates.std(axis=0, ddof=1)
    reported = np.mean([r["reported_std"] for r in runs], axis=0)
    ratio = predicted / actual
    names = parameter_names()
    n = len(runs)
    print(f"{args.problem}: predicted one-sigma (observe, seed 0, node stride {info.get('stride')}) "
          f"vs the spread of {n} solves (seeds 1..{n})\n")
    print(table(names, predicted, predicted_1, actual, reported))
    inside = int(np.sum(np.abs(ratio - 1) <= BAND))
    print(f"\nratio predicted/actual: min {ratio.min():.2f}, median {np.median(ratio):.2f}, max {ratio.max():.2f}; "
          f"{inside} of {len(ratio)} within +/-25 %")
    print(f"sampling scatter of an actual std from {n} runs: about +/-{100 / math.sqrt(2 * (n - 1)):.0f} % (one sigma)")
    print(f"stride-{info.get('stride')} vs stride-1 prediction: largest difference "
          f"{100 * np.max(np.abs(predicted / predicted_1 - 1)):.2f} %")
    print(f"total {time.perf_counter() - started:.0f} s, median solve {np.median([r['seconds'] for r in runs]):.1f} s")
    if args.out:
        with open(args.out, "w", encoding="utf-8") as f:
            json.dump({"problem": args.problem, "runs": n, "jobs": args.jobs, "band": BAND,
                       "seconds": time.perf_counter() - started, "parameters": names, "predicted": predicted.tolist(),
                       "predicted_stride_1": predicted_1.tolist(), "actual": actual.tolist(),
                       "mean_reported_std": reported.tolist(), "ratio": ratio.tolist(), "prediction": info,
                       "estimates": estimates.tolist()}, f, indent=2)


if __name__ == "__main__":
    main()
