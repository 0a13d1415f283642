"""Re-measure the records of docs/numbers/ that are cheap enough, and fail when a number the docs render has moved.

    python benchmarks/verify_records.py                 re-run every covered record, compare, exit 1 on any FAIL
    python benchmarks/verify_records.py --list          which records are covered, which are not and why (cost)
    python benchmarks/verify_records.py --only NAME,NAME
    python benchmarks/verify_records.py --keep DIR      keep the fresh records in DIR (to commit one that moved)

A record is covered when its command takes under about two minutes on the quiet 2-core machine the records are
measured on (the costs below were measured there under other work's load, 1.8-1.9 CPUs taken by other processes,
so up to 2-3x their quiet cost; `--list` prints them). Each covered record
is re-run into a temporary file with its own command and compared with the committed one on the fields its pages
render, each with a tolerance of its kind:

- a deterministic estimate (fixed seeds, fixed data): to a fraction of its own std, or to 1 % where the number is
  not in units of a std (the renderers print 2-3 significant digits; a code change moves them far more);
- a timing: within the factor the table states (2x for a wall or CPU time, 1.25x for a ratio of two CPU times
  of one process), and only when the fresh run is on the record's machine (its `machine` string) and other
  processes took under half a CPU both while it ran and while the record was measured (the record's `other_load`,
  when it has one): a timing on a busy or different machine is shown, marked SKIP, and fails nothing (a check
  that fails on load would be a check of the machine, not of the code). Even then a timing beyond its factor is
  only shown, marked MOVED, unless `--strict-timings`: one kind of 2-core machine ran the same commit's BROAD 02
  solve at 0.94 s of CPU on one day and 2.0 s on another, both quiet (CI fails on numbers, not on speed);
- a count or a label: exactly.

Records that read ../shared/data (BROAD) are skipped, saying so, only when ../shared is absent (CI has it).
A record not covered is too expensive to re-run here: the page that renders it states its commit
(tests/test_doc_numbers.py checks that for every record of NOT_COVERED), and it is refreshed by hand with its
command (docs/numbers/README.md).
"""

import argparse
import json
import math
import re
import os
import shlex
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent
RECORDS = ROOT / "docs" / "numbers"
SHARED = ROOT.parent / "shared"
BROAD = SHARED / "data" / "broad"

sys.path.insert(0, str(HERE))
from machine_load import busy_cpu_s  # noqa: E402

QUIET_OTHER_CPUS = 0.5       # other processes' CPU per wall second under which a timing is compared


# --------------------------------------------------------------------------- what a record's fields are


def at(path: str) -> Callable[[dict], list]:
    """The values at a dotted path of a record; `*` is every item of a list or every value of a dict (sorted keys)."""
    def get(record: dict) -> list:
        items = [record]
        for part in path.split("."):
            out = []
            for item in items:
                if part == "*":
                    out.extend(item[k] for k in sorted(item)) if isinstance(item, dict) else out.extend(item)
                elif isinstance(item, list):
                    out.append(item[int(part)])
                else:
                    out.append(item[part])
            items = out
        return flattened(items)
    return get


def flattened(items: list) -> list:
    """Nested lists as one list of numbers and labels, in order."""
    flat = []
    for item in items:
        flat.extend(flattened(item)) if isinstance(item, list) else flat.append(item)
    return flat


def per_row(key: str, rows: str = "rows") -> Callable[[dict], list]:
    """`key` of every row; a row without it (a refused case) gives the label 'refused' or None."""
    return lambda r: flattened([row[key] if key in row else ("refused" if "refused" in row else None)
                                for row in r[rows]])


def ratio_of(numerator: str, denominator: str) -> Callable[[dict], list]:
    return lambda r: [a / b for a, b in zip(at(numerator)(r), at(denominator)(r))]


@dataclass
class Field:
    """A rendered number (or list of them) and its tolerance: `abs` or `rel` (estimates), `factor` (timings), or
    exact (neither: counts, labels)."""
    name: str
    get: Callable[[dict], list] | None = None
    abs: float | None = None
    rel: float | None = None
    factor: float | None = None
    timing: bool = False

    def values(self, record: dict) -> list:
        return (self.get or at(self.name))(record)

    def tolerance(self) -> str:
        if self.factor is not None:
            return f"x{self.factor:g}" + (" (timing)" if self.timing else "")
        if self.abs is not None:
            return f"+/-{self.abs:g}"
        if self.rel is not None:
            return f"{100 * self.rel:g} %"
        return "exact"

    def within(self, old, new) -> bool:
        if isinstance(old, str) or isinstance(new, str) or old is None or new is None:
            return old == new
        old, new = float(old), float(new)
        if self.factor is not None:
            return old > 0 and new > 0 and max(new / old, old / new) <= self.factor
        if self.abs is not None:
            return abs(new - old) <= self.abs
        if self.rel is not None:
            return abs(new - old) <= self.rel * abs(old)
        return math.isclose(old, new, rel_tol=1e-12, abs_tol=0.0)


