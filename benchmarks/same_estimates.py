"""Are two calibration JSONs the same estimate? Every estimated number's change in units of its std, and the std's
own relative change (the check of issue 27's speed work: |diff| / std <= 1e-6 for every parameter).

    python benchmarks/same_estimates.py BEFORE.json AFTER.json [--tol 1e-6] [--std-tol 1e-4]

Exit 1 when an estimate moved by more than --tol of its std, or a std by more than --std-tol of itself.
"""
from __future__ import annotations

import argparse
import json
import sys

import numpy as np

WHERE = {"K_g": ("gyro", "K_g"), "bias_deg_s": ("gyro", "bias_deg_s"), "misalignment_deg": ("misalignment", "euler_deg"),
         "R": ("magnetometer", "R"), "h": ("magnetometer", "h"), "K": ("gyro", "K"), "field_i": ("field_i",),
         "time_offset_s": ("time_offset_s",)}


def at(d: dict, path: tuple):
    for key in path:
        d = d[key]
    return np.asarray(d, dtype=float)


def compare(a: dict, b: dict) -> tuple[float, float, list[str]]:
    """(largest |diff| / std, largest relative change of a std, one line per quantity)."""
    worst_z, worst_std, lines = 0.0, 0.0, []
    for name, path in WHERE.items():
        std = at(a["std"], (name,))
        if name not in a["std"] or not np.size(std):
            continue
        ea, eb = at(a, path), at(b, path)
        used = std > 0
        z = float(np.max(np.abs(ea - eb)[used] / std[used])) if used.any() else 0.0
        ds = float(np.max(np.abs(at(b["std"], (name,)) - std)[used] / std[used])) if used.any() else 0.0
        dw = float(np.max(np.abs(at(b["std_white"], (name,)) - at(a["std_white"], (name,)))[used]
                          / at(a["std_white"], (name,))[used])) if used.any() else 0.0
        worst_z, worst_std = max(worst_z, z), max(worst_std, ds, dw)
        lines.append(f"  {name:18s} |diff|/std {z:.2e}   std rel. change {ds:.2e} (white {dw:.2e})")
    return worst_z, worst_std, lines


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("before")
    parser.add_argument("after")
    parser.add_argument("--tol", type=float, default=1e-6)
    parser.add_argument("--std-tol", type=float, default=1e-4)
    args = parser.parse_args()
    a, b = (json.load(open(p)) for p in (args.before, args.after))
    z, s, lines = compare(a, b)
    ok = z <= args.tol and s <= args.std_tol
    print(f"{'SAME' if ok else 'DIFFERENT'}: {args.after} against {args.before}: largest |diff|/std {z:.2e} "
          f"(tol {args.tol:g}), largest std change {s:.2e} (tol {args.std_tol:g})")
    print("\n".join(lines))
    sys.exit(0 if ok else 1)


if __name__ == "__main__":
    main()
