"""`magyro` on the command line: a thin layer over the Python API.

Every failure the user can fix ends with one plain message on stderr and the
SPEC exit code (2 unusable input, 3 not observable, 1 solver failed).
"""
from __future__ import annotations

import os
import sys

# one BLAS thread: the products here are small, and on a busy 2-core machine OpenBLAS's
# threads made a 12-column least squares 100x slower (set before numpy is imported)
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
from pathlib import Path
from typing import List, Optional

import numpy as np
import typer

from magyro import __version__
from magyro.errors import MagyroError

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
    loss: str = typer.Option("l2", "--loss", help="Loss on the magnetometer residuals: l2, or huber (robust to spikes and local iron)."),
    time_offset: bool = typer.Option(True, "--time-offset/--no-time-offset", help="Estimate the magnetometer's lag behind the gyro (default) or fix it to 0."),
    keep_rests: bool = typer.Option(False, "--keep-rests", help="Keep the rests at both ends in the solve (default: trimmed, as the paper does)."),
    split_check: bool = typer.Option(False, "--split-check", help="Also calibrate each half of the recording alone and warn when they disagree beyond their std (about 2x the time)."),
    method: str = typer.Option("nls", "--method", help="nls (the joint least squares) or ekf (the paper's two steps and error-state EKF)."),
    history: Optional[Path] = typer.Option(None, "--history", help="--method ekf: write K, bias, m^i and their 1-sigma over time (Parquet)."),
    history_plot: Optional[Path] = typer.Option(None, "--history-plot", help="--method ekf: plot them like the paper's Fig. 3/6/7 (needs magyro[plot])."),
    quiet: bool = typer.Option(False, "--quiet", "-q", help="No table on the terminal."),
):
    """The joint calibration: magnetometer ellipsoid, gyro K_g, bias, misalignment, field, attitude.

    --stride, --loss, --time-offset and --split-check apply to the nls method only.
    """
    from magyro.nls.solve import Options, calibrate
    from magyro.errors import InputError
    from magyro.io.sessions import load_session, write_text_atomically

    def action():
        s = load_session(session, gyro_unit=gyro_unit, mag_unit=mag_unit)
        opts = Options(
            gyro_noise_density_rad_s_sqrt_hz=None if gyro_noise_deg_s_sqrt_hz is None else float(np.deg2rad(gyro_noise_deg_s_sqrt_hz)),
            mag_noise_std=mag_noise, stride=stride, force=force, loss=loss,
            estimate_time_offset=time_offset, trim_rests=not keep_rests, split_check=split_check,
        )
        if method not in ("nls", "ekf"):
            raise InputError(f"unknown method '{method}'; use nls or ekf")
        if method == "ekf" and split_check:
            raise InputError("--split-check needs --method nls (it compares two least-squares solves)")
        if method == "nls" and (history is not None or history_plot is not None):
            raise InputError("--history and --history-plot need --method ekf (the least squares has no estimate over time)")
        if method == "ekf":
            from magyro.ekf.filter import ekf_calibrate, plot_history

            cal, hist = ekf_calibrate(s, opts)
            if history is not None:
                hist.write_parquet(history)
            if history_plot is not None:
                plot_history(hist, history_plot, title=f"{session.name}: EKF estimates, +/- 3 sigma")
        else:
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
    from magyro.studies import simulate as sim
    from magyro.io.sessions import write_session

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