@dataclass
class Record:
    """A covered record: its command (`{out}`: the fresh record's path), its cost, the fields its pages render."""
    name: str
    command: str
    cost: str                      # wall time of the command on the 2-core machine, warm kernel cache: "half-loaded"
                                   # other processes took 1.0 CPU (whole run 327 s), "loaded" 1.8-1.9 CPUs (1042 s)
    fields: list[Field]
    pages: tuple[str, ...]
    shared: bool = False           # reads ../shared/data
    partial: bool = False          # re-runs part of the record (its commit is then stated on its pages too)
    machine: Callable[[dict], str | None] = lambda r: r.get("machine") or r.get("provenance", {}).get("machine")
    note: str = ""


# --------------------------------------------------------------------------- the covered records


def deterministic(path: str, **tol) -> Field:
    return Field(path, **tol)


def timing(path: str, factor: float = 2.0, get=None) -> Field:
    return Field(path, get=get, factor=factor, timing=True)


COVERED: list[Record] = [
    Record("stride-agreement", "python benchmarks/stride_agreement.py --out {out}", "24 s half-loaded, 87-142 s loaded (5 min 49 s on a cold kernel cache)",
           [deterministic("rows.*.max_abs_z", abs=0.01), Field("rows.*.worst"), Field("rows.*.strides")],
           ("docs/how-it-works.md",)),
    Record("trajectory-accuracy", "python benchmarks/trajectory_accuracy.py --out {out}", "38 s half-loaded, 100-274 s loaded (11 s quiet)",
           [deterministic("simulated.rms_z", abs=0.02), Field("simulated.runs"),
            deterministic("broad_02.median_deg", rel=0.01), deterministic("broad_02.p95_deg", rel=0.01),
            deterministic("broad_02.rms_z_per_axis", abs=0.05)],
           ("docs/using-the-result.md", "docs/real-data.md")),
    Record("ekf-lag-shipped", "python benchmarks/ekf_lag_shipped.py --out {out}", "16 s half-loaded, 83-139 s loaded",
           [deterministic("eq13_lag_ms", abs=0.05), deterministic("ekf_lag_ms", abs=0.05),
            deterministic("ekf_lag_std_ms", abs=0.05), Field("filter_runs"), Field("trial")],
           ("docs/ekf.md",)),
    Record("accelerometer-broad-02", "python benchmarks/accelerometer.py real --out {out}", "18 s half-loaded, 114-135 s loaded",
           [deterministic("rests.*.f_over_g", abs=1e-5), deterministic("rests.*.raw_over_g", abs=1e-5),
            deterministic("rests.*.span_s", abs=0.05),
            deterministic("halves_rms_z", abs=0.01), deterministic("halves_max_z", abs=0.05), Field("halves_worst"),
            deterministic("halves_gyro_rms_z", abs=0.01), deterministic("gyro_std_ratio.*", abs=0.01),
            timing("solve_cpu_s"), timing("solve_cpu_s_accelerometer"),
            timing("solve_cpu_s_accelerometer / solve_cpu_s", 1.25,
                   ratio_of("solve_cpu_s_accelerometer", "solve_cpu_s"))],
           ("docs/accelerometer.md",)),
    Record("split-check-shipped", "python benchmarks/split_check_shipped.py --out {out}", "10 s half-loaded, 52-89 s loaded",
           [deterministic("rows.*.rms_z", abs=0.01), deterministic("rows.*.max_abs_z", abs=0.05),
            Field("rows.*.worst"), deterministic("rows.*.spans_s", abs=0.05), Field("rows.*.command")],
           ("docs/how-it-works.md", "docs/results.md")),
    Record("predicted-vs-actual", "python benchmarks/predicted_vs_actual.py --runs 100 --jobs 1 --out {out}",
           "66 s half-loaded, 79 s beside another job",
           [Field("runs"), deterministic("predicted", rel=0.01), deterministic("predicted_stride_1", rel=0.01),
            deterministic("actual", rel=0.01), deterministic("mean_reported_std", rel=0.01),
            deterministic("ratio", abs=0.01)],
           ("docs/observability.md", "docs/results.md")),
    Record("attached-magnets", "python benchmarks/attached_magnets.py --out {out}", "82 s half-loaded, 77 s beside another job",
           [deterministic("undisturbed.scale_ppm_mean", abs=5.0), deterministic("undisturbed.scale_ppm_min", abs=5.0),
            deterministic("undisturbed.scale_ppm_max", abs=5.0),
            Field("rows.*.trial"), Field("rows.*.walk_ut_sqrt_s"),
            Field("scale_minus_undisturbed_ppm", per_row("scale_minus_undisturbed_ppm"), abs=50.0),
            Field("scale_std_ppm", per_row("scale_std_ppm"), rel=0.01),
            Field("bias_minus_rests_deg_s", per_row("bias_minus_rests_deg_s"), abs=0.003),
            Field("bias_std_deg_s", per_row("bias_std_deg_s"), rel=0.01),
            Field("rest_bias_deg_s", per_row("rest_bias_deg_s"), abs=0.003),
            Field("field_disturbance_percent", per_row("field_disturbance_percent"), abs=0.1)],
           ("docs/real-data.md",), shared=True),
    Record("bench-recording-check", "python benchmarks/bench_recording_check.py --out {out}", "21 s half-loaded, 101-120 s loaded",
           [Field("rows.*.session"), Field("rows.*.samples"), timing("rows.*.check_s"), timing("rows.*.solve_s"),
            timing("rows.*.check_s / solve_s", 2.0, ratio_of("rows.*.check_s", "rows.*.solve_s"))],
           ("docs/how-it-works.md",)),
    Record("bench-ekf", "python benchmarks/bench_ekf.py --repeat 3 --out {out}", "35 s half-loaded, 112-152 s loaded",
           [Field("rows.*.problem"), Field("rows.*.samples"), Field("rows.*.duration_s"),
            timing("rows.*.filter_26_s"), timing("rows.*.filter_17_s"), timing("rows.*.calibrate_s"),
            timing("rows.*.filter_26_samples_per_cpu_s"), timing("rows.*.filter_17_samples_per_cpu_s")],
           ("docs/ekf.md",)),
    Record("std-on-real-data", "python benchmarks/std_on_real_data.py --trials 02 --distorted 02 --out {out}",
           "17 s half-loaded, 72 s loaded (trial 02 of 6)",
           [deterministic("trials.02.disturbance_percent", rel=0.01),
            deterministic("trials.02.correlation_time_s", rel=0.01),
            deterministic("trials.02.std_over_white_median", rel=0.01),
            deterministic("trials.02.split_rms_z", abs=0.01), deterministic("trials.02.split_rms_z_white", abs=0.01),
            deterministic("distortions.02.std.*", abs=0.02), deterministic("distortions.02.std_white.*", abs=0.02)],
           ("docs/how-it-works.md", "docs/results.md", "docs/real-data.md", "docs/ekf.md"), shared=True, partial=True,
           note="trial 02 only (the whole record, 6 trials and day B's chi-square, is 153 s half-loaded, 141 s of CPU, "
                "402 s loaded: over two minutes even quiet; its commit is on its pages)"),
]


