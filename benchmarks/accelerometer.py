"""The accelerometer in the joint least squares (issue 26): the targets it is measured against, one table each.

    python benchmarks/accelerometer.py real [--session data/broad-02.parquet]
    python benchmarks/accelerometer.py sim [--problem paper-table1-acc] [--seeds 20] [--jobs 2]

`real`: the calibrated accelerometer's |f| at the rests against g (each rest of the session, found by the rests'
own rule), the split halves (each half solved alone; RMS z of the accelerometer's 12 parameters and the gyro's
12), and the solve's time with and without the accelerometer (CPU s of the solve, second run: kernels cached).
`sim`: per seed the accelerometer's and the gyro's errors against the truth in reported std, the actual spread
over the seeds against the mean reported std (reported/actual), and the gyro's std with the accelerometer
against without it on the same session.
"""
from __future__ import annotations

import argparse
import sys
import time
from concurrent.futures import ProcessPoolExecutor

import numpy as np

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


def timed(session, options):
    t0 = time.process_time()
    cal = calibrate(session, options)
    return cal, time.process_time() - t0


def real(path: str) -> None:
    s = load_session(path)
    g = Options().gravity_m_s2
    timed(s, Options(accelerometer=True))   # compile and cache the kernels before timing
    base, t_base = timed(s, Options())
    cal, t_acc = timed(s, Options(accelerometer=True))
    acc = cal.accelerometer
    print(f"session {path}: solve CPU {t_base:.2f} s without the accelerometer, {t_acc:.2f} s with it "
          f"({t_acc / t_base:.2f}x)")
    print("rest (s)            |f| (m/s^2)   |f|/g - 1 (%)   raw |y|/g - 1 (%)")
    for a, b in find_rests(s).segments_s:
        keep = (s.t_acc_s >= a) & (s.t_acc_s <= b)
        f = np.linalg.norm(acc.apply(s.acc_m_s2[keep]), axis=1).mean()
        raw = np.linalg.norm(s.acc_m_s2[keep], axis=1).mean()
        print(f"{a:8.2f}-{b:8.2f}   {f:10.5f}   {100 * (f / g - 1):+10.3f}   {100 * (raw / g - 1):+10.3f}")
    halves = [calibrate(s.within(*span), Options(accelerometer=True, force=True)) for span in half_spans_s(s)]
    za = (acc_values(halves[0].accelerometer, acc.C_b_a) - acc_values(halves[1].accelerometer, acc.C_b_a)) / np.hypot(
        acc_stds(halves[0].accelerometer), acc_stds(halves[1].accelerometer))
    v = [gyro_values(h, cal.C_b_m) for h in halves]
    sd = [gyro_stds(h) for h in halves]
    zg = np.array([(v[0][k] - v[1][k]) / np.hypot(sd[0][k], sd[1][k]) for k in v[0]])
    print(f"split halves: accelerometer RMS z {np.sqrt(np.mean(za**2)):.2f} (max |z| {np.max(np.abs(za)):.2f}, "
          f"{ACC_NAMES[int(np.argmax(np.abs(za)))]}); gyro RMS z {np.sqrt(np.mean(zg**2)):.2f}")
    print("gyro std with/without the accelerometer: "
          + " ".join(f"{k}={cal_std / base_std:.2f}" for k, cal_std, base_std in
                     zip(gyro_stds(cal), gyro_stds(cal).values(), gyro_stds(base).values())))


def one_seed(args):
    problem, seed = args
    from magyro.studies.simulate import simulate
    session, truth = simulate(problem, seed)
    cal = calibrate(session, Options(accelerometer=True))
    base = calibrate(session, Options())
    return cal, base, truth


def sim(problem: str, seeds: int, jobs: int) -> None:
    from magyro.studies.scenario import load_problem
    from magyro.result.calibration import Calibration
    from magyro.result.accelerometer import AccelerometerCalibration
    prob = load_problem(problem)
    with ProcessPoolExecutor(jobs) as pool:
        runs = list(pool.map(one_seed, [(prob, seed) for seed in range(seeds)]))
    t = runs[0][2]["accelerometer"]
    C_ref = np.asarray(t["C_b_a"])
    truth_acc = np.concatenate([[np.asarray(t["K_a"])[i, j] for i, j in UPPER], t["bias_m_s2"], np.zeros(3)])
    est = np.array([acc_values(c.accelerometer, C_ref) for c, _, _ in runs])
    std = np.array([acc_stds(c.accelerometer) for c, _, _ in runs])
    z = (est - truth_acc) / std
    actual = est.std(axis=0, ddof=1)
    print(f"{problem}: {seeds} seeds; accelerometer")
    print(f"{'parameter':24s} {'mean err':>10s} {'actual':>10s} {'reported':>10s} {'rep/act':>8s} {'max|z|':>7s}")
    for k, name in enumerate(ACC_NAMES):
        print(f"{name:24s} {np.mean(est[:, k] - truth_acc[k]):+10.2e} {actual[k]:10.2e} {std[:, k].mean():10.2e} "
              f"{std[:, k].mean() / actual[k]:8.2f} {np.max(np.abs(z[:, k])):7.2f}")
    truth_gyro = Calibration.from_parameters(np.asarray(runs[0][2]["gyro"]["K_g"]),
                                             np.deg2rad(runs[0][2]["gyro"]["bias_deg_s"]),
                                             np.asarray(runs[0][2]["misalignment"]["C_b_m"]))
    tv = gyro_values(truth_gyro, truth_gyro.C_b_m)
    gz = np.array([[(gyro_values(c, truth_gyro.C_b_m)[k] - tv[k]) / gyro_stds(c)[k] for k in tv] for c, _, _ in runs])
    ratio = np.array([[gyro_stds(c)[k] / gyro_stds(b)[k] for k in tv] for c, b, _ in runs])
    gest = np.array([[gyro_values(c, truth_gyro.C_b_m)[k] for k in tv] for c, _, _ in runs])
    grep = np.array([[gyro_stds(c)[k] for k in tv] for c, _, _ in runs]).mean(axis=0)
    print("gyro with the accelerometer: max |z| {:.2f}; std with/without: {:.2f}-{:.2f} (median {:.2f}); "
          "reported/actual {:.2f}-{:.2f}".format(np.max(np.abs(gz)), ratio.min(), ratio.max(), np.median(ratio),
                                                 (grep / gest.std(axis=0, ddof=1)).min(),
                                                 (grep / gest.std(axis=0, ddof=1)).max()))
    del AccelerometerCalibration


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("what", choices=["real", "sim"])
    ap.add_argument("--session", default="data/broad-02.parquet")
    ap.add_argument("--problem", default="paper-table1-acc")
    ap.add_argument("--seeds", type=int, default=20)
    ap.add_argument("--jobs", type=int, default=2)
    a = ap.parse_args(argv)
    real(a.session) if a.what == "real" else sim(a.problem, a.seeds, a.jobs)


if __name__ == "__main__":
    main(sys.argv[1:])
