"""From a method object to the code that runs it.

A method object holds its method's knobs: `NLS` (magyro.nls.method) holds only knobs, and the joint least
squares that uses them is `magyro.nls.run.calibrate_nls`; `EKF` (magyro.ekf.method) carries its own steps as
`EKF.calibrate`. `run_method` is the one place that knows which is which, so that nothing in magyro.nls imports
back into the module of knobs it is given.
"""
from __future__ import annotations

from dataclasses import replace

from magyro.errors import InputError
from magyro.nls.method import NLS


def run_method(method, session, options=None):
    """Calibrate `session` with `method`: an object with its own `calibrate(session, options)` (EKF) runs it; the
    least squares' knobs (NLS) run `magyro.nls.run.calibrate_nls` (returns a `magyro.Calibration`)."""
    own = getattr(method, "calibrate", None)
    check_method_options(method, options, session)
    if own is not None:
        return own(session, options)
    if isinstance(method, NLS):
        from magyro.nls.run import calibrate_nls

        return calibrate_nls(session, options, method)
    raise InputError(f"{method!r} is not a calibration method; use magyro.NLS(...) or magyro.EKF(...)")


def check_method_options(method, options, session=None) -> None:
    """InputError (exit 2) for options the method cannot honour: the accelerometer is the least squares' only, and
    needs the session's accelerometer (said before any work: a recording refused for its motion would otherwise
    hide that the accelerometer is missing until the motion is fixed)."""
    if options is None or not options.accelerometer:
        return
    if not isinstance(method, NLS):
        raise InputError("the accelerometer is calibrated by the least squares only (--method nls); the paper's "
                         "EKF calibrates the gyro and the magnetometer")
    if session is not None and (session.acc_m_s2 is None or len(session.acc_m_s2) < 2):
        note = (session.metadata or {}).get("sensor_note", "")
        why = note[note.find("no accelerometer: ") + len("no accelerometer: "):] if "no accelerometer: " in note else ""
        raise InputError("--accelerometer: the session has no accelerometer (columns ax ay az, m/s^2)"
                         + (f": {why}" if why else "; import it with its accelerometer") + ", or solve without "
                         "--accelerometer")


def with_accelerometer_decided(method, options, session):
    """`options` with `accelerometer` decided when it is None (the default): the least squares calibrates the
    accelerometer whenever the session has one (ax ay az); the EKF never does."""
    if options.accelerometer is not None:
        return options
    has = session.acc_m_s2 is not None and len(session.acc_m_s2) >= 2
    return replace(options, accelerometer=bool(has and isinstance(method, NLS)))


def accelerometer_not_calibrated(method, options, session) -> str | None:
    """The warning for a session with an accelerometer that the method leaves out without being asked to (the EKF
    calibrates the gyro and the magnetometer only), or None: `--no-accelerometer` asked for it, or the method does
    calibrate it."""
    has = session.acc_m_s2 is not None and len(session.acc_m_s2) >= 2
    if not has or isinstance(method, NLS) or (options is not None and options.accelerometer is False):
        return None
    return (f"accelerometer not calibrated: the session has one, but the {getattr(method, 'name', 'chosen')} method "
            "(--method ekf, the paper's two steps) calibrates the gyro and the magnetometer only; the default method, "
            "the least squares (--method nls), calibrates the accelerometer in the same solve")


def calibrator(method):
    """`run_method` with the method fixed: a function (session, options) -> Calibration."""
    return lambda session, options=None: run_method(method, session, options)
