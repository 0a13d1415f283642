"""Regenerate the numbers of docs/spec.md that are constants of magyro's code (the targets, the refusal bound).

    python docs/make_spec_numbers.py [--check] [PAGE]      (default: docs/spec.md)

Blocks between `<!-- numbers:NAME:start -->` / `<!-- numbers:NAME:end -->` markers (docs/doc_blocks.py);
tests/test_doc_numbers.py fails when the page and the code disagree.
"""
from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
import doc_blocks  # noqa: E402
from doc_blocks import DOCS, fmt, g  # noqa: E402

PAGE = DOCS / "spec.md"
COMMAND = "python docs/make_spec_numbers.py"


def defaults_row() -> str:
    """The 'defaults' row of the targets / refusal bound table."""
    from magyro.options import StdBounds
    from magyro.targets import Targets

    t, b = Targets(), StdBounds()
    return (f"{g(t.scale_factor_ppm)} ppm scale, {g(t.non_orthogonality_deg)} deg non-orthogonality, "
            f"{g(t.bias_deg_s)} deg/s bias, {g(t.misalignment_deg)} deg misalignment | {g(b.scale_ppm)} ppm, "
            f"{g(b.nonorthogonality_deg)} deg, {g(b.bias_deg_s)} deg/s, {g(b.misalignment_deg)} deg")


def why_targets() -> str:
    """What each default target means for a device dead-reckoning its heading, and how much looser the bound is."""
    from magyro.options import StdBounds
    from magyro.targets import Targets

    t, b = Targets(), StdBounds()
    leak = np.sin(np.deg2rad(t.non_orthogonality_deg))
    looser = [b.scale_ppm / t.scale_factor_ppm, b.nonorthogonality_deg / t.non_orthogonality_deg,
              b.bias_deg_s / t.bias_deg_s, b.misalignment_deg / t.misalignment_deg]
    return (f"{g(t.scale_factor_ppm)} ppm of scale is "
            f"{fmt(1e-6 * t.scale_factor_ppm * 360)} deg of heading per full turn about that axis; "
            f"{g(t.non_orthogonality_deg)} deg of non-orthogonality leaks {1e6 * leak:.0f} ppm of a turn into "
            f"another axis, {fmt(leak * 360)} deg per full turn; {g(t.bias_deg_s)} deg/s of bias is "
            f"{fmt(60 * t.bias_deg_s)} deg of drift a minute; {g(t.misalignment_deg)} deg of misalignment is the same "
            "size as the non-orthogonality it is confused with. The refusal bound is "
            f"{min(looser):g}-{max(looser):g}x looser:")


def blocks() -> dict[str, str]:
    return {"good-enough-defaults": defaults_row(), "good-enough-why": why_targets()}


def main(argv: list[str]) -> int:
    return doc_blocks.main(argv, PAGE, lambda: blocks(), COMMAND)


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
