"""The figures measured by studies that the README's pages quote (docs/how-it-works.md, results.md,
using-the-result.md, development.md), rendered from their records in docs/numbers/ (docs/make_readme_numbers.py
adds these blocks to its pages'; tests/test_doc_numbers.py checks them):

- montecarlo-paper-table1.json (docs/make_table1_numbers.py): the honesty check, the EKF's R and h;
- std-on-real-data.json (benchmarks/std_on_real_data.py): the room's wander, the split-half check on BROAD's .mat trials;
- split-check-shipped.json (benchmarks/split_check_shipped.py): `magyro solve data/broad-02.parquet --split-check`;
- predicted-vs-actual.json (benchmarks/predicted_vs_actual.py): the prediction against the spread of solves;
- trajectory-accuracy.json (benchmarks/trajectory_accuracy.py): the attitude trajectory against the truth;
and the code's constants (the unit check's bounds).
"""
from __future__ import annotations

import math

import numpy as np

import doc_blocks
import make_table1_numbers as table1
from doc_blocks import fixed, fmt, has_record, read_record, span

PREFILTER_EXAMPLE = (1.5, 28.0)   # Hz: a hand's turning, and a phone's gyro rate (docs/how-it-works.md step 6)


def honesty(mc: dict) -> str:
    rows = [r for r in table1.result(mc, ("nls",))["nls"].rows if np.isfinite(r.reported_over_actual)]
    return (f"Over the {mc['runs']} simulated paper-table1 sessions of docs/table1.md (commit `{mc['commit']}`), the "
            "mean reported std divided "
            f"by the actual spread is {span([r.reported_over_actual for r in rows], 2)} for every parameter "
            f"({len(rows)}: the gyro's, R, h and the lag)")


def homogeneous_std(mc: dict) -> str:
    g = table1.gyro(table1.result(mc, ("nls",))["nls"].rows)
    return (f"over the {mc['runs']} paper-table1 runs of docs/table1.md the reported std is on average "
            f"{np.mean([r.reported_over_actual for r in g]):.2f}x the actual spread (12 gyro parameters; `{mc['commit']}`)")


def ekf_mag(mc: dict) -> str:
    res = table1.result(mc)
    mag = [r.name for r in res["nls"].rows if r.group in ("R", "h")]
    ratio = [res["ekf"].row(n).std / res["nls"].row(n).std for n in mag]
    return (f"its R and h spread {span(ratio, 1)}x as much as the joint least squares' "
            f"({mc['runs']} paper-table1 runs at `{mc['commit']}`, docs/table1.md)")


def shipped_split(split: dict | None) -> str:
    """`magyro solve data/broad-02.parquet --split-check`'s RMS z (benchmarks/split_check_shipped.py's record)."""
    if split is None:
        return ""
    r = split["rows"][0]
    return (f"the shipped {r['session']}, whole and with its accelerometer, gives {r['rms_z']:.2f} (largest |z| "
            f"{r['max_abs_z']:.1f}; `{r['command']}`, {split['date']}, commit `{split['commit']}`)")


def room(std: dict, split: dict | None = None) -> dict[str, str]:
    """The room's wander and the split-half RMS z on BROAD (benchmarks/std_on_real_data.py: the .mat trials cut to
    their movement +/- 10 s, solved without the accelerometer) beside the shipped trial's as `magyro solve
    --split-check` gives it (benchmarks/split_check_shipped.py)."""
    if split is None and has_record("split-check-shipped"):
        split = read_record("split-check-shipped")
    t = std["trials"].values()
    z, zw = [r["split_rms_z"] for r in t], [r["split_rms_z_white"] for r in t]
    ratio = [r["std_over_white_median"] for r in t]
    cut = (f"the {len(z)} .mat recordings cut to their movement +/- 10 s and solved without the accelerometer "
           f"(`python benchmarks/std_on_real_data.py`, {std['date']}, commit `{std['commit']}`")
    shipped = shipped_split(split)
    return {
        "room-wander": (f"it wanders by {span([r['disturbance_percent'] for r in t], 1)} % of the field (BROAD's "
                        f"undisturbed trials), correlated over {span([r['correlation_time_s'] for r in t], 1)} s"),
        "split-broad": (f"the RMS z is {span(z, 2)} (with `std_white` {span(zw, 2)}) on {cut}, docs/real-data.md "
                        "section 2)" + (f"; {shipped}" if shipped else "")),
        "broad-std": (f"on these recordings the white-noise std is {span(ratio, 1)}x too small (median over the gyro "
                      f"parameters); the std that counts the room's field gives split-half RMS z {span(z, 2)} on {cut})"
                      + (f", and {shipped}" if shipped else "") + "; `--split-check` says when it does not hold"),
    }


def prediction(pva: dict) -> str:
    ratio = np.asarray(pva["predicted"]) / np.asarray(pva["actual"])
    worst = float(np.max(np.abs(ratio - 1)))
    return (f"The prediction is within {100 * worst:.0f} % of the spread of {pva['runs']} solves for every gyro "
            f"parameter (docs/observability.md section 6, commit `{pva['commit']}`; with {pva['runs']} runs the spread "
            f"itself is uncertain by about {100 / math.sqrt(2 * (pva['runs'] - 1)):.0f} %)")


