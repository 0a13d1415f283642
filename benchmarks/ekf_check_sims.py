"""Does `magyro solve --method ekf` ever exit 0 with a calibration that dead-reckons worse than the raw gyro?

    python benchmarks/ekf_check_sims.py [--seeds 0-2] [--methods ekf] [--out docs/numbers/ekf-check-sims.json]

Simulated sessions with a reference attitude (the truth of `magyro.studies.simulate`, as quaternions at the gyro
stamps), including ones built to make the EKF go wrong:

- paper-table1 and phone-module as shipped (the EKF should solve them);
- phone-module in a field that wanders by 5 % of its strength, correlated over 2 s
  (`with_field_disturbance`): the EKF down-weights its magnetometer;
- the same with a gyro that needs no calibration (K_g = I, no bias), where any error is worse than raw
  (the issue's factory-calibrated VN-100);
- a hand turning fast (about 80 deg/s RMS, to 200 deg/s) logged at 40 Hz gyro / 25 Hz magnetometer, with the
  phone's gyro errors and with an ideal gyro (it leaves the field on part of the sphere: step 1 alone cannot
  pin R and h).

Each session goes through `magyro.calibrate` (the recording check, the front end, the result check), then the
raw and the calibrated gyro are dead-reckoned against the reference (`magyro.studies.dead_reckoning.validate`,
what `magyro validate` does). A *violation* is exit 0 with the calibrated RMS error above the raw one.
"""
from __future__ import annotations

import argparse
import dataclasses
import datetime
import json
import subprocess
import time
import tomllib
import warnings
from pathlib import Path

import numpy as np

import magyro
from magyro import so3
from magyro.api import method_named
from magyro.errors import MagyroError
from magyro.studies.dead_reckoning import validate
from magyro.studies.motion import truth_body_attitude
from magyro.studies.scenario import parse_problem, resolve_problem_path
from magyro.studies.simulate import simulate, with_field_disturbance

IDEAL = {"gyro__K_g": np.eye(3).tolist(), "gyro__bias_deg_s": [0.02, -0.02, 0.01]}
FAST = {"gyro__rate_hz": 40.0, "magnetometer__rate_hz": 25.0, "motion__amplitude_deg": [50.0, 25.0, 40.0],
        "motion__band_hz": [0.2, 1.2]}
CASES = {   # name: (problem, changes, field disturbance (fraction, correlation s) or None)
    "paper-table1": ("paper-table1", {}, None),
    "phone-module": ("phone-module", {}, None),
    "phone-module, field wanders 5 %/2 s": ("phone-module", {}, (0.05, 2.0)),
    "ideal gyro, field wanders 5 %/2 s": ("phone-module", IDEAL, (0.05, 2.0)),
    "fast hand 40/25 Hz": ("phone-fast-hand", FAST, None),
    "ideal gyro, fast hand 40/25 Hz": ("phone-fast-hand", {**FAST, **IDEAL}, None),
}


def problem_with(name: str, changes: dict):
    raw = tomllib.loads(resolve_problem_path(name).read_text())
    for key, value in changes.items():
        section, field = key.split("__")
        raw[section][field] = value
    return parse_problem(raw, name)


def session_with_reference(case: str, seed: int):
    name, changes, disturbance = CASES[case]
    problem = problem_with(name, changes)
    session, _ = simulate(problem, seed)
    if disturbance:
        session = with_field_disturbance(session, problem, *disturbance, seed)
    C = truth_body_attitude(problem, session.t_gyro_s)
    return dataclasses.replace(session, t_quat_s=session.t_gyro_s.copy(), quat_wxyz=so3.dcm_to_quat(C))


def run(case: str, seed: int, method: str) -> dict:
    session = session_with_reference(case, seed)
    row = {"case": case, "seed": seed, "method": method}
    t0 = time.process_time()
    try:
        cal = magyro.calibrate(session, magyro.Options(), method=method_named(method))
    except MagyroError as exc:
        return row | {"exit": exc.exit_code, "message": str(exc)[:300], "cpu_s": time.process_time() - t0}
    summary = validate(session, cal).summary
    details = cal.solver.details
    row |= {"exit": 0, "cpu_s": time.process_time() - t0, "raw_rms_deg": summary["raw"]["rms_deg"],
            "calibrated_rms_deg": summary["calibrated"]["rms_deg"],
            "raw_gyro_drift_ratio": [details.get(f"raw_gyro_drift_ratio_{w}s") for w in (5, 10)]}
    row["violation"] = row["calibrated_rms_deg"] > row["raw_rms_deg"]
    return row


def seeds(text: str) -> list[int]:
    a, _, b = text.partition("-")
    return list(range(int(a), int(b or a) + 1))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", default="0-2")
    ap.add_argument("--methods", default="ekf")
    ap.add_argument("--out", type=Path)
    args = ap.parse_args()
    warnings.simplefilter("ignore")   # the front end's warnings on purpose-made bad sessions are not the point here
    rows = []
    for case in CASES:
        for seed in seeds(args.seeds):
            for method in args.methods.split(","):
                rows.append(run(case, seed, method))
                r = rows[-1]
                what = (f"exit 0, dead reckoning {r['raw_rms_deg']:.2f} raw / {r['calibrated_rms_deg']:.2f} "
                        "calibrated deg" + ("  VIOLATION" if r["violation"] else "") if r["exit"] == 0 else
                        f"exit {r['exit']}: {r['message'][:110]}")
                print(f"{case} seed {seed} {method}: {what}", flush=True)
    violations = [r for r in rows if r.get("violation")]
    print(f"{len(violations)} violations in {len(rows)} runs ({sum(r['exit'] == 0 for r in rows)} exit 0)")
    if args.out:
        root = Path(__file__).resolve().parents[1]
        done = subprocess.run(["git", "-C", str(root), "rev-parse", "--short", "HEAD"], capture_output=True, text=True)
        args.out.write_text(json.dumps({
            "command": (f"python benchmarks/ekf_check_sims.py --seeds {args.seeds} --methods {args.methods} "
                        f"--out {args.out}"),
            "date": datetime.date.today().isoformat(), "commit": done.stdout.strip() or "unknown",
            "violations": len(violations), "runs": len(rows), "rows": rows}, indent=1, default=float) + "\n")


if __name__ == "__main__":
    main()
