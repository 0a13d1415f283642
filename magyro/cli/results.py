"""`magyro validate`, `apply`, `export` and `report`: what a calibration is used and checked for."""
from __future__ import annotations

from pathlib import Path
from typing import Optional

import typer

from magyro.cli.common import (TARGET_BIAS_OPTION, TARGET_MISALIGNMENT_OPTION, TARGET_NONORTH_OPTION,
                               TARGET_SCALE_OPTION, TARGETS_OPTION, run_guarded)


def validate_command(
    session: Path = typer.Argument(..., metavar="SESSION", readable=False, help="Session file (.parquet or .csv); truth columns qw qx qy qz are used when present."),
    calibration: Path = typer.Argument(..., metavar="CALIB", readable=False, help="Calibration JSON written by magyro solve."),
    output: Optional[Path] = typer.Option(None, "-o", "--output", readable=False, help="Write the report JSON here."),
    plot: Optional[Path] = typer.Option(None, "--plot", readable=False, help="Write the figure here (.png, .pdf or .svg; needs matplotlib)."),
    series: bool = typer.Option(False, "--series", help="Put the error (or attitude) time series in the JSON too."),
    gyro_unit: Optional[str] = typer.Option(None, "--gyro-unit", help="rad/s or deg/s (overrides the file's metadata)."),
    mag_unit: Optional[str] = typer.Option(None, "--mag-unit", help="Magnetometer unit label, e.g. uT."),
    quiet: bool = typer.Option(False, "--quiet", "-q", help="No table on the terminal."),
):
    """Dead-reckon with the raw and the calibrated gyro: error against truth, or closure drift."""
    from magyro.api import validate_file

    def action():
        report = validate_file(session, calibration, gyro_unit=gyro_unit, mag_unit=mag_unit, output=output, plot=plot,
                               series=series)
        if not quiet:
            typer.echo(report.table())
            for path, what in ((output, "report"), (plot, "figure")):
                if path is not None:
                    typer.echo(f"{what} written to {path}")

    run_guarded(action, progress=not quiet)


def apply_command(
    session: Path = typer.Argument(..., metavar="SESSION", readable=False, help="Session file to correct (.parquet or .csv, docs/spec.md section 2)."),
    calibration: Path = typer.Argument(..., metavar="CALIB", readable=False, help="Calibration JSON written by magyro solve."),
    output: Path = typer.Option(..., "-o", "--output", readable=False, help="Corrected session file to write (.parquet or .csv)."),
    frame: str = typer.Option("b", "--frame", help="Frame of the corrected rates (and of the specific force, when the calibration has an accelerometer): b (the gyro's: K_g y + eps_b) or m (the magnetometer's: K y + eps)."),
    gyro_unit: Optional[str] = typer.Option(None, "--gyro-unit", help="rad/s or deg/s (overrides the file's metadata)."),
    mag_unit: Optional[str] = typer.Option(None, "--mag-unit", help="Magnetometer unit label, e.g. uT."),
):
    """Correct a session with a calibration: gyro as calibrated rates in rad/s, magnetometer as the unit field R (y - h),
    and (when the calibration has an accelerometer) ax ay az as the calibrated specific force in m/s^2."""
    from magyro.api import apply_file

    def action():
        s = apply_file(session, calibration, output, frame=frame, gyro_unit=gyro_unit, mag_unit=mag_unit)
        acc = {"true": f", {0 if s.t_acc_s is None else len(s.t_acc_s)} accelerometer samples as the calibrated "
                       f"specific force in m/s^2 (frame {frame})",
               "false": "; the session has no accelerometer columns: the calibration's accelerometer is not applied"}
        typer.echo(f"corrected session written to {output}: {len(s.t_gyro_s)} gyro samples in rad/s (frame {frame}), "
                   f"{len(s.t_mag_s)} magnetometer samples as the unit field"
                   + acc.get(s.metadata.get("calibrated_accelerometer", ""), ""))

    run_guarded(action)


