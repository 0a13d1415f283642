"""What the README's first command costs on a fresh install's empty kernel cache, and which default commands compile.

    python benchmarks/bench_cold_start.py [--repeat 3] [--source-tree] [--out docs/numbers/bench-cold-start.json]

magyro is first installed as a user installs it (`pip install .`: pip builds the wheel, which compiles the
installed kernels into the package, and installs it; here `pip install --no-deps --target DIR .`, so that it runs
on the running Python's dependencies; its seconds and the kernels' compile seconds are in the report). Every run is
then the installed `magyro` script, started in a folder of this benchmark's that holds `data/` as the checkout
does, with MAGYRO_CACHE_DIR an empty folder of the case's; the files that appear in that folder during a run are the
kernels it compiled. Cases, each on an empty cache of its own, run twice (the second on the cache the first left):

    (a) the README's first command, exactly: `magyro solve data/broad-02.parquet -o calib.json` (the accelerometer
        in, the hand's velocity as states): its first run is the cold one, its second the warm one
    (b) `magyro observe data/broad-02.parquet`
    (c) `magyro solve data/broad-02.parquet --loss huber -o calib.json`
    (d) `magyro solve data/broad-02.parquet --split-check -o calib.json`
    (e) `magyro solve data/broad-02.parquet --no-accelerometer -o calib.json`
    (f) `magyro solve data/simulated-phone-module.parquet -o calib.json` (200/50 Hz, no accelerometer)
    (g) `magyro solve data/broad-02-50hz.parquet -o calib.json` (BROAD 02 taken at 50 Hz, this benchmark's: stride 4,
        the accelerometer and the hand states)
    (h) with --source-tree: (a) by the `magyro` beside the running Python, from the source tree (an editable
        install, which compiles on first use): what the first solve costs when it compiles

See benchmarks/README.md.
"""
from __future__ import annotations

import argparse
import dataclasses
import os
import re
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from machine_load import busy_cpu_s, other_load_line, own_cpu_s

REPO = Path(__file__).resolve().parents[1]
TARGET_COLD_OVER_WARM = 2.0
README_FIRST_COMMAND = ["solve", "data/broad-02.parquet", "-o", "calib.json"]
SHIPPED = ("broad-02.parquet", "simulated-phone-module.parquet")
LOW_RATE = "broad-02-50hz.parquet"
LOW_RATE_HZ = 50.0

# (key, magyro arguments, where the magyro comes from)
CASES = [
    ("a", README_FIRST_COMMAND, "installed"),
    ("b", ["observe", "data/broad-02.parquet"], "installed"),
    ("c", ["solve", "data/broad-02.parquet", "--loss", "huber", "-o", "calib.json"], "installed"),
    ("d", ["solve", "data/broad-02.parquet", "--split-check", "-o", "calib.json"], "installed"),
    ("e", ["solve", "data/broad-02.parquet", "--no-accelerometer", "-o", "calib.json"], "installed"),
    ("f", ["solve", "data/simulated-phone-module.parquet", "-o", "calib.json"], "installed"),
    ("g", ["solve", f"data/{LOW_RATE}", "-o", "calib.json"], "installed"),
]
SOURCE_TREE_CASE = ("h", README_FIRST_COMMAND, "source tree")


def install_magyro(site: Path) -> tuple[float, float | None, int]:
    """`pip install` this checkout into `site` (no dependencies: the running Python's): its seconds, the seconds
    setup.py says the kernels took to compile (None if it did not say), and the kernels installed."""
    start = time.perf_counter()
    done = subprocess.run([sys.executable, "-m", "pip", "install", "-v", "--no-deps", "--target", str(site), str(REPO)],
                          check=True, capture_output=True, text=True)
    install_s = time.perf_counter() - start
    said = re.search(r"magyro: compiled (\d+) solver kernels into the package in ([0-9.]+) s", done.stdout + done.stderr)
    where = subprocess.run([sys.executable, "-c", "import magyro; print(magyro.__file__)"], capture_output=True,
                           text=True, check=True, env={**os.environ, "PYTHONPATH": str(site)}, cwd=site).stdout
    assert where.startswith(str(site)), where
    installed = len(list((site / "magyro" / "nls" / "installed_kernels").glob("*.so")))
    return install_s, float(said.group(2)) if said else None, installed


