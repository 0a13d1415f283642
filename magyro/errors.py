"""The three ways a run can end badly, each with its exit code (docs/spec.md section 3).

The CLI turns these into one plain message on stderr and the exit code; the
Python API lets them propagate so callers can catch them. `one_line` puts any
exception's message on one line, for such messages and for logs of failed runs.
"""


class MagyroError(Exception):
    """Base class; `exit_code` is the process exit code of docs/spec.md section 3."""

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


class AccelerometerRefused(ObservabilityError):
    """The accelerometer cannot be calibrated: its solved std is past the refusal bound, or the hand accelerated the
    device too much for gravity to be read (`nls.accelerometer.hand_too_big`)."""


class SolverError(MagyroError):
    """The solver failed to produce a calibration."""

    exit_code = 1


def one_line(exc: BaseException, limit: int | None = 200) -> str:
    """An exception's message on one line (cut to `limit` characters; None keeps it whole)."""
    text = " ".join(str(exc).split()) or type(exc).__name__
    return text if limit is None else text[:limit]
