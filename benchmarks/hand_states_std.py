"""Is the hand states' std right, and where is it not? The hand's share of it against the error the simulator's
own hand makes (issue 26: reported/actual in [0.85, 1.15]).

    python benchmarks/hand_states_std.py [--problem phone-module-acc] [--seeds 64] [--jobs 2] [--out RECORD]

Per noise seed of the problem, the solve's own steps (`solve_passes`, then `run.solve_with_hand_states`), and at its
solution the sensitivities of the accelerometer's 12 reported parameters to the hand's acceleration in every
interval (`hand_motion.hand_sensitivities`, through the inverse information). Through them:

* realized: the error the simulator's true hand makes in this seed (its acceleration over each interval, frame i);
* reported: the hand's share of the std the solve reports (`run.hand_states_term` plus the prior's share: the
  sandwich's Omega under the hand it measured);
* the same sandwich fed the TRUE hand series (no white noise) instead of the measured one, its autocorrelation
  tapered over 30 s and averaged over the axes as the weighted solve's (`hand_motion.hand_covariance_term`, the
  states' std before 2026-12-03), or shifted in time as the states' (`hand_motion.shifted_hand_information`): where
  these differ from realized, the sandwich is off; where reported differs from them, the hand's measurement.

Printed per parameter: sqrt(mean predicted variance / mean realized square) over the seeds, for the hand's share
alone and for the whole std (the white noise's share, the inverse information less the prior's, added to both). A
ratio of two mean squares over 64 seeds is itself uncertain by about 9 %. Where the realized column and the
Monte Carlo record differ, the linearisation does (the realized error is the hand's linear effect alone).
"""
from __future__ import annotations

import argparse
import os
import sys
from concurrent.futures import ProcessPoolExecutor

os.environ.setdefault("OMP_NUM_THREADS", "1")

import numpy as np

from machine_load import measured_at, write_record

NAMES = ["K_a[0,0]", "K_a[0,1]", "K_a[0,2]", "K_a[1,1]", "K_a[1,2]", "K_a[2,2]", "bias_x_m_s2", "bias_y_m_s2",
         "bias_z_m_s2", "misalignment_dx_deg", "misalignment_dy_deg", "misalignment_dz_deg"]
KINDS = ("reported", "true hand, 30 s taper", "true hand, shifted")


def accelerometer_std(jp, solved, cov: np.ndarray) -> np.ndarray:
    """The 12 reported parameters' std under the corrections' covariance `cov`, as a solve reports them
    (`accelerometer.accelerometer_result`), in NAMES' order."""
    from magyro.nls.accelerometer import UPPER, accelerometer_result

    acc = accelerometer_result(jp, solved.x[: jp.n_theta], jp.globals_of(solved.p), cov)
    return np.concatenate([[acc.std_K_a[i, j] for i, j in UPPER], acc.std_bias_m_s2, acc.std_misalignment_deg])


def true_hand_in_frame_i(problem, grid, seed: int) -> np.ndarray:
    """(n_int, 3) the simulator's hand acceleration over each interval (5-point mean), in the solve's frame i (the
    magnetometer's at the first node)."""
    from magyro.studies.hand import truth_acceleration
    from magyro.studies.motion import inertial_from_world, truth_attitude

    C0 = truth_attitude(problem, grid.t_node_s[:1])[0]
    t = grid.t_node_s[:-1, None] + (np.arange(5) + 0.5)[None] / 5 * np.diff(grid.t_node_s)[:, None]
    a_w = truth_acceleration(problem, t.ravel(), seed).reshape(-1, 5, 3).mean(axis=1)
    return a_w @ (C0.T @ inertial_from_world(problem)).T


