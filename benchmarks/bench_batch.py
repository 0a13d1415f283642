"""Issue 15's batch benchmark: a fleet of 100 s sessions, 5 % of them hostile, on 1 and 2 workers of the local
pool and of a Dask cluster on localhost (`dask scheduler` and `dask worker` processes); prints one table.

    python benchmarks/bench_batch.py                    # 200 sessions (about 15 minutes on 2 cores)
    python benchmarks/bench_batch.py --sessions 40      # a quicker look

The fleet: `production-line` devices (`magyro simulate production-line --seeds`, each with its own errors),
with every 20th replaced by a hostile input made from the shipped real BROAD trial the way real loggers
break it (tests/degrade.py) or a file that is not a session. Columns:

    wall_s            the whole batch (run_batch: hashing, workers' start, solves, outputs, summary)
    devices_per_s     sessions / wall_s;  speedup: against 1 worker of the same executor ("in process" is
                      `--jobs 1`, which solves in the client itself; "local pool 1" a pool of one process)
    overhead_ms       per task, (wall_s * workers - sum of the solves' own seconds) / sessions: everything
                      that is not solving (start-up, dispatch, results, writing, the idle tail)
    dispatch_ms       per task, an empty task's round trip through the executor (200 of them, all workers)
    client_heap_MB    the client's peak Python heap during the batch (tracemalloc; not for "in process",
                      whose client is the solver): what grows with the number of devices
    good/broken       calibrated good devices / broken ones named with the right exit code

Targets (issue 15): 2 workers >= 1.8x the throughput of 1, on both executors; Dask within 10 % of the local
pool; per-task overhead under 50 ms; every good device calibrated and every broken one named; JSON numbers
bit for bit equal between --jobs 2 and the two-worker Dask cluster.
"""
from __future__ import annotations

import argparse
import contextlib
import json
import math
import shutil
import subprocess
import sys
import tempfile
import time
import tracemalloc
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests"))
sys.path.insert(0, str(ROOT))

NUMBERS = ("gyro", "misalignment", "magnetometer", "field_i", "time_offset_s", "std", "std_white")


def hostile_inputs(folder: Path) -> dict[str, int]:
    """Write one file per hostile kind into `folder`; name -> the exit code its refusal must have."""
    from dataclasses import replace

    import degrade
    from magyro.io import write_session
    from magyro.studies.scenario import load_problem
    from magyro.studies.simulate import simulate

    real = degrade.load("broad-02")
    sessions = {
        "hostile-time-in-ms": (degrade.wrong_time_unit(real), 2),
        "hostile-time-in-ns": (degrade.wrong_time_unit(real, 1e9), 2),
        "hostile-deg-labelled-rad": (degrade.gyro_in_deg_s_labelled_rad_s(real), 2),
        "hostile-rad-labelled-deg": (degrade.gyro_in_rad_s_labelled_deg_s(real), 2),
        "hostile-no-common-time": (replace(real, t_mag_s=real.t_mag_s + 1e4), 2),
        "hostile-single-axis": (degrade.single_axis_window(real), 3),
        "hostile-static": (simulate(load_problem("static"), 0)[0], 3),
    }
    expected = {}
    for name, (session, code) in sessions.items():
        write_session(session, folder / f"{name}.parquet")
        expected[name] = code
    (folder / "hostile-not-parquet.parquet").write_bytes(b"PAR1 truncated by a logger that lost power")
    (folder / "hostile-empty.csv").write_text("")
    (folder / "hostile-no-magnetometer.csv").write_text("t,gx,gy,gz\n0,0,0,0\n0.01,0,0,0\n")
    expected.update({"hostile-not-parquet": 2, "hostile-empty": 2, "hostile-no-magnetometer": 2})
    return expected


