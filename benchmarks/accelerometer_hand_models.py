"""How close to the Cramer-Rao bound can a least squares come that models the hand? (issue 26: std/CRLB <= 1.1)

    python benchmarks/accelerometer_hand_models.py [--problem paper-table1-acc] [--out RECORD]

On one simulated session (seed 0, the truth's attitude), the accelerometer's interval means are weighted by the
inverse of an assumed covariance, white noise + a model of the hand's acceleration; the gyro, magnetometer and rest
residuals as the solve has them. The estimator's covariance under the TRUE hand (the simulator's ensemble,
`studies.crlb_accelerometer.hand_covariance`) is the sandwich F_m^-1 (F0 + J^T S_m^-1 (white + hand) S_m^-1 J) F_m^-1,
F_m = F0 + J^T S_m^-1 J, the attitude states marginalised. Printed per model: the accelerometer's std over its bound
(median and largest of its 12 reported parameters), K_a's diagonal std, the largest ratio of the gyro's std with
the accelerometer to without, and the std the model would itself report (F_m^-1) over the one it has (1: honest).

The models, each a Gaussian process on the hand's world-frame acceleration (isotropic), read by each interval's mean:
* `independent`: every interval its own variance, the hand's true variance there; what the solve's weights count
  (before its correlation factor; `crlb_accelerometer.independent_weights_covariance`);
* `velocity OU`: the hand's velocity an Ornstein-Uhlenbeck process (std sigma_v, time constant tau): as states, 3 per
  node, the problem stays banded;
* `position oscillator`: the position a damped second-order process (resonance f0, damping 0.7, std sigma_p): as
  states (position and velocity), 6 per node, banded;
* `true shape x s`: the ensemble's own covariance scaled by s: its shape, a wrong size.
The bound is the last with s = 1. The sandwich needs no solve: the numbers are those of the estimators' dense
equivalents, the states marginalised.
"""
from __future__ import annotations

import argparse
import dataclasses
import sys

import numpy as np

from machine_load import measured_at, write_record

OSCILLATOR_DAMPING = 0.7
MODELS = ([("velocity OU", {"sigma_v_m_s": s, "tau_s": t}) for s, t in ((0.01, 1.0), (0.03, 0.3), (0.03, 1.0), (0.1, 0.3))]
          + [("position oscillator", {"f0_hz": f, "sigma_p_m": p}) for f, p in ((0.1, 0.02), (0.2, 0.02), (0.3, 0.02),
                                                                              (0.2, 0.05))]
          + [("true shape", {"scale": s}) for s in (0.5, 2.0)])


def ou_velocity_autocovariance(sigma_v_m_s: float, tau_s: float):
    return lambda lag_s: sigma_v_m_s ** 2 * np.exp(-np.abs(lag_s) / tau_s)


def oscillator_velocity_autocovariance(f0_hz: float, sigma_p_m: float, damping: float = OSCILLATOR_DAMPING):
    """R_v(lag) of the velocity of a position with spectrum 1 / ((w0^2 - w^2)^2 + (2 zeta w0 w)^2), variance sigma_p^2:
    the cosine transform of w^2 S_p, tabulated to 120 s."""
    f = np.linspace(0.0, 20.0 * f0_hz + 5.0, 20001)
    w, w0 = 2 * np.pi * f, 2 * np.pi * f0_hz
    S_p = 1.0 / ((w0 ** 2 - w ** 2) ** 2 + (2 * damping * w0 * w) ** 2)
    S_p *= sigma_p_m ** 2 / np.trapezoid(S_p, f)
    lags = np.linspace(0.0, 120.0, 12001)
    R = np.concatenate([np.trapezoid(w ** 2 * S_p * np.cos(w * lags[i:i + 400, None]), f, axis=1)
                        for i in range(0, len(lags), 400)])
    return lambda lag_s: np.interp(np.abs(lag_s), lags, R, right=0.0)


