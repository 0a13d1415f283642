"""README.md (and the docs pages that took its sections), docs/spec.md and docs/real-data.md: every generated block
is what its generator makes now.

docs/recording.md has its own module (tests/test_recording_doc.py). The README's blocks come from the suite's
one solve of broad-02 (`broad02_solved`) and the code's constants; docs/real-data.md's from the record
docs/numbers/broad-trials.json, which benchmarks/broad_trials.py measured (the `broad` test re-measures a trial).
"""
from __future__ import annotations

import json
import sys
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).resolve().parent))
from scripts import DOCS, load_script  # noqa: E402

blocks_module = load_script(DOCS / "doc_blocks.py")
readme = load_script(DOCS / "make_readme_numbers.py")
spec = load_script(DOCS / "make_spec_numbers.py")
records = load_script(DOCS / "make_record_numbers.py")
table1 = load_script(DOCS / "make_table1_numbers.py")
observability = load_script(DOCS / "make_observability_table.py")
ekf_page = load_script(DOCS / "make_ekf_numbers.py")
accelerometer_page = load_script(DOCS / "make_accelerometer_numbers.py")
real_data = load_script(DOCS / "real_data_numbers.py")
readme_records = load_script(DOCS / "readme_record_numbers.py")
BROAD = DOCS.parent.parent / "shared" / "data" / "broad"


@pytest.fixture(scope="module")
def readme_blocks(broad02_acc_solved):
    """The README's blocks from the default solve of the shipped trial 02, which has an accelerometer it calibrates
    (the same calibration as `Options(accelerometer=True)`, conftest's broad02_acc_solved)."""
    return readme.blocks(broad02_acc_solved)


def stale_blocks(page: Path, made: dict[str, str]) -> list[str]:
    return blocks_module.stale(page.read_text(encoding="utf-8"), made)


def assert_fresh(generator, made: dict[str, str]) -> None:
    """The page of a generator (its PAGE, its COMMAND) holds exactly the blocks `made`."""
    page = generator.PAGE.relative_to(DOCS.parent)
    assert not stale_blocks(generator.PAGE, made), f"{page} is stale: regenerate it with `{generator.COMMAND}`"


def assert_every_block_generated(generator, made) -> None:
    """Every block of the generator's page is one it makes (no block is left to hand-editing)."""
    assert sorted(blocks_module.block_names_in_page(generator.PAGE.read_text(encoding="utf-8"))) == sorted(made)


def test_readme_is_what_the_tool_gives(readme_blocks):
    """The README and the pages its sections moved to (docs/how-it-works.md, results.md, ...): each page's blocks."""
    for page, share in readme.page_blocks(readme_blocks).items():
        assert not stale_blocks(page, share), (
            f"{page.relative_to(DOCS.parent)} is stale: regenerate it with `{readme.COMMAND}`")


def test_readme_has_no_block_without_a_generator(readme_blocks):
    """Every block of those pages is one the script makes, and every block it makes is in one of them."""
    in_pages = set()
    for page in readme.PAGES:
        names = blocks_module.block_names_in_page(page.read_text(encoding="utf-8"))
        assert sorted(set(names) - set(readme_blocks)) == [], page
        in_pages |= set(names)
    assert sorted(in_pages) == sorted(readme_blocks)


def test_the_readme_keeps_only_the_blocks_a_newcomer_needs():
    """Issue 40: the README has the suite's time and the bias sign; the rest went with its sections to docs/."""
    assert blocks_module.block_names_in_page(readme.PAGE.read_text(encoding="utf-8")) == ["suite-time", "bias-sign"]


def test_readme_quotes_the_lag_the_solve_prints(broad02_acc_solved, readme_blocks):
    """The issue's example: the README said +/-0.33 ms where `magyro solve` printed +/-0.45."""
    cal = broad02_acc_solved[1]
    assert f"{1e3 * cal.time_offset_s:.2f} +/- {1e3 * cal.to_dict()['std']['time_offset_s']:.2f} ms" in (
        readme_blocks["shipped-results"])


def test_spec_is_what_the_code_says():
    made = spec.blocks()
    assert_fresh(spec, made)


