"""`magyro solve`: the joint calibration of one session."""
from __future__ import annotations

from pathlib import Path
from typing import List, Optional

import typer

from magyro.options import STANDARD_GRAVITY_M_S2

from magyro.cli.common import gyro_noise_density, gyro_noise_help, NO_REPAIR_HELP, run_guarded
from magyro.options import Repairs, StdBounds


def solve(
    session: Path = typer.Argument(..., metavar="SESSION", readable=False, help="Session file (.parquet or .csv, docs/spec.md section 2)."),
    output: Optional[Path] = typer.Option(None, "-o", "--output", readable=False, help="Write the calibration JSON here."),
    gyro_unit: Optional[str] = typer.Option(None, "--gyro-unit", help="rad/s or deg/s (overrides the file's metadata)."),
    mag_unit: Optional[str] = typer.Option(None, "--mag-unit", help="Magnetometer unit label, e.g. uT."),
    gyro_noise_deg_s_sqrt_hz: Optional[float] = typer.Option(None, "--gyro-noise", parser=gyro_noise_density, metavar="DENSITY", help=gyro_noise_help("estimated")),
    noise: Optional[Path] = typer.Option(None, "--noise", readable=False, help="A noise file (magyro noise -o): its gyro white noise instead of the estimate (not with --gyro-noise)."),
    mag_noise: Optional[float] = typer.Option(None, "--mag-noise", help="Magnetometer noise std, in its unit (default: estimated)."),
    stride: Optional[int] = typer.Option(None, "--stride", min=1, help="One attitude node every N segments, one per gyro or magnetometer sample (default: 12, or 4 below 96 Hz; other strides compile their kernels once)."),
    force: bool = typer.Option(False, "--force", help="Solve even when the motion does not excite every parameter."),
    loss: str = typer.Option("l2", "--loss", help="Loss on the magnetometer residuals: l2, or huber (robust to spikes and local iron)."),
    hard_iron_walk: Optional[float] = typer.Option(None, "--hard-iron-walk", help="Experimental (nls): let the hard iron move, as a random walk of this density (magnetometer unit per sqrt(s), e.g. 1 for uT); for iron or a magnet on the board whose field drifts. See docs/real-data.md section 4 for where it helps and where it does not."),
    hand_states: bool = typer.Option(True, "--hand-states/--no-hand-states", help="--method nls with the accelerometer: where the hand moved the device while it turned, its velocity is a state at every node, so that its acceleration is told from gravity (default); --no-hand-states weights the accelerometer by the hand's size instead (docs/accelerometer.md)."),
    time_offset: bool = typer.Option(True, "--time-offset/--no-time-offset", help="Estimate the magnetometer's lag behind the gyro (default) or fix it to 0."),
    keep_rests: bool = typer.Option(False, "--keep-rests", help="Keep the rests at both ends in the solve (default: trimmed, as the paper does)."),
    split_check: bool = typer.Option(False, "--split-check", help="Also calibrate each half of the recording alone and warn when they disagree beyond their std (about 2x the time)."),
    no_repair: Optional[List[str]] = typer.Option(None, "--no-repair", help=NO_REPAIR_HELP),
    max_std_scale_ppm: float = typer.Option(StdBounds.scale_ppm, "--max-std-scale-ppm", min=0.0, help="Refusal bound (not the targets): refuse (exit 3) when the predicted one-sigma of a gyro scale factor exceeds this, ppm."),
    max_std_nonorth_deg: float = typer.Option(StdBounds.nonorthogonality_deg, "--max-std-nonorth-deg", min=0.0, help="... of a non-orthogonality angle, deg."),
    max_std_bias_deg_s: float = typer.Option(StdBounds.bias_deg_s, "--max-std-bias-deg-s", min=0.0, help="... of a gyro bias, deg/s."),
    max_std_misalignment_deg: float = typer.Option(StdBounds.misalignment_deg, "--max-std-misalignment-deg", min=0.0, help="... of the misalignment, deg."),
    method: str = typer.Option("nls", "--method", help="nls (the joint least squares) or ekf (the paper's two steps and error-state EKF)."),
    history: Optional[Path] = typer.Option(None, "--history", readable=False, help="--method ekf: write K, bias, m^i and their 1-sigma over time (Parquet)."),
    history_plot: Optional[Path] = typer.Option(None, "--history-plot", readable=False, help="--method ekf: plot them like the paper's Fig. 3/6/7 (needs matplotlib: pip install '.[plot]' in a clone, 'magyro[plot]' from PyPI)."),
    trajectory: Optional[Path] = typer.Option(None, "--trajectory", readable=False, help="--method nls: write the solved attitude at the nodes (quaternion C_m_i and its std) and the calibrated field (Parquet)."),
    accelerometer: Optional[bool] = typer.Option(None, "--accelerometer/--no-accelerometer", help="--method nls: calibrate the accelerometer (ax ay az, m/s^2) in the same least squares: K_a, bias, C_b_a against gravity. Default: when the session has one, left out with a warning saying why when it cannot be calibrated; --accelerometer insists (exit 2 without one, exit 3 past its bound), --no-accelerometer never."),
    gravity: float = typer.Option(STANDARD_GRAVITY_M_S2, "--gravity", min=9.7, max=9.9, help="The local gravity in m/s^2 the accelerometer is calibrated against."),
    quiet: bool = typer.Option(False, "--quiet", "-q", help="No table on the terminal."),
):
    """The joint calibration: magnetometer ellipsoid, gyro K_g, bias, misalignment, field, attitude, and the accelerometer (K_a, bias, C_b_a) when the session has one.

    --stride, --loss, --hard-iron-walk, --hand-states, --time-offset and --split-check apply to the nls method only.
    """
    from magyro.api import solve_file
    from magyro.options import Options

    def action():
        bounds = StdBounds(max_std_scale_ppm, max_std_nonorth_deg, max_std_bias_deg_s, max_std_misalignment_deg)
        if noise is not None:
            from magyro.noise_file import gyro_noise_deg_s_sqrt_hz_option

            density = gyro_noise_deg_s_sqrt_hz_option(noise, gyro_noise_deg_s_sqrt_hz)
        else:
            density = gyro_noise_deg_s_sqrt_hz
        options = Options.in_user_units(density, mag_noise, force=force, estimate_time_offset=time_offset,
                                        trim_rests=not keep_rests, split_check=split_check, max_std=bounds,
                                        repairs=Repairs.without(no_repair or []), accelerometer=accelerometer,
                                        gravity_m_s2=gravity)
        cal = solve_file(session, options, method, {"stride": stride, "loss": loss, "hard_iron_walk": hard_iron_walk,
                                                     "hand_states": hand_states},
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
