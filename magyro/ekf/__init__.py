"""The paper's own method (Wu & Pei): the magnetometer by Gauss-Newton on the constant-norm
condition (step 1), then the gyro by an error-state EKF (step 2), with its streaming API and
the estimates over time (the paper's Fig. 3/6/7). The maths is in docs/ekf.md.

    magnetometer.py  step 1: refine_magnetometer, MagnetometerRefinement
    prior.py         the filter's starting point: eq. (13) and its inflated covariance
    scalar.py        the per-sample helpers in scalar arithmetic
    filter.py        the error-state EKF: state, propagation, measurement, update
    streaming.py     StreamingCalibrator: the filter fed sample by sample; run_filter
    lag.py           the magnetometer's lag from the filter's own likelihood (runs at a few lags, a parabola)
    uncertainty.py   the std of the reported parameters from the filter's covariance, and the lag's share
    history.py       EkfHistory (Parquet) and plot_history
    method.py        EKF, the method object: the steps in order, the Calibration assembled
"""
from magyro.ekf.history import EkfHistory, plot_history
from magyro.ekf.magnetometer import refine_magnetometer
from magyro.ekf.method import EKF
from magyro.ekf.streaming import StreamingCalibrator

__all__ = ["EKF", "EkfHistory", "StreamingCalibrator", "refine_magnetometer", "plot_history"]
