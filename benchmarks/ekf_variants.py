"""The paper's EKF and its variants against the simulated truth: the seed tables of docs/ekf.md.

    python benchmarks/ekf_variants.py [--seeds 1-10] [--step1-seeds 0-7] [--out docs/numbers/ekf-variants.json]

1. Step 1 alone (`magyro.ekf.refine_magnetometer` from the ellipsoid), with the noise-corrected score and plain,
   on paper-table1 and phone-module, `--step1-seeds`: the z-scores of R (upper) and h against the truth, RMS
   per seed.
2. The whole method on paper-table1, `--seeds`, in five variants (the default; the magnetometer known exactly;
   no consider states; plain step 1; the paper literal: plain step 1 and no consider states): per seed the
   errors against the truth of the scale factors (ppm), non-orthogonality (K_g off-diagonal, deg), bias (deg/s)
   and misalignment (deg), and the 12 gyro errors over their reported std (z).

Prints the tables; `--out` writes them as the record docs/make_ekf_numbers.py renders.
"""
from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np

from magyro import Options, calibrate, so3
from magyro.ekf import EKF, refine_magnetometer
from magyro.front import ellipsoid
from magyro.result.reported import UPPER
from magyro.studies.scenario import load_problem
from magyro.studies.simulate import simulate

OFF = ((0, 1), (0, 2), (1, 2))


def seeds(text: str) -> list[int]:
    a, _, b = text.partition("-")
    return list(range(int(a), int(b or a) + 1))


def variants(problem) -> dict[str, EKF]:
    return {"default": EKF(), "magnetometer known": EKF(magnetometer=(problem.R, problem.hard_iron)),
            "no consider states": EKF(consider_magnetometer=False), "plain step 1": EKF(mag_bias_correction=False),
            "paper literal": EKF(mag_bias_correction=False, consider_magnetometer=False)}


def step1(problem_name: str, seed: int) -> dict:
    problem = load_problem(problem_name)
    session, _ = simulate(problem, seed)
    fit = ellipsoid.fit_ellipsoid(session.mag, problem.mag_noise_std)
    out = {}
    for name, noise in (("corrected", problem.mag_noise_std), ("plain", None)):
        ref = refine_magnetometer(session.mag, fit.R, fit.h, noise)
        e = np.concatenate([[(ref.R - problem.R)[i, j] for i, j in UPPER], ref.h - problem.hard_iron])
        out[name] = float(np.sqrt(np.mean((e / np.sqrt(np.diag(ref.covariance))) ** 2)))
    return out


def errors(cal, problem) -> dict:
    dK = cal.K_g - problem.K_g
    d = np.rad2deg(so3.log_so3(problem.C_b_m.T @ cal.C_b_m))
    gyro = np.concatenate([[dK[i, j] for i, j in UPPER], cal.bias_deg_s - problem.gyro_bias_deg_s, d])
    std = np.concatenate([[cal.std.K_g[i, j] for i, j in UPPER], cal.std.bias_deg_s, cal.std.misalignment_deg])
    return {"scale_ppm": (1e6 * np.diag(dK)).tolist(), "nonorth_deg": np.rad2deg([dK[i, j] for i, j in OFF]).tolist(),
            "bias_deg_s": (cal.bias_deg_s - problem.gyro_bias_deg_s).tolist(), "misalignment_deg": d.tolist(),
            "K_g_upper": [float(dK[i, j]) for i, j in UPPER], "z": (gyro / std).tolist()}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", default="1-10")
    parser.add_argument("--step1-seeds", default="0-7")
    parser.add_argument("--out", type=Path)
    args = parser.parse_args()
    t0 = time.perf_counter()
    from machine_load import measured_at, write_record

    record = {**measured_at(f"python benchmarks/ekf_variants.py --seeds {args.seeds} --step1-seeds {args.step1_seeds} "
                            f"--out {args.out}"), "step1": {}, "variants": {}}
    for name in ("paper-table1", "phone-module"):
        record["step1"][name] = {str(s): step1(name, s) for s in seeds(args.step1_seeds)}
        rms = record["step1"][name].values()
        print(f"step 1 on {name}: RMS z corrected {min(r['corrected'] for r in rms):.2f}-"
              f"{max(r['corrected'] for r in rms):.2f}, plain {min(r['plain'] for r in rms):.2f}-"
              f"{max(r['plain'] for r in rms):.2f}", flush=True)
    problem = load_problem("paper-table1")
    sessions = {s: simulate(problem, s)[0] for s in seeds(args.seeds)}
    for name, method in variants(problem).items():
        per_seed = {}
        for s, session in sessions.items():
            per_seed[str(s)] = errors(calibrate(session, Options(), method), problem)
        record["variants"][name] = per_seed
        worst = {k: max(np.max(np.abs(e[k])) for e in per_seed.values())
                 for k in ("scale_ppm", "nonorth_deg", "bias_deg_s", "misalignment_deg", "z")}
        print(f"{name}: " + ", ".join(f"{k} {v:.3g}" for k, v in worst.items()), flush=True)
    record["seconds"] = time.perf_counter() - t0
    print(f"({record['seconds']:.0f} s)")
    if args.out:
        write_record(args.out, record)
        print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
