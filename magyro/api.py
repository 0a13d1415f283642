"""The Python API in one place: what `magyro solve` and `magyro observe` do, for callers of the library.

    import magyro
    session = magyro.load_session("data/broad-02.parquet")
    cal = magyro.calibrate(session)                                   # the joint least squares
    cal = magyro.calibrate(session, magyro.Options(force=True), method=magyro.EKF())
    report = magyro.observe(session)                                  # is the motion enough?

`Options` holds what is true of the sensors and the recording; the method
object (`NLS`, `EKF`) holds that method's own knobs.
"""
from __future__ import annotations

from dataclasses import replace
from pathlib import Path

from magyro.errors import InputError
from magyro.options import Options
from magyro.result.calibration import Calibration
from magyro.result.check import MAX_TURNING_MISFIT  # noqa: F401  (magyro.report reads it here)
from magyro.session import Session


def method_named(name: str, **knobs):
    """The method object for a method's name ('nls' or 'ekf'), with its knobs."""
    if name == "nls":
        from magyro.nls.method import NLS

        return NLS(**knobs)
    if name == "ekf":
        from magyro.ekf.method import EKF

        return EKF(**knobs)
    raise InputError(f"unknown method '{name}'; use nls or ekf")


def calibrate(session: Session, options: Options | None = None, method=None) -> Calibration:
    """Calibrate gyro and magnetometer from one session with `method` (default: `NLS()`).

    Either method goes through the same recording check and repairs, front end and
    result check (`magyro.result.check`). With `Options(split_check=True)` each half of
    the recording is also calibrated alone and compared (`Calibration.consistency`, and
    a warning when they disagree).
    """
    return calibrate_with_history(session, options, method)[0]


def calibrate_with_history(session: Session, options: Options | None = None, method=None):
    """(Calibration, the EKF's history or None): `calibrate`, keeping the filter's estimates over time when the
    method has them. The calibration is the same, number for number, as `calibrate`'s."""
    from magyro.methods import accelerometer_not_calibrated, check_method_options, with_accelerometer_decided
    from magyro.progress import step

    options = options or Options()
    method = method or method_named("nls")
    check_method_options(method, options, session)
    step("checking the recording")
    session, recording = checked_recording(session, options)
    cal, history = solved_with_history(method, session, replace(options, split_check=False), options.accelerometer is None
                                       and with_accelerometer_decided(method, options, session).accelerometer)
    cal.warnings.extend(filter(None, [accelerometer_not_calibrated(method, options, session)]))   # the EKF's: said
    options = replace(options, accelerometer=cal.accelerometer is not None)   # the halves as the whole
    step("checking that the result explains the recording")
    cal.recording = recording
    cal.warnings[:0] = [f"recording: {f.message}; {f.fix}" for f in recording.warnings if not f.repaired]
    check_the_result_explains_the_data(cal, session, options, method)
    if options.split_check:
        add_split_check(cal, session, options, method)
    return cal, history


def solved_with_history(method, session: Session, options: Options, accelerometer_by_default: bool):
    """(Calibration, history or None) of the method. With `accelerometer_by_default` (the session has one and the
    options left it to magyro) the accelerometer joins the solve, and when it cannot be calibrated (its std past the
    refusal bound, a hand too big for gravity to be read, or no solution with it; with --force too) the gyro and the
    magnetometer are calibrated alone, saying why."""
    from magyro.errors import AccelerometerRefused, SolverError, one_line
    from magyro.methods import run_method
    from magyro.nls.run import accelerometer_gate

    def run(opts):
        if hasattr(method, "calibrate_with_history"):
            return method.calibrate_with_history(session, opts)
        return run_method(method, session, opts), None

    if not accelerometer_by_default:
        return run(options)
    try:
        cal, history = run(replace(options, accelerometer=True))
        if options.force:   # --force lets the gyro through; an accelerometer nobody asked for is left out as without it
            accelerometer_gate(cal, replace(options, force=False))
        return cal, history
    except (AccelerometerRefused, SolverError) as refused:
        cal, history = run(replace(options, accelerometer=False))
        cal.warnings.insert(0, f"accelerometer left out: {one_line(refused, None)} (--accelerometer insists: exit "
                               f"{refused.exit_code}; --no-accelerometer leaves it out without trying)")
        return cal, history