def test_a_changed_constant_makes_the_page_stale(monkeypatch):
    import dataclasses

    from magyro import targets

    stricter = dataclasses.replace(targets.Targets(), scale_factor_ppm=2000.0)
    monkeypatch.setattr(targets, "Targets", lambda: stricter)
    assert "2000 ppm of scale" in spec.why_targets()
    assert stale_blocks(spec.PAGE, spec.blocks()) == ["good-enough-defaults", "good-enough-why"]


def test_real_data_tables_are_rendered_from_their_record():
    made = records.blocks()
    assert_fresh(records, made)


def test_a_changed_record_changes_the_table():
    record = blocks_module.read_record(records.RECORD)
    record["trials"]["02"]["lag_ms"] += 1.0
    assert stale_blocks(records.PAGE, records.blocks(record)) == ["trials"]


def test_table1_is_rendered_from_its_record():
    """docs/table1.md: every table and figure is what magyro.studies.montecarlo_table makes of the record's runs."""
    made = table1.blocks()
    assert_fresh(table1, made)
    assert_every_block_generated(table1, made)


def test_the_table_is_recomputed_from_the_runs_not_copied():
    """The rows come from the runs' estimates: they are the ones `magyro montecarlo` wrote beside them."""
    record = blocks_module.read_record(table1.RECORD)
    for method, m in table1.result(record).methods.items():
        written = {p["name"]: p for p in record["methods"][method]["parameters"]}
        for row in m.rows:
            assert row.std == pytest.approx(written[row.name]["std"], rel=1e-12)
            assert row.mean == pytest.approx(written[row.name]["mean"], rel=1e-12)


def test_a_changed_monte_carlo_record_changes_table1_and_the_readme():
    record = blocks_module.read_record(table1.RECORD)
    run = next(r for r in record["methods"]["nls"]["runs"] if r["ok"])
    run["estimate"]["K_g[2,2]"] += 0.01          # one run far off: K_g[2,2]'s spread grows tenfold
    assert {"beside-paper", "full-table", "targets", "ekf"} <= set(stale_blocks(table1.PAGE, table1.blocks(record)))
    assert stale_blocks(readme.page_of("table1-summary"), table1.readme_blocks(record)) == ["table1-summary"]


def test_observability_constants_and_records_are_the_codes(monkeypatch):
    made = observability.cheap_blocks()
    assert_fresh(observability, made)
    from magyro.observability import gate

    monkeypatch.setattr(gate, "WELL_CONDITIONED", 50.0)
    assert stale_blocks(observability.PAGE, observability.cheap_blocks()) == ["well-conditioned"]


def test_observability_has_no_block_without_a_generator():
    """Its blocks are the cheap ones (checked here) and those made from observe's reports (tests/test_observe.py)."""
    assert_every_block_generated(observability, [*observability.cheap_blocks(), *observability.REPORT_BLOCKS])


def test_real_data_has_no_block_without_a_generator():
    assert_every_block_generated(records, records.blocks())


def test_a_changed_std_record_changes_real_data_and_the_readme():
    """Sections 2's tables and the README's room figures come from benchmarks/std_on_real_data.py's record."""
    record = blocks_module.read_record(real_data.STD_RECORD)
    record["trials"]["21"]["split_rms_z"] += 1.0
    page = records.PAGE.read_text(encoding="utf-8")
    assert blocks_module.block_in_page(page, "std-table") != real_data.std_table_block(record)
    readme_text = readme.page_of("split-broad").read_text(encoding="utf-8")
    assert blocks_module.block_in_page(readme_text, "split-broad") != readme_records.room(record)["split-broad"]


def test_a_changed_magnets_record_changes_section_4():
    record = blocks_module.read_record(real_data.MAGNETS_RECORD)
    solved = next(r for r in record["rows"] if "refused" not in r)
    solved["scale_minus_undisturbed_ppm"][0] += 1000.0
    page = records.PAGE.read_text(encoding="utf-8")
    assert blocks_module.block_in_page(page, "magnets-table") != real_data.magnets_table_block(record)
    assert blocks_module.block_in_page(page, "magnets-summary") != real_data.magnets_summary_block(record)