def one_seed(args) -> dict | None:
    from magyro.front.prepare import prepare
    from magyro.nls import run
    from magyro.nls.accelerometer import HAND_MAX_LAG_S, HAND_REACH_M, hand_size, interval_of, tapered_autocorrelation
    from magyro.nls.hand_motion import (hand_covariance_term, hand_sensitivities, sandwich_term,
                                        shifted_hand_information)
    from magyro.nls.hand_states import hand_reach_m, prior_information
    from magyro.nls.method import NLS
    from magyro.nls.reduction import reduce_hessian
    from magyro.nls.solve import build_problem, solve_passes
    from magyro.options import Options
    from magyro.studies.scenario import load_problem
    from magyro.studies.simulate import simulate

    import dataclasses

    name, seed = args
    problem = load_problem(name)
    session, _ = simulate(problem, seed)
    options, method = Options(accelerometer=True), NLS()
    prep = prepare(session, options)
    grid, lin, first = build_problem(prep, options, method)
    sol = solve_passes(first, prep, lin, method, run.level_estimator(first, prep, lin))
    if not sol.hand_found:
        return None
    jp, solved = run.solve_with_hand_states(first, prep, lin, method, sol, run.solved_hand_motion(first, lin, sol))
    reduced = reduce_hessian(run.solved_hessian(jp, solved), jp.n_theta, jp.B)
    S_inv = np.linalg.inv(reduced.information)
    P = prior_information(jp, reduced)
    U = hand_sensitivities(jp, solved.x, solved.p, reduced, np.ones(jp.n_int))
    a = true_hand_in_frame_i(problem, grid, seed)
    e = S_inv @ np.einsum("kga,ka->g", U, a)                      # the corrections' error the true hand makes
    prior = S_inv @ P @ S_inv
    variance = lambda cov: accelerometer_std(jp, solved, cov) ** 2  # of the 12 reported
    used, start = solved.acc_weight > 0, lin.accelerometer
    # the true series measured as the weighted solve's std measures a hand, with no white noise to take out
    local = hand_size(a, used, dataclasses.replace(start, sigma_white_m_s2=0.0))[0]
    reach = min(hand_reach_m(jp, solved.x), HAND_REACH_M)
    max_lag = min(int(used.sum()) // 2, int(round(HAND_MAX_LAG_S / interval_of(start))))
    info = reduced.information
    hand = {"reported": variance(run.hand_states_term(jp, lin, solved, reduced) + prior),
            KINDS[1]: variance(hand_covariance_term(jp, solved.x, solved.p, reduced, info, np.sqrt(local),
                                                    np.zeros(jp.n_int), tapered_autocorrelation(a[used], max_lag, 1.0),
                                                    float(local[used].mean()), reach)),
            KINDS[2]: variance(sandwich_term(info, shifted_hand_information(U, np.where(used[:, None], a, 0.0),
                                                                            np.zeros(jp.n_int))))}
    return {"realized": variance(np.outer(e, e)), "white": variance(S_inv - prior), **hand}


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--problem", default="phone-module-acc")
    ap.add_argument("--seeds", type=int, default=64)
    ap.add_argument("--jobs", type=int, default=2)
    ap.add_argument("--out", default=None, help="write the record here (JSON)")
    a = ap.parse_args(argv)
    with ProcessPoolExecutor(a.jobs) as pool:
        runs = [r for r in pool.map(one_seed, [(a.problem, s) for s in range(a.seeds)]) if r is not None]
    mean = {k: np.mean([r[k] for r in runs], axis=0) for k in runs[0]}
    rows = {}
    for kind in KINDS:
        rows[kind] = {"hand": np.sqrt(mean[kind] / mean["realized"]).tolist(),
                      "whole": np.sqrt((mean["white"] + mean[kind]) / (mean["white"] + mean["realized"])).tolist()}
    print(f"{a.problem}, {len(runs)} of {a.seeds} seeds with a hand; sqrt(mean predicted variance / mean realized "
          f"square), the hand's share | the whole std:")
    print(f"{'':24s}" + " ".join(f"{n[:9]:>9s}" for n in NAMES) + "    range hand | whole")
    for kind, row in rows.items():
        h, w = np.array(row["hand"]), np.array(row["whole"])
        print(f"{kind:24s}" + " ".join(f"{v:9.2f}" for v in h) + f"    {h.min():.2f}-{h.max():.2f} | {w.min():.2f}-{w.max():.2f}")
    if a.out:
        command = f"python benchmarks/hand_states_std.py --problem {a.problem} --seeds {a.seeds} --out {a.out}"
        write_record(a.out, {"problem": a.problem, "seeds": a.seeds, "with_hand": len(runs), "names": NAMES,
                             "ratios": rows, "provenance": measured_at(command)})


if __name__ == "__main__":
    main(sys.argv[1:])