def checked_recording(session: Session, options: Options):
    """(the session repaired as `options.repairs` allows, the recording check): InputError (exit 2) when the
    check finds the recording unusable as it is (stamps that are not seconds, too few samples, ...)."""
    from magyro.front.repairs import repair_recording

    repaired, recording = repair_recording(session, options.repairs)
    if recording.errors:
        raise InputError(recording.error_message())
    return repaired, recording


def check_the_result_explains_the_data(cal: Calibration, session: Session, options: Options, method) -> None:
    """SolverError (exit 1) when the calibration does not explain the recording, warnings when it disagrees with
    the rests (`magyro.result.check`, the same for every method)."""
    from magyro.front.prepare import moving_session
    from magyro.result.check import check_result

    check_result(cal, moving_session(session, options)[0], method.name)


def add_split_check(cal: Calibration, session: Session, options: Options, method) -> None:
    """Add the split-half consistency report (and its warning) to `cal`."""
    from magyro.front.prepare import moving_session
    from magyro.methods import run_method
    from magyro.result import consistency

    moving = moving_session(session, options)[0]
    halves = replace(method, trajectory=False) if getattr(method, "trajectory", False) else method  # no attitudes kept

    def calibrate_half(half: Session, half_options: Options) -> Calibration:   # a half passes the same result check
        from magyro.result.check import check_result

        result = run_method(halves, half, half_options)
        check_result(result, half, method.name)
        return result

    report = consistency.split_check(moving, cal, replace(options, split_check=False), calibrate_half)
    cal.consistency = report
    warning = consistency.split_warning(report)
    if warning:
        cal.warnings.append(warning)


def observe(session: Session, options: Options | None = None, targets=None, method=None):
    """The excitation report of `magyro observe`: rank, weak directions, coverage, predicted accuracy; no solve.
    `targets`: a `magyro.targets.Targets`, a targets TOML path, a 4-tuple, or None (the defaults)."""
    from magyro.observability import observe as excitation_report

    from magyro.progress import step
    from magyro.targets import targets_from

    targets = targets_from(targets)
    options = options or Options()
    step("checking the recording")
    session, recording = checked_recording(session, options)
    step("the excitation and the accuracy it predicts")
    return replace(excitation_report(session, options, targets, method=method), recording=recording)


def solve_file(path, options: Options | None = None, method: str = "nls", method_knobs: dict | None = None, *,
               gyro_unit: str | None = None, mag_unit: str | None = None, output=None, history=None,
               history_plot=None, trajectory=None) -> Calibration:
    """`magyro solve`: load a session file, calibrate it, write the JSON (and the EKF's history, or the least
    squares' attitude trajectory as Parquet, `magyro.result.trajectory`) when asked.

    `method_knobs` are the method's own settings; those left None keep their
    defaults, and those of another method are ignored (the CLI offers the
    least squares' knobs whatever the method).
    """
    from magyro.io import check_outputs
    check_outputs([path], [output, history, history_plot, trajectory])  # before any work: no input overwritten, all writable
    from magyro.io import load_session, write_text_atomically
    from magyro.progress import step

    wants_history = history is not None or history_plot is not None
    if method == "nls" and wants_history:
        raise InputError("--history and --history-plot need --method ekf (the least squares has no estimate over time)")
    if method != "nls" and (method_knobs or {}).get("hard_iron_walk") is not None:
        raise InputError("--hard-iron-walk needs --method nls (the moving hard iron is a part of the least squares)")
    if method != "nls" and trajectory is not None:
        raise InputError("--trajectory needs --method nls (the attitude trajectory is a decision variable of the least squares)")
    knobs = {**nls_knobs(method, method_knobs or {}), **({"trajectory": True} if trajectory is not None else {})}
    chosen = method_named(method, **knobs)
    options = options or Options()
    step(f"reading {Path(path).name}")
    session = load_session(path, gyro_unit=gyro_unit, mag_unit=mag_unit)
    cal, hist = calibrate_with_history(session, options, chosen)   # the same flow with or without --history
    if wants_history:
        write_history(hist, history, history_plot, title=f"{Path(path).name}: EKF estimates, +/- 3 sigma")
    if output is not None:
        write_text_atomically(output, cal.to_json() + "\n")
    if trajectory is not None:
        cal.trajectory.write_parquet(trajectory, source=str(path))
    return cal


