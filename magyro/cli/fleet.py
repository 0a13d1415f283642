"""`magyro batch`: many devices calibrated, judged against limits and summarised."""
from __future__ import annotations

from pathlib import Path
from typing import List, Optional

import typer

from magyro.options import STANDARD_GRAVITY_M_S2

from magyro.cli.common import (NO_REPAIR_HELP, TARGET_BIAS_OPTION, TARGET_MISALIGNMENT_OPTION, TARGET_NONORTH_OPTION,
                               TARGET_SCALE_OPTION, TARGETS_OPTION, fail, gyro_noise_density, gyro_noise_help,
                               run_guarded)
from magyro.options import Repairs


def batch(
    inputs: List[str] = typer.Argument(..., metavar="INPUTS...", help="Session files, folders of them, globs (quoted), or a manifest CSV with columns device_id,session."),
    outdir: Path = typer.Option(..., "-o", "--output", readable=False, help="Folder for the results (created): calibrations/ID.json, rows/, summary.parquet, summary.csv, summary.html."),
    limits: Optional[Path] = typer.Option(None, "--limits", readable=False, help="Acceptance limits (TOML, [limits] table: max_abs_* bounds, target_* one-sigma targets, as in --targets and --target-*; docs/limits-example.toml). Without: every calibrated device is accepted."),
    targets_file: Optional[Path] = TARGETS_OPTION,
    target_scale_ppm: Optional[float] = TARGET_SCALE_OPTION,
    target_nonorth_deg: Optional[float] = TARGET_NONORTH_OPTION,
    target_bias_deg_s: Optional[float] = TARGET_BIAS_OPTION,
    target_misalignment_deg: Optional[float] = TARGET_MISALIGNMENT_OPTION,
    jobs: int = typer.Option(1, "--jobs", "-j", min=1, help="Solve in this many processes (one BLAS thread each)."),
    scheduler: Optional[str] = typer.Option(None, "--scheduler", help="Solve on the Dask cluster whose scheduler is at this address (tcp://host:port; default: $MAGYRO_SCHEDULER, else the local pool of --jobs). Needs magyro[dask]."),
    redo: bool = typer.Option(False, "--redo", help="Solve every device again, even those already done with the same input and options."),
    reports: bool = typer.Option(False, "--reports", help="Also write each device's HTML report into reports/ (needs matplotlib: pip install '.[plot]' in a clone, 'magyro[plot]' from PyPI; slower)."),
    split_check: bool = typer.Option(False, "--split-check", help="Also calibrate each half of every recording alone (about 2x the time); gives the split_rms_z column."),
    accelerometer: Optional[bool] = typer.Option(None, "--accelerometer/--no-accelerometer", help="Calibrate each device's accelerometer (ax ay az, m/s^2) in the same least squares, as magyro solve does: gives the acc_* columns the max_abs_acc_* and target_acc_* limits bound. Default: for each device whose session has one (left out, saying why, where it cannot be calibrated); --accelerometer insists, --no-accelerometer never."),
    gravity: float = typer.Option(STANDARD_GRAVITY_M_S2, "--gravity", min=9.7, max=9.9, help="The local gravity in m/s^2 the accelerometers are calibrated against."),
    gyro_unit: Optional[str] = typer.Option(None, "--gyro-unit", help="rad/s or deg/s (overrides the files' metadata)."),
    mag_unit: Optional[str] = typer.Option(None, "--mag-unit", help="Magnetometer unit label, e.g. uT."),
    gyro_noise_deg_s_sqrt_hz: Optional[float] = typer.Option(None, "--gyro-noise", parser=gyro_noise_density, metavar="DENSITY", help=gyro_noise_help("estimated per device")),
    mag_noise: Optional[float] = typer.Option(None, "--mag-noise", help="Magnetometer noise std, in its unit (default: estimated per device)."),
    no_repair: Optional[List[str]] = typer.Option(None, "--no-repair", help=NO_REPAIR_HELP),
    quiet: bool = typer.Option(False, "--quiet", "-q", help="No progress and no summary on the terminal."),
):
    """Many devices: calibrate every session, judge each against the limits, summarise the fleet.

    Results go to disk as each device finishes; a rerun skips the devices already done with the same
    input and options (--redo solves them again). A device that fails is a row with its cause; the others
    go on. Exit 0 when every device is accepted, 1 when any is rejected or failed (listed, and in the
    summary), 2 when the batch itself is unusable (no inputs, a bad manifest or limits file).
    """
    from magyro.batch.limits import load_limits, with_targets
    from magyro.targets import resolve_targets
    from magyro.batch.run import run_batch
    from magyro.options import Options
    from magyro.progress import counting

    def action():
        chosen = load_limits(limits) if limits is not None else None
        flags = (target_scale_ppm, target_nonorth_deg, target_bias_deg_s, target_misalignment_deg)
        if targets_file is not None or any(v is not None for v in flags):   # the std limits: the shared targets
            chosen = with_targets(chosen, resolve_targets(targets_file, *flags))
        options = Options.in_user_units(gyro_noise_deg_s_sqrt_hz, mag_noise, split_check=split_check,
                                        repairs=Repairs.without(no_repair or []), accelerometer=accelerometer,
                                        gravity_m_s2=gravity)
        with counting(0, "devices", enabled=not quiet) as tick:
            def show(done: int, total: int, row: dict) -> None:
                if tick is not None:
                    tick(done, f"{row['device_id']}: {row['exit_class']} ({row['message']})",
                         alarm=row["exit_code"] != 0, total=total)
            result = run_batch(inputs, outdir, options, limits=chosen, jobs=jobs, scheduler=scheduler, redo=redo,
                               reports=reports, gyro_unit=gyro_unit, mag_unit=mag_unit, progress=show)
        if not quiet:
            typer.echo(result.table())
            typer.echo(f"summary written to {result.summary_paths.get('html', outdir)}")
        return result

    result = run_guarded(action, progress=False)   # its own bar
    not_accepted = len(result.rows) - result.count("accepted")
    if not_accepted:
        fail(f"{not_accepted} of {len(result.rows)} devices not accepted ({result.count('rejected')} rejected, "
             f"{result.count('failed')} failed); the summary names each with its cause", 1)
