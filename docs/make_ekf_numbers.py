"""Regenerate the measured numbers of docs/ekf.md from their records in docs/numbers/.

    python benchmarks/ekf_real_data.py --wild DIR --out docs/numbers/ekf-real-data.json   (BROAD and wild, minutes)
    python benchmarks/ekf_variants.py --out docs/numbers/ekf-variants.json                (simulations, minutes)
    python benchmarks/ekf_check_sims.py --seeds 0-2 --methods ekf,nls --out docs/numbers/ekf-check-sims.json
    magyro montecarlo paper-table1 --runs 20 --method ekf -o MC.json
    python benchmarks/ekf_table1_targets.py MC.json --out docs/numbers/ekf-table1-targets.json
    python benchmarks/ekf_real_data.py --trials 02,07,09 --estimate-magnetometer \
        --out docs/numbers/ekf-real-data-joint.json
    python docs/make_ekf_numbers.py [--check] [PAGE]       rewrite (or check) docs/ekf.md's blocks

ekf-real-data.json: both methods on BROAD's trials and the wild recordings (exit codes, agreement in combined std,
the EKF's split-half RMS z, dead reckoning against the optical truth). ekf-variants.json: step 1's z-scores and
the five variants' errors against the truth on paper-table1. tests/test_doc_numbers.py checks that the page is
what this script renders from the records (and, marked `broad`, that a BROAD trial gives its row now).
"""
from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
import doc_blocks  # noqa: E402
from doc_blocks import DOCS, RECORDS, has_record, read_record, span, table  # noqa: E402

PAGE = DOCS / "ekf.md"
COMMAND = "python docs/make_ekf_numbers.py"
REAL = "ekf-real-data"
SPEED = "bench-ekf"
VARIANTS = "ekf-variants"
VARIANT_LABELS = {
    "default": "**default** (corrected step 1, consider states)",
    "magnetometer known": "magnetometer known exactly (`magnetometer=(R, h)`, as in the paper's simulation)",
    "no consider states": "corrected step 1, no consider states",
    "plain step 1": "plain step 1, consider states",
    "paper literal": "**paper literal** (plain step 1, no consider states)",
}
TABLE1_3SIGMA = {"scale_ppm": 900.0, "nonorth_deg": 0.09, "bias_deg_s": 0.02, "misalignment_deg": 0.06}
PAPER_STD = {"K_g": (3.0, 2.6, 5.5, 1.4, 3.0, 2.6), "bias": (5.8, 3.6, 4.5), "euler": (0.008, 0.018, 0.022)}


# --------------------------------------------------------------------------- both methods on real recordings


def first_clause(text: str) -> str:
    return doc_blocks.escape(text.split(":")[0].split(" (")[0])


def real_row(r: dict) -> list[str]:
    def f(v, digits=2):
        return "-" if v is None else f"{v:.{digits}f}"

    z = f"{r['max_abs_z']:.2f} ({r['worst']})" if "max_abs_z" in r else "-"
    dr = (f"{r['raw_rms_deg']:.1f} / {f(r.get('nls_rms_deg'), 1)} / {f(r.get('ekf_rms_deg'), 1)}"
          if "raw_rms_deg" in r else "no reference")
    if "ekf_error" in r:
        note = f"EKF refuses: {first_clause(r['ekf_error'])}"
        if "nls_error" in r:
            nls, ekf = first_clause(r["nls_error"]), first_clause(r["ekf_error"])
            note = f"both refuse: {nls}" if nls == ekf else f"both refuse; the least squares: {nls}; the EKF: {ekf}"
    else:
        warnings = r.get("ekf_warnings", [])
        note = (f"EKF warns: {'; '.join(first_clause(w) for w in warnings)}" if warnings else "no EKF warning")
    return [r["name"], str(r["nls_exit"]), str(r["ekf_exit"]), z, f(r.get("ekf_split_rms_z")), dr, note]


