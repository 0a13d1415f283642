"""Regenerate the numbers of docs/observability.md: the canonical-problem table (section 5) from `magyro observe`,
the rule's thresholds from the code's constants, the section 6 table and the speed from their records.

    python docs/make_observability_table.py [--check] [PAGE]      (default: docs/observability.md)

Every problem of problems/ named in `CANONICAL` is simulated with noise seed 0 and observed; the table (rank
against the theorem's, condition, time to full rank, sphere visited, verdict, 3 significant digits) and the notes
under it are the blocks `report_blocks` makes (markers `<!-- numbers:NAME:start -->`, docs/doc_blocks.py).
tests/test_observe.py checks those with its shared reports; tests/test_doc_numbers.py checks the others
(`cheap_blocks`: constants and records).
"""
from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

from magyro.observability import ObservabilityReport, observe
from magyro.observability.report import fmt

sys.path.insert(0, str(Path(__file__).resolve().parent))
import doc_blocks  # noqa: E402

PAGE = Path(__file__).resolve().parent / "observability.md"
CANONICAL = (  # problem, motion, rank the theorem predicts (docs/observability.md derives it)
    ("static", "none", 2),
    ("axis-x", "about gyro x only", 6),
    ("axis-y", "about gyro y only", 6),
    ("axis-z", "about gyro z only", 6),
    ("two-axes", "x, then y", 9),
    ("three-axes", "x, then y, then z", 12),
    ("paper-table1", "x, y, z at once (Table I)", 12),
)
COMMAND = "python docs/make_observability_table.py"
PREDICTED_RECORD = "predicted-vs-actual"    # benchmarks/predicted_vs_actual.py --out, section 6
SPEED_RECORD = "bench-observe"               # benchmarks/bench_observe.py --out, section 7
REPORT_BLOCKS = ("canonical", "three-axes-full-rank", "three-axes-scale", "paper-full-rank", "paper-condition",
                 "two-axes-scale")            # made from observe's reports (report_blocks)


def canonical_reports(seed: int = 0) -> dict[str, ObservabilityReport]:
    """observe() on every canonical problem of problems/, simulated with `seed`."""
    from magyro.studies.scenario import load_problem
    from magyro.studies.simulate import simulate

    return {name: observe(simulate(load_problem(name), seed)[0]) for name, _, _ in CANONICAL}


def canonical_table(seed: int = 0, reports: dict | None = None) -> str:
    """The rank/condition table of the canonical problems as the tool reports them (3 significant digits)."""
    reports = reports or canonical_reports(seed)
    lines = ["| problem | motion | rank (theorem) | rank (magyro) | condition | full rank at (s) | sphere visited | verdict |",
             "|---|---|---:|---:|---:|---:|---:|---|"]
    for name, motion, theorem in CANONICAL:
        r = reports[name]
        lines.append(f"| {name} | {motion} | {theorem} | {r.rank} | {fmt(r.condition)} | "
                     f"{'never' if r.full_rank_at_s is None else fmt(r.full_rank_at_s)} | "
                     f"{100 * r.coverage.sphere_fraction:.0f}% | {r.verdict} |")
    return "\n".join(lines)


def table_in_page(text: str) -> str:
    """The canonical table of a page (its `canonical` block)."""
    return doc_blocks.block_in_page(text, "canonical")


def about(x: float) -> str:
    """Two significant digits without an exponent ("about 1600")."""
    return f"{float(f'{x:.2g}'):g}"


def canonical_notes(reports: dict) -> dict[str, str]:
    """The numbers the notes under the table quote from the reports."""
    from magyro.studies.scenario import load_problem

    three, two, paper = reports["three-axes"], reports["two-axes"], reports["paper-table1"]
    problem = load_problem("three-axes")
    slot = problem.duration_s / 3
    return {
        "three-axes-full-rank": (f"**`three-axes` becomes full rank at {fmt(three.full_rank_at_s)} s.** The z slot "
                                 f"starts at {fmt(2 * slot)} s, and one axis slot holds only {fmt(slot)} s of turning"),
        "three-axes-scale": f"scale factor about {about(1e6 * np.max(np.diag(three.predicted_std.K_g)))} ppm",
        "paper-full-rank": f"full rank after {fmt(paper.full_rank_at_s)} s",
        "paper-condition": f"The paper's Table I motion ends at {fmt(paper.condition)}.",
        "two-axes-scale": f"known only to about {about(100 * two.predicted_std.K_g[2][2])} %",
    }


