"""Regenerate every number of docs/recording.md (how to record a calibration session) from magyro itself.

    python docs/make_recording_numbers.py [PAGE]           rewrite the blocks (default: docs/recording.md)
    python docs/make_recording_numbers.py --check [PAGE]   exit 1 when the page is stale, change nothing

The page's numbers sit between `<!-- numbers:NAME:start -->` and `<!-- numbers:NAME:end -->`
markers; `blocks()` makes every block anew:

- simulated sessions of problems/phone-module.toml (noise seed 0) with its duration, pace
  (the motion's frequency band), rests or motion changed (`dataclasses.replace`), or its
  field made to wander (`magyro.studies.simulate.with_field_disturbance`), each through
  `magyro.observe`: rank, time to full rank, rates, sphere visited, predicted std, verdict;
- the shipped real BROAD trial data/broad-02.parquet and degraded copies of it
  (tests/degrade.py) through the recording check (`magyro.front.repairs.repair_recording`,
  what `magyro check` runs);
- the thresholds, read from the code's constants;
- the BROAD room numbers quoted from docs/real-data.md (sections 1 and 2, where they are
  measured), so the quote follows its source.

Numbers have 3 significant digits. The whole regeneration takes a few seconds.
tests/test_recording_doc.py imports this script and fails when the page and the tool disagree.
"""
from __future__ import annotations

import dataclasses
import importlib.util
import re
import sys
from pathlib import Path

import numpy as np

DOCS = Path(__file__).resolve().parent
ROOT = DOCS.parent
PAGE = DOCS / "recording.md"
REAL_DATA = DOCS / "real-data.md"
DEGRADE = ROOT / "tests" / "degrade.py"

PROBLEM = "phone-module"
SEED = 0
DURATIONS_S = (30.0, 60.0, 120.0, 240.0)
PACES = (0.25, 0.5, 1.0, 2.0, 4.0)              # x the problem's motion frequency band
RESTS_S = (0.0, 0.5, 1.0, 2.0, 5.0)             # at each end
ROOM_WANDER = (0.0, 0.005, 0.01, 0.02)          # simulated field wander, fraction of the field per axis ...
LAG_EXAMPLE_S = 0.01                            # a lag error, to show what it costs at the pace's rates
ROOM_CORRELATION_S = 3.0                        # ... with this correlation time (BROAD measured 2.2-5.0 s)
MOTIONS = (  # label, theorem's rank (docs/observability.md), motion changes (None: the problem's own motion)
    ("still", 2, {"kind": "static"}),
    ("about x only", 6, {"kind": "sequential", "axes": ("x",), "amplitude_deg": np.array([120.0])}),
    ("about x, then y", 9, {"kind": "sequential", "axes": ("x", "y"), "amplitude_deg": np.array([120.0, 120.0])}),
    ("about x, then y, then z", 12,
     {"kind": "sequential", "axes": ("x", "y", "z"), "amplitude_deg": np.array([120.0, 120.0, 120.0])}),
    ("about all three at once (the problem's own)", 12, None),
)
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
BLOCK_NAMES = ("targets", "duration", "pace", "motion", "rest-rules", "rests", "room", "broad", "check-rules",
               "check")


def marker(name: str, end: str) -> str:
    return f"<!-- numbers:{name}:{end} -->"


# --------------------------------------------------------------------------- helpers


def fmt(x) -> str:
    """3 significant digits, as `magyro observe` prints them."""
    from magyro.observability.report import fmt as tool_fmt

    return tool_fmt(x)


def g(x) -> str:
    """A constant of the code as written (no trailing zeros)."""
    return f"{x:g}"


def load_degrade():
    """tests/degrade.py (a script of the repository, not part of the package) as a module."""
    spec = importlib.util.spec_from_file_location("degrade", DEGRADE)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def scenario(**changes):
    """problems/phone-module.toml with `changes`; `motion` is a dict of changes to its Motion."""
    from magyro.studies.scenario import load_problem

    p = load_problem(PROBLEM)
    motion = changes.pop("motion", None)
    if motion:
        changes["motion"] = dataclasses.replace(p.motion, **motion)
    return dataclasses.replace(p, **changes)