def write_data(work: Path, site: Path) -> None:
    """`work`/data as the checkout's: the shipped sessions the cases read, and BROAD 02 at LOW_RATE_HZ."""
    (work / "data").mkdir(parents=True)
    for name in SHIPPED:
        shutil.copy(REPO / "data" / name, work / "data" / name)
    sys.path.insert(0, str(site))
    try:
        import magyro
        from magyro.io.session_file import write_session

        session = magyro.load_session(work / "data" / SHIPPED[0])
        write_session(at_one_rate(session, LOW_RATE_HZ), work / "data" / LOW_RATE, truth_quat=False)
    finally:
        sys.path.pop(0)


def at_one_rate(session, rate_hz: float):
    """The session with gyro, magnetometer and accelerometer all taken at `rate_hz` (the nearest sample before)."""
    import numpy as np

    def at(t, t_new, values):
        return values[np.clip(np.searchsorted(t, t_new), 0, len(t) - 1)]
    t = np.arange(session.t_gyro_s[0], session.t_gyro_s[-1], 1.0 / rate_hz)
    return dataclasses.replace(session, t_gyro_s=t, gyro_rad_s=at(session.t_gyro_s, t, session.gyro_rad_s), t_mag_s=t,
                               mag=at(session.t_mag_s, t, session.mag), t_acc_s=t,
                               acc_m_s2=at(session.t_acc_s, t, session.acc_m_s2), t_quat_s=None, quat_wxyz=None)


def source_tree_magyro() -> str:
    beside_python = Path(sys.executable).parent / "magyro"
    return str(beside_python) if beside_python.exists() else (shutil.which("magyro") or "magyro")


def cache_files(cache: Path) -> set[str]:
    return {str(p.relative_to(cache)) for p in cache.rglob("*") if p.is_file()} if cache.exists() else set()


