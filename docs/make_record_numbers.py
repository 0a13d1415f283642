"""The blocks of docs/real-data.md measured on BROAD, rendered from their record docs/numbers/broad-trials.json.

    python benchmarks/broad_trials.py --out /tmp/trials.json       measure (needs ../shared/data/broad, minutes)
    python docs/make_record_numbers.py --record /tmp/trials.json   condense it into docs/numbers/broad-trials.json
    python docs/make_record_numbers.py [--check] [PAGE]            rewrite (or check) docs/real-data.md's blocks

The record holds, per trial, what the page shows (dead reckoning raw and calibrated, estimate minus rest bias,
lag, split-half RMS z, warnings, or the refusal) and the day-B peak to peak, with the date and commit of the
measurement. tests/test_doc_numbers.py checks that the page's blocks are what this script renders from the
record, and (marker `broad`) that a trial solved now gives the record's numbers.
"""
from __future__ import annotations

import datetime
import json
import subprocess
import sys
from pathlib import Path


sys.path.insert(0, str(Path(__file__).resolve().parent))
import doc_blocks  # noqa: E402
from doc_blocks import DOCS, ROOT, fixed, read_record, table, write_record  # noqa: E402

PAGE = DOCS / "real-data.md"
COMMAND = "python docs/make_record_numbers.py"
RECORD = "broad-trials"
UNDISTURBED = ("02", "03", "05", "07", "09", "21")
TRIAL_LABELS = {"30": "30, magnet beside the path", "32": "32, magnet 1 cm", "34": "34, magnet 3 cm",
                "36": "36, magnet 5 cm"}
BIAS_TARGET_DEG_S = 0.05     # the real-data issue's target: bias within this of the rest mean (bold beyond)
DAY_B_ROWS = (("scale (ppm)", "scale_ppm", 1e0, 0), ("non-orthogonality xy xz yz (deg)", "non_orthogonality_deg", 1, 2),
              ("bias (deg/s)", "bias_deg_s", 1, 3), ("misalignment (deg)", "misalignment_deg", 1, 2))
TABLE_II = {"scale_ppm": "4000", "non_orthogonality_deg": "0.2", "bias_deg_s": "0.03", "misalignment_deg": "0.2"}


# --------------------------------------------------------------------------- the record


def condensed_trial(result: dict) -> dict:
    """What the page shows of one trial of benchmarks/broad_trials.py's output."""
    if "error" in result:
        return {"error": result["error"]}
    cal, val = result["calibration"], result["validation"]["summary"]
    return {"raw_rms_deg": val["raw"]["rms_deg"], "calibrated_rms_deg": val["calibrated"]["rms_deg"],
            "estimate_minus_rest_deg_s": (cal.get("rests") or {}).get("estimate_minus_rest_deg_s"),
            "lag_ms": 1e3 * cal["time_offset_s"], "split_rms_z": (cal.get("consistency") or {}).get("rms_z"),
            "warnings": list(cal["warnings"]),
            "findings": sorted({f["kind"] for f in (cal.get("recording") or {}).get("findings", [])
                                if f["severity"] != "info"})}


def commit() -> str:
    done = subprocess.run(["git", "-C", str(ROOT), "rev-parse", "--short", "HEAD"], capture_output=True, text=True)
    return done.stdout.strip() or "unknown"


def condense(benchmark_output: Path) -> dict:
    raw = json.loads(benchmark_output.read_text(encoding="utf-8"))
    return {"command": "python benchmarks/broad_trials.py --out FILE", "date": datetime.date.today().isoformat(),
            "commit": commit(), "trials": {t: condensed_trial(r) for t, r in raw["trials"].items()},
            "day_b_peak_to_peak": raw["day_b_peak_to_peak"]}


# --------------------------------------------------------------------------- the blocks


def bias_cells(values) -> str:
    return " ".join(f"**{v:+.3f}**" if abs(v) > BIAS_TARGET_DEG_S else f"{v:+.3f}" for v in values)


def warnings_cell(warnings: list[str]) -> str:
    """How many warnings, and each one's first clause."""
    if not warnings:
        return "0"
    return f"{len(warnings)}: " + "; ".join(doc_blocks.escape(w.split(":")[0].split(" (")[0]) for w in warnings)


