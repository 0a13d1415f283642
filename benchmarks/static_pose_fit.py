"""magyro's accelerometer against the static-pose method people use (imu_tk, Tedaldi et al., ICRA 2014), issue 39.

    python benchmarks/static_pose_fit.py [--seeds 6] [--problems paper-table1-acc,phone-module-acc] [--out FILE]

Recordings (simulated, `magyro.studies.simulate`, the problem's sensors; the problem's hand moves the device, by its
hand_translation_m, only while it turns: `[accelerometer] hand_while_turning`, the held poses truly still):
  * poses: 12 poses whose gravity directions are the icosahedron's vertices, each held 4 s, a 3 s turn between
    (the static method's home ground);
  * pauses: free-hand turns (random axes, 60-150 deg in 1-2 s) stopped 10 times for 4 s.

The static fit is written here, independent of magyro's code: a detector (the accelerometer's moving variance
over 1 s below 4x its least, as imu_tk's init-interval threshold), each still interval's mean, then the
9 parameters (upper-triangular K with positive diagonal: scale and non-orthogonality in magyro's convention, which
is imu_tk's triangular misalignment; bias) that make every mean's length g (scipy least_squares).

Error of a calibration: the whole specific-force map over 26 directions u (cube faces, edges, corners): for
f = g u in the accelerometer's frame, raw y = K_true^-1 (f - eps_true), calibrated K y + eps; the worst |error| in
ppm of g. magyro's and the static fit's maps share the frame (upper-triangular K), so they compare as they are.
magyro twice: with only the end rests (`Options(stills=False)`, as before issue 39: `magyro_ends_*`) and with every
still (`magyro.front.stills`: `magyro_*`). Printed per recording: the errors and their ratios to the static fit's,
magyro's worst |error| / std over K_a, the bias and C_b_a, and how many stills each detector found.
"""
from __future__ import annotations

import argparse
import dataclasses
import datetime
import itertools
import json
import subprocess

import numpy as np
from scipy.optimize import least_squares

from magyro import calibrate, so3
from magyro.errors import MagyroError
from magyro.options import Options
from magyro.studies.scenario import Motion, Turn, load_problem
from magyro.studies.simulate import simulate

HOLD_S, TURN_S = 4.0, 3.0
DIRECTIONS = np.array([v for v in itertools.product((-1, 0, 1), repeat=3) if any(v)], dtype=float)
DIRECTIONS /= np.linalg.norm(DIRECTIONS, axis=1)[:, None]


def icosahedron() -> np.ndarray:
    """The 12 unit vertices of an icosahedron: gravity directions spread evenly over the sphere."""
    p = (1 + 5 ** 0.5) / 2
    v = np.array([[0, s1, s2 * p] for s1 in (-1, 1) for s2 in (-1, 1)], dtype=float)
    v = np.concatenate([v, np.roll(v, 1, axis=1), np.roll(v, 2, axis=1)])
    return v / np.linalg.norm(v, axis=1)[:, None]


def turn_between(d_from: np.ndarray, d_to: np.ndarray) -> tuple[np.ndarray, float]:
    """The body turn (axis, deg) that carries gravity, seen in the body, from d_from to d_to: Exp(a u)^T d_from =
    d_to, so u = d_to x d_from."""
    axis = np.cross(d_to, d_from)
    if np.linalg.norm(axis) < 1e-9:   # opposite poses: any axis across them
        axis = np.cross(d_from, [1.0, 0.0, 0.0] if abs(d_from[0]) < 0.9 else [0.0, 1.0, 0.0])
    return axis / np.linalg.norm(axis), float(np.rad2deg(np.arccos(np.clip(d_from @ d_to, -1, 1))))


def pose_motion(order_seed: int) -> Motion:
    """12 held poses, 3 s turns between, in an order drawn by the seed (the first pose: the device as it lies)."""
    rng = np.random.default_rng(order_seed)
    poses = icosahedron()[rng.permutation(12)]
    poses = np.concatenate([[[0.0, 0.0, 1.0]], poses])   # body z up at the start (C0 = I: gravity along -z in ENU,
    turns = [Turn(None, 0.0, HOLD_S)]                     # the specific force +z in the body)
    for a, b in zip(poses[:-1], poses[1:]):
        axis, angle = turn_between(a, b)
        turns += [Turn(axis, angle, TURN_S), Turn(None, 0.0, HOLD_S)]
    return motion_of(turns)


