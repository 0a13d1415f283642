"""Regenerate the numbers of README.md, and of the docs pages that took the README's sections, that magyro computes.

    python docs/make_readme_numbers.py [PAGE]           rewrite the blocks (default: every page of PAGES)
    python docs/make_readme_numbers.py --check [PAGE]   exit 1 when a page is stale, change nothing

The numbers sit between `<!-- numbers:NAME:start -->` and `<!-- numbers:NAME:end -->` markers (docs/doc_blocks.py;
a block may sit inside a line) in README.md and in PAGES, the pages its sections moved to (issue 40: how-it-works,
results, using-the-result, commands, development); each page gets the blocks whose markers it has (`page_blocks`).
`blocks()` makes them anew from:

- the shipped BROAD trial data/broad-02.parquet solved with the defaults (`magyro solve`), validated against its
  optical truth (`magyro validate`), its recording check, and its PX4 export's cost (one solve, ~5 s);
- the constants of the code: the targets and the refusal bound, the recording check's, the gate's, the grid's,
  the result check's and the warnings' thresholds;
- the measured records docs/numbers/*.json of the expensive studies (the Monte Carlo Table I, the BROAD trials),
  rendered by docs/make_record_numbers.py, and the BROAD room numbers quoted from docs/real-data.md.

tests/test_doc_numbers.py regenerates every block (with the suite's shared solve of broad-02) and fails when a
page and the tool disagree.
"""
from __future__ import annotations

import dataclasses
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
import doc_blocks  # noqa: E402
from doc_blocks import ROOT, fixed, fmt, g, span  # noqa: E402
import make_record_numbers as records  # noqa: E402
import make_table1_numbers as table1  # noqa: E402
import readme_record_numbers  # noqa: E402
import shipped_data_numbers as shipped_data  # noqa: E402
from recording_check_numbers import shipped_calibration  # noqa: E402

PAGE = ROOT / "README.md"
PAGES = (PAGE, *(ROOT / "docs" / f"{name}.md" for name in ("how-it-works", "results", "using-the-result", "commands",
                                                             "development")))
COMMAND = "python docs/make_readme_numbers.py"
EXAMPLE_SAMPLE = 962          # the gyro sample of the worked example
PX4_RATE_DEG_S = 360.0        # the rate at which the PX4 export's cost is quoted


# --------------------------------------------------------------------------- the shipped trial


def validation(session, cal) -> dict:
    """`magyro validate`'s summary: dead reckoning RMS against the optical truth, raw and calibrated (deg)."""
    from magyro.studies.dead_reckoning import validate

    return validate(session, cal).to_dict()["summary"]


def wrong_sign(cal):
    """The calibration with its bias subtracted instead of added (K_g y - eps_b)."""
    return dataclasses.replace(cal, bias_rad_s=-np.asarray(cal.bias_rad_s))


def bias_sign_block(session, cal) -> str:
    right, wrong = validation(session, cal), validation(session, wrong_sign(cal))["calibrated"]
    return (f"on BROAD trial 02 that dead-reckons to {fmt(wrong['rms_deg'])} deg RMS against the optical truth, "
            f"worse than the raw gyro's {fmt(right['raw']['rms_deg'])} deg, where the right formula gives "
            f"{fmt(right['calibrated']['rms_deg'])} deg")


def px4_block(cal) -> str:
    from magyro.result.export_tools import px4_gyro_cost

    cost = px4_gyro_cost(cal, PX4_RATE_DEG_S)
    return (f"On broad-02 that is {fmt(cost['worst_deg_s'])} deg/s wrong at {g(PX4_RATE_DEG_S)} deg/s in the worst "
            "direction.")


