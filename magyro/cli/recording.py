"""`magyro check` and `magyro observe`: is a recording sound, and does it excite every parameter? No solve."""
from __future__ import annotations

from pathlib import Path
from typing import List, Optional

import typer

from magyro.cli.common import (NO_REPAIR_HELP, TARGET_BIAS_OPTION, TARGET_MISALIGNMENT_OPTION, TARGET_NONORTH_OPTION,
                               TARGET_SCALE_OPTION, TARGETS_OPTION, fail, gyro_noise_density, gyro_noise_help,
                               run_guarded)
from magyro.options import Repairs, StdBounds


def observe_command(
    session: Path = typer.Argument(..., metavar="SESSION", readable=False, help="Session file (.parquet or .csv, docs/spec.md section 2)."),
    output: Optional[Path] = typer.Option(None, "-o", "--output", readable=False, help="Write the report JSON here (schema magyro.observability/1)."),
    plot: Optional[Path] = typer.Option(None, "--plot", readable=False, help="Write a figure here (.png, .pdf, .svg): field-direction coverage, eigenvalue growth, rates. Needs matplotlib."),
    gyro_unit: Optional[str] = typer.Option(None, "--gyro-unit", help="rad/s or deg/s (overrides the file's metadata)."),
    mag_unit: Optional[str] = typer.Option(None, "--mag-unit", help="Magnetometer unit label, e.g. uT."),
    gyro_noise_deg_s_sqrt_hz: Optional[float] = typer.Option(None, "--gyro-noise", parser=gyro_noise_density, metavar="DENSITY", help=gyro_noise_help("estimated")),
    mag_noise: Optional[float] = typer.Option(None, "--mag-noise", help="Magnetometer noise std, in its unit (default: estimated)."),
    targets_file: Optional[Path] = TARGETS_OPTION,
    target_scale_ppm: Optional[float] = TARGET_SCALE_OPTION,
    target_nonorth_deg: Optional[float] = TARGET_NONORTH_OPTION,
    target_bias_deg_s: Optional[float] = TARGET_BIAS_OPTION,
    target_misalignment_deg: Optional[float] = TARGET_MISALIGNMENT_OPTION,
    no_repair: Optional[List[str]] = typer.Option(None, "--no-repair", help=NO_REPAIR_HELP),
    max_std_scale_ppm: float = typer.Option(StdBounds.scale_ppm, "--max-std-scale-ppm", min=0.0, help="Refusal bound (not the targets): refuse (exit 3) when the predicted one-sigma of a gyro scale factor exceeds this, ppm."),
    max_std_nonorth_deg: float = typer.Option(StdBounds.nonorthogonality_deg, "--max-std-nonorth-deg", min=0.0, help="... of a non-orthogonality angle, deg."),
    max_std_bias_deg_s: float = typer.Option(StdBounds.bias_deg_s, "--max-std-bias-deg-s", min=0.0, help="... of a gyro bias, deg/s."),
    max_std_misalignment_deg: float = typer.Option(StdBounds.misalignment_deg, "--max-std-misalignment-deg", min=0.0, help="... of the misalignment, deg."),
    quiet: bool = typer.Option(False, "--quiet", "-q", help="No table on the terminal."),
):
    """Does the recording excite every parameter, and how well? The excitation report, no solve.

    Exit 0 when the excitation is sufficient or marginal, 3 when insufficient (the
    report is still printed and written), 2 when the input is unusable.
    """
    from magyro.api import observe_file
    from magyro.options import Options
    from magyro.targets import resolve_targets

    def action():
        bounds = StdBounds(max_std_scale_ppm, max_std_nonorth_deg, max_std_bias_deg_s, max_std_misalignment_deg)
        options = Options.in_user_units(gyro_noise_deg_s_sqrt_hz, mag_noise, max_std=bounds,
                                        repairs=Repairs.without(no_repair or []))
        targets = resolve_targets(targets_file, target_scale_ppm, target_nonorth_deg, target_bias_deg_s,
                                  target_misalignment_deg)
        report = observe_file(session, options, targets, gyro_unit=gyro_unit, mag_unit=mag_unit, output=output, plot=plot)
        if not quiet:
            typer.echo(report.table())
            for path, what in ((output, "report"), (plot, "figure")):
                if path is not None:
                    typer.echo(f"{what} written to {path}")
        return report

    report = run_guarded(action, progress=not quiet)
    if report.verdict == "insufficient":
        fail(f"insufficient excitation: {report.reason}. " + " ".join(report.advice), 3)


def check_command(
    session: Path = typer.Argument(..., metavar="SESSION", readable=False, help="Session file (.parquet or .csv, docs/spec.md section 2)."),
    output: Optional[Path] = typer.Option(None, "-o", "--output", readable=False, help="Write the check as JSON here (schema magyro.recording/1)."),
    gyro_unit: Optional[str] = typer.Option(None, "--gyro-unit", help="rad/s or deg/s (overrides the file's metadata)."),
    mag_unit: Optional[str] = typer.Option(None, "--mag-unit", help="Magnetometer unit label, e.g. uT."),
    no_repair: Optional[List[str]] = typer.Option(None, "--no-repair", help=NO_REPAIR_HELP),
    quiet: bool = typer.Option(False, "--quiet", "-q", help="No table on the terminal."),
):
    """Is the recording sound? Rates, jitter, bursts, gaps, held samples, clock drift, saturation, spikes, units;
    what magyro repairs. No solve.

    Exit 0 when nothing makes the recording unusable (the table is printed and written either way),
    2 when something does: time not in seconds, a gyro unit that cannot be right, sensors without common time.
    """
    from magyro.api import check_file
    from magyro.errors import InputError

    def action():
        check = check_file(session, gyro_unit=gyro_unit, mag_unit=mag_unit, output=output,
                           repairs=Repairs.without(no_repair or []))
        if not quiet:
            typer.echo(check.table())
            if output is not None:
                typer.echo(f"check written to {output}")
        if check.errors:
            raise InputError(f"{session}: the recording is unusable as it is: {check.error_message()}")

    run_guarded(action, progress=not quiet)