def make_fleet(folder: Path, sessions: int) -> tuple[list[str], dict[str, int]]:
    """The fleet's manifest: production-line devices, every 20th replaced by a hostile input."""
    from magyro.studies.fleet import simulate_fleet
    from magyro.studies.scenario import load_problem

    hostile = hostile_inputs(folder)
    n_hostile = max(1, sessions // 20)
    names = list(hostile)[:n_hostile]
    good_seeds = list(range(sessions - len(names)))
    simulate_fleet(load_problem("production-line"), good_seeds, folder)
    files = sorted(folder.glob("production-line-*.parquet"))
    lines = ["device_id,session"] + [f"{p.stem},{p.name}" for p in files]
    for name in names:
        file = next(folder.glob(f"{name}.*"))
        lines.append(f"{name},{file.name}")
    (folder / "fleet.csv").write_text("\n".join(lines) + "\n")
    return [str(folder / "fleet.csv")], {n: hostile[n] for n in names}


@contextlib.contextmanager
def dask_cluster(workers: int, port: int = 8799):
    """A Dask cluster as a user starts one: `dask scheduler` and `dask worker --nthreads 1` processes (the
    scheduler out of the client's process, as on a real cluster); yields its address."""
    from distributed import Client

    address = f"tcp://127.0.0.1:{port}"
    dask = [sys.executable, "-m", "distributed.cli.dask_scheduler"]
    quiet = {"stdout": subprocess.DEVNULL, "stderr": subprocess.DEVNULL}
    scheduler = subprocess.Popen(dask + ["--host", "127.0.0.1", "--port", str(port), "--no-dashboard"], **quiet)
    worker = subprocess.Popen([sys.executable, "-m", "distributed.cli.dask_worker", address, "--nthreads", "1",
                               "--nworkers", str(workers), "--no-dashboard"], **quiet)
    try:
        with Client(address, timeout="30s") as client:
            client.wait_for_workers(workers, timeout=60)
        yield address
    finally:
        for process in (worker, scheduler):
            process.terminate()
        for process in (worker, scheduler):
            process.wait(timeout=30)


def dispatch_ms(executor, n: int = 200) -> float:
    from magyro.executor import run_unordered

    with executor:
        run_unordered(executor, abs, [0], lambda *a: None)   # workers up
        t0 = time.perf_counter()
        run_unordered(executor, abs, range(n), lambda *a: None)
        return 1e3 * (time.perf_counter() - t0) * executor.workers / n


def one_run(inputs, out: Path, expected: dict, jobs: int = 1, scheduler: str | None = None, executor=None) -> dict:
    from magyro.batch.run import run_batch

    in_client = executor is None and jobs == 1 and scheduler is None   # then the solves' memory is the client's
    if not in_client:
        tracemalloc.start()
    t0 = time.perf_counter()
    result = run_batch(inputs, out, jobs=jobs, scheduler=scheduler, redo=True, executor=executor)
    wall = time.perf_counter() - t0
    heap_mb = math.nan if in_client else tracemalloc.get_traced_memory()[1] / 2**20
    tracemalloc.stop()
    workers = executor.workers if executor is not None else jobs if scheduler is None else \
        int(result.executor.split("(")[1].split()[0])
    rows = result.rows
    solve_s = sum(r["seconds"] for r in rows)
    good = [r for r in rows if r["device_id"] not in expected]
    named = sum(1 for r in rows if r["device_id"] in expected and r["exit_code"] == expected[r["device_id"]]
                and r["message"])
    return {"wall_s": wall, "workers": workers, "client_heap_mb": heap_mb, "devices_per_s": len(rows) / wall,
            "overhead_ms": 1e3 * (wall * workers - solve_s) / len(rows),
            "good": f"{sum(r['exit_code'] == 0 for r in good)}/{len(good)}", "broken": f"{named}/{len(expected)}",
            "failures": [(r["device_id"], r["exit_code"], r["message"][:90]) for r in good if r["exit_code"] != 0]}


def equal_numbers(a: Path, b: Path) -> tuple[int, int]:
    files = sorted((a / "calibrations").glob("*.json"))
    same = 0
    for f in files:
        A, B = json.loads(f.read_text()), json.loads((b / "calibrations" / f.name).read_text())
        same += all(A.get(k) == B.get(k) for k in NUMBERS)
    return same, len(files)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--sessions", type=int, default=200)
    parser.add_argument("--skip-dask", action="store_true")
    args = parser.parse_args()

    from magyro.executor import DaskCluster, LocalPool

    tmp = Path(tempfile.mkdtemp(prefix="bench-batch-"))
    try:
        (tmp / "fleet").mkdir()
        inputs, expected = make_fleet(tmp / "fleet", args.sessions)
        print(f"fleet: {args.sessions} sessions of 100 s ({len(expected)} hostile) in {tmp / 'fleet'}", flush=True)
        from magyro.batch.run import run_batch   # warm the kernel cache: compiling is issue 14's, not this table's
        run_batch([next((tmp / 'fleet').glob('production-line-*.parquet'))], tmp / "warm")

        runs = {}
        runs[("in process", 1)] = one_run(inputs, tmp / "inprocess", expected, jobs=1)
        runs[("local pool", 1)] = one_run(inputs, tmp / "local1", expected, executor=LocalPool(1))
        runs[("local pool", 2)] = one_run(inputs, tmp / "local2", expected, jobs=2)
        dispatch = {("in process", 1): 0.0, ("local pool", 1): dispatch_ms(LocalPool(1)),
                    ("local pool", 2): dispatch_ms(LocalPool(2))}
        if not args.skip_dask:
            for workers in (1, 2):
                with dask_cluster(workers) as address:
                    runs[("dask", workers)] = one_run(inputs, tmp / f"dask{workers}", expected, scheduler=address)
                    dispatch[("dask", workers)] = dispatch_ms(DaskCluster(address))

        print("\n| executor | workers | wall_s | devices_per_s | speedup | overhead_ms | dispatch_ms | client_heap_MB "
              "| good | broken |")
        print("|---|---|---|---|---|---|---|---|---|---|")
        for (name, workers), r in runs.items():
            speedup = r["devices_per_s"] / runs[(name, 1)]["devices_per_s"]   # against 1 worker of its own kind
            print(f"| {name} | {workers} | {r['wall_s']:.1f} | {r['devices_per_s']:.2f} | {speedup:.2f}x | "
                  f"{r['overhead_ms']:.0f} | {dispatch[(name, workers)]:.1f} | {r['client_heap_mb']:.1f} | {r['good']} | "
                  f"{r['broken']} |")
        for (name, workers), r in runs.items():
            for failure in r["failures"]:
                print(f"  good device failed on {name} x{workers}: {failure}")
        if ("dask", 2) in runs:
            ratio = runs[("dask", 2)]["devices_per_s"] / runs[("local pool", 2)]["devices_per_s"]
            same, total = equal_numbers(tmp / "local2", tmp / "dask2")
            print(f"\nDask / local pool throughput at 2 workers: {ratio:.3f}")
            print(f"calibrations with bit-for-bit equal numbers, --jobs 2 vs two-worker Dask: {same}/{total}")
    finally:
        shutil.rmtree(tmp, ignore_errors=True)


if __name__ == "__main__":
    main()
