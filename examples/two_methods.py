"""The same recording calibrated by the joint least squares and by the paper's EKF, against the truth.

The problem is declared once (the session and the physics `Options`); the method is
chosen separately, with its own knobs.

    python examples/two_methods.py
"""
import numpy as np

import magyro
from magyro.studies.scenario import load_problem
from magyro.studies.simulate import simulate

problem = load_problem("phone-module")
session, truth = simulate(problem, seed=3)
options = magyro.Options()
true_bias = np.array(truth["gyro"]["bias_deg_s"])
for method in (magyro.NLS(), magyro.EKF()):
    cal = magyro.calibrate(session, options, method=method)
    error = cal.bias_deg_s - true_bias
    print(f"{method.name}: bias error (deg/s) {np.round(error, 4)}, reported std {np.round(cal.std.bias_deg_s, 4)}, "
          f"|error|/std max {np.max(np.abs(error) / cal.std.bias_deg_s):.2f}")
