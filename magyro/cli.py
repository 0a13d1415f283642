"""`magyro` on the command line: a thin layer over the Python API.

Every failure the user can fix ends with one plain message on stderr and the
exit code of docs/spec.md section 3 (2 unusable input, 3 not observable, 1 solver failed).
"""
from __future__ import annotations

import os
import sys

# one BLAS thread: the products here are small, and on a busy 2-core machine OpenBLAS's
# threads made a 12-column least squares 100x slower (set before numpy is imported)
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
from pathlib import Path
from typing import List, Optional

import typer

from magyro import __version__
from magyro.errors import MagyroError
from magyro.options import Repairs, StdBounds

app = typer.Typer(add_completion=False, no_args_is_help=True, pretty_exceptions_enable=False, help="Gyroscope calibration via the magnetometer (Wu & Pei).")


def fail(message: str, code: int) -> None:
    typer.echo(f"magyro: {message}", err=True)
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


@app.callback()
def main_options(
    version: bool = typer.Option(False, "--version", callback=version_callback, is_eager=True, help="Print the version and exit."),
):
    """Calibrate a gyroscope with the magnetometer on the same board, no turntable needed."""


@app.command()
def solve(
    session: Path = typer.Argument(..., help="Session file (.parquet or .csv, docs/spec.md section 2)."),
    output: Optional[Path] = typer.Option(None, "-o", "--output", help="Write the calibration JSON here."),
    gyro_unit: Optional[str] = typer.Option(None, "--gyro-unit", help="rad/s or deg/s (overrides the file's metadata)."),
    mag_unit: Optional[str] = typer.Option(None, "--mag-unit", help="Magnetometer unit label, e.g. uT."),
    gyro_noise_deg_s_sqrt_hz: Optional[float] = typer.Option(None, "--gyro-noise", help="Gyro noise density, deg/s/sqrt(Hz) (default: estimated)."),
    mag_noise: Optional[float] = typer.Option(None, "--mag-noise", help="Magnetometer noise std, in its unit (default: estimated)."),
    stride: Optional[int] = typer.Option(None, "--stride", min=1, help="One attitude node every N segments, one per gyro or magnetometer sample (default: 12, or 4 below 96 Hz; other strides compile their kernels once)."),
    force: bool = typer.Option(False, "--force", help="Solve even when the motion does not excite every parameter."),
    loss: str = typer.Option("l2", "--loss", help="Loss on the magnetometer residuals: l2, or huber (robust to spikes and local iron)."),
    hard_iron_walk: Optional[float] = typer.Option(None, "--hard-iron-walk", help="Experimental (nls): let the hard iron move, as a random walk of this density (magnetometer unit per sqrt(s), e.g. 1 for uT); for iron or a magnet on the board whose field drifts. See docs/real-data.md section 4 for where it helps and where it does not."),
    time_offset: bool = typer.Option(True, "--time-offset/--no-time-offset", help="Estimate the magnetometer's lag behind the gyro (default) or fix it to 0."),
    keep_rests: bool = typer.Option(False, "--keep-rests", help="Keep the rests at both ends in the solve (default: trimmed, as the paper does)."),
    split_check: bool = typer.Option(False, "--split-check", help="Also calibrate each half of the recording alone and warn when they disagree beyond their std (about 2x the time)."),
    no_repair: Optional[List[str]] = typer.Option(None, "--no-repair", help="Turn a repair of the recording off: restamp, held, saturation, spikes, or all (repeat for several)."),
    max_std_scale_ppm: float = typer.Option(StdBounds.scale_ppm, "--max-std-scale-ppm", min=0.0, help="Refuse (exit 3) when the predicted one-sigma of a gyro scale factor exceeds this, ppm."),
    max_std_nonorth_deg: float = typer.Option(StdBounds.nonorthogonality_deg, "--max-std-nonorth-deg", min=0.0, help="... of a non-orthogonality angle, deg."),
    max_std_bias_deg_s: float = typer.Option(StdBounds.bias_deg_s, "--max-std-bias-deg-s", min=0.0, help="... of a gyro bias, deg/s."),
    max_std_misalignment_deg: float = typer.Option(StdBounds.misalignment_deg, "--max-std-misalignment-deg", min=0.0, help="... of the misalignment, deg."),
    method: str = typer.Option("nls", "--method", help="nls (the joint least squares) or ekf (the paper's two steps and error-state EKF)."),
    history: Optional[Path] = typer.Option(None, "--history", help="--method ekf: write K, bias, m^i and their 1-sigma over time (Parquet)."),
    history_plot: Optional[Path] = typer.Option(None, "--history-plot", help="--method ekf: plot them like the paper's Fig. 3/6/7 (needs magyro[plot])."),
    trajectory: Optional[Path] = typer.Option(None, "--trajectory", help="--method nls: write the solved attitude at the nodes (quaternion C_m_i and its std) and the calibrated field (Parquet)."),
    quiet: bool = typer.Option(False, "--quiet", "-q", help="No table on the terminal."),
):
    """The joint calibration: magnetometer ellipsoid, gyro K_g, bias, misalignment, field, attitude.

    --stride, --loss, --hard-iron-walk, --time-offset and --split-check apply to the nls method only.
    """
    from magyro.api import solve_file
    from magyro.options import Options

    def action():
        bounds = StdBounds(max_std_scale_ppm, max_std_nonorth_deg, max_std_bias_deg_s, max_std_misalignment_deg)
        options = Options.in_user_units(gyro_noise_deg_s_sqrt_hz, mag_noise, force=force, estimate_time_offset=time_offset,
                                        trim_rests=not keep_rests, split_check=split_check, max_std=bounds,
                                        repairs=Repairs.without(no_repair or []))
        cal = solve_file(session, options, method, {"stride": stride, "loss": loss, "hard_iron_walk": hard_iron_walk},
                         gyro_unit=gyro_unit,
                         mag_unit=mag_unit, output=output, history=history, history_plot=history_plot,
                         trajectory=trajectory)
        if not quiet:
            typer.echo(cal.table())
            if output is not None:
                typer.echo(f"calibration written to {output}")
            if trajectory is not None:
                typer.echo(f"attitude trajectory ({len(cal.trajectory.t_s)} nodes) written to {trajectory}")

    run_guarded(action, progress=not quiet)