class Setting:
    """One simulated session's joint problem at the truth: what every model's sandwich needs."""

    def __init__(self, problem_name: str):
        from magyro.nls.accelerometer import segment_start_times
        from magyro.nls.method import NLS
        from magyro.options import Options
        from magyro.result.reported import qr_split
        from magyro.studies import crlb_accelerometer as bound
        from magyro.studies.motion import truth_body_attitude
        from magyro.studies.scenario import load_problem
        from magyro.studies.simulate import simulate

        self.problem = problem = load_problem(problem_name)
        session, _ = simulate(problem, 0)
        jp, lin, s, sigma = bound.truth_accelerometer_problem(problem, session, Options(accelerometer=True), NLS())
        start = lin.accelerometer

        def params(weight):
            return jp.parameters(lin, s.mag, problem.mag_noise_std, problem.gyro_noise_density_rad_s_sqrt_hz,
                                 s.t_gyro_s, s.gyro_rad_s, s.t_mag_s, problem.mag_time_offset_s, weight)

        no_rests = dataclasses.replace(lin, accelerometer=dataclasses.replace(start, rests=[]))
        self.F_without = bound.dense_information(jp, jp.parameters(
            no_rests, s.mag, problem.mag_noise_std, problem.gyro_noise_density_rad_s_sqrt_hz, s.t_gyro_s, s.gyro_rad_s,
            s.t_mag_s, problem.mag_time_offset_s, np.zeros(jp.n_int)))    # the gyro and the magnetometer alone
        used_int = start.count > 0
        used = np.repeat(used_int, 3)
        self.jp, self.F0 = jp, bound.dense_information(jp, params(np.zeros(jp.n_int)))
        p_unit = params(np.ones(jp.n_int))
        self.g = jp.globals_of(p_unit)
        self.C0 = qr_split(lin.K0)[0]
        self.J = bound.accelerometer_jacobian_rows(jp, p_unit)[used]
        self.white = np.repeat(sigma ** 2 * np.sum(start.share ** 2, axis=1), 3)[used]
        self.hand = bound.hand_covariance(problem, start)[np.ix_(used, used)]
        # each interval mean's reading of a world acceleration, and its nodes' times
        t = segment_start_times(jp.grid)
        acc = problem.accelerometer
        L = np.linalg.solve(acc.K_a, acc.C_b_a) @ np.swapaxes(truth_body_attitude(problem, t.ravel()), -1, -2)
        self.readout = np.einsum("ks,ksij->kij", start.share, L.reshape(*t.shape, 3, 3))[used_int]
        nodes = jp.grid.t_node_s
        self.t0_s, self.t1_s = nodes[:-1][used_int], nodes[1:][used_int]

    def model_covariance(self, velocity_autocovariance) -> np.ndarray:
        """The interval means' hand covariance when the world velocity has autocovariance R_v on each axis: the
        interval's mean acceleration is its velocity change over its length."""
        R, a, b = velocity_autocovariance, self.t0_s, self.t1_s
        C = (R(b[:, None] - b[None]) - R(b[:, None] - a[None]) - R(a[:, None] - b[None]) + R(a[:, None] - a[None]))
        C /= (b - a)[:, None] * (b - a)[None]
        m = len(a)
        return np.einsum("kab,kl,lcb->kalc", self.readout, C, self.readout).reshape(3 * m, 3 * m)

    def covariances(self, assumed: np.ndarray | None) -> tuple[np.ndarray, np.ndarray]:
        """(actual, model-reported) corrections' covariance of the estimator weighting by `assumed` (None: every
        interval independent with the true variance, as `independent_weights_covariance`)."""
        from magyro.studies.crlb_accelerometer import independent_weights_covariance

        n = self.jp.n_theta
        if assumed is None:
            own = np.repeat(np.diag(self.hand).reshape(-1, 3).mean(axis=1), 3)
            JW = self.J / (self.white + own)[:, None]
            return (independent_weights_covariance(self.F0, self.J, self.white, self.hand, n),
                    np.linalg.inv(self.F0 + self.J.T @ JW)[:n, :n])
        chol = np.linalg.cholesky(np.diag(self.white) + assumed)
        Jw = np.linalg.solve(chol, self.J)
        F_inv = np.linalg.inv(self.F0 + Jw.T @ Jw)
        SJ = np.linalg.solve(chol.T, Jw)
        actual = F_inv @ (self.F0 + SJ.T @ (np.diag(self.white) + self.hand) @ SJ) @ F_inv
        return actual[:n, :n], F_inv[:n, :n]

    def without_accelerometer(self) -> np.ndarray:
        """The corrections' covariance of the gyro and the magnetometer alone (no interval mean, no rest), the
        accelerometer's corrections (the last N_ACC_THETA, unknown then) left at zero."""
        from magyro.nls.interval import N_ACC_THETA

        n = self.jp.n_theta
        keep = np.r_[0: n - N_ACC_THETA, n: len(self.F_without)]
        cov = np.zeros((n, n))
        cov[: n - N_ACC_THETA, : n - N_ACC_THETA] = np.linalg.inv(self.F_without[np.ix_(keep, keep)])[: n - N_ACC_THETA, : n - N_ACC_THETA]
        return cov

    def reported_std(self, cov: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(the accelerometer's 12 reported std, the gyro's 12)."""
        from magyro.nls.accelerometer import UPPER, accelerometer_result
        from magyro.nls.information import propagate

        acc = accelerometer_result(self.jp, np.zeros(self.jp.n_theta), self.g, cov)
        gyro = np.sqrt(np.diag(propagate(self.jp, np.zeros(self.jp.n_theta), self.g, cov, self.C0)))[:12]
        return np.concatenate([[acc.std_K_a[i, j] for i, j in UPPER], acc.std_bias_m_s2, acc.std_misalignment_deg]), gyro


def assumed_covariance(setting: Setting, kind: str, knobs: dict) -> np.ndarray | None:
    if kind == "independent":
        return None
    if kind == "velocity OU":
        return setting.model_covariance(ou_velocity_autocovariance(**knobs))
    if kind == "position oscillator":
        return setting.model_covariance(oscillator_velocity_autocovariance(**knobs))
    return knobs["scale"] * setting.hand


def study(problem_name: str) -> dict:
    setting = Setting(problem_name)
    bound_acc, bound_gyro = setting.reported_std(setting.covariances(setting.hand)[0])
    n = setting.jp.n_theta
    without_gyro = setting.reported_std(setting.without_accelerometer())[1]
    rows = []
    for kind, knobs in [("independent", {})] + MODELS:
        actual, model = setting.covariances(assumed_covariance(setting, kind, knobs))
        acc, gyro = setting.reported_std(actual)
        acc_model, gyro_model = setting.reported_std(model)
        over = acc / bound_acc
        rows.append({"model": kind, "knobs": knobs, "acc_over_crlb_median": float(np.median(over)),
                     "acc_over_crlb_max": float(over.max()), "K_a_diag_std_ppm": (1e6 * acc[[0, 3, 5]]).tolist(),
                     "gyro_with_over_without_max": float(np.max(gyro / without_gyro)),
                     "acc_model_over_actual": [float(np.min(acc_model / acc)), float(np.max(acc_model / acc))],
                     "gyro_model_over_actual": [float(np.min(gyro_model / gyro)), float(np.max(gyro_model / gyro))]})
    return {"problem": problem_name, "hand_rms_m_s2": float(np.sqrt(np.mean(np.diag(setting.hand)))),
            "crlb_K_a_diag_ppm": (1e6 * bound_acc[[0, 3, 5]]).tolist(), "rows": rows}


def print_study(r: dict) -> None:
    print(f"{r['problem']}: the hand {r['hand_rms_m_s2']:.3f} m/s^2 RMS per axis in an interval mean; the bound's K_a "
          f"diagonal std {', '.join(f'{v:.0f}' for v in r['crlb_K_a_diag_ppm'])} ppm")
    print(f"{'model':21s} {'knobs':28s} {'acc/CRLB med':>12s} {'max':>6s} {'K_a diag std, ppm':>18s} "
          f"{'gyro with/without':>17s} {'acc model/actual':>16s} {'gyro model/actual':>17s}")
    for row in r["rows"]:
        knobs = " ".join(f"{k.split('_')[0]}={v:g}" for k, v in row["knobs"].items())
        print(f"{row['model']:21s} {knobs:28s} {row['acc_over_crlb_median']:12.2f} {row['acc_over_crlb_max']:6.2f} "
              f"{' '.join(f'{v:5.0f}' for v in row['K_a_diag_std_ppm']):>18s} {row['gyro_with_over_without_max']:17.2f} "
              f"{'%.2f-%.2f' % tuple(row['acc_model_over_actual']):>16s} {'%.2f-%.2f' % tuple(row['gyro_model_over_actual']):>17s}")


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--problem", action="append", help="problem(s); default paper-table1-acc and phone-module-acc")
    ap.add_argument("--out", help="write the record here (JSON)")
    args = ap.parse_args(argv)
    records = []
    for name in args.problem or ["paper-table1-acc", "phone-module-acc"]:
        records.append(study(name))
        print_study(records[-1])
        print()
    if args.out:
        command = "python benchmarks/accelerometer_hand_models.py " + " ".join(sys.argv[1:])
        write_record(args.out, {"studies": records, "provenance": measured_at(command.strip())})


if __name__ == "__main__":
    main()
