"""Noise levels without rests (issue 22): N seeded no-rest sessions per problem, each solved.

For every problem: how many solves exit 0, how far the noise levels that weighted the fit are from the
truth (the worst run), where they came from, and for every gyro parameter and misalignment angle the mean
reported std over the actual spread of the estimates (1 when the std is right; targets: levels within
20 %, every solve exit 0, mean std/spread in [0.85, 1.15]).

    PYTHONPATH=$PWD python benchmarks/no_rest.py                  # 30 runs of each problem
    PYTHONPATH=$PWD python benchmarks/no_rest.py -n 5 problems/phone-no-rest.toml
"""
from __future__ import annotations

import argparse
import collections
import time

import numpy as np

from magyro.errors import MagyroError
from magyro.nls.run import calibrate_nls
from magyro.studies.scenario import load_problem
from magyro.studies.simulate import simulate

PROBLEMS = ("problems/phone-no-rest.toml", "problems/paper-table1-hand.toml",
            "problems/phone-fast-hand.toml")   # hand motion up to 1.5 Hz at 28 Hz: the gyro integral's order
PARAMETERS = [f"K_g[{i},{j}]" for i in range(3) for j in range(i, 3)] + ["bias x", "bias y", "bias z",
                                                                        "roll", "pitch", "yaw"]


def one_run(problem, seed: int) -> dict:
    """One seeded session solved: exit code, levels against the truth, estimates and their std."""
    session, truth = simulate(problem, seed)
    t0 = time.perf_counter()
    try:
        cal = calibrate_nls(session)
    except MagyroError as exc:
        return {"seed": seed, "exit": exc.exit_code, "message": str(exc), "seconds": time.perf_counter() - t0}
    iu = np.triu_indices(3)
    estimate = np.concatenate([cal.K_g[iu], cal.bias_deg_s, cal.euler_deg])
    std = np.concatenate([np.asarray(cal.std.K_g)[iu], cal.std.bias_deg_s, cal.std.misalignment_deg])
    true = np.concatenate([np.asarray(truth["gyro"]["K_g"])[iu], truth["gyro"]["bias_deg_s"],
                           truth["misalignment"]["euler_deg"]])
    return {"seed": seed, "exit": 0, "seconds": time.perf_counter() - t0, "estimate": estimate, "std": std,
            "true": true, "guess_warning": any("is a guess" in w for w in cal.warnings),
            "gyro_level": cal.noise.gyro_density_rad_s_sqrt_hz / truth["noise"]["gyro_density_rad_s_sqrt_hz"],
            "mag_level": cal.noise.mag_std / truth["noise"]["mag_std"],
            "sources": (cal.noise.gyro_source, cal.noise.mag_source)}


def summary(name: str, runs: list[dict]) -> str:
    ok = [r for r in runs if r["exit"] == 0]
    lines = [f"{name}: {len(ok)}/{len(runs)} exit 0"
             + "".join(f"; seed {r['seed']} exit {r['exit']}: {r['message']}" for r in runs if r["exit"] != 0)]
    if not ok:
        return "\n".join(lines)
    gyro = np.array([r["gyro_level"] for r in ok])
    mag = np.array([r["mag_level"] for r in ok])
    sources = collections.Counter(r["sources"] for r in ok)
    lines.append(f"  gyro level / truth: {gyro.min():.3f} .. {gyro.max():.3f} (worst {np.max(np.abs(gyro - 1)):.1%})")
    lines.append(f"  mag level / truth:  {mag.min():.3f} .. {mag.max():.3f} (worst {np.max(np.abs(mag - 1)):.1%})")
    lines.append("  sources (gyro, mag): " + ", ".join(f"{k}: {v}" for k, v in sources.items())
                 + f"; 'a guess' warnings: {sum(r['guess_warning'] for r in ok)}")
    lines.append(f"  solve seconds: median {np.median([r['seconds'] for r in ok]):.2f}")
    est = np.array([r["estimate"] for r in ok])
    std = np.array([r["std"] for r in ok])
    err = est - np.array([r["true"] for r in ok])
    spread = est.std(axis=0, ddof=1)
    ratio = std.mean(axis=0) / spread
    lines.append(f"  {'parameter':<10} {'mean err':>11} {'spread':>11} {'mean std':>11} {'std/spread':>10}")
    for k, name_k in enumerate(PARAMETERS):
        lines.append(f"  {name_k:<10} {err[:, k].mean():11.3g} {spread[k]:11.3g} {std[:, k].mean():11.3g} "
                     f"{ratio[k]:10.2f}")
    lines.append(f"  mean std/spread over the {len(PARAMETERS)} parameters: {ratio.mean():.3f} "
                 f"(range {ratio.min():.2f} .. {ratio.max():.2f})")
    return "\n".join(lines)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("problems", nargs="*", default=list(PROBLEMS))
    parser.add_argument("-n", "--runs", type=int, default=30)
    args = parser.parse_args()
    for path in args.problems:
        problem = load_problem(path)
        runs = [one_run(problem, seed) for seed in range(args.runs)]
        print(summary(path, runs), flush=True)


if __name__ == "__main__":
    main()