@app.command()
def simulate(
    problem: str = typer.Argument(..., help="Problem file (TOML, describing a simulated scenario), or the name of one shipped in problems/ (e.g. paper-table1)."),
    output: Optional[Path] = typer.Option(None, "-o", "--output", help="Session file to write (.parquet or .csv); the truth goes beside it as NAME.truth.json. With --seeds: the folder to write the fleet in (created)."),
    seed: Optional[int] = typer.Option(None, "--seed", help="Noise seed (default 0; the motion is fixed by the problem)."),
    seeds: Optional[str] = typer.Option(None, "--seeds", help="A fleet: one device per seed, e.g. 0-199, 3 or 1,5,9, each with its own sensor errors drawn from the problem's spread section; writes NAME-SEED.parquet, its truth and manifest.csv into the -o folder."),
    stream: bool = typer.Option(False, "--stream", help="Write the recording to standard output as CSV lines (t,gx,gy,gz,,, and t,,,,mx,my,mz), paced in real time, for magyro watch -."),
    speed: float = typer.Option(1.0, "--speed", help="With --stream: this many times faster than real time (0: as fast as possible)."),
):
    """A simulated session and its true parameters from a problem file (or a fleet of devices with --seeds, or a
    live stream on standard output with --stream)."""
    from magyro.api import simulate_file, simulate_fleet_dir
    from magyro.errors import InputError

    if stream:
        from magyro.cli_live import simulate_stream

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