# --------------------------------------------------------------------------- the records not covered


@dataclass
class Expensive:
    name: str
    cost: str
    pages: tuple[str, ...]
    why: str = "over two minutes"


NOT_COVERED: list[Expensive] = [
    Expensive("accelerometer-paper-table1-acc", "estimated 10-20 min (200 seeds, 2 jobs; not timed)", ("docs/accelerometer.md",)),
    Expensive("accelerometer-phone-module-acc", "estimated 10-20 min (200 seeds, 2 jobs; not timed)", ("docs/accelerometer.md",)),
    Expensive("accelerometer-paper-table1-acc-still", "estimated 5-10 min (80 seeds; not timed)", ("docs/accelerometer.md",)),
    Expensive("accelerometer-real", "about 20 min quiet, as its command states (every real recording)", ("docs/accelerometer.md",)),
    Expensive("accelerometer-hand-models", "over 15 min loaded (stopped at 900 s), 4 min quiet: hand models x two "
              "problems",
              ("docs/accelerometer.md",)),
    Expensive("hand-states-std-paper-table1-acc", "338 s loaded, 1-2 min quiet (64 seeds, 2 jobs)",
              ("docs/accelerometer.md",)),
    Expensive("hand-states-std-phone-module-acc", "estimated as paper-table1-acc's (64 seeds, 2 jobs; not timed)",
              ("docs/accelerometer.md",)),
    Expensive("broad-reference", "7 min 19 s loaded (432 s of trials; 112 s quiet): nine BROAD trials", ("docs/real-data.md",)),
    Expensive("broad-trials", "estimated 5-10 min (ten BROAD trials with split checks; not timed); trial 02 "
              "re-measured by tests/test_doc_numbers.py's broad test",
              ("docs/real-data.md", "docs/how-it-works.md", "docs/results.md", "docs/ekf.md")),
    Expensive("ekf-real-data", "estimated 10-20 min (EKF and NLS on BROAD and the wild recordings, EKF solves up to 68 s "
              "each in its record; needs an import of ../shared/data/wild)", ("docs/ekf.md", "docs/how-it-works.md")),
    Expensive("ekf-variants", "762 s loaded (196 s quiet, its former record): five EKF variants x ten seeds", ("docs/ekf.md",)),
    Expensive("montecarlo-paper-table1", "169 s (its record; 50 runs, NLS and EKF)",
              ("docs/table1.md", "docs/how-it-works.md", "docs/results.md")),
    Expensive("montecarlo-paper-table1-200", "444 s (its record; 200 runs)", ("docs/table1.md",)),
    Expensive("bench-observe", "estimated 3-4 min (a cold process with an empty kernel cache, 55 s in its record, and "
              "strides 1-20; not timed)",
              ("docs/observability.md",)),
    Expensive("bench-scale", "estimated several minutes (a one-hour session of 360k samples; not timed)",
              ("docs/development.md",)),
    Expensive("bench-cold-start", "12 min loaded (a wheel install compiling 23 kernels, then seven cases cold and warm)",
              ("docs/development.md",)),
    Expensive("suite-time", "403 s (its record: the whole test suite)", ("README.md",), why="the whole suite"),
    Expensive("ekf-check-sims", "several minutes (36 simulated runs with a reference attitude, EKF and NLS)",
              ("docs/ekf.md",)),
    Expensive("ekf-real-data-joint", "several minutes (the EKF with R and h as states on BROAD 02, 07, 09 with split "
              "checks; needs ../shared/data/broad)", ("docs/ekf.md",)),
    Expensive("ekf-table1-targets", "a few minutes (20 EKF Monte Carlo runs of paper-table1)", ("docs/ekf.md",)),
    Expensive("wild-corpus", "about 1 min quiet (ten real recordings imported, checked, observed and solved by both "
              "methods; needs ../shared/data/wild)", ("docs/results.md",)),
    Expensive("hand-turned-phones", "about 1.5 min quiet, 3 min loaded (12 simulated phones, the two iPhone replicas; "
              "needs ../shared for the replicas)", ("docs/how-it-works.md",)),
]


