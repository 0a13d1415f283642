"""magyro: gyroscope calibration via the magnetometer (Wu & Pei), one CasADi/IPOPT least squares.

The public API, loaded on first use so that `import magyro` stays light and
the solve path imports neither pandas nor scipy:

    import magyro
    cal = magyro.calibrate(magyro.load_session("data/broad-02.parquet"))
    print(cal.table())
    cal.to_json("calib.json")
    omega_rad_s, field = magyro.Calibration.from_json("calib.json").apply(gyro_rad_s, mag)

The layers, along the data path: `magyro.io` (session files, importers) ->
`magyro.front` (rests, noise, ellipsoid, gate, initial estimate: what every
method shares) with `magyro.observability` (the theorem: M, the integral,
the gate, the report) -> `magyro.nls` (the joint least squares) or
`magyro.ekf` (the paper's filter) -> `magyro.result` (the typed
calibration and its checks); `magyro.studies` (simulation, Cramer-Rao bound,
Monte Carlo, dead reckoning) and `magyro.cli` sit on top.
"""
from __future__ import annotations

from magyro.lazy import lazy_exports

__version__ = "0.1.0"

_EXPORTS = {
    "load_session": "magyro.io",
    "write_session": "magyro.io",
    "Session": "magyro.session",
    "Options": "magyro.options",
    "NLS": "magyro.nls.method",
    "EKF": "magyro.ekf.method",
    "calibrate": "magyro.api",
    "observe": "magyro.api",
    "Calibration": "magyro.result.calibration",
    "MagyroError": "magyro.errors",
    "InputError": "magyro.errors",
    "ObservabilityError": "magyro.errors",
    "SolverError": "magyro.errors",
}
__all__ = ["__version__", *_EXPORTS]


__getattr__, __dir__ = lazy_exports(__name__, _EXPORTS)
