"""`magyro simulate`, `magyro montecarlo` and `magyro plan`: simulated sessions, accuracy studies over them,
and a motion planned for the smallest predicted std."""
from __future__ import annotations

from pathlib import Path
from typing import Optional

import typer

from magyro.cli.common import gyro_noise_density, gyro_noise_help, fail, run_guarded


def simulate(
    problem: str = typer.Argument(..., metavar="PROBLEM", help="Problem file (TOML, describing a simulated scenario), or the name of one shipped in problems/ (e.g. paper-table1)."),
    output: Optional[Path] = typer.Option(None, "-o", "--output", readable=False, help="Session file to write (.parquet or .csv); the truth goes beside it as NAME.truth.json. With --seeds: the folder to write the fleet in (created)."),
    seed: Optional[int] = typer.Option(None, "--seed", help="Noise seed (default 0; the motion is fixed by the problem)."),
    seeds: Optional[str] = typer.Option(None, "--seeds", help="A fleet: one device per seed, e.g. 0-199, 3 or 1,5,9, each with its own sensor errors drawn from the problem's spread section; writes NAME-SEED.parquet, its truth and manifest.csv into the -o folder."),
    stream: bool = typer.Option(False, "--stream", help="Write the recording to standard output as CSV lines (t,gx,gy,gz,,, and t,,,,mx,my,mz, and t,,,,,,,ax,ay,az for a problem with an [accelerometer]), paced in real time, for magyro watch -."),
    speed: float = typer.Option(1.0, "--speed", help="With --stream: this many times faster than real time (0: as fast as possible)."),
):
    """A simulated session and its true parameters from a problem file (or a fleet of devices with --seeds, or a
    live stream on standard output with --stream)."""
    from magyro.api import simulate_file, simulate_fleet_dir
    from magyro.errors import InputError

    if stream:
        from magyro.cli.live import simulate_stream

        if output is not None or seeds is not None:
            fail("--stream writes to standard output: leave out -o and --seeds", 2)
        simulate_stream(problem, speed, seed)
        return
    if output is None:
        fail("-o/--output is required (a session file, or a folder with --seeds), or --stream for standard output", 2)

    def action():
        if seeds is not None:
            if seed is not None:
                raise InputError("--seed and --seeds together: give one (--seed N for one session, --seeds A-B for a fleet)")
            paths, manifest = simulate_fleet_dir(problem, seeds, output)
            typer.echo(f"{len(paths)} sessions written to {output} (with their truths); manifest in {manifest}")
            return
        s, truth_path = simulate_file(problem, output, 0 if seed is None else seed)
        typer.echo(f"session written to {output} ({len(s.t_gyro_s)} gyro, {len(s.t_mag_s)} magnetometer samples); truth in {truth_path}")

    run_guarded(action)


def montecarlo(
    problem: str = typer.Argument(..., metavar="PROBLEM", help="Problem file (TOML, describing a simulated scenario), or the name of one shipped in problems/ (e.g. paper-table1)."),
    runs: int = typer.Option(..., "--runs", "-n", min=1, help="Number of simulated sessions (noise seeds seed0 .. seed0+N-1)."),
    jobs: int = typer.Option(1, "--jobs", "-j", min=1, help="Solve in this many processes (one BLAS thread each)."),
    method: str = typer.Option("nls", "--method", help="nls, ekf, or nls,ekf to solve the same sessions with both."),
    seed0: int = typer.Option(0, "--seed0", min=0, help="First noise seed."),
    output: Optional[Path] = typer.Option(None, "-o", "--output", readable=False, help="Write the table and every run's estimates as JSON (schema magyro.montecarlo/1)."),
    csv_path: Optional[Path] = typer.Option(None, "--csv", readable=False, help="Write the table as CSV (one row per method and parameter)."),
    scheduler: Optional[str] = typer.Option(None, "--scheduler", help="Solve on the Dask cluster whose scheduler is at this address (tcp://host:port; default: $MAGYRO_SCHEDULER, else the local pool of --jobs). Needs magyro[dask]."),
    quiet: bool = typer.Option(False, "--quiet", "-q", help="No progress and no table on the terminal."),
):
    """Table-I-style accuracy study: N seeded sessions, each solved; mean, std, Cramer-Rao bound of every estimate.

    Exit 0 when every run succeeded, 1 when any run failed: the failed runs are
    listed with their seed and message, and the table of the successful ones is
    still printed and written.
    """
    from magyro.api import montecarlo_study

    def action():
        result = montecarlo_study(problem, runs, jobs=jobs, method=method, seed0=seed0, output=output,
                                  csv_path=csv_path, progress=not quiet, scheduler=scheduler)
        if not quiet:
            typer.echo(result.table())
            for path in (output, csv_path):
                if path is not None:
                    typer.echo(f"written to {path}")
        return result

    result = run_guarded(action, progress=False)   # its own bar
    if not result.all_succeeded:
        fail(f"{result.failed_count} of {runs * len(result.methods)} runs failed (seeds and messages above and in the JSON); "
             "the table holds the successful ones", 1)


def plan_command(
    duration: float = typer.Option(..., "--duration", help="Length of the recording to plan, s (at least 3; 1 s still at both ends)."),
    gyro_noise: Optional[float] = typer.Option(None, "--gyro-noise", parser=gyro_noise_density, metavar="DENSITY", help=gyro_noise_help("the base problem's")),
    mag_noise: Optional[float] = typer.Option(None, "--mag-noise", help="Magnetometer noise std per axis, in the base problem's unit (default: the base problem's)."),
    max_rate: float = typer.Option(200.0, "--max-rate", help="Peak body rate of every turn, deg/s (the comparison motions are brought to it too)."),
    base: str = typer.Option("paper-table1", "--base", help="Problem whose sensors the plan is for (its start pose is the written plan's; the search scores 6 start poses): a file, or the name of one shipped in problems/. With an [accelerometer] (e.g. paper-table1-acc) the plan also holds its six poses and predicts its 12 parameters."),
    output: Optional[Path] = typer.Option(None, "-o", "--output", readable=False, help="Write the plan as a problem file (TOML, motion kind \"turns\", the predicted std in [plan]); simulate or montecarlo it."),
    quiet: bool = typer.Option(False, "--quiet", "-q", help="No progress and no table on the terminal."),
):
    """A motion to do by hand: a short list of turns about the device's axes, chosen for the smallest predicted
    std of the gyro parameters (the Fisher information the solve uses) from any of 6 start poses, beside the paper's
    motion started from each and the canonical ones at the same duration and peak rate. With an accelerometer in the
    base, the six poses it needs held too, and its 12 parameters' predicted std. Under a minute."""
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
