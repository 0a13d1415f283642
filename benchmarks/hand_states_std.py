"""Is the hand states' std right, and where is it not? Its sandwich with the measured hand against the same
sandwich with the simulator's own hand (issue 26: reported/actual in [0.85, 1.15]).

    python benchmarks/hand_states_std.py [--problem phone-module-acc] [--seeds 12]

Per noise seed of the problem: the solve's own steps (`solve_passes`, then `run.solve_with_hand_states`), and the
accelerometer's 12 std three ways: the sandwich the solve reports (`run.hand_states_term`: the hand the states and
residuals hold, measured), the same sandwich with the simulator's hand instead (oracle: the ensemble's stationary
autocovariance over 100 draws, `crlb_accelerometer.hand_readout_samples`' draws, times the translation's window,
isotropic), and the inverse information alone (the velocity's prior taken as the truth). Printed: each one's mean
over the seeds over the actual spread of the record docs/numbers/accelerometer-PROBLEM.json (80 seeds). Where the
oracle is near 1 and the measured one is not, the hand's measurement is what is off; where both are off, the
sandwich itself (its linearisation, the window, the lever arm).
"""
from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent


def ensemble_autocovariance(problem, draws: int = 100):
    """R(lag) per world axis of the simulator's hand acceleration, phase-averaged over `draws` draws."""
    from magyro.studies import crlb_accelerometer as bound
    from magyro.studies.hand import hand_translation

    power, omega = [], []
    for d in range(draws):
        tr = hand_translation(problem, bound.HAND_SEED0 + d)
        w = 2 * np.pi * tr.freqs_hz
        power.append(0.5 * (tr.amplitudes_m * w ** 2) ** 2)
        omega.append(w)
    power = np.concatenate(power, axis=1).ravel() / draws / 3
    omega = np.concatenate(omega, axis=1).ravel()
    lags = np.linspace(0.0, 2.0 * problem.duration_s, 40001)
    R = np.concatenate([(power[None] * np.cos(np.outer(lags[i:i + 2000], omega))).sum(axis=1)
                        for i in range(0, len(lags), 2000)])
    return lambda lag: np.interp(np.abs(lag), lags, R)


def three_stds(problem, seed: int, R) -> dict | None:
    from magyro.front.prepare import prepare
    from magyro.nls import run
    from magyro.nls.accelerometer import UPPER, accelerometer_result
    from magyro.nls.hand_motion import hand_sensitivities
    from magyro.nls.hand_states import prior_information
    from magyro.nls.method import NLS
    from magyro.nls.solve import build_problem, solve_passes
    from magyro.options import Options
    from magyro.studies.hand import translation_span, window_derivatives
    from magyro.studies.simulate import simulate

    session, _ = simulate(problem, seed)
    options, method = Options(accelerometer=True), NLS()
    prep = prepare(session, options)
    grid, lin, first = build_problem(prep, options, method)
    sol = solve_passes(first, prep, lin, method, run.level_estimator(first, prep, lin))
    if not sol.hand_found:
        return None
    jp, solved, reduced = run.solve_with_hand_states(first, prep, lin, method, sol, run.solved_hand_motion(first, lin, sol))
    S = reduced.information
    S_inv = np.linalg.inv(S)
    P = prior_information(jp, reduced)
    g, theta = jp.globals_of(solved.p), solved.x[: jp.n_theta]

    def acc_std(cov):
        a = accelerometer_result(jp, theta, g, cov)
        return np.concatenate([[a.std_K_a[i, j] for i, j in UPPER], a.std_bias_m_s2, a.std_misalignment_deg])
    U = hand_sensitivities(jp, solved.x, solved.p, reduced, np.ones(jp.n_int))
    t = 0.5 * (grid.t_node_s[:-1] + grid.t_node_s[1:])
    start, stop, ramp = translation_span(problem)
    window = window_derivatives(t, start, stop, ramp)[0]
    omega = np.einsum("kga,kl,lha->gh", U, R(t[:, None] - t[None]) * np.outer(window, window), U)
    return {"measured": acc_std(S_inv + run.hand_states_term(jp, lin, solved, reduced)),
            "oracle": acc_std(S_inv @ (S - P + omega) @ S_inv), "model": acc_std(S_inv)}


def main(argv=None) -> None:
    from magyro.studies.scenario import load_problem

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--problem", default="phone-module-acc")
    ap.add_argument("--seeds", type=int, default=12)
    a = ap.parse_args(argv)
    problem = load_problem(a.problem)
    record = json.loads((ROOT / "docs" / "numbers" / f"accelerometer-{a.problem}.json").read_text())
    R = ensemble_autocovariance(problem)
    runs = [r for r in (three_stds(problem, seed, R) for seed in range(a.seeds)) if r is not None]
    actual = np.array(record["actual"])
    print(f"{a.problem}, {len(runs)} seeds with a hand; each std's mean over the record's actual spread "
          f"({record['seeds']} seeds, {record['provenance']['commit']}):")
    print(f"{'':10s}" + " ".join(f"{n[:9]:>9s}" for n in record["names"]))
    for kind in ("measured", "oracle", "model"):
        mean = np.mean([r[kind] for r in runs], axis=0)
        print(f"{kind:10s}" + " ".join(f"{v:9.2f}" for v in mean / actual))


if __name__ == "__main__":
    main(sys.argv[1:])
