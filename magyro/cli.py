"""`magyro` on the command line: a thin layer over the Python API.

Every failure the user can fix ends with one plain message on stderr and the
SPEC exit code (2 unusable input, 3 not observable, 1 solver failed).
"""
from __future__ import annotations

import os
import sys
from pathlib import Path
from typing import Optional

import numpy as np
import typer

from . import __version__
from .errors import MagyroError

app = typer.Typer(add_completion=False, no_args_is_help=True, pretty_exceptions_enable=False, help="Gyroscope calibration via the magnetometer (Wu & Pei).")


def fail(message: str, code: int) -> None:
    typer.echo(f"magyro: {message}", err=True)
    raise typer.Exit(code)


def run_guarded(action):
    """Run `action`, turning magyro errors and I/O failures into a message and an exit code."""
    try:
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


@app.callback()
def main_options(
    version: bool = typer.Option(False, "--version", callback=version_callback, is_eager=True, help="Print the version and exit."),
):
    """Calibrate a gyroscope with the magnetometer on the same board, no turntable needed."""


@app.command()
def solve(
    session: Path = typer.Argument(..., help="Session file (.parquet or .csv, SPEC section 2)."),
    output: Optional[Path] = typer.Option(None, "-o", "--output", help="Write the calibration JSON here."),
    gyro_unit: Optional[str] = typer.Option(None, "--gyro-unit", help="rad/s or deg/s (overrides the file's metadata)."),
    mag_unit: Optional[str] = typer.Option(None, "--mag-unit", help="Magnetometer unit label, e.g. uT."),
    gyro_noise_deg_s_sqrt_hz: Optional[float] = typer.Option(None, "--gyro-noise", help="Gyro noise density, deg/s/sqrt(Hz) (default: estimated)."),
    mag_noise: Optional[float] = typer.Option(None, "--mag-noise", help="Magnetometer noise std, in its unit (default: estimated)."),
    stride: Optional[int] = typer.Option(None, "--stride", min=1, help="One attitude node every N magnetometer samples (default: ~100 nodes/s)."),
    force: bool = typer.Option(False, "--force", help="Solve even when the motion does not excite every parameter."),
    quiet: bool = typer.Option(False, "--quiet", "-q", help="No table on the terminal."),
):
    """The joint calibration: magnetometer ellipsoid, gyro K_g, bias, misalignment, field, attitude."""
    from .calibrate import Options, calibrate
    from .io import load_session, write_text_atomically

    def action():
        s = load_session(session, gyro_unit=gyro_unit, mag_unit=mag_unit)
        opts = Options(
            gyro_noise_density_rad_s_sqrt_hz=None if gyro_noise_deg_s_sqrt_hz is None else float(np.deg2rad(gyro_noise_deg_s_sqrt_hz)),
            mag_noise_std=mag_noise, stride=stride, force=force,
        )
        cal = calibrate(s, opts)
        if output is not None:
            write_text_atomically(output, cal.to_json() + "\n")
        if not quiet:
            typer.echo(cal.table())
            if output is not None:
                typer.echo(f"calibration written to {output}")

    run_guarded(action)


@app.command()
def simulate(
    problem: str = typer.Argument(..., help="Problem TOML file, or the name of one shipped in problems/ (e.g. paper-table1)."),
    output: Path = typer.Option(..., "-o", "--output", help="Session file to write (.parquet or .csv); the truth goes beside it as NAME.truth.json."),
    seed: int = typer.Option(0, "--seed", help="Noise seed (the motion is fixed by the problem)."),
):
    """A simulated session and its true parameters from a problem file."""
    from . import simulate as sim
    from .io import write_session

    def action():
        prob = sim.load_problem(problem)
        s, truth = sim.simulate(prob, seed)
        write_session(s, output)
        truth_path = truth_path_for(output)
        sim.write_truth(truth, truth_path)
        typer.echo(f"session written to {output} ({len(s.t_gyro_s)} gyro, {len(s.t_mag_s)} magnetometer samples); truth in {truth_path}")

    run_guarded(action)


def truth_path_for(session_path: Path) -> Path:
    return session_path.with_name(session_path.stem + ".truth.json")


def main():
    app()


if __name__ == "__main__":
    sys.exit(main())
