"""The accelerometer (`--accelerometer`) on every real recording at hand: what a user gets on each.

    python benchmarks/accelerometer_real.py [--only NAME,NAME] [--broad ../shared/data/broad] [--wild ../shared/data/wild]
                                           [--ulog ../shared/data/ulog] [--trials 03,05,09,21,30,32,34,36]
                                           [--no-hand-states] [--out docs/numbers/accelerometer-real.json]

The recordings: the shipped BROAD trials 02 and 07 (data/), the shipped x-io board (data/wild/fusion) and PX4 log
(data/px4-sample-appended-multiple.ulg); when ../shared is there, its recordings of other devices (wild/: the same
x-io board, two phones through Sensor Logger, ROS bags of a Phidgets board and a SparkFun Razor), its second PX4 log
and BROAD trials (imported as benchmarks/broad_trials.py does: the movement span +/- 10 s). Each is imported the
way tests/test_wild_corpus.py and docs say (the x-io board with --acc-unit g), then solved twice with the defaults,
without and with `Options(accelerometer=True)`.

Per recording: the exit code and message of a refusal (import or solve); else the calibrated |f| at the rests
(`magyro.front.rests.find_rests`) against g beside the raw reading's, K_a's diagonal, the bias (m/s^2) and the
misalignment C_b_a (roll pitch yaw, deg) with their std, the lever arm the solve estimates, and the gyro's 12 std
with the accelerometer over those without (where gravity adds to a weak field direction the ratio drops below 1);
with an optical truth (BROAD) the gyro's dead-reckoning RMS (`magyro.studies.dead_reckoning.validate`) raw, without
and with. A refusal with the accelerometer for the motion or the std (exit 3) is forced too (`--force`), so the
table shows what it would have reported; a solve without the accelerometer refused with exit 3 is forced for the
std ratio and the dead reckoning (the record says so). The recording check's accelerometer findings (unit, saturation) are kept for every
recording that has an accelerometer. `--out` writes the record docs/accelerometer.md's real-data table is rendered
from (docs/make_accelerometer_numbers.py).

Data: BROAD (CC BY 4.0), D. Laidig, M. Caruso, A. Cereatti, T. Seel, "BROAD - A Benchmark for Robust Inertial
Orientation Estimation", Data 6(7):72, 2021; the others as data/PROVENANCE.md and ../shared/data/*/README.md say.
"""
from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

from machine_load import measured_at, write_record
from magyro import calibrate, load_session
from magyro.errors import MagyroError, one_line
from magyro.options import Options

ROOT = Path(__file__).resolve().parents[1]
SHARED = ROOT.parent / "shared" / "data"
DEFAULT_TRIALS = "03,05,09,21,30,32,34,36"
MARGIN_S = 10.0          # as benchmarks/broad_trials.py
MAGNET_TRIALS = ("30", "32", "34", "36")