def nls_knobs(method: str, knobs: dict) -> dict:
    """The knobs that apply to `method`, without the unset ones."""
    return {k: v for k, v in knobs.items() if v is not None} if method == "nls" else {}


def write_history(history, path=None, plot_path=None, title: str = "") -> None:
    """The EKF's estimates over time as Parquet and/or a figure."""
    from magyro.ekf import plot_history

    if path is not None:
        history.write_parquet(path)
    if plot_path is not None:
        plot_history(history, plot_path, title=title)


def observe_file(path, options: Options | None = None, targets=None, *, gyro_unit: str | None = None,
                 mag_unit: str | None = None, output=None, plot=None):
    """`magyro observe`: load a session file, report on its excitation, write the JSON and the figure when asked.

    `targets` is a `Targets`, the path of a targets TOML file (`magyro.targets.load_targets`), or the tuple
    (scale ppm, non-orthogonality deg, bias deg/s, misalignment deg); None: the default targets.
    """
    from magyro.io import check_outputs
    check_outputs([path], [output, plot])  # before any work: no input overwritten, all writable
    from magyro.io import load_session, write_text_atomically
    from magyro.observability.plot import plot_report, require_matplotlib
    from magyro.targets import targets_from

    if plot is not None:
        require_matplotlib()  # fail before any work or output
    targets = targets_from(targets)
    session = load_session(path, gyro_unit=gyro_unit, mag_unit=mag_unit)
    report = observe(session, options, targets)
    if output is not None:
        write_text_atomically(output, report.to_json() + "\n")
    if plot is not None:
        plot_report(report, plot)
    return report


def simulate_file(problem: str, output, seed: int = 0) -> tuple[Session, Path]:
    """`magyro simulate`: a session from a problem file (or a shipped problem's name), written with its
    truth beside it as NAME.truth.json; returns the session and the truth's path."""
    from magyro.io import check_outputs
    check_outputs([problem], [output, Path(output).with_name(Path(output).stem + ".truth.json")])  # before any work
    from magyro.io import write_session
    from magyro.studies.scenario import load_problem
    from magyro.studies.simulate import simulate, write_truth

    session, truth = simulate(load_problem(problem), seed)
    output = Path(output)
    write_session(session, output)
    truth_path = output.with_name(output.stem + ".truth.json")
    write_truth(truth, truth_path)
    return session, truth_path


def simulate_fleet_dir(problem: str, seeds_text: str, outdir) -> tuple[list[Path], Path]:
    """`magyro simulate PROBLEM --seeds A-B -o DIR`: one session per device (its errors drawn from the problem's
    [spread], `magyro.studies.fleet`), each with its truth, and DIR/manifest.csv; DIR is created. Returns the
    session paths and the manifest's path."""
    from magyro.studies.fleet import MANIFEST, parse_seeds, simulate_fleet

    seeds = parse_seeds(seeds_text)   # before any work or folder
    outdir = Path(outdir)
    if outdir.exists() and not outdir.is_dir():
        raise InputError(f"with --seeds, -o is a folder; {outdir} exists and is not one: choose another path")
    from magyro.progress import step
    from magyro.studies.scenario import load_problem

    scenario = load_problem(problem)   # an unusable problem leaves no folder behind
    try:
        outdir.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise InputError(f"cannot create the folder {outdir}: {exc.strerror or exc}; choose another path") from None
    step(f"simulating {len(seeds)} devices")
    paths = simulate_fleet(scenario, seeds, outdir, progress=lambda done, total, path: step(
        f"simulated device {done}/{total} ({path.name})"))
    return paths, outdir / MANIFEST