def run_in_cache(args: list[str], cache: Path, work: Path, site: Path | None) -> dict:
    """One magyro process in `work` (the script installed in `site`, else the source tree's) with
    MAGYRO_CACHE_DIR=cache: wall seconds, peak RSS and the cache files it added."""
    argv = [str(site / "bin" / "magyro") if site else source_tree_magyro(), *args]
    before = cache_files(cache)
    env = {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH", "MAGYRO_JIT")}
    env["MAGYRO_CACHE_DIR"] = str(cache)
    if site:
        env["PYTHONPATH"] = str(site)
    with tempfile.TemporaryFile() as stderr:
        start = time.perf_counter()
        child = subprocess.Popen(argv, stdout=subprocess.DEVNULL, stderr=stderr, env=env, cwd=work)
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


def one_round(cases: list, work: Path, site: Path, caches: Path) -> list[dict]:
    """Every case once, each on an empty cache of its own: its first run, then its second on the same cache."""
    rows = []
    for n, (key, args, source) in enumerate(cases):
        cache = caches / f"cache_{n}"   # magyro makes its cache folder only when it compiles
        where = site if source == "installed" else None
        first = run_in_cache(args, cache, work, where)
        second = run_in_cache(args, cache, work, where)
        rows.append({"case": key, "command": "magyro " + " ".join(args), "magyro": source,
                     "first": first, "second": second})
        shutil.rmtree(cache, ignore_errors=True)
    return rows


def summarise(rounds: list[list[dict]]) -> list[dict]:
    rows = []
    for k, row in enumerate(rounds[0]):
        runs = [r[k] for r in rounds]
        rows.append({"case": row["case"], "command": row["command"], "magyro": row["magyro"],
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
    lines = ["| case | command | magyro | first run s | kernels compiled | second run s | kernels compiled "
             "| first / second |",
             "|------|---------|--------|------------:|-----------------:|-------------:|-----------------:"
             "|---------------:|"]
    for r in rows:
        lines.append(f"| ({r['case']}) | `{r['command']}` | {r['magyro']} | {r['first_s']:.2f} "
                     f"| {counts(r['first_new'])} | {r['second_s']:.2f} | {counts(r['second_new'])} "
                     f"| {r['first_s'] / r['second_s']:.2f} |" + (f" FAILED: {'; '.join(r['errors'])}" if r["errors"] else ""))
    return "\n".join(lines)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=3, help="rounds, each case from an empty cache (medians reported)")
    parser.add_argument("--source-tree", action="store_true",
                        help="also (h): the README's first command from the source tree (an editable install), which "
                             "compiles its kernels (minutes on a busy 2-core machine)")
    parser.add_argument("--out", type=Path, help="also write the record here (docs/numbers/bench-cold-start.json)")
    args = parser.parse_args()
    load_start = (time.perf_counter(), busy_cpu_s(), own_cpu_s())
    cases = CASES + ([SOURCE_TREE_CASE] if args.source_tree else [])

    with tempfile.TemporaryDirectory(prefix="magyro-cold-start-") as tmp:
        site, work = Path(tmp, "site"), Path(tmp, "work")
        install = install_magyro(site)
        print(f"pip install (no dependencies): {install[0]:.1f} s, of which compiling {install[2]} kernels "
              f"{install[1] if install[1] is None else f'{install[1]:.1f}'} s", flush=True)
        write_data(work, site)
        rounds = measure(args.repeat, cases, work, site, Path(tmp))
    report(args, rounds, load_start, install)


def measure(repeat: int, cases: list, work: Path, site: Path, tmp: Path) -> list[list[dict]]:
    rounds = []
    for n in range(repeat):
        t0 = time.perf_counter()
        rounds.append(one_round(cases, work, site, tmp))
        print(f"round {n + 1}/{repeat}: {time.perf_counter() - t0:.0f} s", flush=True)
    return rounds


def report(args, rounds: list, load_start, install: tuple[float, float | None, int]) -> None:
    install_s, compile_s, installed = install
    rows = summarise(rounds)
    load_line = other_load_line(load_start)
    print(f"\npip install of magyro alone: {install_s:.1f} s; {installed} kernels compiled into the package in "
          f"{'?' if compile_s is None else f'{compile_s:.1f}'} s of it")
    print(f"\nfirst run against second run on the same kernel cache, each case from an empty one, median of "
          f"{args.repeat} round(s); kernels compiled = new cache files (one value per round when they differ)\n"
          f"{load_line}\n")
    print(table(rows))
    a = rows[0]
    ratio = a["first_s"] / a["second_s"]
    if any(r["errors"] for r in rows):
        print("\nsome runs failed (the row says how): their times and cache counts are of a failed run")
    print(f"\ntargets:\n  README's first command cold <= {TARGET_COLD_OVER_WARM:g}x warm: "
          f"{'PASS' if ratio <= TARGET_COLD_OVER_WARM else 'FAIL'} ({a['first_s']:.2f} s against {a['second_s']:.2f} s, "
          f"x{ratio:.2f})")
    for r in rows:
        if r["magyro"] != "installed":
            continue
        compiled = max(r["first_new"])
        result = "not measured (failed)" if r["errors"] else "PASS" if compiled == 0 else "FAIL"
        print(f"  ({r['case']}) `{r['command']}` on a fresh install's empty cache compiles nothing: {result} "
              f"({counts(r['first_new'])} new files" + (f": {', '.join(r['added'])}" if compiled else "") + ")")

    if args.out:
        from machine_load import provenance, write_record

        command = (f"python benchmarks/bench_cold_start.py --repeat {args.repeat}"
                   + (" --source-tree" if args.source_tree else "") + f" --out {args.out}")
        write_record(args.out, {
            "readme_first_command": "magyro " + " ".join(README_FIRST_COMMAND),
            "cold_s": a["first_s"], "warm_s": a["second_s"], "cold_over_warm": ratio,
            "cold_kernels_compiled": a["first_new"], "repeat": args.repeat, "install_s": install_s,
            "install_kernels_compiled": installed, "install_kernel_compile_s": compile_s, "results": rows,
            "other_load": load_line, **provenance(command)})


if __name__ == "__main__":
    main()
