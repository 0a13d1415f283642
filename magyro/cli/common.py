"""What every command of `magyro` shares: one plain message and the exit code of docs/spec.md section 3
for every failure the user can fix (`fail`, `run_guarded`), and `--version`."""
from __future__ import annotations

import os

import typer

from magyro import __version__
from magyro.errors import MagyroError


def fail(message: str, code: int) -> None:
    from magyro.text import escaped   # a message may quote input: no control or bidi character reaches the terminal

    typer.echo(f"magyro: {escaped(message, keep_lines=True)}", err=True)
    raise typer.Exit(code)


def run_guarded(action, progress: bool = True):
    """Run `action`, turning magyro errors and I/O failures into a message and an exit code; its steps show as a
    live line on stderr when that is a terminal and `progress` (off with -q)."""
    from magyro.progress import showing

    try:
        with showing(enabled=progress):
            return action()
    except MagyroError as e:
        fail(str(e), e.exit_code)
    except OSError as e:
        fail(f"cannot write output: {e}", 1)
    except Exception as e:  # a bug: still one line, not a traceback, unless debugging
        if os.environ.get("MAGYRO_DEBUG"):
            raise
        fail(f"internal error ({type(e).__name__}: {e}); rerun with MAGYRO_DEBUG=1 for a traceback and please report it", 1)


def version_callback(value: bool):
    if value:
        typer.echo(f"magyro {__version__}")
        raise typer.Exit(0)


# the accuracy targets (magyro.targets), the same options on observe, watch, report and batch
TARGETS_OPTION = typer.Option(
    None, "--targets", help="Accuracy targets: a TOML file with a 'targets' table (docs/targets-example.toml), the same file for "
    "observe, watch, report and batch. Without: the defaults (1000 ppm, 0.1 deg, 0.01 deg/s, 0.1 deg).")
TARGET_SCALE_OPTION = typer.Option(None, "--target-scale-ppm", min=0.0, help="One-sigma target of the gyro scale factors (K_g diagonal), ppm (overrides --targets; default 1000).")
TARGET_NONORTH_OPTION = typer.Option(None, "--target-nonorth-deg", min=0.0, help="... of the non-orthogonality (K_g off-diagonal), deg (default 0.1).")
TARGET_BIAS_OPTION = typer.Option(None, "--target-bias-deg-s", min=0.0, help="... of the gyro bias, deg/s (default 0.01).")
TARGET_MISALIGNMENT_OPTION = typer.Option(None, "--target-misalignment-deg", min=0.0, help="... of the gyro-magnetometer misalignment, deg (default 0.1).")