def montecarlo_study(problem: str, runs: int, *, jobs: int = 1, method: str = "nls", seed0: int = 0, output=None,
                     csv_path=None, progress: bool = True, scheduler: str | None = None):
    """`magyro montecarlo`: `runs` seeded sessions of a problem, each solved; the table, written when asked.

    `progress` shows a bar (or a line per run) on stderr; `scheduler` (a Dask scheduler's address) solves on
    that cluster instead of the local pool (`magyro.executor`).
    """
    from magyro.io import check_outputs
    check_outputs([problem], [output, csv_path])  # before any work: no input overwritten, all writable
    from magyro.studies.montecarlo import progress_display, run_montecarlo
    from magyro.studies.montecarlo_output import write_outputs
    from magyro.studies.scenario import load_problem

    scenario = load_problem(problem)
    with progress_display(runs, enabled=progress) as show:
        result = run_montecarlo(scenario, runs, jobs=jobs, method=method, seed0=seed0, progress=show,
                                scheduler=scheduler)
    write_outputs(result, output, csv_path)
    return result


def validate_file(path, calibration, *, gyro_unit: str | None = None, mag_unit: str | None = None, output=None,
                  plot=None, series: bool = False):
    """`magyro validate`: dead-reckon a session file with the raw and the calibrated gyro (a Calibration or the
    path of its JSON); the report, its JSON and figure written when asked."""
    from magyro.io import check_outputs
    check_outputs([path, calibration], [output, plot])  # before any work: no input overwritten, all writable
    from magyro.io import load_session, write_text_atomically
    from magyro.studies.dead_reckoning import plot_validation, validate

    report = validate(load_session(path, gyro_unit=gyro_unit, mag_unit=mag_unit), calibration)
    if plot is not None:
        plot_validation(report, plot)
    if output is not None:
        write_text_atomically(output, report.to_json(include_series=series) + "\n")
    return report


def check_file(path, gyro_unit: str | None = None, mag_unit: str | None = None, output=None, repairs=None):
    """`magyro check`: load a session file and check the recording (clocks, gaps, held samples, saturation,
    spikes, units), with what the repairs (`magyro.front.repairs.Repairs`, all on by default) fix and
    the gyro holes they leave; the JSON (schema magyro.recording/1) written when asked. No solve.

    Returns the `RecordingCheck`; `check.errors` are what make the recording unusable (exit 2 on the CLI).
    """
    from magyro.front.repairs import repair_recording
    from magyro.io import check_outputs, load_session, write_text_atomically

    check_outputs([path], [output])  # before any work: no input overwritten, the output writable
    session = load_session(path, gyro_unit=gyro_unit, mag_unit=mag_unit)
    check = repair_recording(session, repairs)[1]
    if output is not None:
        write_text_atomically(output, check.to_json() + "\n")
    return check


