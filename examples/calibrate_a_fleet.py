"""A production line in miniature: simulate a few devices, calibrate them all, judge them against limits.

    python examples/calibrate_a_fleet.py [OUTDIR]

Each simulated device has its own gyro errors (problems/production-line.toml's [spread]); the batch writes one
calibration per device and summary.parquet / .csv / .html, and says which devices pass the limits. The same on
the command line:

    magyro simulate production-line --seeds 0-3 -o fleet
    magyro batch fleet/manifest.csv -o out --limits docs/limits-example.toml --jobs 2
"""
import sys
from pathlib import Path

import pandas as pd

from magyro.batch import Limits, run_batch
from magyro.studies.fleet import simulate_fleet
from magyro.studies.scenario import load_problem



def main() -> None:
    out = Path(sys.argv[1] if len(sys.argv) > 1 else "fleet-example")
    (out / "sessions").mkdir(parents=True, exist_ok=True)
    simulate_fleet(load_problem("production-line"), range(4), out / "sessions")

    # a bias limit tight enough that some devices of this problem (bias spread 0.3 deg/s) break it
    limits = Limits(max_abs_bias_deg_s=0.5, target_bias_deg_s=0.05, target_scale_ppm=3000)
    result = run_batch([out / "sessions" / "manifest.csv"], out / "batch", limits=limits, jobs=2)
    print(result.table())

    summary = pd.read_parquet(result.summary_paths["parquet"])
    print(summary[["device_id", "verdict", "bias_deg_s_x", "bias_deg_s_y", "bias_deg_s_z", "std_bias_deg_s_x"]]
          .to_string(index=False, float_format=lambda v: f"{v:.4f}"))
    print(f"summary page: {result.summary_paths['html']}")


if __name__ == "__main__":   # the batch's worker processes import this file: only the main process runs it
    main()
