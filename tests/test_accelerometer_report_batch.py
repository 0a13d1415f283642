"""The accelerometer where a calibration is judged (issue 26): `magyro report` and `magyro batch`'s rows, limits and
summary.

On a real calibration: the shipped BROAD trial 02 solved with the accelerometer in the least squares, once per run
(conftest's broad02_acc_solved), and one batch of that trial with --accelerometer. Without an accelerometer the
report's calibration section and the batch's rows and summary columns are what they were: the same calibration
with its accelerometer dropped gives them exactly, with nothing added.
"""
from __future__ import annotations

import dataclasses
import html
import json
import math
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from magyro.batch import row as R
from magyro.batch.inputs import is_batch_summary
from magyro.batch.limits import Limits, parse_limits, verdict
from magyro.batch.run import options_digest, run_batch
from magyro.batch.summary import ACC_COLUMNS, ACC_FIGURES, SUMMARY_COLUMNS, write_summary
from magyro.options import Options
from magyro.report import sections as S

DATA = Path(__file__).resolve().parents[1] / "data"
BROAD_02 = DATA / "broad-02.parquet"


@pytest.fixture(scope="module")
def cals(broad02_acc_solved):
    """(session, the calibration with its accelerometer, the same without it)."""
    session, cal = broad02_acc_solved
    assert cal.accelerometer is not None
    return session, cal, dataclasses.replace(cal, accelerometer=None)


# --------------------------------------------------------------------------- report


@pytest.fixture(scope="module")
def report(cals):
    pytest.importorskip("matplotlib")
    from magyro.report.build import build_report

    session, cal, _ = cals
    return build_report(session, cal, split_check=False, session_path=str(BROAD_02), calibration_path="acc.json")


def test_the_report_shows_each_accelerometer_parameter_with_its_std(cals, report):
    _, cal, _ = cals
    acc = cal.accelerometer
    section = {s.key: s for s in report.sections}["calibration"]
    assert "<h3>Accelerometer</h3>" in section.details and section.details in report.html
    cells = [f"<td>{html.escape(r.label)}</td><td>{r.value:+.{d}f}</td><td>{r.std:.{d}f}</td>"
             for r, d in zip(S.accelerometer_rows(acc), [0] * 3 + [3] * 3 + [4] * 3 + [3] * 3)]
    for cell in cells:
        assert cell in section.details, cell
    for i in range(3):
        assert f"{1e6 * (acc.K_a[i, i] - 1):+.0f}" in section.sentence
        assert f"{acc.bias_m_s2[i]:+.4f}" in section.sentence
    assert f"{1e6 * acc.std_K_a[0, 0]:.0f}" in section.details
    assert "the accelerometer's scale factors are off by" in section.sentence
    assert section.sentence.count(". ") == 0 and section.sentence.endswith(".")     # still ONE sentence
    assert html.escape(section.sentence) in report.html
    assert "C_b_a (gyro to accelerometer frame)" in section.details


def test_without_an_accelerometer_the_calibration_section_is_what_it_was(cals):
    """The section of the calibration without its accelerometer is the one with it less what the accelerometer
    adds: the same status, headline and caveat, the sentence less its accelerometer clause, the details less the
    accelerometer's table."""
    _, cal, plain = cals
    with_acc, without = S.calibration_section(cal), S.calibration_section(plain)
    for field in ("key", "title", "status", "headline", "figure_alt", "caveat"):
        assert getattr(with_acc, field) == getattr(without, field), field
    head, tail = without.sentence.split(f" ({cal.solver.method} ", 1)
    assert with_acc.sentence.startswith(head + "; the accelerometer's scale factors")
    assert with_acc.sentence.endswith(f" ({cal.solver.method} " + tail)
    assert with_acc.details == without.details + S.accelerometer_details(cal.accelerometer)
    assert "ccelerometer" not in without.details and "ccelerometer" not in without.sentence


# --------------------------------------------------------------------------- batch: rows and limits


def test_a_row_holds_the_accelerometer_and_a_row_without_one_is_unchanged(cals):
    _, cal, plain = cals
    row, plain_row = R.row_from_calibration("d", "d.parquet", cal), R.row_from_calibration("d", "d.parquet", plain)
    assert list(plain_row) == R.COLUMNS and not any(c in plain_row for c in ACC_COLUMNS)
    assert {k: v for k, v in row.items() if k not in ACC_COLUMNS} == plain_row
    acc = cal.accelerometer
    for i, a in enumerate(R.AXES):
        assert row[f"acc_scale_ppm_{a}"] == 1e6 * (acc.K_a[i, i] - 1.0)
        assert row[f"std_acc_scale_ppm_{a}"] == 1e6 * acc.std_K_a[i, i]
        assert row[f"acc_bias_m_s2_{a}"] == acc.bias_m_s2[i]
        assert row[f"std_acc_bias_m_s2_{a}"] == acc.std_bias_m_s2[i]
        assert row[f"std_acc_misalignment_deg_{a}"] == acc.std_misalignment_deg[i]
    for (i, j, p) in R.PAIRS:
        assert row[f"acc_nonorth_deg_{p}"] == math.degrees(acc.K_a[i, j])
    assert [row[f"acc_misalignment_deg_{e}"] for e in R.EULER] == list(acc.euler_deg)
    json.dumps(row)                                                   # plain values, as rows/ID.json stores them


