"""The recording-check and BROAD blocks of docs/recording.md (docs/make_recording_numbers.py writes the page).

- the thresholds of the recording check, read from the code's constants (`check_rules_block`);
- the shipped real BROAD trial data/broad-02.parquet and degraded copies of it (tests/degrade.py) through the
  recording check (`magyro.front.repairs.repair_recording`, what `magyro check` runs; `check_block`);
- the BROAD room and lag numbers quoted from docs/real-data.md (sections 1 and 2, where they are measured), so
  the quote follows its source, with the lag `magyro solve` gives on the shipped trial (`broad_block`).
"""
from __future__ import annotations

import importlib.util
import re

from doc_blocks import DOCS, ROOT, escape, fixed, g, table

REAL_DATA = DOCS / "real-data.md"
DEGRADE = ROOT / "tests" / "degrade.py"
SHIPPED = ROOT / "data" / "broad-02.parquet"
CHECK_CASES = (  # the degradations of tests/degrade.py shown, by name and arguments, applied to broad-02
    ("burst_stamps", ()),
    ("drifting_burst_stamps", ()),
    ("clip_gyro", (250.0,)),
    ("hole", (80.0, 30.0)),
    ("mag_spikes", ()),
    ("clip_mag", (0.1,)),
    ("magnet_pass", ()),
    ("held_mag", ()),
    ("mag_time_offset", (0.3,)),
    ("mag_clock_drift", (20000.0,)),
    ("wrong_time_unit", ()),
    ("gyro_in_deg_s_labelled_rad_s", ()),
)


def load_degrade():
    """tests/degrade.py (a script of the repository, not part of the package) as a module."""
    spec = importlib.util.spec_from_file_location("degrade", DEGRADE)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def shipped_calibration():
    """`magyro solve data/broad-02.parquet` (default options): (session, Calibration)."""
    import magyro

    session = magyro.load_session(SHIPPED)
    return session, magyro.calibrate(session)


# --------------------------------------------------------------------------- BROAD, quoted from docs/real-data.md


def section(text: str, number: int) -> str:
    m = re.search(rf"^## {number}\. .*?(?=^## |\Z)", text, flags=re.S | re.M)
    if not m:
        raise ValueError(f"docs/real-data.md has no section {number}")
    return m.group(0)


def span(values) -> str:
    values = list(values)
    lo, hi = min(values), max(values)
    return f"{lo:g}-{hi:g}"


def broad_block(shipped_lag_s: float, text: str | None = None) -> str:
    """The room and lag numbers of the undisturbed BROAD trials, as docs/real-data.md sections 1 and 2 give them,
    and the lag `magyro solve` finds on the shipped trial (`shipped_lag_s`)."""
    text = text if text is not None else REAL_DATA.read_text(encoding="utf-8")
    rows2 = re.findall(r"^\| (\d\d) \| ([\d.]+), ([\d.]+) \| ([\d.]+) \|", section(text, 2), flags=re.M)
    rows1 = re.findall(r"^\| (\d\d) \|(?:[^|]*\|){3} ([\d.]+) \|", section(text, 1), flags=re.M)
    if not rows2 or not rows1:
        raise ValueError("docs/real-data.md: the tables of sections 1 and 2 are not where this script looks")
    trials = ", ".join(t for t, *_ in rows2)
    return (f"On the undisturbed BROAD trials ({trials}; docs/real-data.md, section 2) magyro measured a field "
            f"that wanders by {span(float(w) for _, w, _, _ in rows2)} % of the field along the path, with a "
            f"correlation time of {span(float(c) for _, _, c, _ in rows2)} s. Counting it made the std "
            f"{span(float(x) for _, _, _, x in rows2)} times the homogeneous-field std (median over the "
            f"parameters). That was a lab with optical cameras, not a workshop. magyro found the magnetometer "
            f"lagging the gyro by {span(float(x) for _, x in rows1)} ms (section 1, trials "
            f"{', '.join(t for t, _ in rows1)}, each cut to its movement span), and by "
            f"{fixed(1e3 * shipped_lag_s, 2)} ms on the shipped copy of trial 02 (`magyro solve "
            f"data/broad-02.parquet`).")


# --------------------------------------------------------------------------- the recording check


