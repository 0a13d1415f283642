"""Acceptance limits (magyro.batch.limits) and the fleet summary (magyro.batch.summary) on simulated rows."""
from __future__ import annotations

import math
import re
import sys
from dataclasses import replace
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from magyro.batch import row as R
from magyro.batch.limits import Limits, load_limits, verdict, with_verdicts
from magyro.batch.summary import FIGURES, SUMMARY_COLUMNS, outliers, write_summary
from magyro.errors import InputError, SolverError

# one-sigma spread of each column across a simulated fleet (phone grade) and its centre
SPREAD = {"scale_ppm": (0.0, 5000.0), "nonorth_deg": (0.0, 0.3), "bias_deg_s": (0.0, 0.3),
          "misalignment_deg": (0.0, 1.0), "std_scale_ppm": (800.0, 100.0), "std_nonorth_deg": (0.03, 0.004),
          "std_bias_deg_s": (0.01, 0.001), "std_misalignment_deg": (0.1, 0.01), "hard_iron": (0.0, 10.0),
          "field_strength": (50.0, 1.0), "time_offset_s": (0.0, 0.002)}


def calibrated_row(device_id: str, rng, **values) -> dict:
    row = R.empty_row(device_id, f"{device_id}.parquet")
    for column in R.parameter_columns():
        for prefix, (centre, sigma) in SPREAD.items():
            if column == prefix or column.rsplit("_", 1)[0] == prefix:
                row[column] = float(rng.normal(centre, sigma))
    row.update(status="calibrated", exit_code=0, exit_class="done", message="calibrated", seconds=4.2, rank=12.0,
               mag_unit="uT", calibration=f"{device_id}.json")
    row.update(values)
    return row


def fleet(n: int, seed: int = 0) -> list[dict]:
    rng = np.random.default_rng(seed)
    return [calibrated_row(f"dev-{i:03d}", rng) for i in range(n)]


def failed_row(device_id: str, message: str = "the session has no gyro_x column") -> dict:
    return R.row_from_failure(device_id, f"{device_id}.csv", InputError(message))


def good_row(**values) -> dict:
    """A calibrated row inside every limit of LIMITS below."""
    row = calibrated_row("dev", np.random.default_rng(1))
    for c in R.parameter_columns():
        if c.startswith(("scale", "nonorth", "bias", "misalignment")):
            row[c] = 0.0
    row.update(split_rms_z=1.0)
    row.update(values)
    return row


LIMITS = Limits(max_abs_scale_ppm=20000, max_abs_nonorth_deg=1.0, max_abs_bias_deg_s=0.5,
                max_abs_misalignment_deg=3.0, target_scale_ppm=2000, target_nonorth_deg=0.1,
                target_bias_deg_s=0.05, target_misalignment_deg=0.3, max_split_rms_z=3.0)


# --------------------------------------------------------------------------- verdicts


def test_inside_every_limit_is_accepted():
    assert verdict(good_row(), LIMITS) == ("accepted", "")
    assert verdict(good_row(), None) == ("accepted", "")
    assert verdict(good_row(), Limits()) == ("accepted", "")


@pytest.mark.parametrize("key, column, value, expected", [
    ("max_abs_scale_ppm", "scale_ppm_z", -25000.0, "|scale_ppm_z| = 25000 > 20000 ppm"),
    ("max_abs_nonorth_deg", "nonorth_deg_xz", 1.2, "|nonorth_deg_xz| = 1.2 > 1.0 deg"),
    ("max_abs_bias_deg_s", "bias_deg_s_y", -0.62, "|bias_deg_s_y| = 0.62 > 0.50 deg/s"),
    ("max_abs_misalignment_deg", "misalignment_deg_yaw", 3.5, "|misalignment_deg_yaw| = 3.5 > 3.0 deg"),
    ("target_scale_ppm", "std_scale_ppm_x", 2400.0, "std_scale_ppm_x = 2400 > 2000 ppm"),
    ("target_nonorth_deg", "std_nonorth_deg_yz", 0.15, "std_nonorth_deg_yz = 0.15 > 0.10 deg"),
    ("target_bias_deg_s", "std_bias_deg_s_z", 0.07, "std_bias_deg_s_z = 0.070 > 0.050 deg/s"),
    ("target_misalignment_deg", "std_misalignment_deg_y", 0.45, "std_misalignment_deg_y = 0.45 > 0.30 deg"),
    ("max_split_rms_z", "split_rms_z", 4.2, "split_rms_z = 4.2 > 3.0"),
])
def test_each_limit_rejects_with_its_numbers(key, column, value, expected):
    assert verdict(good_row(**{column: value}), LIMITS) == ("rejected", expected)
    assert verdict(good_row(**{column: value}), replace(LIMITS, **{key: None})) == ("accepted", "")
    if key.startswith("max_abs"):   # an absolute limit bounds both signs
        assert verdict(good_row(**{column: -value}), LIMITS)[0] == "rejected"


