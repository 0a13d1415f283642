"""Opening magyro's HTML pages in Debian's headless Chromium, offline, for the tests that check them in a browser.

`browser_or_skip()` gives playwright's sync API, or skips saying what is missing and how to install it
(playwright never downloads a browser here). `open_offline(path)` opens a page with the network blocked and
returns what the browser saw; `FIGURES_JS` measures every figure as the browser shows it, and
`assert_crisp_and_readable` judges those measurements.
"""
from __future__ import annotations

from pathlib import Path

import pytest

from magyro.report.embed import MIN_FONT_PX, PIXEL_RATIO

CHROMIUM = Path("/usr/bin/chromium")
CHROMIUM_ARGS = ["--no-sandbox", "--disable-gpu", "--disable-background-networking", "--disable-component-update",
                 "--disable-sync", "--no-first-run"]
VIEWPORT = {"width": 1100, "height": 900}

# every figure of the page as shown: the image's own pixels, its size on the page (CSS px), the size its <img>
# declares and the smallest text it carries at that size (magyro.report.embed); SVG needs no pixels
FIGURES_JS = """() => [...document.querySelectorAll('figure img, figure svg')].map(e => {
    const r = e.getBoundingClientRect(), c = getComputedStyle(e);
    const px = (k) => parseFloat(c[k]) || 0;                     // the picture is the box less border and padding
    const w = r.width - px('borderLeftWidth') - px('borderRightWidth') - px('paddingLeft') - px('paddingRight');
    const h = r.height - px('borderTopWidth') - px('borderBottomWidth') - px('paddingTop') - px('paddingBottom');
    const svg = e.tagName.toLowerCase() === 'svg' || (e.currentSrc || e.src || '').startsWith('data:image/svg');
    return {svg, shown_w: w, shown_h: h, natural_w: e.naturalWidth || 0, natural_h: e.naturalHeight || 0,
            declared_w: Number(e.getAttribute('width')) || 0,
            smallest_font_px: e.dataset ? Number(e.dataset.smallestFontPx) : NaN,
            alt: e.getAttribute('alt') || ''};
})"""


def browser_or_skip():
    """playwright's sync API, or a skip saying what is missing and how to install it."""
    if not CHROMIUM.exists():
        pytest.skip(f"{CHROMIUM} is absent: install Debian's Chromium (apt-get install chromium) to run the "
                    "browser tests")
    try:
        from playwright.sync_api import sync_playwright
    except ImportError:
        pytest.skip("the playwright package is absent: pip install playwright (the test uses /usr/bin/chromium; "
                    "no `playwright install` is needed)")
    return sync_playwright


def launch_or_skip(p):
    """Chromium, or a skip when it does not start here (missing libraries, ...)."""
    try:
        return p.chromium.launch(executable_path=str(CHROMIUM), args=CHROMIUM_ARGS)
    except Exception as exc:
        pytest.skip(f"{CHROMIUM} did not start ({str(exc).splitlines()[0]}); reinstall it: apt-get install chromium")


def figures_of(path: Path) -> list[dict]:
    """FIGURES_JS on the page at `path`, opened offline at VIEWPORT."""
    sync_playwright = browser_or_skip()
    with sync_playwright() as p:
        browser = launch_or_skip(p)
        try:
            context = browser.new_context(viewport=VIEWPORT)
            context.route("**/*", lambda r: r.continue_() if r.request.url.startswith(("file:", "data:"))
                          else r.abort())
            page = context.new_page()
            page.goto(Path(path).resolve().as_uri(), wait_until="load")
            return page.evaluate(FIGURES_JS)
        finally:
            browser.close()


def assert_crisp_and_readable(figures: list[dict]) -> None:
    """Every figure crisp at the size shown (SVG, or an image of at least PIXEL_RATIO x the pixels it covers) and
    its smallest text at least MIN_FONT_PX as shown (the size it declares, scaled by the width really shown)."""
    assert figures, "the page shows no figure"
    for f in figures:
        name = f["alt"] or "a figure"
        assert f["shown_w"] > 0 and f["shown_h"] > 0, f"{name} is not shown"
        if f["svg"]:
            continue
        assert f["natural_w"] >= PIXEL_RATIO * f["shown_w"] and f["natural_h"] >= PIXEL_RATIO * f["shown_h"], (
            f"{name}: {f['natural_w']}x{f['natural_h']} px shown at {f['shown_w']:.0f}x{f['shown_h']:.0f}: blurred")
        assert f["declared_w"] > 0 and f["smallest_font_px"] > 0, f"{name}: no displayed size or smallest text stated"
        shown_font_px = f["smallest_font_px"] * f["shown_w"] / f["declared_w"]
        assert shown_font_px >= MIN_FONT_PX, f"{name}: its smallest text is {shown_font_px:.1f} px as shown"