# --------------------------------------------------------------------------- running and comparing


def committed(name: str) -> dict:
    return json.loads((RECORDS / f"{name}.json").read_text(encoding="utf-8"))


def record_commit(record: dict) -> str:
    return record.get("commit") or record.get("provenance", {}).get("commit", "?")


def run(spec: Record, out: Path) -> tuple[float, float, str]:
    """Run the record's command into `out`: (wall seconds, other processes' CPU per wall second, output tail)."""
    argv = shlex.split(spec.command.format(out=out))
    argv[0] = sys.executable if argv[0] == "python" else argv[0]
    before_busy, before_own = busy_cpu_s(), _children_cpu_s()
    t0 = time.perf_counter()
    done = subprocess.run(argv, cwd=ROOT, capture_output=True, text=True)
    wall = time.perf_counter() - t0
    other = max(0.0, (busy_cpu_s() - before_busy) - (_children_cpu_s() - before_own)) / max(wall, 1e-9)
    if done.returncode != 0:
        raise RuntimeError(f"exit {done.returncode}: {(done.stdout + done.stderr)[-2000:]}")
    return wall, other, done.stdout[-500:]


def _children_cpu_s() -> float:
    import resource

    u = resource.getrusage(resource.RUSAGE_CHILDREN)
    return u.ru_utime + u.ru_stime


def show(values: list) -> str:
    def one(v):
        if isinstance(v, float):
            return f"{v:.4g}"
        return str(v)
    text = ", ".join(one(v) for v in values)
    return text if len(text) <= 60 else text[:57] + "..."


def recorded_load(record: dict) -> float | None:
    """The other processes' CPUs while the record was measured (its `other_load` line), None when not recorded."""
    m = re.search(r"\((\d+) % of one of", record.get("other_load", ""))
    return None if m is None else int(m.group(1)) / 100.0


