"""`magyro plan` with an accelerometer (docs/accelerometer.md, "Planning with the accelerometer"): the plan's poses
and predicted accelerometer std, against a Monte Carlo of the written plan.

    python benchmarks/plan_accelerometer.py [--base paper-table1-acc] [--duration 60] [--runs 200] [--jobs 1]
                                            [--out plan.toml]

1. Makes the plan (`make_plan`, what `magyro plan --base paper-table1-acc` runs) with BLAS on one thread, and prints
   its CPU time, the poses held (observe's count on seed 0, still samples only, and observe's own), how they were
   held and the gyro's largest ratio as searched and with the poses held.
2. Runs the Monte Carlo of the written file (`run_montecarlo`, what `magyro montecarlo plan.toml --runs N` runs)
   and prints per accelerometer parameter the actual std, the predicted bound (the plan's; the study's CRLB is
   checked equal), the white-noise bound, the spread of the solve's own weighting, their ratios, and the reported
   std over the actual; then the gyro's actual std (solved with the accelerometer) over the plan's predicted.

60 s on paper-table1-acc: the plan about 37-40 s of CPU, 200 runs about 60 s with one job.
"""
from __future__ import annotations

import argparse
import os
import tempfile
import time
from pathlib import Path

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
import numpy as np  # noqa: E402


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--base", default="paper-table1-acc")
    ap.add_argument("--duration", type=float, default=60.0)
    ap.add_argument("--runs", type=int, default=200)
    ap.add_argument("--jobs", type=int, default=1)
    ap.add_argument("--out", type=Path, default=None, help="keep the plan's problem file here")
    args = ap.parse_args()

    from threadpoolctl import threadpool_limits

    from magyro.studies.crlb_accelerometer import ACC_ROWS
    from magyro.studies.montecarlo import run_montecarlo
    from magyro.studies.plan import GYRO_ROWS, make_plan
    from magyro.studies.scenario import load_problem

    c0 = time.process_time()
    with threadpool_limits(limits=1):
        plan = make_plan(args.duration, base_problem=args.base)
    a = plan.accelerometer
    print(f"plan: {time.process_time() - c0:.1f} s CPU ({a.seconds:.1f} s the accelerometer's part, {a.pose_seconds:.1f} s "
          f"the poses)")
    print("poses held still (observe's count, seed 0): " + ", ".join(f"{f} {v:.1f}" for f, v in a.held_s.items()))
    print("observe's own count (turning too):         " + ", ".join(f"{f} {v:.1f}" for f, v in a.cone_s.items()))
    print(f"how: {a.how}")
    print(f"gyro's largest ratio over the start poses: {a.searched_worst_ratio:.3f} as searched, {plan.worst_ratio:.3f} "
          f"with the poses held (x{plan.worst_ratio / a.searched_worst_ratio:.3f})")

    path = args.out or Path(tempfile.mkdtemp(prefix="plan_acc_")) / "plan.toml"
    path.write_text(plan.to_problem_toml())
    if args.runs < 1:   # the plan's part alone
        return
    t0 = time.perf_counter()
    result = run_montecarlo(load_problem(path), runs=args.runs, jobs=args.jobs)
    nls = result.methods["nls"]
    print(f"\nMonte Carlo of {path}: {nls.succeeded} of {args.runs} solved in {time.perf_counter() - t0:.0f} s")
    assert np.allclose([result.crlb[k] for k in ACC_ROWS], [a.std[k] for k in ACC_ROWS], rtol=1e-6), "not the same bound"
    print(f"  {'parameter':<26}{'actual':>10}{'bound':>10}{'white':>10}{'solve wt':>10}{'act/bound':>10}"
          f"{'act/solve':>10}{'reported/act':>13}")
    over_bound, over_white, over_solve, reported = [], [], [], []
    for k in ACC_ROWS:
        row = nls.row(k)
        over_bound.append(row.std / a.std[k])
        over_white.append(row.std / a.white_std[k])
        over_solve.append(row.std / a.weighted_std[k])
        reported.append(row.reported_over_actual)
        print(f"  {k:<26}{row.std:>10.3g}{a.std[k]:>10.3g}{a.white_std[k]:>10.3g}{a.weighted_std[k]:>10.3g}"
              f"{over_bound[-1]:>10.2f}{over_solve[-1]:>10.2f}{reported[-1]:>13.2f}")
    print(f"actual / bound {min(over_bound):.2f}-{max(over_bound):.2f} (median {np.median(over_bound):.2f}); / white "
          f"{min(over_white):.2f}-{max(over_white):.2f}; / the solve weighting's spread {min(over_solve):.2f}-"
          f"{max(over_solve):.2f} (median {np.median(over_solve):.2f}); reported / actual {min(reported):.2f}-"
          f"{max(reported):.2f}")
    gyro = [nls.row(k).std / plan.std[k] for k in GYRO_ROWS]
    print(f"gyro: actual (solved with the accelerometer) / the plan's predicted {min(gyro):.2f}-{max(gyro):.2f} "
          f"(mean {np.mean(gyro):.2f})")


if __name__ == "__main__":
    main()
