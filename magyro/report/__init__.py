"""`magyro report`: one self-contained HTML page that judges a calibration on the session it came from.

    from magyro.report import report_file
    report = report_file("data/broad-02.parquet", "cal.json", "report.html")
    print(report.verdict)

Sections: the recording check, the excitation and coverage, the calibration with its std, the fit's
residuals over time, the split-half check, dead reckoning raw against calibrated; each with a figure
(embedded PNG, crisp at the size shown) and one sentence computed from the numbers saying what they mean and whether that is good.

Modules: `build` (loading, computing, the verdict: `report_file`, `build_report`, `Report`), `sections`
and `fit_sections` (each section's numbers, sentence and details; 4 and 5 in `fit_sections`), `section`
(what a section is made of, and the HTML pieces they write), `figures` (the report's own figures), `embed` (a
figure as a PNG at twice the size the page shows it, with that size and its smallest text stated) and `html`
(the page: CSS inline, no scripts, no fonts, no network).
"""
from __future__ import annotations

from magyro.report.build import Report, build_report, report_file

__all__ = ["Report", "build_report", "report_file"]
