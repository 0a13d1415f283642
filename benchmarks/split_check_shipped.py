"""The split-half check of the shipped BROAD trial as a user runs it: `magyro solve data/broad-02.parquet --split-check`.

    python benchmarks/split_check_shipped.py [--out docs/numbers/split-check-shipped.json]

Runs the command itself (default options: the accelerometer in the least squares, as the shipped trial has one)
and keeps its JSON's `consistency`: the RMS z of the twelve gyro parameters' half differences, the largest |z| and
its parameter. This is the whole shipped recording, with the accelerometer; benchmarks/std_on_real_data.py's split
RMS z is another cut (the .mat trials' movement +/- 10 s, without the accelerometer). One solve and its two halves:
under a minute on a quiet 2-core machine.
"""
from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
SESSIONS = ("data/broad-02.parquet",)


def split_check(session: str) -> dict:
    """`magyro solve SESSION --split-check`'s consistency, and the command's wall time."""
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp) / "calibration.json"
        t0 = time.perf_counter()
        subprocess.run([sys.executable, "-m", "magyro", "solve", session, "--split-check", "-o", str(out)], cwd=ROOT,
                       check=True, capture_output=True, text=True)
        seconds = time.perf_counter() - t0
        c = json.loads(out.read_text(encoding="utf-8"))["consistency"]
    return {"session": session, "command": f"magyro solve {session} --split-check", "rms_z": c.get("rms_z"),
            "max_abs_z": c.get("max_abs_z"), "worst": c.get("worst"), "failed": c.get("failed", []),
            "spans_s": c["spans_s"], "seconds": seconds}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--out", help="write the record (JSON) here")
    args = parser.parse_args()
    rows = []
    for session in SESSIONS:
        rows.append(split_check(session))
        r = rows[-1]
        print(f"{r['command']}: RMS z {r['rms_z']:.2f}, largest |z| {r['max_abs_z']:.2f} ({r['worst']}), "
              f"{r['seconds']:.0f} s")
    if args.out:
        sys.path.insert(0, str(Path(__file__).resolve().parent))
        from machine_load import measured_at, write_record

        write_record(args.out, {**measured_at(f"python benchmarks/split_check_shipped.py --out {args.out}"),
                                "rows": rows})
        print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