def report_blocks(reports: dict | None = None) -> dict[str, str]:
    """The blocks made from `magyro observe` on the canonical problems (tests/test_observe.py checks them)."""
    reports = reports or canonical_reports()
    return {"canonical": canonical_table(reports=reports), **canonical_notes(reports)}


def cheap_blocks() -> dict[str, str]:
    """The blocks made from the code's constants and the records (tests/test_doc_numbers.py checks them)."""
    from magyro.observability.excitation import CHECKPOINTS
    from magyro.observability.gate import FLOOR_FACTOR, NUMERICAL_RTOL, WELL_CONDITIONED
    from magyro.observability.report import SPHERE_BANDS, SPHERE_SECTORS

    from magyro.nls.grid import STRIDES
    from magyro.nls.solve import MIN_NODE_RATE_HZ

    from magyro.targets import Targets

    t = Targets()
    out = {
        "targets-table": doc_blocks.table(["target", "default", "flag"], [
            ["scale factor (K_g diagonal)", f"{doc_blocks.g(t.scale_factor_ppm)} ppm", "`--target-scale-ppm`"],
            ["non-orthogonality (K_g off-diagonal, as an angle)", f"{doc_blocks.g(t.non_orthogonality_deg)} deg",
             "`--target-nonorth-deg`"],
            ["gyro bias", f"{doc_blocks.g(t.bias_deg_s)} deg/s", "`--target-bias-deg-s`"],
            ["misalignment (roll, pitch, yaw of C_b^m)", f"{doc_blocks.g(t.misalignment_deg)} deg",
             "`--target-misalignment-deg`"]], left=(0, 2)),
        "paper-std": paper_ranges(),
        "observe-stride": (f"{max(STRIDES)}, or {min(STRIDES)} below {doc_blocks.g(max(STRIDES) * MIN_NODE_RATE_HZ)} "
                           f"Hz, for at least {doc_blocks.g(MIN_NODE_RATE_HZ)} nodes per second"),
        "floor": (f"`lambda_v > {doc_blocks.g(FLOOR_FACTOR)} v^T N v`, that is, when it holds {doc_blocks.g(FLOOR_FACTOR)} "
                  "times what noise alone would put in that very direction. There is also a numerical tolerance of "
                  f"`{doc_blocks.g(NUMERICAL_RTOL)}` times the largest eigenvalue"),
        "checkpoints": f"{CHECKPOINTS} evenly spaced checkpoints",
        "well-conditioned": f"below **{doc_blocks.g(WELL_CONDITIONED)}**",
        "checkpoint-spacing": f"1/{CHECKPOINTS} of the analysed span",
        "timeline-checkpoints": f"the {CHECKPOINTS} checkpoints",
        "sphere-grid": (f"**{SPHERE_BANDS * SPHERE_SECTORS} equal-area cells**: {SPHERE_BANDS} bands of equal height "
                        f"in `z` (by Archimedes' hat-box theorem, equal heights cut equal areas) times {SPHERE_SECTORS} "
                        f"sectors of {doc_blocks.g(360 / SPHERE_SECTORS)} deg longitude"),
    }
    if doc_blocks.has_record(PREDICTED_RECORD):
        out.update(predicted_blocks(doc_blocks.read_record(PREDICTED_RECORD)))
    if doc_blocks.has_record(SPEED_RECORD):
        out.update(speed_blocks(doc_blocks.read_record(SPEED_RECORD)))
    return out


def speed_blocks(record: dict) -> dict[str, str]:
    """Section 7: benchmarks/bench_observe.py's record, labelled with its date, machine and load."""
    med = {k: float(np.median(record[k])) for k in ("process_s", "process_one_blas_thread_s", "call_s",
                                                    "prediction_s")}
    rows = ([["whole process, first run (empty kernel cache: compiles)", f"{record['cold_process_s']:.2f}"]]
            if "cold_process_s" in record else [])
    rows += [["whole process (`magyro observe SESSION -o report.json -q`)", f"{med['process_s']:.2f}"],
             ["whole process, `OPENBLAS_NUM_THREADS=1`", f"{med['process_one_blas_thread_s']:.2f}"],
             ["start-up: `import magyro.cli, magyro.observability.excitation`", f"{record['import_s']:.2f}"],
             ["`observe()` call", f"{med['call_s']:.2f}"],
             [f"of which the accuracy prediction (stride {record['prediction_stride']})", f"{med['prediction_s']:.2f}"]]
    speed = (f"`{record['command']}`, on `{record['problem']}`: 100 s at 100 Hz, {record['samples']} gyro and "
             f"{record['samples']} magnetometer samples, median of {record['repeat']}; measured on {record['date']} at "
             f"commit `{record['commit']}` on {record['machine']} ({record['other_load']}):\n\n"
             + doc_blocks.table(["what", "seconds"], [r for r in rows], left=(0,)))
    strides = doc_blocks.table(
        ["stride", "nodes per second", "seconds (kernels compiled)", "first call (compiles if not cached)",
         "largest change vs stride 1"],
        [[str(r["stride"]), f"{r['nodes_per_s']:g}", f"{r['seconds']:.2f}", f"{r['first_call_seconds']:.2f}",
          f"{100 * r['max_change_vs_stride_1']:.2f} %"] for r in record.get("strides", [])], left=())
    return {"observe-speed": speed, "observe-strides": strides}


