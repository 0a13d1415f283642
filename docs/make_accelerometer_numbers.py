"""docs/accelerometer.md's numbers, rendered from the records benchmarks/accelerometer.py writes.

    python benchmarks/accelerometer.py sim --problem paper-table1-acc --seeds 200 --jobs 2 --out docs/numbers/accelerometer-paper-table1-acc.json
    python benchmarks/accelerometer.py sim --problem phone-module-acc --seeds 200 --jobs 2 --out docs/numbers/accelerometer-phone-module-acc.json
    python benchmarks/accelerometer.py real --out docs/numbers/accelerometer-broad-02.json
    python benchmarks/accelerometer_real.py --out docs/numbers/accelerometer-real.json
    python benchmarks/accelerometer_hand_models.py --out docs/numbers/accelerometer-hand-models.json
    python benchmarks/hand_states_std.py --problem paper-table1-acc --seeds 64 --out docs/numbers/hand-states-std-paper-table1-acc.json
    python benchmarks/hand_states_std.py --problem phone-module-acc --seeds 64 --out docs/numbers/hand-states-std-phone-module-acc.json
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
STILL_RECORD = "accelerometer-paper-table1-acc-still"    # the same problem turned about itself (`sim --still`)
REAL_RECORD = "accelerometer-broad-02"
EVERY_REAL_RECORD = "accelerometer-real"
HAND_MODELS_RECORD = "accelerometer-hand-models"
HAND_STD_RECORDS = ["hand-states-std-paper-table1-acc", "hand-states-std-phone-module-acc"]


def sim_table(r: dict) -> str:
    """One simulated problem's table: each accelerometer parameter's error, spread and std, and the gyro's summary."""
    bound = "crlb" in r     # records since the accelerometer's Cramer-Rao bound (magyro.studies.crlb_accelerometer)
    rows = [[n, fmt(r["mean_error"][k]), fmt(r["actual"][k]), fmt(r["reported"][k]),
             f"{r['reported'][k] / r['actual'][k]:.2f}", f"{r['max_abs_z'][k]:.1f}"]
            + ([fmt(r["crlb"][k]), f"{r['std_over_crlb'][k]:.2f}", fmt(r["weighted"][k])] if bound else [])
            for k, n in enumerate(r["names"])]
    roa = np.array(r["gyro_reported_over_actual"])
    sway = "no hand translation" if r.get("still") else "each with another sway of the hand"
    head = (f"{r['problem']}, {r['seeds']} noise seeds, {sway} "
            f"(`{r['provenance']['command']}`, {r['provenance']['date']}, {r['provenance']['commit']}):\n\n")
    tail = (f"\n\nThe gyro beside it: largest |error|/std {max(r['gyro_max_abs_z']):.1f}; its std with the accelerometer "
            f"against without, median {np.median(r['gyro_std_ratio_median']):.2f}, largest "
            f"{max(r['gyro_std_ratio_max']):.2f}; reported/actual {roa.min():.2f}-{roa.max():.2f}.")
    header = ["parameter", "mean error", "actual std", "reported std", "reported/actual", "max abs z"]
    if bound:
        header += ["CRLB", "actual/CRLB", "independent weights"]
        tail += (" CRLB: the Cramer-Rao bound with the hand as noise of its known ensemble (at seed 0's session); "
                 "independent weights: what weighting every interval as independent, by its hand, reaches with the "
                 "same hand (not a bound; `--no-hand-states` before its correlation factor)." + (
                     " Solved with the hand's velocity as states (the default)." if r.get("hand_states") else
                     " Solved with the hand as weights (`--no-hand-states`, before the hand as states)."))
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
    """The range of reported/actual and the largest |z| per simulated problem (a clause)."""
    parts = []
    for r in records:
        ratios = [r["reported"][k] / r["actual"][k] for k in range(len(r["names"]))]
        parts.append(f"{min(ratios):.2f}-{max(ratios):.2f} on {r['problem']} ({r['seeds']} seeds, the largest |z| "
                     f"{max(r['max_abs_z']):.1f})")
    return "the reported std is " + " and ".join(parts) + " of the actual spread"