def test_a_value_just_above_a_limit_is_not_shown_equal_to_it():
    kind, reason = verdict(good_row(bias_deg_s_x=0.5004), LIMITS)
    assert kind == "rejected"
    value, limit = re.match(r"\|bias_deg_s_x\| = ([\d.]+) > ([\d.]+) deg/s", reason).groups()
    assert value != limit and float(value) > float(limit)


def test_every_broken_limit_is_named_in_order():
    row = good_row(bias_deg_s_y=-0.62, std_scale_ppm_x=2400.0, warning_kinds="split_check")
    limits = replace(LIMITS, reject_warnings=("split_check",))
    assert verdict(row, limits) == (
        "rejected", "|bias_deg_s_y| = 0.62 > 0.50 deg/s; std_scale_ppm_x = 2400 > 2000 ppm; warning split_check")


def test_nan_of_a_limited_quantity_rejects():
    row = good_row(split_rms_z=math.nan)
    assert verdict(row, LIMITS) == ("rejected", "split_rms_z not measured (run the batch with --split-check)")
    assert verdict(row, Limits(max_abs_bias_deg_s=0.5)) == ("accepted", "")   # no limit on it: no matter
    kind, reason = verdict(good_row(std_bias_deg_s_x=math.nan), LIMITS)
    assert kind == "rejected" and reason.startswith("std_bias_deg_s_x not measured")


def test_warnings_by_kind_and_any():
    row = good_row(warning_kinds="rests,split_check")
    assert verdict(row, Limits(reject_warnings=("forced",))) == ("accepted", "")
    assert verdict(row, Limits(reject_warnings=("split_check",))) == ("rejected", "warning split_check")
    assert verdict(row, Limits(reject_warnings=("any",))) == ("rejected", "warning rests; warning split_check")
    assert verdict(good_row(warning_kinds=""), Limits(reject_warnings=("any",))) == ("accepted", "")


def test_findings_reject_repaired_or_not():
    limits = Limits(reject_findings=("saturation",))
    repaired = good_row(findings="spikes,saturation", repaired="saturation")
    assert verdict(repaired, limits) == ("rejected", "finding saturation (repaired)")
    assert verdict(good_row(findings="saturation", warning_kinds="saturation"), limits) == (
        "rejected", "finding saturation")
    assert verdict(good_row(findings="spikes", repaired="spikes"), limits) == ("accepted", "")


def test_failed_rows_fail_whatever_the_limits():
    row = failed_row("dev-9", "the session has no gyro_x column")
    assert verdict(row, None) == ("failed", "exit 2, unusable input: the session has no gyro_x column")
    assert verdict(R.row_from_failure("d", "s", SolverError("IPOPT gave up")), LIMITS) == (
        "failed", "exit 1, solver failed: IPOPT gave up")


def test_with_verdicts_adds_columns_to_copies():
    rows = [good_row(), good_row(bias_deg_s_x=0.9), failed_row("x")]
    out = with_verdicts(rows, LIMITS)
    assert [r["verdict"] for r in out] == ["accepted", "rejected", "failed"]
    assert out[1]["verdict_reason"] == "|bias_deg_s_x| = 0.90 > 0.50 deg/s"
    assert all("verdict" not in r for r in rows)


