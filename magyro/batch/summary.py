"""The fleet summary of a batch: summary.parquet, summary.csv and summary.html in OUTDIR.

`write_summary(rows, outdir, limits)` judges every row (`magyro.batch.limits.with_verdicts`),
sorts them by device and writes the three files, each atomically (whole or absent):

    summary.parquet   one row per session, the columns of `magyro.batch.row.COLUMNS` (with
                      `accelerometer_columns()` before mag_unit when any row has them: a batch with
                      --accelerometer) then verdict, verdict_reason; numbers float64 (exit_code
                      int64), text strings
    summary.csv       the same table; a missing number is an empty field
    summary.html      one self-contained page (CSS inline, figures as PNG data URIs drawn at twice
                      the size shown, `magyro.report.embed`; no scripts, fonts or links): the counts, every failed or rejected device
                      with its reason, the limits, the distribution of each gyro parameter
                      (and std, hard iron..., and the accelerometer's when the rows have them)
                      across the calibrated devices with the limits drawn and the outliers named

`outliers(rows)` names the devices far from the fleet: |x - median| / (1.4826 MAD) above a
threshold (5) in a column, when at least `min_devices` (8) calibrated devices have it.
The figures need matplotlib (`pip install 'magyro[plot]'`); without it the page is written
without them and says so.
"""
from __future__ import annotations

import csv
import html
import io
import math
from datetime import datetime, timezone
from pathlib import Path

import numpy as np

from magyro.batch import row as schema
from magyro.batch.row import number_of, text_of
from magyro.batch.limits import CHECKS, Limits, describe, with_verdicts
from magyro.io.atomic import write_atomically, write_text_atomically

VERDICT_COLUMNS = ["verdict", "verdict_reason"]
SUMMARY_COLUMNS = list(schema.COLUMNS) + VERDICT_COLUMNS
TEXT_COLUMNS = set(schema.TEXT_COLUMNS) | set(VERDICT_COLUMNS)
INT_COLUMNS = {"exit_code"}
FILES = {"parquet": "summary.parquet", "csv": "summary.csv", "html": "summary.html"}