def check_rules_block() -> str:
    from magyro.front import causes
    from magyro.front import field_checks as fc
    from magyro.front import recording as rec, restamp
    from magyro.front import signals as sig
    from magyro.front.findings import GAP_PERIODS
    from magyro.io.checks import MAX_PLAUSIBLE_STEP_S, MIN_PLAUSIBLE_STEP_S
    from magyro.nls.diagnostics import MAX_FIELD_CHANGE
    from magyro.result.consistency import MAX_HALF_Z, MAX_RMS_Z

    return "\n".join([
        f"- **units (time)**: the median gyro step must lie between {g(MIN_PLAUSIBLE_STEP_S)} s and "
        f"{g(MAX_PLAUSIBLE_STEP_S)} s; otherwise the time is not in seconds (error, exit 2).",
        "- **units (gyro)**: the gyro must turn the field as fast as the magnetometer sees it turn; deg/s read as "
        "rad/s, or the reverse, is an error (exit 2).",
        f"- **bursts**: at least {100 * rec.BURST_MIN_SHORT_FRACTION:g} % of the intervals shorter than "
        f"{g(rec.BURST_SHORT_PERIODS)} period, and at least {rec.BURST_MIN_LONG} waits longer than "
        f"{g(rec.BURST_LONG_PERIODS)} periods. magyro restamps the sensor from its sample index; when the "
        f"earliest arrival of each burst wanders more than {g(restamp.RESTAMP_WANDER_PERIODS)} period (or "
        f"{g(1e3 * restamp.RESTAMP_WANDER_S)} ms) off one line, the two clocks drift and the restamp follows them, "
        f"{g(rec.RESTAMP_WINDOW_S)} s at a time; if they still wander by {g(rec.RESTAMP_TRUST_PERIODS)} periods, "
        "no restamp can be trusted (error, exit 2, naming the sensor's clock).",
        f"- **gaps**: an interval longer than {g(GAP_PERIODS)} periods. magyro never integrates the gyro across "
        "one.",
        f"- **held samples**: at least {rec.HELD_MIN_ROWS} rows, and {100 * rec.HELD_MIN_FRACTION:g} % of them, "
        f"repeat the previous row exactly (a warning from {100 * rec.HELD_WARN_FRACTION:g} %). magyro keeps the "
        "first row of each run.",
        f"- **saturation**: at least {sig.SAT_MIN_SAMPLES} gyro samples at exactly one extreme beyond "
        f"{g(sig.SAT_MIN_DEG_S)} deg/s, on {sig.SAT_MIN_RUNS} plateaus, or entered by a step of "
        f"{100 * sig.SAT_STEEP_FRACTION:g} % of the range, or held for {sig.SAT_LONG_RUN} samples. magyro cuts "
        "them out.",
        f"- **spikes**: a magnetometer sample off the median of its four neighbours by {g(sig.SPIKE_SPREAD)} x "
        f"({g(sig.SPIKE_NOISE)} noise stds + the neighbours' spread), the fresh readings only when most rows "
        f"are held. magyro drops it, unless more than {100 * sig.SPIKE_MAX_FRACTION:g} % of the samples (and more "
        f"than {sig.SPIKE_ALWAYS}) look so: that is the noise's shape, reported, nothing dropped.",
        f"- **magnetometer units and faults**: readings of length 1 everywhere (normalised by the logger) and an "
        "axis that never changes (stuck) are errors (exit 2); an axis at exactly its extreme in "
        f"{100 * fc.MAG_SAT_MIN_FRACTION:g} % of the samples or more, on {fc.MAG_SAT_MIN_RUNS} runs, "
        f"{g(fc.MAG_SAT_DOMINANCE)}x as often as any value inside the range, is saturated: cut, and an error "
        f"beyond {100 * fc.MAG_SATURATED_ERROR:g} % of the samples; new values slower than {g(fc.SLOW_MAG_HZ)} Hz "
        "are a warning.",
        f"- **field anomalies**: stretches of {g(fc.ANOMALY_MIN_S)} s or more where the field's magnitude is off "
        f"the ellipsoid of the rest by {100 * fc.ANOMALY_MIN_SIZE:g} % and {g(fc.ANOMALY_NOISE)} robust stds (a "
        "magnet passing by) are cut like spikes; the solve does not cross them. Over "
        f"{100 * fc.ANOMALY_ERROR:g} % of the samples, the field is not homogeneous (error, exit 2).",
        "- **no ellipsoid** (the gate, `magyro.front.causes`): judged against the gyro, in this order: the "
        f"device turned less than {g(causes.SMALL_TURN_DEG)} deg, or about one axis only (that axis tilted "
        f"less than {g(causes.SINGLE_AXIS_TILT_DEG)} deg): exit 3, naming it; it turned "
        f"{g(causes.EVERY_AXIS_TURN_DEG)} deg or more about every axis, and {g(causes.FAR_SPAN_DEG)} deg from "
        "its first attitude: the magnetometer does not follow or "
        "the field is not homogeneous (exit 2); else too little of the sphere (exit 3).",
        f"- **clocks**: the solve searches a magnetometer lag within +/-{g(1e3 * sig.SOLVE_LAG_SEARCH_S)} ms; a "
        f"larger lag, or one that changes by more than {g(1e3 * sig.DRIFT_MIN_S)} ms from start to end, is "
        "flagged and the magnetometer's times are shifted.",
        f"- **jitter** (info): a robust std of the intervals over {100 * rec.JITTER_WARN_FRACTION:g} % of the "
        "period.",
        "- **after the solve** (`magyro solve`, not the check): a warning when the calibrated field's magnitude "
        "changes by more than "
        f"{100 * MAX_FIELD_CHANGE:g} % (iron or a magnet near the path), and with `--split-check` when the two "
        f"halves disagree (RMS z over {g(MAX_RMS_Z)}, or one parameter over {g(MAX_HALF_Z)}).",
    ])


def check_block(checks: dict | None = None) -> str:
    """The clean trial's findings, then what each degradation adds (findings whose kind, sensor and severity the
    clean trial does not have)."""
    checks = checks or recording_checks()
    clean_label, clean = checks[0]
    seen = {(f.kind, f.sensor, f.severity) for f in clean.findings}
    rows = []
    for i, (label, check) in enumerate(checks):
        for f in check.findings:
            if i and (f.kind, f.sensor, f.severity) in seen:
                continue
            rows.append([label, f"`{f.kind}` ({f.sensor})", f.severity, "yes" if f.repaired else "no",
                         escape(f.message)])
    return table(["recording", "finding", "severity", "repaired", "what `magyro check` says"], rows, left=range(5))


def recording_checks() -> list:
    """[(label, RecordingCheck)]: broad-02 as shipped, then each degradation of CHECK_CASES."""
    from magyro.front.repairs import repair_recording

    degrade = load_degrade()
    clean = degrade.load("broad-02")
    out = [("broad-02 as shipped", repair_recording(clean)[1])]
    for name, args in CHECK_CASES:
        bad = getattr(degrade, name)(clean, *args)
        out.append((bad.metadata["degraded"], repair_recording(bad)[1]))
    return out

