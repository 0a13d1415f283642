"""The accelerometer in the joint least squares (issue 26): the targets it is measured against, one table each.

    python benchmarks/accelerometer.py real [--session data/broad-02.parquet] [--no-hand-states] [--out docs/numbers/accelerometer-broad-02.json]
    python benchmarks/accelerometer.py sim [--problem paper-table1-acc] [--still] [--no-hand-states] [--seeds 20] [--jobs 2] [--out RECORD]

`real`: the calibrated accelerometer's |f| at the rests against g (each rest of the session, found by the rests'
own rule), the split halves (each half solved alone with --force; RMS z of the accelerometer's 12 parameters and of
the gyro's 12), the gyro's std with the accelerometer against without, and the solve's CPU time with and without
it (the median of 3 interleaved runs each, after one run that compiles and caches the kernels).
`sim`: per noise seed (each seed draws another sway of the hand; `--still`: no hand translation at all) the accelerometer's and the gyro's errors against
the truth in reported std, the actual spread over the seeds against the mean reported std (reported/actual), and
the gyro's std with the accelerometer against without it on the same session, and the Cramer-Rao bound at seed 0's
session (magyro.studies.crlb_accelerometer: the hand counted as noise of its known ensemble; the white-noise bound,
the hand still, beside it) with std/CRLB, the actual spread over the seeds over it, and what the solve's weighting
reaches with the same hand (`weighted`: not a bound, the sandwich of weights that count every interval as
independent; std/wtd near 1 says the spread is the weighting's, not something else's). `--out` writes the record
docs/accelerometer.md is rendered from (docs/make_accelerometer_numbers.py).
"""
from __future__ import annotations

import argparse
import dataclasses
import os
import sys
import time

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")   # as the CLI has it (magyro/cli/__init__.py): MUMPS's BLAS
os.environ.setdefault("OMP_NUM_THREADS", "1")        # threads cost the accelerometer's solve 1.5 s of spinning
from concurrent.futures import ProcessPoolExecutor
from types import SimpleNamespace

import numpy as np

from machine_load import measured_at, provenance, write_record
from magyro import calibrate, load_session
from magyro.front.rests import find_rests
from magyro.options import Options
from magyro.result.consistency import gyro_stds, gyro_values, half_spans_s
from magyro.result.reported import misalignment_vector

UPPER = [(0, 0), (0, 1), (0, 2), (1, 1), (1, 2), (2, 2)]
ACC_NAMES = ([f"K_a[{i},{j}]" for i, j in UPPER] + [f"bias_{a}_m_s2" for a in "xyz"]
             + [f"misalignment_d{a}_deg" for a in "xyz"])


def acc_values(acc, C_b_a_ref) -> np.ndarray:
    d = np.rad2deg(misalignment_vector(C_b_a_ref, acc.C_b_a))
    return np.concatenate([[acc.K_a[i, j] for i, j in UPPER], acc.bias_m_s2, d])


def acc_stds(acc) -> np.ndarray:
    return np.concatenate([[acc.std_K_a[i, j] for i, j in UPPER], acc.std_bias_m_s2, acc.std_misalignment_deg])


def timed(session, options, method=None):
    t0 = time.process_time()
    cal = calibrate(session, options, method)
    return cal, time.process_time() - t0


def real(path: str, hand_states: bool = True) -> dict:
    from magyro.nls.method import NLS

    method = NLS(hand_states=hand_states)
    s = load_session(path)
    g = Options().gravity_m_s2
    timed(s, Options(accelerometer=True), method)   # compile and cache the kernels before timing
    t_base, t_acc = [], []
    for _ in range(3):
        base, t = timed(s, Options(accelerometer=False))
        t_base.append(t)
        cal, t = timed(s, Options(accelerometer=True), method)
        t_acc.append(t)
    acc = cal.accelerometer
    rests = []
    for a, b in find_rests(s).segments_s:
        keep = (s.t_acc_s >= a) & (s.t_acc_s <= b)
        rests.append({"span_s": [float(a), float(b)],
                      "f_over_g": float(np.linalg.norm(acc.apply(s.acc_m_s2[keep]), axis=1).mean() / g),
                      "raw_over_g": float(np.linalg.norm(s.acc_m_s2[keep], axis=1).mean() / g)})
    halves = [calibrate(s.within(*span), Options(accelerometer=True, force=True), method) for span in half_spans_s(s)]
    za = (acc_values(halves[0].accelerometer, acc.C_b_a) - acc_values(halves[1].accelerometer, acc.C_b_a)) / np.hypot(
        acc_stds(halves[0].accelerometer), acc_stds(halves[1].accelerometer))
    v, sd = [gyro_values(h, cal.C_b_m) for h in halves], [gyro_stds(h) for h in halves]
    zg = np.array([(v[0][k] - v[1][k]) / np.hypot(sd[0][k], sd[1][k]) for k in v[0]])
    return {"session": path, "solve_cpu_s": float(np.median(t_base)), "solve_cpu_s_accelerometer": float(np.median(t_acc)),
            "rests": rests, "halves_rms_z": float(np.sqrt(np.mean(za**2))), "halves_max_z": float(np.max(np.abs(za))),
            "halves_worst": ACC_NAMES[int(np.argmax(np.abs(za)))], "halves_gyro_rms_z": float(np.sqrt(np.mean(zg**2))),
            "gyro_std_ratio": {k: gyro_stds(cal)[k] / gyro_stds(base)[k] for k in gyro_stds(cal)},
            "K_a_diag": [float(v) for v in np.diag(acc.K_a)], "bias_m_s2": [float(v) for v in acc.bias_m_s2]}