def observed(problem, wander: float = 0.0):
    """magyro.observe on `problem` simulated with SEED (its field wandering by `wander`, if any)."""
    import magyro
    from magyro.studies.simulate import simulate, with_field_disturbance

    session = simulate(problem, SEED)[0]
    if wander:
        session = with_field_disturbance(session, problem, wander, ROOM_CORRELATION_S, SEED)
    return magyro.observe(session)


def worst_std(report) -> tuple[float, float, float, float]:
    """(scale ppm, non-orthogonality deg, bias deg/s, misalignment deg): the largest predicted one-sigma of each."""
    from magyro.observability.report import accuracy_rows

    return tuple(float(np.max(values)) for _, values, _, _ in accuracy_rows(report.predicted_std, report.targets))


def gyro_stds(report) -> np.ndarray:
    """The 12 gyro parameters' predicted one-sigma (K_g upper triangle, bias, misalignment)."""
    s = report.predicted_std
    K = np.asarray(s.K_g, dtype=float)
    return np.concatenate([K[np.triu_indices(3)], np.ravel(s.bias_deg_s), np.ravel(s.misalignment_deg)])


def std_cells(report) -> str:
    return " | ".join(fmt(v) for v in worst_std(report))


def full_rank(report) -> str:
    return "never" if report.full_rank_at_s is None else fmt(report.full_rank_at_s)


def typical_rate_deg_s(report) -> float:
    """RMS of |w| over the analysed span (rests trimmed, bias taken out), deg/s."""
    return float(np.sqrt(np.mean(np.sum(np.asarray(report.rates_deg_s) ** 2, axis=1))))


def table(header: list[str], rows: list[list[str]], left: tuple = (0, -1)) -> str:
    """A Markdown table: the columns `left` (indices) left-aligned, the others (numbers) right-aligned."""
    lefts = {i % len(header) for i in left}
    align = ["---" if i in lefts else "---:" for i in range(len(header))]
    return "\n".join("| " + " | ".join(r) + " |" for r in [header, align, *rows])


STD_HEADER = ["scale (ppm)", "non-orthogonality (deg)", "bias (deg/s)", "misalignment (deg)"]


# --------------------------------------------------------------------------- the simulated blocks


def targets_block() -> str:
    from magyro.observability.report import Targets
    from magyro.options import StdBounds

    t, b = Targets(), StdBounds()
    return (f"`magyro observe` calls a recording `sufficient` when every predicted one-sigma is within its target: "
            f"scale factor {g(t.scale_factor_ppm)} ppm, non-orthogonality {g(t.non_orthogonality_deg)} deg, bias "
            f"{g(t.bias_deg_s)} deg/s, misalignment {g(t.misalignment_deg)} deg. Above a target it says `marginal`. "
            f"It says `insufficient` when a parameter is not excited at all, or when a one-sigma is above "
            f"{g(b.scale_ppm)} ppm, {g(b.nonorthogonality_deg)} deg, {g(b.bias_deg_s)} deg/s or "
            f"{g(b.misalignment_deg)} deg: `magyro solve` refuses those (exit 3).")


def duration_block(reports: dict) -> str:
    rows = []
    for d in DURATIONS_S:
        r = reports["duration", d]
        rows.append([fmt(d), full_rank(r), std_cells(r), r.verdict])
    times = [reports["duration", d].full_rank_at_s for d in DURATIONS_S]
    a, b = reports["duration", 60.0], reports["duration", 120.0]
    ratio = np.array(worst_std(a)) / np.array(worst_std(b))
    enough = [d for d in DURATIONS_S if reports["duration", d].verdict == "sufficient"]
    short = reports["duration", DURATIONS_S[0]]
    return table(["duration (s)", "full rank at (s)", *STD_HEADER, "verdict"], rows) + "\n\n" + notes([
        f"Every duration is full rank after {fmt(min(times))}-{fmt(max(times))} s. Length does not decide whether "
        "the parameters are seen, only how well.",
        f"Doubling from 60 to 120 s divides the std by {fmt(ratio.min())}-{fmt(ratio.max())} "
        f"(the square root of 2 is {fmt(np.sqrt(2))}).",
        f"The shortest that is `sufficient` here: {fmt(min(enough))} s. At {fmt(DURATIONS_S[0])} s `magyro observe` "
        f"says: \"{short.reason}\"."])