def real_table_block(record: dict) -> str:
    return (f"Measured on {record['date']} at commit `{record['commit']}` (`{record['command']}`):\n\n"
            + table(["session", "NLS exit", "EKF exit", "max \\|z\\| EKF vs NLS (12 gyro parameters)",
                     "EKF split-half RMS z", "dead reckoning RMS deg: raw / NLS / EKF", "refusals and warnings"],
                    [real_row(r) for r in record["rows"]], left=(0, 3, 5, 6)))


def real_summary_block(record: dict) -> str:
    from magyro.result.consistency import MAX_RMS_Z

    both = [r for r in record["rows"] if "max_abs_z" in r]
    truth = [r for r in both if "raw_rms_deg" in r]
    split = [r for r in both if r.get("ekf_split_rms_z") is not None]
    warned = [r for r in split if r["ekf_split_rms_z"] > MAX_RMS_Z]
    text = (f"Where both methods solve ({len(both)} sessions) they agree within "
            f"{max(r['max_abs_z'] for r in both):.1f} combined std")
    if truth:
        text += (f"; the EKF's dead reckoning is {span([r['ekf_rms_deg'] / r['raw_rms_deg'] for r in truth], 2)} of "
                 f"the raw gyro's (the least squares': {span([r['nls_rms_deg'] / r['raw_rms_deg'] for r in truth], 2)})")
    if split:
        text += f". The EKF's split-half RMS z is {span([r['ekf_split_rms_z'] for r in split], 2)}"
        text += (f"; above {doc_blocks.g(MAX_RMS_Z)} ("
                 + ", ".join(f"{r['name']}: {r['ekf_split_rms_z']:.2f}" for r in warned)
                 + ") the split check warns" if warned else f", within the check's {doc_blocks.g(MAX_RMS_Z)}")
    refused = [r["name"] for r in record["rows"] if r["nls_exit"] and r["ekf_exit"]]
    if refused:
        text += f". Both methods refuse {', '.join(refused)}"
    return text + "."


# --------------------------------------------------------------------------- the variants against the truth


def worst(per_seed: dict, key: str) -> float:
    return max(float(np.max(np.abs(e[key]))) for e in per_seed.values())


def rms_z(e: dict) -> float:
    return float(np.sqrt(np.mean(np.square(e["z"]))))


def variants_block(record: dict) -> str:
    rows = []
    for name in VARIANT_LABELS:
        per_seed = record["variants"][name]
        rms = [rms_z(e) for e in per_seed.values()]
        rows.append([VARIANT_LABELS[name], f"{worst(per_seed, 'scale_ppm'):.0f}", f"{worst(per_seed, 'nonorth_deg'):.3f}",
                     f"{worst(per_seed, 'bias_deg_s'):.3f}", f"{worst(per_seed, 'misalignment_deg'):.3f}",
                     f"{worst(per_seed, 'z'):.1f}", f"{min(rms):.2f} to {max(rms):.2f}"])
    seeds = [int(s) for s in next(iter(record["variants"].values()))]
    return (f"Worst errors over noise seeds {min(seeds)} to {max(seeds)} (`{record['command']}`, {record['date']}, "
            f"commit `{record['commit']}`):\n\n"
            + table(["variant", "scale ppm", "non-orth deg", "bias deg/s", "misalign deg", "max \\|z\\|",
                     "RMS z per seed"], rows, left=(0,)))


def default_block(record: dict) -> str:
    d = record["variants"]["default"]
    meets = all(worst(d, k) < v for k, v in TABLE1_3SIGMA.items())
    rms = {k: np.sqrt(np.mean([np.square(e[k]) for e in d.values()], axis=0)) for k in
           ("K_g_upper", "bias_deg_s", "misalignment_deg")}
    lines = [f"K_g (K11, K12, K13, K22, K23, K33): {', '.join(f'{1e4 * v:.1f}' for v in rms['K_g_upper'])} e-4. "
             f"The paper's std is {', '.join(f'{v:.1f}' for v in PAPER_STD['K_g'])} e-4.",
             f"bias: {', '.join(f'{1e3 * v:.1f}' for v in rms['bias_deg_s'])} e-3 deg/s (paper "
             f"{', '.join(f'{v:.1f}' for v in PAPER_STD['bias'])} e-3).",
             f"misalignment: {', '.join(f'{v:.3f}' for v in rms['misalignment_deg'])} deg (paper "
             f"{', '.join(f'{v:g}' for v in PAPER_STD['euler'])} for the Euler angles)."]
    return ((f"The default variant {'meets all four Table I figures on every seed' if meets else 'does not meet every Table I figure on every seed'}. "
             f"The RMS errors over the {len(d)} seeds are:\n\n") + doc_blocks.notes(lines))


