"""The three ways a run can end badly, each with its SPEC exit code.

The CLI turns these into one plain message on stderr and the exit code; the
Python API lets them propagate so callers can catch them.
"""


class MagyroError(Exception):
    """Base class; `exit_code` is the process exit code of SPEC section 3."""

    exit_code = 1


class InputError(MagyroError):
    """The input is unusable (missing columns, bad time, NaN, wrong unit...)."""

    exit_code = 2


class ObservabilityError(MagyroError):
    """The motion does not excite every gyro parameter (rank of the integral of M^T M < 12)."""

    exit_code = 3

    def __init__(self, message: str, report=None):
        super().__init__(message)
        self.report = report


class SolverError(MagyroError):
    """The solver failed to produce a calibration."""

    exit_code = 1