@app.command()
def montecarlo(
    problem: str = typer.Argument(..., help="Problem TOML file, or the name of one shipped in problems/ (e.g. paper-table1)."),
    runs: int = typer.Option(..., "--runs", "-n", min=1, help="Number of simulated sessions (noise seeds seed0 .. seed0+N-1)."),
    jobs: int = typer.Option(1, "--jobs", "-j", min=1, help="Solve in this many processes (one BLAS thread each)."),
    method: str = typer.Option("nls", "--method", help="nls, ekf, or nls,ekf to solve the same sessions with both."),
    seed0: int = typer.Option(0, "--seed0", min=0, help="First noise seed."),
    output: Optional[Path] = typer.Option(None, "-o", "--output", help="Write the table and every run's estimates as JSON (schema magyro.montecarlo/1)."),
    csv_path: Optional[Path] = typer.Option(None, "--csv", help="Write the table as CSV (one row per method and parameter)."),
    quiet: bool = typer.Option(False, "--quiet", "-q", help="No progress and no table on the terminal."),
):
    """Table-I-style accuracy study: N seeded sessions, each solved; mean, std, Cramer-Rao bound of every estimate.

    Exit 0 when every run succeeded, 1 when any run failed: the failed runs are
    listed with their seed and message, and the table of the successful ones is
    still printed and written.
    """
    from magyro.studies import montecarlo as mc
    from magyro.studies.simulate import load_problem

    def action():
        prob = load_problem(problem)
        with mc.progress_display(runs, enabled=not quiet) as progress:
            result = mc.run_montecarlo(prob, runs, jobs=jobs, method=method, seed0=seed0, progress=progress)
        mc.write_outputs(result, output, csv_path)
        if not quiet:
            typer.echo(result.table())
            for path in (output, csv_path):
                if path is not None:
                    typer.echo(f"written to {path}")
        return result

    result = run_guarded(action)
    if not result.all_succeeded:
        fail(f"{result.failed_count} of {runs * len(result.methods)} runs failed (seeds and messages above and in the JSON); "
             "the table holds the successful ones", 1)


# --------------------------------------------------------------------------- import, validate (issue 6)

import_app = typer.Typer(no_args_is_help=True, help="Convert recordings into session files (BROAD trials, CSV exports).")
app.add_typer(import_app, name="import")


def _write_imported(s, output: Path) -> None:
    """Parquet with zstd (metadata kept), or CSV by suffix."""
    from magyro.io.importers import write_session_parquet
    from magyro.io.sessions import PARQUET_SUFFIXES, write_session

    if output.suffix.lower() in PARQUET_SUFFIXES:
        write_session_parquet(s, output)
    else:
        write_session(s, output)


def _cut(s, start: Optional[float], end: Optional[float]):
    from magyro.io.importers import trim

    if start is None and end is None:
        return s
    return trim(s, s.t_gyro_s[0] if start is None else start, s.t_gyro_s[-1] if end is None else end)


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
    from magyro.io.importers import BROAD_CITATION, decimate, import_broad, import_broad_movement

    def action():
        s = import_broad_movement(trial, rest_s) if movement else import_broad(trial)
        s = decimate(_cut(s, start, end), decimate_by)
        _write_imported(s, output)
        n_truth = 0 if s.t_quat_s is None else len(s.t_quat_s)
        typer.echo(f"session written to {output}: {len(s.t_gyro_s)} samples at {s.gyro_rate_hz:.3f} Hz, "
                   f"{s.t_gyro_s[0]:.3f} to {s.t_gyro_s[-1]:.3f} s, {n_truth} truth quaternions")
        typer.echo(f"BROAD data are CC BY 4.0; credit {BROAD_CITATION}")

    run_guarded(action)


