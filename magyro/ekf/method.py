"""The paper's two-step method as a method object, `EKF`: the steps in order, and the result assembled.

    magyro.calibrate(session, options, method=EKF())
    cal, history = EKF().calibrate_with_history(session, options)

    1. the shared front end (`magyro.front.prepare`): rests, noise, ellipsoid, unit check, gate
    2. step 1, the magnetometer: Gauss-Newton on the constant-norm condition,
       from the ellipsoid (`magyro.ekf.magnetometer`)
    3. the filter's prior: eq. (13) on the calibrated field (`magyro.ekf.prior`)
    4. step 2, the error-state EKF fed the whole session in time order
       (`magyro.ekf.streaming`, `magyro.ekf.filter`)
    5. the result: the same Calibration as the joint least squares
       (solver.method = "ekf"), std from the final covariance of
       [vec K, eps, R, h, m^i] through `result.reported_vector` (central
       differences, like the least squares' `magyro.nls.information.propagate`:
       `magyro.ekf.uncertainty`), and the estimates over time
       (`magyro.ekf.history`, the paper's Fig. 3/6/7).
"""
from __future__ import annotations

import math
import time
from dataclasses import dataclass, replace
from typing import ClassVar

import numpy as np

from magyro.ekf.history import HISTORY_ROWS, EkfHistory
from magyro.ekf.magnetometer import known_magnetometer, refine_magnetometer
from magyro.ekf.prior import PRIOR_INFLATION, Initial, initial_estimate
from magyro.ekf.streaming import StreamingCalibrator, run_filter
from magyro.ekf.uncertainty import reported_covariance
from magyro.errors import InputError
from magyro.nls.information import predicted_std
from magyro.observability.gate import accuracy_gate, needs_accuracy_check, unexcited_directions
from magyro.front.prepare import Prepared, prepare
from magyro.options import Options
from magyro.result.calibration import Calibration
from magyro.result.fit import FilterFit
from magyro.result.parts import Excitation, NoiseReport, SolverReport
from magyro.result.reported import qr_split, std_from_covariance
from magyro.session import Session


@dataclass(frozen=True)
class EKF:
    """The paper's method: magnetometer first (ellipsoid + Gauss-Newton), then the gyro by an error-state EKF.

    Noise levels, rest trimming and the observability gate are those of the
    shared front end (`magyro.front.prepare`: `Options.force`, the noise
    options and `trim_rests` apply; ObservabilityError when the motion does
    not excite every parameter). A fixed `Options.time_offset_s`
    (magnetometer lag) shifts the magnetometer stamps; the EKF does not
    estimate the lag (`Options.estimate_time_offset` is ignored).

    magnetometer=(R, h): take this magnetometer calibration as exact and skip
    step 1 (the paper's Table I simulation assumes a calibrated magnetometer).
    mag_bias_correction: step 1 on the noise-corrected score (default) or the
    paper's plain least squares (see `refine_magnetometer`).
    consider_magnetometer: carry step 1's uncertainty into the std of the gyro
    parameters (Schmidt-Kalman consider states); off, the std is the filter's
    alone, as in the paper, which treats the calibrated magnetometer as exact.
    history_rows: about how many instants the history keeps.
    prior_inflation: the eq. (13) std is multiplied by this for the filter's prior.
    """

    name: ClassVar[str] = "ekf"
    magnetometer: tuple | None = None      # (R, h) taken as exact: skip step 1
    mag_bias_correction: bool = True
    consider_magnetometer: bool = True
    history_rows: int = HISTORY_ROWS
    prior_inflation: float = PRIOR_INFLATION

    def calibrate(self, session: Session, options: Options | None = None) -> Calibration:
        """Calibrate gyro and magnetometer from one session (returns a `magyro.Calibration`)."""
        return self.calibrate_with_history(session, options)[0]

    def calibrate_with_history(self, session: Session, options: Options | None = None) -> tuple[Calibration, EkfHistory]:
        """(Calibration, EkfHistory): the calibration and the filter's estimates over time."""
        options = options or Options()
        t_start = time.perf_counter()
        prep = prepare(session, options)
        gate_warnings = (accuracy_gate(predicted_std(prep, options), options)   # the same gate as the NLS's
                         if needs_accuracy_check(prep.analysis) else [])
        s = prep.session
        tau = float(options.time_offset_s or 0.0)
        if tau:
            s = replace(s, t_mag_s=s.t_mag_s - tau)
        if self.magnetometer is not None:
            ref = known_magnetometer(*self.magnetometer)
        else:
            ref = refine_magnetometer(s.mag, prep.fit.R, prep.fit.h, prep.sigma_mag if self.mag_bias_correction else None)
        init = initial_estimate(s, ref, self.prior_inflation, unexcited_directions(prep.analysis))
        stride = max(1, int(math.ceil(len(s.t_mag_s) / max(self.history_rows - 2, 1))))
        cov_Rh = ref.covariance if (self.consider_magnetometer and self.magnetometer is None) else None
        filt = StreamingCalibrator(ref.R, ref.h, init.K0, init.eps0, None, prep.gyro_density, prep.sigma_mag,
                                   P0=init.P0, cov_Rh=cov_Rh, history_stride=stride)
        t_filter = time.perf_counter()
        run_filter(s, filt)
        filter_s = time.perf_counter() - t_filter
        if not filt.started or filt.mag_updates == 0:
            raise InputError("the EKF got no magnetometer sample inside the gyro's time span")
        history = filt.history()
        cal = assemble(filt, prep, init, filter_s, time.perf_counter() - t_start, tau)
        cal.warnings.extend(gate_warnings)
        return cal, history


def assemble(filt: StreamingCalibrator, prep: Prepared, init: Initial, filter_s: float, total_s: float,
             tau: float) -> Calibration:
    """The Calibration of the filter's final state, with the same fields as the joint least squares'."""
    K, eps, m = filt.K.copy(), filt.eps.copy(), filt.m.copy()
    C, Kg = qr_split(K)
    ref = init.refinement
    std = std_from_covariance(reported_covariance(K, eps, ref.R, ref.h, m, filt.input_covariance(ref.covariance), C))
    n_samples = filt.gyro_samples + filt.mag_updates
    return Calibration(
        K_g=Kg, bias_rad_s=C.T @ eps, K=K, eps_rad_s=eps, C_b_m=C, R=ref.R, h=ref.h,
        mag_unit=prep.session.mag_unit, field_i=m, std=std,
        observability=Excitation.of(prep.analysis),
        solver=SolverReport("ekf", "done", int(n_samples), float(filter_s), float(total_s), {
            "gyro_samples": int(filt.gyro_samples), "mag_updates": int(filt.mag_updates),
            "skipped_mag": int(filt.skipped_mag),
            "samples_per_second": float(n_samples / filter_s) if filter_s > 0 else None,
            "state_dimension": int(filt.n), "consider_magnetometer": bool(filt.consider),
            "magnetometer_newton_iterations": int(ref.iterations),
            "magnetometer_bias_corrected": bool(ref.bias_corrected)}),
        noise=NoiseReport(prep.gyro_density, prep.sigma_mag),
        fit=FilterFit(float(ref.rms_norm_error), float(ref.rms_norm_error_initial),
                      float(filt.nis_sum / max(filt.mag_updates, 1)), tuple(np.sqrt(np.diag(init.P0)).tolist())),
        time_offset_s=tau,
    )
