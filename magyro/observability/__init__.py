"""The paper's observability theorem (Wu & Pei, Section III.B), evaluated on a session.

The 12 gyro parameters theta = [vec K; eps] enter the field's motion linearly,
d m^m/dt = M theta with M = [y_g^T (x) (m^m x), m^m x] (eq. 10); they are
observable when the integral of M^T M over the session is nonsingular (eq. 11).
With noisy data the rank is counted against what sensor noise alone puts in
each direction. docs/observability.md derives it all.

    matrix      M, its integral and the cumulative integral (also eq. 13's rows)
    gate        rank against the noise floor: `analyse` -> `ObservabilityAnalysis`;
                the gate of `magyro solve` (on the solve path: numpy only)
    excitation  `observe`: the report of `magyro observe` (timeline, coverage,
                predicted accuracy, verdict); no solve
    advice      weak directions in parameter names, and the motion that excites them
    report      `ObservabilityReport`, `Targets`: the report as data, JSON and table
    gravity     with an accelerometer: what its 12 parameters need, and gravity as a second reference
                vector beside the field (shown beside the verdict, never in it)
    plot        the report's figure (matplotlib)

`analyse` and `ObservabilityAnalysis` are imported with the package; `observe`,
`ObservabilityReport` and `Targets` on first use: `observe` needs the least
squares (for the prediction), which itself imports the gate, and the solve path
needs none of the report.
"""
from __future__ import annotations

from magyro.lazy import lazy_exports
from magyro.observability.gate import ObservabilityAnalysis, analyse

_LAZY = {
    "observe": "magyro.observability.excitation",
    "ObservabilityReport": "magyro.observability.report",
    "Targets": "magyro.targets",
}
__all__ = ["analyse", "ObservabilityAnalysis", *_LAZY]


__getattr__, __dir__ = lazy_exports(__name__, _LAZY)