def pause_motion(seed: int, pauses: int = 10) -> Motion:
    """Free-hand turns (random axis, 60-150 deg in 1-2 s) in 10 stretches of 4-6 turns, each followed by a 4 s
    still; 4 s still at the start."""
    rng = np.random.default_rng([seed, 39])
    turns = [Turn(None, 0.0, HOLD_S)]
    for _ in range(pauses):
        for _ in range(int(rng.integers(4, 7))):
            axis = rng.standard_normal(3)
            turns.append(Turn(axis / np.linalg.norm(axis), float(rng.choice([-1, 1]) * rng.uniform(60, 150)),
                              float(rng.uniform(1.0, 2.0))))
        turns.append(Turn(None, 0.0, HOLD_S))
    return motion_of(turns)


def motion_of(turns: list) -> Motion:
    return Motion(kind="turns", seed=0, axes=(), amplitude_deg=np.zeros(0), band_hz=(0.05, 0.5), components=1,
                  rest_start_s=0.0, rest_end_s=0.0, ramp_s=1.0, initial_euler_deg=np.zeros(3), turns=tuple(turns))


def recording(problem_name: str, kind: str, seed: int):
    base = load_problem(problem_name)
    motion = pose_motion(seed) if kind == "poses" else pause_motion(seed)
    duration = sum(t.seconds for t in motion.turns)
    acc = dataclasses.replace(base.accelerometer, hand_while_turning=True)   # the problem's hand, while turning only
    problem = dataclasses.replace(base, motion=motion, duration_s=duration, accelerometer=acc)
    session, _ = simulate(problem, seed)
    return problem, session


# ------------------------------------------------------------------ the static method, written from the paper


def still_intervals(t_s: np.ndarray, acc: np.ndarray, window_s: float = 1.0, factor: float = 4.0,
                    min_s: float = 2.0) -> list[tuple[int, int]]:
    """[a, b) sample ranges where the accelerometer's moving variance (sum over axes, over `window_s`) stays below
    `factor` times its least value (imu_tk's threshold on the initial still's variance)."""
    rate = 1.0 / np.median(np.diff(t_s))
    n = max(3, int(round(window_s * rate)))
    c1 = np.cumsum(np.concatenate([np.zeros((1, 3)), acc]), axis=0)
    c2 = np.cumsum(np.concatenate([np.zeros((1, 3)), acc**2]), axis=0)
    mean = (c1[n:] - c1[:-n]) / n
    var = ((c2[n:] - c2[:-n]) / n - mean**2).sum(axis=1)
    still = np.zeros(len(t_s), dtype=bool)
    quiet = var < factor * np.min(var)
    for k in np.flatnonzero(quiet):
        still[k: k + n] = True
    edges = np.flatnonzero(np.diff(np.concatenate([[0], still.astype(int), [0]])))
    return [(a, b) for a, b in zip(edges[::2], edges[1::2]) if (b - a) / rate >= min_s]


def static_fit(means: np.ndarray, g_m_s2: float) -> tuple[np.ndarray, np.ndarray]:
    """(K upper triangular, eps) making |K y + eps| = g for every still mean y (9 parameters, Gauss-Newton from
    the identity)."""
    def unpack(p):
        K = np.array([[p[0], p[3], p[4]], [0.0, p[1], p[5]], [0.0, 0.0, p[2]]])
        return K, p[6:9]

    def residual(p):
        K, eps = unpack(p)
        return np.linalg.norm(means @ K.T + eps, axis=1) - g_m_s2

    fit = least_squares(residual, np.array([1, 1, 1, 0, 0, 0, 0, 0, 0], dtype=float), method="lm", xtol=1e-15,
                        ftol=1e-15)
    return unpack(fit.x)


def map_error_ppm(K, eps, K_true, eps_true, g_m_s2: float) -> float:
    """The worst error over 26 directions of the calibrated specific force, ppm of g."""
    f = g_m_s2 * DIRECTIONS
    y = np.linalg.solve(K_true, (f - eps_true).T).T
    return float(1e6 * np.max(np.linalg.norm(y @ np.asarray(K).T + eps - f, axis=1)) / g_m_s2)


