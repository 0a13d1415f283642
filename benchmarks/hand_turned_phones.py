"""Phones turned fast by hand at 25-40 Hz with no rest (issue 38): solve every seed, compare with the truth.

    python benchmarks/hand_turned_phones.py [--seeds 12] [--replicas ../shared/data/replicas] [--out FILE]

Each seed is a `magyro.studies.hand_turned` recording of one of four kinds, in turn: the iPhone's schedule
(40 Hz for 33 s, then 25 Hz), 25 Hz, 30 Hz and 40 Hz throughout; the gyro taken 6-12 ms RMS off its stamps (the
iPhone replica's white-looking floor is 10 ms's worth). Printed per seed: exit (0 solved, else the error's
class), iterations, CPU seconds, the largest |error / std| over the 12 gyro parameters (K_g upper, bias,
misalignment), where the gyro level came from, and how far the start was from the magnetometer (deg, 90th
percentile). With `--replicas`, the replicas `iphone-fast25` and `iphone-slow25-control` too.
"""
from __future__ import annotations

import argparse
import datetime
import json
import subprocess
import time
from pathlib import Path

import numpy as np

from magyro import calibrate, load_session
from magyro.errors import MagyroError
from magyro.options import Options
from magyro.result.consistency import QUANTITIES, gyro_stds, gyro_values
from magyro.studies.hand_turned import HandTurned, simulate_hand_turned

KINDS = (("40 then 25 Hz", ((0.0, 40.0), (32.8, 25.0))), ("25 Hz", ((0.0, 25.0),)), ("30 Hz", ((0.0, 30.0),)),
         ("40 Hz", ((0.0, 40.0),)))
JITTERS_MS = (10.0, 6.0, 12.0, 8.0)


def largest_z(cal, truth: dict) -> tuple[float, str]:
    """The largest |estimate - truth| / std over the gyro parameters, and which."""
    values, stds = gyro_values(cal, np.asarray(truth["C_b_m"])), gyro_stds(cal)
    source = {"K_g": np.asarray(truth["K_g"]), "bias_deg_s": np.asarray(truth["bias_deg_s"]),
              "misalignment_deg": np.zeros(3)}
    z = {name: (values[name] - float(source[key][idx])) / stds[name] for name, key, idx in QUANTITIES}
    worst = max(z, key=lambda k: abs(z[k]))
    return float(abs(z[worst])), worst


def solved(session, truth: dict, name: str) -> dict:
    t0 = time.process_time()
    try:
        cal = calibrate(session, Options())
    except MagyroError as error:
        return {"name": name, "exit": type(error).__name__, "message": str(error)[:300],
                "cpu_s": round(time.process_time() - t0, 2)}
    z, worst = largest_z(cal, truth)
    return {"name": name, "exit": 0, "iterations": cal.solver.iterations, "cpu_s": round(time.process_time() - t0, 2),
            "largest_z": round(z, 2), "largest_z_of": worst, "gyro_source": cal.noise.gyro_source,
            "gyro_density_deg_s_sqrt_hz": round(float(np.rad2deg(cal.noise.gyro_density_rad_s_sqrt_hz)), 4),
            "start_disagreement_deg": round(float(cal.solver.details.get("start_disagreement_deg", float("nan"))), 1)}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, default=12)
    ap.add_argument("--replicas", type=Path, default=None)
    ap.add_argument("--out", type=Path, default=None)
    args = ap.parse_args()
    rows = []
    for seed in range(1, args.seeds + 1):
        label, schedule = KINDS[(seed - 1) % len(KINDS)]
        jitter = JITTERS_MS[(seed - 1) % len(JITTERS_MS)]
        session, truth = simulate_hand_turned(seed, HandTurned(gyro_schedule=schedule, sample_jitter_ms=jitter))
        rows.append({"seed": seed, "kind": label, "jitter_ms": jitter,
                     **solved(session, truth, f"seed {seed}")})
        print(json.dumps(rows[-1]), flush=True)
    for name in ("iphone-fast25", "iphone-slow25-control") if args.replicas else ():
        truth = json.loads((args.replicas / f"{name}.truth.json").read_text())
        rows.append(solved(load_session(args.replicas / f"{name}.parquet"), truth, name))
        print(json.dumps(rows[-1]), flush=True)
    simulated = [r for r in rows if "seed" in r]
    summary = {"solved": sum(r["exit"] == 0 for r in simulated), "of": len(simulated),
               "largest_z": max((r["largest_z"] for r in simulated if r["exit"] == 0), default=None)}
    print(json.dumps(summary))
    if args.out:
        commit = subprocess.run(["git", "rev-parse", "--short", "HEAD"], capture_output=True, text=True).stdout.strip()
        record = {"date": datetime.date.today().isoformat(), "commit": commit,
                  "command": "python benchmarks/hand_turned_phones.py --seeds %d%s --out %s" % (
                      args.seeds, " --replicas ../shared/data/replicas" if args.replicas else "", args.out),
                  "summary": summary, "rows": rows}
        args.out.write_text(json.dumps(record, indent=1) + "\n")


if __name__ == "__main__":
    main()
