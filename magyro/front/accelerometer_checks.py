"""The recording check's look at the accelerometer (issue 26), when the session has one (nothing otherwise):

- `acc_unit`    gravity read as about 1 (g) or about 1000 (mg) by an accelerometer the session holds in
                m/s^2, where it reads 9.8: error (exit 2), naming the unit and the import's --acc-unit;
- `saturation`  accelerometer axes on a plateau at the range, found by the gyro's rule
                (`magyro.front.signals.plateaus`) beyond ACC_SAT_MIN_M_S2: a warning; the samples are kept.

The unit is told from the median |a| by the ranges the CSV import's --acc-unit auto uses
(`magyro.io.csv_units.GRAVITY_READS`), and only when gravity is there all along: an accelerometer in g
never reads much under 1 g for long, whereas a gravity-free (linear) acceleration reads about 0
whenever the hand pauses, and is not in g for reading about 1 in between.
"""
from __future__ import annotations

import numpy as np

from magyro.front.findings import Finding
from magyro.front.signals import plateaus
from magyro.io.csv_units import ACC_UNITS, STANDARD_GRAVITY_M_S2, acc_unit_from_gravity
from magyro.session import Session

MIN_SAMPLES = 10                       # as the other sensors: fewer, nothing is checked
GRAVITY_LOW_QUANTILE = 0.05            # this share of the samples may read under ...
GRAVITY_LOW_FRACTION = 0.5             # ... this share of the median |a|: more, gravity is not there all along
ACC_SAT_MIN_M_S2 = 1.2 * STANDARD_GRAVITY_M_S2   # above gravity at rest, below the smallest full scale (+/-1.5 g)
FULL_SCALES_G = (1.5, 2, 4, 8, 16)      # named when within 3 %


def accelerometer_findings(session: Session) -> tuple[np.ndarray | None, list]:
    """(the accelerometer rows on a saturation plateau, findings); (None, []) without an accelerometer."""
    t, acc = session.t_acc_s, session.acc_m_s2
    if t is None or acc is None:
        return None, []
    cut = np.zeros(len(t), dtype=bool)
    if len(t) < MIN_SAMPLES:
        return cut, []
    found = unit_findings(t, acc)
    if found:   # a plateau at the range means nothing in the wrong unit
        return cut, found
    return saturation(t, acc)


def unit_findings(t: np.ndarray, acc: np.ndarray) -> list:
    """`acc_unit`: an error when the accelerometer reads gravity as g or mg would (labelled m/s^2)."""
    norm = np.linalg.norm(acc, axis=1)
    median = float(np.median(norm))
    unit = acc_unit_from_gravity(median)
    if unit in (None, "m/s^2"):
        return []
    if np.quantile(norm, GRAVITY_LOW_QUANTILE) < GRAVITY_LOW_FRACTION * median:
        return []   # not gravity all along (a gravity-free acceleration?): not a unit this check can name
    factor = ACC_UNITS[unit]
    shown = f"{median:.2f}" if median < 100 else f"{median:.0f}"
    return [Finding(
        "acc_unit", "accelerometer",
        f"the accelerometer reads gravity as about {shown} (median |a|), where m/s^2 would read "
        f"{STANDARD_GRAVITY_M_S2:.2f}: it is in {unit}, not m/s^2", ((float(t[0]), float(t[-1])),), "error",
        f"every specific force would be {STANDARD_GRAVITY_M_S2 / factor:.3g}x too small: gravity, the "
        "accelerometer's scale factors and biases cannot be told apart",
        f"import with --acc-unit {unit} (magyro import csv), or multiply the accelerometer columns by "
        f"{factor:g}", numbers={"median_norm": median, "unit": unit, "factor_m_s2": factor})]


def saturation(t: np.ndarray, acc: np.ndarray) -> tuple[np.ndarray, list]:
    """(rows with an axis on a saturation plateau, findings): `magyro.front.signals.plateaus` beyond
    ACC_SAT_MIN_M_S2, one warning per axis and sign."""
    cut = np.zeros(len(t), dtype=bool)
    findings = []
    for axis, sign, extreme, at, begin, end in plateaus(acc, ACC_SAT_MIN_M_S2):
        cut |= at
        findings.append(saturation_finding("xyz"[axis], sign, extreme, t, at, begin, end))
    return cut, findings


def saturation_finding(name, sign, extreme, t, at, begin, end) -> Finding:
    in_g = extreme / STANDARD_GRAVITY_M_S2
    scale = [s for s in FULL_SCALES_G if abs(in_g - s) <= 0.03 * s]
    return Finding(
        "saturation", "accelerometer", f"accelerometer {name} saturates at {'+' if sign > 0 else '-'}{extreme:.2f} "
        f"m/s^2 ({in_g:.2f} g): {int(at.sum())} samples ({100 * at.mean():.2f} %) on {len(begin)} plateau(s)"
        + (f", a +/-{scale[0]:g} g full scale" if scale else ""),
        tuple((float(t[a]), float(t[b])) for a, b in zip(begin, end)), "warning",
        "the true specific force was beyond the range there: a clipped sample reads less than the device felt, "
        "which pulls the accelerometer's scale factors and biases",
        "the samples are kept as recorded; record with a larger accelerometer range, or move more gently",
        numbers={"axis": name, "limit_m_s2": sign * extreme, "samples": int(at.sum()), "plateaus": len(begin)})