def worked_example_block(session, cal) -> str:
    """The worked example: K_g, eps_b, one raw gyro sample and its magnetometer sample, and what apply gives."""
    k = EXAMPLE_SAMPLE
    y, mag = session.gyro_rad_s[k], session.mag[np.searchsorted(session.t_mag_s, session.t_gyro_s[k])]
    omega_b, m_m = cal.apply(y[None, :], mag[None, :])
    omega_m, _ = cal.apply(y[None, :], frame="m")
    wrong, _ = wrong_sign(cal).apply(y[None, :])
    K = cal.K_g

    def vec(v, digits=6):
        return "[" + ", ".join(f"{x:+.{digits}f}" for x in v) + "]"

    def row(r):
        return ", ".join(f"{x:9.6f}" for x in r)

    return "\n".join([
        "A worked example on the shipped BROAD trial 02 (`magyro solve data/broad-02.parquet -o",
        f"calib.json`), the gyro sample at t = {session.t_gyro_s[k]:.3f} s (`session.gyro_rad_s[{k}]`):",
        "",
        f"    K_g   = [[{row(K[0])}],      eps_b = {vec(cal.bias_rad_s)} rad/s",
        f"             [{row(K[1])}],              ({vec(np.rad2deg(cal.bias_rad_s), 4)[1:-1]} deg/s)",
        f"             [{row(K[2])}]]",
        f"    y       = {vec(y)} rad/s   raw",
        f"    omega_b = {vec(omega_b[0])} rad/s   K_g y + eps_b (right)",
        f"              {vec(wrong[0])} rad/s   K_g y - eps_b (wrong sign)",
        f"    omega_m = {vec(omega_m[0])} rad/s   K y + eps",
        f"    y_m     = {vec(mag, 4)} {cal.mag_unit}          the magnetometer sample at the same instant",
        f"    m_m     = {vec(m_m[0], 4)}               R (y_m - h), norm {np.linalg.norm(m_m[0]):.3f}"])


def nodes_per_second(cal) -> float:
    """Attitude nodes per second of the solved span (rests trimmed)."""
    d = cal.to_dict()
    (_, start), (end, _) = d["rests"]["segments_s"][0], d["rests"]["segments_s"][-1]
    return d["solver"]["nodes"] / (end - start)


def trajectory_nodes_block(cal) -> str:
    stride = cal.to_dict()["solver"]["stride"]
    return (f"per attitude node (every {stride}th segment boundary: {fmt(nodes_per_second(cal))} a "
            "second on broad-02)")


def held_block(session) -> str:
    from magyro.front.repairs import repair_recording

    held = next(f for f in repair_recording(session)[1].findings if f.kind == "held" and f.sensor == "magnetometer")
    return f"{100 * held.numbers['fraction']:.0f} % of BROAD's magnetometer rows"


def shipped_results_block(session, cal) -> str:
    val = validation(session, cal)
    rest = np.abs(cal.to_dict()["rests"]["estimate_minus_rest_deg_s"])
    return doc_blocks.notes([
        f"bias within {fmt(np.max(rest))} deg/s of the rest-period gyro mean;",
        f"magnetometer lag {fixed(1e3 * cal.time_offset_s, 2)} +/- "
        f"{fixed(1e3 * cal.to_dict()['std']['time_offset_s'], 2)} ms "
        "(the held magnetometer rows dropped, see the recording check);",
        f"calibrated dead reckoning against the optical truth: {fmt(val['calibrated']['rms_deg'])} deg RMS over the "
        f"trial, against {fmt(val['raw']['rms_deg'])} deg with the raw gyro."])


# --------------------------------------------------------------------------- the code's constants


def targets_block() -> str:
    """The targets' defaults and what they mean for a device dead-reckoning its heading."""
    from magyro.targets import Targets

    t = Targets()
    return (f"defaults {g(t.scale_factor_ppm)} ppm, {g(t.non_orthogonality_deg)} deg, {g(t.bias_deg_s)} deg/s, "
            f"{g(t.misalignment_deg)} deg: {fmt(1e-6 * t.scale_factor_ppm * 360)} deg of heading per turn, "
            f"{fmt(60 * t.bias_deg_s)} deg of drift a minute")