def literal_block(record: dict) -> str:
    """How far the paper-literal variant misses Table I's figures, and whether the known magnetometer meets them."""
    v = record["variants"]
    over = min(worst(v["paper literal"], k) / t for k, t in TABLE1_3SIGMA.items())
    known = all(worst(v["magnetometer known"], k) < t for k, t in TABLE1_3SIGMA.items())
    return (f"The literal method misses every Table I figure by at least {over:.1f}x. The cause is step 1's O(σ²) "
            "bias, amplified by the partial sphere coverage, and not the filter. With the magnetometer given exactly, "
            "as in the paper's own simulation (\"the magnetometer is assumed having been well calibrated\"), the "
            + ("filter meets the targets on every seed." if known else "filter still misses a target on some seed."))


def consider_block(record: dict) -> str:
    v = record["variants"]
    return (f"the worst K_g scale error falls from up to {worst(v['no consider states'], 'scale_ppm'):.0f} ppm "
            f"without them to at most {worst(v['default'], 'scale_ppm'):.0f} ppm")


def no_consider_z_block(record: dict) -> str:
    return f"the K errors reach {worst(record['variants']['no consider states'], 'z'):.1f} sigma"


def step1_block(record: dict) -> str:
    s = record["step1"]
    n = len(next(iter(s.values())))

    def rms(problem, which):
        return span([r[which] for r in s[problem].values()], 1)

    return (f"Over {n} seeds, the corrected z-scores of R and h have an RMS of {rms('paper-table1', 'corrected')} on "
            f"paper-table1 and {rms('phone-module', 'corrected')} on phone-module. For the plain step the RMS is "
            f"{rms('paper-table1', 'plain')} and {rms('phone-module', 'plain')}.")


def speed_block(record: dict) -> str:
    """benchmarks/bench_ekf.py's record: the filter's throughput with and without the consider states."""
    rows = []
    for r in record["rows"]:
        rows.append([f"{r['problem']} ({r['duration_s']:.0f} s, {r['gyro_hz']:.0f} Hz + {r['mag_hz']:.0f} Hz)",
                     str(r["samples"]),
                     f"{r['filter_26_s']:.2f} s, {r['filter_26_samples_per_s'] / 1e3:.1f}k/s",
                     f"{r['filter_26_samples_per_cpu_s'] / 1e3:.1f}k/s",
                     f"{r['filter_17_s']:.2f} s, {r['filter_17_samples_per_s'] / 1e3:.1f}k/s",
                     f"{r['filter_17_samples_per_cpu_s'] / 1e3:.1f}k/s", f"{r['calibrate_s']:.1f} s"])
    return (f"`{record['command']}` (noise seed 0, median of {record['repeat']}), measured on {record['date']} at "
            f"commit `{record['commit']}` on {record['machine']}; {record['other_load']}:\n\n"
            + table(["problem", "samples", "filter (26 states)", "per CPU s", "filter (17 states)", "per CPU s",
                     "whole `EKF().calibrate_with_history`"], rows, left=(0,)))


def check_blocks() -> dict[str, str]:
    """The result check's bounds, from magyro.result.check."""
    from magyro.front.initial import DEFAULT_WINDOW_S
    from magyro.result import check

    g = doc_blocks.g
    return {"ekf-check": (f"field's turning over {g(DEFAULT_WINDOW_S)} s windows within {g(check.MAX_TURNING_MISFIT)}x "
                          f"of the plain linear fit (eq. 13), and dead-reckoned over {g(check.LONG_WINDOW_S)} s windows "
                          f"within {g(check.MAX_LONG_TURNING_MISFIT)}x; dead-reckoned over "
                          + " and ".join(f"{g(w)} s" for w in check.DRIFT_WINDOWS_S)
                          + f" windows it must miss the magnetometer's direction change no more than "
                          f"{g(check.MAX_RAW_DRIFT)}x as much as the raw gyro does"),
            "ekf-rest-z": g(check.MAX_REST_Z)}