# the page's figures: (title, [(panel title, unit, columns, limit key or None)])
AX, PR, EU = schema.AXES, [p for *_, p in schema.PAIRS], schema.EULER
FIGURES = [
    ("The gyro's parameters", [
        ("scale factor off 1", "ppm", [f"scale_ppm_{a}" for a in AX], "max_abs_scale_ppm"),
        ("non-orthogonality", "deg", [f"nonorth_deg_{p}" for p in PR], "max_abs_nonorth_deg"),
        ("bias", "deg/s", [f"bias_deg_s_{a}" for a in AX], "max_abs_bias_deg_s"),
        ("misalignment (C_b_m Euler)", "deg", [f"misalignment_deg_{e}" for e in EU],
         "max_abs_misalignment_deg")]),
    ("Their one-sigma", [
        ("std of the scale factor", "ppm", [f"std_scale_ppm_{a}" for a in AX], "target_scale_ppm"),
        ("std of the non-orthogonality", "deg", [f"std_nonorth_deg_{p}" for p in PR], "target_nonorth_deg"),
        ("std of the bias", "deg/s", [f"std_bias_deg_s_{a}" for a in AX], "target_bias_deg_s"),
        ("std of the misalignment", "deg", [f"std_misalignment_deg_{a}" for a in AX], "target_misalignment_deg")]),
    ("The magnetometer and the checks", [
        ("hard iron", "mag unit", [f"hard_iron_{a}" for a in AX], None),
        ("field strength", "mag unit", ["field_strength"], None),
        ("time offset", "s", ["time_offset_s"], None),
        ("split-half RMS z", "", ["split_rms_z"], "max_split_rms_z")]),
]
# drawn only when the table has the accelerometer's columns (a batch with --accelerometer)
ACC_FIGURES = [
    ("The accelerometer's parameters", [
        ("scale factor off 1", "ppm", [f"acc_scale_ppm_{a}" for a in AX], "max_abs_acc_scale_ppm"),
        ("non-orthogonality", "deg", [f"acc_nonorth_deg_{p}" for p in PR], "max_abs_acc_nonorth_deg"),
        ("bias", "m/s²", [f"acc_bias_m_s2_{a}" for a in AX], "max_abs_acc_bias_m_s2"),
        ("misalignment (C_b_a Euler)", "deg", [f"acc_misalignment_deg_{e}" for e in EU],
         "max_abs_acc_misalignment_deg")]),
    ("The accelerometer's one-sigma", [
        ("std of the scale factor", "ppm", [f"std_acc_scale_ppm_{a}" for a in AX], "target_acc_scale_ppm"),
        ("std of the non-orthogonality", "deg", [f"std_acc_nonorth_deg_{p}" for p in PR], "target_acc_nonorth_deg"),
        ("std of the bias", "m/s²", [f"std_acc_bias_m_s2_{a}" for a in AX], "target_acc_bias_m_s2"),
        ("std of the misalignment", "deg", [f"std_acc_misalignment_deg_{a}" for a in AX],
         "target_acc_misalignment_deg")]),
]
ACC_COLUMNS = schema.accelerometer_columns()
# a column that fewer than `min_devices` rows hold (the accelerometer's, in a fleet without one) names no outlier
OUTLIER_COLUMNS = [c for c in schema.parameter_columns() if c != "rank"] + ACC_COLUMNS
MAX_LABELS = 6          # outliers labelled on one panel (all of them are in the table)
MAIN_MAX_WIDTH_PX, MAIN_PADDING_PX = 1040, 28             # the page's main column (CSS) and its padding either side
FIGURE_WIDTH_PX = MAIN_MAX_WIDTH_PX - 2 * MAIN_PADDING_PX  # the width the figures are drawn for and shown at
FIGURE_TEXT_PT = 7.5    # the smallest text of a figure: 10.8 CSS px on a 9.5 in figure shown FIGURE_WIDTH_PX wide
ACCEPTED_COLOR, REJECTED_COLOR, OUTLIER_COLOR, LIMIT_COLOR = "#1f5fa8", "#b3261e", "#e08a1e", "#b3261e"


# --------------------------------------------------------------------------- the files


def write_summary(rows, outdir, limits: Limits | None = None, title: str = "magyro batch: fleet summary") -> dict:
    """Judge `rows` against `limits` and write summary.parquet, summary.csv and summary.html into `outdir`.

    Returns {"parquet": Path, "csv": Path, "html": Path}. Each file is written atomically."""
    outdir = Path(outdir)
    outdir.mkdir(parents=True, exist_ok=True)
    table = summary_rows(rows, limits)
    paths = {kind: outdir / name for kind, name in FILES.items()}
    write_parquet(table, paths["parquet"])
    write_text_atomically(paths["csv"], csv_text(table))
    write_text_atomically(paths["html"], render_html(table, limits, title))
    return paths


def columns_for(rows) -> list[str]:
    """The summary's columns: SUMMARY_COLUMNS, with the accelerometer's (before mag_unit) when any row has them."""
    if not any(c in r for r in rows for c in ACC_COLUMNS):
        return list(SUMMARY_COLUMNS)
    columns = list(SUMMARY_COLUMNS)
    at = columns.index("mag_unit")
    return columns[:at] + ACC_COLUMNS + columns[at:]


def summary_rows(rows, limits: Limits | None) -> list[dict]:
    """The rows with every summary column (missing ones from `empty_row`, NaN for the accelerometer's in a row
    without one when another row has them), judged, sorted by device and session."""
    columns = columns_for(rows)
    with_accelerometer = len(columns) > len(SUMMARY_COLUMNS)
    full = []
    for r in rows:
        base = schema.empty_row(str(r.get("device_id", "")), str(r.get("session", "")))
        if with_accelerometer:
            base.update({c: math.nan for c in ACC_COLUMNS})
        base.update({k: v for k, v in r.items() if k in base})
        full.append(base)
    judged = with_verdicts(full, limits)
    judged.sort(key=lambda r: (text_of(r["device_id"]), text_of(r["session"])))
    return [{c: _clean(c, r.get(c)) for c in columns} for r in judged]


