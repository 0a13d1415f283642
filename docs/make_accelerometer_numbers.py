"""docs/accelerometer.md's numbers, rendered from the records benchmarks/accelerometer.py writes.

    python benchmarks/accelerometer.py sim --problem paper-table1-acc --seeds 20 --out docs/numbers/accelerometer-paper-table1-acc.json
    python benchmarks/accelerometer.py sim --problem phone-module-acc --seeds 20 --out docs/numbers/accelerometer-phone-module-acc.json
    python benchmarks/accelerometer.py real --out docs/numbers/accelerometer-broad-02.json
    python docs/make_accelerometer_numbers.py [--check] [PAGE]      (default: docs/accelerometer.md)

The observe block is `magyro observe data/broad-02.parquet`'s accelerometer section, made afresh (no record).
"""
from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
import doc_blocks  # noqa: E402
from doc_blocks import DOCS, fmt, read_record, table  # noqa: E402

PAGE = DOCS / "accelerometer.md"
COMMAND = "python docs/make_accelerometer_numbers.py"
SIM_RECORDS = {"acc-sim-paper": "accelerometer-paper-table1-acc", "acc-sim-phone": "accelerometer-phone-module-acc"}
REAL_RECORD = "accelerometer-broad-02"


def sim_table(r: dict) -> str:
    """One simulated problem's table: each accelerometer parameter's error, spread and std, and the gyro's summary."""
    bound = "crlb" in r     # records since the accelerometer's Cramer-Rao bound (magyro.studies.crlb_accelerometer)
    rows = [[n, fmt(r["mean_error"][k]), fmt(r["actual"][k]), fmt(r["reported"][k]),
             f"{r['reported'][k] / r['actual'][k]:.2f}", f"{r['max_abs_z'][k]:.1f}"]
            + ([fmt(r["crlb"][k]), f"{r['std_over_crlb'][k]:.2f}", fmt(r["weighted"][k])] if bound else [])
            for k, n in enumerate(r["names"])]
    roa = np.array(r["gyro_reported_over_actual"])
    head = (f"{r['problem']}, {r['seeds']} noise seeds, each with another sway of the hand "
            f"(`{r['provenance']['command']}`, {r['provenance']['date']}, {r['provenance']['commit']}):\n\n")
    tail = (f"\n\nThe gyro beside it: largest |error|/std {max(r['gyro_max_abs_z']):.1f}; its std with the accelerometer "
            f"against without, median {np.median(r['gyro_std_ratio_median']):.2f}, largest "
            f"{max(r['gyro_std_ratio_max']):.2f}; reported/actual {roa.min():.2f}-{roa.max():.2f}.")
    header = ["parameter", "mean error", "actual std", "reported std", "reported/actual", "max abs z"]
    if bound:
        header += ["CRLB", "actual/CRLB", "independent weights"]
        tail += (" CRLB: the Cramer-Rao bound with the hand as noise of its known ensemble (at seed 0's session); "
                 "independent weights: what the solve's weighting reaches with the same hand (not a bound).")
    return head + table(header, rows, left=(0,)) + tail


def real_block(r: dict) -> str:
    """BROAD trial 2: |f| at the rests, the split halves, the gyro's std ratio, the time."""
    rests = "; ".join(f"{a:.1f}-{b:.1f} s: {100 * (x['f_over_g'] - 1):+.3f} % (raw {100 * (x['raw_over_g'] - 1):+.3f} %)"
                      for x in r["rests"] for a, b in [x["span_s"]])
    ratios = list(r["gyro_std_ratio"].values())
    return doc_blocks.notes([
        f"|f| at the rests against g: {rests}.",
        f"Split halves (each half alone, --force): the accelerometer's 12 parameters agree to {r['halves_rms_z']:.2f} "
        f"RMS z (largest |z| {r['halves_max_z']:.1f}, {r['halves_worst']}); the gyro's to {r['halves_gyro_rms_z']:.2f}.",
        f"The gyro's std with the accelerometer against without: {min(ratios):.2f}-{max(ratios):.2f}.",
        f"Solve CPU time: {r['solve_cpu_s']:.2f} s without, {r['solve_cpu_s_accelerometer']:.2f} s with "
        f"({r['solve_cpu_s_accelerometer'] / r['solve_cpu_s']:.2f}x; median of 3, {r['provenance']['machine']}).",
        f"Measured by `{r['provenance']['command']}` ({r['provenance']['date']}, {r['provenance']['commit']})."])


def shortfall(records: list[dict]) -> str:
    """The range of reported/actual and the largest |z| over the simulated problems (a clause)."""
    ratios = [r["reported"][k] / r["actual"][k] for r in records for k in range(len(r["names"]))]
    worst = max(max(r["max_abs_z"]) for r in records)
    return (f"the reported std is {min(ratios):.2f}-{max(ratios):.2f} of the actual spread (above; the largest |z| "
            f"{worst:.1f})")


def observe_block() -> str:
    """`magyro observe data/broad-02.parquet`'s accelerometer section (computed: a second, no solve)."""
    import magyro
    from magyro.io import load_session

    report = magyro.observe(load_session(DOCS.parent / "data" / "broad-02.parquet"))
    return "```\n" + "\n".join(report.accelerometer.table_lines()) + "\n```"


def blocks() -> dict[str, str]:
    out = {block: sim_table(read_record(record)) for block, record in SIM_RECORDS.items()}
    out["acc-observe-broad-02"] = observe_block()
    out["acc-broad-02"] = real_block(read_record(REAL_RECORD))
    out["acc-shortfall"] = shortfall([read_record(record) for record in SIM_RECORDS.values()])
    return out


def main(argv: list[str]) -> int:
    return doc_blocks.main(argv, PAGE, lambda: blocks(), COMMAND)


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