def full_scale_needed(peak_deg_s: float) -> str:
    from magyro.front.signals import FULL_SCALES_DEG_S

    fits = sorted(s for s in set(FULL_SCALES_DEG_S) if s >= peak_deg_s)
    return f"+/-{fits[0]}" if fits else "beyond every range"


def pace_block(reports: dict) -> str:
    rows = []
    for pace in PACES:
        r = reports["pace", pace]
        peak = float(np.max(r.coverage.peak_rate_deg_s))
        rows.append([f"{g(pace)}x", fmt(peak), fmt(typical_rate_deg_s(r)), fmt(peak / r.mag_rate_hz),
                     full_scale_needed(peak), f"{100 * r.coverage.sphere_fraction:.0f}%", std_cells(r), r.verdict])
    from magyro.front.signals import FULL_SCALES_DEG_S

    r = reports["pace", 1.0]
    slow_pace, fast_pace = PACES[0], PACES[-1]
    slow, fast = reports["pace", slow_pace], reports["pace", fast_pace]
    ranges = ", ".join(str(s) for s in sorted(set(FULL_SCALES_DEG_S)))
    return table(["pace", "peak rate (deg/s)", "typical rate (deg/s)",
                  f"turn between magnetometer samples at peak (deg, {fmt(r.mag_rate_hz)} Hz)",
                  "smallest gyro range that holds the peak (deg/s)", "sphere visited", *STD_HEADER, "verdict"],
                 rows) + "\n\n" + notes([
        "The typical rate is the RMS of the rate over the moving part; the peak is the fastest moment on any one "
        f"axis. The gyro ranges the check knows by name: +/-{ranges} deg/s.",
        f"Slow ({g(slow_pace)}x, typical {fmt(typical_rate_deg_s(slow))} deg/s): the scale-factor std is "
        f"{fmt(worst_std(slow)[0] / worst_std(r)[0])}x that of the 1x pace, and the verdict is `{slow.verdict}`.",
        f"Fast ({g(fast_pace)}x, typical {fmt(typical_rate_deg_s(fast))} deg/s): the scale-factor std is "
        f"{fmt(worst_std(fast)[0] / worst_std(r)[0])}x and the bias std {fmt(worst_std(fast)[2] / worst_std(r)[2])}x "
        f"that of the 1x pace, and the verdict is `{fast.verdict}`; the peak needs a "
        f"{full_scale_needed(float(np.max(fast.coverage.peak_rate_deg_s)))} deg/s gyro, and the device turns "
        f"{fmt(float(np.max(fast.coverage.peak_rate_deg_s)) / fast.mag_rate_hz)} deg between two magnetometer "
        "samples.",
        f"A magnetometer lag the solve gets wrong by {g(1e3 * LAG_EXAMPLE_S)} ms turns into an attitude error of "
        f"rate x lag: {fmt(typical_rate_deg_s(r) * LAG_EXAMPLE_S)} deg at the 1x typical rate, "
        f"{fmt(typical_rate_deg_s(fast) * LAG_EXAMPLE_S)} deg at {g(fast_pace)}x."])


def motion_block(reports: dict) -> str:
    rows = []
    for label, theorem, _ in MOTIONS:
        r = reports["motion", label]
        rows.append([label, str(theorem), str(r.rank), full_rank(r), f"{100 * r.coverage.sphere_fraction:.0f}%",
                     r.verdict])
    seq, once = reports["motion", MOTIONS[-2][0]], reports["motion", MOTIONS[-1][0]]
    return table(["turning", "rank (theorem)", "rank (magyro)", "full rank at (s)", "sphere visited", "verdict"],
                 rows) + "\n\n" + notes([
        f"One axis at a time reaches full rank only once the third axis turns ({full_rank(seq)} s), and stays "
        f"`{seq.verdict}`; all three at once is full rank after {full_rank(once)} s and `{once.verdict}`.",
        "What `magyro observe` says about one axis only: \"" + reports["motion", MOTIONS[1][0]].reason + "\"."])


