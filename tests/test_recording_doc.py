"""docs/recording.md: every block of numbers is what magyro gives now (docs/make_recording_numbers.py).

The blocks are made once (about 10 s: 20 simulated sessions through `magyro.observe`, the
BROAD trial and its degraded copies through the recording check; broad-02's solve is the shared
`broad02_solved` fixture's) and shared.
"""
from __future__ import annotations

import sys

from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).resolve().parent))
from scripts import DOCS, load_script  # noqa: E402
PAGE = DOCS / "recording.md"


numbers = load_script(DOCS / "make_recording_numbers.py")
REGENERATE = "regenerate it with `python docs/make_recording_numbers.py`"


@pytest.fixture(scope="module")
def blocks(broad02_solved):
    return numbers.blocks(broad02_solved)


@pytest.mark.slow
@pytest.mark.parametrize("name", numbers.BLOCK_NAMES)
def test_page_block_is_what_the_tool_gives(blocks, name):
    page = PAGE.read_text(encoding="utf-8")
    assert numbers.block_in_page(page, name) == blocks[name], (
        f"docs/recording.md, block {name}, disagrees with the tool: {REGENERATE}")


@pytest.mark.slow
def test_check_mode_fails_on_a_stale_page_and_passes_on_a_fresh_one(blocks, tmp_path, monkeypatch, capsys):
    monkeypatch.setattr(numbers, "blocks", lambda: blocks)   # no second regeneration
    page = PAGE.read_text(encoding="utf-8")
    stale = tmp_path / "recording.md"
    stale.write_text(page.replace(blocks["duration"], blocks["duration"].replace("|", "| 1", 1)), encoding="utf-8")
    assert numbers.main(["--check", str(stale)]) == 1
    assert "duration" in capsys.readouterr().out
    assert numbers.main([str(stale)]) == 0                   # rewrite it ...
    assert stale.read_text(encoding="utf-8") == page         # ... into the page as shipped
    assert numbers.main(["--check", str(stale)]) == 0


def test_a_page_without_the_numbers_is_filled_in():
    """The generator fills empty blocks and keeps everything outside the markers."""
    start, end = numbers.marker("rests", "start"), numbers.marker("rests", "end")
    text = f"intro\n{start}\n{end}\noutro\n"
    assert numbers.block_in_page(text, "rests") == ""
    filled = numbers.with_blocks(text, {"rests": "| a |\n| b |"})
    assert filled == f"intro\n{start}\n| a |\n| b |\n{end}\noutro\n"
    assert numbers.block_in_page(filled, "rests") == "| a |\n| b |"


def test_broad_quote_follows_docs_real_data(broad02_solved):
    """The BROAD room numbers are read from docs/real-data.md's tables (sections 1 and 2), not copied by hand;
    the shipped trial's lag is the solve's."""
    source = numbers.REAL_DATA.read_text(encoding="utf-8")
    row = next(line for line in numbers.section(source, 2).splitlines() if line.startswith("| 21 | "))
    wander = row.split("|")[2].split(",")[0].strip()
    changed = source.replace(row, row.replace(f"| {wander},", "| 9.99,", 1))
    lag_s = broad02_solved[1].time_offset_s
    assert f"-{wander} %" in numbers.broad_block(lag_s, source)
    assert "-9.99 %" in numbers.broad_block(lag_s, changed)
    assert f"{1e3 * lag_s:.2f} ms on the shipped" in numbers.broad_block(lag_s, source)
    page = PAGE.read_text(encoding="utf-8")
    assert numbers.block_in_page(page, "broad") == numbers.broad_block(lag_s, source)


def test_thresholds_are_the_codes():
    from magyro.front import recording, signals

    text = numbers.check_rules_block()
    assert f"+/-{signals.SOLVE_LAG_SEARCH_S * 1e3:g} ms" in text
    assert f"{recording.BURST_SHORT_PERIODS:g} period" in text
    page = PAGE.read_text(encoding="utf-8")
    assert numbers.block_in_page(page, "check-rules") == text
