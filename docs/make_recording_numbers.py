"""Regenerate every number of docs/recording.md (how to record a calibration session) from magyro itself.

    python docs/make_recording_numbers.py [PAGE]           rewrite the blocks (default: docs/recording.md)
    python docs/make_recording_numbers.py --check [PAGE]   exit 1 when the page is stale, change nothing

The page's numbers sit between `<!-- numbers:NAME:start -->` and `<!-- numbers:NAME:end -->`
markers (docs/doc_blocks.py rewrites and checks them); `blocks()` makes every block anew:

- simulated sessions of problems/phone-module.toml (noise seed 0) with its duration, pace
  (the motion's frequency band), rests or motion changed (`dataclasses.replace`), or its
  field made to wander (`magyro.studies.simulate.with_field_disturbance`), each through
  `magyro.observe`: rank, time to full rank, rates, sphere visited, predicted std, verdict;
- the rest rules and targets, read from the code's constants;
- the recording check's rules, broad-02 and its degraded copies through the check, and the BROAD
  room numbers quoted from docs/real-data.md (docs/recording_check_numbers.py).

Numbers have 3 significant digits. The whole regeneration takes a few seconds (and one solve of
broad-02). tests/test_recording_doc.py imports this script and fails when the page and the tool disagree.
"""
from __future__ import annotations

import dataclasses
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
import doc_blocks  # noqa: E402
from doc_blocks import (DOCS, block_in_page, fmt, g, marker, notes, stale, table,  # noqa: E402,F401
                        with_blocks)
from recording_check_numbers import (REAL_DATA, broad_block, check_block, check_rules_block,  # noqa: E402,F401
                                     recording_checks, section, shipped_calibration)

PAGE = DOCS / "recording.md"
COMMAND = "python docs/make_recording_numbers.py"

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
BLOCK_NAMES = ("targets", "duration", "pace", "motion", "rest-rules", "rests", "room", "broad", "check-rules",
               "check")



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


def blocks(shipped=None) -> dict[str, str]:
    """Every numbers block of the page, as the tool makes it now; `shipped`: (session, Calibration) of
    data/broad-02.parquet when already solved."""
    reports = simulated_reports()
    _, cal = shipped or shipped_calibration()
    out = {"targets": targets_block(), "duration": duration_block(reports), "pace": pace_block(reports),
           "motion": motion_block(reports), "rest-rules": rest_rules_block(), "rests": rests_block(reports),
           "room": room_block(reports), "broad": broad_block(cal.time_offset_s), "check-rules": check_rules_block(),
           "check": check_block()}
    assert tuple(out) == BLOCK_NAMES
    return out


def main(argv: list[str]) -> int:
    return doc_blocks.main(argv, PAGE, lambda: blocks(), COMMAND)


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