# --------------------------------------------------------------------------- the limits file


def test_example_limits_file_loads():
    from pathlib import Path
    limits = load_limits(Path(__file__).resolve().parent.parent / "docs" / "limits-example.toml")
    assert limits.max_abs_scale_ppm > 0 and limits.target_bias_deg_s > 0
    assert "saturation" in limits.reject_findings


def test_load_limits_reads_a_file(tmp_path):
    path = tmp_path / "limits.toml"
    path.write_text("[limits]\nmax_abs_bias_deg_s = 0.5\ntarget_scale_ppm = 2000\nreject_warnings = ['any']\n")
    assert load_limits(path) == Limits(max_abs_bias_deg_s=0.5, target_scale_ppm=2000.0, reject_warnings=("any",))


@pytest.mark.parametrize("text, words", [
    ("[limits]\nmax_abs_bias = 0.5\n", ["max_abs_bias", "max_abs_bias_deg_s"]),          # says which keys exist
    ("[limits]\nmax_abs_bias_deg_s = -0.5\n", ["max_abs_bias_deg_s", "negative"]),
    ("[limits]\ntarget_scale_ppm = 'a lot'\n", ["target_scale_ppm", "number"]),
    ("[limits]\ntarget_scale_ppm = true\n", ["target_scale_ppm", "number"]),
    ("[limits]\nmax_abs_bias_deg_s = nan\n", ["max_abs_bias_deg_s", "finite"]),
    ("[limits]\nreject_warnings = ['saturaton']\n", ["reject_warnings", "saturaton"]),
    ("[limits]\nreject_findings = [1]\n", ["reject_findings"]),
    ("[limits\nmax_abs_bias_deg_s = 0.5\n", ["not valid TOML"]),
    ("max_abs_bias_deg_s = 0.5\n", ["max_abs_bias_deg_s", "[limits]"]),                  # outside the table
    ("[limits]\n[schema]\nversion = 1\n", ["schema"]),
    ("", ["[limits]"]),
])
def test_load_limits_refuses(tmp_path, text, words):
    path = tmp_path / "limits.toml"
    path.write_text(text)
    with pytest.raises(InputError) as info:
        load_limits(path)
    message = str(info.value)
    assert str(path) in message and "\n" not in message
    for word in words:
        assert word in message


def test_load_limits_missing_file(tmp_path):
    with pytest.raises(InputError, match="not found") as info:
        load_limits(tmp_path / "nope.toml")
    assert "nope.toml" in str(info.value)


# --------------------------------------------------------------------------- outliers


def test_a_planted_outlier_is_named_and_a_clean_fleet_has_none():
    rows = fleet(40, seed=3)
    assert outliers(rows) == []
    sigma = SPREAD["bias_deg_s"][1]
    rows[17]["bias_deg_s_y"] = float(np.median([r["bias_deg_s_y"] for r in rows]) + 10 * sigma)
    found = outliers(rows)
    assert [(o["device_id"], o["column"]) for o in found] == [("dev-017", "bias_deg_s_y")]
    assert found[0]["robust_z"] > 5 and found[0]["value"] == rows[17]["bias_deg_s_y"]


def test_outliers_need_enough_calibrated_devices():
    rows = fleet(7, seed=4)
    rows[0]["bias_deg_s_x"] = 100.0
    assert outliers(rows) == []
    rows += [failed_row(f"f{i}") for i in range(5)]          # failed rows do not count
    assert outliers(rows) == []
    assert outliers(rows, min_devices=7)[0]["device_id"] == "dev-000"


def test_outliers_columns_and_threshold():
    rows = fleet(20, seed=5)
    rows[3]["scale_ppm_x"] = 4 * SPREAD["scale_ppm"][1]
    assert outliers(rows, columns=["bias_deg_s_x"]) == []
    assert any(o["device_id"] == "dev-003" for o in outliers(rows, columns=["scale_ppm_x"], threshold=2.5))


# --------------------------------------------------------------------------- the files


