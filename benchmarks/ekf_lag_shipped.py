"""The lag the EKF searches (`magyro.ekf.method.magnetometer_lag`: eq. (13) on its step-1 field) on the shipped
BROAD trial 07, beside the least squares' (docs/ekf.md, "The magnetometer's lag"). A few seconds.

    python benchmarks/ekf_lag_shipped.py [--out docs/numbers/ekf-lag-shipped.json]
"""
from __future__ import annotations

import argparse
from pathlib import Path

from magyro import load_session
from magyro.ekf.method import EKF, magnetometer_lag, magnetometer_step
from magyro.front.prepare import prepare
from magyro.options import Options

ROOT = Path(__file__).resolve().parent.parent
TRIAL = ROOT / "data" / "broad-07.parquet"


def ekf_lag_ms(path: Path = TRIAL) -> float:
    options = Options()
    prep = prepare(load_session(path), options)
    ref = magnetometer_step(prep.session, prep, EKF().mag_bias_correction)
    return 1e3 * magnetometer_lag(prep.session, ref, prep, options)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--out", help="write the record (JSON) here")
    args = parser.parse_args()
    lag = ekf_lag_ms()
    print(f"the EKF's lag on {TRIAL.name}: {lag:.2f} ms")
    if args.out:
        from machine_load import measured_at, write_record

        write_record(args.out, {**measured_at(f"python benchmarks/ekf_lag_shipped.py --out {args.out}"),
                                "trial": TRIAL.name, "ekf_lag_ms": lag})
        print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
