"""What the first run costs on an empty kernel cache, and which commands compile again after one solve.

    python benchmarks/bench_cold_start.py [--repeat 3] [--out results.json]

magyro is first installed as a user installs it (`pip install .`, here
`pip install --no-deps --target DIR .`, with pip's isolated build, so that it
runs on the running Python's dependencies: the install compiles the usual kernels
into the package, and its seconds are in the table), and every run is a
`python -m magyro` process of that copy with MAGYRO_CACHE_DIR set to a folder of
this benchmark's; the files that appear in that folder during a run are the
kernels it compiled. Cases:

    (a) the README's first command, `magyro solve data/broad-02.parquet -o calib.json`, on an empty cache,
        then again on the same cache (warm)
    (b) `magyro observe data/broad-02.parquet` on an empty cache; and right after (a)'s solve
    (c) `magyro solve data/broad-02.parquet --loss huber` right after (a)'s solve
    (d) `magyro solve data/broad-02.parquet --split-check` right after (a)'s solve
    (e) `magyro solve data/simulated-phone-module.parquet` (another rate) right after (a)'s solve
    (f) `magyro solve data/broad-02.parquet` from the source tree on an empty cache (an editable install, or
        an install without a C compiler: the first solve compiles)

"Right after (a)'s solve" is a copy of the cache as (a) left it, one copy per
case, so no case profits from another's kernels. Each case then runs a second
time on its own cache: the same command with nothing left to compile. See
benchmarks/README.md.
"""
from __future__ import annotations

import argparse
import json
import os
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from machine_load import busy_cpu_s, other_load_line, own_cpu_s

REPO = Path(__file__).resolve().parents[1]
BROAD = REPO / "data" / "broad-02.parquet"
PHONE = REPO / "data" / "simulated-phone-module.parquet"
TARGET_COLD_OVER_WARM = 2.0

# (key, what, magyro arguments before the output option, output kind, cache it starts from)
CASES = [
    ("a", "solve broad-02 (README's first command)", ["solve", str(BROAD)], "calib", "empty"),
    ("b", "observe broad-02", ["observe", str(BROAD)], "none", "empty"),
    ("b", "observe broad-02", ["observe", str(BROAD)], "none", "after solve"),
    ("c", "solve broad-02 --loss huber", ["solve", str(BROAD), "--loss", "huber"], "calib", "after solve"),
    ("d", "solve broad-02 --split-check", ["solve", str(BROAD), "--split-check"], "calib", "after solve"),
    ("e", "solve simulated-phone-module", ["solve", str(PHONE)], "calib", "after solve"),
    ("f", "solve broad-02, from the source tree", ["solve", str(BROAD)], "calib", "empty, source tree"),
]


def install_magyro(folder: Path) -> float:
    """`pip install` this checkout into `folder` (no dependencies: the running Python's); its seconds."""
    start = time.perf_counter()
    subprocess.run([sys.executable, "-m", "pip", "install", "--quiet", "--no-deps",
                    "--target", str(folder), str(REPO)], check=True, stdout=subprocess.DEVNULL)
    seconds = time.perf_counter() - start
    where = subprocess.run([sys.executable, "-c", "import magyro; print(magyro.__file__)"], capture_output=True,
                           text=True, check=True, env={**os.environ, "PYTHONPATH": str(folder)}, cwd=folder).stdout
    assert where.startswith(str(folder)), where
    return seconds


def magyro_executable() -> str:
    beside_python = Path(sys.executable).parent / "magyro"
    return str(beside_python) if beside_python.exists() else (shutil.which("magyro") or "magyro")


def cache_files(cache: Path) -> set[str]:
    return {str(p.relative_to(cache)) for p in cache.rglob("*") if p.is_file()} if cache.exists() else set()


def run_in_cache(args: list[str], cache: Path, out: Path | None, site: Path | None) -> dict:
    """One magyro process (the copy installed in `site`, else the source tree's) with MAGYRO_CACHE_DIR=cache: wall
    seconds, peak RSS and the cache files it added."""
    argv = ([sys.executable, "-m", "magyro"] if site else [magyro_executable()]) + args + (["-o", str(out)] if out else [])
    before = cache_files(cache)
    env = {**os.environ, "MAGYRO_CACHE_DIR": str(cache)}
    if site:
        env["PYTHONPATH"] = str(site)
    with tempfile.TemporaryFile() as stderr:
        start = time.perf_counter()
        child = subprocess.Popen(argv, stdout=subprocess.DEVNULL, stderr=stderr, env=env,
                                 cwd=site)   # outside the checkout: not the checkout's magyro
        _, status, usage = os.wait4(child.pid, 0)
        wall_s = time.perf_counter() - start
        code = os.waitstatus_to_exitcode(status)
        error = ""
        if code != 0:   # recorded and shown in the table; the other cases still run
            stderr.seek(0)
            lines = stderr.read().decode(errors="replace").strip().splitlines()
            error = f"exit {code}: {lines[-1] if lines else ''}"
            print(f"{' '.join(argv)} failed, {error}", file=sys.stderr, flush=True)
    added = sorted(cache_files(cache) - before)
    rss_bytes = usage.ru_maxrss if sys.platform == "darwin" else usage.ru_maxrss * 1024
    return {"seconds": wall_s, "new_files": len(added), "added": added, "peak_rss_mb": rss_bytes / 2**20,
            "error": error}


