"""`magyro watch SOURCE` and `magyro simulate PROBLEM --stream` on the command line, over magyro.live.

magyro.cli registers `watch_command`; `magyro simulate` (magyro.cli.simulation) calls
`simulate_stream(problem, speed, seed)` when given --stream.
"""
from __future__ import annotations

import sys
from pathlib import Path
from typing import Optional

import typer

from magyro.cli.common import (TARGET_BIAS_OPTION, TARGET_MISALIGNMENT_OPTION, TARGET_NONORTH_OPTION,
                               TARGET_SCALE_OPTION, TARGETS_OPTION, fail, run_guarded)


def watch_command(
    source: str = typer.Argument(..., metavar="SOURCE", help="'-' for standard input, a serial device (/dev/ttyUSB0, COM3; or any path with --serial), or a file being written (followed like tail -f). Lines: t,gx,gy,gz,mx,my,mz, or t,gx,gy,gz,,, and t,,,,mx,my,mz for sensors on lines of their own; an accelerometer (m/s^2) as three more fields, t,gx,gy,gz,mx,my,mz,ax,ay,az or t,,,,,,,ax,ay,az."),
    output: Optional[Path] = typer.Option(None, "-o", "--output", readable=False, help="Save what was received as a session file (.parquet or .csv), whatever stops the watch: end of input, --idle, Ctrl-C or SIGTERM."),
    status: Optional[Path] = typer.Option(None, "--status", readable=False, help="Write every update as a JSON line here (t_s, rank, coverage, predicted_std per group, enough, ...)."),
    serial: bool = typer.Option(False, "--serial", help="SOURCE is a serial port (needs pyserial), whatever its name."),
    baud: int = typer.Option(115200, "--baud", min=1, help="Serial port speed."),
    idle: Optional[float] = typer.Option(None, "--idle", min=0.0, help="Stop after this many seconds without new data (default: 10 for a file, never for standard input or a serial port)."),
    gyro_unit: str = typer.Option("rad/s", "--gyro-unit", help="Unit of gx gy gz: rad/s or deg/s (the session is saved in rad/s)."),
    mag_unit: str = typer.Option("unknown", "--mag-unit", help="Magnetometer unit label, e.g. uT (any unit works)."),
    targets_file: Optional[Path] = TARGETS_OPTION,
    target_scale_ppm: Optional[float] = TARGET_SCALE_OPTION,
    target_nonorth_deg: Optional[float] = TARGET_NONORTH_OPTION,
    target_bias_deg_s: Optional[float] = TARGET_BIAS_OPTION,
    target_misalignment_deg: Optional[float] = TARGET_MISALIGNMENT_OPTION,
    refresh: float = typer.Option(2.0, "--refresh", min=0.0, help="Seconds of data between two predictions of the accuracy (each is magyro observe on the data so far, in a background process; a new one starts only when the last is in)."),
    quiet: bool = typer.Option(False, "--quiet", "-q", help="No live display; only the final summary."),
):
    """Live excitation feedback while recording: rank, coverage, predicted accuracy, the motion to make next.

    ENOUGH shows once magyro observe's predicted one-sigma of every gyro parameter (on the data so far)
    is within its target. With ax ay az it also shows the poses held, the rank of the accelerometer's
    12 parameters, the poses to hold next and the gyro's rank with gravity beside the field (magyro observe's accelerometer section). Stop with Ctrl-C; -o saves what was received. Exit 0 once the input ends or is
    stopped (and the session, if asked, is written), 2 when the input is unusable.
    """
    from magyro.live.watch import watch
    from magyro.targets import resolve_targets

    def action():
        targets = resolve_targets(targets_file, target_scale_ppm, target_nonorth_deg, target_bias_deg_s,
                                  target_misalignment_deg)
        return watch(source, output=output, status=status, serial=serial, baud=baud, idle=idle, gyro_unit=gyro_unit,
                     mag_unit=mag_unit, targets=targets, refresh=refresh, quiet=quiet)

    result = run_guarded(action, progress=False)
    if output is not None and not result.saved:
        fail(result.summary, 2)
    typer.echo(result.summary, err=True)


def simulate_stream(problem: str, speed: float = 1.0, seed: Optional[int] = None) -> None:
    """`magyro simulate PROBLEM --stream [--speed X] [--seed N]`: the simulated recording as CSV lines on
    standard output, paced in real time (X times faster; 0 as fast as possible)."""

    def action():
        from magyro.live.stream import stream_session
        from magyro.studies.scenario import load_problem
        from magyro.studies.simulate import simulate

        if speed < 0:
            from magyro.errors import InputError
            raise InputError(f"--speed {speed}: give 0 (as fast as possible) or a positive factor (1 = real time)")
        session, _ = simulate(load_problem(problem), 0 if seed is None else seed)
        try:
            stream_session(session, sys.stdout, speed)
            sys.stdout.flush()
        except BrokenPipeError:
            pass
        finally:
            _quiet_broken_pipe()

    try:
        run_guarded(action, progress=False)
    except KeyboardInterrupt:
        _quiet_broken_pipe()
        raise typer.Exit(130)


def _quiet_broken_pipe() -> None:
    """After the reader went away, Python's flush at exit must not print a BrokenPipeError."""
    import os

    try:
        sys.stdout.flush()
    except (BrokenPipeError, ValueError):
        try:
            devnull = os.open(os.devnull, os.O_WRONLY)
            os.dup2(devnull, sys.stdout.fileno())
        except OSError:
            pass