def recordings(broad: Path, wild: Path, ulog: Path, trials: list[str]) -> list[dict]:
    """name, what it is, and how to import it (a function giving the Session), in table order; those whose files
    are absent are listed with `absent` (the reason) instead."""
    from magyro.io import import_broad_movement, import_csv, import_preset, import_rosbag, import_ulog

    def csv_xio(path):
        return lambda: import_csv(path, None, gyro_unit="deg/s", mag_unit="uT", acc_unit="g")

    out = [
        {"name": "broad-02", "what": "BROAD trial 2 (shipped; rests 3 s)", "files": [ROOT / "data" / "broad-02.parquet"],
         "load": lambda: load_session(ROOT / "data" / "broad-02.parquet")},
        {"name": "broad-07", "what": "BROAD trial 7, fast (shipped)", "files": [ROOT / "data" / "broad-07.parquet"],
         "load": lambda: load_session(ROOT / "data" / "broad-07.parquet")},
        {"name": "fusion", "what": "x-io board, accelerometer in g (shipped data/wild)",
         "files": [ROOT / "data" / "wild" / "fusion" / "sensor_data.csv"],
         "load": csv_xio(ROOT / "data" / "wild" / "fusion" / "sensor_data.csv")},
        {"name": "px4-appended", "what": "PX4 log, board on a bench (shipped)",
         "files": [ROOT / "data" / "px4-sample-appended-multiple.ulg"],
         "load": lambda: import_ulog(ROOT / "data" / "px4-sample-appended-multiple.ulg")},
        {"name": "px4-small", "what": "PX4 log, 6.5 s on the ground", "files": [ulog / "sample_log_small.ulg"],
         "load": lambda: import_ulog(ulog / "sample_log_small.ulg")},
        {"name": "simorxb", "what": "Android phone (Sensor Logger, uncalibrated files)", "files": [wild / "simorxb"],
         "load": lambda: import_preset([wild / "simorxb"], "sensor-logger")},
        {"name": "bennyjhui", "what": "iPhone 12 (Sensor Logger, calibrated files)", "files": [wild / "bennyjhui"],
         "load": lambda: import_preset([wild / "bennyjhui"], "sensor-logger")},
        {"name": "phidgets-2013", "what": "Phidgets Spatial on a robot (ROS1 bag, older driver)",
         "files": [wild / "imu_tools" / "imutools-2013-phidgets_imu_upside_down.bag"],
         "load": lambda: import_rosbag(wild / "imu_tools" / "imutools-2013-phidgets_imu_upside_down.bag")},
        {"name": "phidgets-2017", "what": "Phidgets Spatial on a robot (ROS1 bag)",
         "files": [wild / "imu_tools" / "imutools-2017-phidgets_imu_upside_down.bag"],
         "load": lambda: import_rosbag(wild / "imu_tools" / "imutools-2017-phidgets_imu_upside_down.bag")},
        {"name": "razor-2013", "what": "SparkFun 9DOF Razor, +/-2 g (ROS1 bag)",
         "files": [wild / "imu_tools" / "imutools-2013-sparkfun_razor.bag"],
         "load": lambda: import_rosbag(wild / "imu_tools" / "imutools-2013-sparkfun_razor.bag")},
    ]
    for trial in trials:
        found = sorted(broad.glob(f"{trial}_*.mat"))
        path = found[0] if found else broad / f"{trial}_*.mat"
        magnet = " (magnet)" if trial in MAGNET_TRIALS else ""
        out.append({"name": f"broad-{trial}", "what": f"BROAD trial {int(trial)}{magnet}, +/- {MARGIN_S:g} s",
                    "files": [path], "load": (lambda p=path: import_broad_movement(p, MARGIN_S))})
    for r in out:
        missing = [f for f in r["files"] if not f.exists()]
        if missing:
            r["absent"] = f"{missing[0]} not found"
    return out


METHOD = {"hand_states": True}   # --no-hand-states: NLS(hand_states=False) for every solve


def solve(session, options: Options) -> dict:
    from magyro.nls.method import NLS

    t0 = time.process_time()
    try:
        cal = calibrate(session, options, NLS(hand_states=METHOD["hand_states"]))
    except MagyroError as exc:
        return {"exit": exc.exit_code, "message": one_line(exc, None), "cpu_s": time.process_time() - t0}
    except Exception as exc:   # a defect, not a refusal: recorded as such, and the other recordings still run
        return {"exit": "traceback", "message": f"{type(exc).__name__}: {exc}", "cpu_s": time.process_time() - t0}
    return {"exit": 0, "cal": cal, "cpu_s": time.process_time() - t0}


def accelerometer_findings(session) -> list[dict]:
    """The recording check's findings on the accelerometer (unit, saturation), as the check prints them."""
    from magyro.front.recording import check_recording

    return [{"kind": f.kind, "severity": f.severity, "message": f.message}
            for f in check_recording(session).findings if f.sensor == "accelerometer"]


def at_rests(session, acc, g: float) -> list[dict]:
    """|f| (calibrated; without `acc` only the raw) and |y| (raw), each rest's mean, over g."""
    from magyro.front.rests import find_rests

    out = []
    for a, b in find_rests(session).segments_s:
        keep = (session.t_acc_s >= a) & (session.t_acc_s <= b)
        if keep.sum() < 2:
            continue
        out.append({"span_s": [float(a), float(b)],
                    "raw_over_g": float(np.linalg.norm(session.acc_m_s2[keep], axis=1).mean() / g)})
        if acc is not None:
            out[-1]["f_over_g"] = float(np.linalg.norm(acc.apply(session.acc_m_s2[keep]), axis=1).mean() / g)
    return out