@import_app.command("csv")
def import_csv_command(
    source: Path = typer.Argument(..., help="CSV export: a time column and sensor columns; sensors may sit on separate rows."),
    output: Path = typer.Option(..., "-o", "--output", help="Session file to write (.parquet or .csv)."),
    column_map: Optional[List[str]] = typer.Option(None, "--map", "-m", help="NAME=COLUMN for session names t gx gy gz mx my mz (ax ay az, qw qx qy qz), e.g. -m gx=gyroX; repeat, or comma-separate. Unmapped names are guessed from common headers."),
    gyro_unit: str = typer.Option(..., "--gyro-unit", help="Unit of the gyro columns: rad/s or deg/s."),
    mag_unit: str = typer.Option(..., "--mag-unit", help="Unit of the magnetometer columns (kept): uT, nT, G, mG, counts, ..."),
    time_unit: str = typer.Option("s", "--time-unit", help="Unit of the time column: s, ms, us or ns (times restart at 0)."),
    acc_unit: str = typer.Option("m/s^2", "--acc-unit", help="Unit of the accelerometer columns: m/s^2, g or mg."),
    delimiter: Optional[str] = typer.Option(None, "--delimiter", help="Column separator (default: detected among , ; tab |)."),
    start: Optional[float] = typer.Option(None, "--start", help="Drop samples before this time (s after the first stamp)."),
    end: Optional[float] = typer.Option(None, "--end", help="Drop samples after this time (s)."),
):
    """A phone or logger CSV export, with column and unit mapping, as a session file."""
    from magyro.errors import InputError
    from magyro.io.importers import import_csv

    def action():
        mapping = {}
        for item in column_map or []:
            for pair in item.split(","):
                name, sep, column = pair.partition("=")
                if not sep or not name.strip() or not column.strip():
                    raise InputError(f"--map {pair!r}: expected NAME=COLUMN, e.g. --map gx=gyroX")
                mapping[name.strip()] = column.strip()
        s = import_csv(source, mapping, gyro_unit=gyro_unit, mag_unit=mag_unit, time_unit=time_unit,
                       acc_unit=acc_unit, delimiter=delimiter)
        s = _cut(s, start, end)
        _write_imported(s, output)
        typer.echo(f"session written to {output}: {len(s.t_gyro_s)} gyro samples ({s.gyro_rate_hz:.1f} Hz), "
                   f"{len(s.t_mag_s)} magnetometer samples ({s.mag_rate_hz:.1f} Hz), {s.duration_s:.1f} s; "
                   f"columns {s.metadata['column_map']}")

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
    from magyro.io.sessions import load_session, write_text_atomically
    from magyro.studies.dead_reckoning import plot_validation, validate as run_validation

    def action():
        s = load_session(session, gyro_unit=gyro_unit, mag_unit=mag_unit)
        report = run_validation(s, calibration)
        if plot is not None:
            plot_validation(report, plot)
        if output is not None:
            write_text_atomically(output, report.to_json(include_series=series) + "\n")
        if not quiet:
            typer.echo(report.table())
            for path, what in ((output, "report"), (plot, "figure")):
                if path is not None:
                    typer.echo(f"{what} written to {path}")

    run_guarded(action)


@app.command("observe")
def observe_command(
    session: Path = typer.Argument(..., help="Session file (.parquet or .csv, SPEC section 2)."),
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
    quiet: bool = typer.Option(False, "--quiet", "-q", help="No table on the terminal."),
):
    """Does the recording excite every parameter, and how well? The excitation report, no solve.

    Exit 0 when the excitation is sufficient or marginal, 3 when insufficient (the
    report is still printed and written), 2 when the input is unusable.
    """
    from magyro.nls.solve import Options
    from magyro.io.sessions import load_session, write_text_atomically
    from magyro.observability.report import Targets, observe, plot_report, require_matplotlib

    def action():
        if plot is not None:
            require_matplotlib()  # fail before any work or output
        s = load_session(session, gyro_unit=gyro_unit, mag_unit=mag_unit)
        opts = Options(
            gyro_noise_density_rad_s_sqrt_hz=None if gyro_noise_deg_s_sqrt_hz is None else float(np.deg2rad(gyro_noise_deg_s_sqrt_hz)),
            mag_noise_std=mag_noise,
        )
        targets = Targets(target_scale_ppm, target_nonorth_deg, target_bias_deg_s, target_misalignment_deg)
        report = observe(s, opts, targets)
        if output is not None:
            write_text_atomically(output, report.to_json() + "\n")
        if plot is not None:
            plot_report(report, plot)
        if not quiet:
            typer.echo(report.table())
            for path, what in ((output, "report"), (plot, "figure")):
                if path is not None:
                    typer.echo(f"{what} written to {path}")
        return report

    report = run_guarded(action)
    if report.verdict == "insufficient":
        fail(f"insufficient excitation: {report.reason}. " + " ".join(report.advice), 3)


def main():
    app()


if __name__ == "__main__":
    sys.exit(main())
