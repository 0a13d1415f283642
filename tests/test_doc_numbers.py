"""README.md, docs/spec.md and docs/real-data.md: every generated block is what its generator makes now.

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
BROAD = DOCS.parent.parent / "shared" / "data" / "broad"


@pytest.fixture(scope="module")
def readme_blocks(broad02_solved):
    return readme.blocks(broad02_solved)


def stale_blocks(page: Path, made: dict[str, str]) -> list[str]:
    return blocks_module.stale(page.read_text(encoding="utf-8"), made)


def test_readme_is_what_the_tool_gives(readme_blocks):
    assert not stale_blocks(readme.PAGE, readme_blocks), f"README.md is stale: regenerate it with `{readme.COMMAND}`"


def test_readme_has_no_block_without_a_generator(readme_blocks):
    names = blocks_module.block_names_in_page(readme.PAGE.read_text(encoding="utf-8"))
    assert sorted(names) == sorted(readme_blocks)


def test_readme_quotes_the_lag_the_solve_prints(broad02_solved, readme_blocks):
    """The issue's example: the README said +/-0.33 ms where `magyro solve` printed +/-0.45."""
    cal = broad02_solved[1]
    assert f"{1e3 * cal.time_offset_s:.2f} +/- {1e3 * cal.to_dict()['std']['time_offset_s']:.2f} ms" in (
        readme_blocks["shipped-results"])


def test_spec_is_what_the_code_says():
    made = spec.blocks()
    assert not stale_blocks(spec.PAGE, made), f"docs/spec.md is stale: regenerate it with `{spec.COMMAND}`"


def test_a_changed_constant_makes_the_page_stale(monkeypatch):
    import dataclasses

    from magyro import targets

    stricter = dataclasses.replace(targets.Targets(), scale_factor_ppm=2000.0)
    monkeypatch.setattr(targets, "Targets", lambda: stricter)
    assert "2000 ppm of scale" in spec.why_targets()
    assert stale_blocks(spec.PAGE, spec.blocks()) == ["good-enough-defaults", "good-enough-why"]


def test_real_data_tables_are_rendered_from_their_record():
    made = records.blocks()
    assert not stale_blocks(records.PAGE, made), f"docs/real-data.md is stale: regenerate it with `{records.COMMAND}`"


def test_a_changed_record_changes_the_table():
    record = blocks_module.read_record(records.RECORD)
    record["trials"]["02"]["lag_ms"] += 1.0
    assert stale_blocks(records.PAGE, records.blocks(record)) == ["trials"]


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
