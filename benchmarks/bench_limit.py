"""magyro solve against its limit: the interval kernels alone, measured in the same run on the same machine.

    python benchmarks/bench_limit.py [--sizes 10000,36000,360000] [--out limit.json] [--no-phases]
    python benchmarks/bench_limit.py --sizes 3600000 --timeout 900        # ten hours at 100 Hz

The limit (issue 27) is what IPOPT's Gauss-Newton iterations cannot do without: the installed interval kernels
(residuals, gradient, and the Jacobian with its Gauss-Newton products J^T J formed per piece of intervals) evaluated
over every interval of the session's problem, once per IPOPT iteration the solve took, plus one banded Cholesky of
the attitude block with the Schur complement for the calibration parameters. Every figure is then a ratio to that limit, measured in the same run.

Per size (paper-table1 at 100 Hz, noise seed 0, made by bench_solve.problem_for_samples in a child process):

1. the limit, in a child of its own: the front end and problem are built (not timed), then each kernel's `map`
   over all intervals is timed on numeric arguments (best of 3), and the factorisation (scipy's
   cholesky_banded / cho_solve_banded on the Gauss-Newton Hessian at the start, then the Schur complement);
2. `magyro solve SESSION -o calib.json -q` as its own process, CPU user + sys and peak RSS from os.wait4 on that
   child alone, wall time; the process runs the CLI itself with a few of magyro's functions wrapped by timers
   (`--no-phases`: the plain `magyro` executable), so the same run says where the CPU time and the memory went:
   inclusive CPU seconds per phase and the resident high-water mark when the phase ended.

The targets of issue 27 are printed with PASS/FAIL. MAGYC is compared against the issue's figures (3.7 s /
448 MB at 36k samples, 16.8 s / 846 MB at 360k) unless `--magyc PYTHON` names an interpreter with MAGYC installed
(`pip install magyc` in a venv of its own: it brings jax and gtsam): then `magyc_nls` (the method whose memory the
issue's figures match: 424 MB at 36k, 846 MB at 360k here) runs side by side on the same session as its own
process (the gyro and the magnetometer on the gyro's times, from an .npz written beforehand), CPU user + sys and
peak RSS measured as magyro's.
"""
from __future__ import annotations

import argparse
import json
import os
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
# bench_scale and machine_load are imported by the parent only: the measured solve process imports nothing of theirs

TARGET_360K_LIMIT_RATIO = 2.0
TARGET_360K_RSS_MB = 500.0
TARGET_3_6M_S = 120.0
TARGET_3_6M_RSS_MB = 4096.0
TARGET_100S_S = 0.8
TARGET_GROWTH = 10.0
MAGYC_ISSUE = {36000: (3.7, 448.0), 360000: (16.8, 846.0)}   # the issue's MAGYC figures: CPU s (lower end), MB