def export_command(
    calibration: Path = typer.Argument(..., metavar="CALIB", readable=False, help="Calibration JSON written by magyro solve."),
    fmt: str = typer.Option(..., "--format", "-f", help="yaml (a plain, commented YAML file), c (a C99 header with the matrices and apply functions), kalibr (Kalibr's scale-misalignment IMU yaml, exact), px4 (a QGroundControl .params file: gyro offset only, its cost stated) or ardupilot (a Mission Planner / MAVProxy .parm file: COMPASS_OFS/DIA/ODI, INS_GYROFFS, INS_ACCOFFS/ACCSCAL; what ArduPilot cannot hold and its cost stated, also on stderr)."),
    output: Optional[Path] = typer.Option(None, "-o", "--output", readable=False, help="Write here (default: print to the terminal)."),
    noise: Optional[Path] = typer.Option(None, "--noise", readable=False, help="kalibr: a noise file (magyro noise -o) for Kalibr's noise densities, random walks and update_rate."),
    rostopic: Optional[str] = typer.Option(None, "--rostopic", help="kalibr with --noise: the IMU's topic (default /imu0)."),
):
    """The calibration for other programs: K_g, bias, C_b_m, K, eps, R, h (and K_a, its bias and C_b_a when it has an
    accelerometer) and the model, as YAML (yaml), a C99 header (c), Kalibr's IMU yaml (kalibr), a PX4 .params file
    (px4) or an ArduPilot parameter file (ardupilot)."""
    from magyro.api import export_file

    def action():
        if noise is not None or rostopic is not None:
            from magyro.noise_file import kalibr_export_file

            text = kalibr_export_file(calibration, noise, rostopic, output, fmt)
        else:
            text = export_file(calibration, fmt, output)
        if fmt == "ardupilot":   # what the parameters cannot hold, and its cost, where it is not missed
            from magyro.result.calibration import Calibration
            from magyro.result.export_ardupilot import cannot_hold_lines

            for line in cannot_hold_lines(Calibration.from_json(calibration)):
                typer.echo(f"ardupilot cannot hold: {line}", err=True)
        if output is None:
            typer.echo(text, nl=False)
        else:
            typer.echo(f"{fmt} export written to {output}")

    run_guarded(action)


def report_command(
    session: Path = typer.Argument(..., metavar="SESSION", readable=False, help="The session file the calibration was solved from."),
    calibration: Path = typer.Argument(..., metavar="CALIB", readable=False, help="The calibration JSON (magyro solve -o)."),
    output: Path = typer.Option(..., "-o", "--output", readable=False, help="The HTML page to write (self-contained: opens with no network)."),
    split_check: bool = typer.Option(True, "--split-check/--no-split-check", help="Compute the split-half check when the calibration has none (two more solves)."),
    gyro_unit: Optional[str] = typer.Option(None, "--gyro-unit", help="rad/s or deg/s (overrides the file's metadata)."),
    mag_unit: Optional[str] = typer.Option(None, "--mag-unit", help="Magnetometer unit label, e.g. uT."),
    targets_file: Optional[Path] = TARGETS_OPTION,
    target_scale_ppm: Optional[float] = TARGET_SCALE_OPTION,
    target_nonorth_deg: Optional[float] = TARGET_NONORTH_OPTION,
    target_bias_deg_s: Optional[float] = TARGET_BIAS_OPTION,
    target_misalignment_deg: Optional[float] = TARGET_MISALIGNMENT_OPTION,
    quiet: bool = typer.Option(False, "--quiet", "-q", help="No progress and no verdict on the terminal."),
):
    """One HTML page to read or send: the recording check, excitation, calibration with std, residuals, split-half
    check and dead reckoning, each with a figure and a sentence saying whether it is good (needs matplotlib: pip install '.[plot]' in a clone, 'magyro[plot]' from PyPI)."""
    from magyro.report import report_file
    from magyro.targets import resolve_targets

    def action():
        say = None if quiet else (lambda message: typer.echo(f"report: {message}", err=True))
        targets = resolve_targets(targets_file, target_scale_ppm, target_nonorth_deg, target_bias_deg_s,
                                  target_misalignment_deg)
        report = report_file(session, calibration, output, split_check=split_check, gyro_unit=gyro_unit,
                             mag_unit=mag_unit, progress=say, targets=targets)
        if not quiet:
            typer.echo(report.verdict)
            typer.echo(f"report written to {output}")

    run_guarded(action, progress=False)   # its own lines
