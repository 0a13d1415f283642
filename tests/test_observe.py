"""`magyro observe`: the excitation report on the canonical motions, its JSON, its CLI, and the docs table.

The ranks are the theorem's (docs/observability.md derives them): still 2, one axis 6,
two axes 9, three axes 12. Every canonical problem is observed once (seed 0) and shared.
"""
from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np
import pytest

from magyro.errors import InputError
from magyro.io import write_session
from magyro.observability import Targets
from magyro.observability.excitation import judge, sphere_cell
from magyro.observability.plot import plot_report
from magyro.observability.report import SCHEMA, SPHERE_BANDS, SPHERE_SECTORS
from magyro.studies.scenario import load_problem
from magyro.studies.simulate import motion_factors, simulate

sys.path.insert(0, str(Path(__file__).resolve().parent))
from scripts import DOCS, load_script  # noqa: E402


table_script = load_script(DOCS / "make_observability_table.py")
THEOREM = {name: rank for name, _, rank in table_script.CANONICAL}
SPEC_KEYS = ("schema", "rank", "condition", "eigenvalues", "full_rank_at_s", "verdict", "weak_directions",
             "predicted_std")
STD_SHAPES = {"K_g": (3, 3), "bias_deg_s": (3,), "misalignment_deg": (3,), "R": (3, 3), "h": (3,)}


@pytest.fixture(scope="module")
def reports():
    return table_script.canonical_reports(seed=0)


# --------------------------------------------------------------------------- the theorem


@pytest.mark.parametrize("name", list(THEOREM))
def test_rank_is_the_theorems(reports, name):
    assert reports[name].rank == THEOREM[name]


@pytest.mark.parametrize("name", list(THEOREM))
def test_cumulative_integral_ends_at_the_gates_rank(reports, name):
    """The timeline judges each checkpoint like the gate judges the session: the last one is the gate's rank."""
    r = reports[name]
    tl = r.timeline
    assert tl.rank[-1] == r.rank
    assert [tl.t_s[0], tl.t_s[-1]] == pytest.approx(r.analysed_span_s)  # it covers what the gate judged


def test_docs_table_is_what_the_tool_gives(reports):
    page = (DOCS / "observability.md").read_text(encoding="utf-8")
    made = table_script.report_blocks(reports)
    assert sorted(made) == sorted(table_script.REPORT_BLOCKS)
    assert [n for n in made if table_script.doc_blocks.block_in_page(page, n) != made[n]] == [], (
        "docs/observability.md disagrees with the tool: regenerate it with `python docs/make_observability_table.py`")


# --------------------------------------------------------------------------- verdicts and times


def test_single_axis_is_insufficient_and_never_full_rank(reports):
    r = reports["axis-x"]
    assert r.verdict == "insufficient" and r.exit_code == 3
    assert r.full_rank_at_s is None and r.well_conditioned_at_s is None
    assert not r.ellipsoid_fitted and "plane" in r.reason
    assert any("y-axis response" in w for w in r.weak_directions)
    assert any("z-axis response" in w for w in r.weak_directions)
    assert any("y axis and z axis" in a for a in r.advice)


def test_paper_table1_is_sufficient_and_full_rank_early(reports):
    r = reports["paper-table1"]
    assert r.verdict == "sufficient" and r.exit_code == 0
    assert 0.0 < r.full_rank_at_s < r.duration_s
    assert r.full_rank_at_s <= r.well_conditioned_at_s < r.duration_s
    assert r.condition < 100
    # the paper's Table I 3-sigma figures, as one sigma: scale 900 ppm/3, non-orthogonality 0.09/3 deg, bias 0.02/3
    std = r.predicted_std
    assert np.all(np.diag(std.K_g) < 300e-6 * 1.5)
    assert np.all(std.bias_deg_s < 0.02 / 3 * 1.5)


def test_full_rank_waits_for_the_last_axis(reports):
    """three-axes turns about x, then y, then z: the integral cannot be full rank before z starts."""
    z_starts_s = motion_factors(load_problem("three-axes"))[2].start_s
    r = reports["three-axes"]
    assert r.full_rank_at_s is not None
    assert z_starts_s < r.full_rank_at_s < r.duration_s
    assert r.full_rank_at_s > reports["paper-table1"].full_rank_at_s
    assert r.timeline.rank[r.timeline.t_s < z_starts_s].max() == 9  # two axes' worth until then


def test_still_device_turns_nothing_and_sees_one_field_direction(reports):
    r = reports["static"]
    assert r.verdict == "insufficient"
    assert np.all(r.coverage.angle_turned_deg < 30.0)  # noise only, the bias taken out
    assert r.coverage.cells_visited <= 3
    assert any("all three" in a for a in r.advice)