def misfit_broad(record: dict) -> str:
    """The result check's ratios of the results that solved on BROAD (both methods), from ekf-real-data.json."""
    solved = [(r[f"{m}_misfit"], r[f"{m}_misfit_1s"]) for r in record["rows"] if r["name"].startswith("BROAD")
              for m in ("nls", "ekf") if not r[f"{m}_exit"] and r.get(f"{m}_misfit") is not None]
    trials = [r["name"].split()[1] for r in record["rows"] if r["name"].startswith("BROAD")]
    return (f"the results of either method on BROAD {trials[0]}-{trials[-1]} reach at most "
            f"{max(a for a, _ in solved):.2f} over the short windows and {max(b for _, b in solved):.2f} over the long "
            f"ones ({record['date']}, commit `{record['commit']}`)")


LAG = "ekf-lag-shipped"   # benchmarks/ekf_lag_shipped.py --out


def lag_shipped_block(record: dict) -> str:
    return (f"On trial 07 (the shipped data/{record['trial']}) eq. (13) starts the filter at "
            f"{record['eq13_lag_ms']:.1f} ms and its likelihood puts the lag at {record['ekf_lag_ms']:.2f} +/- "
            f"{record['ekf_lag_std_ms']:.2f} ms in {record['filter_runs']} filter runs (`{record['command']}`, "
            f"{record['date']})")


CHECK_SIMS = "ekf-check-sims"   # benchmarks/ekf_check_sims.py --out


def check_sims_block(record: dict) -> str:
    """Per simulated case: how each method ended, and the dead reckoning of those that exited 0 (raw / calibrated)."""
    cases: dict[str, dict[str, list]] = {}
    for r in record["rows"]:
        cases.setdefault(r["case"], {}).setdefault(r["method"], []).append(r)
    methods = sorted({r["method"] for r in record["rows"]})

    def cell(rows: list) -> str:
        parts = []
        for r in rows:
            if r["exit"]:
                parts.append(f"exit {r['exit']}")
            else:
                parts.append(f"0: {r['raw_rms_deg']:.2f} / {r['calibrated_rms_deg']:.2f}"
                             + (" **worse**" if r["violation"] else ""))
        return "; ".join(parts)

    seeds = sorted({r["seed"] for r in record["rows"]})
    head = (f"Measured on {record['date']} at commit `{record['commit']}` (`{record['command']}`), seeds "
            f"{seeds[0]}-{seeds[-1]}; each cell: exit code, and for exit 0 the dead-reckoning RMS against the "
            "reference, raw / calibrated, deg:\n\n")
    rows = [[case] + [cell(per.get(m, [])) for m in methods] for case, per in cases.items()]
    worse = {m: sum(1 for r in record["rows"] if r["method"] == m and r.get("violation")) for m in methods}
    zero = {m: sum(1 for r in record["rows"] if r["method"] == m and r["exit"] == 0) for m in methods}
    tail = "\n\n" + "; ".join(f"{m}: {worse[m]} of its {zero[m]} exits 0 dead-reckon worse than the raw gyro"
                               for m in methods) + "."
    return head + table(["case"] + methods, rows) + tail


TABLE1_TARGETS = "ekf-table1-targets"   # benchmarks/ekf_table1_targets.py --out
JOINT = "ekf-real-data-joint"            # benchmarks/ekf_real_data.py --estimate-magnetometer --out


def table1_targets_block(record: dict) -> str:
    """Issue 38's Table I targets: the worst error over 3 sigma per parameter group and the bias std over the CRLB."""
    rows = record["parameters"]
    worst = max(rows, key=lambda k: rows[k]["over_three_sigma"])
    bias = ", ".join(f"{v:.2f}" for v in record["bias_std_over_crlb"])
    return (f"Over {record['succeeded']} of {record['runs']} seeds (`{record['command']}`, {record['date']}, commit "
            f"`{record['commit']}`) every parameter's worst error is "
            + ("within" if record["all_within_three_sigma"] else "not within")
            + f" Table I's 3 sigma (the closest: {worst} at {rows[worst]['over_three_sigma']:.2f} of it); the bias "
            f"std is {bias} x its Cramer-Rao bound (x, y, z)")


