"""magyro on the degraded corpus: the shipped real trials with each defect of issue 11 applied.

    python benchmarks/degraded_corpus.py [--no-repair] [--only NAME,...] [--out corpus.json]

For each defect of `tests/degrade.py` (`CORPUS`: burst stamps, clipping, a hole, spikes, a held
magnetometer, time in ms/ns, gyro units both ways, magnetometer clock drift and offset, small
shaking, near-single-axis motion) the degraded trial is calibrated with `magyro.calibrate`
(defaults) and compared with the clean trial's calibration. Printed per defect: the exit code
(0, or the `MagyroError`'s), the largest K_g diagonal difference (ppm), the largest bias
difference (deg/s), the misalignment difference (deg, the angle of C_clean^T C), the seconds,
what the recording check finds (warnings and errors), the first warning or the refusal, and
whether the issue's target is met: exit 0 within 2000 ppm, 0.05 deg/s and 0.1 deg, or the
right refusal (its exit code).

`magyro.calibrate` repairs what the recording check knows how to (all repairs on, as `magyro solve`
does); `--no-repair` turns them off, to show what they buy.
"""
from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))

import degrade  # noqa: E402  (tests/degrade.py)

from magyro import calibrate, so3  # noqa: E402
from magyro.errors import MagyroError, one_line  # noqa: E402
from magyro.front.recording import check_recording  # noqa: E402
from magyro.options import Options, Repairs  # noqa: E402

TARGET_PPM, TARGET_BIAS_DEG_S, TARGET_MISALIGNMENT_DEG = 2000.0, 0.05, 0.1


def solve(session, repair: bool) -> dict:
    """Calibrate (the repairs on or off): the numbers compared, or the refusal."""
    t0 = time.perf_counter()
    try:
        cal = calibrate(session, Options(repairs=Repairs() if repair else Repairs.none()))
    except MagyroError as exc:
        return {"exit": exc.exit_code, "message": one_line(exc, None), "seconds": time.perf_counter() - t0}
    except Exception as exc:  # a bug: the CLI would say "internal error", exit 1; the issue wants none
        return {"exit": "TB", "message": f"traceback: {type(exc).__name__}: {one_line(exc, None)}",
                "seconds": time.perf_counter() - t0}
    return {"exit": 0, "K_g_diag": np.diag(cal.K_g).tolist(), "bias_deg_s": np.asarray(cal.bias_deg_s).tolist(),
            "C_b_m": np.asarray(cal.C_b_m).tolist(), "message": cal.warnings[0] if cal.warnings else "",
            "warnings": list(cal.warnings), "seconds": time.perf_counter() - t0}


def compare(result: dict, clean: dict) -> dict:
    if result["exit"] != 0 or clean["exit"] != 0:
        return {}
    C = np.asarray(clean["C_b_m"]).T @ np.asarray(result["C_b_m"])
    return {"dK_ppm": float(np.max(np.abs(np.subtract(result["K_g_diag"], clean["K_g_diag"]))) * 1e6),
            "dbias_deg_s": float(np.max(np.abs(np.subtract(result["bias_deg_s"], clean["bias_deg_s"])))),
            "dmisalignment_deg": float(np.degrees(np.linalg.norm(so3.log_so3(C))))}


def verdict(result: dict, diff: dict, expected) -> str:
    if expected is None:
        return "-"
    if result["exit"] != expected:
        return f"NO (want {expected})"
    if expected != 0:
        return "yes"
    ok = (diff["dK_ppm"] <= TARGET_PPM and diff["dbias_deg_s"] <= TARGET_BIAS_DEG_S
          and diff["dmisalignment_deg"] <= TARGET_MISALIGNMENT_DEG)
    return "yes" if ok else "NO (numbers)"


def check_summary(session) -> str:
    check = check_recording(session)
    found = [f"{f.kind}{'!' if f.severity == 'error' else ''}" for f in check.findings if f.severity != "info"]
    return ",".join(dict.fromkeys(found)) or "-"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--no-repair", dest="repair", action="store_false", help="turn the recording repairs off")
    parser.add_argument("--only", default="", help="comma-separated defect names (substrings) to run")
    parser.add_argument("--out", type=Path, help="write every result as JSON")
    args = parser.parse_args()
    wanted = [w.strip() for w in args.only.split(",") if w.strip()]
    corpus = [c for c in degrade.CORPUS if not wanted or any(w in c[0] for w in wanted)]

    clean_sessions = {trial: degrade.load(trial) for trial in sorted({c[1] for c in corpus})}
    clean = {trial: solve(s, args.repair) for trial, s in clean_sessions.items()}
    rows, out = [], {"repair": args.repair, "clean": clean, "corpus": []}
    header = (f"{'defect':<30}{'trial':<10}{'exit':>5}{'dK_g ppm':>10}{'dbias deg/s':>12}{'dmis deg':>9}{'s':>6}"
              f"  {'target':<13}{'check finds':<34}first warning / message")
    print(f"degraded corpus, {'with' if args.repair else 'without'} the recording repairs; clean: " + ", ".join(
        f"{t} exit {r['exit']} in {r['seconds']:.1f} s" for t, r in clean.items()))
    print(header)
    print("-" * len(header))
    for name, trial, make, expected in corpus:
        session = make(clean_sessions[trial])
        result = solve(session, args.repair)
        diff = compare(result, clean[trial])
        row = (f"{name:<30}{trial:<10}{str(result['exit']):>5}"
               + (f"{diff['dK_ppm']:>10.0f}{diff['dbias_deg_s']:>12.3f}{diff['dmisalignment_deg']:>9.3f}" if diff
                  else f"{'':>10}{'':>12}{'':>9}")
               + f"{result['seconds']:>6.1f}  {verdict(result, diff, expected):<13}{check_summary(session)[:33]:<34}"
               + result["message"][:150])
        print(row, flush=True)
        rows.append(row)
        out["corpus"].append({"defect": name, "trial": trial, "expected_exit": expected, **result, **diff})
    if args.out:
        args.out.write_text(json.dumps(out, indent=2) + "\n")


if __name__ == "__main__":
    main()