def print_real(r: dict) -> None:
    print(f"session {r['session']}: solve CPU {r['solve_cpu_s']:.2f} s without the accelerometer, "
          f"{r['solve_cpu_s_accelerometer']:.2f} s with it ({r['solve_cpu_s_accelerometer'] / r['solve_cpu_s']:.2f}x)")
    print("rest (s)            |f|/g - 1 (%)   raw |y|/g - 1 (%)")
    for rest in r["rests"]:
        a, b = rest["span_s"]
        print(f"{a:8.2f}-{b:8.2f}   {100 * (rest['f_over_g'] - 1):+10.3f}   {100 * (rest['raw_over_g'] - 1):+10.3f}")
    print(f"split halves: accelerometer RMS z {r['halves_rms_z']:.2f} (max |z| {r['halves_max_z']:.2f}, "
          f"{r['halves_worst']}); gyro RMS z {r['halves_gyro_rms_z']:.2f}")
    print("gyro std with/without the accelerometer: " + " ".join(f"{k}={v:.2f}" for k, v in r["gyro_std_ratio"].items()))


def one_seed(args):
    problem, seed, hand_states = args
    from magyro.nls.method import NLS
    from magyro.studies.simulate import simulate
    session, truth = simulate(problem, seed)
    return (calibrate(session, Options(accelerometer=True), NLS(hand_states=hand_states)),
            calibrate(session, Options(accelerometer=False)), truth)


def sim(problem: str, seeds: int, jobs: int, still: bool = False, hand_states: bool = True) -> dict:
    from magyro.result.calibration import Calibration
    from magyro.studies.scenario import load_problem

    prob = load_problem(problem)
    if still:   # turned about itself: no hand translation (a gimbal, a careful hand)
        prob = dataclasses.replace(prob, accelerometer=dataclasses.replace(prob.accelerometer, hand_translation_m=0.0))
    with ProcessPoolExecutor(jobs) as pool:
        runs = list(pool.map(one_seed, [(prob, seed, hand_states) for seed in range(seeds)]))
    t = runs[0][2]["accelerometer"]
    C_ref = np.asarray(t["C_b_a"])
    truth_acc = np.concatenate([[np.asarray(t["K_a"])[i, j] for i, j in UPPER], t["bias_m_s2"], np.zeros(3)])
    est = np.array([acc_values(c.accelerometer, C_ref) for c, _, _ in runs])
    std = np.array([acc_stds(c.accelerometer) for c, _, _ in runs])
    tg = runs[0][2]
    truth_gyro = Calibration.from_parameters(np.asarray(tg["gyro"]["K_g"]), np.deg2rad(tg["gyro"]["bias_deg_s"]),
                                             np.asarray(tg["misalignment"]["C_b_m"]))
    tv = gyro_values(truth_gyro, truth_gyro.C_b_m)
    gest = np.array([[gyro_values(c, truth_gyro.C_b_m)[k] for k in tv] for c, _, _ in runs])
    gstd = np.array([[gyro_stds(c)[k] for k in tv] for c, _, _ in runs])
    ratio = np.array([[gyro_stds(c)[k] / gyro_stds(b)[k] for k in tv] for c, b, _ in runs])
    bound = crlb(prob)
    actual, gactual = est.std(axis=0, ddof=1), gest.std(axis=0, ddof=1)
    gcrlb = np.array([gyro_stds(SimpleNamespace(std=bound.std))[k] for k in tv])
    return {"problem": problem, "still": still, "hand_states": hand_states, "seeds": seeds, "names": ACC_NAMES,
            "mean_error": (est - truth_acc).mean(axis=0).tolist(), "actual": est.std(axis=0, ddof=1).tolist(),
            "reported": std.mean(axis=0).tolist(),
            "max_abs_z": np.max(np.abs((est - truth_acc) / std), axis=0).tolist(),
            "max_abs_error": np.max(np.abs(est - truth_acc), axis=0).tolist(),
            "gyro_names": list(tv), "gyro_max_abs_z": np.max(np.abs((gest - np.array(list(tv.values()))) / gstd), axis=0).tolist(),
            "gyro_reported_over_actual": (gstd.mean(axis=0) / gest.std(axis=0, ddof=1)).tolist(),
            "gyro_std_ratio_median": np.median(ratio, axis=0).tolist(), "gyro_std_ratio_max": ratio.max(axis=0).tolist(),
            "crlb": bound.accelerometer_std.tolist(), "crlb_white": bound.white_accelerometer_std.tolist(),
            "std_over_crlb": (actual / bound.accelerometer_std).tolist(),
            "weighted": bound.weighted_accelerometer_std.tolist(),
            "gyro_crlb": gcrlb.tolist(), "gyro_std_over_crlb": (gactual / gcrlb).tolist()}


