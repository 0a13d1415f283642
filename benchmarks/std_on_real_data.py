"""Does the std hold on real recordings? Issue 13's targets on BROAD, with the std and with the white std beside it.

    python benchmarks/std_on_real_data.py [--broad ../shared/data/broad] [--trials 02,03,05,07,09,21]
                                          [--out docs/numbers/std-on-real-data.json]

Per trial (cut to its movement span +/- 10 s, solved with the defaults but the accelerometer: the gyro and the
magnetometer alone, `Options(accelerometer=False)`, `--no-accelerometer`, as issue 13's targets are theirs; with the
accelerometer, benchmarks/accelerometer_real.py): the field
disturbance the solve measured, std / white std, and the split-half RMS z computed with
each (each half calibrated alone; z = half difference / combined std of the halves).
Then the day-B trials (02, 05, 07, 09): chi-square of their spread about the weighted mean,
per parameter group (3 parameters x 3 degrees of freedom each), against its 95 % point.
Then known distortions (magyro.studies.distortion) applied to 02, 03 and 07: the largest
|distorted estimate - prediction from the undistorted solve| per group, in std.

Data: BROAD (CC BY 4.0), D. Laidig, M. Caruso, A. Cereatti, T. Seel, "BROAD - A Benchmark
for Robust Inertial Orientation Estimation", Data 6(7):72, 2021.
"""
from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np
from scipy.stats import chi2

from magyro import calibrate
from magyro.front.prepare import moving_session
from magyro.io import import_broad_movement
from magyro.options import Options
from magyro.result.consistency import half_options, half_spans_s

GYRO_ALONE = Options(accelerometer=False)   # the gyro and the magnetometer, as issue 13 measured them
from magyro.result.reported import misalignment_vector
from magyro.studies.distortion import distorted, distortion_z_scores, predicted_distorted

MARGIN_S = 10.0
DAY_B = ("02", "05", "07", "09")
GROUPS = {"scale": slice(0, 3), "non-orthogonality": slice(3, 6), "bias": slice(6, 9), "misalignment": slice(9, 12)}
UPPER_OFF = ((0, 1), (0, 2), (1, 2))


def gyro_values(cal, C_ref) -> np.ndarray:
    """scale (3), non-orthogonality K_g[i,j] (3), bias deg/s (3), misalignment rotation vector deg (3)."""
    K = cal.K_g
    return np.concatenate([np.diag(K), [K[i, j] for i, j in UPPER_OFF], cal.bias_deg_s,
                           np.rad2deg(misalignment_vector(C_ref, cal.C_b_m))])


def gyro_stds(std) -> np.ndarray:
    K = np.asarray(std.K_g)
    return np.concatenate([np.diag(K), [K[i, j] for i, j in UPPER_OFF], std.bias_deg_s, std.misalignment_deg])


def split_rms_z(session, cal) -> tuple[float, float]:
    """(RMS z with std, with the white std) of the two halves of the moving session, each calibrated alone."""
    moving = moving_session(session, GYRO_ALONE)[0]
    halves = [calibrate(moving.within(a, b), half_options(GYRO_ALONE, cal)) for a, b in half_spans_s(moving)]
    diff = gyro_values(halves[0], cal.C_b_m) - gyro_values(halves[1], cal.C_b_m)
    out = []
    for which in ("std", "std_white"):
        sigma = np.hypot(*(gyro_stds(getattr(h, which)) for h in halves))
        out.append(float(np.sqrt(np.mean((diff / sigma) ** 2))))
    return out[0], out[1]


def day_b_chi_square(cals: dict, which: str) -> dict[str, float]:
    """Chi-square of the day-B calibrations about their weighted mean, per group (9 degrees of freedom)."""
    C_ref = cals[DAY_B[0]].C_b_m
    x = np.array([gyro_values(cals[t], C_ref) for t in DAY_B])
    s = np.array([gyro_stds(getattr(cals[t], which)) for t in DAY_B])
    w = 1.0 / s**2
    mean = np.sum(w * x, axis=0) / np.sum(w, axis=0)
    terms = np.sum(w * (x - mean) ** 2, axis=0)
    return {name: float(np.sum(terms[g])) for name, g in GROUPS.items()}