# (module, attribute, label, depth): the functions timed in the solve's own process. A class attribute given as
# "Class.method"; where a module imported a name, the name is wrapped in the module that calls it.
PHASES = [
    ("magyro.io", "load_session", "read the session", 0),
    ("magyro.api", "checked_recording", "recording check and repairs", 0),
    ("magyro.nls.run", "prepare", "front end (prepare)", 0),
    ("magyro.front.prepare", "moving_session", "rests, noise, trim", 1),
    ("magyro.front.ellipsoid", "fit_ellipsoid", "ellipsoid", 1),
    ("magyro.front.prepare", "check_gyro_unit", "gyro unit check", 1),
    ("magyro.front.prepare", "analyse", "observability analysis", 1),
    ("magyro.front.causes", "turning", "turning (causes)", 1),
    ("magyro.nls.solve", "build_grid", "grid", 0),
    ("magyro.nls.solve", "with_time_offset", "time-offset search + linear estimate", 0),
    ("magyro.nls.solve", "linear_gyro_estimate", "linear estimate (no search)", 0),
    ("magyro.nls.solve", "nominal_attitudes", "nominal attitude", 0),
    ("magyro.nls.solve", "aligned_stretches", "aligned stretches", 0),
    ("magyro.nls.solve", "JointProblem", "problem object (kernels loaded)", 0),
    ("magyro.nls.run", "excitation_gate", "accuracy gate (observe's prediction)", 0),
    ("magyro.nls.run", "solve_passes", "solve passes", 0),
    ("magyro.nls.problem", "JointProblem.solver", "graphs and nlpsol", 1),
    ("magyro.nls.solve", "problem_parameters", "parameter vector", 1),
    ("magyro.nls.problem", "JointProblem.solve", "IPOPT", 1),
    ("magyro.nls.problem", "JointProblem.hessian_values", "Gauss-Newton Hessian (IPOPT's callback; the gate's; the std's)", 2),
    ("magyro.nls.solve", "residual_matrix", "residuals", 1),
    ("magyro.nls.run", "solved_hessian", "the std's Gauss-Newton Hessian (at IPOPT's last point)", 0),
    ("magyro.nls.run", "reduce_hessian", "reduce_hessian", 0),
    ("magyro.nls.problem", "JointProblem.gradient_values", "gradient evaluated (decrement)", 0),
    ("magyro.nls.run", "disturbance_covariance", "disturbance step", 0),
    ("magyro.nls.run", "assemble", "assemble", 0),
    ("magyro.api", "check_the_result_explains_the_data", "result check", 0),
    ("magyro.result.calibration", "Calibration.to_json", "JSON", 0),
]


# ------------------------------------------------------------------ in the solve's own process
def rss_mb() -> tuple[float, float]:
    """(resident now, high-water mark) of this process, MB."""
    now = hwm = 0.0
    for line in Path("/proc/self/status").read_text().splitlines():
        if line.startswith("VmRSS:"):
            now = int(line.split()[1]) / 1024
        elif line.startswith("VmHWM:"):
            hwm = int(line.split()[1]) / 1024
    return now, hwm


def timed(fn, label: str, record: dict):
    def wrapper(*args, **kwargs):
        c0, w0 = time.process_time(), time.perf_counter()
        try:
            return fn(*args, **kwargs)
        finally:
            entry = record.setdefault(label, {"calls": 0, "cpu_s": 0.0, "wall_s": 0.0})
            entry["calls"] += 1
            entry["cpu_s"] += time.process_time() - c0
            entry["wall_s"] += time.perf_counter() - w0
            entry["rss_mb"], entry["hwm_mb"] = rss_mb()
    wrapper.__wrapped__ = fn
    return wrapper


def install_timers(record: dict) -> None:
    import importlib

    import magyro.api  # noqa: F401  (the modules the phases live in, imported as the solve would)
    import magyro.nls.run  # noqa: F401

    for module_name, attr, label, _ in PHASES:
        module = importlib.import_module(module_name)
        owner, name = (getattr(module, attr.split(".")[0]), attr.split(".")[1]) if "." in attr else (module, attr)
        if hasattr(owner, name):
            setattr(owner, name, timed(getattr(owner, name), label, record))


def run_solve_here(session: str, calib: str, phases_out: str) -> None:
    """`magyro solve SESSION -o CALIB -q` in this process, the phases timed, their record written at exit."""
    import atexit

    os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")   # as magyro.cli sets it before numpy is imported
    record: dict = {}
    start = time.process_time()

    def write():
        record["_process_cpu_s"] = time.process_time() - start
        Path(phases_out).write_text(json.dumps(record))
    atexit.register(write)
    install_timers(record)
    from magyro.cli import main
    record["_imports_cpu_s"] = time.process_time() - start
    sys.argv = ["magyro", "solve", session, "-o", calib, "-q"]
    main()


