"""Calibrate a real recording, save the result, read it back and apply it (docs/using-the-result.md's API example).

    python examples/calibrate_a_recording.py [SESSION] [OUTPUT_DIR]
"""
import sys
from pathlib import Path

import numpy as np

import magyro

here = Path(__file__).resolve().parent
session_path = Path(sys.argv[1]) if len(sys.argv) > 1 else here.parent / "data" / "broad-02.parquet"
out_dir = Path(sys.argv[2]) if len(sys.argv) > 2 else Path(".")

session = magyro.load_session(session_path)
cal = magyro.calibrate(session)                       # the joint least squares, default options
print(cal.table())
print("bias (deg/s):", np.round(cal.bias_deg_s, 4), "+/-", np.round(cal.std.bias_deg_s, 4))

path = out_dir / "calib.json"
cal.to_json(path)                                     # written whole or not at all
again = magyro.Calibration.from_json(path)            # refuses anything that is not a calibration

# the model: omega = K_g y + eps_b (rad/s, gyro frame); field = R (y_m - h), unit norm
omega_rad_s, field = again.apply(session.gyro_rad_s, session.mag)
print(f"corrected {len(omega_rad_s)} gyro samples; calibrated field norm "
      f"{np.mean(np.linalg.norm(field, axis=1)):.3f} +/- {np.std(np.linalg.norm(field, axis=1)):.3f}")
