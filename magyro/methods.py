"""From a method object to the code that runs it.

A method object holds its method's knobs: `NLS` (magyro.nls.method) holds only knobs, and the joint least
squares that uses them is `magyro.nls.run.calibrate_nls`; `EKF` (magyro.ekf.method) carries its own steps as
`EKF.calibrate`. `run_method` is the one place that knows which is which, so that nothing in magyro.nls imports
back into the module of knobs it is given.
"""
from __future__ import annotations

from magyro.errors import InputError
from magyro.nls.method import NLS


def run_method(method, session, options=None):
    """Calibrate `session` with `method`: an object with its own `calibrate(session, options)` (EKF) runs it; the
    least squares' knobs (NLS) run `magyro.nls.run.calibrate_nls` (returns a `magyro.Calibration`)."""
    own = getattr(method, "calibrate", None)
    check_method_options(method, options)
    if own is not None:
        return own(session, options)
    if isinstance(method, NLS):
        from magyro.nls.run import calibrate_nls

        return calibrate_nls(session, options, method)
    raise InputError(f"{method!r} is not a calibration method; use magyro.NLS(...) or magyro.EKF(...)")


def check_method_options(method, options) -> None:
    """InputError (exit 2) for options the method cannot honour: the accelerometer is the least squares' only."""
    if options is not None and options.accelerometer and not isinstance(method, NLS):
        raise InputError("the accelerometer is calibrated by the least squares only (--method nls); the paper's "
                         "EKF calibrates the gyro and the magnetometer")


def calibrator(method):
    """`run_method` with the method fixed: a function (session, options) -> Calibration."""
    return lambda session, options=None: run_method(method, session, options)