def speed(r: dict) -> str:
    """BROAD 02's CPU time with the accelerometer over without (a clause)."""
    return f"{r['solve_cpu_s_accelerometer'] / r['solve_cpu_s']:.2f}x"


def reason(message: str) -> str:
    """A refusal's cause, its first clause: what the table says of a refused recording."""
    first = message.removeprefix("--accelerometer: ").split(": ")[0].split("; ")[0].split(" (")[0]
    return doc_blocks.escape(first if len(first) <= 120 else first[:117].rsplit(" ", 1)[0] + " ...")


def plus_minus(values, stds, digits: int, sign: bool = False) -> str:
    return ", ".join(f"{v:{'+' if sign else ''}.{digits}f}±{s:.{digits}f}" for v, s in zip(values, stds))


def exit_cell(row: dict) -> str:
    """The exit code with the accelerometer (its cause when refused), the one without when it differs, and what
    --force gave for a refusal for the motion or the std."""
    if row["stage"] == "import":
        return f"import: {row['exit']}, {reason(row['message'])}"
    if row["exit"] == "traceback":   # a defect the benchmark caught, not a refusal
        return f"traceback: {doc_blocks.escape(row['message'].strip())}" + (
            f" (without: {row['exit_without']})" if row["exit_without"] != row["exit"] else "")
    cell = str(row["exit"]) + (f", {reason(row['message'])}" if row["exit"] else "")
    if row["exit_without"] != row["exit"]:
        cell += f" (without: {row['exit_without']})"
    if "forced_exit" in row:
        cell += f"; forced: {row['forced_exit']}" + (f", {reason(row['forced_message'])}" if row["forced_exit"] else "")
    return cell


def dead_reckoning_cell(row: dict) -> str:
    dr = row.get("dead_reckoning_rms_deg")
    if dr is None:
        return "-"
    return " / ".join("-" if dr[k] is None else f"{dr[k]:.2f}" for k in ("raw", "without", "with"))


def real_row(row: dict) -> list[str]:
    """One recording: what is reported on it with the accelerometer (or, forced, would have been), the gyro beside."""
    what = f"{row['name']}: {row['what']}"
    saturates = [f for f in row.get("acc_findings", []) if f["kind"] == "saturation"]
    if saturates:
        what += f"; the accelerometer saturates ({len(saturates)} axis-signs, `magyro check`)"
    n = row.get("solved") or row.get("forced")
    if n is None:
        raw = "; ".join(f"({100 * (x['raw_over_g'] - 1):+.2f})" for x in row.get("raw_rests", []))
        return [doc_blocks.escape(what), exit_cell(row), raw or "-"] + ["-"] * 4 + [dead_reckoning_cell(row)]
    rests = "; ".join(f"{100 * (x['f_over_g'] - 1):+.2f} ({100 * (x['raw_over_g'] - 1):+.2f})" for x in n["rests"])
    ratio = "-"
    if "gyro_std_ratio" in n:
        v = np.array(list(n["gyro_std_ratio"].values()))
        ratio = f"{v.min():.2f}-{v.max():.2f}, median {np.median(v):.2f}" + (" (forced)" if row.get("without_forced") else "")
    return [doc_blocks.escape(what), exit_cell(row), rests or "no rest", plus_minus(n["K_a_diag"], n["K_a_diag_std"], 3),
            plus_minus(n["bias_m_s2"], n["bias_std_m_s2"], 3, sign=True),
            plus_minus(n["euler_deg"], n["misalignment_std_deg"], 2, sign=True), ratio, dead_reckoning_cell(row)]