def compare(problem_name: str, kind: str, seed: int) -> dict:
    problem, session = recording(problem_name, kind, seed)
    acc = problem.accelerometer
    g = acc.g_m_s2
    stills = still_intervals(session.t_acc_s, session.acc_m_s2)
    row = {"problem": problem_name, "kind": kind, "seed": seed, "duration_s": round(session.duration_s, 1),
           "static_stills": len(stills)}
    if len(stills) >= 9:
        K_s, eps_s = static_fit(np.array([session.acc_m_s2[a:b].mean(axis=0) for a, b in stills]), g)
        row["static_ppm"] = round(map_error_ppm(K_s, eps_s, acc.K_a, acc.bias_m_s2, g))
    for key, stills in (("magyro_ends", False), ("magyro", True)):   # only the end rests (before issue 39), every still
        try:
            cal = calibrate(session, Options(accelerometer=True, stills=stills))
            a = cal.accelerometer
            row[f"{key}_ppm"] = round(map_error_ppm(a.K_a, a.bias_m_s2, acc.K_a, acc.bias_m_s2, g))
            row[f"{key}_worst_z"] = round(worst_z(a, acc), 1)
            row[f"{key}_rests"] = len(cal.rests.segments_s) if cal.rests is not None else 0
        except MagyroError as error:
            row[key] = f"{type(error).__name__}: {str(error)[:200]}"
    if cal.stills is not None:
        row["magyro_stills"] = len(cal.stills.segments_s)
    for key in ("magyro_ends", "magyro"):
        if "static_ppm" in row and f"{key}_ppm" in row:
            row[f"{key}_ratio"] = round(row[f"{key}_ppm"] / row["static_ppm"], 2)
    return row


def worst_z(a, truth) -> float:
    """The largest |estimate - truth| / std over K_a's six entries, the bias and the frame's three angles (d with
    C_b_a(true) = C_b_a(est) Exp(d), which the static fit has not)."""
    iu = np.triu_indices(3)
    d_deg = np.rad2deg(so3.log_so3(np.asarray(a.C_b_a).T @ truth.C_b_a))
    err = np.concatenate([(a.K_a - truth.K_a)[iu], a.bias_m_s2 - truth.bias_m_s2, d_deg])
    std = np.concatenate([np.asarray(a.std_K_a)[iu], np.asarray(a.std_bias_m_s2), np.asarray(a.std_misalignment_deg)])
    return float(np.max(np.abs(err) / std))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, default=6)
    ap.add_argument("--problems", default="paper-table1-acc,phone-module-acc")
    ap.add_argument("--kinds", default="poses,pauses")
    ap.add_argument("--out", default=None)
    args = ap.parse_args()
    rows = []
    for problem_name in args.problems.split(","):
        for kind in args.kinds.split(","):
            for seed in range(1, args.seeds + 1):
                rows.append(compare(problem_name, kind, seed))
                print(json.dumps(rows[-1]), flush=True)
    summary = {}
    for problem_name in args.problems.split(","):
        for kind in args.kinds.split(","):
            got = [r for r in rows if r["problem"] == problem_name and r["kind"] == kind
                   and "magyro_ratio" in r and "magyro_ends_ratio" in r]
            if got:
                rms = lambda key: float(np.sqrt(np.mean([r[key] ** 2 for r in got])))
                summary[f"{problem_name} {kind}"] = {
                    "static_ppm_rms": round(rms("static_ppm")),
                    "magyro_ends_ppm_rms": round(rms("magyro_ends_ppm")), "magyro_ppm_rms": round(rms("magyro_ppm")),
                    "ends_ratio_of_rms": round(rms("magyro_ends_ppm") / rms("static_ppm"), 2),
                    "ratio_of_rms": round(rms("magyro_ppm") / rms("static_ppm"), 2),
                    "magyro_worst_z": max(r["magyro_worst_z"] for r in got), "recordings": len(got)}
    print(json.dumps(summary, indent=1))
    if args.out:
        commit = subprocess.run(["git", "rev-parse", "--short", "HEAD"], capture_output=True, text=True).stdout.strip()
        with open(args.out, "w") as f:
            json.dump({"date": datetime.date.today().isoformat(), "commit": commit,
                       "command": f"python benchmarks/static_pose_fit.py --seeds {args.seeds} --out {args.out}",
                       "summary": summary, "rows": rows}, f, indent=1)
            f.write("\n")


if __name__ == "__main__":
    main()
