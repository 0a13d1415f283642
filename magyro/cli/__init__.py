"""`magyro` on the command line: a thin layer over the Python API.

One module per command family, each command a plain function registered here (in the order `--help` lists them):
  solve       magyro.cli.solve        the joint calibration
  simulate, montecarlo, plan          magyro.cli.simulation
  batch       magyro.cli.fleet        many devices against limits
  import ...  magyro.cli.importing    BROAD, CSV, ULog, ROS bag recordings as session files
  validate, apply, export, report     magyro.cli.results
  observe, check                      magyro.cli.recording
  watch       magyro.cli.live         (and simulate --stream)
  noise       magyro.cli.noise        the Allan deviation of a still recording (Kalibr's noise numbers)
Every failure the user can fix ends with one plain message on stderr and the exit code of docs/spec.md
section 3 (2 unusable input, 3 not observable, 1 solver failed): magyro.cli.common.
"""
from __future__ import annotations

import os
import sys

# one BLAS thread: the products here are small, and on a busy 2-core machine OpenBLAS's
# threads made a 12-column least squares 100x slower (set before numpy is imported)
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import typer  # noqa: E402

from magyro.cli.common import Command, as_written, fail, run_guarded, version_callback  # noqa: E402,F401  (fail, run_guarded: public)
from magyro.cli.fleet import batch  # noqa: E402
from magyro.cli.importing import import_app  # noqa: E402
from magyro.cli.live import watch_command  # noqa: E402
from magyro.cli.noise import noise_command  # noqa: E402
from magyro.cli.recording import check_command, observe_command  # noqa: E402
from magyro.cli.results import apply_command, export_command, report_command, validate_command  # noqa: E402
from magyro.cli.simulation import montecarlo, plan_command, simulate  # noqa: E402
from magyro.cli.solve import solve  # noqa: E402

def _deprecations_on_one_line() -> None:
    """An old spelling still read (magyro.targets.DeprecatedKeyWarning) shown as one plain line on stderr; only while
    the command runs (`main`): importing magyro.cli changes nothing of the caller's warnings."""
    import warnings

    from magyro.targets import DeprecatedKeyWarning

    shown = warnings.showwarning

    def show(message, category, filename, lineno, file=None, line=None):
        if isinstance(category, type) and issubclass(category, DeprecatedKeyWarning):
            sys.stderr.write(f"magyro: {message}\n")
        else:
            shown(message, category, filename, lineno, file, line)

    warnings.showwarning = show


app = typer.Typer(add_completion=False, no_args_is_help=True, pretty_exceptions_enable=False, help="Gyroscope calibration via the magnetometer (Wu & Pei), with the accelerometer in the same least squares when the session has one.")


@app.callback()
def main_options(
    version: bool = typer.Option(False, "--version", callback=version_callback, is_eager=True, help="Print the version and exit."),
):
    """Calibrate a gyroscope with the magnetometer on the same board (and the accelerometer, when the session has one), no turntable needed."""


app.command(cls=Command)(as_written(solve))
app.command(cls=Command)(as_written(simulate))
app.command(cls=Command)(as_written(montecarlo))
app.command(cls=Command)(as_written(batch))
app.add_typer(import_app, name="import")
app.command("validate", cls=Command)(as_written(validate_command))
app.command("observe", cls=Command)(as_written(observe_command))
app.command("check", cls=Command)(as_written(check_command))
app.command("apply", cls=Command)(as_written(apply_command))
app.command("export", cls=Command)(as_written(export_command))
app.command("report", cls=Command)(as_written(report_command))
app.command("watch", cls=Command)(as_written(watch_command))
app.command("plan", cls=Command)(as_written(plan_command))
app.command("noise", cls=Command)(as_written(noise_command))


def main():
    import warnings

    with warnings.catch_warnings():   # the one-line deprecations while the command runs, the caller's settings after
        _deprecations_on_one_line()
        app()


if __name__ == "__main__":
    sys.exit(main())
