"""magyro on BROAD's real trials: the per-trial numbers of the real-data issue, and day-B repeatability.

    python benchmarks/broad_trials.py [--trials 02,03,05,07,09,21,30,32,34,36] [--broad ../shared/data/broad]
                                      [--no-split-check] [--out trials.json]

Each trial is imported (`magyro import broad`), trimmed to its movement span +/- 10 s,
calibrated with the defaults plus `--split-check` but without the accelerometer (`--no-accelerometer`: these
are the gyro's and the magnetometer's numbers; benchmarks/accelerometer_real.py has both), and validated against the optical
truth (`magyro validate`). Printed per trial: dead-reckoning RMS raw -> calibrated and
their ratio, the estimated bias minus the rest-period bias, the magnetometer lag, the
split-half RMS z and the warnings. Then the peak-to-peak spread of the gyro parameters
over the day-B trials (02, 05, 07, 09) beside the paper's Table II figures for the Xsens
MTi-G-700.

Data: BROAD (CC BY 4.0), D. Laidig, M. Caruso, A. Cereatti, T. Seel, "BROAD - A Benchmark
for Robust Inertial Orientation Estimation", Data 6(7):72, 2021.
"""
from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import numpy as np

from magyro.options import Options

from magyro import calibrate
from magyro.errors import MagyroError
from magyro.io import import_broad_movement
from magyro.studies.dead_reckoning import validate

DEFAULT_TRIALS = "02,03,05,07,09,21,30,32,34,36"
DAY_B = ("02", "05", "07", "09")
MARGIN_S = 10.0
TABLE_II = {"scale_ppm": 4000.0, "non_orthogonality_deg": 0.2, "bias_deg_s": 0.03, "misalignment_deg": 0.2}


def trial_path(broad: Path, trial: str) -> Path:
    found = sorted(broad.glob(f"{trial}_*.mat"))
    if not found:
        raise SystemExit(f"no BROAD trial {trial} in {broad}")
    return found[0]


def run_trial(path: Path, split_check: bool) -> dict:
    session = import_broad_movement(path, MARGIN_S)
    t_start = time.perf_counter()
    try:
        cal = calibrate(session, Options(split_check=split_check, accelerometer=False))
    except MagyroError as exc:
        return {"error": str(exc), "seconds": time.perf_counter() - t_start}
    report = validate(session, cal)
    return {"calibration": cal.to_dict(), "validation": report.to_dict(), "seconds": time.perf_counter() - t_start}


def trial_row(trial: str, result: dict) -> str:
    if "error" in result:
        return f"{trial:>5}  not solved: {result['error'][:110]}"
    cal, val = result["calibration"], result["validation"]["summary"]
    raw, calibrated = val["raw"]["rms_deg"], val["calibrated"]["rms_deg"]
    rest = np.array(cal["rests"]["estimate_minus_rest_deg_s"]) if cal.get("rests") else np.full(3, np.nan)
    split = cal.get("consistency", {}).get("rms_z", float("nan"))
    return (f"{trial:>5}  {raw:7.2f} -> {calibrated:6.2f}  {calibrated / raw:5.2f}   "
            f"{' '.join(f'{v:+.3f}' for v in rest)}   {np.max(np.abs(rest)):.3f}  "
            f"{1e3 * cal['time_offset_s']:6.2f}  {split:5.2f}  {len(cal['warnings']):>3}  {result['seconds']:5.1f}")


def gyro_summary(cal: dict) -> dict[str, np.ndarray]:
    K_g = np.array(cal["gyro"]["K_g"])
    return {
        "scale_ppm": 1e6 * (np.diag(K_g) - 1.0),
        "non_orthogonality_deg": np.rad2deg(K_g[[0, 0, 1], [1, 2, 2]]),
        "bias_deg_s": np.array(cal["gyro"]["bias_deg_s"]),
        "misalignment_deg": np.array(cal["misalignment"]["euler_deg"]),
    }


def repeatability(results: dict) -> dict[str, list[float]] | None:
    """Peak-to-peak over the day-B trials, per component."""
    solved = [gyro_summary(results[t]["calibration"]) for t in DAY_B if t in results and "calibration" in results[t]]
    if len(solved) < 2:
        return None
    return {key: np.ptp(np.array([s[key] for s in solved]), axis=0).tolist() for key in TABLE_II}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--trials", default=DEFAULT_TRIALS)
    ap.add_argument("--broad", type=Path, default=Path(__file__).resolve().parents[2] / "shared" / "data" / "broad")
    ap.add_argument("--no-split-check", action="store_true")
    ap.add_argument("--out", type=Path)
    args = ap.parse_args()
    results = {}
    print("trial  dead reckoning RMS (deg)  ratio   estimate - rest bias (deg/s)  max    lag ms  splitz warn  s")
    for trial in args.trials.split(","):
        results[trial] = run_trial(trial_path(args.broad, trial), not args.no_split_check)
        print(trial_row(trial, results[trial]), flush=True)
    spread = repeatability(results)
    if spread:
        print(f"\nday B ({', '.join(t for t in DAY_B if t in results)}): peak-to-peak over trials, x y z  (Table II)")
        for key, limit in TABLE_II.items():
            print(f"  {key:22s} {' '.join(f'{v:8.4g}' for v in spread[key])}   ({limit:g})")
    if args.out:
        args.out.write_text(json.dumps({"trials": results, "day_b_peak_to_peak": spread}, indent=1, default=float))


if __name__ == "__main__":
    main()