def rest_rules_block() -> str:
    from magyro.front.noise import MIN_REST_FOR_NOISE_S
    from magyro.front.rests import MIN_REST_S, STILL_IN_NOISE_STD, WINDOW_S

    return (f"magyro takes the first and last {g(WINDOW_S)} s as what still looks like on this sensor. The rest lasts "
            f"while the smoothed gyro and magnetometer stay within {g(STILL_IN_NOISE_STD)} noise stds of that. "
            f"A still stretch counts as a rest only when it lasts at least {g(MIN_REST_S)} s. When the rests last "
            f"at least {g(MIN_REST_FOR_NOISE_S)} s in all, the noise levels come from the longest one, its "
            "correlation included; otherwise they come from the moving data, and white noise is assumed.")


def rests_block(reports: dict) -> str:
    rows = []
    for rest in RESTS_S:
        r = reports["rests", rest]
        found = sum(b - a for a, b in r.rests_s)
        density = r.noise["gyro_density_deg_s_sqrt_hz"]
        rest_bias = fmt(density / np.sqrt(found)) if found > 0 else "no rest check"
        noise_from = "the longest rest" if "rest" in r.noise["source"] else "the moving data"
        rows.append([fmt(rest), fmt(found), noise_from, rest_bias, fmt(worst_std(r)[2]), r.verdict])
    return table(["rest at each end (s)", "rests found, in all (s)", "noise levels from",
                  "bias from the rests, one-sigma (deg/s)", "bias from the motion, one-sigma (deg/s)", "verdict"], rows,
                 left=(0, 2, -1)) + "\n\n" + notes(rest_notes(reports))


def rest_notes(reports: dict) -> list[str]:
    from magyro.front.rests import MIN_REST_S

    missed = [r for r in RESTS_S if 0 < r < MIN_REST_S]
    own = scenario().motion.rest_start_s
    r = reports["rests", own]
    found = sum(b - a for a, b in r.rests_s)
    motion = [worst_std(reports["rests", x])[2] for x in RESTS_S]
    at_rest = r.noise["gyro_density_deg_s_sqrt_hz"] / np.sqrt(found)
    return [f"A pause shorter than {g(MIN_REST_S)} s is not a rest" + (f" (the {g(missed[0])} s row)" if missed else "")
            + ": no rest check, and the noise levels come from the moving data.",
            f"With {g(own)} s at each end (the phone module's), the rests give the bias to "
            f"{fmt(at_rest)} deg/s, {compared(at_rest / worst_std(r)[2])} the motion does ({fmt(worst_std(r)[2])} "
            "deg/s), and without the magnetometer.",
            f"The rests do not change what the motion gives (bias {fmt(min(motion))}-{fmt(max(motion))} deg/s in "
            "every row): magyro trims them before the calibration."]


def compared(ratio: float) -> str:
    return "better than" if ratio < 0.9 else "about as well as" if ratio <= 1.1 else "less well than"


def notes(lines: list[str]) -> str:
    return "\n".join(f"- {line}" for line in lines)


def room_block(reports: dict) -> str:
    clean = gyro_stds(reports["room", 0.0])
    rows = []
    for wander in ROOM_WANDER:
        r = reports["room", wander]
        d = r.prediction.get("field_disturbance") or {}
        measured = float(d.get("std_fraction", 0.0))
        corr = f", {fmt(d['correlation_time_s'])} s" if measured > 0 else ""
        ratio = float(np.median(gyro_stds(r) / clean))
        rows.append([f"{100 * wander:g}%" + (f", {g(ROOM_CORRELATION_S)} s" if wander else ""),
                     f"{fmt(100 * measured)}%{corr}", std_cells(r), fmt(ratio), r.verdict])
    one = reports["room", ROOM_WANDER[2]]
    ratio = float(np.median(gyro_stds(one) / clean))
    return table(["field wander simulated (per axis, correlation)", "magyro measures", *STD_HEADER,
                  "std / homogeneous std (median of 12)", "verdict"], rows) + "\n\n" + notes([
        f"A field that wanders by {100 * ROOM_WANDER[2]:g} % multiplies the std by {fmt(ratio)}.",
        f"What `magyro observe` says then: \"{one.reason}\"."])


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