def _columns_of(table: list[dict]) -> list[str]:
    """The columns of a judged table (`summary_rows`), in order."""
    return list(table[0]) if table else list(SUMMARY_COLUMNS)


def _clean(column: str, value):
    if column in TEXT_COLUMNS:
        return text_of(value)
    if column in INT_COLUMNS:
        try:
            return int(value)
        except (TypeError, ValueError, OverflowError):
            return -1
    return number_of(value)


def write_parquet(table: list[dict], path: Path) -> None:
    import pyarrow as pa
    import pyarrow.parquet as pq

    def kind(c):
        return pa.string() if c in TEXT_COLUMNS else pa.int64() if c in INT_COLUMNS else pa.float64()
    columns = _columns_of(table)
    schema_ = pa.schema([(c, kind(c)) for c in columns])
    arrays = {c: pa.array([r[c] for r in table], type=schema_.field(c).type, from_pandas=True)
              for c in columns}
    frame = pa.Table.from_pydict(arrays, schema=schema_)
    write_atomically(Path(path), lambda tmp: pq.write_table(frame, tmp))


def csv_text(table: list[dict]) -> str:
    """The summary as CSV: a header of the columns, numbers at full precision, a missing number empty."""
    buffer = io.StringIO()
    writer = csv.writer(buffer, lineterminator="\n")
    columns = _columns_of(table)
    writer.writerow(columns)
    for r in table:
        writer.writerow([_csv_value(c, r[c]) for c in columns])
    return buffer.getvalue()


def _csv_value(column: str, value):
    if column in TEXT_COLUMNS or column in INT_COLUMNS:
        return value
    return "" if not math.isfinite(value) else repr(float(value))


# --------------------------------------------------------------------------- outliers


def outliers(rows, columns=None, threshold: float = 5.0, min_devices: int = 8) -> list[dict]:
    """The calibrated rows far from the fleet: robust z = |x - median| / (1.4826 MAD) > `threshold` in a column
    that at least `min_devices` calibrated rows hold (finite). When the MAD is 0 (over half the values equal)
    the mean absolute deviation times 1.2533 stands in; when that is 0 too, every value is equal: no outlier.

    Returns dicts (device_id, session, column, value, median, robust_z), largest robust z first."""
    columns = OUTLIER_COLUMNS if columns is None else list(columns)
    calibrated = [r for r in rows if r.get("status") == "calibrated"]
    found = []
    for column in columns:
        values = np.array([number_of(r.get(column)) for r in calibrated])
        ok = np.isfinite(values)
        if ok.sum() < max(min_devices, 1):
            continue
        x = values[ok]
        median = float(np.median(x))
        deviation = np.abs(x - median)
        scale = 1.4826 * float(np.median(deviation))
        if scale <= 0:
            scale = 1.2533 * float(np.mean(deviation))
        if scale <= 0:
            continue
        for r, value in zip((r for r, good in zip(calibrated, ok) if good), x):
            z = abs(value - median) / scale
            if z > threshold:
                found.append({"device_id": text_of(r.get("device_id")), "session": text_of(r.get("session")),
                              "column": column, "value": float(value), "median": median, "robust_z": float(z)})
    found.sort(key=lambda o: (-o["robust_z"], o["device_id"], o["column"]))
    return found


# --------------------------------------------------------------------------- the page