def numbers(cal, session, base) -> dict:
    """What a solve with the accelerometer reports on it, beside the solve without (`base`, or None)."""
    from magyro.result.consistency import gyro_stds

    acc = cal.accelerometer
    out = {
        "rests": at_rests(session, acc, acc.g_m_s2),
        "K_a_diag": np.diag(acc.K_a).tolist(), "K_a_diag_std": np.diag(acc.std_K_a).tolist(),
        "K_a_upper": [acc.K_a[0, 1], acc.K_a[0, 2], acc.K_a[1, 2]],
        "K_a_upper_std": [acc.std_K_a[0, 1], acc.std_K_a[0, 2], acc.std_K_a[1, 2]],
        "bias_m_s2": acc.bias_m_s2.tolist(), "bias_std_m_s2": acc.std_bias_m_s2.tolist(),
        "euler_deg": acc.euler_deg.tolist(), "misalignment_std_deg": acc.std_misalignment_deg.tolist(),
        "lever_arm_m": None if acc.lever_arm_m is None else acc.lever_arm_m.tolist(),
        "warnings": [str(w) for w in cal.warnings], "iterations": cal.solver.iterations, "status": cal.solver.status,
    }
    if base is not None:
        reference = gyro_stds(base)
        out["gyro_std_ratio"] = {k: v / reference[k] for k, v in gyro_stds(cal).items()}
    return out


def dead_reckoning_deg(session, cal) -> float:
    """RMS attitude error (deg) of the gyro dead-reckoned with `cal` (None: raw) against the session's truth."""
    from magyro.studies.dead_reckoning import validate

    summary = validate(session, cal).to_dict()["summary"]
    return float(summary["raw" if cal is None else "calibrated"]["rms_deg"])


def run(r: dict) -> dict:
    """One recording's row of the record: the solves without and with the accelerometer; a refusal for the motion
    or the std (exit 3) forced too, to show what would have been reported."""
    row = {"name": r["name"], "what": r["what"]}
    if "absent" in r:
        return {**row, "absent": r["absent"]}
    try:
        session = r["load"]()
    except MagyroError as exc:
        return {**row, "stage": "import", "exit": exc.exit_code, "message": one_line(exc, None)}
    row.update({"duration_s": float(session.duration_s), "has_accelerometer": session.acc_m_s2 is not None})
    if session.acc_m_s2 is not None:
        row["acc_findings"] = accelerometer_findings(session)
        row["raw_rests"] = at_rests(session, None, Options().gravity_m_s2)   # the import's unit, whatever the solve
    without = solve(session, Options(accelerometer=False))
    row.update({"stage": "solve", "exit_without": without["exit"], "cpu_s_without": without["cpu_s"]})
    if without["exit"]:
        row["message_without"] = without["message"]
    else:
        row["warnings_without"] = [str(w) for w in without["cal"].warnings]
    if without["exit"] == 3:   # refused for its std or its motion: what it would have given, for the comparison
        without = solve(session, Options(force=True, accelerometer=False))
        row["forced_exit_without"] = without["exit"]
        if without["exit"]:
            row["forced_message_without"] = without["message"]
    base = None if without["exit"] else without["cal"]
    row["without_forced"] = bool(row["exit_without"]) and base is not None
    if session.quat_wxyz is not None:
        row["dead_reckoning_rms_deg"] = {"raw": dead_reckoning_deg(session, None),
                                         "without": None if base is None else dead_reckoning_deg(session, base),
                                         "with": None}
    with_acc = solve(session, Options(accelerometer=True))
    row.update({"exit": with_acc["exit"], "cpu_s": with_acc["cpu_s"]})
    if with_acc["exit"]:
        row["message"] = with_acc["message"]
        if with_acc["exit"] != 3:
            return row
        with_acc = solve(session, Options(accelerometer=True, force=True))
        row["forced_exit"] = with_acc["exit"]
        row["forced_cpu_s"] = with_acc["cpu_s"]
        if with_acc["exit"]:
            row["forced_message"] = with_acc["message"]
            return row
    row["forced" if row["exit"] else "solved"] = numbers(with_acc["cal"], session, base)
    if session.quat_wxyz is not None:
        row["dead_reckoning_rms_deg"]["with"] = dead_reckoning_deg(session, with_acc["cal"])
    return row


# --------------------------------------------------------------------------- the table


def rests_text(n: dict) -> str:
    return "; ".join(f"{100 * (x['f_over_g'] - 1):+.2f} ({100 * (x['raw_over_g'] - 1):+.2f})" for x in n["rests"]) or "no rest"


def ratio_text(row: dict, n: dict) -> str:
    if "gyro_std_ratio" not in n:
        return "-"
    v = np.array(list(n["gyro_std_ratio"].values()))
    forced = " (against the solve without, forced)" if row.get("without_forced") else ""
    return f"{v.min():.2f}-{v.max():.2f} (median {np.median(v):.2f}){forced}"


def saturation_text(row: dict) -> str:
    found = [f for f in row.get("acc_findings", []) if f["kind"] == "saturation"]
    return f"; the accelerometer saturates ({len(found)} axis-signs, recording check)" if found else ""