def distortion_worst(cal_u, cal_d, which: str) -> dict[str, float]:
    z = distortion_z_scores(cal_d, predicted_distorted(cal_u), getattr(cal_d, which))
    return {"scale/non-orth": float(np.max(np.abs(z["K_g"]))), "bias": float(np.max(np.abs(z["bias_deg_s"]))),
            "misalignment": float(np.max(np.abs(z["misalignment_deg"])))}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--broad", type=Path, default=Path(__file__).resolve().parents[1].parent / "shared/data/broad")
    parser.add_argument("--trials", default="02,03,05,07,09,21")
    parser.add_argument("--distorted", default="02,03,07")
    parser.add_argument("--out", type=Path, help="write the numbers as JSON (the record docs/real-data.md renders)")
    args = parser.parse_args()
    t0 = time.perf_counter()
    sessions, cals = {}, {}
    from machine_load import measured_at, write_record

    record = {**measured_at("python benchmarks/std_on_real_data.py --out docs/numbers/std-on-real-data.json"),
              "trials": {}, "day_b_chi_square": None, "distortions": {}}
    print("| trial | field disturbance (% of field, s) | std / white std (median) | split RMS z, std | split RMS z, white std |")
    print("|---|---|---|---|---|")
    for trial in args.trials.split(","):
        path = sorted(args.broad.glob(f"{trial}_*.mat"))[0]
        sessions[trial] = import_broad_movement(path, MARGIN_S)
        cal = cals[trial] = calibrate(sessions[trial], GYRO_ALONE)
        d = cal.noise.field_disturbance
        ratio = float(np.median(gyro_stds(cal.std) / gyro_stds(cal.std_white)))
        z_new, z_white = split_rms_z(sessions[trial], cal)
        record["trials"][trial] = {"disturbance_percent": 100 * d.std_fraction,
                                   "correlation_time_s": d.correlation_time_s, "std_over_white_median": ratio,
                                   "split_rms_z": z_new, "split_rms_z_white": z_white}
        print(f"| {trial} | {100 * d.std_fraction:.2f}, {d.correlation_time_s:.1f} | {ratio:.2f} | {z_new:.2f} | {z_white:.2f} |",
              flush=True)
    if all(t in cals for t in DAY_B):
        limit = chi2.ppf(0.95, 3 * (len(DAY_B) - 1))
        print(f"\nday B (02, 05, 07, 09): chi-square per group, 9 dof, 95 % point {limit:.1f}")
        print("| group | with std | with white std |")
        print("|---|---|---|")
        new, white = day_b_chi_square(cals, "std"), day_b_chi_square(cals, "std_white")
        record["day_b_chi_square"] = {"limit_95": float(limit), "std": new, "std_white": white}
        for name in GROUPS:
            print(f"| {name} | {new[name]:.1f}{' (exceeds)' if new[name] > limit else ''} | {white[name]:.1f} |")
    print("\nknown distortions: largest |distorted - predicted| per group, in std (with std / with white std)")
    print("| trial | scale and non-orthogonality | bias | misalignment |")
    print("|---|---|---|---|")
    for trial in args.distorted.split(","):
        if trial not in sessions:
            path = sorted(args.broad.glob(f"{trial}_*.mat"))[0]
            sessions[trial] = import_broad_movement(path, MARGIN_S)
            cals[trial] = calibrate(sessions[trial], GYRO_ALONE)
        cal_d = calibrate(distorted(sessions[trial]), GYRO_ALONE)
        new, white = distortion_worst(cals[trial], cal_d, "std"), distortion_worst(cals[trial], cal_d, "std_white")
        record["distortions"][trial] = {"std": new, "std_white": white}
        print(f"| {trial} | " + " | ".join(f"{new[k]:.2f} / {white[k]:.2f}" for k in new) + " |", flush=True)
    record["seconds"] = time.perf_counter() - t0
    print(f"\n({record['seconds']:.0f} s)")
    if args.out:
        write_record(args.out, record)
        print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