def phrases() -> dict[str, str]:
    """Phrases of the README that quote a constant of the code (blocks inside a line)."""
    from magyro.front import causes, field_checks as fc, recording as rec, rests, signals as sig
    from magyro.front.initial import DEFAULT_WINDOW_S, MAX_TIME_OFFSET_S
    from magyro.nls.diagnostics import MAX_FIELD_CHANGE, SUSPECT_FACTOR
    from magyro.nls.grid import STRIDES
    from magyro.nls.method import NLS
    from magyro.nls.problem import HOLE_LINK_STD_RAD
    from magyro.nls.solve import MIN_NODE_RATE_HZ
    from magyro.observability.gate import FLOOR_FACTOR
    from magyro.options import StdBounds
    from magyro.result import check
    from magyro.result.consistency import MAX_HALF_Z, MAX_RMS_Z
    from magyro.result.reported import MISALIGNMENT_WARNING_DEG
    from magyro.session import HOLE_FACTOR

    b, small, large = StdBounds(), min(STRIDES), max(STRIDES)
    return {
        "restamp-window": f"in {g(rec.RESTAMP_WINDOW_S)} s windows",
        "spike-share": f"at most {100 * sig.SPIKE_MAX_FRACTION:g} % of the samples",
        "mag-saturated": f"exit 2 above {100 * fc.MAG_SATURATED_ERROR:g} % of the samples",
        "slow-mag": f"new values below {g(fc.SLOW_MAG_HZ)} Hz",
        "anomaly-share": f"above {100 * fc.ANOMALY_ERROR:g} % of the samples",
        "rest-window": f"first and last {g(rests.WINDOW_S)} s",
        "no-ellipsoid": (f"a device that turned less than {g(causes.SMALL_TURN_DEG)} deg \"turned too little\" "
                         "(exit 3, with the motion to add); readings that stay within their noise or in one plane "
                         f"while the device turned {g(causes.EVERY_AXIS_TURN_DEG)} deg or more about every axis, and "
                         f"{g(causes.FAR_SPAN_DEG)} deg from its first attitude, are not a magnetometer (exit 2)"),
        "noise-floor": f"{g(FLOOR_FACTOR)} times the most",
        "refusal-bound": (f"(scale {g(b.scale_ppm / 1e4)} %, non-orthogonality {g(b.nonorthogonality_deg)} deg, "
                          f"bias {g(b.bias_deg_s)} deg/s, misalignment {g(b.misalignment_deg)} deg; "
                          "`--max-std-*`)"),
        "linear-window": f"the field change over {g(DEFAULT_WINDOW_S)} s windows",
        "lag-search": f"+/-{g(MAX_TIME_OFFSET_S)} s",
        "stride": (f"the stride {large}, or {small} where that would give fewer than {g(MIN_NODE_RATE_HZ)} nodes "
                   f"per second (sensors below {g(large * MIN_NODE_RATE_HZ)} Hz)"),
        "hole": f"A step over {g(HOLE_FACTOR)} typical intervals",
        "hole-link": f"a loose {g(HOLE_LINK_STD_RAD)} rad link",
        "huber": f"at {g(NLS().huber_threshold)} sigma",
        "split-warn": f"Above {g(MAX_RMS_Z)} RMS (or one |z| above {g(MAX_HALF_Z)})",
        "misfit": f"Above {g(check.MAX_TURNING_MISFIT)}x the result is refused (exit 1)",
        "misfit-1s": f"above {g(check.MAX_LONG_TURNING_MISFIT)}x. A bias more than {g(check.MAX_REST_Z)} std",
        "field-change": f"changes by more than {100 * MAX_FIELD_CHANGE:g} % within half a second",
        "suspect": f"exceed {g(SUSPECT_FACTOR)} times the typical",
        "mirror-warn": f"{g(MISALIGNMENT_WARNING_DEG)} deg",
    }


