"""`magyro plan`: the command function (registered in magyro.cli as `app.command("plan")(plan_command)`)."""
from __future__ import annotations

from pathlib import Path
from typing import Optional

import typer


def plan_command(
    duration: float = typer.Option(..., "--duration", help="Length of the recording to plan, s (at least 3; 1 s still at both ends)."),
    gyro_noise: Optional[float] = typer.Option(None, "--gyro-noise", help="Gyro noise density, deg/s/sqrt(Hz) (default: the base problem's)."),
    mag_noise: Optional[float] = typer.Option(None, "--mag-noise", help="Magnetometer noise std per axis, in the base problem's unit (default: the base problem's)."),
    max_rate: float = typer.Option(200.0, "--max-rate", help="Peak body rate of every turn, deg/s (the comparison motions are brought to it too)."),
    base: str = typer.Option("paper-table1", "--base", help="Problem whose sensors (and start pose) the plan is for: a file, or the name of one shipped in problems/."),
    output: Optional[Path] = typer.Option(None, "-o", "--output", help="Write the plan as a problem file (TOML, motion kind \"turns\", the predicted std in [plan]); simulate or montecarlo it."),
    quiet: bool = typer.Option(False, "--quiet", "-q", help="No progress and no table on the terminal."),
):
    """A motion to do by hand: a short list of turns about the device's axes, chosen for the smallest predicted
    std of the gyro parameters (the Fisher information the solve uses), beside the paper's motion and the
    canonical ones at the same duration and peak rate. About a minute."""
    from magyro.cli import run_guarded

    def action():
        from magyro.io import check_outputs, write_text_atomically
        from magyro.studies.plan import make_plan
        from magyro.studies.scenario import resolve_problem_path

        check_outputs([resolve_problem_path(base)], [output])
        plan = make_plan(duration, gyro_noise, mag_noise, max_rate, base)
        if output is not None:
            write_text_atomically(output, plan.to_problem_toml())
        if not quiet:
            typer.echo(plan.table())
            if output is not None:
                typer.echo(f"plan written to {output} (magyro simulate / montecarlo {output})")
        return plan

    return run_guarded(action, progress=not quiet)
