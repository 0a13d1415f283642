"""Building the report: load, check, observe, judge the calibration, the residuals, the split halves and the
dead reckoning, then lay the page out (`magyro.report.html`)."""
from __future__ import annotations

from dataclasses import dataclass, field, replace
from datetime import datetime, timezone
from pathlib import Path

from magyro.errors import InputError, MagyroError
from magyro.text import PLOT_INSTALL
from magyro.report import sections as S


@dataclass
class Report:
    """The report's parts and its page (`html`)."""

    title: str
    session_path: str
    calibration_path: str
    made_utc: str
    version: str
    verdict: str
    status: str                      # overall: good | fair | poor
    warnings: list
    sections: list                   # of sections.Section
    facts: list = field(default_factory=list)   # (label, value) for the header
    html: str = ""


def report_file(session_path, calibration_path, output, *, split_check: bool = True, gyro_unit: str | None = None,
                mag_unit: str | None = None, progress=None, targets=None) -> Report:
    """`magyro report SESSION CALIB -o report.html`: one self-contained HTML page judging a calibration.

    The page (figures as embedded PNG, CSS inline, no scripts) has six sections: the recording check, the
    excitation, the calibration with its std, the fit's residuals over time, the split-half check (computed
    here when the calibration does not carry one and `split_check`: two more least-squares solves, a few
    seconds) and dead reckoning raw against calibrated. `output` None builds it without writing.
    `progress`, when given, is called with a short message before each step. Returns the `Report`
    (its `html` is the page). InputError for an unusable session or calibration file, before any output.
    `targets` (a `magyro.targets.Targets`, a targets TOML path or None for the defaults) are what sections 2
    and 3 judge the one-sigma against, as `magyro observe` and `magyro batch` do.
    """
    from magyro.io import check_outputs
    check_outputs([session_path, calibration_path], [output])  # before any work: no input overwritten, writable
    from magyro.io import load_session, write_text_atomically
    from magyro.result.calibration import Calibration

    from magyro.targets import targets_from

    targets = targets_from(targets)   # an unusable targets file is refused before any work
    say = progress or (lambda message: None)
    say("reading the calibration")
    cal = Calibration.from_json(calibration_path)
    _require_matplotlib()
    say("reading the session")
    session = load_session(session_path, gyro_unit=gyro_unit, mag_unit=mag_unit)
    from magyro.result.applicable import check_applicable

    check_applicable(cal, session, str(session_path))   # not twice, not in another unit, no absurd matrix
    report = build_report(session, cal, split_check=split_check, progress=say, session_path=str(session_path),
                          calibration_path=str(calibration_path), targets=targets)
    if output is not None:
        say(f"writing {output}")
        write_text_atomically(output, report.html)
    return report


def _require_matplotlib() -> None:
    try:
        import matplotlib  # noqa: F401  (the figures need it; say so before any work)
    except ImportError:
        raise InputError(f"magyro report needs matplotlib for its figures, which is not installed: {PLOT_INSTALL}") from None


def build_report(session, cal, *, split_check: bool = True, progress=None, session_path: str = "",
                 calibration_path: str = "", targets=None) -> Report:
    """The report of a calibration `cal` on the session it was solved from (see `report_file`)."""
    import magyro
    from magyro.api import method_named, observe
    from magyro.front.prepare import moving_session
    from magyro.front.repairs import repair_recording
    from magyro.methods import calibrator
    from magyro.options import Options
    from magyro.report.html import render
    from magyro.result import consistency
    from magyro.studies.dead_reckoning import validate
    from magyro.targets import Targets

    say = progress or (lambda message: None)
    options = Options()
    say("checking the recording")
    repaired, check = repair_recording(session, None)
    if check.errors:
        raise InputError(f"{session_path or 'the session'}: {check.error_message()}")
    parts = [S.recording_section(session, repaired, check)]
    say("analysing the excitation")
    parts.append(S.excitation_section(observe(session, options, targets)))
    moving = moving_session(repaired, options)[0]

    split, computed, why_not = cal.consistency, False, None
    if split is None and split_check:
        if cal.solver.method != "nls":
            why_not = f"it compares two least-squares solves, and this calibration is from {cal.solver.method}"
        else:
            say("split-half check: solving each half (two least-squares solves)")
            try:
                split = consistency.split_check(moving, cal, replace(options, split_check=False),
                                                calibrator(method_named("nls")))
                computed = True
            except MagyroError as exc:
                why_not = f"it failed ({exc})"
    elif split is None:
        why_not = "the calibration carries none and it was not asked for (--no-split-check)"
    say("tabulating the calibration")
    parts.append(S.calibration_section(cal, split, targets))
    say("computing the residuals over time")
    parts.append(S.residual_section(moving, cal))
    parts.append(S.split_section(split, computed, why_not))
    say("dead reckoning raw and calibrated")
    parts.append(S.dead_reckoning_section(validate(session, cal)))

    warnings = list(cal.warnings)
    if computed:
        warning = consistency.split_warning(split)
        if warning and warning not in warnings:
            warnings.append(f"(split-half check computed for this report) {warning}")
    meta = session.metadata or {}
    name = meta.get("device") or meta.get("trial") or Path(session_path or session.source or "session").stem
    facts = [("targets (one-sigma)", (targets or Targets()).text()),
             ("session", Path(session_path).name if session_path else session.source),
             ("calibration", Path(calibration_path).name if calibration_path else "given"),
             ("span", f"{session.t_gyro_s[0]:.1f}–{session.t_gyro_s[-1]:.1f} s "
                      f"({session.t_gyro_s[-1] - session.t_gyro_s[0]:.0f} s), moving {moving.t_gyro_s[0]:.1f}–"
                      f"{moving.t_gyro_s[-1]:.1f} s"),
             ("magnetometer unit", session.mag_unit)]
    if meta.get("source"):
        facts.append(("from", meta["source"]))
    status, verdict = overall_verdict(parts)
    report = Report(title=str(name), session_path=str(session_path), calibration_path=str(calibration_path),
                    made_utc=datetime.now(timezone.utc).strftime("%Y-%m-%d %H:%M UTC"), version=magyro.__version__,
                    verdict=verdict, status=status, warnings=warnings, sections=parts, facts=facts)
    report.html = render(report)
    return report


def overall_verdict(parts: list) -> tuple[str, str]:
    """(status, one paragraph): the worst section decides; each section's sentence is the evidence."""
    by = {p.key: p for p in parts}
    judged = [p for p in parts if p.status]
    rank = {S.GOOD: 0, S.FAIR: 1, S.POOR: 2}
    worst = max((rank[p.status] for p in judged), default=0)
    status = (S.GOOD, S.FAIR, S.POOR)[worst]
    dr = by["dead-reckoning"]
    opening = {
        S.GOOD: "This calibration is good to use.",
        S.FAIR: "This calibration is usable, with caveats.",
        S.POOR: "This calibration should not be used as it is.",
    }[status]
    evidence = [dr.sentence]
    caveats = [p for p in judged if p.key != "dead-reckoning" and rank[p.status] > 0]
    fine = [p.title.split(". ", 1)[-1].lower() for p in judged if p.key != "dead-reckoning" and p.status == S.GOOD]
    if fine:
        evidence.append(f"These look right: {', '.join(fine)}.")
    for p in caveats:
        what = p.caveat or p.sentence[:1].lower() + p.sentence[1:].rstrip(".")
        evidence.append(f"{'Caveat' if p.status == S.FAIR else 'Problem'} ({p.title.split('. ', 1)[-1].lower()}): "
                        f"{what}.")
    return status, " ".join([opening, *evidence])