def mixed_fleet(n: int = 40, seed: int = 7):
    rows = fleet(n, seed)
    rows[2]["bias_deg_s_x"] = 1.9            # over 1.5 deg/s
    rows[5]["warning_kinds"] = "split_check"
    rows.append(failed_row("dev-bad<1>", "no <gyro> & no mag"))
    rows.append(R.row_from_failure("dev-zz", "zz.csv", SolverError("IPOPT: maximum iterations")))
    return rows


def test_parquet_and_csv_round_trip(tmp_path):
    rows = mixed_fleet()
    rows = rows[::-1]                         # given in any order, written sorted by device
    limits = Limits(max_abs_bias_deg_s=1.5, reject_warnings=("split_check",))
    paths = write_summary(rows, tmp_path, limits)
    assert set(paths) == {"parquet", "csv", "html"} and all(p.exists() for p in paths.values())
    assert not [p for p in tmp_path.iterdir() if p.name.startswith(".")]        # no temp file left

    frame = pd.read_parquet(paths["parquet"])
    text_columns = set(R.TEXT_COLUMNS) | {"verdict", "verdict_reason"}
    numeric = [c for c in SUMMARY_COLUMNS if c not in text_columns and c != "exit_code"]
    assert list(frame.columns) == SUMMARY_COLUMNS == list(R.COLUMNS) + ["verdict", "verdict_reason"]
    assert len(frame) == len(rows)
    assert list(frame["device_id"]) == sorted(r["device_id"] for r in rows)
    for c in numeric:   # split_rms_z is NaN in every row: it stays float
        assert frame[c].dtype == np.float64, c
    assert frame["split_rms_z"].isna().all()
    assert frame["exit_code"].dtype == np.int64
    for c in text_columns:
        assert pd.api.types.is_string_dtype(frame[c]), c
    verdicts = dict(zip(frame["device_id"], frame["verdict"]))
    assert verdicts["dev-002"] == "rejected" and verdicts["dev-005"] == "rejected"
    assert verdicts["dev-bad<1>"] == "failed" and verdicts["dev-000"] == "accepted"
    assert (frame["verdict"] == "accepted").sum() == 38
    reasons = dict(zip(frame["device_id"], frame["verdict_reason"]))
    assert reasons["dev-002"] == "|bias_deg_s_x| = 1.9 > 1.5 deg/s"
    assert reasons["dev-zz"] == "exit 1, solver failed: IPOPT: maximum iterations"
    original = {r["device_id"]: r for r in rows}
    assert np.allclose(frame["scale_ppm_y"], [original[d]["scale_ppm_y"] for d in frame["device_id"]],
                       equal_nan=True)

    csv = pd.read_csv(paths["csv"], dtype={c: str for c in text_columns}, keep_default_na=False,
                      na_values={c: [""] for c in numeric})
    assert list(csv.columns) == SUMMARY_COLUMNS and len(csv) == len(rows)
    for c in numeric:
        assert csv[c].dtype == np.float64, c
    assert csv["exit_code"].dtype == np.int64
    assert list(csv["verdict"]) == list(frame["verdict"])
    assert list(csv["verdict_reason"]) == list(frame["verdict_reason"])
    assert list(csv["message"]) == list(frame["message"])
    for c in numeric:   # full precision
        assert np.array_equal(csv[c].to_numpy(), frame[c].to_numpy(), equal_nan=True), c


def test_html_names_failures_and_outliers(tmp_path):
    rows = mixed_fleet(40)
    rows[11]["scale_ppm_z"] = 10 * SPREAD["scale_ppm"][1]       # 10 sigma
    page = write_summary(rows, tmp_path, LIMITS, title="Line 3 <night shift>")["html"].read_text(encoding="utf-8")
    assert "Line 3 &lt;night shift&gt;" in page and "<night shift>" not in page
    assert "dev-bad&lt;1&gt;" in page and "no &lt;gyro&gt; &amp; no mag" in page and "dev-bad<1>" not in page
    assert "exit 1, solver failed: IPOPT: maximum iterations" in page and "dev-zz" in page
    assert "|bias_deg_s_x| = 1.90 &gt; 0.50 deg/s" in page
    table = page.split("<h2>Outliers</h2>", 1)[1]
    assert "<td>dev-011</td><td>scale_ppm_z</td>" in table
    assert "<td>dev-002</td><td>bias_deg_s_x</td>" in table        # the planted 1.9 deg/s is 6 sigma out too
    assert table.count("<tr>") == 3                                # the header and the two outliers
    assert page.count("data:image/png;base64,") == 3
    assert not re.search(r"""(src|href)\s*=\s*["']?\s*(https?:)?//""", page, re.I)
    assert "http://" not in page and "https://" not in page


