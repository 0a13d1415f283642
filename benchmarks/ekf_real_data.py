"""The paper's EKF (`--method ekf`) beside the least squares on real recordings: the table of docs/ekf.md.

    python benchmarks/ekf_real_data.py [--trials 02,03,05,07,09,21] [--broad ../shared/data/broad]
                                       [--wild DIR_OF_SESSIONS] [--out ekf_real.json]

BROAD trials are imported as benchmarks/broad_trials.py does (movement span +/- 10 s). `--wild` names a
folder of session files made with `magyro import` from ../shared/data/wild (see docs/ekf.md for the
commands). Each session is calibrated by both methods through `magyro.calibrate` (the same recording check,
front end and result check); the EKF also with `--split-check`. Printed per session: each method's exit
code, the largest |z| of the EKF against the least squares over the twelve gyro parameters (K_g upper,
bias, misalignment as a rotation vector; z with the two std combined), the EKF's split-half RMS z, and on
BROAD the dead-reckoning RMS against the optical truth (`magyro validate`) of the raw gyro and of each
calibration.
"""
from __future__ import annotations

import argparse
import datetime
import json
import subprocess
import time
from pathlib import Path

import numpy as np

from magyro import EKF, calibrate, load_session
from magyro.errors import MagyroError
from magyro.io import import_broad_movement
from magyro.options import Options
from magyro.result.consistency import gyro_stds, gyro_values
from magyro.studies.dead_reckoning import validate

DEFAULT_TRIALS = "02,03,05,07,09,21"
MARGIN_S = 10.0


def solve(session, method, split_check: bool) -> dict:
    t0 = time.perf_counter()
    try:
        cal = calibrate(session, Options(split_check=split_check, accelerometer=False), method)
    except MagyroError as exc:
        return {"exit": exc.exit_code, "error": str(exc), "seconds": time.perf_counter() - t0}
    return {"exit": 0, "cal": cal, "seconds": time.perf_counter() - t0}


def agreement_z(ekf, nls) -> dict[str, float]:
    """(EKF - NLS) / sqrt(std_ekf^2 + std_nls^2) per gyro parameter, misalignment against the NLS's C_b_m."""
    a, b = gyro_values(ekf, nls.C_b_m), gyro_values(nls, nls.C_b_m)
    sa, sb = gyro_stds(ekf), gyro_stds(nls)
    return {k: (a[k] - b[k]) / float(np.hypot(sa[k], sb[k])) for k in a}


def run(name: str, session, truth: bool, ekf_method: EKF = EKF()) -> dict:
    nls = solve(session, None, False)
    ekf = solve(session, ekf_method, True)
    row = {"name": name, "nls_exit": nls["exit"], "ekf_exit": ekf["exit"],
           "nls_s": nls["seconds"], "ekf_s": ekf["seconds"]}
    for key, res in (("nls", nls), ("ekf", ekf)):
        if res["exit"]:
            row[f"{key}_error"] = res["error"]
            continue
        cal = res["cal"]
        row[f"{key}_K_g_diag"] = np.diag(cal.K_g).tolist()
        row[f"{key}_bias_deg_s"] = cal.bias_deg_s.tolist()
        row[f"{key}_warnings"] = list(cal.warnings)
        row[f"{key}_misfit_1s"] = cal.solver.details.get("turning_misfit_ratio_1s")
        row[f"{key}_misfit"] = cal.solver.details.get("turning_misfit_ratio")
        if cal.std_white is not None:
            ratio = [np.asarray(a) / np.asarray(b) for a, b in (
                (cal.std.K_g, cal.std_white.K_g), (cal.std.bias_deg_s, cal.std_white.bias_deg_s),
                (cal.std.misalignment_deg, cal.std_white.misalignment_deg))]
            row[f"{key}_std_over_white"] = float(np.nanmedian(np.concatenate([r[np.isfinite(r)].ravel() for r in ratio])))
        if cal.rests is not None:
            row[f"{key}_rest_z"] = cal.solver.details.get("rest_bias_z")
        if truth:
            summary = validate(session, cal).to_dict()["summary"]
            row["raw_rms_deg"] = summary["raw"]["rms_deg"]
            row[f"{key}_rms_deg"] = summary["calibrated"]["rms_deg"]
    if not ekf["exit"]:
        report = ekf["cal"].consistency
        row["ekf_split_rms_z"] = report.rms_z if report is not None and report.compared else None
    if not ekf["exit"] and not nls["exit"]:
        z = agreement_z(ekf["cal"], nls["cal"])
        worst = max(z, key=lambda k: abs(z[k]))
        row.update(agreement_z=z, max_abs_z=abs(z[worst]), worst=worst)
    return row


def table_row(r: dict) -> str:
    def fmt(v, f="{:.2f}"):
        return "-" if v is None else f.format(v)
    dr = ""
    if "raw_rms_deg" in r:
        dr = f"{r['raw_rms_deg']:.1f} / {fmt(r.get('nls_rms_deg'), '{:.1f}')} / {fmt(r.get('ekf_rms_deg'), '{:.1f}')}"
    ekf_note = r.get("ekf_error", "; ".join(w[:60] for w in r.get("ekf_warnings", [])))[:90]
    return (f"| {r['name']} | {r['nls_exit']} | {r['ekf_exit']} | {fmt(r.get('max_abs_z'))} {r.get('worst', '')} | "
            f"{fmt(r.get('ekf_split_rms_z'))} | {dr} | {ekf_note} |")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--trials", default=DEFAULT_TRIALS)
    ap.add_argument("--broad", type=Path, default=Path(__file__).resolve().parents[2] / "shared" / "data" / "broad")
    ap.add_argument("--wild", type=Path)
    ap.add_argument("--out", type=Path)
    ap.add_argument("--estimate-magnetometer", action="store_true",
                    help="the EKF with R and h as states (EKF(estimate_magnetometer=True)), not the paper's two steps")
    args = ap.parse_args()
    method = EKF(estimate_magnetometer=args.estimate_magnetometer)
    rows = []
    print("| session | nls exit | ekf exit | max \\|z\\| EKF vs NLS | EKF split RMS z | dead reckoning deg raw / nls / ekf "
          "| EKF refusal or warnings |\n|---|--:|--:|---|--:|---|---|", flush=True)
    for trial in filter(None, args.trials.split(",")):
        path = sorted(args.broad.glob(f"{trial}_*.mat"))[0]
        rows.append(run(f"BROAD {trial}", import_broad_movement(path, MARGIN_S), truth=True, ekf_method=method))
        print(table_row(rows[-1]), flush=True)
    for path in sorted(args.wild.glob("*.parquet")) if args.wild else []:
        rows.append(run(path.stem, load_session(path), truth=False, ekf_method=method))
        print(table_row(rows[-1]), flush=True)
    if args.out:
        root = Path(__file__).resolve().parents[1]
        done = subprocess.run(["git", "-C", str(root), "rev-parse", "--short", "HEAD"], capture_output=True, text=True)
        flags = (f" --trials {args.trials}" if args.trials != DEFAULT_TRIALS else "") + (
            " --estimate-magnetometer" if args.estimate_magnetometer else "") + (" --wild DIR" if args.wild else "")
        record = {"command": f"python benchmarks/ekf_real_data.py{flags} --out {args.out}",
                  "date": datetime.date.today().isoformat(), "commit": done.stdout.strip() or "unknown", "rows": rows}
        args.out.write_text(json.dumps(record, indent=1, default=float) + "\n")


if __name__ == "__main__":
    main()