def test_accelerometer_limits_judge_the_row_and_reject_a_device_without_one(cals):
    _, cal, plain = cals
    row, plain_row = R.row_from_calibration("d", "d.parquet", cal), R.row_from_calibration("d", "d.parquet", plain)
    limits = parse_limits({"limits": {"max_abs_acc_scale_ppm": 50000, "max_abs_acc_nonorth_deg": 1.0,
                                      "max_abs_acc_bias_m_s2": 0.5, "max_abs_acc_misalignment_deg": 2.0,
                                      "target_acc_scale_ppm": 10000, "target_acc_nonorth_deg": 1.0,
                                      "target_acc_bias_m_s2": 0.1, "target_acc_misalignment_deg": 1.0}})
    assert verdict(row, limits) == ("accepted", "")
    worst_bias = max(abs(row[f"acc_bias_m_s2_{a}"]) for a in R.AXES)
    axis = max(R.AXES, key=lambda a: abs(row[f"acc_bias_m_s2_{a}"]))
    tight = dataclasses.replace(limits, max_abs_acc_bias_m_s2=round(worst_bias / 2, 3))
    decided, reason = verdict(row, tight)
    assert decided == "rejected" and f"|acc_bias_m_s2_{axis}| = {worst_bias:.3f}" in reason and "m/s^2" in reason
    worst_scale_std = max(row[f"std_acc_scale_ppm_{a}"] for a in R.AXES)
    decided, reason = verdict(row, dataclasses.replace(limits, target_acc_scale_ppm=worst_scale_std / 2))
    assert decided == "rejected" and "std_acc_scale_ppm_" in reason and "ppm" in reason
    decided, reason = verdict(plain_row, limits)             # measured nothing: rejected, said once
    assert decided == "rejected" and reason.count(";") == 0
    assert "accelerometer not measured" in reason and "--accelerometer" in reason
    assert verdict(plain_row, Limits(max_abs_bias_deg_s=10.0)) == ("accepted", "")   # gyro limits as before


# --------------------------------------------------------------------------- batch: the summary


def test_the_summary_has_the_accelerometer_columns_only_when_a_row_has_them(cals, tmp_path):
    _, cal, plain = cals
    row = R.row_from_calibration("acc", "acc.parquet", cal)
    plain_row = R.row_from_calibration("plain", "plain.parquet", plain)
    only_plain = write_summary([plain_row], tmp_path / "plain")
    assert list(pd.read_parquet(only_plain["parquet"]).columns) == SUMMARY_COLUMNS
    assert list(pd.read_csv(only_plain["csv"]).columns) == SUMMARY_COLUMNS
    assert "accelerometer" not in only_plain["html"].read_text()
    mixed = write_summary([row, plain_row], tmp_path / "mixed")
    frame = pd.read_parquet(mixed["parquet"])
    at = SUMMARY_COLUMNS.index("mag_unit")
    assert list(frame.columns) == SUMMARY_COLUMNS[:at] + ACC_COLUMNS + SUMMARY_COLUMNS[at:]
    by = frame.set_index("device_id")
    for c in ACC_COLUMNS:
        assert by.loc["acc", c] == row[c] and math.isnan(by.loc["plain", c])
    csv_frame = pd.read_csv(mixed["csv"]).set_index("device_id")
    np.testing.assert_array_equal(csv_frame.loc["acc", ACC_COLUMNS].to_numpy(float),
                                  np.array([row[c] for c in ACC_COLUMNS]))
    for path in (mixed["parquet"], mixed["csv"], only_plain["parquet"], only_plain["csv"]):
        assert is_batch_summary(path)                      # a batch's own output, never read as a device
    page = mixed["html"].read_text()
    if "<figure>" in page:                                  # with matplotlib: the accelerometer's figures
        for title, _ in ACC_FIGURES:
            assert html.escape(title) in page


def test_a_batch_with_accelerometer_calibrates_it_and_its_limits_judge_it(cals, tmp_path):
    _, cal, _ = cals
    assert options_digest(Options(), "nls", {}, None, None, False) != \
        options_digest(Options(accelerometer=True), "nls", {}, None, None, False)   # a rerun re-solves
    bias = max(abs(cal.accelerometer.bias_m_s2))
    limits = Limits(max_abs_acc_bias_m_s2=bias / 2, max_abs_acc_scale_ppm=1e6)
    result = run_batch([BROAD_02], tmp_path / "out", Options(accelerometer=True), limits=limits)
    (row,) = result.rows
    assert row["status"] == "calibrated" and row["verdict"] == "rejected"
    assert "acc_bias_m_s2_" in row["verdict_reason"] and "acc_scale" not in row["verdict_reason"]
    stored = json.loads((tmp_path / "out" / row["calibration"]).read_text())
    np.testing.assert_allclose(np.array(stored["accelerometer"]["K_a"]), cal.accelerometer.K_a, rtol=0, atol=1e-9)
    expected = R.row_from_calibration(row["device_id"], row["session"], cal)
    for c in ACC_COLUMNS:
        assert row[c] == pytest.approx(expected[c], rel=1e-6, abs=1e-9), c
    summary = pd.read_csv(result.summary_paths["csv"])
    assert all(c in summary.columns for c in ACC_COLUMNS)
