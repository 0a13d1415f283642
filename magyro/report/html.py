"""The report's page: one HTML file, CSS inline, figures embedded, no scripts, fonts or other files."""
from __future__ import annotations

from magyro.report.figures import PAGE_MAX_WIDTH_PX, PAGE_PADDING_PX
from magyro.report.section import esc

STATUS_WORDS = {"good": "good", "fair": "caveat", "poor": "problem", "": "not judged"}

CSS = """
:root { --ink:#1d232b; --muted:#5b6570; --line:#e3e7ec; --bg:#ffffff; --panel:#f6f8fa;
        --good:#2e7d32; --fair:#b26a00; --poor:#b3261e; --accent:#1f5fa8; }
* { box-sizing: border-box; }
html { -webkit-text-size-adjust: 100%; }
body { margin: 0; background: var(--bg); color: var(--ink);
       font: 15px/1.55 system-ui, -apple-system, "Segoe UI", Roboto, "Helvetica Neue", Arial, sans-serif; }
header { border-bottom: 1px solid var(--line); padding-bottom: 18px; margin-bottom: 22px; }
.kicker { color: var(--muted); font-size: 13px; letter-spacing: .04em; text-transform: uppercase; margin: 0; }
h1 { font-size: 28px; line-height: 1.2; margin: 4px 0 10px; font-weight: 650; }
h2 { font-size: 20px; margin: 0 0 6px; font-weight: 650; display: flex; align-items: center; gap: 10px; }
h3 { font-size: 15px; margin: 18px 0 6px; }
.facts { display: grid; grid-template-columns: max-content 1fr; gap: 2px 16px; font-size: 13px; color: var(--muted);
         margin: 0; }
.facts dt { font-weight: 600; color: var(--ink); }
.facts dd { margin: 0; overflow-wrap: anywhere; }
.verdict { border-left: 5px solid var(--accent); background: var(--panel); padding: 14px 18px; margin: 18px 0;
           border-radius: 0 6px 6px 0; font-size: 15.5px; }
.verdict.good { border-color: var(--good); } .verdict.fair { border-color: var(--fair); }
.verdict.poor { border-color: var(--poor); }
.warnings { border: 1px solid #f0d9a8; background: #fff9ec; border-radius: 6px; padding: 10px 16px; margin: 16px 0; }
.warnings h3 { margin: 2px 0 6px; color: var(--fair); }
.warnings ul { margin: 0; padding-left: 20px; font-size: 13.5px; }
.warnings li { margin: 4px 0; }
table { border-collapse: collapse; width: 100%; margin: 8px 0 4px; font-size: 13.5px; }
th, td { padding: 5px 10px; border-bottom: 1px solid var(--line); text-align: left; vertical-align: top; }
th { font-weight: 600; color: var(--muted); font-size: 12.5px; border-bottom: 2px solid var(--line); }
table.numbers td:not(:first-child), table.numbers th:not(:first-child) { text-align: right;
       font-variant-numeric: tabular-nums; white-space: nowrap; }
table.numbers td:last-child, table.numbers th:last-child { text-align: left; }
table.keyvalue thead { display: none; }
table.keyvalue td:first-child { color: var(--muted); width: 42%; }
table.keyvalue td { font-variant-numeric: tabular-nums; }
table.summary td:nth-child(2) { white-space: nowrap; }
table.summary a { color: var(--ink); text-decoration: none; font-weight: 600; }
table.summary a:hover { text-decoration: underline; }
.pill { display: inline-block; font-size: 11.5px; font-weight: 700; letter-spacing: .03em; text-transform: uppercase;
        padding: 2px 9px; border-radius: 999px; color: #fff; background: #8a939c; white-space: nowrap; }
.pill.good { background: var(--good); } .pill.fair { background: var(--fair); } .pill.poor { background: var(--poor); }
section { border-top: 1px solid var(--line); padding-top: 26px; margin-top: 30px; }
p.sentence { font-size: 16px; margin: 6px 0 14px; }
figure { margin: 8px 0 4px; }
figure img { max-width: 100%; height: auto; display: block; border: 1px solid var(--line); border-radius: 4px; }
figcaption { color: var(--muted); font-size: 12.5px; margin-top: 4px; }
details { margin-top: 12px; }
details > summary { cursor: pointer; color: var(--accent); font-weight: 600; font-size: 14px; }
ul.findings { padding-left: 18px; font-size: 13.5px; }
ul.findings li { margin: 6px 0; }
.sub { color: var(--muted); margin-left: 4px; }
.tag { font-size: 11px; font-weight: 700; text-transform: uppercase; padding: 1px 6px; border-radius: 4px;
       background: #e9edf1; color: var(--muted); }
.tag.warning { background: #fff1d6; color: var(--fair); } .tag.error { background: #fde4e1; color: var(--poor); }
.tag.repaired { background: #e3f1e4; color: var(--good); }
.small { color: var(--muted); font-size: 12.5px; }
footer { margin-top: 48px; color: var(--muted); font-size: 12px; border-top: 1px solid var(--line); padding-top: 12px; }
"""
# the main column: its width less its padding is the width the figures are drawn for (figures.FIGURE_WIDTH_PX)
CSS += (f"main {{ max-width: {PAGE_MAX_WIDTH_PX}px; margin: 0 auto; padding: 32px {PAGE_PADDING_PX}px 64px; }}\n"
        + """@media print { main { max-width: none; padding: 0; } section { break-inside: avoid-page; }
                details { display: block; } }\n""")


