"""`magyro watch`: can it keep up, how late does it show a change, and what does its prediction cost?

    python benchmarks/bench_watch.py [--repeat 3] [--skip-pipeline] [--out results.json]

1. **Throughput** on a 120 s recording at 200 Hz (problems/three-axes.toml's sensors, its
   motion stretched over 120 s; 24001 gyro + 24001 magnetometer lines):
   - parse: `LineParser` on the CSV text (what the reader thread does), microseconds per line;
   - monitor: `ExcitationMonitor.add` + `update` with an update every 0.05 s of data (the live
     cadence of `magyro watch`: one update per 0.05 s of wall clock), no prediction;
   - both: per second of recording, and the real-time factor on one core
     (120 s / the time taken); the requirement is above 10x;
   - pipeline: `magyro simulate --stream --speed 0 | magyro watch - -q` end to end (two processes,
     start-up and the final prediction included).
2. **Rank latency** on the staged recording of tests/test_watch.py (still 10 s, then +/-90 deg
   about x, y, z in turn): the data time at which the monitor first shows rank 6, 9, 12 after each
   change of motion, at an update every 0.1 and every 0.05 s of data.
3. **Prediction cost**: `predict_session` (`magyro.observe` on the data so far, what the background
   worker runs) on the first 30, 60, 90 and 120 s of the 200 Hz recording and of a 100 Hz one;
   median of `--repeat`. The refresh of `magyro watch` (`--refresh`, 2 s of data, and never two at
   once) is chosen from it.
4. **Enough agreement**: the staged recording fed at an update every 0.1 s with predictions every
   2 s of data (inline); at the first "enough", magyro.observe on the session saved and cut at the
   prediction's time and at the moment shown: the largest relative difference of any predicted std.

Absolute times depend on the machine and its load: compare on a quiet machine.
"""
from __future__ import annotations

import argparse
import dataclasses
import io
import json
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import numpy as np  # noqa: E402

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parent / "tests"))


def recording(rate_hz: float, duration_s: float = 120.0, problem: str = "three-axes"):
    from magyro.studies.scenario import load_problem
    from magyro.studies.simulate import simulate

    p = load_problem(problem)
    p = dataclasses.replace(p, duration_s=duration_s, gyro_rate_hz=rate_hz, mag_rate_hz=rate_hz)
    return simulate(p, 0)[0]


def csv_bytes(session) -> bytes:
    from magyro.live.stream import stream_session

    out = io.StringIO()
    stream_session(session, out, speed=0)
    return out.getvalue().encode()


def throughput(session, repeat: int) -> dict:
    from magyro.live.monitor import ExcitationMonitor
    from magyro.live.sources import LineParser

    data = csv_bytes(session)
    lines = data.count(b"\n")
    parse_s = []
    for _ in range(repeat):
        p = LineParser()
        start = time.perf_counter()
        for k in range(0, len(data), 65536):
            p.feed(data[k: k + 65536])
        parse_s.append(time.perf_counter() - start)
    g = np.column_stack([session.t_gyro_s, session.gyro_rad_s])
    m = np.column_stack([session.t_mag_s, session.mag])
    edges = np.arange(0.05, session.t_gyro_s[-1] + 0.1, 0.05)
    ig, im = np.searchsorted(g[:, 0], edges), np.searchsorted(m[:, 0], edges)
    monitor_s, updates = [], len(edges)
    for _ in range(repeat):
        mon = ExcitationMonitor()
        start = time.perf_counter()
        for k in range(len(edges)):
            mon.add(g[(ig[k - 1] if k else 0): ig[k]], m[(im[k - 1] if k else 0): im[k]])
            mon.update()
        monitor_s.append(time.perf_counter() - start)
    duration = float(session.t_gyro_s[-1] - session.t_gyro_s[0])
    parse, monitor = statistics.median(parse_s), statistics.median(monitor_s)
    return {"lines": lines, "samples": len(g) + len(m), "duration_s": duration, "updates": updates,
            "parse_s": parse, "parse_us_per_line": 1e6 * parse / lines,
            "monitor_s": monitor, "monitor_us_per_sample": 1e6 * monitor / (len(g) + len(m)),
            "monitor_ms_per_update": 1e3 * monitor / updates,
            "realtime_factor": duration / (parse + monitor)}


def pipeline(session_rate_hz: float) -> dict:
    """The two processes end to end (the simulate is of the 100 Hz three-axes problem when the CLI streams it)."""
    from test_watch import cli_prefix, stream_command

    with tempfile.TemporaryDirectory() as d:
        out = Path(d) / "s.parquet"
        start = time.perf_counter()
        prod = subprocess.Popen(stream_command("three-axes", 0), stdout=subprocess.PIPE)
        res = subprocess.run(cli_prefix() + ["watch", "-", "-o", str(out), "-q"], stdin=prod.stdout,
                             capture_output=True, text=True)
        prod.stdout.close()
        prod.wait()
        wall = time.perf_counter() - start
    return {"wall_s": wall, "recording_s": 60.0, "returncode": res.returncode, "summary": res.stderr.strip()[-300:]}