def compare(spec: Record, old: dict, new: dict, other_cpus: float,
            strict_timings: bool = False) -> list[tuple[str, str, str, str, str]]:
    """One row per field: (field, old, new, tolerance, PASS / FAIL / SKIP reason)."""
    rows = []
    same_machine = spec.machine(old) is None or spec.machine(old) == spec.machine(new)
    for f in spec.fields:
        try:
            a, b = f.values(old), f.values(new)
        except (KeyError, IndexError, TypeError) as e:
            rows.append((f.name, "?", "?", f.tolerance(), f"FAIL (missing {e})"))
            continue
        try:
            ok = len(a) == len(b) and all(f.within(x, y) for x, y in zip(a, b))
        except (TypeError, ValueError) as e:
            rows.append((f.name, show(a), show(b), f.tolerance(), f"FAIL (not comparable: {e})"))
            continue
        verdict = "PASS" if ok else "FAIL"
        if f.timing and not ok and not strict_timings:
            verdict = ("MOVED (a timing: shown, not failed; the same kind of machine ran the base commit's BROAD 02 "
                       "solve at 2.1x its recorded CPU on another day; --strict-timings fails it)")
        elif f.timing and not ok:
            if not same_machine:
                verdict = f"SKIP (machine {spec.machine(new)!r}, record's {spec.machine(old)!r})"
            elif other_cpus > QUIET_OTHER_CPUS:
                verdict = f"SKIP (busy now: other processes {other_cpus:.1f} CPUs)"
            elif (recorded := recorded_load(old)) is not None and recorded > QUIET_OTHER_CPUS:
                verdict = f"SKIP (the record was measured busy: other processes {recorded:.1f} CPUs)"
        rows.append((f.name, show(a), show(b), f.tolerance(), verdict))
    return rows


def list_records() -> None:
    print("covered (re-run and compared):")
    for s in COVERED:
        needs = " [needs ../shared]" if s.shared else ""
        print(f"  {s.name:<34} {s.cost:<46} {s.command}{needs}" + (f"\n  {'':<34} {s.note}" if s.note else ""))
    print("\nnot covered (their commit stated on the pages that render them):")
    for e in NOT_COVERED:
        c = record_commit(committed(e.name))
        print(f"  {e.name:<38} commit {c:<8} {e.cost}; {', '.join(e.pages)}")
    known = {s.name for s in COVERED} | {e.name for e in NOT_COVERED}
    extra = sorted(p.stem for p in RECORDS.glob("*.json") if p.stem not in known)
    if extra:
        print(f"\nin docs/numbers but in neither list: {', '.join(extra)}")


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--list", action="store_true", help="show the covered records and those too expensive")
    ap.add_argument("--only", help="comma-separated record names")
    ap.add_argument("--keep", type=Path, help="write the fresh records into this folder")
    ap.add_argument("--strict-timings", action="store_true",
                    help="fail a timing beyond its factor (quiet machine, record's machine) instead of showing it")
    a = ap.parse_args(argv)
    if a.list:
        list_records()
        return 0
    chosen = [s for s in COVERED if not a.only or s.name in a.only.split(",")]
    if a.only and len(chosen) != len(a.only.split(",")):
        ap.error(f"--only: covered records are {', '.join(s.name for s in COVERED)}")
    failed, t_all = [], time.perf_counter()
    with tempfile.TemporaryDirectory() as tmp:
        folder = a.keep or Path(tmp)
        folder.mkdir(parents=True, exist_ok=True)
        for spec in chosen:
            command = spec.command.format(out=f"FRESH/{spec.name}.json")
            print(f"\n== {spec.name}: {command}" + (f"  ({spec.note})" if spec.note else ""), flush=True)
            if spec.shared and not BROAD.is_dir():
                print(f"SKIP: no ../shared/data/broad beside the checkout ({BROAD})")
                continue
            out = folder / f"{spec.name}.json"
            try:
                wall, other, _ = run(spec, out)
            except RuntimeError as e:
                print(f"FAIL: the command failed: {e}")
                failed.append(spec.name)
                continue
            old, new = committed(spec.name), json.loads(out.read_text(encoding="utf-8"))
            print(f"{wall:.0f} s; other processes {other:.1f} CPUs; record's commit {record_commit(old)}")
            rows = compare(spec, old, new, other, a.strict_timings)
            width = max(len(r[0]) for r in rows)
            for r in rows:
                print(f"  {r[0]:<{width}}  old {r[1]:<28} new {r[2]:<28} tol {r[3]:<16} {r[4]}")
            if any(r[4].startswith("FAIL") for r in rows):
                failed.append(spec.name)
    total = time.perf_counter() - t_all
    print(f"\n{len(chosen)} records in {total:.0f} s ({os.cpu_count()} CPUs): "
          + (f"FAIL: {', '.join(failed)}; re-measure with the record's command (docs/numbers/README.md)"
             if failed else "all PASS"))
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
