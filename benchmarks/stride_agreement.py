"""Do fewer attitude nodes cost accuracy? One session solved at two strides: the largest difference of the twelve
gyro parameters between the two solves, in units of the denser solve's reported std (docs/how-it-works.md "Nodes").

    python benchmarks/stride_agreement.py [--out docs/numbers/stride-agreement.json]

Cases: paper-table1 (seed 0) at strides 12 and 4, and the shipped BROAD trial 02 at strides 12 and 4 (both
strides' kernels are installed; a stride of one's own compiles its kernels first, minutes).
"""
from __future__ import annotations

import argparse
import time
from pathlib import Path

import magyro
from magyro.result.consistency import gyro_stds, gyro_values
from magyro.studies.scenario import load_problem
from magyro.studies.simulate import simulate

ROOT = Path(__file__).resolve().parent.parent
CASES = (("paper-table1 seed 0", 12, 4), ("BROAD 02 (data/broad-02.parquet)", 12, 4))


def session_of(name: str):
    if name.startswith("paper-table1"):
        return simulate(load_problem("paper-table1"), 0)[0]
    return magyro.load_session(ROOT / "data" / "broad-02.parquet")


def compare(name: str, sparse: int, dense: int) -> dict:
    session = session_of(name)
    t0 = time.perf_counter()
    a = magyro.calibrate(session, method=magyro.NLS(stride=sparse))
    b = magyro.calibrate(session, method=magyro.NLS(stride=dense))
    va, vb, sb = gyro_values(a, b.C_b_m), gyro_values(b, b.C_b_m), gyro_stds(b)
    z = {k: (va[k] - vb[k]) / sb[k] for k in vb}
    worst = max(z, key=lambda k: abs(z[k]))
    return {"case": name, "strides": [sparse, dense], "max_abs_z": abs(z[worst]), "worst": worst,
            "z": z, "seconds": time.perf_counter() - t0}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--out", help="write the record (JSON) here")
    args = parser.parse_args()
    rows = []
    for case in CASES:
        rows.append(compare(*case))
        print(f"{rows[-1]['case']}: strides {case[1]} and {case[2]} differ by at most "
              f"{rows[-1]['max_abs_z']:.3f} std ({rows[-1]['worst']}), {rows[-1]['seconds']:.0f} s")
    if args.out:
        from machine_load import measured_at, write_record

        write_record(args.out, {**measured_at(f"python benchmarks/stride_agreement.py --out {args.out}"), "rows": rows})
        print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