def latency() -> list[dict]:
    from magyro.live.monitor import ExcitationMonitor
    from test_watch import EXPECTED_RANKS, PHASES, feed, staged_session

    s = staged_session()
    rows = []
    for chunk in (0.1, 0.05):
        statuses = feed(ExcitationMonitor(), s, chunk_s=chunk, until_s=PHASES[-1][1])
        t = np.array([x.t_s for x in statuses])
        rank = np.array([x.rank for x in statuses])
        for expected, (start, _, axis) in zip(EXPECTED_RANKS[1:], PHASES):
            hit = t[(rank >= expected) & (t >= start)]
            rows.append({"update_every_s": chunk, "change": f"turns about {axis} start at {start:g} s",
                         "rank": expected, "shown_at_s": float(hit[0]) if hit.size else None,
                         "latency_s": float(hit[0] - start) if hit.size else None})
        hit = t[rank == EXPECTED_RANKS[0]]
        rows.append({"update_every_s": chunk, "change": "still, from 0 s", "rank": 2,
                     "shown_at_s": float(hit[0]), "latency_s": float(hit[0])})
    return rows


def prediction_cost(repeat: int) -> list[dict]:
    from magyro.live.prediction import predict_session

    rows = []
    for rate in (100.0, 200.0):
        s = recording(rate, problem="paper-table1")    # all three axes from the start: full rank, a real prediction
        predict_session(s.within(0, 30.0), 30.0)   # warm: compiled kernels, imports
        for T in (30.0, 60.0, 90.0, 120.0):
            cut = s.within(0.0, T)
            times = []
            for _ in range(repeat):
                p = predict_session(cut, T)
                times.append(p.seconds)
            rows.append({"rate_hz": rate, "data_s": T, "seconds": statistics.median(times), "verdict": p.verdict})
    return rows


def agreement() -> dict:
    import magyro
    from magyro.io import load_session, write_session
    from magyro.live.monitor import ExcitationMonitor
    from magyro.live.prediction import GROUPS, Predictor
    from magyro.observability.report import accuracy_rows
    from test_watch import feed, staged_session

    s = staged_session()
    refresh = 2.0
    predictor = Predictor("inline", refresh_s=refresh)
    mon = ExcitationMonitor(predictor=predictor)
    start = time.perf_counter()
    statuses = feed(mon, s, stop=lambda x: x.enough)
    feed_s = time.perf_counter() - start
    st = statuses[-1]
    mon.predictor = None
    feed(mon, s)                          # the rest of the recording (earlier samples are not taken twice)
    with tempfile.TemporaryDirectory() as d:
        path = Path(d) / "w.parquet"
        write_session(mon.session(), path)
        saved = load_session(path)
    t0 = saved.t_gyro_s[0]
    cost = st.prediction.seconds
    out = {"enough_shown_at_s": st.t_s, "prediction_of_first_s": st.prediction.t_s, "feed_with_inline_predictions_s": feed_s,
           "predictions": len(predictor.history), "prediction_cost_s": cost}
    # live (a background worker, data in real time), the prediction of the data up to t is shown at t + its cost,
    # and the data may have met the targets up to one refresh before that prediction started
    for name, T in (("at_the_prediction_time", st.prediction.t_s),
                    ("live: shown at +cost", st.prediction.t_s + cost),
                    ("live: worst, +refresh+cost", st.prediction.t_s + refresh + cost),
                    ("3 s later", st.prediction.t_s + 3.0), ("10 s later", st.prediction.t_s + 10.0)):
        rep = magyro.observe(saved.within(t0, t0 + T))
        worst = 0.0
        for g, (_, values, _, _) in zip(GROUPS, accuracy_rows(rep.predicted_std, rep.targets)):
            worst = max(worst, float(np.max(np.abs(np.asarray(st.prediction.std[g]) / values - 1.0))))
        out[name] = {"observe_data_s": T, "verdict": rep.verdict, "max_rel_diff": worst}
    return out


def table(title: str, rows: list[dict]) -> str:
    keys = list(rows[0])
    width = {k: max(len(k), *(len(fmt(r[k])) for r in rows)) for k in keys}
    lines = [title, "  ".join(k.ljust(width[k]) for k in keys)]
    lines += ["  ".join(fmt(r[k]).ljust(width[k]) for k in keys) for r in rows]
    return "\n".join(lines)


def fmt(v) -> str:
    if isinstance(v, float):
        return f"{v:.4g}"
    return str(v)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--skip-pipeline", action="store_true")
    ap.add_argument("--out", type=Path)
    args = ap.parse_args()
    results = {}
    s200 = recording(200.0)
    results["throughput_200hz_120s"] = throughput(s200, args.repeat)
    print(table("1. throughput, 120 s at 200 Hz (one core)", [results["throughput_200hz_120s"]]), "\n")
    if not args.skip_pipeline:
        results["pipeline"] = pipeline(100.0)
        print(table("   pipeline: magyro simulate three-axes --stream --speed 0 | magyro watch - -q",
                    [{k: v for k, v in results["pipeline"].items() if k != "summary"}]), "\n")
    results["latency"] = latency()
    print(table("2. rank latency after each change of motion (data time)", results["latency"]), "\n")
    results["prediction_cost"] = prediction_cost(args.repeat)
    print(table("3. cost of one prediction (magyro.observe on the data so far)", results["prediction_cost"]), "\n")
    results["agreement"] = agreement()
    flat = [{"observe on": k, **v} for k, v in results["agreement"].items() if isinstance(v, dict)]
    print(table("4. enough vs magyro observe on the saved session "
                f"(enough shown at {results['agreement']['enough_shown_at_s']:.2f} s, prediction of the first "
                f"{results['agreement']['prediction_of_first_s']:.2f} s)", flat))
    if args.out:
        args.out.write_text(json.dumps(results, indent=2, default=str) + "\n")


if __name__ == "__main__":
    main()