def joint_split_block(two_step: dict, joint: dict) -> str:
    """The EKF's split-half RMS z per BROAD trial, two steps against R and h as states."""
    def by_trial(record):
        return {r["name"]: r for r in record["rows"] if r["name"].startswith("BROAD")}

    a, b = by_trial(two_step), by_trial(joint)

    def cell(r):
        if r is None:
            return "-"
        if r.get("ekf_exit"):
            return f"exit {r['ekf_exit']}"
        z = r.get("ekf_split_rms_z")
        return "a half refused" if z is None else f"{z:.2f}"

    def dead_reckoning(r):
        if r.get("ekf_rms_deg") is None:
            return "-"
        return f"{r['raw_rms_deg']:.1f} / {r.get('nls_rms_deg', float('nan')):.1f} / {r['ekf_rms_deg']:.1f}"

    rows = [[name, cell(a.get(name)), cell(b.get(name)), dead_reckoning(b[name])] for name in b]
    return (f"`{joint['command']}` ({joint['date']}, commit `{joint['commit']}`), beside the two steps' record:\n\n"
            + table(["trial", "split RMS z, two steps", "split RMS z, R and h as states",
                     "dead reckoning deg raw / NLS / EKF (R and h as states)"], rows))


def blocks() -> dict[str, str]:
    out = check_blocks()
    if has_record(TABLE1_TARGETS):
        out["ekf-table1-targets"] = table1_targets_block(read_record(TABLE1_TARGETS))
    if has_record(JOINT) and has_record(REAL):
        out["ekf-joint-split"] = joint_split_block(read_record(REAL), read_record(JOINT))
    if has_record(CHECK_SIMS):
        out["ekf-check-sims"] = check_sims_block(read_record(CHECK_SIMS))
    trials = read_record("broad-trials")
    out["ekf-lag-07"] = (f"{trials['trials']['07']['lag_ms']:.1f} ms (docs/real-data.md section 1, "
                         f"commit `{trials['commit']}`)")
    import shipped_data_numbers

    out["ekf-mag-levels"] = shipped_data_numbers.ekf_mag_levels_block()
    if has_record(LAG):
        out["ekf-lag-shipped"] = lag_shipped_block(read_record(LAG))
    if has_record(REAL):
        r = read_record(REAL)
        out.update({"ekf-real-table": real_table_block(r), "ekf-real-summary": real_summary_block(r),
                    "ekf-misfit-broad": misfit_broad(r)})
    if has_record(VARIANTS):
        v = read_record(VARIANTS)
        out.update({"ekf-variants": variants_block(v), "ekf-default": default_block(v),
                    "ekf-consider": consider_block(v), "ekf-no-consider-z": no_consider_z_block(v),
                    "ekf-step1": step1_block(v), "ekf-literal": literal_block(v)})
    if (RECORDS / "std-on-real-data.json").is_file():
        std_record = read_record("std-on-real-data")
        t = std_record["trials"]["07"]
        out["ekf-room-07"] = (f"{t['disturbance_percent']:.2f} % of the field, correlated over "
                              f"{t['correlation_time_s']:.1f} s, on trial 07")
        out["ekf-room-ratio"] = (f"{t['std_over_white_median']:.1f}x its white std (median over the gyro parameters, "
                                 f"docs/real-data.md section 2, commit `{std_record['commit']}`)")
        if has_record(REAL):
            row = next(r for r in read_record(REAL)["rows"] if r["name"] == "BROAD 07")
            if row.get("ekf_std_over_white"):
                out["ekf-room-ratio"] += f"; the EKF's, {row['ekf_std_over_white']:.1f}x"
    if has_record(SPEED):
        out["ekf-speed"] = speed_block(read_record(SPEED))
    return out


def main(argv: list[str]) -> int:
    return doc_blocks.main(argv, PAGE, blocks, COMMAND)


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
