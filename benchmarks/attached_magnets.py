"""BROAD's attached-magnet trials with the hard iron constant and walking (`--hard-iron-walk`).

    python benchmarks/attached_magnets.py [--broad ../shared/data/broad] [--walks 0.3,1,3]
                                          [--out docs/numbers/attached-magnets.json]

Per trial (32, 34, 36: a magnet 1, 3, 5 cm from the sensor; cut to the movement +/- 10 s;
solved with --force so that a weak result is shown, not refused): the gyro scale factors
(ppm off 1) and bias (deg/s) with their std, the bias at the trial's own rests, and the
measured field disturbance. For reference, the undisturbed trials 02, 03, 05, 07, 09, 21
with the constant model. The gyro's bias differs from recording to recording (rests:
-0.21 deg/s on day B, +0.03 on the magnet trials), so the bias is compared with the trial's
own rests; the scale factors with the undisturbed trials' mean.

Data: BROAD (CC BY 4.0), D. Laidig, M. Caruso, A. Cereatti, T. Seel, "BROAD - A Benchmark
for Robust Inertial Orientation Estimation", Data 6(7):72, 2021.
"""
from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np

from magyro import calibrate
from magyro.errors import MagyroError
from magyro.io import import_broad_movement
from magyro.nls.method import NLS
from magyro.options import Options

UNDISTURBED = ("02", "03", "05", "07", "09", "21")
MAGNETS = ("32", "34", "36")


def solved(session, walk):
    try:
        return calibrate(session, Options(force=True, accelerometer=False), method=NLS(hard_iron_walk=walk)), None
    except MagyroError as exc:
        return None, str(exc).split(":")[0]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--broad", type=Path, default=Path(__file__).resolve().parents[1].parent / "shared/data/broad")
    parser.add_argument("--walks", default="0.3,1,3")
    parser.add_argument("--out", type=Path, help="write the numbers as JSON (the record docs/real-data.md renders)")
    args = parser.parse_args()
    t0 = time.perf_counter()
    from machine_load import measured_at, write_record

    record = {**measured_at("python benchmarks/attached_magnets.py --out docs/numbers/attached-magnets.json"),
              "rows": []}
    load = lambda trial: import_broad_movement(sorted(args.broad.glob(f"{trial}_*.mat"))[0], 10.0)   # noqa: E731
    scales = [1e6 * (np.diag(calibrate(load(t), Options(accelerometer=False)).K_g) - 1) for t in UNDISTURBED]
    mean = np.mean(scales, axis=0)
    record["undisturbed"] = {"trials": list(UNDISTURBED), "scale_ppm_mean": mean.tolist(),
                             "scale_ppm_min": np.min(scales, axis=0).tolist(),
                             "scale_ppm_max": np.max(scales, axis=0).tolist()}
    print(f"undisturbed {', '.join(UNDISTURBED)}: scale factors (ppm) mean {np.round(mean)}, range "
          f"{np.round(np.min(scales, axis=0))} to {np.round(np.max(scales, axis=0))}\n")
    print("| trial | hard iron | scale - undisturbed mean (ppm) | +/- std | bias - rests (deg/s) | +/- std | field wander |")
    print("|---|---|---|---|---|---|---|")
    for trial in MAGNETS:
        session = load(trial)
        for walk in [None, *(float(w) for w in args.walks.split(","))]:
            cal, failure = solved(session, walk)
            label = "constant" if walk is None else f"walk {walk:g} uT/sqrt(s)"
            row = {"trial": trial, "walk_ut_sqrt_s": walk}
            record["rows"].append(row)
            if cal is None:
                row["refused"] = failure
                print(f"| {trial} | {label} | refused: {failure} | | | | |", flush=True)
                continue
            scale = 1e6 * (np.diag(cal.K_g) - 1) - mean
            rest = cal.rests.bias_deg_s if cal.rests is not None else np.full(3, np.nan)
            row.update(scale_minus_undisturbed_ppm=scale.tolist(), scale_std_ppm=(1e6 * np.diag(cal.std.K_g)).tolist(),
                       bias_minus_rests_deg_s=(cal.bias_deg_s - rest).tolist(),
                       bias_std_deg_s=np.asarray(cal.std.bias_deg_s).tolist(),
                       rest_bias_deg_s=None if cal.rests is None else np.asarray(rest).tolist(),
                       field_disturbance_percent=100 * cal.noise.field_disturbance.std_fraction,
                       warnings=list(cal.warnings))
            print(f"| {trial} | {label} | {np.round(scale).astype(int).tolist()} | "
                  f"{np.round(1e6 * np.diag(cal.std.K_g)).astype(int).tolist()} | {np.round(cal.bias_deg_s - rest, 3).tolist()} | "
                  f"{np.round(cal.std.bias_deg_s, 3).tolist()} | {100 * cal.noise.field_disturbance.std_fraction:.1f} % |",
                  flush=True)
    record["seconds"] = time.perf_counter() - t0
    print(f"\n({record['seconds']:.0f} s)")
    if args.out:
        write_record(args.out, record)
        print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