def test_html_of_a_clean_fleet_names_no_outlier(tmp_path):
    page = write_summary(fleet(40, seed=3), tmp_path)["html"].read_text(encoding="utf-8")
    assert "<h2>Outliers</h2><p class='sentence'>None." in page
    assert "40 of 40 accepted" in page


def test_html_of_200_devices_is_small(tmp_path):
    rows = fleet(200, seed=8)
    rows += [failed_row(f"broken-{i}") for i in range(20)]
    rows[0]["bias_deg_s_z"] = 5.0
    path = write_summary(rows, tmp_path, LIMITS)["html"]
    assert path.stat().st_size < 2_000_000
    page = path.read_text(encoding="utf-8")
    assert all(f"broken-{i}" in page for i in range(20))


def test_html_without_matplotlib(tmp_path, monkeypatch):
    monkeypatch.setitem(sys.modules, "matplotlib", None)         # import matplotlib -> ImportError
    page = write_summary(mixed_fleet(10), tmp_path, LIMITS)["html"].read_text(encoding="utf-8")
    assert "data:image/png" not in page
    assert "pip install 'magyro[plot]', or pip install '.[plot]' in a clone" in page.replace("&#x27;", "'")
    assert "dev-bad&lt;1&gt;" in page


def test_no_device_and_no_calibrated_device(tmp_path):
    paths = write_summary([], tmp_path)
    assert len(pd.read_parquet(paths["parquet"])) == 0
    assert list(pd.read_parquet(paths["parquet"]).columns) == SUMMARY_COLUMNS
    page = write_summary([failed_row("a"), failed_row("b")], tmp_path)["html"].read_text(encoding="utf-8")
    assert "No device calibrated" in page and "0 of 2 accepted" in page


# --------------------------------------------------------------------------- crisp, readable figures (issue 24)


def test_an_embedded_figure_has_twice_the_pixels_it_is_shown_at_and_knows_its_smallest_text():
    pytest.importorskip("matplotlib")
    from magyro.report.embed import embed_png
    from magyro.report.figures import new_figure

    fig = new_figure(9.5, 3.0)
    ax = fig.subplots()
    ax.plot([0, 1], [0, 1])
    ax.tick_params(labelsize=9)
    ax.text(0.5, 0.5, "small", fontsize=5)
    shown = embed_png(fig, 984)
    assert (shown.pixel_width, shown.width_px) == (1968, 984) and shown.pixel_height - 2 * shown.height_px in (0, 1)
    assert shown.smallest_font_px == pytest.approx(5 * 984 / 9.5 / 72)      # 5 pt of a 9.5 in figure 984 px wide
    assert "width='984'" in shown.img("a") and f"height='{shown.height_px}'" in shown.img("a")


def test_summary_figures_are_crisp_and_readable_in_a_browser(tmp_path):
    """The page's figures have twice the pixels the browser shows them at, and their smallest text is 10 px there."""
    pytest.importorskip("matplotlib")
    sys.path.insert(0, str(Path(__file__).resolve().parent))
    from browser import assert_crisp_and_readable, figures_of

    rows = mixed_fleet(40)
    rows[11]["scale_ppm_z"] = 10 * SPREAD["scale_ppm"][1]      # an outlier, named on its figure
    figures = figures_of(write_summary(rows, tmp_path, LIMITS)["html"])
    assert len(figures) == len(FIGURES)
    assert_crisp_and_readable(figures)