# ------------------------------------------------------------------ the limit, in a child of its own
def measure_limit_here(session_path: str, repeat: int = 3) -> dict:
    """Each kernel's map over all intervals (best of `repeat`) and the banded factorisation, as JSON on stdout."""
    os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
    import casadi as ca
    import numpy as np
    from scipy.linalg import cho_solve_banded, cholesky, cholesky_banded

    from magyro.api import checked_recording
    from magyro.front.prepare import prepare
    from magyro.io import load_session
    from magyro.nls.method import NLS
    from magyro.nls.on_numpy import MapOnNumpy
    from magyro.nls.reduction import tridiagonal_blocks
    from magyro.nls.solve import build_problem, problem_parameters
    from magyro.options import Options

    options = Options()
    session, _ = checked_recording(load_session(session_path), options)
    prep = prepare(session, options)
    grid, lin, problem = build_problem(prep, options, NLS())
    p = problem_parameters(problem, prep, lin, prep.sigma_mag, lin.time_offset_s)
    n, G, B = problem.n_int, problem.n_theta, problem.B
    x = np.zeros(problem.n_x)
    states = np.vstack([np.zeros(B), x[G:].reshape(-1, B)])
    args = [ca.DM(x[:G]), ca.DM(states[:-1].T), ca.DM(states[1:].T), ca.DM(problem.globals_of(p)),
            ca.DM(problem.data_of(p).T)]
    # the Gauss-Newton blocks: the Jacobian kernel over every interval in pieces (on numpy by pointer: a map's
    # output of every interval's dense J is 280 MB at 360k samples) and its products batched per piece
    products, H_tt = problem._products, np.zeros((G, G))
    shape = problem.jacobian_kernel.size_out(0)[::-1]
    jacobian = MapOnNumpy(problem, problem.jacobian_kernel, pieces=True)
    residuals, gradient = problem.residual_kernel.map(n), problem.gradient_kernel.map(n)
    kernels = {"residuals": lambda: residuals(*args), "gradient": lambda: gradient(*args),
               "gauss_newton": lambda: jacobian(x, p, lambda a, b, o: products(o[0].reshape(b - a, *shape), H_tt))}
    seconds = {}
    for name, fn in kernels.items():
        best = np.inf
        for _ in range(repeat):
            c0 = time.process_time()
            fn()
            best = min(best, time.process_time() - c0)
        seconds[name] = best

    H = problem.hessian_function(x, ca.DM(p))
    A, Bk = tridiagonal_blocks(H[G:, G:], B)
    A = A + np.triu(A, 1).transpose(0, 2, 1)   # triu blocks -> full diagonal blocks
    m = B * n
    u = 2 * B - 1
    ab = np.zeros((u + 1, m))
    full = np.zeros((n, B, 2 * B))   # per block row: [diagonal block, upper block]
    full[:, :, :B] = A
    full[:-1, :, B:] = Bk
    rows = np.arange(m)
    for j in range(2 * B):
        cols = (rows // B) * B + j
        ok = (cols < m) & (cols >= rows)
        ab[u + rows[ok] - cols[ok], cols[ok]] = full.reshape(m, 2 * B)[ok, j]
    H_tt = np.array(ca.densify(H[:G, :G]))
    H_tt = H_tt + np.triu(H_tt, 1).T
    H_tp = np.array(ca.densify(H[:G, G:]))
    best = np.inf
    for _ in range(repeat):
        c0 = time.process_time()
        c = cholesky_banded(ab)
        X = cho_solve_banded((c, False), H_tp.T)
        cholesky(H_tt - H_tp @ X)
        best = min(best, time.process_time() - c0)
    seconds["factorisation"] = best
    return {"intervals": n, "n_theta": G, "seconds": seconds, "per_pass_s": sum(seconds[k] for k in kernels)}


# ------------------------------------------------------------------ the benchmark
def child(argv: list[str], timeout_s: float, env: dict) -> dict:
    from bench_scale import mem_total_mb, run_guarded
    ram_mb = mem_total_mb()
    return run_guarded(argv, timeout_s, 0.8 * ram_mb, env)


def measure_size(samples: int, folder: Path, args, env: dict) -> dict:
    import resource
    import subprocess

    from bench_scale import write_session_in_child
    session = folder / f"session_{samples}.parquet"
    if not session.exists():
        count = write_session_in_child(samples, session)
    else:
        count = samples
    calib, phases = folder / "calib.json", folder / "phases.json"
    out = folder / "limit.json"
    subprocess.run([sys.executable, __file__, "--limit", str(session), str(out)], check=True, env=env)
    limit = json.loads(out.read_text())
    phases.unlink(missing_ok=True)
    calib.unlink(missing_ok=True)
    if args.no_phases:
        argv = [str(Path(sys.executable).parent / "magyro"), "solve", str(session), "-o", str(calib), "-q"]
    else:
        argv = [sys.executable, __file__, "--run", str(session), str(calib), str(phases)]
    runs = []
    for _ in range(args.repeat if samples < 1_000_000 else 1):
        before = resource.getrusage(resource.RUSAGE_CHILDREN)
        runs.append(child(argv, args.timeout, env))
        after = resource.getrusage(resource.RUSAGE_CHILDREN)
        runs[-1]["cpu_s"] = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
        if runs[-1]["outcome"] != "ok":
            break
    run = median_run(runs)
    row = {"size": samples, "samples": count, "limit": limit, "run": run, "runs": runs}
    if run["outcome"] == "ok":
        solver = json.loads(calib.read_text())["solver"]
        row["iterations"], row["passes"] = solver["iterations"], solver.get("passes")
        row["limit_s"] = solver["iterations"] * limit["per_pass_s"] + limit["seconds"]["factorisation"]
        row["ratio"] = run["cpu_s"] / row["limit_s"]
        if phases.exists():
            row["phases"] = json.loads(phases.read_text())
    if args.magyc:
        npz = folder / f"magyc_{samples}.npz"
        subprocess.run([sys.executable, "-c", MAGYC_INPUT, str(session), str(npz)], check=True, env=env)
        before = resource.getrusage(resource.RUSAGE_CHILDREN)
        magyc = child([args.magyc, __file__, "--magyc-run", "magyc_nls", str(npz)], args.timeout, env)
        after = resource.getrusage(resource.RUSAGE_CHILDREN)
        magyc["cpu_s"] = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
        row["magyc"] = magyc
        npz.unlink()
    if samples >= 1_000_000:
        session.unlink()
    return row


def median_run(runs: list[dict]) -> dict:
    """The run of median CPU time (the failed one, if any), with the largest peak RSS of all and the CPU range."""
    if any(r["outcome"] != "ok" for r in runs):
        return next(r for r in runs if r["outcome"] != "ok")
    ordered = sorted(runs, key=lambda r: r["cpu_s"])
    run = dict(ordered[(len(ordered) - 1) // 2])
    run["peak_rss_mb"] = max(r["peak_rss_mb"] for r in runs)
    run["cpu_range_s"] = (ordered[0]["cpu_s"], ordered[-1]["cpu_s"])
    return run


MAGYC_INPUT = """import sys, numpy as np
from magyro.io import load_session
s = load_session(sys.argv[1])
mag = np.column_stack([np.interp(s.t_gyro_s, s.t_mag_s, s.mag[:, i]) for i in range(3)])
np.savez(sys.argv[2], t=s.t_gyro_s, mag=mag, gyro=s.gyro_rad_s)
"""


def magyc_row(samples: int) -> tuple[float, float] | None:
    return MAGYC_ISSUE.get(samples)


def fmt(v, spec):
    return "-" if v is None else format(v, spec)


def print_tables(rows: list[dict]) -> None:
    print("| samples | intervals | iterations | kernels per pass s | factorisation s | limit s | process CPU s (range) "
          "| x limit | wall s | peak RSS MB |")
    print("|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|")
    for r in rows:
        lim, run = r["limit"], r["run"]
        spread = (f" ({run['cpu_range_s'][0]:.2f}-{run['cpu_range_s'][1]:.2f})" if len(r.get("runs", [])) > 1
                  and "cpu_range_s" in run else "")
        print(f"| {r['samples']} | {lim['intervals']} | {fmt(r.get('iterations'), 'd')} | {lim['per_pass_s']:.3f} "
              f"| {lim['seconds']['factorisation']:.3f} | {fmt(r.get('limit_s'), '.2f')} | {run['cpu_s']:.2f}{spread} "
              f"| {fmt(r.get('ratio'), '.2f')} | {run['process_s']:.2f} | {run['peak_rss_mb']:.0f} |"
              + ("" if run["outcome"] == "ok" else f" {run['outcome']}: {run['error']}"))
    for r in rows:
        if "phases" not in r:
            continue
        ph = r["phases"]
        print(f"\nwhere the CPU went, {r['samples']} samples (inclusive CPU s of each phase; x limit; the process's "
              f"resident high-water mark when the phase last ended)")
        print("| phase | calls | CPU s | x limit | resident after MB | high-water MB |")
        print("|---|---:|---:|---:|---:|---:|")
        for _, _, label, depth in PHASES:
            if label in ph:
                e = ph[label]
                print(f"| {'  ' * depth}{label} | {e['calls']} | {e['cpu_s']:.2f} | {e['cpu_s'] / r['limit_s']:.2f} "
                      f"| {e['rss_mb']:.0f} | {e['hwm_mb']:.0f} |")
        inside, imports = ph["_process_cpu_s"], ph["_imports_cpu_s"]
        top = sum(ph[label]["cpu_s"] for _, _, label, depth in PHASES if depth == 0 and label in ph)
        before = r["run"]["cpu_s"] - inside
        print(f"| Python's start-up and exit (freeing the memory) | | {before:.2f} | {before / r['limit_s']:.2f} | | |")
        print(f"| importing magyro.cli | | {imports:.2f} | {imports / r['limit_s']:.2f} | | |")
        rest = inside - imports - top
        print(f"| not in a phase above (CLI, exit) | | {rest:.2f} | {rest / r['limit_s']:.2f} | | |")
        print(f"| whole process (os.wait4) | | {r['run']['cpu_s']:.2f} | {r['ratio']:.2f} | | {r['run']['peak_rss_mb']:.0f} |")


def verdict(ok: bool | None, text: str) -> str:
    return ("not measured" if ok is None else ("PASS" if ok else "FAIL")) + f" ({text})"


def print_targets(rows: list[dict]) -> dict:
    by = {r["size"]: r for r in rows if r["run"]["outcome"] == "ok"}
    out = {}

    def line(key, ok, text):
        out[key] = verdict(ok, text)
        print(f"  {key}: {out[key]}")
    print("\ntargets (issue 27; CPU = user + sys of the whole process):")
    r = by.get(360000)
    line("360k CPU <= 2x limit", None if r is None else r["ratio"] <= TARGET_360K_LIMIT_RATIO,
         "-" if r is None else f"{r['ratio']:.2f}x: {r['run']['cpu_s']:.2f} s against {r['limit_s']:.2f} s")
    line("360k peak RSS <= 500 MB", None if r is None else r["run"]["peak_rss_mb"] <= TARGET_360K_RSS_MB,
         "-" if r is None else f"{r['run']['peak_rss_mb']:.0f} MB")
    r = by.get(3600000)
    line("3.6M <= 120 s", None if r is None else max(r["run"]["cpu_s"], r["run"]["process_s"]) <= TARGET_3_6M_S,
         "-" if r is None else f"CPU {r['run']['cpu_s']:.1f} s, wall {r['run']['process_s']:.1f} s")
    line("3.6M peak RSS <= 4 GB", None if r is None else r["run"]["peak_rss_mb"] <= TARGET_3_6M_RSS_MB,
         "-" if r is None else f"{r['run']['peak_rss_mb']:.0f} MB")
    r = by.get(10000)
    line("100 s at 100 Hz <= 0.8 s", None if r is None else r["run"]["cpu_s"] <= TARGET_100S_S,
         "-" if r is None else f"CPU {r['run']['cpu_s']:.2f} s, wall {r['run']['process_s']:.2f} s")
    a, b = by.get(36000), by.get(360000)
    g = None if a is None or b is None else b["run"]["cpu_s"] / a["run"]["cpu_s"]
    line("growth 36k -> 360k <= 10x", None if g is None else g <= TARGET_GROWTH, "-" if g is None else f"x{g:.2f} CPU")
    for size in sorted(set(MAGYC_ISSUE) | {r["size"] for r in rows if "magyc" in r}):
        r = by.get(size)
        measured = r is not None and r.get("magyc", {}).get("outcome") == "ok"
        if measured:
            cpu, mb = r["magyc"]["cpu_s"], r["magyc"]["peak_rss_mb"]
            source = f"magyc_nls measured side by side: {cpu:.2f} s, {mb:.0f} MB"
        elif size in MAGYC_ISSUE:
            cpu, mb = MAGYC_ISSUE[size]
            source = f"MAGYC not run here: the issue's figures {cpu} s, {mb:.0f} MB"
        else:
            continue
        ok = None if r is None else (r["run"]["cpu_s"] <= 0.5 * cpu and r["run"]["peak_rss_mb"] <= 0.5 * mb)
        line(f"{size // 1000}k <= 0.5x MAGYC ({source})", ok,
             "-" if r is None else f"{r['run']['cpu_s'] / cpu:.2f}x CPU, {r['run']['peak_rss_mb'] / mb:.2f}x memory")
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--sizes", default="10000,36000,360000", help="comma-separated sample counts")
    parser.add_argument("--timeout", type=float, default=900.0)
    parser.add_argument("--out", type=Path, help="also write every number as JSON")
    parser.add_argument("--no-phases", action="store_true", help="the plain magyro executable, no phase timers")
    parser.add_argument("--repeat", type=int, default=1,
                        help="solves per size below 1M samples: the median CPU run is shown (its phases those of the last "
                             "run), the largest peak RSS, and the CPU range")
    parser.add_argument("--sessions", type=Path, help="keep the simulated sessions in this folder (reused)")
    parser.add_argument("--magyc", help="a Python with MAGYC installed: run magyc_nls side by side")
    parser.add_argument("--magyc-run", nargs=2, help=argparse.SUPPRESS)
    parser.add_argument("--run", nargs=3, help=argparse.SUPPRESS)
    parser.add_argument("--limit", nargs=2, help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.run:
        run_solve_here(*args.run)
        return
    if args.magyc_run:   # in MAGYC's own interpreter: nothing of magyro's imported
        import numpy as np
        import magyc
        data = np.load(args.magyc_run[1])
        getattr(magyc, args.magyc_run[0])(data["mag"], data["gyro"], data["t"])
        return
    if args.limit:
        Path(args.limit[1]).write_text(json.dumps(measure_limit_here(args.limit[0])))
        return
    from machine_load import busy_cpu_s, other_load_line, own_cpu_s, provenance
    load_start = (time.perf_counter(), busy_cpu_s(), own_cpu_s())
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        folder = args.sessions or Path(tmp)
        folder.mkdir(parents=True, exist_ok=True)
        # as an installed magyro runs: its bytecode compiled once (the limit's child of the first size fills a
        # cache of the benchmark's own), not every module compiled again in every run (0.09 s of a 100 s session's
        # 0.9 s where PYTHONDONTWRITEBYTECODE is set)
        env = {**os.environ, "OPENBLAS_NUM_THREADS": "1", "PYTHONPYCACHEPREFIX": str(Path(tmp) / "pycache")}
        env.pop("PYTHONDONTWRITEBYTECODE", None)
        for n in sorted(int(s) for s in args.sizes.split(",")):
            rows.append(measure_size(n, folder, args, env))
            r = rows[-1]
            print(f"{n}: CPU {r['run']['cpu_s']:.2f} s, limit {fmt(r.get('limit_s'), '.2f')} s, "
                  f"RSS {r['run']['peak_rss_mb']:.0f} MB", flush=True)
    load = other_load_line(load_start)
    print(f"\nmagyro solve, paper-table1 at 100 Hz; {load}; load average {os.getloadavg()[0]:.2f}\n")
    print_tables(rows)
    targets = print_targets(rows)
    if args.out:
        args.out.write_text(json.dumps({"rows": rows, "targets": targets, "other_load": load,
                                        **provenance(f"python benchmarks/bench_limit.py --sizes {args.sizes}")},
                                       indent=1) + "\n")


if __name__ == "__main__":
    main()