def render_html(table: list[dict], limits: Limits | None, title: str, now: datetime | None = None) -> str:
    """The summary page of judged, sorted rows (`summary_rows`)."""
    now = now or datetime.now(timezone.utc)
    counts = {v: sum(r["verdict"] == v for r in table) for v in ("accepted", "rejected", "failed")}
    devices = len({r["device_id"] for r in table})
    found = outliers(table)
    seconds = sum(r["seconds"] for r in table if math.isfinite(r["seconds"]))

    facts = [("devices", f"{devices}" + (f" ({len(table)} sessions)" if len(table) != devices else "")),
             ("accepted", str(counts["accepted"])), ("rejected", str(counts["rejected"])),
             ("failed", str(counts["failed"])),
             ("written", now.astimezone(timezone.utc).strftime("%Y-%m-%d %H:%M:%S UTC")),
             ("compute time", f"{seconds:.1f} s in all")]
    headline = (f"{counts['accepted']} of {len(table)} accepted, {counts['rejected']} rejected, "
                f"{counts['failed']} failed")
    if limits is None or limits.is_empty():
        headline += " (no limits given: every calibrated device is accepted)"
    parts = [f"<header><p class='kicker'>magyro batch</p><h1>{esc(title)}</h1>",
             f"<div class='verdict {'good' if counts['accepted'] == len(table) else 'poor'}'>{esc(headline)}</div>",
             "<dl class='facts'>" + "".join(f"<dt>{esc(k)}</dt><dd>{esc(v)}</dd>" for k, v in facts) + "</dl>",
             "</header>"]
    parts.append(_problems_section(table))
    parts.append(_limits_section(limits))
    parts.append(_distribution_section(table, limits, found))
    parts.append(_outliers_section(found, table))
    body = "\n".join(p for p in parts if p)
    return (f"<!DOCTYPE html>\n<html lang='en'>\n<head>\n<meta charset='utf-8'>\n"
            f"<meta name='viewport' content='width=device-width, initial-scale=1'>\n<title>{esc(title)}</title>\n"
            f"<style>{CSS}</style>\n</head>\n<body>\n<main>\n{body}\n"
            f"<footer>Written by magyro. The full table: summary.csv / summary.parquet beside this page.</footer>\n"
            f"</main>\n</body>\n</html>\n")


def _problems_section(table) -> str:
    bad = [r for r in table if r["verdict"] in ("failed", "rejected")]
    if not bad:
        return ("<section><h2>Failed and rejected devices</h2><p class='sentence'>None: every device "
                "calibrated and passed.</p></section>")
    rows = "".join(
        f"<tr><td>{esc(r['device_id'])}</td><td>{esc(r['session'])}</td>"
        f"<td><span class='pill {'poor' if r['verdict'] == 'failed' else 'fair'}'>{esc(r['verdict'])}</span></td>"
        f"<td>{esc(r['verdict_reason'])}</td></tr>" for r in sorted(bad, key=lambda r: r["verdict"] != "failed"))
    return (f"<section><h2>Failed and rejected devices</h2><p class='sentence'>{len(bad)} device(s): "
            f"failed ones did not calibrate (exit code, class and cause), rejected ones break the limits named.</p>"
            f"<table class='problems'><thead><tr><th>device</th><th>session</th><th>verdict</th><th>reason</th>"
            f"</tr></thead><tbody>{rows}</tbody></table></section>")


def _limits_section(limits) -> str:
    items = describe(limits)
    if not items:
        return ("<section><h2>Limits</h2><p class='sentence'>No limits were given (<code>--limits</code>): "
                "every device that calibrated is accepted.</p></section>")
    rows = "".join(f"<tr><td>{esc(k)}</td><td>{esc(v)}</td></tr>" for k, v in items)
    return (f"<section><h2>Limits</h2><table class='keyvalue'><thead><tr><th>limit</th><th>value</th></tr></thead>"
            f"<tbody>{rows}</tbody></table></section>")


def _distribution_section(table, limits, found) -> str:
    calibrated = [r for r in table if r["status"] == "calibrated"]
    head = "<section><h2>Distributions across the calibrated devices</h2>"
    if not calibrated:
        return head + "<p class='sentence'>No device calibrated: nothing to show.</p></section>"
    try:
        import matplotlib  # noqa: F401
    except ImportError:
        from magyro.text import PLOT_INSTALL

        return (head + "<p class='sentence'>The figures need matplotlib, which is not installed: "
                f"<code>{html.escape(PLOT_INSTALL)}</code> adds them.</p></section>")
    from magyro.report.embed import embed_png

    sentence = (f"Each dot is one of the {len(calibrated)} calibrated devices (red: the value breaks its limit); "
                "dashed lines are the limits; outliers (robust z above 5) are ringed and named.")
    figures = []
    has_acc = any(c in calibrated[0] for c in ACC_COLUMNS)
    for fig_title, panels in FIGURES + (ACC_FIGURES if has_acc else []):
        fig = distribution_figure(calibrated, panels, limits, found)
        if fig is None:
            continue
        figures.append(f"<figure>{embed_png(fig, FIGURE_WIDTH_PX).img(fig_title)}"
                       f"<figcaption>{esc(fig_title)}</figcaption></figure>")
    return head + f"<p class='sentence'>{esc(sentence)}</p>" + "".join(figures) + "</section>"