def test_tight_targets_make_a_full_rank_session_marginal(reports):
    r = reports["paper-table1"]
    verdict, reason = judge(r.analysis, None, r.predicted_std, Targets(scale_factor_ppm=100.0))
    assert verdict == "marginal" and "scale factor" in reason
    assert judge(r.analysis, None, r.predicted_std, Targets())[0] == "sufficient"


def test_sphere_cells_have_equal_area():
    rng = np.random.default_rng(0)
    u = rng.normal(size=(288_000, 3))
    counts = np.bincount(sphere_cell(u), minlength=SPHERE_BANDS * SPHERE_SECTORS)
    expected = len(u) / counts.size
    assert counts.size == SPHERE_BANDS * SPHERE_SECTORS
    assert np.all(np.abs(counts - expected) < 5 * np.sqrt(expected))


# --------------------------------------------------------------------------- the JSON


def test_json_has_the_spec_keys(reports):
    for name in ("axis-x", "paper-table1"):
        d = json.loads(reports[name].to_json())  # allow_nan=False: no Infinity/NaN in the file
        for key in SPEC_KEYS:
            assert key in d, key
        assert d["schema"] == SCHEMA == "magyro.observability/1"
        assert d["verdict"] in ("sufficient", "marginal", "insufficient")
        lam = np.array(d["eigenvalues"])
        assert lam.shape == (12,) and np.all(np.diff(lam) >= 0) and lam[-1] == pytest.approx(1.0)
        assert all(isinstance(w, str) for w in d["weak_directions"])
        for key, shape in STD_SHAPES.items():
            assert np.array(d["predicted_std"][key], dtype=float).shape == shape, key
        assert set(d["coverage"]["axes"]) == {"x", "y", "z"}
        assert d["coverage"]["sphere"]["cells"] == SPHERE_BANDS * SPHERE_SECTORS
    axis_x = json.loads(reports["axis-x"].to_json())
    paper = json.loads(reports["paper-table1"].to_json())
    turned = {a: v["angle_turned_deg"] for a, v in axis_x["coverage"]["axes"].items()}
    assert turned["x"] > 10 * max(turned["y"], turned["z"])  # turned about x only: y and z hold noise
    assert paper["coverage"]["sphere"]["fraction_visited"] > 2 * axis_x["coverage"]["sphere"]["fraction_visited"]
    assert axis_x["full_rank_at_s"] is None
    assert axis_x["predicted_std"]["bias_deg_s"] == [None, None, None]
    assert all(v is not None for v in paper["predicted_std"]["bias_deg_s"])


# --------------------------------------------------------------------------- the command line


def write(tmp_path, name) -> Path:
    path = tmp_path / f"{name}.parquet"
    write_session(simulate(load_problem(name), 0)[0], path)
    return path


def test_cli_axis_x_exits_3_and_still_writes_the_report(tmp_path, run_magyro, assert_plain_failure):
    out = tmp_path / "report.json"
    result = run_magyro("observe", write(tmp_path, "axis-x"), "-o", out)
    message = assert_plain_failure(result, 3)
    assert "insufficient" in message and "y axis and z axis" in message
    assert "INSUFFICIENT" in result.stdout and "rank 6 of 12" in result.stdout
    report = json.loads(out.read_text())
    assert report["verdict"] == "insufficient" and report["rank"] == 6


def test_cli_paper_table1_exits_0_with_json_and_figure(tmp_path, run_magyro):
    pytest.importorskip("matplotlib")
    out, fig = tmp_path / "report.json", tmp_path / "report.png"
    result = run_magyro("observe", write(tmp_path, "paper-table1"), "-o", out, "--plot", fig)
    assert result.returncode == 0, result.stderr
    assert "SUFFICIENT" in result.stdout and "rank 12 of 12" in result.stdout
    report = json.loads(out.read_text())
    assert report["verdict"] == "sufficient" and report["rank"] == 12
    assert fig.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["paper-table1.parquet", "report.json", "report.png"]


def test_cli_bad_input_exits_2(tmp_path, run_magyro, assert_plain_failure):
    bad = tmp_path / "bad.csv"
    bad.write_text("t,gx,gy\n0,1,2\n")
    message = assert_plain_failure(run_magyro("observe", bad, "-o", tmp_path / "r.json"), 2)
    assert "missing column" in message
    assert not (tmp_path / "r.json").exists()


def test_plot_without_matplotlib_says_how_to_install(reports, tmp_path, monkeypatch):
    monkeypatch.setitem(sys.modules, "matplotlib", None)  # import matplotlib now raises ImportError
    with pytest.raises(InputError, match=r"pip install 'magyro\[plot\]'"):
        plot_report(reports["axis-x"], tmp_path / "fig.png")
    assert not (tmp_path / "fig.png").exists()