def test_ekf_page_is_rendered_from_its_records():
    made = ekf_page.blocks()
    assert_fresh(ekf_page, made)
    assert_every_block_generated(ekf_page, made)


def test_accelerometer_page_is_rendered_from_its_records():
    made = accelerometer_page.blocks()
    assert_fresh(accelerometer_page, made)
    assert_every_block_generated(accelerometer_page, made)


def test_a_changed_accelerometer_record_changes_its_page():
    text = accelerometer_page.PAGE.read_text(encoding="utf-8")
    sim = blocks_module.read_record(accelerometer_page.SIM_RECORDS["acc-sim-paper"])
    sim["reported"][7] *= 2.0                    # bias_y's reported std
    assert accelerometer_page.sim_table(sim) != blocks_module.block_in_page(text, "acc-sim-paper")
    real = blocks_module.read_record(accelerometer_page.REAL_RECORD)
    real["halves_rms_z"] += 1.0
    assert accelerometer_page.real_block(real) != blocks_module.block_in_page(text, "acc-broad-02")
    every = blocks_module.read_record(accelerometer_page.EVERY_REAL_RECORD)
    trial = next(row for row in every["rows"] if (row.get("dead_reckoning_rms_deg") or {}).get("with") is not None)
    trial["dead_reckoning_rms_deg"]["with"] *= 3.0        # the accelerometer would now harm the gyro there
    assert accelerometer_page.every_real_table(every) != blocks_module.block_in_page(text, "acc-real")
    assert accelerometer_page.every_real_summary(every) != blocks_module.block_in_page(text, "acc-real-summary")


def test_a_changed_ekf_record_changes_its_tables():
    real = blocks_module.read_record(ekf_page.REAL)
    both = next(r for r in real["rows"] if "max_abs_z" in r)
    both["max_abs_z"] += 10.0
    assert ekf_page.real_table_block(real) != blocks_module.block_in_page(ekf_page.PAGE.read_text(), "ekf-real-table")
    assert ekf_page.real_summary_block(real) != blocks_module.block_in_page(ekf_page.PAGE.read_text(),
                                                                            "ekf-real-summary")
    variants = blocks_module.read_record(ekf_page.VARIANTS)
    seed = next(iter(variants["variants"]["default"].values()))
    seed["scale_ppm"][0] += 5000.0           # K11 off by 0.005 more on one seed
    seed["K_g_upper"][0] += 0.005
    text = ekf_page.PAGE.read_text(encoding="utf-8")
    for name, make in (("ekf-variants", ekf_page.variants_block), ("ekf-default", ekf_page.default_block),
                       ("ekf-consider", ekf_page.consider_block)):
        assert make(variants) != blocks_module.block_in_page(text, name), name


def test_the_suite_time_script_reads_pytest_s_summary():
    bench = load_script(DOCS.parent / "benchmarks" / "suite_time.py")
    out = "....\n== 3 failed, 886 passed, 2 skipped in 586.1s (0:09:46) ==\n"
    assert bench.counts(out) == {"failed": 3, "passed": 886, "skipped": 2}
    assert bench.counts("no summary") == {}


def test_inline_and_line_blocks_are_rewritten_in_their_form():
    start, end = blocks_module.marker("a", "start"), blocks_module.marker("a", "end")
    s2, e2 = blocks_module.marker("b", "start"), blocks_module.marker("b", "end")
    text = f"x {start}1 %{end} y\n{s2}\nold\n{e2}\n"
    out = blocks_module.with_blocks(text, {"a": "2 %", "b": "new\nlines"})
    assert out == f"x {start}2 %{end} y\n{s2}\nnew\nlines\n{e2}\n"
    with pytest.raises(ValueError):
        blocks_module.with_blocks(text, {"a": "two\nlines"})