def trajectory(tr: dict) -> str:
    sim, b = tr["simulated"], tr["broad_02"]
    return (f"the attitude error in units of that std has an RMS of {fixed(sim['rms_z'], 2)} ({sim['runs']} "
            f"{sim['problem']} runs); on BROAD trial 02 the trajectory follows the optical truth to "
            f"{fmt(b['median_deg'])} deg median ({fmt(b['p95_deg'])} deg at the 95th percentile), an RMS of "
            f"{', '.join(f'{v:.1f}' for v in b['rms_z_per_axis'])} of its std about the three axes "
            f"(`python benchmarks/trajectory_accuracy.py`, {tr['date']})")


def unit_ratios() -> str:
    from magyro.front import prepare as p

    return (f"the path of the field's {doc_blocks.g(p.UNIT_CHECK_BLOCK_S)} s means, each step counted beyond "
            f"{doc_blocks.g(p.UNIT_CHECK_NOISE_STDS)} noise stds: a gyro that turned less than "
            f"{doc_blocks.g(p.MAX_SLOW_RATE_RATIO)}x that path, or a field that turned less than "
            f"{doc_blocks.g(p.MIN_RATE_RATIO)}x what the gyro predicts, has the wrong unit")


def prefilter_bias() -> str:
    f, fs = PREFILTER_EXAMPLE
    return f"{100 * (2 * math.pi * f / fs) ** 2 / 12:+.2f} % at {doc_blocks.g(f)} Hz and {doc_blocks.g(fs)} Hz"


def load_label(record: dict) -> str:
    """When, at which commit, on what machine and under how much other load a timing was measured."""
    other = record["other_load"].split(" (")[0].replace("other processes used ", "")
    return f"{record['date']}, `{record['commit']}`, {record['machine']}; other processes used {other}"


def scale_timing(record: dict) -> str:
    rows = {r["size"]: r for r in record["results"] if r.get("status") == "ok"}
    parts = []
    for size, r in sorted(rows.items()):
        seconds = size / 100.0
        length = f"{seconds:g} s" if seconds < 3600 else f"{seconds / 3600:g} hour{'s' if seconds > 3600 else ''}"
        parts.append(f"{length} at 100 Hz ({size // 1000}k samples) solves in {r['process_s']:.1f} s with "
                     f"{r['peak_rss_mb'] / 1024:.2f} GB")
    return (f"{'; '.join(parts)}, whole process included (`{record['command']}`: {load_label(record)})")


def recording_check_timing(record: dict) -> str:
    r = max(record["rows"], key=lambda r: r["samples"])
    return (f"{1e3 * r['check_s']:.0f} ms on a {r['samples'] / 1000:.0f}k-sample session ({r['session']}: "
            f"{100 * r['check_s'] / r['solve_s']:.1f} % of its solve; `{record['command']}`, {load_label(record)})")


def cold_start(record: dict) -> str:
    """benchmarks/bench_cold_start.py's record: the README's first command on a fresh install, cold and warm."""
    compiled = sorted(set(record["cold_kernels_compiled"]))
    return (f"`{record['readme_first_command']}` on a fresh install with an empty kernel cache compiled "
            f"{', '.join(map(str, compiled))} kernels and took {record['cold_s']:.1f} s, "
            f"{record['cold_over_warm']:.2f}x a warm run (installing compiled {record['install_kernels_compiled']} "
            f"kernels; `{record['command']}`: {load_label(record)})")


def suite_time(record: dict) -> str:
    """benchmarks/suite_time.py's record: how long the tests took, where and under how much other load."""
    c = record["counts"]
    minutes, seconds = divmod(round(record["wall_s"]), 60)
    tests = ", ".join(f"{n} {word}" for word, n in c.items())
    return (f"`python -m pytest {' '.join(record['pytest_args'])}` ({tests}) took {minutes} min {seconds} s "
            f"({load_label(record)}; `{record['command']}`)")


def stride_agreement(record: dict) -> str:
    """benchmarks/stride_agreement.py's record: each case solved at two strides, the largest difference in std."""
    parts = [f"{r['case'].split(' (')[0]} at strides {r['strides'][0]} and {r['strides'][1]} agree to "
             f"{r['max_abs_z']:.3f} std" for r in record["rows"]]
    return f"{'; '.join(parts)}: `{record['command']}`, {record['date']}"


def blocks() -> dict[str, str]:
    out = {"unit-ratios": unit_ratios(), "prefilter-bias": prefilter_bias()}
    mc = read_record(table1.RECORD)
    out.update({"honesty": honesty(mc), "homogeneous-std": homogeneous_std(mc), "ekf-mag": ekf_mag(mc)})
    if has_record("std-on-real-data"):
        out.update(room(read_record("std-on-real-data")))
    if has_record("predicted-vs-actual"):
        out["prediction-accuracy"] = prediction(read_record("predicted-vs-actual"))
    for name, key, make in (("bench-scale", "scale-timing", scale_timing),
                            ("bench-recording-check", "recording-check-timing", recording_check_timing),
                            ("bench-cold-start", "cold-start", cold_start)):
        if has_record(name):
            out[key] = make(read_record(name))
    if has_record("ekf-real-data"):
        import make_ekf_numbers

        out["misfit-broad"] = make_ekf_numbers.misfit_broad(read_record("ekf-real-data"))
    if has_record("stride-agreement"):
        out["stride-agreement"] = stride_agreement(read_record("stride-agreement"))
    if has_record("trajectory-accuracy"):
        out["trajectory-accuracy"] = trajectory(read_record("trajectory-accuracy"))
    return out