def render(report) -> str:
    """The page of a `magyro.report.build.Report`."""
    facts = "".join(f"<dt>{esc(k)}</dt><dd>{esc(v)}</dd>" for k, v in report.facts)
    summary_rows = "".join(
        f"<tr><td><a href='#{esc(s.key)}'>{esc(s.title)}</a></td>"
        f"<td><span class='pill {esc(s.status)}'>{esc(STATUS_WORDS.get(s.status, s.status))}</span></td>"
        f"<td>{esc(s.headline)}</td></tr>" for s in report.sections)
    warnings = ""
    if report.warnings:
        warnings = ("<div class='warnings'><h3>Warnings of the calibration</h3><ul>"
                    + "".join(f"<li>{esc(w)}</li>" for w in report.warnings) + "</ul></div>")
    body = "".join(section_html(s) for s in report.sections)
    return f"""<!DOCTYPE html>
<html lang="en">
<head>
<meta charset="utf-8">
<meta name="viewport" content="width=device-width, initial-scale=1">
<meta name="generator" content="magyro {esc(report.version)}">
<title>magyro report: {esc(report.title)}</title>
<style>{CSS}</style>
</head>
<body>
<main>
<header>
<p class="kicker">magyro calibration report</p>
<h1>{esc(report.title)}</h1>
<dl class="facts">{facts}<dt>made</dt><dd>{esc(report.made_utc)} by magyro {esc(report.version)}</dd></dl>
</header>
<div class="verdict {esc(report.status)}" id="verdict"><span class="pill {esc(report.status)}">{esc(STATUS_WORDS[report.status])}</span>
{esc(report.verdict)}</div>
<table class="summary" id="summary"><thead><tr><th>check</th><th>status</th><th>result</th></tr></thead>
<tbody>{summary_rows}</tbody></table>
{warnings}
{body}
<footer>Made by magyro {esc(report.version)} (gyroscope calibration with the magnetometer, after Wu &amp; Pei) on
{esc(report.made_utc)} from {esc(report.session_path)} and {esc(report.calibration_path)}. This page is self-contained:
it needs no network and no other file.</footer>
</main>
</body>
</html>
"""


def section_html(s) -> str:
    pill = f"<span class='pill {esc(s.status)}'>{esc(STATUS_WORDS.get(s.status, s.status))}</span>"
    figure = ""
    if s.figure:
        figure = (f"<figure>{s.figure.img(s.figure_alt)}"
                  f"<figcaption>{esc(s.figure_alt[:1].upper() + s.figure_alt[1:])}.</figcaption></figure>")
    details = f"<details open><summary>Details</summary>{s.details}</details>" if s.details else ""
    return (f"<section id='{esc(s.key)}'><h2>{esc(s.title)} {pill}</h2>"
            f"<p class='sentence'>{esc(s.sentence)}</p>{figure}{details}</section>\n")