def apply_file(session_path, calibration_path, output, frame: str = "b", gyro_unit: str | None = None,
               mag_unit: str | None = None) -> Session:
    """`magyro apply`: a session file corrected by a calibration JSON, written as a new session file.

    The written gyro columns are the calibrated rates in rad/s, K_g y + eps_b in the gyro frame
    (`frame="b"`) or K y + eps in the magnetometer frame (`frame="m"`); the magnetometer columns
    are the calibrated field R (y_m - h), of unit norm ("unitless"). When the calibration has an
    accelerometer (`magyro solve --accelerometer`), the accelerometer columns are the calibrated
    specific force in m/s^2 in the same frame as the rates: C_b_a^T (K_a y_a + eps_a) in frame b,
    C_b_m of that in frame m; without one they are kept as they are, as are time stamps and truth
    columns. Parquet metadata says the file is calibrated, by which calibration file, in which frame
    and with which model (`calibrated_model`; with an accelerometer in the calibration also
    `calibrated_accelerometer`, "false" when the session has no accelerometer columns to correct).
    Returns the corrected session; the inputs are not changed.
    """
    from dataclasses import replace as replaced

    from magyro.io import check_outputs
    check_outputs([session_path, calibration_path], [output])  # before any work: no input overwritten, writable
    from magyro.io import load_session, write_session
    from magyro.result.applicable import check_applicable, check_finite_result

    if frame not in ("b", "m"):
        raise InputError(f"unknown frame '{frame}'; use b (the gyro's) or m (the magnetometer's)")
    cal = Calibration.from_json(calibration_path)
    session = load_session(session_path, gyro_unit=gyro_unit, mag_unit=mag_unit)
    check_applicable(cal, session, str(session_path))   # not twice, not in another unit, no absurd matrix
    rates_rad_s, field = cal.apply(session.gyro_rad_s, session.mag, frame=frame)
    acc = session.acc_m_s2
    has_acc = cal.accelerometer is not None and acc is not None and len(acc) > 0
    specific_force = cal.apply_accelerometer(acc, frame=frame) if has_acc else acc
    check_finite_result(rates_rad_s, field, specific_force if has_acc else None)
    metadata = {**session.metadata, "calibrated": "true", "calibration": str(calibration_path),
                "calibration_frame": frame, "calibrated_model": (
                    "gyro = K_g y + eps_b (rad/s, gyro frame b)" if frame == "b" else
                    "gyro = K y + eps = C_b_m (K_g y + eps_b) (rad/s, magnetometer frame m)")
                + "; mag = R (y_m - h) (unit norm)" + accelerometer_model(cal, frame, has_acc),
                "raw_mag_unit": session.mag_unit, "source_session": str(session_path),
                **({"calibrated_accelerometer": "true" if has_acc else "false"} if cal.accelerometer is not None else {})}
    corrected = replaced(session, gyro_rad_s=rates_rad_s, mag=field, mag_unit="unitless", acc_m_s2=specific_force,
                         metadata=metadata)
    write_session(corrected, output)
    return corrected


def accelerometer_model(cal: Calibration, frame: str, applied: bool) -> str:
    """What `apply_file` did to the accelerometer columns, for `calibrated_model` ("" for a calibration without an
    accelerometer: the model string is then what it always was)."""
    if cal.accelerometer is None:
        return ""
    if not applied:
        return "; acc: the session has no accelerometer columns, so the calibration's accelerometer is not applied"
    return ("; acc = C_b_a^T (K_a y_a + eps_a) (m/s^2, gyro frame b)" if frame == "b" else
            "; acc = C_b_m C_b_a^T (K_a y_a + eps_a) (m/s^2, magnetometer frame m)")


def export_file(calibration_path, fmt: str, output=None) -> str:
    """`magyro export`: a calibration JSON as `fmt` (`magyro.result.export.FORMATS`: yaml, a plain YAML file;
    c, a C99 header with the matrices and apply functions; kalibr, its scale-misalignment IMU yaml; px4, a
    QGroundControl parameter file; ardupilot, a Mission Planner / MAVProxy .parm file), written whole to `output`
    when given. Returns the text."""
    from magyro.io import check_outputs, write_text_atomically

    check_outputs([calibration_path], [output])  # before any work: no input overwritten, the output writable
    from magyro.result.export import FORMATS, export_text

    if fmt not in FORMATS:
        raise InputError(f"unknown export format '{fmt}'; use one of: {', '.join(FORMATS)}")
    text = export_text(Calibration.from_json(calibration_path), fmt, source=str(calibration_path))
    if output is not None:
        write_text_atomically(output, text)
    return text
