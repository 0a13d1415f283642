"""The magnetometer lag the EKF finds on the shipped BROAD trial 07, beside the least squares' (docs/ekf.md, "The
magnetometer's lag"): eq. (13)'s search, where the filter starts (`magyro.ekf.method.magnetometer_lag`), and the
lag at the vertex of the filter's own likelihood with its std (`magyro.ekf.lag`), as `magyro solve --method ekf`
gives them. Half a minute.

    python benchmarks/ekf_lag_shipped.py [--out docs/numbers/ekf-lag-shipped.json]
"""
from __future__ import annotations

import argparse
from pathlib import Path

from magyro import calibrate, load_session
from magyro.ekf.method import EKF
from magyro.options import Options

ROOT = Path(__file__).resolve().parent.parent
TRIAL = ROOT / "data" / "broad-07.parquet"


def ekf_lags_ms(path: Path = TRIAL) -> dict[str, float]:
    """{eq13_lag_ms, ekf_lag_ms, ekf_lag_std_ms, filter_runs}: the start, the likelihood's lag and its std."""
    cal = calibrate(load_session(path), Options(), EKF())
    return {"eq13_lag_ms": 1e3 * cal.solver.details["lag_start_s"], "ekf_lag_ms": 1e3 * cal.time_offset_s,
            "ekf_lag_std_ms": 1e3 * cal.std.time_offset_s, "filter_runs": cal.solver.details["filter_runs"]}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--out", help="write the record (JSON) here")
    args = parser.parse_args()
    lags = ekf_lags_ms()
    print(f"the EKF's lag on {TRIAL.name}: {lags['ekf_lag_ms']:.2f} +/- {lags['ekf_lag_std_ms']:.2f} ms "
          f"(eq. 13's start {lags['eq13_lag_ms']:.2f} ms; {lags['filter_runs']} filter runs)")
    if args.out:
        from machine_load import measured_at, write_record

        write_record(args.out, {**measured_at(f"python benchmarks/ekf_lag_shipped.py --out {args.out}"),
                                "trial": TRIAL.name, **lags})
        print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