def crlb(prob):
    """The Cramer-Rao bound at seed 0's session (`crlb_accelerometer.accelerometer_cramer_rao`)."""
    from magyro.studies.crlb_accelerometer import accelerometer_cramer_rao
    from magyro.studies.simulate import simulate

    return accelerometer_cramer_rao(prob, simulate(prob, 0)[0], Options(accelerometer=True))


def print_sim(r: dict) -> None:
    print(f"{r['problem']}: {r['seeds']} seeds; accelerometer")
    print(f"{'parameter':24s} {'mean err':>10s} {'actual':>10s} {'reported':>10s} {'rep/act':>8s} {'max|z|':>7s} "
          f"{'CRLB':>10s} {'std/CRLB':>8s} {'CRLB white':>10s} {'weighted':>10s} {'std/wtd':>7s}")
    for k, name in enumerate(r["names"]):
        print(f"{name:24s} {r['mean_error'][k]:+10.2e} {r['actual'][k]:10.2e} {r['reported'][k]:10.2e} "
              f"{r['reported'][k] / r['actual'][k]:8.2f} {r['max_abs_z'][k]:7.2f} {r['crlb'][k]:10.2e} "
              f"{r['std_over_crlb'][k]:8.2f} {r['crlb_white'][k]:10.2e} {r['weighted'][k]:10.2e} "
              f"{r['actual'][k] / r['weighted'][k]:7.2f}")
    ratio, roa = np.array(r["gyro_std_ratio_max"]), np.array(r["gyro_reported_over_actual"])
    print(f"gyro with the accelerometer: max |z| {max(r['gyro_max_abs_z']):.2f}; std with/without: median "
          f"{np.median(r['gyro_std_ratio_median']):.2f}, max {ratio.max():.2f}; reported/actual {roa.min():.2f}-{roa.max():.2f}")
    print("gyro std/CRLB (with the accelerometer): " + " ".join(
        f"{n}={v:.2f}" for n, v in zip(r["gyro_names"], r["gyro_std_over_crlb"])))


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("what", choices=["real", "sim"])
    ap.add_argument("--session", default="data/broad-02.parquet")
    ap.add_argument("--problem", default="paper-table1-acc")
    ap.add_argument("--seeds", type=int, default=20)
    ap.add_argument("--jobs", type=int, default=2)
    ap.add_argument("--still", action="store_true", help="sim: the problem's hand translation set to 0 (turned about itself)")
    ap.add_argument("--no-hand-states", dest="hand_states", action="store_false",
                    help="weight the accelerometer by the hand instead of taking its velocity as states "
                         "(NLS(hand_states=False), magyro solve --no-hand-states)")
    ap.add_argument("--out", help="write the record here (docs/numbers/accelerometer-*.json)")
    a = ap.parse_args(argv)
    command = "python benchmarks/accelerometer.py " + " ".join(argv or [])
    if a.what == "real":
        record = real(a.session, a.hand_states)
        print_real(record)
        record["provenance"] = provenance(command)
    else:
        record = sim(a.problem, a.seeds, a.jobs, a.still, a.hand_states)
        print_sim(record)
        record["provenance"] = measured_at(command)
    if a.out:
        write_record(a.out, record)


if __name__ == "__main__":
    main(sys.argv[1:])