def findings_cell(findings: list[str]) -> str:
    return ", ".join(f"`{k}`" for k in findings) or "-"


def trial_row(trial: str, r: dict) -> list[str]:
    label = TRIAL_LABELS.get(trial, trial)
    if "error" in r:
        return [label, f"not solved (exit 3): {doc_blocks.escape(r['error'].split(':')[0])}", "", "", "", "", "", ""]
    return [label, f"{r['raw_rms_deg']:.2f} -> {r['calibrated_rms_deg']:.2f}",
            f"{r['calibrated_rms_deg'] / r['raw_rms_deg']:.2f}", bias_cells(r["estimate_minus_rest_deg_s"]),
            f"{r['lag_ms']:.2f}", f"{r['split_rms_z']:.2f}", findings_cell(r["findings"]),
            warnings_cell(r["warnings"])]


def trials_block(record: dict) -> str:
    rows = [trial_row(t, r) for t, r in record["trials"].items()]
    return (f"Measured on {record['date']} at commit `{record['commit']}` (`{record['command']}`; "
            f"`{COMMAND} --record FILE` writes docs/numbers/{RECORD}.json):\n\n"
            + table(["trial", "dead reckoning RMS, raw -> calibrated (deg)", "ratio",
                     "estimate - rest bias, x y z (deg/s)", "lag (ms)", "split-half RMS z",
                     "recording check (warnings)", "solve's warnings"],
                    rows, left=(0, 1, 3, -2, -1)))


def day_b_block(record: dict) -> str:
    ptp = record["day_b_peak_to_peak"]
    rows = [[label, *(fixed(v, digits) for v in ptp[key]), TABLE_II[key]] for label, key, _, digits in DAY_B_ROWS]
    return table(["", "x / roll", "y / pitch", "z / yaw", "Table II"], rows, left=(0,))


def ratios(record: dict) -> list[float]:
    """Calibrated over raw dead reckoning on the undisturbed trials."""
    return [r["calibrated_rms_deg"] / r["raw_rms_deg"] for t, r in record["trials"].items()
            if t in UNDISTURBED and "error" not in r]


def ratio_span(record: dict) -> str:
    return doc_blocks.span(ratios(record), digits=2)


def bias_target(record: dict) -> str:
    """Which undisturbed trials have their bias within the target of the rest mean, and how far the others are."""
    worst = {t: max(abs(v) for v in record["trials"][t]["estimate_minus_rest_deg_s"]) for t in UNDISTURBED
             if "error" not in record["trials"][t]}
    met = [t for t, v in worst.items() if v <= BIAS_TARGET_DEG_S]
    missed = [f"{t} ({v:.3f})" for t, v in worst.items() if v > BIAS_TARGET_DEG_S]
    return f"met on {', '.join(met) or 'none'}" + (f"; not on {', '.join(missed)}" if missed else "")


def day_b_excess(record: dict) -> str:
    ptp = record["day_b_peak_to_peak"]
    return (f"scale {min(ptp['scale_ppm']):.0f}-{max(ptp['scale_ppm']):.0f} ppm, non-orthogonality up to "
            f"{max(ptp['non_orthogonality_deg']):.2f} deg")


def blocks(record: dict | None = None) -> dict[str, str]:
    """The page's blocks: the trials' (this module) and sections 2 and 4's (docs/real_data_numbers.py)."""
    import real_data_numbers
    import shipped_data_numbers

    record = record or read_record(RECORD)
    from magyro.nls.grid import MAX_SEGMENT_FACTOR

    return {"trials": trials_block(record), "day-b": day_b_block(record), "bias-target": bias_target(record),
            "day-b-excess": day_b_excess(record), "gap-factor": doc_blocks.g(MAX_SEGMENT_FACTOR),
            "dead-reckoning-target": f"met, ratios {ratio_span(record)}", **real_data_numbers.blocks(record),
            "rest-drift": shipped_data_numbers.rest_drift_block()}


def main(argv: list[str]) -> int:
    if "--record" in argv:
        path = write_record(RECORD, condense(Path(argv[argv.index("--record") + 1])))
        print(f"wrote {path}")
        argv = [a for a in argv if a not in ("--record", argv[argv.index("--record") + 1])]
    return doc_blocks.main(argv, PAGE, lambda: blocks(), COMMAND)


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