def one_round(folder: Path, site: Path) -> list[dict]:
    """Every case once: its first run on its starting cache, then its second run on the same cache."""
    calib = folder / "calib.json"
    after_solve = folder / "cache_solved"
    after_solve.mkdir()      # magyro makes its cache folder only when it compiles
    first = run_in_cache(CASES[0][2], after_solve, calib, site)     # (a) cold: the README's first command
    second = run_in_cache(CASES[0][2], after_solve, calib, site)    # (a) warm
    rows = [{"case": CASES[0][0], "what": CASES[0][1], "cache": "empty", "first": first, "second": second}]
    for n, (key, what, args, output, start) in enumerate(CASES[1:], 1):
        cache = folder / f"cache_{n}"
        if start == "after solve":
            shutil.copytree(after_solve, cache)
        else:
            cache.mkdir()
        out = calib if output == "calib" else None
        where = None if "source tree" in start else site
        first = run_in_cache(args, cache, out, where)
        second = run_in_cache(args, cache, out, where)
        rows.append({"case": key, "what": what, "cache": start, "first": first, "second": second})
        shutil.rmtree(cache)
    return rows


def summarise(rounds: list[list[dict]]) -> list[dict]:
    rows = []
    for k, row in enumerate(rounds[0]):
        runs = [r[k] for r in rounds]
        rows.append({"case": row["case"], "what": row["what"], "cache": row["cache"],
                     "first_s": statistics.median(r["first"]["seconds"] for r in runs),
                     "first_new": [r["first"]["new_files"] for r in runs],
                     "second_s": statistics.median(r["second"]["seconds"] for r in runs),
                     "second_new": [r["second"]["new_files"] for r in runs],
                     "added": sorted({f for r in runs for f in r["first"]["added"]}),
                     "errors": sorted({r[t]["error"] for r in runs for t in ("first", "second") if r[t]["error"]}),
                     "runs": runs})
    return rows


def counts(values: list[int]) -> str:
    return str(values[0]) if len(set(values)) == 1 else "/".join(str(v) for v in values)


def table(rows: list[dict]) -> str:
    lines = ["| case | command | cache at start | first run s | new cache files | second run s | new cache files "
             "| first / second |",
             "|------|---------|----------------|------------:|----------------:|-------------:|----------------:"
             "|---------------:|"]
    for r in rows:
        lines.append(f"| ({r['case']}) | {r['what']} | {r['cache']} | {r['first_s']:.2f} | {counts(r['first_new'])} "
                     f"| {r['second_s']:.2f} | {counts(r['second_new'])} | {r['first_s'] / r['second_s']:.2f} |"
                     + (f" FAILED: {'; '.join(r['errors'])}" if r["errors"] else ""))
    return "\n".join(lines)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=3, help="rounds, each from an empty cache (medians reported)")
    parser.add_argument("--out", type=Path, help="also write the raw numbers here as JSON")
    args = parser.parse_args()
    load_start = (time.perf_counter(), busy_cpu_s(), own_cpu_s())

    rounds = []
    site = Path(tempfile.mkdtemp(prefix="magyro-installed-"))
    try:
        install_s = install_magyro(site)
        print(f"pip install (no dependencies, compiles the installed kernels): {install_s:.1f} s", flush=True)
        measure(args, rounds, site)
    finally:
        shutil.rmtree(site, ignore_errors=True)
    report(args, rounds, load_start, install_s)


def measure(args, rounds: list, site: Path) -> None:
    for n in range(args.repeat):
        with tempfile.TemporaryDirectory() as tmp:
            t0 = time.perf_counter()
            rounds.append(one_round(Path(tmp), site))
            print(f"round {n + 1}/{args.repeat}: {time.perf_counter() - t0:.0f} s", flush=True)


def report(args, rounds: list, load_start, install_s: float) -> None:
    rows = summarise(rounds)
    load_line = other_load_line(load_start)

    print(f"\npip install of magyro alone (kernels compiled into the package): {install_s:.1f} s")
    print(f"\nfirst run against second run on the same kernel cache, median of {args.repeat} round(s); "
          f"new cache files = kernels compiled (one value per round when they differ)\n{load_line}\n")
    print(table(rows))
    a = rows[0]
    ratio = a["first_s"] / a["second_s"]
    if any(r["errors"] for r in rows):
        print("\nsome runs failed (the row says how): their times and cache counts are of a failed run")
    print(f"\ntargets:\n  cold first command <= {TARGET_COLD_OVER_WARM:g}x warm: "
          f"{'PASS' if ratio <= TARGET_COLD_OVER_WARM else 'FAIL'} "
          f"({a['first_s']:.2f} s against {a['second_s']:.2f} s, "
          f"x{ratio:.2f})")
    for r in rows[1:]:
        if r["cache"] != "after solve":
            continue
        compiled = max(r["first_new"])
        result = "not measured (failed)" if r["errors"] else "PASS" if compiled == 0 else "FAIL"
        print(f"  ({r['case']}) {r['what']} after one solve compiles nothing: "
              f"{result} ({counts(r['first_new'])} new files"
              + (f": {', '.join(r['added'])}" if compiled else "") + ")")

    if args.out:
        from machine_load import provenance

        summary = {"repeat": args.repeat, "install_s": install_s, "results": rows, "other_load": load_line,
                   **provenance(f"python benchmarks/bench_cold_start.py --repeat {args.repeat} --out FILE")}
        args.out.write_text(json.dumps(summary, indent=2) + "\n")


if __name__ == "__main__":
    main()