def _outliers_section(found, table) -> str:
    n = sum(r["status"] == "calibrated" for r in table)
    if not found:
        why = "" if n >= 8 else f" (only {n} calibrated device(s); outliers are named from 8 on)"
        return f"<section><h2>Outliers</h2><p class='sentence'>None{esc(why)}.</p></section>"
    rows = "".join(
        f"<tr><td>{esc(o['device_id'])}</td><td>{esc(o['column'])}</td><td>{esc(_g(o['value']))}</td>"
        f"<td>{esc(_g(o['median']))}</td><td>{o['robust_z']:.1f}</td><td>{esc(o['session'])}</td></tr>"
        for o in found)
    return (f"<section><h2>Outliers</h2><p class='sentence'>{len(found)} value(s) with a robust z "
            f"(|x − median| / (1.4826 MAD)) above 5.</p><table class='numbers'><thead><tr><th>device</th>"
            f"<th>column</th><th>value</th><th>median</th><th>robust z</th><th>session</th></tr></thead>"
            f"<tbody>{rows}</tbody></table></section>")


def distribution_figure(calibrated, panels, limits, found):
    """One row of strip plots (one panel per group, one strip per column); None when no panel has a value."""
    from magyro.report.figures import new_figure, style

    panels = [p for p in panels if any(math.isfinite(r[c]) for r in calibrated for c in p[2])]
    if not panels:
        return None
    fig = new_figure(9.5, 2.9)
    axes = np.atleast_1d(fig.subplots(1, len(panels)))
    flagged = {(o["device_id"], o["session"], o["column"]) for o in found}
    units = sorted({r["mag_unit"] for r in calibrated if r["mag_unit"]})
    mag_unit = units[0] if len(units) == 1 else "mag unit"
    rng = np.random.default_rng(0)
    for ax, (panel_title, unit, columns, limit_key) in zip(axes, panels):
        style(ax)
        unit = mag_unit if unit == "mag unit" else unit
        labelled = 0
        limit = getattr(limits, limit_key) if limits is not None and limit_key else None
        absolute = CHECKS[limit_key][2] if limit_key else False
        for i, column in enumerate(columns):
            points = [(r, r[column]) for r in calibrated if math.isfinite(r[column])]
            if not points:
                continue
            y = np.array([v for _, v in points])
            x = i + rng.uniform(-0.18, 0.18, len(y))
            colors = [REJECTED_COLOR if limit is not None and (abs(v) if absolute else v) > limit else ACCEPTED_COLOR
                      for _, v in points]
            ax.scatter(x, y, s=9, c=colors, alpha=0.7, linewidths=0)
            for (r, v), xi in zip(points, x):
                if (r["device_id"], r["session"], column) not in flagged:
                    continue
                ax.scatter([xi], [v], s=40, facecolors="none", edgecolors=OUTLIER_COLOR, linewidths=1.2)
                if labelled < MAX_LABELS:
                    ax.annotate(_mpl_text(r["device_id"]), (xi, v), xytext=(4, 2), textcoords="offset points",
                                fontsize=FIGURE_TEXT_PT, color=OUTLIER_COLOR)
                    labelled += 1
        if limit is not None:
            _draw_limit(ax, limit, absolute, unit)
        ax.set_xticks(range(len(columns)), [_mpl_text(c.rsplit("_", 1)[-1]) if len(columns) > 1 else ""
                                            for c in columns], fontsize=FIGURE_TEXT_PT)
        ax.set_xlim(-0.6, len(columns) - 0.4)
        ax.set_title(_mpl_text(f"{panel_title}" + (f" ({unit})" if unit else "")), fontsize=8)
    return fig


