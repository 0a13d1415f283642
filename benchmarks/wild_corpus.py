"""Every real recording of other devices in ../shared/data/wild, as a new user would run magyro on it (issue 38).

    python benchmarks/wild_corpus.py [--wild ../shared/data/wild] [--out FILE]

Each recording is imported with `magyro import` (the arguments in IMPORTS), then `magyro check`, `magyro observe`,
`magyro solve` and `magyro solve --method ekf` run on it. Printed per recording and command: the exit code, the
seconds, the refusal's first words, and whether the terminal showed a traceback, a Python warning or a "nan".
Targets: observe 0 implies solve 0; no exit 1; every refusal names the true cause; nothing a user should never see.
"""
from __future__ import annotations

import argparse
import datetime
import json
import re
import subprocess
import sys
import tempfile
import time
from pathlib import Path

NAN = re.compile(r"\bnan\b", re.IGNORECASE)


def imports(wild: Path) -> dict[str, tuple]:
    """name -> the `magyro import` arguments (the output added), for what is in `wild`."""
    out = {
        "fusion": ("csv", wild / "fusion" / "sensor_data.csv", "--gyro-unit", "deg/s", "--mag-unit", "uT",
                   "--acc-unit", "g"),
        "simorxb": ("csv", wild / "simorxb", "--preset", "sensor-logger"),
        "bennyjhui": ("csv", wild / "bennyjhui", "--preset", "sensor-logger"),
        "phidgets-2013": ("rosbag", wild / "imu_tools" / "imutools-2013-phidgets_imu_upside_down.bag"),
        "phidgets-2017": ("rosbag", wild / "imu_tools" / "imutools-2017-phidgets_imu_upside_down.bag"),
        "arduplane-testlog2": ("dataflash", wild / "inertialnav" / "TestLog2.mat"),
    }
    for name in ("InputFilesPX4", "InputFilesPX4_bench", "f450_glitch_log", "quad106"):
        out[name] = ("dataflash", wild / "inertialnav" / f"{name}.zip")
    return out


def magyro(*args, timeout: float = 900) -> dict:
    t0 = time.perf_counter()
    exe = Path(sys.executable).with_name("magyro")
    result = subprocess.run([str(exe), *map(str, args)], capture_output=True, text=True, timeout=timeout)
    both = result.stdout + result.stderr
    refusal = [line[len("magyro:"):].strip() for line in result.stderr.splitlines() if line.startswith("magyro:")]
    return {"exit": result.returncode, "seconds": round(time.perf_counter() - t0, 1),
            "message": refusal[-1][:400] if refusal else None,
            "unseen_by_users": [what for what, seen in (("traceback", "Traceback" in both),
                                                        ("warning", "Warning" in result.stderr),
                                                        ("nan", bool(NAN.search(both)))) if seen]}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--wild", type=Path, default=Path(__file__).resolve().parents[2] / "shared" / "data" / "wild")
    ap.add_argument("--only", default=None, help="comma-separated names")
    ap.add_argument("--out", type=Path, default=None)
    args = ap.parse_args()
    rows = []
    with tempfile.TemporaryDirectory() as folder:
        for name, (kind, *rest) in imports(args.wild).items():
            if args.only and name not in args.only.split(","):
                continue
            session = Path(folder) / f"{name}.parquet"
            row = {"name": name, "import": magyro("import", kind, *rest, "-o", session)}
            if row["import"]["exit"] == 0:
                row["check"] = magyro("check", session)
                row["observe"] = magyro("observe", session)
                row["solve"] = magyro("solve", session, "-o", Path(folder) / f"{name}.json")
                row["ekf"] = magyro("solve", session, "--method", "ekf", "-o", Path(folder) / f"{name}-ekf.json")
            rows.append(row)
            print(json.dumps(row), flush=True)
    solved = [r for r in rows if "solve" in r]
    summary = {
        "observe_0_implies_solve_0": all(r["solve"]["exit"] == 0 for r in solved if r["observe"]["exit"] == 0),
        "exit_1": [f"{r['name']} {c}" for r in solved for c in ("solve", "ekf") if r[c]["exit"] == 1],
        "unseen_by_users": [f"{r['name']} {c}: {r[c]['unseen_by_users']}" for r in rows for c in
                            ("import", "check", "observe", "solve", "ekf") if c in r and r[c]["unseen_by_users"]],
    }
    print(json.dumps(summary))
    if args.out:
        commit = subprocess.run(["git", "rev-parse", "--short", "HEAD"], capture_output=True, text=True).stdout.strip()
        args.out.write_text(json.dumps({"date": datetime.date.today().isoformat(), "commit": commit,
                                        "command": f"python benchmarks/wild_corpus.py --out {args.out}",
                                        "summary": summary, "rows": rows}, indent=1) + "\n")


if __name__ == "__main__":
    main()
