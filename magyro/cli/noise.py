"""`magyro noise`: the gyro's and the accelerometer's noise from the Allan deviation of a still recording
(magyro.noise_allan)."""
from __future__ import annotations

from pathlib import Path
from typing import Optional

import typer

from magyro.cli.common import run_guarded


def noise_command(
    session: Path = typer.Argument(..., metavar="SESSION", readable=False, help="Session file (.parquet or .csv, docs/spec.md section 2): a still recording, or any recording with rests at its ends."),
    output: Optional[Path] = typer.Option(None, "-o", "--output", readable=False, help="Write the noise JSON here (schema magyro.noise/1), for solve --noise and export --format kalibr --noise."),
    plot: Optional[Path] = typer.Option(None, "--plot", readable=False, help="Plot the Allan deviations and the fitted slopes (needs matplotlib: pip install '.[plot]' in a clone, 'magyro[plot]' from PyPI)."),
    still: bool = typer.Option(False, "--still", help="The whole recording is still: use all of it (default: the rests at its ends, as magyro.front.rests finds them)."),
    white_only: bool = typer.Option(False, "--white-only", help="Measure the white noise only (a short rest: BROAD's are 3-18 s); without, the bias instability and the random walk are required too, which need about 2 h still (exit 3 when shorter)."),
    gyro_unit: Optional[str] = typer.Option(None, "--gyro-unit", help="rad/s or deg/s (overrides the file's metadata)."),
    quiet: bool = typer.Option(False, "--quiet", "-q", help="No table on the terminal."),
):
    """The noise Kalibr needs, from the Allan deviation (needs allantools: pip install '.[noise]' in a clone, 'magyro[noise]' from PyPI): per axis the white noise (gyro rad/s/sqrt(Hz), accelerometer m/s^2/sqrt(Hz); the -1/2 slope at tau = 1 s), the bias instability (the flat minimum / 0.664) and the random walk (the +1/2 slope at tau = 3 s), each with its std from the number of clusters."""
    from magyro.io import check_outputs, load_session
    from magyro.noise_allan import require_allantools, session_noise

    def action():
        check_outputs([session], [output, plot])
        require_allantools()
        if plot is not None:
            from magyro.observability.plot import require_matplotlib

            require_matplotlib()
        report = session_noise(load_session(session, gyro_unit=gyro_unit), whole=still, white_only=white_only)
        if output is not None:
            report.to_json(output)
        if plot is not None:
            from magyro.noise_allan import write_plot

            write_plot(report, plot)
        if not quiet:
            typer.echo(report.table())
            for path, what in ((output, "noise"), (plot, "Allan deviation plot")):
                if path is not None:
                    typer.echo(f"{what} written to {path}")

    run_guarded(action, progress=not quiet)