@pytest.mark.broad
@pytest.mark.heavy
@pytest.mark.slow
def test_the_record_is_what_trial_02_gives_now():
    """Provenance: BROAD trial 02 measured now (as benchmarks/broad_trials.py does) gives the record's row."""
    if not BROAD.is_dir():
        pytest.skip(f"no BROAD data at {BROAD}")
    bench = load_script(DOCS.parent / "benchmarks" / "broad_trials.py")
    now = records.condensed_trial(bench.run_trial(bench.trial_path(BROAD, "02"), split_check=True))
    recorded = blocks_module.read_record(records.RECORD)["trials"]["02"]
    assert records.trial_row("02", now) == records.trial_row("02", recorded), (
        "the BROAD record is stale: python benchmarks/broad_trials.py --out FILE, then "
        f"{records.COMMAND} --record FILE")
    json.dumps(now)   # the record stays JSON


@pytest.mark.broad
@pytest.mark.slow
def test_the_std_record_is_what_trial_02_gives_now():
    """Provenance: benchmarks/std_on_real_data.py's row of trial 02, measured now, is the record's."""
    if not BROAD.is_dir():
        pytest.skip(f"no BROAD data at {BROAD}")
    bench = load_script(DOCS.parent / "benchmarks" / "std_on_real_data.py")
    import magyro

    session = bench.import_broad_movement(sorted(BROAD.glob("02_*.mat"))[0], bench.MARGIN_S)
    cal = magyro.calibrate(session, bench.GYRO_ALONE)
    recorded = blocks_module.read_record(real_data.STD_RECORD)["trials"]["02"]
    assert 100 * cal.noise.field_disturbance.std_fraction == pytest.approx(recorded["disturbance_percent"], rel=1e-3)
    assert bench.split_rms_z(session, cal) == pytest.approx(
        (recorded["split_rms_z"], recorded["split_rms_z_white"]), rel=1e-3), (
        "the record is stale: python benchmarks/std_on_real_data.py --out docs/numbers/std-on-real-data.json")


@pytest.mark.slow
def test_the_trajectory_record_is_what_the_shipped_trial_gives_now():
    """Provenance: benchmarks/trajectory_accuracy.py on the shipped BROAD trial 02, measured now, is the record's."""
    bench = load_script(DOCS.parent / "benchmarks" / "trajectory_accuracy.py")
    recorded = blocks_module.read_record("trajectory-accuracy")["broad_02"]
    now = bench.broad02()
    assert [now["median_deg"], now["p95_deg"], *now["rms_z_per_axis"]] == pytest.approx(
        [recorded["median_deg"], recorded["p95_deg"], *recorded["rms_z_per_axis"]], rel=1e-3), (
        "the record is stale: python benchmarks/trajectory_accuracy.py --out docs/numbers/trajectory-accuracy.json")


def test_a_changed_reference_record_changes_sections_3_and_4():
    record = blocks_module.read_record(real_data.REFERENCE_RECORD)
    record["day_b"]["C_b_m_euler_deg"][2] += 1.0
    record["trials"]["34"]["mag"]["plain"]["rms_uT"] += 1.0
    page = records.PAGE.read_text(encoding="utf-8")
    assert blocks_module.block_in_page(page, "ref-frames") != real_data.reference_frames_block(record)
    assert blocks_module.block_in_page(page, "ref-magnets") != real_data.reference_magnets_block(record)
    assert blocks_module.block_in_page(page, "ref-mag-moves") != real_data.reference_prose(record)["ref-mag-moves"]


shipped_data = load_script(DOCS / "shipped_data_numbers.py")


def test_a_changed_stride_record_changes_the_readme():
    record = blocks_module.read_record("stride-agreement")
    record["rows"][0]["max_abs_z"] += 0.5
    text = readme.page_of("stride-agreement").read_text(encoding="utf-8")
    assert blocks_module.block_in_page(text, "stride-agreement") != readme_records.stride_agreement(record)


def test_a_changed_ekf_lag_record_changes_the_ekf_page():
    record = blocks_module.read_record(ekf_page.LAG)
    record["ekf_lag_ms"] += 1.0
    text = ekf_page.PAGE.read_text(encoding="utf-8")
    assert blocks_module.block_in_page(text, "ekf-lag-shipped") != ekf_page.lag_shipped_block(record)


