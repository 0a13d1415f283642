"""A matplotlib Figure embedded in an HTML page, crisp and readable at the size the page shows it.

The page's figures are PNG data URIs (the page needs no other file). A PNG shown larger than its pixels is
blurred, and one drawn at 72 dpi and stretched to the page's width is both blurred and small-lettered. So each
figure is drawn for the width the page shows it at, `width_px` (CSS pixels: the page's content width), at
twice as many pixels (`PIXEL_RATIO`: crisp on a high-density screen and when printed), and its `<img>` states
the displayed size (width and height attributes), so the browser shows it at that size and no larger.

The text is judged at that displayed size: `smallest_font_px` is the smallest text of the figure in CSS
pixels when it is shown `width_px` wide; the page writes it on the image (`data-smallest-font-px`) and the
browser test checks it against `MIN_FONT_PX`, scaled by the width the browser really shows.
"""
from __future__ import annotations

import base64
import html
import io
import struct
from dataclasses import dataclass

PIXEL_RATIO = 2          # image pixels per displayed CSS pixel
MIN_FONT_PX = 10.0       # the smallest text a figure may show, in CSS pixels at its displayed size
POINTS_PER_INCH = 72.0


@dataclass(frozen=True)
class EmbeddedFigure:
    """A figure as a PNG data URI, with the size the page shows it at and the size of its smallest text there."""

    uri: str
    width_px: int                 # displayed (CSS pixels)
    height_px: int
    pixel_width: int              # of the PNG
    pixel_height: int
    smallest_font_px: float       # at the displayed size

    def img(self, alt: str) -> str:
        """The `<img>` tag: the displayed size in its attributes (the page's CSS lets it shrink, never grow)."""
        return (f"<img src='{self.uri}' width='{self.width_px}' height='{self.height_px}' "
                f"data-smallest-font-px='{self.smallest_font_px:.1f}' alt='{html.escape(alt, quote=True)}'>")


def embed_png(fig, width_px: int) -> EmbeddedFigure:
    """`fig` drawn as a PNG of PIXEL_RATIO x `width_px` pixels across, for a page that shows it `width_px` wide."""
    width_in, _ = fig.get_size_inches()
    target = PIXEL_RATIO * int(width_px)
    dpi = (target + 0.5) / width_in         # a hair over, so that rounding down still gives `target` pixels
    buffer = io.BytesIO()
    fig.savefig(buffer, format="png", dpi=dpi, metadata={"Software": None})
    png = buffer.getvalue()
    pixel_width, pixel_height = png_size(png)
    height_px = pixel_height * int(width_px) // pixel_width    # rounded down: never fewer than 2 pixels per px
    return EmbeddedFigure("data:image/png;base64," + base64.b64encode(png).decode("ascii"), int(width_px),
                          int(height_px), pixel_width, pixel_height, smallest_font_px(fig, width_px))


def png_size(png: bytes) -> tuple[int, int]:
    """(width, height) in pixels, from the PNG's header chunk."""
    return struct.unpack(">II", png[16:24])


def smallest_font_px(fig, width_px: float) -> float:
    """The size of the figure's smallest visible text, in CSS pixels, when the figure is shown `width_px` wide.

    A text of s points is s/72 of an inch of the figure; the figure's width in inches is shown as `width_px`."""
    from matplotlib.text import Text

    px_per_point = width_px / fig.get_size_inches()[0] / POINTS_PER_INCH
    sizes = [t.get_fontsize() for t in fig.findobj(Text) if t.get_visible() and t.get_text().strip()]
    return min(sizes, default=float("inf")) * px_per_point