def print_numbers(row: dict, n: dict) -> None:
    print(f"    |f|/g - 1 at the rests, % (raw): {rests_text(n)}")
    print("    K_a diagonal " + "  ".join(f"{v:.4f} +/- {s:.4f}" for v, s in zip(n["K_a_diag"], n["K_a_diag_std"])))
    print("    bias (m/s^2) " + "  ".join(f"{v:+.3f} +/- {s:.3f}" for v, s in zip(n["bias_m_s2"], n["bias_std_m_s2"])))
    print("    C_b_a roll pitch yaw (deg) " + "  ".join(f"{v:+.2f} +/- {s:.2f}" for v, s in
                                                         zip(n["euler_deg"], n["misalignment_std_deg"])))
    if n.get("lever_arm_m") is not None:
        print("    lever arm (m) " + "  ".join(f"{v:+.3f}" for v in n["lever_arm_m"]))
    for w in n["warnings"]:
        print(f"    warning: {w}")
    print(f"    gyro std with/without the accelerometer: {ratio_text(row, n)}")
    if "dead_reckoning_rms_deg" in row:
        dr = row["dead_reckoning_rms_deg"]
        print("    dead-reckoning RMS against the optical truth (deg): "
              + ", ".join(f"{k} {'-' if v is None else f'{v:.2f}'}" for k, v in dr.items()))


def print_table(rows: list[dict]) -> None:
    for row in rows:
        head = f"{row['name']:14s} {row['what']}"
        if "absent" in row:
            print(f"{head}: skipped, {row['absent']}")
            continue
        if row["stage"] == "import":
            print(f"{head}: import refused, exit {row['exit']}: {row['message']}")
            continue
        other = "" if row["exit_without"] == row["exit"] else f" (without the accelerometer: exit {row['exit_without']})"
        print(f"{head}: exit {row['exit']}{other}{saturation_text(row)}" + (f": {row['message']}" if row["exit"] else ""))
        if "forced_exit" in row:
            print(f"    forced (--force): exit {row['forced_exit']}" + (f": {row['forced_message']}" if row["forced_exit"] else ""))
        if "forced_exit_without" in row:
            print(f"    without the accelerometer, forced: exit {row['forced_exit_without']}"
                  + (f": {row['forced_message_without']}" if row["forced_exit_without"] else ""))
        for w in row.get("warnings_without", []):
            print(f"    warning without the accelerometer: {w}")
        n = row.get("solved") or row.get("forced")
        if n is not None:
            print_numbers(row, n)
        if n is None and "dead_reckoning_rms_deg" in row:
            dr = row["dead_reckoning_rms_deg"]
            print("    dead-reckoning RMS against the optical truth (deg): "
                  + ", ".join(f"{k} {'-' if v is None else f'{v:.2f}'}" for k, v in dr.items()))
        if n is None and row.get("raw_rests"):
            print("    raw |y|/g - 1 at the rests, %: " + "; ".join(f"{100 * (x['raw_over_g'] - 1):+.2f}"
                                                               for x in row["raw_rests"]))


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--broad", type=Path, default=SHARED / "broad")
    ap.add_argument("--wild", type=Path, default=SHARED / "wild")
    ap.add_argument("--ulog", type=Path, default=SHARED / "ulog")
    ap.add_argument("--trials", default=DEFAULT_TRIALS, help="BROAD trials from --broad (comma-separated)")
    ap.add_argument("--only", help="run these recordings only (comma-separated names)")
    ap.add_argument("--no-hand-states", dest="hand_states", action="store_false",
                    help="weight the accelerometer by the hand instead of taking its velocity as states "
                         "(NLS(hand_states=False), magyro solve --no-hand-states)")
    ap.add_argument("--out", help="write the record here (docs/numbers/accelerometer-real.json)")
    a = ap.parse_args(argv)
    METHOD["hand_states"] = a.hand_states
    chosen = recordings(a.broad, a.wild, a.ulog, [t.strip() for t in a.trials.split(",") if t.strip()])
    if a.only:
        names = {n.strip() for n in a.only.split(",")}
        chosen = [r for r in chosen if r["name"] in names]
    rows = []
    command = "python benchmarks/accelerometer_real.py " + " ".join(argv or [])
    for r in chosen:
        row = run(r)
        print_table([row])
        sys.stdout.flush()
        rows.append(row)
        if a.out:   # after every recording: a long run stopped half way keeps what it measured
            write_record(a.out, {"rows": rows, "gravity_m_s2": Options().gravity_m_s2, "complete": len(rows) == len(chosen),
                                 "provenance": measured_at(command.strip())})


if __name__ == "__main__":
    main(sys.argv[1:])