def sampling_note(ratio: np.ndarray, runs: int) -> str:
    """Whether the ratios' median lies within the one-sigma sampling scatter of a spread of `runs` solves."""
    m = float(np.median(ratio))
    if abs(m - 1) <= 1 / np.sqrt(2 * (runs - 1)):
        return ", so the remaining differences are sampling scatter."
    side = "cautious (above the spread)" if m > 1 else "optimistic (below the spread)"
    return (f"; the median ratio, {m:.2f}, lies beyond that scatter: the prediction "
            f"is {side} by about {100 * abs(m - 1):.0f} %.")


def paper_ranges() -> str:
    """The paper's Table I std (magyro.studies.montecarlo_table), as ranges per group."""
    from magyro.studies.montecarlo_table import PAPER_TABLE1_STD as p

    def rng(prefix, scale=1.0):
        v = [scale * x for k, x in p.items() if k.startswith(prefix)]
        return f"{min(v):g} to {max(v):g}"

    return (f"`K_g` {rng('K_g', 1e4)}e-4, bias {rng('bias', 1e3)}e-3 deg/s, misalignment {rng('euler')} deg")


def predicted_blocks(record: dict) -> dict[str, str]:
    """Section 6: the prediction against the actual spread, from benchmarks/predicted_vs_actual.py's record."""
    names = record["parameters"]
    pred, pred1, actual, reported = (np.asarray(record[k], dtype=float) for k in
                                     ("predicted", "predicted_stride_1", "actual", "mean_reported_std"))
    ratio = pred / actual
    band = record.get("band", 0.25)
    rows = [[n, fmt(p), fmt(p1), fmt(a), fmt(r), f"{q:.2f}", "yes" if abs(q - 1) <= band else "no"]
            for n, p, p1, a, r, q in zip(names, pred, pred1, actual, reported, ratio)]
    n = record["runs"]
    inside10 = int(np.sum(np.abs(ratio - 1) <= 0.10))
    return {
        "predicted-command": (f"With N = {n} (`{record['command']}`, {record['date']}, commit `{record['commit']}`; "
                              f"{record['seconds']:.0f} s on this shared 2-core machine, one job)"),
        "predicted-table": doc_blocks.table(
            ["parameter", "predicted (observe)", "predicted (stride 1)", "actual spread", "mean reported std (solve)",
             "predicted / actual", f"within +/-{100 * band:.0f} %"], rows, left=(0, -1)),
        "predicted-summary": (f"The ratio of predicted to actual lies between {ratio.min():.2f} and {ratio.max():.2f}, "
                              f"median {np.median(ratio):.2f}: {int(np.sum(np.abs(ratio - 1) <= band))} of "
                              f"{len(ratio)} gyro parameters are within +/-{100 * band:.0f} %, {inside10} within "
                              f"+/-10 %. With {n} runs the actual spread is itself uncertain by about "
                              f"+/-{100 / np.sqrt(2 * (n - 1)):.0f} % (one sigma)" + sampling_note(ratio, n)),
    }


def blocks() -> dict[str, str]:
    return {**report_blocks(), **cheap_blocks()}


def keep_record(path: Path) -> Path:
    """benchmarks/predicted_vs_actual.py's --out JSON as the record docs/numbers/predicted-vs-actual.json."""
    import datetime
    import json

    d = json.loads(Path(path).read_text(encoding="utf-8"))
    d.pop("estimates", None)
    d.update(command=f"python benchmarks/predicted_vs_actual.py --runs {d['runs']} --jobs {d.get('jobs', 1)} --out FILE",
             date=datetime.date.today().isoformat(), commit=doc_blocks.commit())
    return doc_blocks.write_record(PREDICTED_RECORD, d)


def main(argv: list[str]) -> int:
    if "--record" in argv:
        i = argv.index("--record")
        print(f"wrote {keep_record(Path(argv[i + 1]))}")
        argv = argv[:i] + argv[i + 2:]
    return doc_blocks.main(argv, PAGE, blocks, COMMAND)


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