def test_a_changed_reference_record_changes_the_fast_slow_scales():
    record = blocks_module.read_record(real_data.REFERENCE_RECORD)
    record["trials"]["07"]["ideal"]["scale_ppm"][0] -= 3000.0
    page = records.PAGE.read_text(encoding="utf-8")
    made = real_data.fast_slow_blocks(record)
    for name in ("ref-fast-slow", "ref-ideal-spread"):
        assert blocks_module.block_in_page(page, name) != made[name], name


def test_a_changed_trial_30_record_changes_the_readme():
    record = blocks_module.read_record(records.RECORD)
    record["trials"]["30"]["findings"] = []
    assert "finds nothing" in readme.anomaly_30(record)
    text = readme.page_of("anomaly-30").read_text(encoding="utf-8")
    assert blocks_module.block_in_page(text, "anomaly-30") != readme.anomaly_30(record)


def test_the_shipped_data_figures_are_computed_cheaply_and_follow_their_sources(monkeypatch):
    """The autocorrelations, magnetometer levels, rest drift and simulated-hand figures come from the shipped
    trials and the code (no solve); the drifting logger's from tests/degrade.py's defaults."""
    import time

    t0 = time.perf_counter()
    made = {"mag-autocorrelation": shipped_data.mag_autocorrelation_block(),
            "third-difference": shipped_data.third_difference_block(),
            "rest-drift": shipped_data.rest_drift_block(), "ekf-mag-levels": shipped_data.ekf_mag_levels_block()}
    assert time.perf_counter() - t0 < 5.0       # loads two trials and finds their rests: no solve
    pages = {"mag-autocorrelation": readme.page_of("mag-autocorrelation"),
             "third-difference": readme.page_of("third-difference"), "rest-drift": records.PAGE,
             "ekf-mag-levels": ekf_page.PAGE}
    for name, body in made.items():
        assert blocks_module.block_in_page(pages[name].read_text(encoding="utf-8"), name) == body, name
    monkeypatch.setattr(shipped_data, "NOISE_STD", 0.01)          # ten times the noise: the motion shows less
    assert shipped_data.third_difference_block() != made["third-difference"]
    degrade = shipped_data.degrade_module()
    import inspect

    assert f"{inspect.signature(degrade.drifting_burst_stamps).parameters['ppm'].default:+g} ppm" in (
        shipped_data.serial_drift_block())


@pytest.mark.slow
def test_the_ekf_lag_record_is_what_the_shipped_trial_gives_now():
    """Provenance: benchmarks/ekf_lag_shipped.py on the shipped trial 07, measured now, is the record's (one EKF
    solve, half a minute)."""
    bench = load_script(DOCS.parent / "benchmarks" / "ekf_lag_shipped.py")
    record = blocks_module.read_record(ekf_page.LAG)
    now = bench.ekf_lags_ms()
    for key in ("eq13_lag_ms", "ekf_lag_ms", "ekf_lag_std_ms"):
        assert now[key] == pytest.approx(record[key], abs=0.05), (
            f"{key}: the record is stale: python benchmarks/ekf_lag_shipped.py --out docs/numbers/ekf-lag-shipped.json")


@pytest.mark.broad
@pytest.mark.slow
def test_trial_30_s_field_anomaly_is_what_the_check_finds_now():
    """Provenance of the README's trial-30 example: the recording check on BROAD trial 30, now, finds the
    record's `field_anomaly`."""
    if not BROAD.is_dir():
        pytest.skip(f"no BROAD data at {BROAD}")
    from magyro.front.repairs import repair_recording
    from magyro.io import import_broad_movement

    bench = load_script(DOCS.parent / "benchmarks" / "broad_trials.py")
    session = import_broad_movement(bench.trial_path(BROAD, "30"), bench.MARGIN_S)
    kinds = {f.kind for f in repair_recording(session)[1].findings}
    recorded = blocks_module.read_record(records.RECORD)["trials"]["30"]["findings"]
    assert set(recorded) <= kinds


verify_records = load_script(DOCS.parent / "benchmarks" / "verify_records.py")