def field_change_broad(record: dict) -> str:
    """What BROAD's trial with a magnet beside the path and its undisturbed trials get (the trials' record)."""
    trial30 = record["trials"]["30"]
    undisturbed = [t for t in records.UNDISTURBED if record["trials"][t].get("warnings")]
    field = [w for w in trial30.get("warnings", []) if "field magnitude" in w]
    found = ", ".join(f"`{k}`" for k in trial30.get("findings", []))
    return (f"on BROAD trial 30 the recording check {'cuts the magnet first (' + found + ')' if found else 'finds nothing'}"
            f"{' and this warning is still given' if field else ', so this warning is not left'}; "
            f"{'no undisturbed trial warns' if not undisturbed else 'undisturbed trials ' + ', '.join(undisturbed) + ' warn'}")


def anomaly_30(record: dict) -> str:
    """BROAD trial 30 (a magnet beside the path): what the recording check found there (the trials' record)."""
    found = record["trials"]["30"].get("findings", [])
    return (f"BROAD trial 30, {'where the check finds ' + ', '.join(f'`{k}`' for k in found) if found else 'where the check finds nothing'}"
            f" (docs/numbers/{records.RECORD}.json, commit `{record['commit']}`)")


def blocks(shipped=None) -> dict[str, str]:
    """Every numbers block of the README, as the tool makes it now; `shipped`: (session, Calibration) of
    data/broad-02.parquet when already solved."""
    session, cal = shipped or shipped_calibration()
    record = records.read_record(records.RECORD)
    return {"targets": targets_block(), "bias-sign": bias_sign_block(session, cal), "px4-cost": px4_block(cal),
            "worked-example": worked_example_block(session, cal), "trajectory-nodes": trajectory_nodes_block(cal),
            "held": held_block(session), "shipped-results": shipped_results_block(session, cal),
            "broad-ratios": (f"calibrated dead reckoning is {records.ratio_span(record)} of the raw error "
                             f"(`{record.get('commit') or record.get('provenance', {}).get('commit', '?')}`)"),
            "field-change-broad": field_change_broad(record), "anomaly-30": anomaly_30(record),
            "serial-drift": shipped_data.serial_drift_block(),
            "mag-autocorrelation": shipped_data.mag_autocorrelation_block(),
            "third-difference": shipped_data.third_difference_block(),
            **phrases(), **table1.readme_blocks(), **readme_record_numbers.blocks(), **suite_time_block()}


def suite_time_block() -> dict[str, str]:
    """The suite's time (benchmarks/suite_time.py's record), once the README has its markers."""
    if "<!-- numbers:suite-time:start -->" not in PAGE.read_text(encoding="utf-8") or not doc_blocks.has_record(
            "suite-time"):
        return {}
    return {"suite-time": readme_record_numbers.suite_time(doc_blocks.read_record("suite-time"))}


def page_blocks(made: dict[str, str], pages=PAGES) -> dict[Path, dict[str, str]]:
    """Each page's share of `made`: the blocks whose markers it has (a block may sit in more than one page)."""
    out = {}
    for page in pages:
        names = set(doc_blocks.block_names_in_page(page.read_text(encoding="utf-8")))
        out[page] = {name: body for name, body in made.items() if name in names}
    return out


def page_of(name: str) -> Path:
    """The first page of PAGES with block `name`'s markers."""
    return next(p for p in PAGES if name in doc_blocks.block_names_in_page(p.read_text(encoding="utf-8")))


def main(argv: list[str]) -> int:
    pages = [Path(a) for a in argv if a != "--check"] or list(PAGES)
    made = blocks()
    homeless = sorted(set(made) - {n for share in page_blocks(made, PAGES).values() for n in share})
    if homeless:
        sys.exit(f"blocks in no page of {COMMAND}: {', '.join(homeless)}")
    check = [a for a in argv if a == "--check"]
    return max(doc_blocks.main([*check, str(page)], page, lambda share=share: share, COMMAND)
               for page, share in page_blocks(made, pages).items())


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