def every_real_table(r: dict) -> str:
    """benchmarks/accelerometer_real.py's record: one row per recording, the absent ones listed below."""
    present = [row for row in r["rows"] if "absent" not in row]
    absent = [row for row in r["rows"] if "absent" in row]
    head = (f"Every real recording at hand, solved with `--no-accelerometer` and with `--accelerometer` "
            f"(`{r['provenance']['command']}`, {r['provenance']['date']}, {r['provenance']['commit']}); a refusal "
            "with the accelerometer for the motion or the std (exit 3) forced too, its numbers then those `--force` "
            "reports, and a refusal without it forced for the columns that compare:\n\n")
    body = table(
        ["recording", "exit with the accelerometer", "\\|f\\|/g - 1 at the rests, % (raw)", "K_a diagonal",
         "bias, m/s^2", "C_b_a roll pitch yaw, deg", "gyro std with/without", "dead-reckoning RMS raw / without / with, deg"],
        [real_row(row) for row in present], left=(0, 1))
    tail = "" if not absent else ("\n\nNot at hand when measured: "
                                  + "; ".join(f"{row['name']} ({row['absent']})" for row in absent) + ".")
    return head + body + tail


def every_real_summary(r: dict) -> str:
    """What the table says, in lines: the dead reckoning with the accelerometer against without on each recording
    with an optical truth, the refusals with it, and the warnings it adds."""
    lines = []
    for row in r["rows"]:
        dr = row.get("dead_reckoning_rms_deg")
        if dr is None or dr["without"] is None or dr["with"] is None:
            continue
        verdict = "helps" if dr["with"] < 0.9 * dr["without"] else "harms" if dr["with"] > 1.1 * dr["without"] else "changes little"
        forced = " (both forced)" if row.get("without_forced") and row.get("forced") else (
            " (with forced)" if row.get("forced") else " (without forced)" if row.get("without_forced") else "")
        lines.append(f"{row['name']}: dead reckoning {dr['without']:.2f} -> {dr['with']:.2f} deg RMS with the "
                     f"accelerometer ({dr['with'] / dr['without']:.2f}x; raw {dr['raw']:.2f}): it {verdict}{forced}.")
    for row in r["rows"]:
        n = row.get("solved") or row.get("forced")
        if n is None or "gyro_std_ratio" not in n:
            continue
        worst = max(n["gyro_std_ratio"], key=n["gyro_std_ratio"].get)
        if n["gyro_std_ratio"][worst] > 1.1:
            lines.append(f"{row['name']}: the gyro's std with the accelerometer up to {n['gyro_std_ratio'][worst]:.2f}x "
                         f"the one without ({worst}){' (with forced)' if row.get('forced') else ''}.")
    for row in r["rows"]:
        n = row.get("forced")
        if n is None:
            continue
        z = [(abs(v - 1.0) / s, k, v, s) for k, (v, s) in enumerate(zip(n["K_a_diag"], n["K_a_diag_std"]))]
        far, k, v, sd = max(z)
        lines.append(f"{row['name']}, forced: K_a[{k},{k}] {v:.3f}±{sd:.3f}, {far:.1f} of its std from 1.")
    for row in r["rows"]:
        if "absent" in row or not row.get("exit"):
            continue
        text = f"{row['name']}: exit {row['exit']} with the accelerometer, exit {row.get('exit_without', '-')} without"
        if row["exit"] == "traceback":
            lines.append(text + f": {doc_blocks.escape(row['message'].strip())}.")
            continue
        text += f": {reason(row['message'])}"
        if "forced_exit" in row:
            text += "; forced: exit " + str(row["forced_exit"])
            if row["forced_exit"]:
                same = reason(row["forced_message"]) == reason(row["message"])
                text += " (the same)" if same else f" ({reason(row['forced_message'])})"
        lines.append(text + ("" if text.endswith("...") else "."))
    for row in r["rows"]:
        n = row.get("solved") or row.get("forced")
        if n is None:
            continue
        added = [w for w in n["warnings"] if w not in row.get("warnings_without", [])]
        if added and row.get("solved"):
            lines.append(f"{row['name']}: warned with the accelerometer only: "
                         + "; ".join(doc_blocks.escape(w.split(". ")[0]) for w in added) + ".")
    return doc_blocks.notes(lines)