def test_every_record_is_re_measured_or_listed_as_too_expensive():
    """benchmarks/verify_records.py knows every record of docs/numbers/: it re-runs it, or lists it with its cost."""
    names = {path.stem for path in blocks_module.RECORDS.glob("*.json")}
    covered = [spec.name for spec in verify_records.COVERED]
    expensive = [e.name for e in verify_records.NOT_COVERED]
    assert sorted(covered + expensive) == sorted(names)


def test_a_record_not_re_measured_states_its_commit_where_it_is_shown():
    """A record too expensive for verify_records (or re-run only in part) shows its commit on every page that
    renders it: the reader sees how old the number is."""
    unverified = [*verify_records.NOT_COVERED, *(s for s in verify_records.COVERED if s.partial)]
    missing = []
    for e in unverified:
        commit = verify_records.record_commit(blocks_module.read_record(e.name))
        missing += [f"{e.name} ({commit}): {page}" for page in e.pages
                    if commit not in (DOCS.parent / page).read_text(encoding="utf-8")]
    assert not missing


def test_the_records_readme_lists_every_record():
    text = (blocks_module.RECORDS / "README.md").read_text(encoding="utf-8")
    assert [p.name for p in sorted(blocks_module.RECORDS.glob("*.json")) if f"`{p.name}`" not in text] == []


def test_verify_records_compares_within_each_fields_tolerance():
    """A deterministic field within its tolerance passes, beyond it fails; a timing off by more than its factor
    on a busy machine is shown, skipped, not failed."""
    spec = verify_records.Record("x", "", "", [verify_records.deterministic("rows.*.z", abs=0.01),
                                               verify_records.timing("seconds", 2.0)], ())
    old = {"rows": [{"z": 0.006}, {"z": 0.023}], "seconds": 10.0, "machine": "m"}
    verdicts = lambda new, load=0.0, strict=True: [row[4].split(" ")[0]
                                                   for row in verify_records.compare(spec, old, new, load, strict)]
    assert verdicts({"rows": [{"z": 0.010}, {"z": 0.023}], "seconds": 15.0, "machine": "m"}) == ["PASS", "PASS"]
    assert verdicts({"rows": [{"z": 0.086}, {"z": 0.023}], "seconds": 15.0, "machine": "m"}) == ["FAIL", "PASS"]
    assert verdicts({"rows": [{"z": 0.006}, {"z": 0.023}], "seconds": 40.0, "machine": "m"}) == ["PASS", "FAIL"]
    assert verdicts({"rows": [{"z": 0.006}, {"z": 0.023}], "seconds": 40.0, "machine": "m"}, 1.5) == ["PASS", "SKIP"]
    assert verdicts({"rows": [{"z": 0.006}, {"z": 0.023}], "seconds": 40.0, "machine": "other"}) == ["PASS", "SKIP"]
    # without --strict-timings (CI) a timing beyond its factor is shown, never failed; an estimate still fails
    assert verdicts({"rows": [{"z": 0.086}, {"z": 0.023}], "seconds": 40.0, "machine": "m"}, strict=False) == \
        ["FAIL", "MOVED"]
    nested = verify_records.Record("y", "", "", [verify_records.deterministic("rows.*.spans_s", abs=0.05)], ())
    assert verify_records.compare(nested, {"rows": [{"spans_s": [[0.0, 90.0]]}]},
                                  {"rows": [{"spans_s": [[0.0, 90.01]]}]}, 0.0)[0][4] == "PASS"
    old["other_load"] = "other processes used 42 CPU-s during the benchmark's 32 s (132 % of one of 2 CPUs; ...)"
    assert verdicts({"rows": [{"z": 0.006}, {"z": 0.023}], "seconds": 40.0, "machine": "m"}) == ["PASS", "SKIP"]


def test_verify_records_skips_a_broad_record_without_shared_and_says_so(monkeypatch, tmp_path, capsys):
    monkeypatch.setattr(verify_records, "BROAD", tmp_path / "no-broad")
    assert verify_records.main(["--only", "std-on-real-data"]) == 0
    assert "SKIP: no ../shared/data/broad" in capsys.readouterr().out