def _draw_limit(ax, limit: float, absolute: bool, unit: str) -> None:
    """The limit as dashed lines when it is near the data; far off it, a note (the dots stay readable)."""
    low, high = ax.get_ylim()
    span = max(high - low, 1e-300)
    levels = (-limit, limit) if absolute else (limit,)
    near = [v for v in levels if low - span <= v <= high + span]
    for level in near:
        ax.axhline(level, color=LIMIT_COLOR, ls="--", lw=0.9)
    if len(near) < len(levels):
        text = f"limit {'±' if absolute else ''}{limit:g} {unit}".strip()
        ax.set_xlabel(_mpl_text(text + ": off the scale"), fontsize=FIGURE_TEXT_PT, color=LIMIT_COLOR)


# --------------------------------------------------------------------------- small helpers


def esc(text) -> str:
    return html.escape(str(text), quote=True)


def _mpl_text(text) -> str:
    """Text shown as is by matplotlib (a "$" would start mathtext)."""
    return str(text).replace("$", r"\$")


def _g(value: float) -> str:
    return f"{value:.4g}"


CSS = """
:root { --ink:#1d232b; --muted:#5b6570; --line:#e3e7ec; --panel:#f6f8fa; --good:#2e7d32; --fair:#b26a00;
        --poor:#b3261e; --accent:#1f5fa8; }
* { box-sizing: border-box; }
body { margin: 0; background: #fff; color: var(--ink);
       font: 15px/1.55 system-ui, -apple-system, "Segoe UI", Roboto, "Helvetica Neue", Arial, sans-serif; }
header { border-bottom: 1px solid var(--line); padding-bottom: 18px; margin-bottom: 22px; }
.kicker { color: var(--muted); font-size: 13px; letter-spacing: .04em; text-transform: uppercase; margin: 0; }
h1 { font-size: 28px; line-height: 1.2; margin: 4px 0 10px; font-weight: 650; }
h2 { font-size: 20px; margin: 0 0 6px; font-weight: 650; }
.facts { display: grid; grid-template-columns: max-content 1fr; gap: 2px 16px; font-size: 13px; color: var(--muted);
         margin: 0; }
.facts dt { font-weight: 600; color: var(--ink); } .facts dd { margin: 0; }
.verdict { border-left: 5px solid var(--accent); background: var(--panel); padding: 14px 18px; margin: 18px 0;
           border-radius: 0 6px 6px 0; }
.verdict.good { border-color: var(--good); } .verdict.poor { border-color: var(--poor); }
table { border-collapse: collapse; width: 100%; margin: 8px 0 4px; font-size: 13.5px; }
th, td { padding: 5px 10px; border-bottom: 1px solid var(--line); text-align: left; vertical-align: top; }
th { font-weight: 600; color: var(--muted); font-size: 12.5px; border-bottom: 2px solid var(--line); }
td { overflow-wrap: anywhere; }
table.numbers td:nth-child(n+3):nth-child(-n+5) { text-align: right; font-variant-numeric: tabular-nums; }
table.keyvalue td:first-child { color: var(--muted); width: 42%; }
.pill { display: inline-block; white-space: nowrap; font-size: 11.5px; font-weight: 700; text-transform: uppercase; padding: 2px 9px;
        border-radius: 999px; color: #fff; background: #8a939c; }
.pill.fair { background: var(--fair); } .pill.poor { background: var(--poor); }
section { border-top: 1px solid var(--line); padding-top: 26px; margin-top: 30px; }
p.sentence { font-size: 16px; margin: 6px 0 14px; }
figure { margin: 8px 0 14px; }
figure img { max-width: 100%; height: auto; display: block; border: 1px solid var(--line); border-radius: 4px; }
figcaption { color: var(--muted); font-size: 12.5px; margin-top: 4px; }
code { font-size: 13px; background: var(--panel); padding: 1px 4px; border-radius: 3px; }
footer { margin-top: 48px; color: var(--muted); font-size: 12px; border-top: 1px solid var(--line); padding-top: 12px; }
"""
CSS += f"main {{ max-width: {MAIN_MAX_WIDTH_PX}px; margin: 0 auto; padding: 32px {MAIN_PADDING_PX}px 64px; }}\n"