def broad_block(text: str | None = None) -> str:
    """The room and lag numbers of the undisturbed BROAD trials, as docs/real-data.md sections 1 and 2 give them."""
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
            f"{', '.join(t for t, _ in rows1)}).")


# --------------------------------------------------------------------------- the recording check


def check_rules_block() -> str:
    from magyro.front import causes
    from magyro.front import field_checks as fc
    from magyro.front import recording as rec
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
        f"earliest arrival of each burst wanders more than {g(rec.RESTAMP_WANDER_PERIODS)} period (or "
        f"{g(1e3 * rec.RESTAMP_WANDER_S)} ms) off one line, the two clocks drift and the restamp follows them, "
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


def escape(text: str) -> str:
    return text.replace("|", "\\|")


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


# --------------------------------------------------------------------------- the page


def simulated_reports() -> dict:
    """Every simulated session's report, by (study, value)."""
    reports = {}
    for d in DURATIONS_S:
        reports["duration", d] = observed(scenario(duration_s=d))
    base = scenario()
    for pace in PACES:
        lo, hi = base.motion.band_hz
        reports["pace", pace] = (reports["duration", 60.0] if pace == 1.0 and base.duration_s == 60.0 else
                                 observed(scenario(motion={"band_hz": (pace * lo, pace * hi)})))
    for label, _, motion in MOTIONS:
        reports["motion", label] = reports["pace", 1.0] if motion is None else observed(scenario(motion=motion))
    for rest in RESTS_S:
        reports["rests", rest] = observed(scenario(motion={"rest_start_s": rest, "rest_end_s": rest}))
    for wander in ROOM_WANDER:
        reports["room", wander] = reports["pace", 1.0] if wander == 0.0 else observed(base, wander)
    return reports


def blocks() -> dict[str, str]:
    """Every numbers block of the page, as the tool makes it now."""
    reports = simulated_reports()
    out = {"targets": targets_block(), "duration": duration_block(reports), "pace": pace_block(reports),
           "motion": motion_block(reports), "rest-rules": rest_rules_block(), "rests": rests_block(reports),
           "room": room_block(reports), "broad": broad_block(), "check-rules": check_rules_block(),
           "check": check_block()}
    assert tuple(out) == BLOCK_NAMES
    return out


def block_pattern(name: str) -> re.Pattern:
    return re.compile(re.escape(marker(name, "start")) + r"\n(.*?)\n?" + re.escape(marker(name, "end")), flags=re.S)


def block_in_page(text: str, name: str) -> str:
    """The text between a block's markers ("" when there is none yet)."""
    m = block_pattern(name).search(text)
    if not m:
        raise ValueError(f"no {marker(name, 'start')} ... {marker(name, 'end')} block in the page")
    return m.group(1)


def blocks_in_page(text: str) -> dict[str, str]:
    return {name: block_in_page(text, name) for name in BLOCK_NAMES}


def with_blocks(text: str, new: dict[str, str]) -> str:
    """The page with every block's text replaced by `new`'s."""
    for name, body in new.items():
        block_in_page(text, name)   # the markers must be there
        text = block_pattern(name).sub(lambda _: f"{marker(name, 'start')}\n{body}\n{marker(name, 'end')}", text,
                                       count=1)
    return text


def stale(text: str, new: dict[str, str]) -> list[str]:
    """The names of the blocks whose text differs from `new` (or that the page lacks)."""
    return [name for name in BLOCK_NAMES
            if not block_pattern(name).search(text) or block_in_page(text, name) != new[name]]


def main(argv: list[str]) -> int:
    check = "--check" in argv
    args = [a for a in argv if a != "--check"]
    page = Path(args[0]) if args else PAGE
    if not page.is_file():
        sys.exit(f"no page at {page}")
    text = page.read_text(encoding="utf-8")
    new = blocks()
    old = stale(text, new)
    if check:
        if old:
            print(f"{page} is stale: {', '.join(old)}; regenerate it with `python docs/make_recording_numbers.py`")
            return 1
        print(f"{page} is up to date")
        return 0
    for name in BLOCK_NAMES:
        print(f"--- {name}\n{new[name]}")
    page.write_text(with_blocks(text, new), encoding="utf-8")
    print(f"updated {page} ({', '.join(old) or 'nothing changed'})")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
