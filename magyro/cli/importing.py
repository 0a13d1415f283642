"""`magyro import broad|csv|ulog|rosbag|dataflash`: recordings from other tools as session files."""
from __future__ import annotations

from pathlib import Path
from typing import List, Optional

import typer

from magyro.cli.common import Command, as_written, run_guarded

import_app = typer.Typer(no_args_is_help=True, help="Convert recordings into session files: BROAD trials (broad), phone or logger CSV exports (csv), PX4 flight logs (ulog), ROS bags (rosbag), ArduPilot logs (dataflash).")


@import_app.command("broad", cls=Command)
@as_written
def import_broad_command(
    trial: Path = typer.Argument(..., metavar="TRIAL", readable=False, help="A BROAD trial file (.mat, or .hdf5/.h5 with h5py installed)."),
    output: Path = typer.Option(..., "-o", "--output", readable=False, help="Session file to write (.parquet or .csv)."),
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


@import_app.command("csv", cls=Command)
@as_written
def import_csv_command(
    sources: List[Path] = typer.Argument(..., metavar="SOURCES...", readable=False, help="CSV export(s): one file with a time column and sensor columns, or one file per sensor (gyro, magnetometer, optional accelerometer) merged on time; with --preset also the app's export folder or zip."),
    output: Path = typer.Option(..., "-o", "--output", readable=False, help="Session file to write (.parquet or .csv)."),
    preset: Optional[str] = typer.Option(None, "--preset", help="An app's export: sensor-logger or phyphox (files, columns, units and time known; no --gyro-unit/--mag-unit/--map)."),
    column_map: Optional[List[str]] = typer.Option(None, "--map", "-m", help="NAME=COLUMN for session names t gx gy gz mx my mz (ax ay az, qw qx qy qz), e.g. -m gx=gyroX; with several files NAME=FILE:COLUMN, e.g. -m gx=gyro.csv:x -m t=gyro.csv:time. Repeat, or comma-separate. Unmapped names are guessed from common headers."),
    gyro_unit: Optional[str] = typer.Option(None, "--gyro-unit", help="Unit of the gyro columns: rad/s or deg/s (needed without --preset unless the header says it, e.g. \"gx (deg/s)\")."),
    mag_unit: Optional[str] = typer.Option(None, "--mag-unit", help="Unit of the magnetometer columns (kept): uT, nT, G, mG, counts, ... (needed without --preset unless the header says it, e.g. \"mag_x [uT]\")."),
    time_unit: Optional[str] = typer.Option(None, "--time-unit", help="Unit of the time column(s): s, ms, us or ns (default: the header's, e.g. \"Time (ms)\", else s; times restart at 0 at the earliest stamp)."),
    acc_unit: Optional[str] = typer.Option(None, "--acc-unit", help="Unit of the accelerometer columns: m/s^2, g or mg (default: the header's, e.g. \"ax (g)\", else m/s^2)."),
    delimiter: Optional[str] = typer.Option(None, "--delimiter", help="Column separator (default: detected among , ; tab |)."),
    skip_rows: int = typer.Option(0, "--skip-rows", min=0, help="Lines to skip right after the header of every file (a units row, a second header row)."),
    header_line: int = typer.Option(0, "--header-line", min=0, help="Lines before the header of every file (a preamble)."),
    start: Optional[float] = typer.Option(None, "--start", help="Drop samples before this time (s after the first stamp)."),
    end: Optional[float] = typer.Option(None, "--end", help="Drop samples after this time (s)."),
    rate: Optional[float] = typer.Option(None, "--rate", help="Sampling rate in Hz of one CSV whose time column is a sample counter (or which has none): t = count / rate."),
):
    """A phone or logger CSV export (one file, or one file per sensor, or an app's export by --preset) as a session file."""
    from magyro.io.csv_presets import convert_csv

    def action():
        s = convert_csv(sources, output, preset=preset, column_map_items=column_map, gyro_unit=gyro_unit,
                        mag_unit=mag_unit, time_unit=time_unit, acc_unit=acc_unit, delimiter=delimiter,
                        skip_rows=skip_rows, header_line=header_line, start_s=start, end_s=end, rate_hz=rate)
        typer.echo(f"session written to {output}: {len(s.t_gyro_s)} gyro samples ({s.gyro_rate_hz:.1f} Hz), "
                   f"{len(s.t_mag_s)} magnetometer samples ({s.mag_rate_hz:.1f} Hz), {s.duration_s:.1f} s; "
                   f"columns {s.metadata['column_map']}")
        if s.metadata.get("sensor_note"):
            typer.echo(s.metadata["sensor_note"])

    run_guarded(action)


@import_app.command("ulog", cls=Command)
@as_written
def import_ulog_command(
    log: Path = typer.Argument(..., metavar="LOG", readable=False, help="A PX4 ULog file (.ulg)."),
    output: Path = typer.Option(..., "-o", "--output", readable=False, help="Session file to write (.parquet or .csv)."),
    instance: int = typer.Option(0, "--instance", min=0, help="Topic instance (multi_id), e.g. 1 for the second gyro and magnetometer."),
    topics: Optional[str] = typer.Option(None, "--topics", help="GYRO,MAG topics, e.g. sensor_combined,vehicle_magnetometer (default: sensor_gyro,sensor_mag when logged fast enough, else sensor_combined with vehicle_magnetometer)."),
):
    """A PX4 flight log: gyro (rad/s), magnetometer (gauss) and accelerometer (m/s^2, when logged), fresh samples only, times from the first sample."""
    from magyro.io.ulog import convert_ulog, parse_topics

    def action():
        s = convert_ulog(log, output, instance=instance, topics=parse_topics(topics))
        m = s.metadata
        typer.echo(f"session written to {output}: {len(s.t_gyro_s)} gyro samples ({s.gyro_rate_hz:.1f} Hz) from "
                   f"{m['ulog_gyro_topic']} instance {m['ulog_instance']}, {len(s.t_mag_s)} magnetometer samples "
                   f"({s.mag_rate_hz:.1f} Hz, gauss) from {m['ulog_mag_topic']}"
                   + (f", {len(s.t_acc_s)} accelerometer samples (m/s^2) from {m['ulog_acc_topic']}"
                      if s.t_acc_s is not None else ", no accelerometer") + f", {s.duration_s:.1f} s")
        typer.echo("PX4 logs are usually already calibrated by the autopilot; the metadata says which fields were used")

    run_guarded(action)


@import_app.command("rosbag", cls=Command)
@as_written
def import_rosbag_command(
    bag: Path = typer.Argument(..., metavar="BAG", readable=False, help="A ROS1 bag file (.bag) or a ROS2 bag folder."),
    output: Path = typer.Option(..., "-o", "--output", readable=False, help="Session file to write (.parquet or .csv)."),
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


@import_app.command("dataflash", cls=Command)
@as_written
def import_dataflash_command(
    log: Path = typer.Argument(..., metavar="LOG", readable=False, help="An ArduPilot DataFlash log: .bin (with pymavlink), or Mission Planner's .log or .mat export."),
    output: Path = typer.Option(..., "-o", "--output", readable=False, help="Session file to write (.parquet or .csv)."),
    imu: int = typer.Option(0, "--imu", min=0, help="IMU instance (the I column, or IMU2/IMU3 in older logs), e.g. 1 for the second gyro."),
    mag: int = typer.Option(0, "--mag", min=0, help="Compass instance (the I column, or MAG2/MAG3 in older logs)."),
):
    """An ArduPilot log: gyro (rad/s), raw magnetometer (logged minus the offsets in force, uT), accelerometer (m/s^2), ATT as the reference quaternion."""
    from magyro.io.dataflash import convert_dataflash

    def action():
        s = convert_dataflash(log, output, imu=imu, mag=mag)
        m = s.metadata
        n_ref = 0 if s.t_quat_s is None else len(s.t_quat_s)
        typer.echo(f"session written to {output}: {len(s.t_gyro_s)} gyro samples ({s.gyro_rate_hz:.1f} Hz) from "
                   f"{m['dataflash_imu']}, {len(s.t_mag_s)} magnetometer samples ({s.mag_rate_hz:.1f} Hz, raw, uT) "
                   f"from {m['dataflash_mag']}"
                   + (f", {len(s.t_acc_s)} accelerometer samples (m/s^2)" if s.t_acc_s is not None else "")
                   + f", {n_ref} reference quaternions (ATT), {s.duration_s:.1f} s")
        typer.echo(f"autopilot gyro offsets: {m['dataflash_gyro_offsets_applied']}")

    run_guarded(action)