@app.command()
def montecarlo(
    problem: str = typer.Argument(..., help="Problem file (TOML, describing a simulated scenario), or the name of one shipped in problems/ (e.g. paper-table1)."),
    runs: int = typer.Option(..., "--runs", "-n", min=1, help="Number of simulated sessions (noise seeds seed0 .. seed0+N-1)."),
    jobs: int = typer.Option(1, "--jobs", "-j", min=1, help="Solve in this many processes (one BLAS thread each)."),
    method: str = typer.Option("nls", "--method", help="nls, ekf, or nls,ekf to solve the same sessions with both."),
    seed0: int = typer.Option(0, "--seed0", min=0, help="First noise seed."),
    output: Optional[Path] = typer.Option(None, "-o", "--output", help="Write the table and every run's estimates as JSON (schema magyro.montecarlo/1)."),
    csv_path: Optional[Path] = typer.Option(None, "--csv", help="Write the table as CSV (one row per method and parameter)."),
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


@app.command()
def batch(
    inputs: List[str] = typer.Argument(..., help="Session files, folders of them, globs (quoted), or a manifest CSV with columns device_id,session."),
    outdir: Path = typer.Option(..., "-o", "--output", help="Folder for the results (created): calibrations/ID.json, rows/, summary.parquet, summary.csv, summary.html."),
    limits: Optional[Path] = typer.Option(None, "--limits", help="Acceptance limits (TOML, [limits] table; docs/limits-example.toml). Without: every calibrated device is accepted."),
    jobs: int = typer.Option(1, "--jobs", "-j", min=1, help="Solve in this many processes (one BLAS thread each)."),
    scheduler: Optional[str] = typer.Option(None, "--scheduler", help="Solve on the Dask cluster whose scheduler is at this address (tcp://host:port; default: $MAGYRO_SCHEDULER, else the local pool of --jobs). Needs magyro[dask]."),
    redo: bool = typer.Option(False, "--redo", help="Solve every device again, even those already done with the same input and options."),
    reports: bool = typer.Option(False, "--reports", help="Also write each device's HTML report into reports/ (needs magyro[plot]; slower)."),
    split_check: bool = typer.Option(False, "--split-check", help="Also calibrate each half of every recording alone (about 2x the time); gives the split_rms_z column."),
    gyro_unit: Optional[str] = typer.Option(None, "--gyro-unit", help="rad/s or deg/s (overrides the files' metadata)."),
    mag_unit: Optional[str] = typer.Option(None, "--mag-unit", help="Magnetometer unit label, e.g. uT."),
    gyro_noise_deg_s_sqrt_hz: Optional[float] = typer.Option(None, "--gyro-noise", help="Gyro noise density, deg/s/sqrt(Hz) (default: estimated per device)."),
    mag_noise: Optional[float] = typer.Option(None, "--mag-noise", help="Magnetometer noise std, in its unit (default: estimated per device)."),
    no_repair: Optional[List[str]] = typer.Option(None, "--no-repair", help="Turn a repair of the recording off: restamp, held, saturation, spikes, or all (repeat for several)."),
    quiet: bool = typer.Option(False, "--quiet", "-q", help="No progress and no summary on the terminal."),
):
    """Many devices: calibrate every session, judge each against the limits, summarise the fleet.

    Results go to disk as each device finishes; a rerun skips the devices already done with the same
    input and options (--redo solves them again). A device that fails is a row with its cause; the others
    go on. Exit 0 when every device is accepted, 1 when any is rejected or failed (listed, and in the
    summary), 2 when the batch itself is unusable (no inputs, a bad manifest or limits file).
    """
    from magyro.batch.limits import load_limits
    from magyro.batch.run import run_batch
    from magyro.options import Options
    from magyro.progress import counting

    def action():
        chosen = load_limits(limits) if limits is not None else None
        options = Options.in_user_units(gyro_noise_deg_s_sqrt_hz, mag_noise, split_check=split_check,
                                        repairs=Repairs.without(no_repair or []))
        with counting(0, "devices", enabled=not quiet) as tick:
            def show(done: int, total: int, row: dict) -> None:
                if tick is not None:
                    tick(done, f"{row['device_id']}: {row['exit_class']} ({row['message'][:80]})",
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


# --------------------------------------------------------------------------- import, validate (issue 6)

import_app = typer.Typer(no_args_is_help=True, help="Convert recordings into session files (BROAD trials, CSV exports).")
app.add_typer(import_app, name="import")


@import_app.command("broad")
def import_broad_command(
    trial: Path = typer.Argument(..., help="A BROAD trial file (.mat, or .hdf5/.h5 with h5py installed)."),
    output: Path = typer.Option(..., "-o", "--output", help="Session file to write (.parquet or .csv)."),
    movement: bool = typer.Option(False, "--movement", help="Keep only the trial's marked movement phase plus --rest seconds at each end."),
    rest_s: float = typer.Option(3.0, "--rest", min=0.0, help="Seconds of rest kept before and after the movement with --movement."),
    start: Optional[float] = typer.Option(None, "--start", help="Drop samples before this time (s, trial time k/rate)."),
    end: Optional[float] = typer.Option(None, "--end", help="Drop samples after this time (s)."),
    decimate_by: int = typer.Option(1, "--decimate", min=1, help="Keep every N-th sample (no filtering)."),
):
    """A BROAD benchmark trial: gyro, magnetometer (uT), accelerometer, optical truth as qw qx qy qz."""
    from magyro.io import BROAD_CITATION, convert_broad

    def action():
        s = convert_broad(trial, output, movement=movement, rest_s=rest_s, start_s=start, end_s=end,
                          decimate_by=decimate_by)
        n_truth = 0 if s.t_quat_s is None else len(s.t_quat_s)
        typer.echo(f"session written to {output}: {len(s.t_gyro_s)} samples at {s.gyro_rate_hz:.3f} Hz, "
                   f"{s.t_gyro_s[0]:.3f} to {s.t_gyro_s[-1]:.3f} s, {n_truth} truth quaternions")
        typer.echo(f"BROAD data are CC BY 4.0; credit {BROAD_CITATION}")

    run_guarded(action)


@import_app.command("csv")
def import_csv_command(
    sources: List[Path] = typer.Argument(..., help="CSV export(s): one file with a time column and sensor columns, or one file per sensor (gyro, magnetometer, optional accelerometer) merged on time; with --preset also the app's export folder or zip."),
    output: Path = typer.Option(..., "-o", "--output", help="Session file to write (.parquet or .csv)."),
    preset: Optional[str] = typer.Option(None, "--preset", help="An app's export: sensor-logger or phyphox (files, columns, units and time known; no --gyro-unit/--mag-unit/--map)."),
    column_map: Optional[List[str]] = typer.Option(None, "--map", "-m", help="NAME=COLUMN for session names t gx gy gz mx my mz (ax ay az, qw qx qy qz), e.g. -m gx=gyroX; with several files NAME=FILE:COLUMN, e.g. -m gx=gyro.csv:x -m t=gyro.csv:time. Repeat, or comma-separate. Unmapped names are guessed from common headers."),
    gyro_unit: Optional[str] = typer.Option(None, "--gyro-unit", help="Unit of the gyro columns: rad/s or deg/s (needed without --preset)."),
    mag_unit: Optional[str] = typer.Option(None, "--mag-unit", help="Unit of the magnetometer columns (kept): uT, nT, G, mG, counts, ... (needed without --preset)."),
    time_unit: str = typer.Option("s", "--time-unit", help="Unit of the time column(s): s, ms, us or ns (times restart at 0 at the earliest stamp)."),
    acc_unit: str = typer.Option("m/s^2", "--acc-unit", help="Unit of the accelerometer columns: m/s^2, g or mg."),
    delimiter: Optional[str] = typer.Option(None, "--delimiter", help="Column separator (default: detected among , ; tab |)."),
    skip_rows: int = typer.Option(0, "--skip-rows", min=0, help="Lines to skip right after the header of every file (a units row, a second header row)."),
    header_line: int = typer.Option(0, "--header-line", min=0, help="Lines before the header of every file (a preamble)."),
    start: Optional[float] = typer.Option(None, "--start", help="Drop samples before this time (s after the first stamp)."),
    end: Optional[float] = typer.Option(None, "--end", help="Drop samples after this time (s)."),
):
    """A phone or logger CSV export (one file, or one file per sensor, or an app's export by --preset) as a session file."""
    from magyro.io.csv_presets import convert_csv

    def action():
        s = convert_csv(sources, output, preset=preset, column_map_items=column_map, gyro_unit=gyro_unit,
                        mag_unit=mag_unit, time_unit=time_unit, acc_unit=acc_unit, delimiter=delimiter,
                        skip_rows=skip_rows, header_line=header_line, start_s=start, end_s=end)
        typer.echo(f"session written to {output}: {len(s.t_gyro_s)} gyro samples ({s.gyro_rate_hz:.1f} Hz), "
                   f"{len(s.t_mag_s)} magnetometer samples ({s.mag_rate_hz:.1f} Hz), {s.duration_s:.1f} s; "
                   f"columns {s.metadata['column_map']}")
        if s.metadata.get("sensor_note"):
            typer.echo(s.metadata["sensor_note"])

    run_guarded(action)


@import_app.command("ulog")
def import_ulog_command(
    log: Path = typer.Argument(..., help="A PX4 ULog file (.ulg)."),
    output: Path = typer.Option(..., "-o", "--output", help="Session file to write (.parquet or .csv)."),
    instance: int = typer.Option(0, "--instance", min=0, help="Topic instance (multi_id), e.g. 1 for the second gyro and magnetometer."),
    topics: Optional[str] = typer.Option(None, "--topics", help="GYRO,MAG topics, e.g. sensor_combined,vehicle_magnetometer (default: sensor_gyro,sensor_mag when logged fast enough, else sensor_combined with vehicle_magnetometer)."),
):
    """A PX4 flight log: gyro (rad/s) and magnetometer (gauss), fresh samples only, times from the first sample."""
    from magyro.io.ulog import convert_ulog, parse_topics

    def action():
        s = convert_ulog(log, output, instance=instance, topics=parse_topics(topics))
        m = s.metadata
        typer.echo(f"session written to {output}: {len(s.t_gyro_s)} gyro samples ({s.gyro_rate_hz:.1f} Hz) from "
                   f"{m['ulog_gyro_topic']} instance {m['ulog_instance']}, {len(s.t_mag_s)} magnetometer samples "
                   f"({s.mag_rate_hz:.1f} Hz, gauss) from {m['ulog_mag_topic']}, {s.duration_s:.1f} s")
        typer.echo("PX4 logs are usually already calibrated by the autopilot; the metadata says which fields were used")

    run_guarded(action)


@import_app.command("rosbag")
def import_rosbag_command(
    bag: Path = typer.Argument(..., help="A ROS1 bag file (.bag) or a ROS2 bag folder."),
    output: Path = typer.Option(..., "-o", "--output", help="Session file to write (.parquet or .csv)."),
    imu_topic: Optional[str] = typer.Option(None, "--imu-topic", help="The sensor_msgs/msg/Imu topic (default: the bag's only one)."),
    mag_topic: Optional[str] = typer.Option(None, "--mag-topic", help="The magnetometer topic: sensor_msgs/msg/MagneticField, or geometry_msgs/msg/Vector3Stamped of older drivers (default: the bag's only one)."),
):
    """A ROS bag: gyro (rad/s) and accelerometer from Imu, magnetometer (tesla to uT), times from the header stamps."""
    from magyro.io.rosbag import convert_rosbag

    def action():
        s = convert_rosbag(bag, output, imu_topic=imu_topic, mag_topic=mag_topic)
        m = s.metadata
        typer.echo(f"session written to {output}: {len(s.t_gyro_s)} gyro samples ({s.gyro_rate_hz:.1f} Hz) from "
                   f"{m['rosbag_imu_topic']}, {len(s.t_mag_s)} magnetometer samples ({s.mag_rate_hz:.1f} Hz, {s.mag_unit}) "
                   f"from {m['rosbag_mag_topic']}, {s.duration_s:.1f} s ({m['rosbag_ros_version']} bag, header stamps)")

    run_guarded(action)


@app.command("validate")
def validate_command(
    session: Path = typer.Argument(..., help="Session file (.parquet or .csv); truth columns qw qx qy qz are used when present."),
    calibration: Path = typer.Argument(..., help="Calibration JSON written by magyro solve."),
    output: Optional[Path] = typer.Option(None, "-o", "--output", help="Write the report JSON here."),
    plot: Optional[Path] = typer.Option(None, "--plot", help="Write the figure here (.png, .pdf or .svg; needs matplotlib)."),
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


@app.command("observe")
def observe_command(
    session: Path = typer.Argument(..., help="Session file (.parquet or .csv, docs/spec.md section 2)."),
    output: Optional[Path] = typer.Option(None, "-o", "--output", help="Write the report JSON here (schema magyro.observability/1)."),
    plot: Optional[Path] = typer.Option(None, "--plot", help="Write a figure here (.png, .pdf, .svg): field-direction coverage, eigenvalue growth, rates. Needs matplotlib."),
    gyro_unit: Optional[str] = typer.Option(None, "--gyro-unit", help="rad/s or deg/s (overrides the file's metadata)."),
    mag_unit: Optional[str] = typer.Option(None, "--mag-unit", help="Magnetometer unit label, e.g. uT."),
    gyro_noise_deg_s_sqrt_hz: Optional[float] = typer.Option(None, "--gyro-noise", help="Gyro noise density, deg/s/sqrt(Hz) (default: estimated)."),
    mag_noise: Optional[float] = typer.Option(None, "--mag-noise", help="Magnetometer noise std, in its unit (default: estimated)."),
    target_scale_ppm: float = typer.Option(1000.0, "--target-scale-ppm", min=0.0, help="One-sigma target of the gyro scale factors (K_g diagonal), ppm."),
    target_nonorth_deg: float = typer.Option(0.1, "--target-nonorth-deg", min=0.0, help="One-sigma target of the gyro non-orthogonality (K_g off-diagonal), deg."),
    target_bias_deg_s: float = typer.Option(0.01, "--target-bias-deg-s", min=0.0, help="One-sigma target of the gyro bias, deg/s."),
    target_misalignment_deg: float = typer.Option(0.1, "--target-misalignment-deg", min=0.0, help="One-sigma target of the gyro-magnetometer misalignment, deg."),
    no_repair: Optional[List[str]] = typer.Option(None, "--no-repair", help="Turn a repair of the recording off: restamp, held, saturation, spikes, or all (repeat for several)."),
    max_std_scale_ppm: float = typer.Option(StdBounds.scale_ppm, "--max-std-scale-ppm", min=0.0, help="Refuse (exit 3) when the predicted one-sigma of a gyro scale factor exceeds this, ppm."),
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

    def action():
        bounds = StdBounds(max_std_scale_ppm, max_std_nonorth_deg, max_std_bias_deg_s, max_std_misalignment_deg)
        options = Options.in_user_units(gyro_noise_deg_s_sqrt_hz, mag_noise, max_std=bounds,
                                        repairs=Repairs.without(no_repair or []))
        targets = (target_scale_ppm, target_nonorth_deg, target_bias_deg_s, target_misalignment_deg)
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


@app.command("check")
def check_command(
    session: Path = typer.Argument(..., help="Session file (.parquet or .csv, docs/spec.md section 2)."),
    output: Optional[Path] = typer.Option(None, "-o", "--output", help="Write the check as JSON here (schema magyro.recording/1)."),
    gyro_unit: Optional[str] = typer.Option(None, "--gyro-unit", help="rad/s or deg/s (overrides the file's metadata)."),
    mag_unit: Optional[str] = typer.Option(None, "--mag-unit", help="Magnetometer unit label, e.g. uT."),
    no_repair: Optional[List[str]] = typer.Option(None, "--no-repair", help="Turn a repair of the recording off: restamp, held, saturation, spikes, or all (repeat for several)."),
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


# --------------------------------------------------------------------------- apply, export (issue 12)


@app.command("apply")
def apply_command(
    calibration: Path = typer.Argument(..., help="Calibration JSON written by magyro solve."),
    session: Path = typer.Argument(..., help="Session file to correct (.parquet or .csv, docs/spec.md section 2)."),
    output: Path = typer.Option(..., "-o", "--output", help="Corrected session file to write (.parquet or .csv)."),
    frame: str = typer.Option("b", "--frame", help="Frame of the corrected rates: b (the gyro's: K_g y + eps_b) or m (the magnetometer's: K y + eps)."),
    gyro_unit: Optional[str] = typer.Option(None, "--gyro-unit", help="rad/s or deg/s (overrides the file's metadata)."),
    mag_unit: Optional[str] = typer.Option(None, "--mag-unit", help="Magnetometer unit label, e.g. uT."),
):
    """Correct a session with a calibration: gyro as calibrated rates in rad/s, magnetometer as the unit field R (y - h)."""
    from magyro.api import apply_file

    def action():
        s = apply_file(calibration, session, output, frame=frame, gyro_unit=gyro_unit, mag_unit=mag_unit)
        typer.echo(f"corrected session written to {output}: {len(s.t_gyro_s)} gyro samples in rad/s (frame {frame}), "
                   f"{len(s.t_mag_s)} magnetometer samples as the unit field")

    run_guarded(action)


@app.command("export")
def export_command(
    calibration: Path = typer.Argument(..., help="Calibration JSON written by magyro solve."),
    fmt: str = typer.Option(..., "--format", "-f", help="yaml (a plain, commented YAML file), c (a C99 header with the matrices and apply functions), kalibr (Kalibr's scale-misalignment IMU yaml, exact) or px4 (a QGroundControl .params file: gyro offset only, its cost stated)."),
    output: Optional[Path] = typer.Option(None, "-o", "--output", help="Write here (default: print to the terminal)."),
):
    """The calibration for other programs: K_g, bias, C_b_m, K, eps, R, h and the model, as YAML or a C99 header."""
    from magyro.api import export_file

    def action():
        text = export_file(calibration, fmt, output)
        if output is None:
            typer.echo(text, nl=False)
        else:
            typer.echo(f"{fmt} export written to {output}")

    run_guarded(action)


@app.command("report")
def report_command(
    session: Path = typer.Argument(..., help="The session file the calibration was solved from."),
    calibration: Path = typer.Argument(..., help="The calibration JSON (magyro solve -o)."),
    output: Path = typer.Option(..., "-o", "--output", help="The HTML page to write (self-contained: opens with no network)."),
    split_check: bool = typer.Option(True, "--split-check/--no-split-check", help="Compute the split-half check when the calibration has none (two more solves)."),
    gyro_unit: Optional[str] = typer.Option(None, "--gyro-unit", help="rad/s or deg/s (overrides the file's metadata)."),
    mag_unit: Optional[str] = typer.Option(None, "--mag-unit", help="Magnetometer unit label, e.g. uT."),
    quiet: bool = typer.Option(False, "--quiet", "-q", help="No progress and no verdict on the terminal."),
):
    """One HTML page to read or send: the recording check, excitation, calibration with std, residuals, split-half
    check and dead reckoning, each with a figure and a sentence saying whether it is good (needs magyro[plot])."""
    from magyro.report import report_file

    def action():
        say = None if quiet else (lambda message: typer.echo(f"report: {message}", err=True))
        report = report_file(session, calibration, output, split_check=split_check, gyro_unit=gyro_unit,
                             mag_unit=mag_unit, progress=say)
        if not quiet:
            typer.echo(report.verdict)
            typer.echo(f"report written to {output}")

    run_guarded(action, progress=False)   # its own lines


from magyro.cli_live import watch_command  # noqa: E402  (its module uses this one's helpers)
from magyro.cli_plan import plan_command  # noqa: E402

app.command("watch")(watch_command)
app.command("plan")(plan_command)


def main():
    app()


if __name__ == "__main__":
    sys.exit(main())