def hand_models_table(r: dict) -> str:
    """The hand models' study (benchmarks/accelerometer_hand_models.py): one row per model and problem."""
    rows = []
    for study in r["studies"]:
        for row in study["rows"]:
            knobs = ", ".join(f"{k} {v:g}" for k, v in row["knobs"].items())
            rows.append([study["problem"], row["model"] + (f" ({knobs})" if knobs else ""),
                         f"{row['acc_over_crlb_median']:.2f}", f"{row['acc_over_crlb_max']:.2f}",
                         ", ".join(f"{v:.0f}" for v in row["K_a_diag_std_ppm"]), f"{row['gyro_with_over_without_max']:.2f}",
                         "%.2f-%.2f" % tuple(row["acc_model_over_actual"]), "%.2f-%.2f" % tuple(row["gyro_model_over_actual"])])
    head = (f"`{r['provenance']['command']}` ({r['provenance']['date']}, {r['provenance']['commit']}), seed 0 of each "
            "problem; the bound's K_a diagonal std: " + "; ".join(
                f"{s['problem']} {', '.join(f'{v:.0f}' for v in s['crlb_K_a_diag_ppm'])} ppm" for s in r["studies"]) + ":\n\n")
    return head + table(["problem", "the hand as the estimator models it", "acc std/CRLB, median", "largest",
                         "K_a diagonal std, ppm", "gyro std with/without, largest", "acc model std/actual",
                         "gyro model std/actual"], rows, left=(0, 1))


def hand_std_table(records: list[dict]) -> str:
    """benchmarks/hand_states_std.py: the std's hand share, and the whole std, against the error the true hand makes."""
    rows = []
    for r in records:
        for kind, ratio in r["ratios"].items():
            hand, whole = np.array(ratio["hand"]), np.array(ratio["whole"])
            rows.append([r["problem"], kind, f"{hand.min():.2f}-{hand.max():.2f}", f"{whole.min():.2f}-{whole.max():.2f}",
                         f"{r['names'][int(np.argmax(np.abs(np.log(whole))))]}"])
    head = "; ".join(f"`{r['provenance']['command']}` ({r['provenance']['date']}, {r['provenance']['commit']}, "
                     f"{r['with_hand']} seeds with a hand)" for r in records) + ":\n\n"
    return head + table(["problem", "the hand the sandwich is fed", "hand's share over the error the true hand makes",
                         "whole std over white + that error", "farthest from 1"], rows, left=(0, 1, 4))


def observe_block() -> str:
    """`magyro observe data/broad-02.parquet`'s accelerometer section (computed: a second, no solve)."""
    import magyro
    from magyro.io import load_session

    report = magyro.observe(load_session(DOCS.parent / "data" / "broad-02.parquet"))
    return "```\n" + "\n".join(report.accelerometer.table_lines()) + "\n```"


def blocks() -> dict[str, str]:
    out = {block: sim_table(read_record(record)) for block, record in SIM_RECORDS.items()}
    out["acc-sim-still"] = sim_table(read_record(STILL_RECORD))
    out["acc-observe-broad-02"] = observe_block()
    out["acc-broad-02"] = real_block(read_record(REAL_RECORD))
    out["acc-shortfall"] = shortfall([read_record(record) for record in SIM_RECORDS.values()])
    out["acc-speed"] = speed(read_record(REAL_RECORD))
    every = read_record(EVERY_REAL_RECORD)
    out["acc-real"] = every_real_table(every)
    out["acc-real-summary"] = every_real_summary(every)
    out["acc-hand-models"] = hand_models_table(read_record(HAND_MODELS_RECORD))
    out["acc-hand-states-std"] = hand_std_table([read_record(record) for record in HAND_STD_RECORDS])
    return out


def main(argv: list[str]) -> int:
    return doc_blocks.main(argv, PAGE, lambda: blocks(), COMMAND)


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
