"""The solved attitude trajectory (`magyro solve --trajectory`) against the truth: docs/using-the-result.md's figures.

    python benchmarks/trajectory_accuracy.py [--runs 40] [--out docs/numbers/trajectory-accuracy.json]

1. `--runs` simulated phone-module sessions (seeds 0..N-1): the attitude error against the analytic truth, in
   units of the reported std, per m axis; its RMS over every node (but the fixed first) and run.
2. The shipped BROAD trial 02: the trajectory, conjugated into the gyro frame by the solved C_b_m, against the
   optical truth: the error angle's median and 95th percentile (deg), and the error in units of the reported
   std per m axis (RMS over the nodes).

tests/test_trajectory.py checks the same two comparisons with bounds; docs/make_readme_numbers.py renders the
README's sentence from the record.
"""
from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import numpy as np

import magyro
from magyro import so3
from magyro.studies.dead_reckoning import attitude_at
from magyro.studies.scenario import load_problem
from magyro.studies.simulate import simulate, truth_attitude

ROOT = Path(__file__).resolve().parents[1]


def attitude_error_deg(C_m_i_est: np.ndarray, C_m_i_true: np.ndarray) -> np.ndarray:
    """(N, 3) phi in deg with C_est Exp(phi) = the truth re-gauged to the first node (i = m there)."""
    rel = np.swapaxes(C_m_i_true[0], -1, -2) @ C_m_i_true
    return np.rad2deg(so3.log_so3(np.swapaxes(C_m_i_est, -1, -2) @ rel))


def simulated(runs: int) -> dict:
    problem = load_problem("phone-module")
    z2 = []
    for seed in range(runs):
        session, _ = simulate(problem, seed)
        trajectory = magyro.calibrate(session, method=magyro.NLS(trajectory=True)).trajectory
        err = attitude_error_deg(trajectory.C_m_i, truth_attitude(problem, trajectory.t_s))
        z2.append(np.mean((err[1:] / trajectory.std_deg[1:]) ** 2, axis=0))
    return {"problem": "phone-module", "runs": runs, "rms_z_per_axis": np.sqrt(np.mean(z2, axis=0)).tolist(),
            "rms_z": float(np.sqrt(np.mean(z2)))}


def broad02() -> dict:
    session = magyro.load_session(ROOT / "data" / "broad-02.parquet")
    cal = magyro.calibrate(session, method=magyro.NLS(trajectory=True))
    trajectory = cal.trajectory
    ok = np.isfinite(session.quat_wxyz).all(axis=1)
    C_b_enu = attitude_at(session.t_quat_s[ok], so3.quat_to_dcm(session.quat_wxyz[ok]), trajectory.t_s)
    C_m_i_true = cal.C_b_m @ C_b_enu @ cal.C_b_m.T
    err = attitude_error_deg(trajectory.C_m_i, C_m_i_true)
    angle = np.linalg.norm(err, axis=1)
    return {"median_deg": float(np.median(angle)), "p95_deg": float(np.percentile(angle, 95)),
            "rms_z_per_axis": np.sqrt(np.mean((err[1:] / trajectory.std_deg[1:]) ** 2, axis=0)).tolist(),
            "nodes": int(len(angle))}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=40)
    parser.add_argument("--out", type=Path)
    args = parser.parse_args()
    t0 = time.perf_counter()
    from machine_load import measured_at, write_record

    record = {**measured_at(f"python benchmarks/trajectory_accuracy.py --runs {args.runs} --out FILE"),
              "broad_02": broad02()}
    print(json.dumps(record["broad_02"], indent=1), flush=True)
    record["simulated"] = simulated(args.runs)
    record["seconds"] = time.perf_counter() - t0
    print(json.dumps(record["simulated"], indent=1))
    if args.out:
        write_record(args.out, record)
        print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
